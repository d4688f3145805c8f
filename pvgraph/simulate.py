"""Run a circuit or a compiled system in time and address the results by name."""

from __future__ import annotations

import csv
import dataclasses
import math
import os
import re
import sys
import tempfile
import types
import warnings
from collections.abc import Mapping
from typing import Iterable

import numpy as np

from .circuit import Circuit
from .errors import (InitializationError, PlausibilityWarning, PvgraphError, SolverError,
                     StartValueWarning, outside_stacklevel)
from .system import System

__all__ = ["simulate", "Solution"]

SOLVERS = ("pvgraph", "ida")


class Solution:
    """Times, values and derivatives of every variable of a run, addressed by dotted name.

    ``sol["pvb.main_spool.flange.x"]`` is the array over ``sol.t``; ``sol.der(name)`` its time
    derivative; derived outputs (an orifice's ``q``, a spool's flow force) are addressed the same
    way. ``sol.unit(name)`` gives the unit. A name through an exposed port of a sub-circuit
    (``sol["valve.P.p"]``, see :meth:`System.exposed_names`) gives exactly the values of the
    inner variable it stands for.
    """

    #: why the run ended: it reached ``t_end``, or a terminal event stopped it (its name and
    #: time); ``terminal`` is that event's record (its state at that instant) or None, and
    #: ``t_stop`` the time the run ended (with ``t_eval``, the last output row may be before)
    message: str = ""
    terminal = None
    t_stop: float = math.nan

    def __init__(self, system: System, t, y, yp, *, events=(), stats=None, mode_log=None,
                 solver="pvgraph"):
        self.system = system
        self.t = np.asarray(t)
        self.y = np.asarray(y)
        self.yp = np.asarray(yp)
        self.events = list(events)
        self.stats = dict(stats or {})
        self.solver = solver
        self._mode_log = list(mode_log or [(-math.inf, tuple(system.mode_start))])
        self._observed = None

    @property
    def names(self) -> list[str]:
        """Every variable and output once, by its canonical name (:meth:`System.all_names`);
        the exposed-port names that are also accepted are ``system.exposed_names()``."""
        return self.system.all_names()

    def _modes_per_time(self):
        times = [t for t, _ in self._mode_log]
        rows = [m for _, m in self._mode_log]
        idx = np.searchsorted(times, self.t, side="right") - 1
        # an event's time is in the output twice: before the action (the modes before it,
        # the first row) and after it; the first of such a pair takes the modes it had
        # (searchsorted gives both the modes set there); mode records at one time in a row
        # collapse to the last of them
        t = np.asarray(self.t)
        first = np.flatnonzero(t[:-1] == t[1:]) if t.size > 1 else np.zeros(0, int)
        for i in first:
            k = idx[i]
            if k > 0 and times[k] == t[i]:
                while k > 0 and times[k] == t[i]:
                    k -= 1
                idx[i] = k
        return np.asarray([rows[max(i, 0)] for i in idx], dtype=float).reshape(len(self.t), -1)

    def _observed_values(self):
        if self._observed is None:
            self._observed = self.system.evaluate_observed(self.t, self.y, self.yp,
                                                           self._modes_per_time())
        return self._observed

    def __getitem__(self, name: str) -> np.ndarray:
        if not isinstance(name, str):
            raise TypeError(f"a solution is read by variable name (sol['node.port.p']), got "
                            f"{name!r}")
        if name in self.system.observed:
            return self._observed_values()[name]
        coef, idx, off = self.system.resolve(name)
        if idx is None:
            return np.full(len(self.t), off)
        return coef * self.y[:, idx] + off

    def der(self, name: str) -> np.ndarray:
        """Time derivative of a variable over the run."""
        if not isinstance(name, str):
            raise TypeError(f"sol.der() takes a variable name (sol.der('node.port.p')), got "
                            f"{name!r}")
        if name in self.system.observed:
            # by differences within each stretch between events (an event repeats its time:
            # the values before and after it are two sides, not a difference over dt = 0)
            values, t = self[name], self.t
            out = np.zeros(len(t))
            cuts = np.flatnonzero(np.diff(t) <= 0.0) + 1
            for seg in np.split(np.arange(len(t)), cuts):
                if len(seg) > 1:
                    out[seg] = np.gradient(values[seg], t[seg])
                elif len(seg) == 1 and len(t) > 1:    # one point between two events
                    out[seg] = np.nan
            return out
        coef, idx, _ = self.system.resolve(name)
        if idx is None:
            return np.zeros(len(self.t))
        return coef * self.yp[:, idx]

    def __contains__(self, name: str) -> bool:
        if not isinstance(name, str):
            return False
        try:
            self.unit(name)
        except KeyError:
            return False
        return True

    def unit(self, name: str) -> str:
        return self.system.unit(name)

    def final(self, name: str) -> float:
        """Value at the last time point."""
        return float(self[name][-1])

    def at(self, name: str, t: float) -> float:
        """Value at time ``t`` (linear interpolation between output points); ``t`` outside
        the run raises; ``t`` may carry a unit (``"0.1 s"``)."""
        t = _seconds(t, "t")
        lo, hi = float(self.t[0]), float(self.t[-1])
        slack = 1e-12 * max(1.0, abs(lo), abs(hi))
        if not (lo - slack <= t <= hi + slack):
            raise PvgraphError(f"{self.system.name}: t = {t:g} s is outside the run "
                               f"[{lo:g}, {hi:g}] s")
        return float(np.interp(t, self.t, self[name]))

    def to_csv(self, path, names: Iterable[str] | None = None) -> None:
        """Write time and the named variables (default: all unknowns) to ``path`` atomically."""
        names = list(self.system.names) if names is None else _name_list(names, "to_csv: names")
        if not names:
            raise PvgraphError("to_csv: name at least one variable (or none for all unknowns)")
        cols = [self[n] for n in names]
        header = ["t [s]"] + [f"{n} [{self.unit(n)}]" for n in names]
        _atomic_write(path, lambda f: _write_csv(f, header, self.t, cols))

    def __repr__(self):
        return (f"<Solution of {self.system.name}: {len(self.t)} points, t = {self.t[0]:g} .. "
                f"{self.t[-1]:g} s, {len(self.events)} events>")


#: [Pa] above this a gauge pressure is taken as a modelling error (1000 bar: hydraulic
#: components are rated to a few hundred bar, and the library's pressure parameters end here)
PRESSURE_LIMIT = 1e8


def _write_csv(f, header, t, cols):
    w = csv.writer(f)
    w.writerow(header)
    for k in range(len(t)):
        w.writerow([repr(float(t[k]))] + [repr(float(c[k])) for c in cols])


def _name_list(names, what: str) -> list:
    """``names`` as a list of str: one str is one name, otherwise an iterable of str."""
    if isinstance(names, str):
        return [names]
    try:
        out = list(names)
    except TypeError:
        raise TypeError(f"{what}: give a name or a list of names, got {names!r}") from None
    bad = [n for n in out if not isinstance(n, str)]
    if bad:
        raise TypeError(f"{what}: names are strings, got {bad[0]!r} in {out!r}")
    return out


def _atomic_write(path, write):
    try:
        path = os.fspath(path)
    except TypeError:
        raise TypeError(f"path: a file name (str or os.PathLike), got {path!r}") from None
    if os.path.isdir(path):
        raise IsADirectoryError(f"{path!r} is a directory; give a file name in it "
                                f"(e.g. {os.path.join(path, 'result.csv')!r})")
    folder = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(folder, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=os.path.basename(path))
    except OSError as exc:      # named by the file asked for, not the temporary one
        raise type(exc)(exc.errno, f"cannot write {path!r}: {exc.strerror}", path) from None
    umask = os.umask(0o22)
    os.umask(umask)
    try:
        os.chmod(tmp, 0o666 & ~umask)       # mkstemp makes 0600; the user's umask decides
        with os.fdopen(fd, "w", newline="") as f:
            write(f)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _seconds(value, what: str) -> float:
    """A time [s]: a number, or a quantity (``"2 s"``, ``"500 ms"``, a pint Quantity)."""
    from .units import UnitError, to_unit
    if isinstance(value, bool):      # True is 1 to Python, not a time
        raise PvgraphError(f"{what} = {value!r}: give a time in seconds (a number, or a "
                           f"quantity such as '2 s')")
    try:
        return float(to_unit(value, "s", what))
    except UnitError as exc:
        raise PvgraphError(str(exc)) from None
    except (TypeError, ValueError):
        raise PvgraphError(f"{what} = {value!r}: give a time in seconds (a number, or a "
                           f"quantity such as '2 s')") from None


def _tolerance(value, what: str, per_variable: bool = False):
    """A relative tolerance (``rtol``, and ``atol`` in nominal units) as a float between 0 and
    1 (``per_variable``: or an array of them, one per unknown), or a :class:`PvgraphError`
    naming it."""
    if per_variable and isinstance(value, (list, tuple, np.ndarray)):
        try:
            values = np.asarray(value, dtype=float).ravel()
        except (TypeError, ValueError):
            values = np.array([np.nan])
        if not values.size or not np.all((values > 0.0) & (values < 1.0)):
            raise PvgraphError(f"simulate: {what}: one number per unknown, each between 0 and "
                               f"1 (in units of its nominal size), got {value!r}")
        return values
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise PvgraphError(f"simulate: {what} = {value!r}: give a number between 0 and 1 "
                           f"(e.g. {what}=1e-6), not a {type(value).__name__}")
    value = float(value)
    if not (0.0 < value < 1.0):
        raise PvgraphError(f"simulate: {what} = {value!r}: a tolerance is a number between 0 "
                           f"and 1 (relative to each variable's size), e.g. {what}=1e-6")
    return value


def _full_vector(system, values, what: str) -> np.ndarray:
    """``values`` as a float vector of the system's ``n`` unknowns, or an error naming it."""
    try:
        out = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise PvgraphError(f"{what}: not an array of numbers") from None
    if out.shape != (system.n,):
        raise PvgraphError(f"{what} has shape {out.shape}, but {system.name} has {system.n} "
                           f"unknowns (system.names lists them in order)")
    return out


def _nonnegative_indices(system, names) -> list[int]:
    """The unknowns' indices of ``nonnegative=[names]``: an unknown, or an alias that is one
    of them (``node.port.p`` of a volume's pressure); a variable fixed by parameters, one of
    negative sign or a derived output cannot be held >= 0 by the solver, and is refused."""
    out = []
    for name in names:
        if not isinstance(name, str):
            raise PvgraphError(f"simulate: nonnegative takes variable names or indices of "
                               f"system.names, not both; got {name!r} among names")
        try:
            coef, idx, off = system.resolve(name)
        except KeyError as exc:
            raise PvgraphError(f"simulate: nonnegative: {exc.args[0]}") from None
        if idx is None or coef <= 0.0 or off != 0.0:
            raise PvgraphError(f"simulate: nonnegative: {name!r} is not an unknown of the run "
                               f"(fixed by parameters, or another unknown scaled or shifted): "
                               f"the solver can hold only unknowns >= 0")
        out.append(idx)
    return out


def simulate(target, t_end: float, *, t_start: float = 0.0, rtol: float = 1e-6,
             atol: float | None = None, solver: str = "pvgraph", t_eval=None,
             max_step: float | None = None, start: dict[str, float] | None = None,
             calc_initial: str | None = "algebraic", y0=None, yp0=None, params=None,
             switch_states: bool = True, **options) -> Solution:
    """Simulate a circuit (compiled on the fly) or a :class:`System` from ``t_start`` to ``t_end``.

    Parameters
    ----------
    target : Circuit or System
    t_end : float or quantity
        End time [s] (``t_start`` and ``max_step`` alike; ``"500 ms"`` is read too).
    rtol : float
        Relative tolerance.
    atol : float or array, optional
        Absolute tolerance in units of each variable's nominal magnitude (default ``rtol``; an
        array gives one per unknown, in the order of ``system.names``), so
        a pressure (nominal 10 bar) gets ``atol * 1e6`` Pa and a spool position (nominal 1 mm)
        ``atol * 1e-3`` m.
    solver : {"pvgraph", "ida"}
        The built-in IDA-style solver, or SUNDIALS IDA through scikit-sundae.
    t_eval : array, optional
        Output times; default every internal step.
    start : dict, optional
        Start values by variable name, overriding the components' (``{"node.port.p": 1e6}``).
        A state keeps its start value; an algebraic variable's is a first guess that the
        consistent start may change (a :class:`~pvgraph.errors.StartValueWarning` says so).
    y0, yp0 : array, optional
        Full initial vectors (e.g. a previous operating point); ``start`` is applied on top.
    calc_initial : {"algebraic", "all", None}
        How to make the initial values consistent (see :func:`pvgraph.solver.solve_dae`).
    params : dict, optional
        Parameter values by name (``{"orifice.A": 2e-6}``), applied with
        :meth:`System.with_params` without compiling again; the solution's ``system`` carries
        them. ``target.parameter_names`` lists the names.
    switch_states : bool
        Where a rigid constraint's choice of states becomes ill-conditioned during the run (a
        Cartesian pendulum passing through the bottom, see :meth:`System.index_report`), stop
        the step there, choose the states again at that instant (compiling the circuit again)
        and go on (default); ``False`` stops the run there with a :class:`SolverError`
        naming the variables. The solution is in the layout of the system the run started
        with; ``sol.stats["state_switches"]`` lists ``(t, states before, states after)``.
    **options
        Passed on to the solver: for ``"pvgraph"`` :func:`pvgraph.solver.solve_dae`'s options
        (``c_step``, ``linear_solver``, ``max_steps``, ``suppress_alg``, ...).

    With the built-in solver the algebraic variables (flows, forces, the pressures of
    chambers without volume) stay out of the local error test when the circuit has
    differential ones (``suppress_alg=True``): their kinks (friction, end stops, tables)
    would otherwise cut the steps without making the states more accurate. A circuit without
    any differential variable keeps them all in the test. A fast source that drives only
    algebraic parts is then followed at the steps the states need, so where ``max_step`` is
    not given, a periodic source bounds it (``Sine``: a tenth of its period; a 200 Hz
    pressure through a check valve into a volume had whole openings stepped over, 2.3 bar
    low at rtol 1e-4); give ``max_step`` or ``suppress_alg=False`` otherwise. Events between
    steps are located with the algebraic variables solved from the equations at the
    interpolated states (a threshold on a saturated controller output fires on time); rows at
    ``t_eval`` are the steps' interpolant, which keeps every node's flow balance, so an
    algebraic variable with a kink inside a step can be off its own equation there (a
    saturated PI output 1e-3 at rtol 1e-6): ask for every step, or a tighter rtol, there.
    """
    if not isinstance(target, (Circuit, System)):
        raise PvgraphError(f"simulate() takes a Circuit or a System, got {type(target).__name__}")
    t_end, t_start = _seconds(t_end, "t_end"), _seconds(t_start, "t_start")
    if max_step is not None:
        max_step = _seconds(max_step, "max_step")
    if solver not in SOLVERS:
        raise PvgraphError(f"unknown solver {solver!r}; choose one of {SOLVERS}")
    if not (math.isfinite(t_end) and t_end > t_start):
        raise PvgraphError(f"t_end ({t_end!r}) must be finite and greater than t_start "
                           f"({t_start!r})")
    _check_options(options, solver)
    solve = _solver_function(solver)        # an optional backend missing: told before compiling
    if start is not None and not isinstance(start, Mapping):
        raise PvgraphError(f"simulate: start takes a mapping {{variable name: value}} "
                           f"(start={{'node.port.p': '5 bar'}}), got {type(start).__name__}")
    if t_eval is not None and np.size(t_eval) == 0:
        raise PvgraphError("simulate: t_eval is empty; give the output times, or None for "
                           "every step")
    rtol = _tolerance(rtol, "rtol")
    if atol is not None:
        atol = _tolerance(atol, "atol", per_variable=True)
    recompile = options.pop("recompile", True)
    system = target.compile() if isinstance(target, Circuit) else target
    if params is not None:
        from .circuit import parameter_values
        params = parameter_values(params, "simulate: params")
    if params:
        system = system.with_params(params, recompile=recompile, _starts_follow=bool(start))
    if max_step is None:
        max_step = _source_step(system, t_end - t_start)
    y_init = _full_vector(system, system.y0 if y0 is None else y0, "y0")
    yp_init = _full_vector(system, system.yp0 if yp0 is None else yp0, "yp0")
    given = {}
    for name, value in (start or {}).items():
        coef, idx, off = system.resolve(name)
        if idx is None or coef == 0.0:
            raise PvgraphError(f"start value for {name!r}: it is fixed to {off!r} by the circuit")
        value = _start_value(system, name, value)
        y_init[idx] = (value - off) / coef
        given[name] = value
    reduction = getattr(system, "index_reduction", None)
    if given and reduction is not None and reduction.reduced:
        # a start on a variable the constraints determine moves the state it is tied to;
        # contradicting ones are refused with the values the constraints force. After runtime
        # parameters, the start values they changed are imposed with these (these win)
        pending = system.__dict__.pop("_pending_starts", None) or {}
        reduction.impose(system, {**pending, **given}, y_init, yp_init, t_start)
        _check_build_starts_moved(system, reduction, given, y_init, yp_init, t_start)
    if atol is not None and np.ndim(atol) and len(atol) != system.n:
        raise PvgraphError(f"simulate: atol has {len(atol)} values; {system.name} has "
                           f"{system.n} unknowns (system.names), one value each")
    atol_vec = (rtol if atol is None else atol) * system.nominal
    system.reset_modes()
    system.apply_start_events(t_start, y_init, yp_init)
    if system.n == 0:  # the circuit is fully determined algebraically: nothing to integrate
        t = np.asarray(t_eval if t_eval is not None else [t_start, t_end], dtype=float)
        return Solution(system, t, np.zeros((len(t), 0)), np.zeros((len(t), 0)),
                        mode_log=system.mode_log, solver=solver)
    if solver == "pvgraph":
        # circuits: algebraic forces and flows of friction, end stops and tables have kinks
        # on which Newton fails; leaving them out of the error test and not growing the step
        # right after a failure keep the rig running (solve_dae's defaults, IDA's, do not)
        # ... unless nothing would be left in it: with no differential variable the step
        # would grow unchecked over whatever drives the algebraic ones (a sine source)
        options.setdefault("suppress_alg", bool(np.any(~np.asarray(system.algebraic))))
        options.setdefault("no_growth_after_failure", True)
        options.setdefault("newton_iterate_retry", True)
    if isinstance(options.get("nonnegative"), (list, tuple)) and \
            any(isinstance(v, str) for v in options["nonnegative"]):
        options["nonnegative"] = _nonnegative_indices(system, options["nonnegative"])
    kwargs = dict(rtol=rtol, atol=atol_vec, algebraic=system.algebraic,
                  jac=system.solver_jacobian(), jac_sparsity=system.jac_sparsity,
                  events=system._run_events() or None, t_eval=t_eval, max_step=max_step,
                  calc_initial=calc_initial, var_names=system.names, **options)
    if not isinstance(switch_states, (bool, np.bool_)):
        raise PvgraphError(f"simulate: switch_states takes True or False, got {switch_states!r}")
    switches = []
    if kwargs["events"]:
        from . import _state_switch
        watched = getattr(system, "_circuit", None) is not None and \
            bool(_state_switch.watch_names(kwargs["events"]))
        switching = switch_states and watched
        kwargs["events"] = _state_switch.for_run(kwargs["events"], switching) or None
        if watched:
            solve = _switching(solve, system, kwargs, rtol, atol, switches, switching)
    try:
        res = solve(system.residual, (t_start, t_end), y_init, yp_init, **kwargs)
    except SolverError as exc:
        hint = _stiff_node_hint(system, exc.culprits)
        if not hint:
            raise
        raise SolverError(f"{exc} {hint}", t=exc.t, h=exc.h, culprits=exc.culprits) from None
    except InitializationError as exc:
        res = None
        start = _algebraic_start(system, exc, y_init, t_start, calc_initial)
        if start is not None:
            try:
                res = solve(system.residual, (t_start, t_end), start, yp_init, **kwargs)
            except InitializationError:
                pass
        if res is None:
            named = re.findall(r"'([^']+)'", str(exc))
            if "did not converge" not in str(exc):
                hint = ""
                if "singular" in str(exc):
                    hint = _massless_hint(system) or _rigid_node_hint(system, named)
                if hint:
                    raise InitializationError(f"{exc} {hint}") from None
                raise
            if not any(u == "Pa" and a for u, a in zip(system.units, system.algebraic)):
                raise   # no pressure without a volume: the valve advice does not apply
            raise InitializationError(
                f"{exc} A valve fed by a flow source with no volume on its node starts closed, "
                f"where its opening law is flat: put a VolumeNode on that node, or give its "
                f"pressure a start value above the opening pressure.") from None
    if not res.success:
        raise PvgraphError(f"{system.name}: simulation stopped early: {res.message}")
    sol = Solution(system, res.t, res.y, res.yp, events=res.events, stats=res.stats,
                   mode_log=getattr(res, "mode_log", None) or system.mode_log, solver=solver)
    sol.message = res.message
    # a terminal event ends the run: where the last event recorded is one, it stopped there
    stopping = {f"{path}.{spec.name}" for path, spec in system.event_specs if spec.terminal}
    if res.events and res.events[-1].name in stopping:
        sol.terminal = res.events[-1]
        sol.t_stop = float(sol.terminal.t)
    else:
        sol.t_stop = float(t_end)
    if switches:
        sol.stats["state_switches"] = switches
    if calc_initial == "all" and reduction is not None and reduction.given:
        # the components' given starts (Mass(x0=...)) are moved by "all" as start= ones are
        given = {**reduction.given, **given}
    _check_starts_kept(sol, given, calc_initial)
    _check_pressures(sol)
    return sol


def _source_step(system, span):
    """The largest step the circuit's periodic sources allow (their ``max_step_hint``, with
    the run's parameter values), or None."""
    hints = []
    for path, comp in (getattr(system, "_components", None) or {}).items():
        hint = getattr(comp, "max_step_hint", None)
        if hint is None:
            continue

        def value(field, path=path, comp=comp):
            info = system.parameters.get(f"{path}.{field}")
            return info.value if info is not None else getattr(comp.params, field)
        got = hint(value)
        if got is not None and math.isfinite(got) and got > 0.0:
            hints.append(got)
    return min(hints) if hints and min(hints) < span else None


def _switching(solve, system, kwargs, rtol, atol, switches, switching=True):
    """``solve`` for a system whose index reduction watches its pivots (see
    :mod:`pvgraph._state_switch`). The watches are relative to the pivots' values where the
    states were chosen: a run starting elsewhere (``start=``, runtime parameters: a pendulum
    compiled at 0.1 rad started beyond the bottom, a link of another length) first chooses
    them there. With ``switching``, the run goes on where a watch fires, with the states chosen
    again; the segments are returned as one result in ``system``'s layout; ``switches``
    receives ``(t, states before, states after)``."""
    from . import _state_switch as S

    def retarget(kw, current, new):
        kw.update(algebraic=new.algebraic, jac=new.solver_jacobian(),
                  jac_sparsity=new.jac_sparsity, var_names=new.names,
                  events=S.for_run(new._run_events(), switching) or None,
                  atol=_carried_atol(system, new, kw["atol"], rtol, atol))
        if "suppress_alg" in kw:
            kw["suppress_alg"] = bool(np.any(~np.asarray(new.algebraic)))

    def run(residual, span, y0, yp0, **kw):
        t_end = span[1]
        current, kw = system, dict(kw)
        pieces = []        # (system, result) per segment
        kept = set()       # switch watches whose block kept its states (not watched again)
        t_eval = kw.get("t_eval")
        rebased = S.rebased(current, span[0], y0, yp0)
        if rebased is not None:
            if S.states_of(rebased) != S.states_of(current):
                switches.append((float(span[0]), S.states_of(current), S.states_of(rebased)))
            rebased.modes[:] = current.modes
            y0, yp0 = (a[0] for a in S.to_layout(rebased, current, np.array([span[0]]), y0,
                                                 yp0))
            retarget(kw, current, rebased)
            current = rebased
        while True:
            res = solve(current.residual, span, y0, yp0, **kw)
            pieces.append((current, res))
            rec = S.fired(res, S.watch_names(kw["events"] or ())) if switching else None
            if rec is None or not res.success:
                break
            new = S.switched(current, rec) if len(switches) < S.MAX_SWITCHES else None
            if new is None and ".pivot_" in rec.name:   # no better choice, and nearly singular
                raise current.index_reduction.pivot_lost(int(rec.name.rsplit("_", 1)[1]),
                                                         rec.t)
            if new is None:     # this choice is still the best there: go on with it
                kept.add(rec.name)
                y0, yp0 = rec.y, rec.yp
                kw["events"] = S.for_run(current._run_events(), True, kept) or None
            else:
                switches.append((float(rec.t), S.states_of(current), S.states_of(new)))
                new.modes[:] = current.modes
                new.mode_log = [(float(rec.t), tuple(new.modes))]
                y0, yp0 = (a[0] for a in S.to_layout(new, current, np.array([rec.t]), rec.y,
                                                     rec.yp))
                kept = set()
                retarget(kw, current, new)
                current = new
            kw["calc_initial"] = "algebraic"
            span = (float(rec.t), t_end)
            if t_eval is not None:
                # the run goes on to t_end (its events, a terminal one) with what is left
                t_eval = np.asarray(t_eval)[np.asarray(t_eval) > rec.t]
                kw["t_eval"] = t_eval
        if len(pieces) == 1 and current is system:
            return res
        return _joined(system, pieces)
    return run


def _carried_atol(system, new, atol_vec, rtol, atol):
    """The absolute tolerances of ``new``'s unknowns: by name those given per unknown of
    ``system``, else the relative rule of :func:`simulate`."""
    out = (rtol if atol is None or np.ndim(atol) else atol) * new.nominal
    if atol is not None and np.ndim(atol):
        for j, name in enumerate(new.names):
            k = system.index.get(name)
            if k is not None:
                out[j] = atol_vec[k]
    return out


def _joined(system, pieces):
    """One result of the segments ``pieces`` (``(system, result)``) in ``system``'s layout:
    times in order (a segment's first point, the switch instant the previous one ends on,
    once), events, statistics summed, the modes' log of every segment."""
    from . import _state_switch as S
    from .solver.result import DAEResult
    ts, ys, yps, events, log = [], [], [], [], []
    stats: dict = {}
    for k, (sysk, res) in enumerate(pieces):
        t, y, yp = np.asarray(res.t), np.asarray(res.y), np.asarray(res.yp)
        # a switch's instant stays twice (before and after, as at an event): the algebraic
        # variables are solved again there, and sol.der() of an output does not difference
        # across it
        if sysk is not system and len(t):
            y, yp = S.to_layout(system, sysk, t, y, yp)
        ts.append(t)
        ys.append(y.reshape(len(t), system.n))
        yps.append(yp.reshape(len(t), system.n))
        for rec in res.events:
            if rec.name.startswith(S.EVENT_OWNER + "."):
                continue            # the pivot watches: told in stats["state_switches"]
            if sysk is not system:
                ry, ryp = S.to_layout(system, sysk, np.array([rec.t]), rec.y, rec.yp)
                rec = dataclasses.replace(rec, y=ry[0], yp=ryp[0])
            events.append(rec)
        for key, value in res.stats.items():
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                stats[key] = stats.get(key, 0) + value
            else:
                stats.setdefault(key, value)
        log.extend(sysk.mode_log)
    last = pieces[-1][1]
    out = DAEResult(t=np.concatenate(ts), y=np.concatenate(ys), yp=np.concatenate(yps),
                    events=events, t_events=np.array([r.t for r in events], dtype=float),
                    stats=stats, success=last.success, message=last.message)
    out.mode_log = log
    return out


def _solver_function(solver):
    """``solve_dae`` or ``solve_dae_sundials`` by the name ``simulate`` takes."""
    if solver == "pvgraph":
        from .solver import solve_dae
        return solve_dae
    import importlib.util
    if importlib.util.find_spec("sksundae") is None:
        raise PvgraphError("solver='ida' needs SUNDIALS through scikit-sundae, which is not "
                           "installed: pip install \"pvgraph[sundials]\" (or scikit-sundae)")
    from .solver import solve_dae_sundials
    return solve_dae_sundials


def _check_options(options, solver) -> None:
    """Refuse an option the chosen solver does not take, with the closest names (the
    solver would say only that its own function got an unexpected keyword)."""
    import difflib
    import inspect
    solve = _solver_function(solver)
    own = {"t_span", "y0", "yp0", "residual", "rtol", "atol", "algebraic", "jac",
           "jac_sparsity", "events", "t_eval", "max_step", "calc_initial", "var_names"}
    taken = (set(inspect.signature(solve).parameters) - own) | {"recompile"}
    for name in options:
        if name not in taken:
            close = difflib.get_close_matches(name, sorted(taken | set(
                inspect.signature(simulate).parameters) - {"options"}), n=3, cutoff=0.6)
            hint = f" (did you mean {', '.join(map(repr, close))}?)" if close else ""
            raise PvgraphError(f"simulate: unknown option {name!r} for solver {solver!r}{hint}; "
                               f"the options it takes: {', '.join(sorted(taken))}")


def _stiff_node_hint(system, culprits) -> str:
    """A sentence for a failed run whose culprits include a pressure with no volume on its
    node (an algebraic pressure), or "": moving parts meeting there with no compliance
    between them (a poppet with mass straight on a flow source) make the run stall."""
    names = list(system.names)
    bare = [c for c in culprits if c in system.index and system.units[system.index[c]] == "Pa"
            and system.algebraic[system.index[c]]]
    if not bare or not any(c not in bare for c in culprits if c in names):
        return ""
    return (f"{', '.join(map(repr, bare))} has no volume on its node (an algebraic pressure): "
            f"the parts meeting there, with mass or dynamics of their own, are joined with no "
            f"compliance between them. A VolumeNode on that node, even a small one, gives the "
            f"oil somewhere to go.")


def _rigid_node_hint(system, named) -> str:
    """A sentence for a singular start among whose ``named`` variables is a pressure with no
    volume on its node, or "": displacement machines or pistons meeting there without
    leakage tie their motions rigidly through the oil, which the equations do not resolve."""
    bare = [n for n in named if n in system.index and system.units[system.index[n]] == "Pa"
            and system.algebraic[system.index[n]]]
    if not bare:
        return ""
    return (f"{bare[0]!r} has no volume on its node: the pumps, motors or pistons meeting "
            f"there with no leakage tie their motions to each other rigidly through the oil. "
            f"Put a VolumeNode on that node (the line's oil, however small), or give a machine "
            f"leakage (eta_v < 1).")


def _massless_hint(system) -> str:
    """A sentence naming the shafts and flanges that move with nothing carrying inertia on
    them (no part with a mass ``m`` or an inertia ``J``), or "" where there are none.

    Two motors on one shaft and nothing else (a rotary flow divider) balance their torques by
    pressures alone: the shaft's speed appears in the flows only, and no equation sets it.
    """
    groups: dict = {}
    for path, comp in (getattr(system, "_components", None) or {}).items():
        params = getattr(comp, "params", None)
        # a part with a mass or an inertia, or one that sets the motion (a speed source)
        heavy = getattr(params, "m", None) is not None or getattr(params, "J", None) is not None \
            or getattr(type(comp), "prescribes_motion", False)
        for port_name, port in type(comp).ports.items():
            domain = port.domain
            if domain.through is None or domain.name == "hydraulic":
                continue
            try:
                _, idx, _ = system.resolve(f"{path}.{port_name}.{domain.across}")
            except KeyError:
                continue
            if idx is None or not system.differential[idx]:
                continue
            g = groups.setdefault(idx, [domain.name, False, []])
            g[1] = g[1] or heavy
            g[2].append(f"{path}.{port_name}")
    bare = [(kind, ports) for kind, heavy, ports in groups.values() if not heavy]
    if not bare:
        return ""
    what = "; ".join(f"the {'shaft' if kind == 'rotational' else 'flange'} joining "
                     f"{', '.join(ports)}" for kind, ports in bare)
    return (f"Nothing with inertia moves with {what}: where its torques or forces balance by "
            f"the pressures alone (two motors on one shaft, a rotary flow divider), no "
            f"equation sets its speed. Put an Inertia (on a flange, a Mass) on it, however "
            f"small.")


def _algebraic_start(system, exc, y, t0, calc_initial):
    """Better first guesses of the algebraic unknowns after the consistent start failed, or
    None: their values at a steady state from ``y`` (the states kept). Newton from a valve
    closed at its start (a pump straight into a relief or check valve, no volume on the node:
    the opening law is flat there) stalls; the steady solver's line search and continuation
    reach the open valve, and the consistent start converges from there."""
    if calc_initial != "algebraic" or "consistent initialisation at t" not in str(exc):
        return None
    alg = np.asarray(system.algebraic, dtype=bool)
    if not alg.any():
        return None
    from .analysis.steady import limited_start, steady_state
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            op = steady_state(system, y0=y, t=t0, tol=1e-6)   # a first guess only
    except PvgraphError:
        # no steady state (a load the flow keeps moving): the start's own equations, by
        # Newton with limited steps from the closed valve
        got = limited_start(system, t0, y, np.zeros(system.n))
        if got is None:
            return None
        return got[0]
    start = np.array(y, dtype=float)
    start[alg] = op.y[alg]
    return start


def _check_build_starts_moved(system, reduction, given, y, yp, t0) -> None:
    """Warn of start values given when building (``Mass(v0=...)``) on variables the
    constraints tie together that they move to meet the ones given to simulate (``start=``,
    which win)."""
    moved = []
    involved = reduction._involved_indices(system)
    if not any(name not in given for name in reduction.given):
        return
    from .index_reduction import _consistent_values
    y, _, ok = _consistent_values(system, t0, y, yp)
    if not ok:
        return
    for name, value in reduction.given.items():
        if name in given:
            continue
        try:
            coef, idx, off = system.resolve(name)
        except KeyError:
            continue
        if idx is None or idx not in involved:
            continue
        got = coef * y[idx] + off
        if abs(got - value) > 1e-6 * max(abs(value), abs(got), float(system.nominal[idx])):
            moved.append(f"{name} from {value:.6g} to {got:.6g}")
    if moved:
        warnings.warn(StartValueWarning(
            f"{system.name}: the start values given to simulate move ones given when building, "
            f"through the constraints: {'; '.join(moved[:6])}."), stacklevel=outside_stacklevel())


def _check_starts_kept(sol, given, calc_initial="algebraic") -> None:
    """Warn of each ``start=`` value the consistent start did not keep.

    A start value of an algebraic variable (the pressure of a node without volume, a flow)
    is a first guess only, as in Modelica: the consistent start computes it from the states.
    Where it then differs from the value given, the user learns so and which variables do
    hold a start value (a Simscape "target not satisfied" warning)."""
    system = sol.system
    for name, value in given.items():
        got = float(sol[name][0])
        _, idx, _ = system.resolve(name)
        scale = max(abs(value), abs(got), float(system.nominal[idx]))
        if abs(got - value) <= 1e-4 * scale:
            continue
        if idx is not None and not system.algebraic[idx]:
            warnings.warn(StartValueWarning(
                f"{system.name}: start value for {name!r} ({value:.6g}) was not kept; the run "
                f"starts at {got:.6g}: calc_initial={calc_initial!r} computes the states too "
                f"(from y' given). Use calc_initial='algebraic' (the default) to start the "
                f"states at their start values."), stacklevel=outside_stacklevel())
            continue
        states = [nm for nm, alg in zip(system.names, system.algebraic) if not alg]
        shown = ", ".join(states[:6]) + (", ..." if len(states) > 6 else "")
        warnings.warn(StartValueWarning(
            f"{system.name}: start value for {name!r} ({value:.6g}) was not kept; the run "
            f"starts at {got:.6g}. {name!r} is an algebraic variable: the consistent start "
            f"computes it from the states, so its start value is a first guess only. Give "
            f"start values of states instead ({shown})."), stacklevel=outside_stacklevel())


def _start_value(system, name, value) -> float:
    """A start value in SI: a number, or a quantity in the variable's unit (``"50 bar"``)."""
    from .units import number_in
    return number_in(value, system.unit(name) or "-", f"start value for {name!r}")


def _check_pressures(sol: Solution) -> None:
    """Warn when a pressure leaves the physical range: the circuit, not the solver, is wrong."""
    system = sol.system
    worst = []
    cols = [j for j, unit in enumerate(system.units) if unit == "Pa"]
    if not cols or sol.y.shape[0] == 0:
        return
    # one pass over the pressure columns; the columns out of range looked at one by one
    with np.errstate(invalid="ignore"):
        bad = ~(np.abs(sol.y[:, cols]) <= PRESSURE_LIMIT).all(axis=0)
    for j in np.asarray(cols)[bad]:
        col = np.abs(sol.y[:, j])
        k = int(np.argmax(col))
        if not np.isfinite(col[k]) or col[k] > PRESSURE_LIMIT:
            first = int(np.argmax(~np.isfinite(col) | (col > PRESSURE_LIMIT)))
            worst.append((float(col[k]), system.names[j], float(sol.t[first])))
    if worst:
        worst.sort(reverse=True)
        same = {}
        for alias, (coef, target, off) in system.aliases.items():
            if target is not None and coef == 1.0 and off == 0.0:
                same.setdefault(target, []).append(alias)

        def node(n):
            others = sorted(same.get(n, []))[:3]
            return f"{n} (= {', '.join(others)})" if others else n
        listed = "; ".join(f"{node(n)} reaches {v / 1e5:.3g} bar (beyond {PRESSURE_LIMIT / 1e5:.0f} "
                           f"bar from t = {t:.4g} s)" for v, n, t in worst[:3])
        warnings.warn(PlausibilityWarning(
            f"{system.name}: implausible pressure: {listed}. A flow source or pump pushes its "
            f"flow through whatever is open: an outlet too small for it (an orifice or valve "
            f"sized for less flow) holds such a pressure, and a closed valve or dead end with "
            f"no leakage and no relief builds it without bound; give the flow a way out sized "
            f"for it, or a relief valve (CheckValve to tank). "
            f"Where such a pressure is meant (an intensifier's area ratio), raise "
            f"pvgraph.simulate.PRESSURE_LIMIT."), stacklevel=3)


class _CallableModule(types.ModuleType):
    """This module, callable as :func:`simulate`: ``import pvgraph; pvgraph.simulate(c, 1.0)``
    and ``from pvgraph import simulate`` run a simulation as
    ``from pvgraph.simulate import simulate`` does."""

    def __call__(self, *args, **kwargs):
        return simulate(*args, **kwargs)

    def __reduce__(self):   # pickled by name (a partial of it sent to a process pool)
        import importlib
        return importlib.import_module, (self.__name__,)


sys.modules[__name__].__class__ = _CallableModule
