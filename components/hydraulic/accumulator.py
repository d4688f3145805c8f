"""Gas-charged (bladder or piston) accumulator with polytropic gas and bladder bottoming.

Port ``port`` (oil). The gas of volume ``V0`` is precharged to ``p_pre`` (gauge) with the oil
side empty, and compressed polytropically with exponent ``n`` (1: isothermal, slow cycles; 1.4:
adiabatic nitrogen, fast cycles). Above the precharge the oil volume against the gas is::

    V_oil(p) = V0 * (1 - ((p_pre + p_atm) / (p + p_atm))^(1/n))

Below the precharge the bladder is bottomed on the poppet: only the oil in ``V_dead`` is left,
so the port pressure follows ``beta / V_dead`` per volume drawn. The oil stored is one
function of the port pressure, and its rate is the port flow (positive into it)::

    V_stored(p) = V_oil(p_g) + V_dead / beta * (p - p_pre),    der(V_stored) = port.q

with the gas pressure ``p_g = p`` above ``p_pre + dp_b`` and ``p_g = p_pre`` below ``p_pre``,
joined C2 in between (``p_g = p_pre + dp_b F(u)``, ``u = (p - p_pre) / dp_b``,
``F = 6u^3 - 8u^4 + 3u^5``: F(0) = F'(0) = 0, F(1) = F'(1) = 1, F'(u) > 0), ``dp_b = 1e-3
(p_pre + p_atm)``. One state, so the gas volume and the port pressure cannot drift apart:
above ``p_pre + dp_b`` the port pressure is the gas pressure exactly.

Observed: ``p_gas``, ``V_oil``, ``V_gas``, ``V_stored`` and the energy stored in the gas
relative to the precharge state, ``E_gas = (p_gas_abs V_gas - p_pre_abs V0) / (n - 1)``
(``p_abs V ln(V0 / V_gas)`` for ``n = 1``).
"""

from __future__ import annotations

from pydantic import Field, model_validator

from pvgraph import expr as E
from pvgraph.component import Component, Hydraulic, Params, der

from .fluid import BETA, P_ATM

__all__ = ["GasAccumulator"]


class GasAccumulatorParams(Params):
    V0: float = Field(..., gt=0.0, le=1.0, description="Gas volume at precharge (size) [m^3]")
    p_pre: float = Field(..., gt=0.0, le=1e8, description="Precharge pressure (gauge) [Pa]")
    n: float = Field(1.4, ge=1.0, le=1.67,
                     description="Polytropic exponent of the gas [-] (1: isothermal, 1.4: "
                                 "adiabatic nitrogen)")
    V_dead: float = Field(1e-6, gt=0.0, le=1e-2,
                          description="Oil volume at the port when bottomed [m^3]")
    beta: float = Field(BETA, gt=1e6, le=1e11, description="Bulk modulus of the oil [Pa]")
    p_atm: float = Field(P_ATM, gt=5e4, le=1.2e5,
                         description="Atmospheric reference of the gauge pressures [Pa]")
    p0: float | None = Field(None, ge=-1e5, le=1e9,
                             description="Initial port pressure (gauge) [Pa]; default p_pre "
                                         "(empty)")

    @model_validator(mode="after")
    def _start(self):
        if self.p0 is not None and self.p0 > 1e3 * (self.p_pre + self.p_atm):
            raise ValueError("p0 is beyond the compression range of the gas")
        return self

    @property
    def start_pressure(self) -> float:
        """Initial port pressure: ``p0``, or the precharge."""
        return self.p_pre if self.p0 is None else self.p0

    def oil_volume(self, p: float) -> float:
        """Oil volume at the gauge port pressure ``p`` above the precharge [m^3]."""
        if p <= self.p_pre:
            return 0.0
        return self.V0 * (1.0 - ((self.p_pre + self.p_atm) / (p + self.p_atm)) ** (1.0 / self.n))


class GasAccumulator(Component):
    """Gas-charged accumulator: polytropic gas, precharge, bottoming (``der(V_stored) = port.q``).

    Above the precharge ``(p + p_atm) (V0 - V_oil)^n = (p_pre + p_atm) V0^n`` (gauge ``p``;
    ``n = 1`` isothermal, 1.4 adiabatic), exactly for the observed ``p_gas`` and, above
    ``p_pre + dp_b``, for the port pressure (``dp_b = 1e-3 (p_pre + p_atm)``, the band over which
    bottoming is smoothed).
    """

    Params = GasAccumulatorParams
    ports = {"port": Hydraulic("oil connection")}

    def starts(self, p):
        return {"port.p": p.start_pressure}

    def equations(self, v, p):
        p_pre_abs = p.p_pre + p.p_atm
        band = 1e-3 * p_pre_abs
        u = E.clip((v.port.p - p.p_pre) / band, 0.0, 1.0)
        p_g = E.where(v.port.p - p.p_pre >= band, v.port.p,
                      p.p_pre + band * (u * u * u * (6.0 + u * (-8.0 + 3.0 * u))))
        p_gas_abs = p_g + p.p_atm
        V_oil = v.observe("V_oil", p.V0 * (1.0 - (p_pre_abs / p_gas_abs) ** (1.0 / p.n)), "m^3",
                          "oil volume against the gas")
        V_stored = v.observe("V_stored", V_oil + p.V_dead / p.beta * (v.port.p - p.p_pre),
                             "m^3", "oil stored: against the gas and compressed in V_dead")
        V_gas = v.observe("V_gas", p.V0 - V_oil, "m^3", "gas volume")
        v.observe("p_gas", p_g, "Pa", "gas pressure (gauge)")
        if p.n == 1.0:
            energy = p_pre_abs * p.V0 * E.log(p.V0 / V_gas)
        else:
            energy = (p_gas_abs * V_gas - p_pre_abs * p.V0) / (p.n - 1.0)
        v.observe("E_gas", energy, "J", "energy stored in the gas since precharge")
        return [der(V_stored) - v.port.q]
