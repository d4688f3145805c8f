"""Lines and hoses: a lumped pi-line and a segmented (distributed) line built from it.

``PiLine``: a pipe or hose of length ``l`` and inner diameter ``d`` as one pi-section: half its
oil capacitance at each end, the inertance and friction of its whole length between. With the
bore area ``A = pi d^2 / 4``, the line volume ``V = A l`` and the through flow ``q`` from a to b
(an internal state)::

    V/2 * c(a.p) * der(a.p) = a.q - q            c = 1/beta_e (+ cavitation, fluid.py)
    V/2 * c(b.p) * der(b.p) = b.q + q
    rho l / A * der(q) = a.p - b.p - dp_f(q)

A hose is softer than steel: ``beta_wall`` adds the wall compliance, ``1/beta_line = 1/beta +
1/beta_wall`` (``beta_wall = E_wall t / d`` for a thin-walled pipe). Friction, with the mean
velocity ``w = q / A`` and ``Re = |w| d / nu``::

    dp_lam  = 32 rho nu l w / d^2                              (Hagen-Poiseuille)
    dp_turb = 0.158 rho l / d * (nu / d)^(1/4) * |w|^(7/4)     (Blasius, 0.316 Re^(-1/4))
    dp_f    = sign(w) * max(|dp_lam|, dp_turb)                 (smoothly)

The laminar and Blasius laws cross at Re = 1189; the max of the two is the usual continuous
stand-in for the transition (the friction factor is 64/Re below and Blasius above).
``friction="laminar"`` keeps only the first.

``segmented_line(n, ...)`` chains ``n`` pi-sections into a circuit with ports ``a`` and ``b``:
the halves of neighbouring capacitances meet at the inner nodes. A lossless chain carries waves
at ``c = sqrt(beta_line / rho)``; its lowest eigenfrequencies approach those of the continuous
line as ``n`` grows (a line closed at b and fed at a constant pressure at a: ``f1 = c / (4 l)``,
the wave reaching b after ``l / c``).
"""

from __future__ import annotations

import operator

import math
from typing import Literal

from pydantic import Field

from pvgraph.circuit import Circuit
from pvgraph.component import Component, Hydraulic, Variable, der
from pvgraph.laws import smooth_abs, smooth_max

from .fluid import FluidCompliance, cavitation_warning, compliance, nu_field, rho_field

__all__ = ["PiLine", "segmented_line", "line_friction"]


class PiLineParams(FluidCompliance):
    l: float = Field(..., gt=0.0, le=1e4, description="Length [m]")
    d: float = Field(..., gt=0.0, le=2.0, description="Inner diameter [m]")
    beta_wall: float | None = Field(None, gt=1e6, le=1e12,
                                    description="Wall (hose) stiffness [Pa]; None: rigid pipe")
    friction: Literal["laminar", "blended"] = Field(
        "blended", description="Friction law [-]: laminar, or laminar/Blasius blended")
    rho: float = rho_field()
    nu: float = nu_field()
    p0: float = Field(0.0, ge=-1e5, le=1e9, description="Initial pressure (gauge) [Pa]")

    @property
    def area(self) -> float:
        """Bore area [m^2]."""
        return math.pi * self.d ** 2 / 4.0

    @property
    def beta_line(self) -> float:
        """Bulk modulus including the wall compliance [Pa]."""
        if self.beta_wall is None:
            return self.beta
        return 1.0 / (1.0 / self.beta + 1.0 / self.beta_wall)

    @property
    def wave_speed(self) -> float:
        """Speed of pressure waves ``sqrt(beta_line / rho)`` [m/s]."""
        return math.sqrt(self.beta_line / self.rho)


def line_friction(q, p: PiLineParams):
    """Friction pressure drop along the line at the flow ``q`` [Pa]."""
    A, d, l = p.area, p.d, p.l
    w = q / A
    dp_lam = 32.0 * p.rho * p.nu * l * w / d ** 2
    if p.friction == "laminar":
        return dp_lam
    w_eps = 1e-3 * p.nu / d           # Re = 1e-3: rounds |w| at rest
    speed = smooth_abs(w, w_eps)
    dp_turb = 0.158 * p.rho * l / d * (p.nu / d) ** 0.25 * speed ** 1.75
    lam_abs = 32.0 * p.rho * p.nu * l * speed / d ** 2
    eps = 32.0 * p.rho * p.nu * l * (p.nu / d) / d ** 2   # the laminar drop at Re = 1
    return w / speed * smooth_max(lam_abs, dp_turb, eps)


class PiLine(Component):
    """Pipe or hose as one pi-section: end capacitances, inertance and friction.

    Steady friction drop, laminar (Hagen-Poiseuille): ``dp = 128 rho nu l q / (pi d^4)``;
    ``friction="blended"`` (the default) follows Blasius above Re ~ 1189. For a distributed
    line, ``segmented_line(n, l=..., d=...)`` chains ``n`` sections (ports ``a``, ``b``).
    """

    Params = PiLineParams
    ports = {"a": Hydraulic("end a"), "b": Hydraulic("end b")}
    variables = {"q": Variable("m^3/s", 0.0, 1e-4, "flow from a to b")}
    modes = {"cavitated_a": 0.0, "cavitated_b": 0.0}

    def starts(self, p):
        return {"a.p": p.p0, "b.p": p.p0}

    def equations(self, v, p):
        half = 0.5 * p.area * p.l
        wall = 0.0 if p.beta_wall is None else 1.0 / p.beta_wall
        c_a = compliance(v.a.p, p) + wall
        c_b = compliance(v.b.p, p) + wall
        cavitation_warning(v, v.a.p, p, "end a of the line", "cavitated_a")
        cavitation_warning(v, v.b.p, p, "end b of the line", "cavitated_b")
        dp_f = v.observe("dp_friction", line_friction(v.q, p), "Pa", "friction pressure drop")
        v.observe("w", v.q / p.area, "m/s", "mean velocity")
        v.observe("P_loss", v.q * dp_f, "W", "power lost to friction")
        return [half * c_a * der(v.a.p) - (v.a.q - v.q),
                half * c_b * der(v.b.p) - (v.b.q + v.q),
                p.rho * p.l / p.area * der(v.q) - (v.a.p - v.b.p - dp_f)]


def segmented_line(n: int, name: str = "line", **params) -> Circuit:
    """A line of ``n`` equal pi-sections (``l`` is the total length); ports ``a`` and ``b``."""
    try:
        count = operator.index(n)     # an int or a numpy integer; not a float, not a bool
    except TypeError:
        count = 0
    if isinstance(n, bool) or count < 1:
        from pvgraph.errors import ParameterError
        raise ParameterError(f"segmented_line: n = {n!r}: give the number of sections, a "
                             f"positive integer")
    n = count
    if "l" not in params:
        from pvgraph.errors import ParameterError
        raise ParameterError("segmented_line: give the total length l [m]")
    from pvgraph.errors import ParameterError
    from pvgraph.units import to_unit
    length = to_unit(params["l"], "m", "l")
    if not length > 0.0:
        raise ParameterError(f"segmented_line: the total length l must be positive, got "
                             f"{params['l']!r}")
    seg = dict(params, l=length / n)
    c = Circuit(name)
    parts = [c.add(f"s{k}", PiLine(**seg)) for k in range(n)]
    for left, right in zip(parts, parts[1:]):
        c.connect(left.b, right.a)
    c.expose("a", parts[0].a, "end a")
    c.expose("b", parts[-1].b, "end b")
    return c
