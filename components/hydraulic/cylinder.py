"""Double-acting cylinder: two piston chambers on one rod (for load networks).

Ports ``A`` (cap-side chamber), ``B`` (rod-side chamber) and ``flange`` (the rod; ``x = 0``
fully retracted, ``x = stroke`` fully extended). With the annulus area ``A_B = A_A - A_rod``::

    V_A = V_dead_A + A_A * x
    V_B = V_dead_B + A_B * (stroke - x)
    V_A / beta(p_A) * der(p_A) = A.q - A_A * der(x) - q_leak
    V_B / beta(p_B) * der(p_B) = B.q + A_B * der(x) + q_leak
    q_leak = K_leak * (p_A - p_B)
    F_stop = max(k_stop pen_hi + d_stop c_hi v, 0) - max(k_stop pen_lo - d_stop c_lo v, 0)
             + d_cush * (w_hi + w_lo) * v
    flange.f = -(A_A * p_A - A_B * p_B) + F_stop

This is the chamber continuity of report appendix A.5 (eq. A.7) applied to each side, as the
report does for the spool chambers (eqs. 4.14, 4.93-4.94). Sign convention: port flows are
positive into the cylinder; ``flange.f`` is the force the mechanical node exerts on the cylinder
in +x, so the rod pushes its load with ``F = A_A p_A - A_B p_B`` in +x (observed as ``F``).

End stops: ``pen_hi``/``pen_lo`` are the penetrations past ``x = stroke`` and before ``x = 0``
with a quadratic onset over ``eps_stop`` (exactly zero in free travel,
:func:`pvgraph.components.mechanical.laws.onset_penetration`), ``c_hi``/``c_lo`` = clip(depth/eps, 0, 1)
their contact indicators, so the stops push the rod back with a stiff spring ``k_stop`` and a
damper ``d_stop`` acting only in contact. At rest against a stop under a force ``F`` the rod is
``F / k_stop + eps_stop / 2`` past it.
Cushioning: over the last ``l_cush`` of travel at each end a viscous force ``d_cush * v`` brakes
the rod, faded in smoothly: ``w = 3 s^2 - 2 s^3`` with ``s`` from 0 where the cushion begins
(``l_cush`` before the end) to 1 at the end, so the full ``d_cush`` acts only at the end of
stroke (half of it halfway in); this is the lumped effect of the throttled outflow of a
cushion spear. Observed: ``F_stop``,
``penetration`` (past the stroke, positive; before 0, negative) and the chamber volumes.
A rod more than 1 mm past an end (a load starting outside the stroke, a force the stop cannot
hold) raises a :class:`PlausibilityWarning` once, naming the cylinder.
"""

from __future__ import annotations

import warnings

from pydantic import Field, model_validator

from pvgraph import expr as E
from pvgraph.component import Component, Hydraulic, Mechanical, der
from pvgraph.errors import PlausibilityWarning

from ..mechanical.laws import onset_indicator, onset_penetration
from .fluid import cavitation_warning
from .volumes import FluidCompliance, chamber_continuity, chamber_volume


def _cushion_weight(depth, length):
    """0 more than ``length`` before the end, 1 at and past it: smoothstep across the cushion."""
    s = E.clip(depth / length + 1.0, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


#: how far past an end stop the rod may go before the cylinder warns [m]
OVERRUN = 1e-3


def _overrun_warning(v, x, p):
    """Warn once when the rod is more than OVERRUN past an end (at the start, too)."""
    path = v._prefix
    done = v.mode("overrun")
    stroke = f" (stroke {p.stroke:g} m)" if isinstance(p.stroke, (int, float)) else ""
    for name, depth, end in (("overrun_hi", x - p.stroke, "x = stroke"), ("overrun_lo", -x,
                                                                         "x = 0")):
        def action(modes, end=end):
            modes["overrun"] = 1.0
            warnings.warn(PlausibilityWarning(
                f"{path}: the rod is more than {OVERRUN * 1e3:g} mm past its end stop at "
                f"{end}{stroke}. Does the load on the rod start outside the stroke (its x0), "
                f"or push harder than the stop (k_stop) can hold?"),
                stacklevel=2)
        v.event(name, E.where(done < 0.5, depth - OVERRUN, -1.0), direction=1, action=action,
                at_start=True)


class CylinderParams(FluidCompliance):
    A_A: float = Field(..., gt=0.0, le=1.0, description="Piston (cap-side) area [m^2]")
    A_rod: float = Field(..., ge=0.0, le=1.0,
                         description="Rod cross-section area [m^2] (0: double rod ends equal)")
    stroke: float = Field(..., gt=0.0, le=20.0, description="Stroke [m]")
    V_dead_A: float = Field(..., gt=0.0, le=10.0,
                            description="Cap-side volume at x = 0 (lines and dead volume) [m^3]")
    V_dead_B: float = Field(..., gt=0.0, le=10.0,
                            description="Rod-side volume at x = stroke [m^3]")
    K_leak: float = Field(0.0, ge=0.0, le=1e-6,
                          description="Laminar leakage A -> B across the piston [m^3/(s Pa)]")
    V_min: float = Field(1e-9, gt=0.0, le=1.0,
                         description="Smooth lower limit of each chamber volume [m^3]")
    p0_A: float = Field(0.0, ge=-1e5, le=1e9, description="Initial pressure in A [Pa]")
    p0_B: float = Field(0.0, ge=-1e5, le=1e9, description="Initial pressure in B [Pa]")
    k_stop: float = Field(1e9, gt=0.0, le=1e13, description="End-stop contact stiffness [N/m]")
    d_stop: float = Field(1e6, ge=0.0, le=1e10,
                          description="End-stop contact damping [N s/m] (acts only in contact)")
    eps_stop: float = Field(1e-6, gt=0.0, le=1e-3,
                            description="Rounding of the end-stop contact onset [m]")
    l_cush: float = Field(0.0, ge=0.0, le=1.0,
                          description="Cushion length at each end [m] (0: no cushioning)")
    d_cush: float = Field(0.0, ge=0.0, le=1e10,
                          description="Cushion damping coefficient [N s/m]")

    @model_validator(mode="after")
    def _geometry(self):
        if self.A_rod >= self.A_A:
            raise ValueError(f"A_rod ({self.A_rod:.6g} m^2) must be smaller than A_A "
                             f"({self.A_A:.6g} m^2)")
        if self.l_cush >= 0.5 * self.stroke:
            raise ValueError(f"l_cush ({self.l_cush!r} m) must be below half the stroke")
        if self.d_cush > 0.0 and self.l_cush == 0.0:
            raise ValueError("d_cush > 0 needs a cushion length l_cush > 0")
        if min(self.V_dead_A, self.V_dead_B) <= 10.0 * self.V_min:
            raise ValueError("V_dead_A and V_dead_B must be well above V_min")
        return self

    @property
    def A_B(self) -> float:
        """Annulus (rod-side) area [m^2]."""
        return self.A_A - self.A_rod


class Cylinder(Component):
    """Double-acting differential cylinder with chambers A (cap) and B (rod) and end stops."""

    Params = CylinderParams
    modes = {"cavitated_A": 0.0, "cavitated_B": 0.0, "overrun": 0.0}
    ports = {"A": Hydraulic("cap-side chamber"), "B": Hydraulic("rod-side chamber"),
             "flange": Mechanical("the rod: position x from fully retracted")}

    def starts(self, p):
        return {"A.p": p.p0_A, "B.p": p.p0_B}

    def equations(self, v, p):
        x, p_A, p_B = v.flange.x, v.A.p, v.B.p
        V_A = v.observe("V_A", chamber_volume(p.V_dead_A, p.A_A, x, p.V_min), "m^3",
                        "cap-side volume")
        V_B = v.observe("V_B", chamber_volume(p.V_dead_B + p.A_B * p.stroke, -p.A_B, x,
                                              p.V_min), "m^3", "rod-side volume")
        q_leak = v.observe("q_leak", p.K_leak * (p_A - p_B), "m^3/s", "leakage A -> B")
        F = v.observe("F", p.A_A * p_A - p.A_B * p_B, "N", "pressure force on the load in +x")
        vel = v.observe("v", der(x), "m/s", "rod velocity")
        pen_hi = onset_penetration(x - p.stroke, p.eps_stop)
        pen_lo = onset_penetration(-x, p.eps_stop)
        c_hi = onset_indicator(x - p.stroke, p.eps_stop)
        c_lo = onset_indicator(-x, p.eps_stop)
        # each stop only pushes: its damping does not pull a rod that leaves it
        F_contact = (E.maximum(p.k_stop * pen_hi + p.d_stop * c_hi * vel, 0.0)
                     - E.maximum(p.k_stop * pen_lo - p.d_stop * c_lo * vel, 0.0))
        if p.l_cush > 0.0:
            F_contact = F_contact + p.d_cush * (_cushion_weight(x - p.stroke, p.l_cush)
                                                + _cushion_weight(-x, p.l_cush)) * vel
        v.observe("penetration", pen_hi - pen_lo, "m", "past the stroke (+) or before 0 (-)")
        F_stop = v.observe("F_stop", F_contact, "N",
                           "end-stop and cushion force (on the rod in -x)")
        cavitation_warning(v, p_A, p, "chamber A", "cavitated_A")
        cavitation_warning(v, p_B, p, "chamber B", "cavitated_B")
        _overrun_warning(v, x, p)
        return [chamber_continuity(V_A, p_A, v.A.q - q_leak, p.A_A, x, p),
                chamber_continuity(V_B, p_B, v.B.q + q_leak, -p.A_B, x, p),
                v.flange.f + F - F_stop]
