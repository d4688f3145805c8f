"""Pressure valves: relief (direct-acting, with spool dynamics, pilot-operated), reducing,
sequence and counterbalance valves.

Every flow path is the turbulent orifice of report appendix A.1 (eq. A.4, smooth laminar
transition ``dp_t``): ``q = Cd * A * sqrt(2/rho) * reg_root(dp, dp_t)``. Flows are positive into
the component at each port; each valve is a restriction, so its port flows sum to zero.

``ReliefValve`` (direct-acting, static spool). A spool or poppet of area ``A_s`` is pushed open
by ``dp = P.p - T.p`` against a spring of rate ``k`` preloaded to ``A_s * p_crack`` and against
the steady flow force ``2 Cd w x dp cos(theta)`` (report eq. A.6). The opening ``x`` solves the
force balance, then is limited to ``[0, x_max]``; the area gradient ``w`` is the flow gain::

    x* = A_s * (dp - p_crack) / (k + 2 Cd w cos(theta) max(dp, 0))
    x  = onset(x*) - onset(x* - x_max),   A = A_leak + w * x

``onset`` is the quadratic-onset max(., 0) of width ``eps = 1e-3 x_max``
(:func:`pvgraph.components.mechanical.laws.onset_penetration`): ``x = x* - eps/2`` inside the stroke,
exactly 0 when closed. Without flow force the valve opens fully at
``p_full = p_crack + k x_max / A_s``.

``DynamicReliefValve``: the same valve with the spool's mass ``m`` and damping ``b``, ``x`` a
state, and stiff stops at 0 (the seat) and ``x_max``::

    m der(v) = A_s (dp - p_crack) - k x - 2 Cd w cos(theta) x dp - b v - F_stops,  der(x) = v

``PilotReliefValve``: a small pilot relief (setting ``p_set``, opening over ``dp_pilot``, area
``A_pilot``) fed through the main spool's orifice ``A_orifice`` from P; the pilot flow drops the
pressure across the main spool, which opens when that drop exceeds ``dp_main`` and is fully
open at ``dp_main + dp_main_open``. With ``p_c = P.p - dp_o`` the pilot chamber pressure
(``dp_o`` is the internal algebraic unknown)::

    q_o = orifice(A_orifice, P.p - p_c) = orifice(A_pilot * ramp(p_c - T.p; p_set, dp_pilot), p_c - T.p)
    q_m = orifice(A_main * ramp(P.p - p_c; dp_main, dp_main_open), P.p - T.p)
    P.q = q_o + q_m

``ramp(u; u0, du)`` is the C1 smoothstep from 0 at ``u0`` to 1 at ``u0 + du``
(:func:`pvgraph.components.hydraulic.check_valve.smoothstep_ramp`). The pressure override of a pilot
relief at full flow is a few bar, against tens of bar for a direct valve of the same size.

``PressureReducingValve`` (2-way, normally open): the area from P to A closes as the outlet
pressure rises to ``p_set``: ``A = A_leak + A_max * (1 - ramp(A.p; p_set - dp_open, dp_open))``;
above the setting the outlet drains to tank through ``A_drain * ramp(A.p; p_set, dp_open)``, so
a dead-ended outlet holds at the setting.

``SequenceValve`` (externally drained to tank at gauge 0): P to A opens when the inlet pressure
reaches ``p_set``: ``A = A_leak + A_max * ramp(P.p; p_set, dp_open)``.

``CounterbalanceValve``: ports ``load`` (the cylinder chamber holding the load), ``valve`` (the
directional-valve side) and ``pilot`` (the opposite line; it takes no flow). Flow from valve to
load passes a free check (cracking ``p_check``); flow from load to valve is held until the load
pressure, assisted by the pilot pressure times the pilot ratio, reaches the setting::

    A_cb = A_leak + A_max * ramp(load.p + ratio * pilot.p; p_set, dp_open)
    q (load -> valve) = orifice(A_cb, load.p - valve.p) - q_check(valve -> load)
"""

from __future__ import annotations

import math
from typing import Optional

from pydantic import Field, model_validator

from pvgraph import expr as E
from pvgraph.component import Component, Hydraulic, Params, Variable, der
from pvgraph.laws import orifice_flow

from ..mechanical.laws import onset_indicator, onset_penetration
from .check_valve import smoothstep_ramp
from .fluid import rho_field

__all__ = ["ReliefValve", "DynamicReliefValve", "PilotReliefValve", "PressureReducingValve",
           "SequenceValve", "CounterbalanceValve", "relief_opening"]


class _RestrictionParams(Params):
    Cd: float = Field(0.6, gt=0.0, le=1.0, description="Discharge coefficient [-] (report A.1)")
    rho: float = rho_field()
    dp_t: float = Field(1e4, gt=0.0, le=1e7,
                        description="Laminar-turbulent transition pressure drop [Pa] (eq. A.4)")
    A_leak: float = Field(1e-11, gt=0.0, le=1e-4,
                          description="Leakage area when closed, for regularity [m^2]")


# ---------------------------------------------------------------------------------------------
class ReliefValveParams(_RestrictionParams):
    p_crack: float = Field(..., gt=0.0, le=1e8, description="Cracking pressure P - T [Pa]")
    A_s: float = Field(..., gt=0.0, le=1e-2,
                       description="Area the pressure acts on (spool or seat) [m^2]")
    k: float = Field(..., gt=0.0, le=1e9, description="Spring rate [N/m]")
    x_max: float = Field(..., gt=0.0, le=0.1, description="Largest opening stroke [m]")
    w: Optional[float] = Field(
        None, gt=0.0, le=1.0,
        description="Area gradient (flow gain) of the opening [m^2/m] (or Q_rated instead)")
    theta: float = Field(math.radians(69.0), ge=0.0, le=math.pi / 2,
                         description="Jet angle of the flow force [rad] (pi/2: no flow force)")
    Q_rated: Optional[float] = Field(
        None, gt=0.0, le=1.0,
        description="Flow the valve passes fully open at p_rated, in the circuit's fluid "
                    "[m^3/s], instead of w (ReliefValve.from_setting gives both): the "
                    "opening's area gradient is then Q_rated / (Cd sqrt(2 p_rated / rho) "
                    "x_max) at run time, so the data sheet's point holds whatever rho the "
                    "circuit gives (Cd w is what a data sheet fixes: Cd then scales the "
                    "leakage only)")
    p_rated: Optional[float] = Field(
        None, gt=0.0, le=1e8,
        description="Pressure drop at which Q_rated passes fully open [Pa] (the data "
                    "sheet's p_crack + dp_rated; a setting changed later keeps the opening)")

    @model_validator(mode="after")
    def _leak(self):
        if (self.w is None) == (self.Q_rated is None):
            raise ValueError("give the opening as its area gradient w or as the flow Q_rated "
                             "it passes fully open at p_rated (from_setting), one of the two")
        if (self.Q_rated is None) != (self.p_rated is None):
            raise ValueError("Q_rated and p_rated go together: the flow the valve passes fully "
                             "open, and the pressure drop it passes it at")
        if self.A_leak >= 0.01 * self.w_open * self.x_max:
            raise ValueError(f"A_leak ({self.A_leak!r}) must be below 1 % of w * x_max")
        return self

    @property
    def w_open(self) -> float:
        """The opening's area gradient [m^2/m] (from Q_rated where that is given)."""
        return self.w if self.w is not None else rated_gradient(self)

    @property
    def p_full(self) -> float:
        """Pressure drop at which the stroke is full, without flow force [Pa]."""
        return self.p_crack + self.k * self.x_max / self.A_s


def rated_gradient(p):
    """The area gradient [m^2/m] that passes ``p.Q_rated`` fully open at ``p.p_rated`` (numbers
    or the traced parameters alike)."""
    if any(isinstance(x, E.Expr) for x in (p.Q_rated, p.p_rated, p.rho, p.Cd, p.x_max)):
        return p.Q_rated / (p.Cd * E.sqrt(2.0 * p.p_rated / p.rho) * p.x_max)
    return p.Q_rated / (p.Cd * math.sqrt(2.0 * p.p_rated / p.rho) * p.x_max)


def relief_opening(dp, p, w=None):
    """Static opening ``x`` of a direct-acting relief valve at the pressure drop ``dp`` [m]
    (``w``: the opening's area gradient, ``p.w`` by default)."""
    k_f = 2.0 * p.Cd * (p.w if w is None else w) * math.cos(p.theta)
    x_star = p.A_s * (dp - p.p_crack) / (p.k + k_f * onset_penetration(dp, 1.0))
    eps = 1e-3 * p.x_max
    return onset_penetration(x_star, eps) - onset_penetration(x_star - p.x_max, eps)


class ReliefValve(Component):
    """Direct-acting relief valve P -> T with a quasi-static spool (spring, area, flow gain).

    Closed below ``dp = p_crack``; above it the opening is
    ``x = A_s (dp - p_crack) / (k + 2 Cd w cos(theta) dp)``, limited to ``x_max``, and the flow
    ``q = Cd (A_leak + w x) sqrt(2 dp / rho)``. Without flow force (``theta = pi/2``) it is fully
    open at ``p_full = p_crack + k x_max / A_s``. The smoothing of the seat (width
    ``1e-3 x_max``) takes ``5e-4 x_max`` off the opening. The steady pressure at a pump flow
    ``Q`` is the root of ``q(dp) = Q``. From a data sheet's setting instead of the spool:
    ``ReliefValve.from_setting("200 bar", "60 L/min", "15 bar")`` (cracking pressure, rated
    flow, pressure rise to it).
    """

    Params = ReliefValveParams
    ports = {"P": Hydraulic("inlet (protected line)"), "T": Hydraulic("outlet to tank")}

    @classmethod
    def from_setting(cls, p_crack, Q_rated, dp_rated, **params) -> "ReliefValve":
        """A relief valve from its data-sheet characteristic (as Simscape's set pressure and
        regulation range): closed below ``p_crack``, opening in proportion to the pressure
        above it, and passing ``Q_rated`` fully open at ``p_crack + dp_rated`` (``"200 bar"``,
        ``"60 L/min"``, ``"15 bar"``; quantities or SI numbers). The spool is chosen to fit:
        no flow force, a 1 mm stroke on 20 mm^2 (``params`` may set ``Cd``, ``rho``,
        ``A_leak``, ``dp_t``).

        ``Q_rated`` is where the stroke ends: beyond it the valve is a fixed orifice and the
        pressure rises with the square of the flow (a "60 L/min, 150 + 15 bar" valve holds
        225 bar at 70 L/min, 371 bar at 90 L/min). Give the largest flow the valve will
        pass, not a catalogue's nominal flow, where the characteristic must stay flat; a
        data sheet's p-Q curve read at two flows gives ``dp_rated`` at that flow. The point
        holds in the circuit's fluid: the opening is sized from ``Q_rated`` at ``p_rated``
        (``p_crack + dp_rated``) at run time (a circuit's
        :meth:`~pvgraph.Circuit.use_fluid` or a runtime ``rho`` keeps it), as a ServoValve
        keeps its rated flow; a setting changed later keeps the opening."""
        from pvgraph.units import number_in
        p_crack = number_in(p_crack, "Pa", "ReliefValve.from_setting p_crack")
        Q = number_in(Q_rated, "m^3/s", "ReliefValve.from_setting Q_rated")
        dp_o = number_in(dp_rated, "Pa", "ReliefValve.from_setting dp_rated")
        for name, value in (("p_crack", p_crack), ("Q_rated", Q), ("dp_rated", dp_o)):
            if not value > 0.0:
                from pvgraph.errors import ParameterError
                raise ParameterError(f"ReliefValve.from_setting: {name} must be positive, got "
                                     f"{value!r}")
        for name in ("A_s", "k", "x_max", "w", "theta", "p_crack", "Q_rated", "p_rated"):
            if name in params:
                from pvgraph.errors import ParameterError
                raise ParameterError(f"ReliefValve.from_setting chooses {name} from the setting; "
                                     f"give the spool's parameters to ReliefValve(...) instead")
        x_max, a_s = 1e-3, 20e-6
        return cls(p_crack=p_crack, A_s=a_s, k=dp_o * a_s / x_max, x_max=x_max,
                   theta=math.pi / 2, Q_rated=Q, p_rated=p_crack + dp_o, **params)

    def equations(self, v, p):
        dp = v.observe("dp", v.P.p - v.T.p, "Pa", "pressure drop P - T")
        # the opening as given, or sized from the data sheet in the circuit's fluid
        w = p.w if p.Q_rated is None else rated_gradient(p)
        x = v.observe("x", relief_opening(dp, p, w), "m", "spool opening")
        A = p.A_leak + w * x
        q = v.observe("q", orifice_flow(p.Cd, A, dp, p.rho, p.dp_t), "m^3/s", "flow P -> T")
        v.observe("P_loss", q * dp, "W", "hydraulic power dissipated")
        return [v.P.q - q, v.P.q + v.T.q]


class DynamicReliefValveParams(ReliefValveParams):
    w: float = Field(..., gt=0.0, le=1.0,
                     description="Area gradient (flow gain) of the opening [m^2/m]")
    m: float = Field(..., gt=0.0, le=10.0, description="Mass of the spool or poppet [kg]")
    b: float = Field(..., ge=0.0, le=1e6, description="Viscous damping of the spool [N s/m]")
    k_stop: float = Field(1e8, gt=0.0, le=1e12,
                          description="Stiffness of the seat and the stroke stop [N/m]")
    d_stop: float = Field(1e3, ge=0.0, le=1e8,
                          description="Damping of the seat and the stroke stop [N s/m]")

    @model_validator(mode="after")
    def _no_rating(self):
        if self.Q_rated is not None:
            raise ValueError("Q_rated sizes the quasi-static ReliefValve (from_setting); a "
                             "dynamic valve's opening is its area gradient w")
        if self.p_rated is not None:
            raise ValueError("p_rated goes with Q_rated, which sizes the quasi-static "
                             "ReliefValve (from_setting) only")
        return self


class DynamicReliefValve(Component):
    """Direct-acting relief valve with spool dynamics (mass, damping, seat and stroke stop)."""

    Params = DynamicReliefValveParams
    ports = {"P": Hydraulic("inlet (protected line)"), "T": Hydraulic("outlet to tank")}
    variables = {"x": Variable("m", lambda p: -p.A_s * p.p_crack / p.k_stop - 5e-4 * p.x_max,
                               1e-3, "spool opening (negative: pressed into the seat)"),
                 "v": Variable("m/s", 0.0, 0.1, "spool velocity")}

    def equations(self, v, p):
        dp = v.observe("dp", v.P.p - v.T.p, "Pa", "pressure drop P - T")
        eps = 1e-3 * p.x_max
        pen_lo, pen_hi = onset_penetration(-v.x, eps), onset_penetration(v.x - p.x_max, eps)
        contact = onset_indicator(-v.x, eps) + onset_indicator(v.x - p.x_max, eps)
        F_stop = v.observe("F_stop", p.k_stop * (pen_hi - pen_lo) + p.d_stop * contact * v.v,
                           "N", "seat and stop force on the spool in -x")
        x_open = onset_penetration(v.x, eps)
        A = p.A_leak + p.w * x_open
        F_flow = 2.0 * p.Cd * p.w * x_open * math.cos(p.theta) * dp
        q = v.observe("q", orifice_flow(p.Cd, A, dp, p.rho, p.dp_t), "m^3/s", "flow P -> T")
        v.observe("P_loss", q * dp, "W", "hydraulic power dissipated")
        return [der(v.x) - v.v,
                p.m * der(v.v) - (p.A_s * (dp - p.p_crack) - p.k * v.x - F_flow - p.b * v.v
                                  - F_stop),
                v.P.q - q, v.P.q + v.T.q]


# ---------------------------------------------------------------------------------------------
class PilotReliefValveParams(_RestrictionParams):
    p_set: float = Field(..., gt=0.0, le=1e8, description="Pilot setting (cracking) [Pa]")
    dp_pilot: float = Field(5e5, gt=0.0, le=1e7,
                            description="Pressure rise over which the pilot opens fully [Pa]")
    A_pilot: float = Field(1e-6, gt=0.0, le=1e-3, description="Full pilot area [m^2]")
    A_orifice: float = Field(0.5e-6, gt=0.0, le=1e-3,
                             description="Orifice from P to the pilot chamber [m^2]")
    dp_main: float = Field(3e5, gt=0.0, le=1e7,
                           description="Pressure drop across the main spool that cracks it "
                                       "(main spring preload / area) [Pa]")
    dp_main_open: float = Field(2e5, gt=0.0, le=1e7,
                                description="Further drop that opens the main spool fully [Pa]")
    A_main: float = Field(..., gt=0.0, le=1e-2, description="Full main-stage area [m^2]")


class PilotReliefValve(Component):
    """Pilot-operated relief valve P -> T: a pilot relief steers a main spool (flat override)."""

    Params = PilotReliefValveParams
    ports = {"P": Hydraulic("inlet (protected line)"), "T": Hydraulic("outlet to tank")}
    variables = {"dp_o": Variable("Pa", 0.0, 1e5,
                                  "drop across the main spool's orifice, P.p - p_c")}

    def equations(self, v, p):
        P, T = v.P.p, v.T.p
        p_c = v.observe("p_c", P - v.dp_o, "Pa", "pilot chamber pressure")
        A_pilot = p.A_leak + p.A_pilot * smoothstep_ramp(p_c - T, p.p_set, p.dp_pilot)
        q_o = v.observe("q_pilot", orifice_flow(p.Cd, p.A_orifice, P - p_c, p.rho, p.dp_t),
                        "m^3/s", "pilot flow")
        q_pilot = orifice_flow(p.Cd, A_pilot, p_c - T, p.rho, p.dp_t)
        A_m = p.A_leak + p.A_main * smoothstep_ramp(P - p_c, p.dp_main, p.dp_main_open)
        q_m = v.observe("q_main", orifice_flow(p.Cd, A_m, P - T, p.rho, p.dp_t), "m^3/s",
                        "main-stage flow")
        q = v.observe("q", q_o + q_m, "m^3/s", "flow P -> T")
        v.observe("P_loss", q * (P - T), "W", "hydraulic power dissipated")
        return [q_o - q_pilot, v.P.q - q, v.P.q + v.T.q]


# ---------------------------------------------------------------------------------------------
class SettingParams(_RestrictionParams):
    p_set: float = Field(..., gt=0.0, le=1e8, description="Pressure setting [Pa]")
    dp_open: float = Field(5e5, gt=0.0, le=1e7,
                           description="Pressure band over which the valve opens/closes [Pa]")
    A_max: float = Field(..., gt=0.0, le=1e-2, description="Fully open area [m^2]")


class ReducingValveParams(SettingParams):
    A_drain: float = Field(1e-9, ge=0.0, le=1e-4,
                           description="Area from the outlet to the drain (the spring "
                                       "chamber's, to tank) once the outlet is above the "
                                       "setting; 0: none [m^2]")
    p_drain: float = Field(0.0, ge=-1e5, le=1e7,
                           description="Pressure of the drain (tank, gauge) [Pa]")


class PressureReducingValve(Component):
    """2-way pressure-reducing valve P -> A, normally open, closing as A.p reaches ``p_set``.

    Area ``A_leak + A_max (1 - ramp(A.p; p_set - dp_open, dp_open))``: with the supply above
    the setting and the outlet flowing, the outlet holds between ``p_set - dp_open`` and
    ``p_set``. Above the setting the outlet drains to ``p_drain`` through
    ``A_drain ramp(A.p; p_set, dp_open)`` (the spool's leakage into its drained spring
    chamber), which takes the closed valve's leak ``A_leak``: a dead-ended outlet (a clamp at
    stall) holds just above the setting instead of creeping up to the supply: where the
    drain takes the leak, ``A_drain ramp sqrt(A.p - p_drain) = A_leak sqrt(P.p - A.p)``. With
    the defaults (``A_drain = 100 A_leak``) that is within ``0.1 dp_open`` of the setting
    while ``P.p - p_set < 7.8 (p_set - p_drain)`` (a 50 bar setting: supplies up to 430 bar;
    200 bar gives 50.389 bar) and within ``dp_open`` up to ``10^4 (p_set - p_drain)``. The
    drain flow (observed ``q_drain``) leaves the circuit; it is of the order of the leak
    (a few mL/min).
    """

    Params = ReducingValveParams
    ports = {"P": Hydraulic("inlet (supply)"), "A": Hydraulic("reduced outlet")}

    def equations(self, v, p):
        dp = v.P.p - v.A.p
        A = v.observe("A_open", p.A_leak + p.A_max * (1.0 - smoothstep_ramp(
            v.A.p, p.p_set - p.dp_open, p.dp_open)), "m^2", "opening area")
        q = v.observe("q", orifice_flow(p.Cd, A, dp, p.rho, p.dp_t), "m^3/s", "flow P -> A")
        a_drain = p.A_drain * smoothstep_ramp(v.A.p, p.p_set, p.dp_open)
        q_drain = v.observe("q_drain", orifice_flow(p.Cd, a_drain, v.A.p - p.p_drain, p.rho,
                                                    p.dp_t), "m^3/s", "flow A -> drain")
        return [v.P.q - q, v.P.q + v.A.q - q_drain]


class SequenceValve(Component):
    """Sequence valve P -> A, opening when the inlet reaches ``p_set`` (drained to tank)."""

    Params = SettingParams
    ports = {"P": Hydraulic("inlet (primary circuit)"), "A": Hydraulic("secondary circuit")}

    def equations(self, v, p):
        A = v.observe("A_open", p.A_leak + p.A_max * smoothstep_ramp(v.P.p, p.p_set, p.dp_open),
                      "m^2", "opening area")
        q = v.observe("q", orifice_flow(p.Cd, A, v.P.p - v.A.p, p.rho, p.dp_t), "m^3/s",
                      "flow P -> A")
        return [v.P.q - q, v.P.q + v.A.q]


class CounterbalanceValveParams(SettingParams):
    ratio: float = Field(3.0, ge=0.0, le=20.0,
                         description="Pilot ratio: pilot area / load-side area [-]")
    A_check: float = Field(..., gt=0.0, le=1e-2, description="Free-flow check area [m^2]")
    p_check: float = Field(1e5, ge=0.0, le=1e7,
                           description="Cracking pressure of the free-flow check [Pa]")


class CounterbalanceValve(Component):
    """Counterbalance (over-centre) valve: free flow to the load, pilot-assisted relief back.

    Flow from load to valve is held until ``load.p + ratio * pilot.p`` reaches ``p_set``; while
    holding, the relief path and the closed check each leak through ``A_leak``:
    ``q = 2 Cd A_leak sqrt(2 (load.p - valve.p) / rho)``.
    """

    Params = CounterbalanceValveParams
    ports = {"valve": Hydraulic("directional-valve side"),
             "load": Hydraulic("load side (cylinder chamber holding the load)"),
             "pilot": Hydraulic("pilot line (opposite cylinder line); no flow")}

    def equations(self, v, p):
        dp = v.load.p - v.valve.p
        p_ctrl = v.observe("p_control", v.load.p + p.ratio * v.pilot.p, "Pa",
                           "opening pressure load.p + ratio * pilot.p")
        A_cb = p.A_leak + p.A_max * smoothstep_ramp(p_ctrl, p.p_set, p.dp_open)
        A_ck = p.A_leak + p.A_check * smoothstep_ramp(-dp, p.p_check, 0.5 * p.dp_open)
        q = v.observe("q", orifice_flow(p.Cd, A_cb, dp, p.rho, p.dp_t)
                      + orifice_flow(p.Cd, A_ck, dp, p.rho, p.dp_t), "m^3/s",
                      "flow load -> valve")
        return [v.load.q - q, v.load.q + v.valve.q, v.pilot.q]
