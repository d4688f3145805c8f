"""Signal blocks: gain, weighted sums, saturation and a first-order lag.

::

    Gain:           y = k * u
    Sum:            y = k1 * u1 + k2 * u2
    Sum3:           y = k1 * u1 + k2 * u2 + k3 * u3
    Saturation:     y = clip(u, y_min, y_max)       kinked, or rounded within eps
    FirstOrderLag:  tau * der(y) + y = k * u        (transfer function k / (tau*s + 1))
    Product:        y = k * u1 * u2
    Integrator:     der(y) = k * u,  y(0) = y0      (transfer function k / s)
    PID:            e = r - m
                    v = Kp e + I + D,   der(I) = Ki e + (y - v) / Tt,
                    der(x_d) = N (e - x_d),  D = Kd N (e - x_d)     (Kd N s / (s + N) on e)
                    y = clip(v, y_min, y_max)       (no limits: y = v)

The PID controller is the parallel form with a first-order filter on the derivative term (the
form of Simulink's PID Controller block and of Modelica's ``LimPID``, which writes it with
``Ti = Kp/Ki`` and ``Td = Kd/Kp``). With output limits its integrator is held back by back
calculation (Astrom and Hagglund, *Advanced PID Control*, 2006, sec. 3.5): the difference between
the limited and the unlimited output, divided by the tracking time ``Tt``, is fed back into the
integral, so the integral does not wind up while the output is saturated.

A component's ports are fixed by its class, so sums come with two (``Sum``) or three (``Sum3``)
inputs; chain them for more.
"""

from __future__ import annotations

from pydantic import Field, field_validator, model_validator

from pvgraph import expr as E
from pvgraph.component import Component, Params, SignalIn, SignalOut, Variable, der
from pvgraph.laws import smooth_clip

__all__ = ["Gain", "GainParams", "Sum", "SumParams", "Sum3", "Sum3Params", "Saturation",
           "SaturationParams", "FirstOrderLag", "FirstOrderLagParams", "Product", "ProductParams",
           "Integrator", "IntegratorParams", "PID", "PIDParams"]


class GainParams(Params):
    k: float = Field(..., ge=-1e12, le=1e12, description="Gain [unit of y / unit of u]")


class Gain(Component):
    """Static gain ``y = k * u``."""

    Params = GainParams
    ports = {"u": SignalIn("input"), "y": SignalOut("output")}

    def equations(self, v, p):
        return [v.y - p.k * v.u]


class SumParams(Params):
    k1: float = Field(1.0, ge=-1e12, le=1e12, description="Weight of u1 [-]")
    k2: float = Field(1.0, ge=-1e12, le=1e12, description="Weight of u2 [-]")


class Sum(Component):
    """Weighted sum of two signals ``y = k1*u1 + k2*u2`` (``k2 = -1`` for a difference)."""

    Params = SumParams
    ports = {"u1": SignalIn("first input"), "u2": SignalIn("second input"),
             "y": SignalOut("weighted sum")}

    def equations(self, v, p):
        return [v.y - (p.k1 * v.u1 + p.k2 * v.u2)]


class Sum3Params(SumParams):
    k3: float = Field(1.0, ge=-1e12, le=1e12, description="Weight of u3 [-]")


class Sum3(Component):
    """Weighted sum of three signals ``y = k1*u1 + k2*u2 + k3*u3``."""

    Params = Sum3Params
    ports = {"u1": SignalIn("first input"), "u2": SignalIn("second input"),
             "u3": SignalIn("third input"), "y": SignalOut("weighted sum")}

    def equations(self, v, p):
        return [v.y - (p.k1 * v.u1 + p.k2 * v.u2 + p.k3 * v.u3)]


class SaturationParams(Params):
    y_min: float = Field(..., ge=-1e12, le=1e12, description="Lower limit [unit of u]")
    y_max: float = Field(..., ge=-1e12, le=1e12, description="Upper limit [unit of u]")
    eps: float = Field(0.0, ge=0.0, le=1e12,
                       description="Rounding of the corners [unit of u]; 0 gives the exact "
                                   "kinked limit")

    @model_validator(mode="after")
    def _ordered(self):
        if not self.y_min < self.y_max:
            raise ValueError(f"y_min ({self.y_min!r}) must be below y_max ({self.y_max!r})")
        if self.eps > 0.1 * (self.y_max - self.y_min):
            raise ValueError(f"eps ({self.eps!r}) must be at most a tenth of y_max - y_min")
        return self


class Saturation(Component):
    """Limits a signal to ``[y_min, y_max]``: exactly (kinked) or rounded within ``eps``."""

    Params = SaturationParams
    ports = {"u": SignalIn("input"), "y": SignalOut("limited output")}

    def equations(self, v, p):
        if p.eps > 0.0:
            limited = smooth_clip(v.u, p.y_min, p.y_max, p.eps)
        else:
            limited = E.clip(v.u, p.y_min, p.y_max)
        return [v.y - limited]


class FirstOrderLagParams(Params):
    k: float = Field(1.0, ge=-1e12, le=1e12, description="Static gain [unit of y / unit of u]")
    tau: float = Field(..., gt=0.0, le=1e6, description="Time constant [s]")
    y0: float = Field(0.0, ge=-1e12, le=1e12, description="Initial output [unit of y]")


class FirstOrderLag(Component):
    """First-order lag ``k / (tau*s + 1)``: ``tau * der(y) + y = k * u``."""

    Params = FirstOrderLagParams
    ports = {"u": SignalIn("input"), "y": SignalOut("lagged output")}

    def starts(self, p):
        return {"y": p.y0}

    def equations(self, v, p):
        return [p.tau * der(v.y) + v.y - p.k * v.u]


class ProductParams(Params):
    k: float = Field(1.0, ge=-1e12, le=1e12, description="Gain [unit of y / (unit of u1 * unit "
                                                         "of u2)]")


class Product(Component):
    """Product of two signals ``y = k * u1 * u2``."""

    Params = ProductParams
    ports = {"u1": SignalIn("first factor"), "u2": SignalIn("second factor"),
             "y": SignalOut("product")}

    def equations(self, v, p):
        return [v.y - p.k * v.u1 * v.u2]


class IntegratorParams(Params):
    k: float = Field(1.0, ge=-1e12, le=1e12, description="Gain [unit of y / (unit of u * s)]")
    y0: float = Field(0.0, ge=-1e12, le=1e12, description="Initial output [unit of y]")


class Integrator(Component):
    """Integrator ``k / s``: ``der(y) = k * u``, ``y(0) = y0``."""

    Params = IntegratorParams
    ports = {"u": SignalIn("input"), "y": SignalOut("integral")}

    def starts(self, p):
        return {"y": p.y0}

    def equations(self, v, p):
        return [der(v.y) - p.k * v.u]


class PIDParams(Params):
    Kp: float = Field(1.0, ge=0.0, le=1e12,
                      description="Proportional gain [unit of y / unit of e]; the gains are "
                                  ">= 0: for a reverse-acting loop swap r and m")
    Ki: float = Field(0.0, ge=0.0, le=1e12,
                      description="Integral gain [unit of y / (unit of e * s)]; 0: no integral "
                                  "term")
    Kd: float = Field(0.0, ge=0.0, le=1e12,
                      description="Derivative gain [unit of y * s / unit of e]; 0: no derivative "
                                  "term")
    N: float = Field(100.0, gt=0.0, le=1e9,
                     description="Derivative filter bandwidth [rad/s]: the derivative term is "
                                 "Kd N s / (s + N)")
    y_min: float | None = Field(None, ge=-1e12, le=1e12,
                                description="Lower output limit [unit of y]; None: no limit")
    y_max: float | None = Field(None, ge=-1e12, le=1e12,
                                description="Upper output limit [unit of y]; None: no limit")
    Tt: float | None = Field(None, gt=0.0, le=1e6,
                             description="Anti-windup tracking time [s] (with limits and Ki > 0); "
                                         "None: Ti = Kp/Ki, or 1/Ki where Kp = 0")
    I0: float = Field(0.0, ge=-1e12, le=1e12,
                      description="Initial integral term [unit of y]")

    @field_validator("Kp", "Ki", "Kd", mode="before")
    @classmethod
    def _not_negative(cls, value):
        if isinstance(value, (int, float)) and not isinstance(value, bool) and value < 0:
            raise ValueError("the gains are >= 0; for a reverse-acting loop swap r and m, or "
                             "follow the controller with Gain(k=-1)")
        return value

    @model_validator(mode="after")
    def _limits(self):
        if self.y_min is not None and self.y_max is not None and not self.y_min < self.y_max:
            raise ValueError(f"y_min ({self.y_min!r}) must be below y_max ({self.y_max!r})")
        if self.Kp == 0.0 and self.Ki == 0.0 and self.Kd == 0.0:
            raise ValueError("Kp, Ki and Kd are all 0: the controller's output would be 0")
        if self.I0 != 0.0 and self.Ki == 0.0:
            raise ValueError(f"I0 = {self.I0!r} starts an integral term, but Ki = 0: there is "
                             f"none (give Ki > 0, or leave I0 at 0)")
        if self.Tt is not None and (self.Ki == 0.0 or (self.y_min is None and
                                                       self.y_max is None)):
            raise ValueError("Tt tracks the integral while the output is limited: it needs "
                             "Ki > 0 and y_min or y_max")
        return self


class PID(Component):
    """PID controller on the error ``e = r - m``, derivative filtered, optional output limits
    with back-calculation anti-windup (module docstring)."""

    Params = PIDParams
    ports = {"r": SignalIn("set point"), "m": SignalIn("measurement"),
             "y": SignalOut("controller output")}
    variables = {"I": Variable("", 0.0, 1.0, "integral term (0 where Ki = 0)"),
                 "x_d": Variable("", 0.0, 1.0, "derivative filter state (0 where Kd = 0)")}

    def starts(self, p):
        return {"I": p.I0} if p.Ki > 0.0 else {}

    def equations(self, v, p):
        e = v.observe("e", v.r - v.m, "", "control error r - m")
        out = p.Kp * e
        if p.Ki > 0.0:
            out = out + v.I
        if p.Kd > 0.0:
            out = out + p.Kd * p.N * (e - v.x_d)
            filter_row = der(v.x_d) - p.N * (e - v.x_d)
        else:
            filter_row = v.x_d
        limited = p.y_min is not None or p.y_max is not None
        y = out
        if limited:
            v.observe("v", out, "", "output before the limits")
            if p.y_min is not None:
                y = E.maximum(y, p.y_min)
            if p.y_max is not None:
                y = E.minimum(y, p.y_max)
        if p.Ki == 0.0:
            integral_row = v.I
        elif limited:
            Tt = p.Tt if p.Tt is not None else (p.Kp / p.Ki if p.Kp > 0.0 else 1.0 / p.Ki)
            integral_row = der(v.I) - (p.Ki * e + (v.y - out) / Tt)
        else:
            integral_row = der(v.I) - p.Ki * e
        return [v.y - y, integral_row, filter_row]
