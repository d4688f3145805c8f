"""Transmissions between translation and rotation (rack and pinion), between two translations
(lever) and between two shafts (gear).

``RackPinion``: ports ``flange`` (the rack, x [m], f [N]) and ``shaft`` (the pinion, phi [rad],
tau [N m]), pinion radius ``r``. Ideal (``k`` None), it is the holonomic constraint and the
power balance::

    flange.x = r * shaft.phi,     shaft.tau = -r * flange.f        (f v + tau w = 0)

With a mesh stiffness ``k`` (and damping ``d``) the teeth deflect instead, so both sides may
carry inertia (an ideal constraint between two inertias is a DAE of index two)::

    F = k (flange.x - r shaft.phi) + d (der(flange.x) - r der(shaft.phi))
    flange.f = F,   shaft.tau = -r F

``Lever``: ports ``a`` and ``b`` (translational), ratio ``i = x_b / x_a``::

    b.x = i * a.x,   a.f = -i * b.f          (ideal)
    F = k (b.x - i a.x) + d der(b.x - i a.x),   b.f = F,   a.f = -i F   (compliant)

``Gear``: shafts ``a`` (input) and ``b`` (output), ratio ``i = w_a / w_b`` (Modelica's
``IdealGear`` convention: i > 1 reduces the speed and multiplies the torque), efficiency ``eta``
of the mesh, a loss whichever way the power flows::

    a.phi = i * b.phi,   b.tau = -i * e * a.tau          (ideal teeth)
    T = k (a.phi - i b.phi) + d der(a.phi - i b.phi),   a.tau = T,   b.tau = -i e T  (compliant)
    e = eta ** tanh(P_a / P_eps),      P_a = a.tau * der(a.phi)  (the power into the gear at a)

so e = eta while power flows from a to b, e = 1 / eta while it flows from b to a (an
overrunning load driving the input back), and e = 1 at rest: the power leaving is at most the
power entering, eta times it beyond P_eps, in both directions (a winch lowering its load
through the gearbox heats the gearbox as much as one lifting it), and a gear at rest passes
the ideal torque. ``eta = 1`` is the lossless gear, ``b.tau = -i a.tau``. Self-locking (a worm
gear holding its load) is not modelled.
"""

from __future__ import annotations

from pydantic import Field, field_validator, model_validator

from pvgraph import expr as E
from pvgraph.component import Component, Mechanical, Params, der
from pvgraph.laws import smooth_sign

from .rotational import Rotational

__all__ = ["RackPinion", "Lever", "Gear"]


def _damping_needs_stiffness(params):
    """A mesh damping acts across the mesh's compliance: without a stiffness there is none."""
    if params.k is None and params.d != 0.0:
        raise ValueError(f"d = {params.d!r} damps the mesh's deflection, but k is None (rigid): "
                         f"give k, or leave d at 0")
    return params


class RackPinionParams(Params):
    r: float = Field(..., gt=0.0, le=10.0, description="Pinion pitch radius [m]")
    k: float | None = Field(None, gt=0.0, le=1e12,
                            description="Mesh stiffness [N/m]; None: ideal, rigid teeth")
    d: float = Field(0.0, ge=0.0, le=1e9, description="Mesh damping [N s/m] (with k)")

    @model_validator(mode="after")
    def _mesh(self):
        return _damping_needs_stiffness(self)


class RackPinion(Component):
    """Rack and pinion: ``x = r phi`` and ``tau = -r f`` (ideal, or through a mesh stiffness)."""

    Params = RackPinionParams
    ports = {"flange": Mechanical("the rack"), "shaft": Rotational("the pinion")}

    def equations(self, v, p):
        if p.k is None:
            return [v.flange.x - p.r * v.shaft.phi, v.shaft.tau + p.r * v.flange.f]
        gap = v.flange.x - p.r * v.shaft.phi
        F = v.observe("F", p.k * gap + p.d * der(gap), "N", "mesh force")
        return [v.flange.f - F, v.shaft.tau + p.r * F]


class LeverParams(Params):
    i: float = Field(..., ge=-100.0, le=100.0, description="Ratio x_b / x_a [-]")

    @field_validator("i")
    @classmethod
    def _nonzero(cls, value):
        if value == 0.0:
            raise ValueError("the ratio i must not be 0 (b would be held and a free)")
        return value
    k: float | None = Field(None, gt=0.0, le=1e12,
                            description="Stiffness at b [N/m]; None: ideal, rigid lever")
    d: float = Field(0.0, ge=0.0, le=1e9, description="Damping at b [N s/m] (with k)")

    @model_validator(mode="after")
    def _mesh(self):
        return _damping_needs_stiffness(self)


class Lever(Component):
    """Lever between two translational flanges: ``b.x = i a.x``, ``a.f = -i b.f``."""

    Params = LeverParams
    ports = {"a": Mechanical("input end"), "b": Mechanical("output end")}

    def equations(self, v, p):
        if p.k is None:
            return [v.b.x - p.i * v.a.x, v.a.f + p.i * v.b.f]
        gap = v.b.x - p.i * v.a.x
        F = v.observe("F", p.k * gap + p.d * der(gap), "N", "force at b")
        return [v.b.f - F, v.a.f + p.i * F]


class GearParams(Params):
    i: float = Field(..., ge=-1000.0, le=1000.0,
                     description="Ratio w_a / w_b [-] (i > 1: b turns slower with more torque); "
                                 "negative reverses the direction")
    eta: float = Field(1.0, gt=0.0, le=1.0,
                       description="Mesh efficiency [-], in both directions of the power flow")
    P_eps: float = Field(1.0, gt=0.0, le=1e6,
                         description="Power over which the loss changes sides when the power "
                                     "flow reverses [W] (with eta < 1)")
    k: float | None = Field(None, gt=0.0, le=1e12,
                            description="Torsional mesh stiffness at a [N m/rad]; None: ideal, "
                                        "rigid teeth")
    d: float = Field(0.0, ge=0.0, le=1e9, description="Mesh damping at a [N m s/rad] (with k)")

    @field_validator("i")
    @classmethod
    def _nonzero(cls, value):
        if value == 0.0:
            raise ValueError("the ratio i must not be 0 (b could not turn)")
        return value

    @model_validator(mode="after")
    def _mesh(self):
        return _damping_needs_stiffness(self)


class Gear(Component):
    """Gearbox between two shafts: ``a.phi = i b.phi``, ``b.tau = -i e a.tau`` with the loss
    ``e`` = eta or 1/eta by the direction of the power flow (module docstring)."""

    Params = GearParams
    ports = {"a": Rotational("input shaft"), "b": Rotational("output shaft")}

    def equations(self, v, p):
        if p.k is None:
            T = v.a.tau
            rows = [v.a.phi - p.i * v.b.phi]
        else:
            twist = v.a.phi - p.i * v.b.phi
            T = v.observe("T", p.k * twist + p.d * der(twist), "N m", "mesh torque at a")
            rows = [v.a.tau - T]
        e = 1.0
        if p.eta < 1.0:
            P_a = v.observe("P_a", T * der(v.a.phi), "W", "power into the gear at a")
            # eta^s with s in [-1, 1] of the power's sign: a loss whichever way, none at rest
            e = E.exp(smooth_sign(P_a, p.P_eps) * E.log(p.eta))
        return rows + [v.b.tau + p.i * e * T]
