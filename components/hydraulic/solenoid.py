"""Solenoid valves: the rig's on/off valve L2 and the PVE's PWM-driven NC and NO valves.

Sign convention: ``a.q = q``, ``b.q = -q``, ``q`` positive from ``a`` to ``b``; ``dp = a.p - b.p``.

``OnOffValve`` (signal input ``u``: 0 closed, 1 open) and ``TimedOnOffValve`` (switched at
scheduled times by declared events), the rig's L2 (report 4.6-4.7). The opening fraction ``s``
follows the clipped command ``u_c = clip(u, 0, 1)`` through

- ``dynamics="lag"``: ``der(s) = (u_c - s) / tau``, ``tau = tau_open`` while opening
  (``u_c > s``), ``tau_close`` while closing;
- ``dynamics="ramp"``: a rate-limited ramp, ``der(s) = min((u_c - s)/tau_f, 1/tau_open)`` while
  opening and ``max((u_c - s)/tau_f, -1/tau_close)`` while closing, so a full stroke takes
  ``tau_open`` (``tau_close``); ``tau_f = min(tau_open, tau_close) / 50`` lands it smoothly.

The flow is that of the open valve scaled by ``o = s_leak + (1 - s_leak) * s``::

    q = Cd * (o * A) * sqrt(2/rho) * dp / (dp^2 + dp_t^2)^(1/4)   (turbulent, report A.4;
                                                                   L2: A = 5.800 mm^2, Cd 0.6,
                                                                   table 4.7)
    q = (o * K) * dp                                             (laminar, eq. 4.132; L2:
                                                                   K = 1.6111 L/(bar min),
                                                                   table 4.8)

The report gives no switching time for L2 (its traces are aligned to the step, 4.7.3): the
default 20 ms is an assumption.

``PWMValve``: the PVE's normally closed (NC1, NC3, pilot side) and normally open (NO2, NO4, tank
side) valves as duty-cycle-averaged flow maps (report 4.5.4, figures 4.22 and 4.55). The duty
cycle ``DT`` [0..1] is a signal input, clipped to [0, 1] and delayed by a first-order lag of
the switching delay (report 4.5.5: 20 ms NC, 3 ms NO)::

    tau * der(d) = clip(DT, 0, 1) - d
    q = Q_ref(d) * r(dp) / r(dp_ref),   r(dp) = dp / (dp^2 + dp_t^2)^(1/4)

``Q_ref(d)`` is a monotone pchip table of the flow at the reference pressure drop ``dp_ref``;
the pressure dependence is the orifice law's square root with a laminar transition ``dp_t``.

Reconstruction of the default maps. The report's 4D map (Danfoss) is not published; its
figure 4.55 gives least-squares lines of the flow over DT [%]:

- NC at 13.5 bar: ``Q = 3.0e-7 DT - 3.7e-6`` [m^3/s]; NC at 2 bar: ``Q = 1.1e-7 DT - 2.4e-6``;
- NO at 4 bar: ``Q = -1.8e-7 DT + 1.6e-5``; NO at 2 bar: ``Q = -1.7e-7 DT + 1.3e-5``.

The default ``Q_ref`` follows the line at the pressure the report linearised at (NC 13.5 bar,
NO 4 bar, section 4.8) wherever the line is positive, with a smooth toe to zero flow (NC below
about 12 % DT, NO above about 89 %). ``dp_t`` is fitted to the second line: NC 1.9 bar (the 2 bar
line at DT = 70 % and 100 % within 7 %), NO 0.2 bar (the 2 bar line at DT = 0, 25, 50 % within
13 %). Check against figure 4.22: the NC map gives 2.86e-5 m^3/s at 16 bar and 100 % (the
figure's largest curve, below its 3e-5 axis limit); the NO map gives 3.4e-5 m^3/s at 16 bar and
0 %, below the figure's 4.5-5e-5 range: a separable map cannot match figure 4.22's NO plateau
and figure 4.55's NO lines at once, and the lines (which the report's linear model uses) are
kept. Pass ``DT_table``/``Q_table``/``dp_ref`` to use another map (e.g. from
``pvgraph.circuits.pvg32.tables``).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from pvgraph import expr as E
from pvgraph.component import Component, Hydraulic, Params, SignalIn, Variable, der
from pvgraph.laws import orifice_flow, reg_root
from pvgraph.units import bar, lpm_per_bar, mm2

from .fluid import rho_field

# Default flow maps (see the module docstring): duty cycle [-] -> flow at dp_ref [m^3/s].
NC_DT = (0.0, 0.05, 0.10, 0.15, 0.20, 0.30, 0.40, 0.50, 0.60, 0.70, 0.80, 0.90, 1.00)
NC_Q = (0.0, 0.0, 0.15e-6, 0.8e-6, 2.3e-6, 5.3e-6, 8.3e-6, 11.3e-6, 14.3e-6, 17.3e-6,
        20.3e-6, 23.3e-6, 26.3e-6)
NC_DP_REF = bar(13.5)
NC_DP_T = bar(1.9)
NO_DT = (0.0, 0.10, 0.20, 0.30, 0.40, 0.50, 0.60, 0.70, 0.80, 0.85, 0.90, 0.95, 1.00)
NO_Q = (16.0e-6, 14.2e-6, 12.4e-6, 10.6e-6, 8.8e-6, 7.0e-6, 5.2e-6, 3.4e-6, 1.6e-6, 0.75e-6,
        0.15e-6, 0.0, 0.0)
NO_DP_REF = bar(4.0)
NO_DP_T = bar(0.2)
DEFAULTS = {
    "NC": dict(DT_table=NC_DT, Q_table=NC_Q, dp_ref=NC_DP_REF, dp_t=NC_DP_T, tau=0.020),
    "NO": dict(DT_table=NO_DT, Q_table=NO_Q, dp_ref=NO_DP_REF, dp_t=NO_DP_T, tau=0.003),
}

# the rig's L2 valve (report tables 4.7 and 4.8)
L2_AREA = mm2(5.800)
L2_K = lpm_per_bar(1.6111)


class OnOffValveParams(Params):
    A: float | None = Field(
        None, gt=0.0, le=1.0,
        description="Open area, turbulent law [m^2] (rig L2: 5.800 mm^2 at Cd 0.6, report table "
                    "4.7); give A or K")
    K: float | None = Field(
        None, gt=0.0, le=1.0,
        description="Open flow-pressure coefficient, laminar law [m^3/(s Pa)] (rig L2: 1.6111 "
                    "L/(bar min), report table 4.8); give A or K")
    Cd: float = Field(0.6, gt=0.0, le=1.0, description="Discharge coefficient [-] (table 4.7)")
    rho: float = rho_field()
    dp_t: float = Field(1e3, gt=0.0, le=1e7,
                        description="Laminar-turbulent transition pressure drop [Pa] (turbulent "
                                    "law only)")
    dynamics: Literal["lag", "ramp"] = Field(
        "lag", description="Opening dynamics [-]: first-order lag or rate-limited ramp")
    tau_open: float = Field(0.02, gt=0.0, le=10.0,
                            description="Opening time constant (lag) or full-stroke opening time "
                                        "(ramp) [s] (not in the report; assumed)")
    tau_close: float = Field(0.02, gt=0.0, le=10.0,
                             description="Closing time constant (lag) or full-stroke closing "
                                         "time (ramp) [s] (not in the report; assumed)")
    s0: float = Field(0.0, ge=0.0, le=1.0, description="Initial opening fraction [-]")
    s_leak: float = Field(1e-9, ge=0.0, lt=1.0,
                          description="Opening fraction when closed, for regularity [-]")

    @model_validator(mode="after")
    def _one_law(self):
        if (self.A is None) == (self.K is None):
            raise ValueError("give exactly one of A (turbulent orifice) and K (laminar "
                             "restriction)")
        return self


def _opening_rate(u, s, p):
    """der(s) of the opening fraction towards the clipped command ``u``."""
    if p.dynamics == "lag":
        return (u - s) / E.where(u > s, p.tau_open, p.tau_close)
    tau_f = min(p.tau_open, p.tau_close) / 50.0
    return E.where(u > s, E.minimum((u - s) / tau_f, 1.0 / p.tau_open),
                   E.maximum((u - s) / tau_f, -1.0 / p.tau_close))


def _valve_flow(dp, s, p):
    opening = p.s_leak + (1.0 - p.s_leak) * s
    if p.K is not None:
        return opening * p.K * dp
    return orifice_flow(p.Cd, opening * p.A, dp, p.rho, p.dp_t)


class _OnOffBase(Component):
    variables = {"s": Variable("1", lambda p: p.s0, 1.0, "opening fraction (0 closed, 1 open)")}

    def _command(self, v, p):
        raise NotImplementedError

    def equations(self, v, p):
        u = v.observe("u_cmd", E.clip(self._command(v, p), 0.0, 1.0), "1",
                      "open command, clipped to [0, 1]")
        dp = v.observe("dp", v.a.p - v.b.p, "Pa", "pressure drop a - b")
        q = v.observe("q", _valve_flow(dp, v.s, p), "m^3/s", "flow from a to b")
        v.observe("P_loss", q * dp, "W", "hydraulic power dissipated")
        return [der(v.s) - _opening_rate(u, v.s, p), v.a.q - q, v.a.q + v.b.q]


class OnOffValve(_OnOffBase):
    """On/off solenoid valve driven by the signal ``u`` (0 closed, 1 open); the rig's L2."""

    Params = OnOffValveParams
    ports = {"a": Hydraulic("inlet"), "b": Hydraulic("outlet"),
             "u": SignalIn("open command: 0 closed, 1 open", "1", 1.0)}

    def _command(self, v, p):
        return v.u


class TimedOnOffValveParams(OnOffValveParams):
    u0: Literal[0, 1] = Field(0, description="Command before the first switching time [-]")
    t_switch: tuple[float, ...] = Field(
        ..., min_length=1,
        description="Times at which the command toggles [s], positive, strictly increasing")

    @model_validator(mode="after")
    def _schedule(self):
        t = self.t_switch
        if t[0] <= 0.0 or any(b <= a for a, b in zip(t, t[1:])):
            raise ValueError(f"t_switch must be positive and strictly increasing, got {t!r}")
        return self


class TimedOnOffValve(_OnOffBase):
    """On/off solenoid valve toggled at the times ``t_switch`` (events); the rig's L2 steps."""

    Params = TimedOnOffValveParams
    ports = {"a": Hydraulic("inlet"), "b": Hydraulic("outlet")}
    modes = {"toggled": 0.0}

    def _command(self, v, p):
        # at_start: a run that starts at or after a switching time starts with it applied
        # (the latest one last), as Step does
        for k, t_k in enumerate(p.t_switch):
            v.event(f"switch{k}", v.t - t_k, direction=1, action=_set_toggled((k + 1) % 2),
                    at_start=True)
        toggled = v.mode("toggled")
        return p.u0 + (1 - 2 * p.u0) * toggled


def _set_toggled(value):
    def action(modes):
        modes["toggled"] = value
    return action


class PWMValveParams(Params):
    kind: Literal["NC", "NO"] = Field(
        ..., description="Normally closed (pilot side NC1/NC3, flow grows with DT) or normally "
                         "open (tank side NO2/NO4, flow falls with DT) [-] (report 4.5.4)")
    DT_table: tuple[float, ...] | None = Field(
        None, description="Duty cycles of the flow map [-] in [0, 1], strictly increasing "
                          "(None: the reconstruction of figures 4.22/4.55 for `kind`)")
    Q_table: tuple[float, ...] | None = Field(
        None, description="Flow at dp_ref for each duty cycle [m^3/s], >= 0")
    dp_ref: float | None = Field(
        None, gt=0.0, le=1e8,
        description="Pressure drop of Q_table [Pa] (default NC 13.5 bar, NO 4 bar: report 4.8)")
    dp_t: float | None = Field(
        None, gt=0.0, le=1e7,
        description="Laminar-turbulent transition pressure drop [Pa] (default fitted: NC 1.9 "
                    "bar, NO 0.2 bar)")
    tau: float | None = Field(
        None, gt=0.0, le=1.0,
        description="Switching delay as a first-order lag on DT [s] (report 4.5.5: 20 ms NC, "
                    "3 ms NO)")
    DT0: float = Field(0.0, ge=0.0, le=1.0, description="Initial effective duty cycle [-]")

    @model_validator(mode="after")
    def _map(self):
        if (self.DT_table is None) != (self.Q_table is None):
            raise ValueError("DT_table and Q_table must be given together")
        if self.DT_table is not None:
            x, y = self.DT_table, self.Q_table
            if len(x) != len(y) or len(x) < 2:
                raise ValueError(f"DT_table ({len(x)} points) and Q_table ({len(y)} points) "
                                 f"must have the same length >= 2")
            if any(b <= a for a, b in zip(x, x[1:])) or x[0] < 0.0 or x[-1] > 1.0:
                raise ValueError("DT_table must be strictly increasing within [0, 1]")
            if min(y) < 0.0:
                raise ValueError("Q_table must not be negative")
        return self

    def setting(self, name):
        """A field's value, or the default of the valve kind when it is None."""
        value = getattr(self, name)
        return DEFAULTS[self.kind][name] if value is None else value

    def flow_table(self) -> E.Table:
        return E.Table(self.setting("DT_table"), self.setting("Q_table"), method="pchip",
                       name=f"{self.kind} flow map")

    def flow(self, DT, dp):
        """Steady duty-cycle-averaged flow at duty cycle ``DT`` and pressure drop ``dp``."""
        dp_t = self.setting("dp_t")
        return (self.flow_table()(DT) * reg_root(dp, dp_t)
                / reg_root(self.setting("dp_ref"), dp_t))


class PWMValve(Component):
    """PWM-driven solenoid valve as a duty-cycle-averaged flow map (report 4.5.4-4.5.5)."""

    Params = PWMValveParams
    ports = {"a": Hydraulic("inlet"), "b": Hydraulic("outlet"),
             "DT": SignalIn("duty cycle, 0..1", "1", 1.0)}
    variables = {"d": Variable("1", lambda p: p.DT0, 1.0,
                               "effective (delayed) duty cycle")}

    def equations(self, v, p):
        dp = v.observe("dp", v.a.p - v.b.p, "Pa", "pressure drop a - b")
        q = v.observe("q", p.flow(v.d, dp), "m^3/s", "flow from a to b")
        v.observe("P_loss", q * dp, "W", "hydraulic power dissipated")
        return [p.setting("tau") * der(v.d) - (E.clip(v.DT, 0.0, 1.0) - v.d),
                v.a.q - q, v.a.q + v.b.q]
