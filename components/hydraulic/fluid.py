"""The hydraulic fluid: one description shared by every hydraulic part.

Pressures in the library are gauge, relative to the atmospheric reference ``p_atm``; the
absolute pressure is ``p_abs = p + p_atm``. A fluid is described by

- ``rho`` density [kg/m^3] and ``nu`` kinematic viscosity [m^2/s] (restrictions, lines),
- ``beta`` bulk modulus of the pure oil [Pa] and ``air`` the entrained free-air volume fraction
  of the mixture at atmospheric pressure, compressed polytropically with exponent ``kappa``
  (volumes, lines); the gas is taken beside a chamber's volume ``V`` of oil, ``V_gas = air /
  (1 - air) V`` at atmospheric pressure (with ``air`` a fraction of the chamber, ``air V``,
  the air term would be ``1 - air`` of this: 1 % less at air = 0.01, 10 % at 0.1),
- ``p_vap`` the (absolute) vapour pressure [Pa], below which the oil cavitates.

Effective bulk modulus with free air (Merritt, *Hydraulic Control Systems*, 1967, eq. 2-12;
PVG 32 report figure A.8), normalised at atmospheric pressure::

    1/beta_e = 1/beta + (air / (1 - air)) * (p_atm / p_air)^(1/kappa) / (kappa * p_air)
    p_air = max(p_abs, p_min_abs)                     (smoothly)

Cavitation limit: near the vapour pressure the oil releases vapour and gas, so a chamber takes
up any outflow with a growing cavity instead of falling below ``p_vap``. The compliance gets a
term that grows without bound as ``p_abs -> p_vap`` and is exactly zero above
``p_vap + 10 dp_cav`` (0.32 bar absolute with the defaults; twice continuously differentiable
there)::

    V / beta_c(p) = V / beta_e(p) + V / beta * max(dp_cav / s - 1/10, 0)^3
    s = max(p_abs - p_vap, 1e-2 dp_cav)                (smoothly)

Drawing a volume ``dV`` out of a closed chamber of volume ``V`` lowers its pressure only to
about ``p_vap + dp_cav * sqrt(V * dp_cav / (2 * beta * dV))`` (about 40 Pa for 1 % of
its volume with the defaults). From about 2 % the compliance levels off at
``(100 - 1/10)^3 / beta`` (1.4e-3 /Pa): a cavity of half the chamber sits some 350 Pa lower,
around 0.016 bar absolute. The level is chosen so that the solver's pressure tolerance (a few
pascals) stands for a fraction of a cm^3 of oil in a cavitating chamber, so that a run's result
does not depend on its tolerance. The cavity takes the fraction ``void_fraction(p)`` of a
chamber's volume (the integral of the compliance, so ``d(void)/dp = -compliance``) and the oil
the rest: a chamber whose wall moves while it cavitates (a rod running ahead of its supply)
keeps its oil balance, as the run converges, to 0.0003 cm^3 of 333 (``chamber_continuity``).
The cavity is not a state of its own: it hangs on the pressure, which the solver resolves to
its tolerance, and the oil it stands for follows the pressure's errors: at the default rtol
1e-6, 0.45 cm^3 of 333 in the cylinder above, but about 50 cm^3 over 3.5 s of a
counterbalance valve's limit cycle that cavitates a third of the time (5 cm^3 at 1e-7);
where a chamber cavitates again and again, tighten rtol.

``Fluid`` is the description on its own; a hydraulic part's parameter model takes the fields it
uses under the same names, so ``Orifice(A=..., **oil.args_for(Orifice))`` applies one fluid
to any part. ``MINERAL_OIL`` holds the library defaults (ISO VG 32 mineral oil near 40 C).
"""

from __future__ import annotations

import math
import os
import warnings

from pydantic import Field, model_validator

from pvgraph import expr as E
from pvgraph.circuit import register_fluid_model
from pvgraph.component import Params
from pvgraph.errors import PlausibilityWarning, outside_stacklevel
from pvgraph.laws import smooth_max

__all__ = ["Fluid", "FluidCompliance", "MINERAL_OIL", "P_ATM", "RHO", "NU",
           "effective_bulk_modulus", "cavitation_compliance", "void_fraction",
           "cavitation_warning",
           "CavitationWarning", "rho_field", "nu_field"]

P_ATM = 101325.0   # [Pa] standard atmosphere, the gauge reference
RHO = 870.0        # [kg/m^3] mineral hydraulic oil near 40 C
NU = 3.2e-5        # [m^2/s] ISO VG 32 at 40 C (32 cSt; PVG 32 report eq. 4.25)
BETA = 7e8         # [Pa] pure oil, 7000 bar (PVG 32 report A.5)


def rho_field(**kw):
    """The density field every hydraulic part declares (one default for the library)."""
    return Field(RHO, gt=100.0, le=3000.0, description="Oil density [kg/m^3]", **kw)


def nu_field(**kw):
    """The kinematic viscosity field every hydraulic part declares."""
    return Field(NU, gt=0.0, le=1e-2, description="Kinematic viscosity [m^2/s]", **kw)


class FluidCompliance(Params):
    """Fluid fields of parts with a volume: bulk modulus, air, vapour pressure."""

    beta: float = Field(BETA, gt=1e6, le=1e11,
                        description="Bulk modulus of the oil [Pa] (7000 bar, report A.5)")
    air: float = Field(0.0, ge=0.0, le=0.2,
                       description="Entrained air volume fraction of the mixture at "
                                   "atmospheric pressure [-], the gas taken beside the "
                                   "chamber's volume of oil: air / (1 - air) of it (0: constant "
                                   "bulk modulus; report figure A.8)")
    kappa: float = Field(1.4, ge=1.0, le=1.4, description="Polytropic exponent of the air [-]")
    p_min_abs: float = Field(2e4, gt=0.0, description="Lower limit of the absolute pressure "
                                                      "used in the air term [Pa]")
    p_vap: float = Field(2e3, gt=0.0, le=9e4,
                         description="Vapour (cavitation) pressure, absolute [Pa]")
    dp_cav: float = Field(3e3, gt=0.0, le=5e4,
                          description="Width of the cavitation limit above p_vap [Pa]")
    p_atm: float = Field(P_ATM, gt=5e4, le=1.2e5,
                         description="Atmospheric reference of the gauge pressures [Pa]")

    @model_validator(mode="after")
    def _start_above_vapour(self):
        # a chamber started below the vapour pressure would start with a cavity larger than
        # itself (void fraction above 1, oil of negative volume)
        for name in type(self).model_fields:
            value = getattr(self, name)
            if name.startswith("p0") and isinstance(value, float) and \
                    value + self.p_atm < self.p_vap:
                raise ValueError(
                    f"{name} = {value:g} Pa (gauge) is below the vapour pressure "
                    f"({self.p_vap:g} Pa absolute, {self.p_vap - self.p_atm:g} Pa gauge): no "
                    f"oil holds there; start at or above it (a cavitated chamber: "
                    f"{name}={self.p_vap - self.p_atm:g})")
        return self


class Fluid(FluidCompliance):
    """A complete fluid description (density, viscosity, compressibility, vapour pressure)."""

    rho: float = rho_field()
    nu: float = nu_field()

    def __init__(self, **values):
        from pydantic import ValidationError

        from pvgraph.component import _describe_validation
        from pvgraph.errors import ParameterError
        try:
            super().__init__(**values)
        except ValidationError as exc:     # told as a part's parameters are
            raise ParameterError(_describe_validation(
                "Fluid", exc, list(type(self).model_fields), values, type(self))) from None

    def args_for(self, component_class) -> dict:
        """The fields of this fluid that ``component_class`` takes, as keyword arguments."""
        fields = component_class.Params.model_fields
        return {k: getattr(self, k) for k in type(self).model_fields if k in fields}

    @property
    def speed_of_sound(self) -> float:
        """Wave speed ``sqrt(beta / rho)`` of the pure oil [m/s]."""
        return (self.beta / self.rho) ** 0.5


register_fluid_model(Fluid)     # a circuit's fluid is checked by it (Circuit.use_fluid)


MINERAL_OIL = Fluid()


def _is_expr(x):
    return isinstance(x, E.Expr)


def effective_bulk_modulus(p, fp: FluidCompliance):
    """Effective bulk modulus at gauge pressure ``p`` (constant when ``air == 0``)."""
    if fp.air == 0.0:
        return E.const(fp.beta) if _is_expr(p) else fp.beta
    p_air = smooth_max(p + fp.p_atm, fp.p_min_abs, 0.1 * fp.p_min_abs)
    ratio = fp.air / (1.0 - fp.air)
    inv = 1.0 / fp.beta + ratio * (fp.p_atm / p_air) ** (1.0 / fp.kappa) / (fp.kappa * p_air)
    return 1.0 / inv


# the cavitation term's compliance levels off where the absolute pressure is this fraction of
# dp_cav above p_vap: (1/FLOOR - 1/10)^3 / beta, about 1.4e-3 /Pa for mineral oil. A void of
# half a chamber's volume then sits 350 Pa below that point. Much larger values (a floor of
# 1e-4 dp_cav: 1.4e3 /Pa) let a 1 Pa error of the pressure, well inside the solver's
# tolerance, stand for tens of cm^3 of oil: a cavitating chamber then swallowed a pump's
# flow at some tolerances and the rod never moved
CAVITATION_FLOOR = 1e-2
CAVITATION_ONSET = 10.0  # the cavitation term vanishes above p_vap + CAVITATION_ONSET * dp_cav


def cavitation_compliance(p, fp: FluidCompliance):
    """``1/beta * max(dp_cav/s - 1/10, 0)^3``: compliance per volume added near ``p_vap``,
    ``s`` the absolute pressure above ``p_vap``, levelled off below ``CAVITATION_FLOOR``."""
    return _cavitation(p, fp)[0]


def void_fraction(p, fp: FluidCompliance):
    """Fraction of a chamber's volume the cavity takes at gauge pressure ``p`` [-]: the
    integral of :func:`cavitation_compliance` from ``p`` up to where it vanishes, so that
    ``d(void_fraction)/dp = -cavitation_compliance`` exactly."""
    return _cavitation(p, fp)[1]


def _cavitation(p, fp: FluidCompliance):
    """``(compliance, void fraction)`` of the cavitation term at gauge pressure ``p``.

    With ``a = dp_cav``, ``b = 1/CAVITATION_ONSET`` and ``s = smooth_max(depth, f, f)`` the
    absolute pressure above ``p_vap`` (``depth``) levelled off at the floor ``f =
    CAVITATION_FLOOR * a``: the compliance is ``(a/s - b)^3 / beta``, the void fraction its
    integral from ``p`` up to the onset ``a/b`` (10 dp_cav, where both vanish, continuously).
    Integrated over ``s``, ``d depth = (1 + f^2 / (4 (s - f)^2)) ds``; with ``P(u) = -a^3/(2
    u^2) + 3 a^2 b/u + 3 a b^2 ln u - b^3 u`` (``P' = (a/u - b)^3``) and ``Q`` the integral of
    ``f^2 (a/u - b)^3 / (4 (u - f)^2)``, the void fraction is ``(P(s_S) - P(s) + Q(s_S) -
    Q(s)) / beta`` (``s_S``: s at the onset), exactly.
    """
    a = fp.dp_cav
    b = 1.0 / CAVITATION_ONSET
    f = CAVITATION_FLOOR * a
    depth = p + fp.p_atm - fp.p_vap
    expr = _is_expr(depth)
    log = E.log if expr else math.log
    s = smooth_max(depth, f, f)
    onset = a / b
    s_on = smooth_max(onset, f, f)

    def P(u):
        return -a * a * a / (2.0 * u * u) + 3.0 * a * a * b / u + 3.0 * a * b * b * log(u) \
            - b * b * b * u

    def Q(u):
        k = a - b * f
        return f * f * (6.0 * a * u * u * k * k * (f - u) * (log(u) - log(u - f))
                        + f * (-a * a * a * f * f - 3.0 * a * a * f * u * (a - 2.0 * b * f)
                               + 2.0 * u * u * (3.0 * a * k * k - b * b * b * f * f * f))) \
            / (8.0 * f ** 4 * u * u * (f - u))
    r = a / s - b
    compliance_ = r * r * r / fp.beta
    void = (P(s_on) - P(s) + Q(s_on) - Q(s)) / fp.beta
    near = depth < onset
    if expr:
        return E.where(near, compliance_, 0.0), E.where(near, void, 0.0)
    return (compliance_, void) if near else (0.0, 0.0)


def compliance(p, fp: FluidCompliance):
    """``1/beta_e(p)`` plus the cavitation term [1/Pa]: ``V * compliance * der(p) = q``."""
    return 1.0 / effective_bulk_modulus(p, fp) + cavitation_compliance(p, fp)


#: the component library's folder: warnings point past it, at the user's call
LIBRARY = (os.path.dirname(os.path.dirname(os.path.abspath(__file__))),)


class CavitationWarning(PlausibilityWarning):
    """A chamber reached the vapour pressure: the oil cavitates there."""


def cavitation_warning(v, p, fp: FluidCompliance, what: str, mode: str = "cavitated"):
    """Declare the events of a chamber's cavity at gauge pressure ``p``.

    Components using it declare the discrete mode ``mode``: 0 before the first cavity, 1 while
    a cavity is open, 2 after it closed, 3 closed without a warning yet (a chamber that
    started inside the cavity and left it). The event ``cavity`` (``cavity_A`` for the mode
    ``cavitated_A``) opens the cavity where the absolute pressure falls to ``p_vap + dp_cav``
    and closes it where it rises again past ``p_vap + 2 dp_cav`` (a band, so that a pressure
    resting at the threshold does not switch at every wiggle): the solver restarts at each
    (order 1, a fresh iteration matrix), where the compliance changes by orders of magnitude.
    With the matrix of the other side, Newton took points that do not satisfy the chamber's
    equation: oil made from nothing as the column rejoins, 400 bar from 33. The event
    ``cavitation`` warns, once, naming the chamber (``v``'s component path).
    """
    path = v._prefix
    state = v.mode(mode)
    p_abs = p + fp.p_atm - fp.p_vap
    is_open = E.where(state > 0.5, 1.0, 0.0) * E.where(state < 1.5, 1.0, 0.0)
    edge = E.where(is_open > 0.5, p_abs - 2.0 * fp.dp_cav, p_abs - fp.dp_cav)
    v.event("cavity" + mode[len("cavitated"):], edge, direction=0, action=_toggle(mode))
    unwarned = E.where(state < 0.5, 1.0, 0.0) + E.where(state > 2.5, 1.0, 0.0)
    condition = E.where(unwarned > 0.5, p_abs - fp.dp_cav, 1.0)

    # p_vap is a runtime parameter symbol while tracing: name it rather than freeze a number
    vapour = (f"{fp.p_vap:g} Pa absolute" if isinstance(fp.p_vap, (int, float))
              else "the fluid's p_vap")

    def action(modes):
        modes[mode] = 1.0
        t = getattr(modes, "t", None)
        when = f" at t = {t:.6g} s" if t is not None else ""
        warnings.warn(CavitationWarning(
            f"{path}: the pressure in {what} falls to the vapour pressure ({vapour}){when}: "
            f"the oil cavitates there. Check the flow out of it (a load running "
            f"ahead of its supply, a motor overrunning) or add a make-up (anti-cavitation) "
            f"check valve from tank."), stacklevel=outside_stacklevel(LIBRARY))
    v.event("cavitation", condition, direction=-1, action=action)


def _toggle(mode):
    """The action of a cavity's edge: closed (2) from open (1); open from closed (2, 3);
    from before any cavity (0) "closed, not warned" (3), which the warning's action (at a
    first opening, the same instant: it is declared after this one) makes open (1)."""
    def act(modes):
        state = modes[mode]
        modes[mode] = 2.0 if state == 1.0 else (3.0 if state == 0.0 else 1.0)
    act.__name__ = f"toggle_{mode}"
    return act
