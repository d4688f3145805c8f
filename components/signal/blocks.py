"""Signal blocks: gain, weighted sums, saturation and a first-order lag.

::

    Gain:           y = k * u
    Sum:            y = k1 * u1 + k2 * u2
    Sum3:           y = k1 * u1 + k2 * u2 + k3 * u3
    Saturation:     y = clip(u, y_min, y_max)       kinked, or rounded within eps
    FirstOrderLag:  tau * der(y) + y = k * u        (transfer function k / (tau*s + 1))

A component's ports are fixed by its class, so sums come with two (``Sum``) or three (``Sum3``)
inputs; chain them for more.
"""

from __future__ import annotations

from pydantic import Field, model_validator

from pvgraph import expr as E
from pvgraph.component import Component, Params, SignalIn, SignalOut, der
from pvgraph.laws import smooth_clip

__all__ = ["Gain", "GainParams", "Sum", "SumParams", "Sum3", "Sum3Params", "Saturation",
           "SaturationParams", "FirstOrderLag", "FirstOrderLagParams"]


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
