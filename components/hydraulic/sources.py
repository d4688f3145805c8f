"""Hydraulic boundary conditions: tank, pressure source, flow source, pump, plug.

Equations (port flow ``q`` positive into the component):

- ``Tank``, ``PressureSource``: ``port.p = p0`` (a reservoir; takes or gives any flow).
- ``FlowSource``: ``port.q = -Q(t)`` (injects ``Q`` into the node it is connected to).
- ``Pump``: fixed displacement, ``b.q = -Q(t)``, ``a.q = Q(t)`` (draws from ``a``, delivers to
  ``b``); the flow is ``Q0`` or a table in time. Report section 4.6: the rig's pump delivers
  about 16.3-17 L/min (tuned 16.3 L/min, table 4.14).
- ``Plug``: ``port.q = 0`` (a closed port).
"""

from __future__ import annotations

from pydantic import Field, model_validator

from pvgraph.component import Component, Hydraulic, Params, SignalIn, check_table
from pvgraph import expr as E

from .fluid import P_ATM


class TankParams(Params):
    p0: float = Field(0.0, ge=-1e5, le=1e9,
                      description="Tank (gauge) pressure [Pa]; 0 is atmospheric")

    @model_validator(mode="after")
    def _one_atmosphere_gauge(self):
        # "1 atm", "1 bar", "14.7 psi", "101325 Pa": an atmosphere written absolute, most
        # likely (2 % of one atmosphere holds them all)
        if abs(self.p0 - P_ATM) <= 0.02 * P_ATM:
            import warnings

            from pvgraph.errors import PlausibilityWarning, outside_stacklevel

            from .fluid import LIBRARY
            warnings.warn(PlausibilityWarning(
                f"p0 = {self.p0:g} Pa is about one atmosphere above the atmosphere here: "
                f"pressures in the library are gauge (0 = atmospheric, the absolute pressure "
                f"is p + p_atm). An open reservoir is p0 = 0 (the default); a reservoir "
                f"pressurised to about 1 bar gauge is as written."),
                stacklevel=outside_stacklevel(LIBRARY))
        return self


class Tank(Component):
    """Reservoir at constant pressure ``p0``; ``port.p = p0``."""

    Params = TankParams
    ports = {"port": Hydraulic("connection to the reservoir")}

    def equations(self, v, p):
        return [v.port.p - p.p0]


class PressureSource(Tank):
    """Ideal pressure source ``port.p = p0`` (same law as :class:`Tank`)."""


class PressureInput(Component):
    """Pressure source driven by a signal: ``port.p = u`` [Pa]."""

    ports = {"port": Hydraulic("pressurised node"), "u": SignalIn("pressure set point", "Pa",
                                                                   1e6)}

    def equations(self, v, p):
        return [v.port.p - v.u]


class FlowSourceParams(Params):
    Q: float = Field(..., ge=-1.0, le=1.0, description="Flow delivered into the node [m^3/s]")


class FlowSource(Component):
    """Ideal flow source: delivers ``Q`` into the node, ``port.q = -Q``."""

    Params = FlowSourceParams
    ports = {"port": Hydraulic("node fed by the source")}

    def equations(self, v, p):
        v.observe("Q", E.const(p.Q), "m^3/s", "delivered flow")
        return [v.port.q + p.Q]


class FlowInput(Component):
    """Flow source driven by a signal: delivers ``u`` [m^3/s] into the node."""

    ports = {"port": Hydraulic("node fed by the source"),
             "u": SignalIn("flow set point", "m^3/s", 1e-4)}

    def equations(self, v, p):
        return [v.port.q + v.u]


class PumpParams(Params):
    Q0: float = Field(..., ge=0.0, le=1.0,
                      description="Delivered flow [m^3/s] (rig: 16.3 L/min, report table 4.14)")
    t_table: tuple[float, ...] | None = Field(
        None, description="Times of a flow table [s] (optional; overrides Q0)")
    Q_table: tuple[float, ...] | None = Field(
        None, description="Flows of the table [m^3/s], same length as t_table")

    @model_validator(mode="after")
    def _table_shape(self):
        if (self.t_table is None) != (self.Q_table is None):
            raise ValueError("t_table and Q_table must be given together")
        if self.t_table is not None:
            check_table(self.t_table, self.Q_table, "t_table", "Q_table", y_range=(0.0, 1.0))
        return self


class Pump(Component):
    """Fixed-displacement pump: draws ``Q`` from ``a`` and delivers it into ``b``.

    ``a.q = Q``, ``b.q = -Q``, with ``Q = Q0`` or ``Q = table(t)`` (linear interpolation,
    held at the ends). Observed: ``Q`` [m^3/s] and hydraulic power ``P = Q*(b.p - a.p)`` [W].
    """

    Params = PumpParams
    ports = {"a": Hydraulic("suction"), "b": Hydraulic("delivery")}

    def equations(self, v, p):
        if p.t_table is not None:
            Q = E.interp(E.Table(p.t_table, p.Q_table, method="linear", name="pump flow"), v.t)
        else:
            Q = E.const(p.Q0)
        v.observe("Q", Q, "m^3/s", "delivered flow")
        v.observe("P", Q * (v.b.p - v.a.p), "W", "hydraulic power delivered")
        return [v.a.q - Q, v.b.q + Q]


class Plug(Component):
    """A closed hydraulic port: ``port.q = 0``."""

    ports = {"port": Hydraulic("closed port")}

    def equations(self, v, p):
        return [v.port.q]
