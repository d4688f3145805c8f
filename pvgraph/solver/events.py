"""Zero-crossing events: declaration, detection over a step and location on the interpolant.

After each successful step the event functions g_i(t, y, y') are evaluated at the new point
and compared with their values at the previous one. A sign change in an allowed direction
is located by Brent's method on the BDF interpolant of the step, as IDA locates roots on
its interpolant. An event function that is exactly zero at the start of a step (at t0, or
just after a reset) has no sign yet: its sign is taken slightly inside the step instead,
so a reset that leaves g on zero does not trigger the same event again.

References
----------
.. [1] A. C. Hindmarsh et al., "User Documentation for IDA", SUNDIALS, section
   "Rootfinding".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np
from scipy.optimize import brentq
from pvgraph.errors import SolverError

__all__ = ["Event", "normalize_events", "EventTracker", "turned_back", "zeno_error", "probe"]

UROUND = np.finfo(float).eps
SIGN_PROBE = 1e-6           # fraction of the step at which an initially-zero g is probed
AFTER_CROSSING = 1e-300     # |g| standing for "just past zero" on the side crossed to
#: an event firing this many times in a row with no time between its zeros (rounding apart)
#: is a switch without end (a sliding mode, Zeno behaviour): the run stops with its name
CHATTER_EVENTS = 50


@dataclass
class Event:
    """A zero crossing of ``fun(t, y, yp)`` to detect during integration.

    Parameters
    ----------
    fun : callable
        ``fun(t, y, yp) -> float``; the event occurs where it crosses zero.
    direction : int
        +1 only rising crossings (negative to positive), -1 only falling, 0 both. A crossing
        back right after the event's own action is a crossing (as a relay's switch makes it):
        an impact that reverses the motion is ``direction=-1``, or it fires again at once.
    terminal : bool
        Stop the integration at this event. The actions of the events that fire at that
        instant (its own included) still run, and the output ends with the state after them
        (as Modelica's when-clauses run at a ``terminate()``).
    action : callable or None
        ``action(t, y, yp)`` called at the event. It may switch mode state captured by the
        residual and may return a new ``(y, yp)``. The solver then recomputes consistent
        initial conditions and restarts at order 1 (a DAE of index two is not made consistent
        by that: its action must return consistent ``(y, yp)``, hidden constraints included,
        as IDA needs after ``IDAReInit``).
    name : str
        Used in the event records; defaults to ``fun.__name__``.
    """

    fun: Callable[[float, np.ndarray, np.ndarray], float]
    direction: int = 0
    terminal: bool = False
    action: Optional[Callable] = None
    name: str = ""

    def apply(self, t: float, y: np.ndarray, yp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Run the action at the event; the ``(y, yp)`` to restart from (copies)."""
        out = self.action(t, y.copy(), yp.copy()) if self.action is not None else None
        if out is None:
            return y, yp
        y_new = np.array(out[0], dtype=float).ravel()
        yp_new = np.array(out[1], dtype=float).ravel()
        if y_new.shape != y.shape or yp_new.shape != y.shape:
            raise ValueError(f"the action of event {self.name!r} returned arrays of shapes "
                             f"{y_new.shape}, {yp_new.shape}; expected {y.shape}")
        return y_new, yp_new


def atol_vector(atol, n):
    """``atol`` as one entry per variable: given as a number, or as ``n`` of them."""
    atol = np.asarray(atol, dtype=float)
    if atol.ndim > 1 or atol.size not in (1, n):
        raise ValueError(f"atol must be a number or have one entry per variable ({n}), got "
                         f"shape {atol.shape}")
    return np.broadcast_to(atol.ravel() if atol.ndim else atol, (n,)).copy()


def stopping_event(fired, events):
    """The event that stops the run among those ``fired`` at one instant: the first terminal
    one, else the first (declaration order)."""
    return next((events[j] for j in fired if events[j].terminal), events[fired[0]])


def normalize_events(events):
    """Turn Events and scipy-style callables (``.terminal``, ``.direction``) into Events."""
    if events is None:
        return []
    if callable(events) and not isinstance(events, Event):
        events = [events]
    out = []
    for i, ev in enumerate(events):
        if not isinstance(ev, Event):
            if not callable(ev):
                raise TypeError(f"event {i} is neither an Event nor callable: {ev!r}")
            ev = Event(fun=ev, direction=int(np.sign(getattr(ev, "direction", 0))),
                       terminal=bool(getattr(ev, "terminal", False)),
                       action=getattr(ev, "action", None),
                       name=getattr(ev, "__name__", ""))
        if ev.direction not in (-1, 0, 1):
            raise ValueError(f"event {i} has direction {ev.direction}; use -1, 0 or +1")
        if not ev.name:
            ev = Event(ev.fun, ev.direction, ev.terminal, ev.action,
                       getattr(ev.fun, "__name__", f"event{i}"))
        out.append(ev)
    return out


def _shared_vector(events):
    """``(g_all, indices)`` if every event function is one entry of one vector function.

    An event function may carry ``fun.vector = (g_all, k)``: ``g_all(t, y, yp)`` returns every
    event value of a system at once (one generated function), and this event is entry ``k``.
    """
    if not events:
        return None
    tags = [getattr(ev.fun, "vector", None) for ev in events]
    if any(tag is None for tag in tags) or len({id(tag[0]) for tag in tags}) != 1:
        return None
    return tags[0][0], np.array([tag[1] for tag in tags], dtype=np.int64)


class EventTracker:
    """Event function values across steps, and location of crossings within a step.

    When the events are entries of one vector function (see :func:`_shared_vector`), every
    evaluation is one call of it, whatever the number of events.
    """

    def __init__(self, events):
        self.events = events
        self.m = len(events)
        self.g = np.zeros(self.m)
        self.nroot = 0
        self._vector = _shared_vector(events)
        self._last = None       # (rounding factor, g at the start, g at the end, length)
        self._turned = {}       # index -> time of the action that turned its function back

    def evaluate(self, t, y, yp):
        """Return all event function values at (t, y, yp)."""
        self.nroot += self.m
        if self._vector is not None:
            g_all, idx = self._vector
            g = np.asarray(g_all(t, y, yp), dtype=float)[idx]
        else:
            try:
                g = np.array([float(ev.fun(t, y, yp)) for ev in self.events])
            except (TypeError, ValueError):
                self._name_bad_value(t, y, yp)
                raise
        if not np.all(np.isfinite(g)):
            k = int(np.flatnonzero(~np.isfinite(g))[0])
            raise SolverError(f"event {self.events[k].name!r} returned {g[k]} at t = {t:.9g}; "
                              f"an event function must return a finite number")
        return g

    def _name_bad_value(self, t, y, yp):
        """Raise naming the event whose function does not return one number."""
        for ev in self.events:
            value = ev.fun(t, y, yp)
            try:
                float(value)
            except (TypeError, ValueError):
                raise TypeError(f"event {ev.name!r} returned {value!r} (shape "
                                f"{np.shape(value)}); an event function returns one number "
                                f"(give several events as a list of functions)") from None

    def reset(self, t, y, yp, unknown=(), crossed=None, located=None):
        """Start tracking at t; events in ``unknown`` get their sign from the next step.

        ``crossed``: ``{index: direction}`` of the events that fired at ``t``. Such an event
        is on the side it crossed to where its value after the actions is zero, of that
        side's sign, or of the other sign by rounding only (its slope over the step times
        the time tolerance of the location, a few ulps of t): a crossing back, as a relay's ``der(x) = -sign(x)`` makes it, is then seen,
        and a step's ``t - t_step`` a few ulps short of zero does not fire twice. A value of
        the other sign beyond rounding is a function the action switched (a condition a mode
        changes): its sign comes from the next step. ``located``: ``(t, y, y')`` where the
        events were found, before the actions and the restart; an event whose function is
        still at its zero there (within rounding) after the actions was not switched by them,
        so a value of the other sign now comes from the restart re-solving the algebraic
        variables (the crossing was found on their interpolant): it stays crossed, or it
        would fire again for the same crossing.
        """
        last = self._last
        self._turned = {}
        self.g = self.evaluate(t, y, yp)
        for i in unknown:
            self.g[i] = 0.0
        for i, direction in (crossed or {}).items():
            g = self.g[i]
            if not direction:
                self.g[i] = 0.0
            elif g != 0.0 and (g > 0.0) == (direction > 0):
                continue
            elif last is not None and (
                    abs(g) <= last[0] * abs(last[2][i] - last[1][i]) or (
                        located is not None and abs(self._value_at(i, located))
                        <= last[0] * abs(last[2][i] - last[1][i]))):
                self.g[i] = direction * AFTER_CROSSING
                if self.events[i].direction and self._reversed(i, direction, t, y, yp, last):
                    # on the side it came from: a step across the zero is a new crossing
                    self.g[i] = -direction * AFTER_CROSSING
                    self._turned[i] = t
            else:
                self.g[i] = 0.0

    def _reversed(self, i, direction, t, y, yp, last) -> bool:
        """:func:`turned_back` for event ``i`` after the step ``last`` it crossed in."""
        return turned_back(lambda *p: self._value_at(i, p), direction, t, y, yp, last[3],
                           abs(last[2][i] - last[1][i]))

    def _value_at(self, i, point):
        """Event ``i``'s function at ``point = (t, y, y')`` (the modes as they are now)."""
        t, y, yp = point
        self.nroot += 1
        if self._vector is not None:
            g_all, idx = self._vector
            return float(np.asarray(g_all(t, y, yp), dtype=float)[idx][i])
        return float(self.events[i].fun(t, y, yp))

    def crossings(self, t_old, t_new, g_new, interp):
        """Return the crossings in (t_old, t_new] as sorted (t, index, direction) tuples.

        ``interp(t) -> (y, yp)`` is the interpolant of the step.
        """
        g_old = self.g
        if not g_old.all():         # an event function exactly at zero: its sign from a probe
            zero = g_old == 0.0
            t_probe = t_old + SIGN_PROBE * (t_new - t_old)
            y, yp = interp(t_probe)
            g_old = g_old.copy()
            if self._vector is not None:
                self.nroot += self.m
                g_probe = self.evaluate(t_probe, y, yp)
                g_old[zero] = g_probe[zero]
            else:
                for i in np.flatnonzero(zero):
                    self.nroot += 1
                    g_old[i] = float(self.events[i].fun(t_probe, y, yp))
        found = []
        g_new = np.asarray(g_new)
        # for reset: the rounding of g at a located zero is its change over the step times
        # the location's time tolerance (see _locate) over the step's length, with a margin
        dt = t_new - t_old
        xtol = max(4 * UROUND * abs(t_new), 1e-14 * abs(dt), 1e-300)
        self._last = (16.0 * xtol / dt if dt > 0 else 0.0, g_old, g_new, dt)
        # only the events whose sign changed are looked at one by one: a change makes the
        # product <= 0 (NaN compares false on both tests); the exact test follows
        candidates = (g_old * g_new <= 0.0).nonzero()[0]
        for i in candidates.tolist():
            ev = self.events[i]
            a, b = g_old[i], g_new[i]
            rising = a < 0.0 <= b
            falling = a > 0.0 >= b
            if not (rising or falling):
                continue
            if b == 0.0 and abs(a) == AFTER_CROSSING:
                # from just past the zero it fired at to exactly zero: the function stays at
                # its zero (a clipped quantity, min(t - t0, 0)), not a crossing back (IDA
                # likewise masks a root function that stays at zero)
                continue
            if (ev.direction > 0 and not rising) or (ev.direction < 0 and not falling):
                continue
            if i in self._turned and self._turned[i] == t_old:
                raise zeno_error(ev, t_old, t_new)
            found.append((self._locate(ev, t_old, t_new, a, b, interp),
                          i, 1 if rising else -1))
        self._turned = {}
        found.sort()
        return found

    def _locate(self, ev, t_old, t_new, g_old, g_new, interp):
        """Root of g on the interpolant, or the step end if the interpolant does not bracket."""
        if g_new == 0.0:
            return t_new

        def g(t):
            self.nroot += 1
            y, yp = interp(t)
            return float(ev.fun(t, y, yp))

        ga = g(t_old)
        gb = g(t_new)
        if ga == 0.0 or np.sign(ga) == np.sign(gb):
            # the interpolant and the stored values disagree near the ends; take the end
            # of the step where the sign is known to have changed
            return t_new if ga == 0.0 or np.sign(ga) == np.sign(g_old) else t_old
        xtol = max(4 * UROUND * abs(t_new), 1e-14 * abs(t_new - t_old), 1e-300)
        return brentq(g, t_old, t_new, xtol=xtol, rtol=4 * UROUND)


def turned_back(g, direction, t, y, yp, dt, change=0.0) -> bool:
    """True if an action at ``t`` turned the event function ``g(t, y, y')``, which crossed its
    zero in ``direction`` over a step of length ``dt`` (changing by ``change``), back from its
    zero: its rate at the restart (a first-order probe along y') points away from the side it
    crossed to, at more than a millionth of its mean rate over that step. It is then on the
    side it came from, so a step that ends across the zero again is a new crossing (a ball
    leaving the floor), not the same one."""
    if not dt > 0.0:
        return False
    delta = SIGN_PROBE * dt
    _, rise = probe(g, t, y, yp, delta)
    return rise * direction < 0.0 and abs(rise) / delta > 1e-6 * change / dt


def probe(g, t, y, yp, delta) -> tuple[float, float]:
    """``(g at (t, y, y'), its change a first-order step delta along y' later)``."""
    g0 = float(g(t, y, yp))
    return g0, float(g(t + delta, y + delta * yp, yp)) - g0


def zeno_error(ev, t_old, t_new) -> SolverError:
    """The stop for event ``ev``, turned back by its action at ``t_old`` and carried across
    its zero again by the very next step (to ``t_new``): the motion the action started ends
    within one step (a ball that leaves the floor below the tolerances' resolution). Firing
    again there would act on the state the action left (a rising ball's speed reversed);
    going on would leave the condition crossed unseen (the ball falls through the floor)."""
    return SolverError(
        f"event {ev.name!r} fired at t = {t_old:.12g} and its action turned its function "
        f"back, but the next step (to t = {t_new:.12g}, {t_new - t_old:.3g} long) carried it "
        f"across its zero again: the motion the action starts is below the tolerances' "
        f"resolution, and the events accumulate there (Zeno behaviour: a bouncing ball's "
        f"impacts at its resting time). Give the model a resting state (e.g. the impact's "
        f"action holds the body where the rebound speed falls below a threshold), or end the "
        f"run before t = {t_old:.9g}.", t=t_old)


def check_times(t0, t_end, t_eval, max_step, first_step):
    """``t_eval`` as a float array (or None), after the checks both solvers make of the
    output times and step options; ValueError naming what is wrong."""
    if max_step is not None and not (max_step > 0.0):      # NaN fails too; inf: no limit
        raise ValueError(f"max_step must be positive, got {max_step!r}")
    if first_step is not None and not (0.0 < first_step < np.inf):
        raise ValueError(f"first_step must be positive and finite, got {first_step!r}")
    if t_eval is None:
        return None
    t_eval = np.asarray(t_eval, dtype=float).ravel()
    bad = np.flatnonzero(~np.isfinite(t_eval))
    if bad.size:
        raise ValueError(f"t_eval must be finite: t_eval[{bad[0]}] = {float(t_eval[bad[0]])!r}")
    down = np.flatnonzero(np.diff(t_eval) < 0.0)
    if down.size:
        k = int(down[0])
        raise ValueError(f"t_eval must be sorted: t_eval[{k + 1}] = {float(t_eval[k + 1])!r} "
                         f"comes after t_eval[{k}] = {float(t_eval[k])!r}")
    if t_eval.size and (t_eval[0] < t0 or t_eval[-1] > t_end):
        # times past an end by rounding only (np.arange(0, t_end + dt, dt) ends at
        # 0.30000000000000004 for 0.3) are that end
        fuzz = 64.0 * UROUND * max(abs(t0), abs(t_end), t_end - t0)
        t_eval = t_eval.copy()
        t_eval[(t_eval < t0) & (t_eval >= t0 - fuzz)] = t0
        t_eval[(t_eval > t_end) & (t_eval <= t_end + fuzz)] = t_end
        if t_eval[0] < t0 or t_eval[-1] > t_end:
            raise ValueError(f"t_eval must lie within the run's interval [{t0!r}, {t_end!r}], "
                             f"got [{float(t_eval[0])!r}, {float(t_eval[-1])!r}]")
    return t_eval
