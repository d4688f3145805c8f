"""Signal sources: functions of time on a causal output ``y``.

::

    Constant:   y = k
    Step:       y = offset + height * after        after: 0 -> 1 at t = t_step (an event)
    Ramp:       y = offset + height * clip((t - t_start) / duration, 0, 1)
    TimeTable:  y = table(t)                       linear or pchip, held beyond the ends
    Sine:       y = offset + amplitude * sin(2*pi*f*t + phase)
    Pulse:      y = offset + height * on           on: 1 for duty * period from t_start + k period

``Step`` and ``Ramp`` switch a discrete mode at declared events (``t - t_step`` crossing zero
upwards), so the solver stops exactly at the switching time and restarts from consistent values
there instead of stepping across the discontinuity. The modes start as "before"; a switching time
at or before ``t = 0`` is applied at trace time (the value is the one after the switch). A
simulation that starts at or after a switching time (``t_start >= t_step``) starts with that
switch applied (the events are declared ``at_start``), so the value at ``t_step`` is the new one
whichever side the run comes from.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from pvgraph import expr as E
from pvgraph.component import Component, Params, SignalOut

__all__ = ["Constant", "ConstantParams", "Step", "StepParams", "Ramp", "RampParams",
           "TimeTable", "TimeTableParams", "Sine", "SineParams", "Pulse", "PulseParams"]


def _switch(name):
    """An event action that sets the mode ``name`` to 1."""
    def act(view):
        view[name] = 1.0
    act.__name__ = f"set_{name}"
    return act


class ConstantParams(Params):
    k: float = Field(..., ge=-1e12, le=1e12, description="Output value [unit of y]")


class Constant(Component):
    """Constant signal ``y = k``."""

    Params = ConstantParams
    ports = {"y": SignalOut("the constant")}

    def equations(self, v, p):
        return [v.y - p.k]


class StepParams(Params):
    height: float = Field(1.0, ge=-1e12, le=1e12, description="Size of the step [unit of y]")
    offset: float = Field(0.0, ge=-1e12, le=1e12, description="Value before the step [unit of y]")
    t_step: float = Field(0.0, ge=0.0, le=1e9,
                          description="Time of the step [s]; the value at t_step is the new one")


class Step(Component):
    """Step from ``offset`` to ``offset + height`` at ``t_step``, switched by an event."""

    Params = StepParams
    ports = {"y": SignalOut("the step signal")}
    modes = {"after": 0.0}

    def equations(self, v, p):
        if p.t_step <= 0.0:
            return [v.y - (p.offset + p.height)]
        v.event("step", v.t - p.t_step, direction=1, action=_switch("after"), at_start=True)
        return [v.y - (p.offset + p.height * E.where(v.mode("after") > 0.5, 1.0, 0.0))]


class RampParams(Params):
    height: float = Field(1.0, ge=-1e12, le=1e12, description="Total change [unit of y]")
    duration: float = Field(..., gt=0.0, le=1e9, description="Duration of the ramp [s]")
    offset: float = Field(0.0, ge=-1e12, le=1e12, description="Value before the ramp [unit of y]")
    t_start: float = Field(0.0, ge=0.0, le=1e9, description="Start of the ramp [s]")


class Ramp(Component):
    """Ramp from ``offset`` to ``offset + height`` over ``[t_start, t_start + duration]``."""

    Params = RampParams
    ports = {"y": SignalOut("the ramp signal")}
    modes = {"started": 0.0, "ended": 0.0}

    def equations(self, v, p):
        t_end = p.t_start + p.duration
        rising = (v.t - p.t_start) / p.duration
        if t_end <= 0.0:
            fraction = E.const(1.0)
        else:
            v.event("end", v.t - t_end, direction=1, action=_switch("ended"), at_start=True)
            fraction = E.where(v.mode("ended") > 0.5, 1.0, rising)
            if p.t_start > 0.0:
                v.event("start", v.t - p.t_start, direction=1,
                        action=_switch("started"), at_start=True)
                fraction = E.where(v.mode("started") > 0.5, fraction, 0.0)
        return [v.y - (p.offset + p.height * fraction)]


class TimeTableParams(Params):
    t: tuple[float, ...] = Field(..., min_length=2, description="Times [s], strictly increasing")
    y: tuple[float, ...] = Field(..., min_length=2, description="Values at those times "
                                                                "[unit of y]")
    method: Literal["linear", "pchip"] = Field(
        "linear", description="Interpolation: linear, or pchip (monotone cubic, C1)")

    @model_validator(mode="after")
    def _table(self):
        if len(self.t) != len(self.y):
            raise ValueError(f"t has {len(self.t)} points but y has {len(self.y)}")
        if any(b <= a for a, b in zip(self.t, self.t[1:])):
            raise ValueError("t must be strictly increasing")
        if not all(math.isfinite(x) for x in self.t + self.y):
            raise ValueError("t and y must be finite")
        return self


class TimeTable(Component):
    """Signal interpolated in a table of time, held constant beyond its ends.

    The knots where the table turns are time events (as Modelica's ``CombiTimeTable`` makes
    its knots): the condition ``t - t_next`` with the index of the next such knot held in a
    mode, so the solver stops there however long its steps. A run at rest otherwise steps
    over a short plateau of a command profile entirely (a 50 ms command at 2 s seen as 0 by
    a run of 11 steps). A knot turns where its change of slope, over the shorter of its two
    segments, exceeds ``TURN_FRACTION`` of the table's range (the held ends count as flat):
    a command's corners do, the samples of a logged smooth signal do not (2000 events for a
    2001-sample trace cost 36 times the run, and buy nothing: the error test follows it). The
    knots are chosen from the values the table is built with. A run that starts after some
    of them starts at the next one ahead.
    """

    Params = TimeTableParams
    ports = {"y": SignalOut("the interpolated signal")}
    modes = {"knot": 0.0}

    def equations(self, v, p):
        table = E.Table(p.t, p.y, method=p.method, name=f"{self.path} y(t)")
        corners = turning_knots(tuple(p.t), tuple(self.params.y))
        if corners:
            # the time of the next corner by its index (past the last: never)
            times = E.Table(tuple(float(k) for k in range(len(corners) + 1)),
                            corners + (corners[-1] + 1e12,), name=f"{self.path} knots")
            v.event("knot", v.t - E.interp(times, v.mode("knot")), direction=1,
                    action=_NextKnot(corners), at_start=True)
        return [v.y - E.interp(table, v.t)]


#: a TimeTable's knot is an event where its slope changes by more than this fraction of the
#: table's range over the shorter of its two segments
TURN_FRACTION = 1e-2


def turning_knots(t, y) -> tuple:
    """The times of the knots of the table ``(t, y)`` where it turns (see TimeTable)."""
    span = max(y) - min(y)
    if not span > 0.0:
        return ()
    out = []
    n = len(t)
    for k in range(n):
        dt_l = t[k] - t[k - 1] if k > 0 else math.inf
        dt_r = t[k + 1] - t[k] if k + 1 < n else math.inf
        s_l = (y[k] - y[k - 1]) / dt_l if k > 0 else 0.0
        s_r = (y[k + 1] - y[k]) / dt_r if k + 1 < n else 0.0
        if abs(s_r - s_l) * min(dt_l, dt_r) > TURN_FRACTION * span:
            out.append(float(t[k]))
    return tuple(out)


class _NextKnot:
    """The action at a knot of a TimeTable: the next one ahead. At the start of a run past
    the first knots, the first knot after the start time."""

    def __init__(self, times):
        self.times = times

    def __call__(self, view):
        t = view.t
        if t is None or not getattr(view, "starting", False):
            view["knot"] = view["knot"] + 1.0
            return
        slack = 1e-9 * max(abs(t), self.times[-1] - self.times[0])
        view["knot"] = float(sum(1 for tk in self.times if tk <= t + slack))


class SineParams(Params):
    amplitude: float = Field(1.0, ge=-1e12, le=1e12, description="Amplitude [unit of y]")
    f: float = Field(..., gt=0.0, le=1e6, description="Frequency [Hz]")
    phase: float = Field(0.0, ge=-1e3, le=1e3, description="Phase at t = 0 [rad]")
    offset: float = Field(0.0, ge=-1e12, le=1e12, description="Mean value [unit of y]")


class Sine(Component):
    """Sine wave ``y = offset + amplitude * sin(2*pi*f*t + phase)``."""

    Params = SineParams
    ports = {"y": SignalOut("the sine wave")}

    def equations(self, v, p):
        return [v.y - (p.offset + p.amplitude * E.sin(2.0 * math.pi * p.f * v.t + p.phase))]

    @staticmethod
    def max_step_hint(value):
        """A tenth of the period: ``simulate`` bounds its steps by it where no ``max_step``
        is given, so a wave that drives only algebraic parts (a pressure source feeding a
        check valve) is not stepped over."""
        return 0.1 / value("f")


class PulseParams(Params):
    height: float = Field(1.0, ge=-1e12, le=1e12, description="Size of the pulses [unit of y]")
    offset: float = Field(0.0, ge=-1e12, le=1e12,
                          description="Value between the pulses [unit of y]")
    period: float = Field(..., gt=0.0, le=1e9, description="Period of the pulse train [s]")
    duty: float = Field(0.5, gt=0.0, lt=1.0,
                        description="Fraction of each period at offset + height [-]")
    t_start: float = Field(0.0, ge=0.0, le=1e9, description="Time of the first rise [s]")


class Pulse(Component):
    """Pulse train (a PWM command, Simulink's Pulse Generator): ``offset + height`` for
    ``duty * period`` from each rise at ``t_start + k period``, ``offset`` in between.

    Each edge is an event on ``t - t_next``, with the time of the next edge held in the modes
    (periods done, and whether the pulse is on), so the condition only grows between two
    edges and the solver stops at every edge, however long its steps (a condition on
    ``cos(2 pi t / period)`` rises and falls within one step and is missed where the step
    spans a period). A run that starts after ``t_start`` starts with the train where it is
    at that time (the edges before it applied, as ``Step`` does).
    """

    Params = PulseParams
    ports = {"y": SignalOut("the pulse train")}
    modes = {"on": 0.0, "periods": 0.0}

    def equations(self, v, p):
        on = v.mode("on")
        t_next = p.t_start + (v.mode("periods") + p.duty * on) * p.period
        # the catch-up at a late start uses the values given (the parameters are symbols here)
        given = self.params
        v.event("edge", v.t - t_next, direction=1,
                action=_NextEdge(given.t_start, given.period, given.duty), at_start=True)
        return [v.y - (p.offset + p.height * E.where(on > 0.5, 1.0, 0.0))]


class _NextEdge:
    """The action at an edge: at a rise on, at a fall off and one period more done. At the
    start of a run past ``t_start`` (the action applied there once) the train is moved on to
    where it is at that time, with the run's parameter values."""

    def __init__(self, t_start, period, duty):
        self.t_start, self.period, self.duty = t_start, period, duty

    def __call__(self, view):
        if view["on"] > 0.5:
            view["on"] = 0.0
            view["periods"] = view["periods"] + 1.0
        else:
            view["on"] = 1.0
        t = view.t
        if t is None or not getattr(view, "starting", False):
            return      # at an edge: the condition, with the run's values, found it
        # the run's values of the parameters where the system gives them (a period changed
        # at run time), else those the circuit was built with
        ask = getattr(view, "parameter", None) or (lambda field: None)

        def value(field, given):
            got = ask(field)
            return got if isinstance(got, (int, float)) else given
        t_start, period, duty = (value("t_start", self.t_start), value("period", self.period),
                                 value("duty", self.duty))
        t_next = t_start + (view["periods"] + duty * view["on"]) * period
        slack = 1e-9 * period
        if t_next > t + slack:      # the first edge lies ahead
            return
        k = math.floor((t - t_start + slack) / period)
        phase = t - t_start - k * period
        if phase + slack < duty * period:               # on, the fall of period k ahead
            view["periods"], view["on"] = float(k), 1.0
        else:                                           # off, the rise of period k + 1 ahead
            view["periods"], view["on"] = float(k + 1), 0.0
