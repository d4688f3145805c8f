"""Double-acting cylinder: two piston chambers on one rod (for load networks).

Ports ``A`` (cap-side chamber), ``B`` (rod-side chamber) and ``flange`` (the rod; ``x = 0``
fully retracted, ``x = stroke`` fully extended). With the annulus area ``A_B = A_A - A_rod``::

    V_A = V_dead_A + A_A * x
    V_B = V_dead_B + A_B * (stroke - x)
    V_A / beta(p_A) * der(p_A) = A.q - A_A * der(x) - q_leak
    V_B / beta(p_B) * der(p_B) = B.q + A_B * der(x) + q_leak
    q_leak = K_leak * (p_A - p_B)
    flange.f = -(A_A * p_A - A_B * p_B)

This is the chamber continuity of report appendix A.5 (eq. A.7) applied to each side, as the
report does for the spool chambers (eqs. 4.14, 4.93-4.94). Sign convention: port flows are
positive into the cylinder; ``flange.f`` is the force the mechanical node exerts on the cylinder
in +x, so the rod pushes its load with ``F = A_A p_A - A_B p_B`` in +x (observed as ``F``).
There are no end stops: add a mechanical stop to the load if the rod can reach them (the
volumes are only kept positive, smoothly, at ``V_min``).
"""

from __future__ import annotations

from pydantic import Field, model_validator

from pvgraph.component import Component, Hydraulic, Mechanical, der

from .volumes import FluidCompliance, chamber_continuity, chamber_volume


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

    @model_validator(mode="after")
    def _geometry(self):
        if self.A_rod >= self.A_A:
            raise ValueError(f"A_rod ({self.A_rod!r}) must be smaller than A_A ({self.A_A!r})")
        if min(self.V_dead_A, self.V_dead_B) <= 10.0 * self.V_min:
            raise ValueError("V_dead_A and V_dead_B must be well above V_min")
        return self

    @property
    def A_B(self) -> float:
        """Annulus (rod-side) area [m^2]."""
        return self.A_A - self.A_rod


class Cylinder(Component):
    """Double-acting differential cylinder with chambers A (cap) and B (rod)."""

    Params = CylinderParams
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
        F = v.observe("F", p.A_A * p_A - p.A_B * p_B, "N", "force on the load in +x")
        v.observe("v", der(x), "m/s", "rod velocity")
        return [chamber_continuity(V_A, p_A, v.A.q - q_leak, p.A_A, x, p),
                chamber_continuity(V_B, p_B, v.B.q + q_leak, -p.A_B, x, p),
                v.flange.f + F]
