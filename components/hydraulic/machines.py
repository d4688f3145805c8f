"""Pumps and motors with shafts: fixed and variable displacement, pressure-compensated and
load-sensing pumps, with volumetric and hydromechanical efficiencies.

Displacement ``D`` [m^3/rad] (``D = V_g / (2 pi)`` for a geometric volume ``V_g`` per
revolution); shaft speed ``w = der(shaft.phi)`` [rad/s]; ``shaft.tau`` is the torque the shaft
node exerts on the machine (positive into it). Losses are specified by the efficiencies at the
rated point (speed ``w_nom``, pressure rise or drop ``dp_nom``) and modelled as a laminar
leakage ``K dp`` and a friction torque proportional to the pressure, so they are exact at the
rated point and scale physically away from it.

Pump (ports ``a`` suction, ``b`` delivery), displacement fraction ``eps`` in [0, 1],
``dp = b.p - a.p``::

    q   = eps D w - K dp,            K = (1 - eta_v) D w_nom / dp_nom
    T   = eps D dp + (1/eta_hm - 1) eps D |dp| tanh(w / w_eps)
    a.q = q,  b.q = -q,  shaft.tau = T            (the pump absorbs T)

so at the rated point ``q = eta_v D w`` and ``T = D dp / eta_hm``. Motor (ports ``A`` inlet,
``B`` outlet), ``dp = A.p - B.p``::

    q   = D w + K dp,                K = (1/eta_v - 1) D w_nom / dp_nom
    T   = D dp - (1 - eta_hm) D |dp| tanh(w / w_eps)
    A.q = q,  B.q = -q,  shaft.tau = -T           (the motor drives the shaft with T)

so ``D w = eta_v q`` and ``T = eta_hm D dp`` at the rated point. ``|dp|`` is rounded within
``dp_eps``. In every case the power lost, ``K dp^2 + friction * |w|``, is never negative.

Displacement control:

- ``FixedDisplacementPump``: ``eps = 1``.
- ``VariableDisplacementPump``: ``eps = clip(u)`` from a signal.
- ``PressureCompensatedPump``: the compensator destrokes the pump as the delivery pressure
  nears the setting ``p_c``, with the first-order response ``tau`` of the swash plate::

      tau der(eps) = 1 - ramp(b.p; p_c - dp_reg, dp_reg) - eps

- ``LoadSensingPump``: as well, the LS compensator holds the delivery a margin ``dp_ls``
  above the pressure at the ``LS`` port (which takes no flow)::

      tau der(eps) = (1 - ramp(b.p - LS.p; dp_ls - dp_reg, dp_reg))
                     * (1 - ramp(b.p; p_c - dp_reg, dp_reg)) - eps

``ramp(u; u0, du)`` is the C1 smoothstep from 0 at ``u0`` to 1 at ``u0 + du``: at a steady
state below full stroke the margin lies within ``[dp_ls - dp_reg, dp_ls]``.
"""

from __future__ import annotations

from pydantic import Field

from pvgraph import expr as E
from pvgraph.component import Component, Hydraulic, Params, SignalIn, Variable, der
from pvgraph.laws import smooth_abs, smooth_sign

from ..mechanical.rotational import Rotational
from .check_valve import smoothstep_ramp

__all__ = ["FixedDisplacementPump", "VariableDisplacementPump", "PressureCompensatedPump",
           "LoadSensingPump", "HydraulicMotor"]


class MachineParams(Params):
    D: float = Field(..., gt=0.0, le=1e-2,
                     description="Displacement [m^3/rad] (V_g / 2 pi; per revolution give the "
                                 "unit: '28 cm^3/rev')")
    eta_v: float = Field(0.95, gt=0.5, le=1.0,
                         description="Volumetric efficiency at the rated point [-]")
    eta_hm: float = Field(0.92, gt=0.5, le=1.0,
                          description="Hydromechanical efficiency at the rated point [-]")
    w_nom: float = Field(157.08, gt=0.0, le=2e3,
                         description="Rated speed [rad/s] (157 rad/s = 1500 rpm)")
    dp_nom: float = Field(2e7, gt=0.0, le=1e8, description="Rated pressure difference [Pa]")
    w_eps: float = Field(0.1, gt=0.0, le=10.0,
                         description="Speed below which the friction torque fades [rad/s]")
    dp_eps: float = Field(1e4, gt=0.0, le=1e6, description="Rounding of |dp| [Pa]")


def _pump(v, p, eps):
    """Residuals and observed outputs of a pump at displacement fraction ``eps``."""
    dp = v.observe("dp", v.b.p - v.a.p, "Pa", "pressure rise b - a")
    w = v.observe("w", der(v.shaft.phi), "rad/s", "shaft speed")
    K = (1.0 - p.eta_v) * p.D * p.w_nom / p.dp_nom
    q = v.observe("q", eps * p.D * w - K * dp, "m^3/s", "delivered flow")
    T = v.observe("T", eps * p.D * dp + (1.0 / p.eta_hm - 1.0) * eps * p.D
                  * smooth_abs(dp, p.dp_eps) * smooth_sign(w, p.w_eps), "N m", "shaft torque")
    v.observe("P_shaft", T * w, "W", "mechanical power in")
    v.observe("P_hyd", q * dp, "W", "hydraulic power out")
    return [v.a.q - q, v.a.q + v.b.q, v.shaft.tau - T]


PUMP_PORTS = {"a": Hydraulic("suction"), "b": Hydraulic("delivery"),
              "shaft": Rotational("drive shaft")}


class FixedDisplacementPump(Component):
    """Fixed-displacement pump driven by its shaft: ``q = D w - K dp``.

    ``K = (1 - eta_v) D w_nom / dp_nom``, shaft torque
    ``T = D dp + (1/eta_hm - 1) D |dp| tanh(w / w_eps)``: at the rated point (``w_nom``,
    ``dp_nom``) ``q = eta_v D w`` and ``T = D dp / eta_hm``; the leakage is proportional to
    ``dp``. ``w = der(shaft.phi)``; drive it with a ``SpeedSource`` (``w0="1500 rpm"``).
    """

    Params = MachineParams
    ports = PUMP_PORTS

    def equations(self, v, p):
        return _pump(v, p, 1.0)


class VariableDisplacementPump(Component):
    """Variable-displacement pump; the displacement fraction comes from the signal ``u``."""

    Params = MachineParams
    ports = {**PUMP_PORTS, "u": SignalIn("displacement fraction (clipped to [0, 1])")}

    def equations(self, v, p):
        return _pump(v, p, E.clip(v.u, 0.0, 1.0))


class PressureCompensatedParams(MachineParams):
    p_c: float = Field(..., gt=0.0, le=1e8, description="Compensator (cut-off) setting [Pa]")
    dp_reg: float = Field(5e5, gt=0.0, le=1e7,
                          description="Pressure band over which the pump destrokes [Pa]")
    tau: float = Field(0.02, gt=0.0, le=10.0,
                       description="Time constant of the displacement control [s]")
    eps0: float = Field(1.0, ge=0.0, le=1.0, description="Initial displacement fraction [-]")


class PressureCompensatedPump(Component):
    """Pressure-compensated variable pump: destrokes to hold its delivery at ``p_c``; the
    regulation band lies below the setting, full stroke up to ``p_c - dp_reg`` and none at
    ``p_c`` (a proportional compensator: the pressure held sits inside the band)."""

    Params = PressureCompensatedParams
    ports = PUMP_PORTS
    variables = {"eps": Variable("", lambda p: p.eps0, 1.0, "displacement fraction")}

    def equations(self, v, p):
        cmd = 1.0 - smoothstep_ramp(v.b.p, p.p_c - p.dp_reg, p.dp_reg)
        return [p.tau * der(v.eps) - (cmd - v.eps)] + _pump(v, p, v.eps)


class LoadSensingParams(PressureCompensatedParams):
    dp_ls: float = Field(2e6, gt=0.0, le=1e7,
                         description="LS margin: delivery above the LS pressure [Pa]")


class LoadSensingPump(Component):
    """Load-sensing variable pump: delivery ``dp_ls`` above the ``LS`` port, cut off at ``p_c``.

    Proportional compensators: the margin held lies within ``[dp_ls - dp_reg, dp_ls]``
    (nearer ``dp_ls - dp_reg`` at low flow), the cut-off within ``[p_c - dp_reg, p_c]``."""

    Params = LoadSensingParams
    ports = {**PUMP_PORTS, "LS": Hydraulic("load-sensing signal (takes no flow)")}
    variables = {"eps": Variable("", lambda p: p.eps0, 1.0, "displacement fraction")}

    def equations(self, v, p):
        ls = 1.0 - smoothstep_ramp(v.b.p - v.LS.p, p.dp_ls - p.dp_reg, p.dp_reg)
        pc = 1.0 - smoothstep_ramp(v.b.p, p.p_c - p.dp_reg, p.dp_reg)
        v.observe("margin", v.b.p - v.LS.p, "Pa", "delivery above LS")
        return [p.tau * der(v.eps) - (ls * pc - v.eps), v.LS.q] + _pump(v, p, v.eps)


class HydraulicMotor(Component):
    """Fixed-displacement motor: ``q = D w + K dp``, drives its shaft with ``T``.

    ``K = (1/eta_v - 1) D w_nom / dp_nom``, ``T = D dp - (1 - eta_hm) D |dp| tanh(w / w_eps)``:
    at the rated point ``w = eta_v q / D`` and ``T = eta_hm D dp``; elsewhere
    ``w = (q - K dp) / D``. On an inertia with bearing friction ``b`` the steady state has
    ``T = b w``.
    """

    Params = MachineParams
    ports = {"A": Hydraulic("inlet"), "B": Hydraulic("outlet"),
             "shaft": Rotational("output shaft")}

    def equations(self, v, p):
        dp = v.observe("dp", v.A.p - v.B.p, "Pa", "pressure drop A - B")
        w = v.observe("w", der(v.shaft.phi), "rad/s", "shaft speed")
        K = (1.0 / p.eta_v - 1.0) * p.D * p.w_nom / p.dp_nom
        q = v.observe("q", p.D * w + K * dp, "m^3/s", "flow A -> B")
        T = v.observe("T", p.D * dp - (1.0 - p.eta_hm) * p.D * smooth_abs(dp, p.dp_eps)
                      * smooth_sign(w, p.w_eps), "N m", "torque on the shaft")
        v.observe("P_shaft", T * w, "W", "mechanical power out")
        v.observe("P_hyd", q * dp, "W", "hydraulic power in")
        return [v.A.q - q, v.A.q + v.B.q, v.shaft.tau + T]
