"""Volume nodes: the compliance of oil in a fixed volume (report appendix A.5).

``VolumeNode``, one port, many components connect to it::

    V / beta(p) * der(port.p) = port.q

``beta`` is the effective bulk modulus: constant (7000 bar, report A.5) or, with an entrained
air fraction ``air`` > 0, the pressure-dependent effective modulus of oil with free air
(report figure A.8; the usual mixture law, e.g. Merritt, Hydraulic Control Systems, 1967)::

    1/beta_e = 1/beta + (air / (1 - air)) * (p_atm / p_abs)^(1/kappa) / (kappa * p_abs)

normalised at atmospheric pressure, with ``p_abs = p + p_atm`` (gauge ``p``), smoothly limited
from below at ``p_min_abs``.
"""

from __future__ import annotations

from pydantic import Field

from pvgraph import expr as E
from pvgraph.component import Component, Hydraulic, Params, der
from pvgraph.laws import smooth_max

P_ATM = 101325.0


class FluidCompliance(Params):
    """Shared fluid parameters of components with a volume."""

    beta: float = Field(7e8, gt=1e6, le=1e11,
                        description="Bulk modulus of the oil [Pa] (7000 bar, report A.5)")
    air: float = Field(0.0, ge=0.0, le=0.2,
                       description="Entrained air volume fraction at atmospheric pressure [-] "
                                   "(0: constant bulk modulus; report figure A.8)")
    kappa: float = Field(1.4, ge=1.0, le=1.4, description="Polytropic exponent of the air [-]")
    p_min_abs: float = Field(2e4, gt=0.0, description="Lower limit of the absolute pressure "
                                                      "used in the air term [Pa]")


def effective_bulk_modulus(p, fp: FluidCompliance):
    """Effective bulk modulus at gauge pressure ``p`` (constant when ``air == 0``)."""
    if fp.air == 0.0:
        return E.const(fp.beta) if isinstance(p, E.Expr) else fp.beta
    p_abs = smooth_max(p + P_ATM, fp.p_min_abs, 0.1 * fp.p_min_abs)
    ratio = fp.air / (1.0 - fp.air)
    inv = 1.0 / fp.beta + ratio * (P_ATM / p_abs) ** (1.0 / fp.kappa) / (fp.kappa * p_abs)
    return 1.0 / inv


class VolumeNodeParams(FluidCompliance):
    V: float = Field(..., gt=0.0, le=10.0, description="Volume [m^3]")
    p0: float = Field(0.0, ge=-1e5, le=1e9, description="Initial (gauge) pressure [Pa]")


class VolumeNode(Component):
    """Fixed volume of compressible oil: ``V/beta * der(p) = q``."""

    Params = VolumeNodeParams
    ports = {"port": Hydraulic("the node")}

    def starts(self, p):
        return {"port.p": p.p0}

    def equations(self, v, p):
        beta = effective_bulk_modulus(v.port.p, p)
        return [p.V / beta * der(v.port.p) - v.port.q]
