"""The compiled DAE system F(t, y, y') = 0 of a circuit.

A :class:`System` holds generated functions for the residual, the Jacobian values on a fixed
sparse pattern (dF/dy + c dF/dy'), event functions and derived outputs, together with everything
needed to address results by name: variable names, units, nominal magnitudes, the split into
differential and algebraic variables, and the aliases removed by the compiler. Parameters are
runtime values (the vector ``P`` every generated function takes): one compiled system runs with
other parameter values (:meth:`System.with_params`), and gives the parameter derivative dF/dp
(:meth:`System.parameter_jacobian`) for sensitivities.

In big systems (``ARRAY_MIN_ROWS`` rows or more) residual rows and event functions of one shape
repeated ``ARRAY_MIN_GROUP`` times or more are generated once, as a template over slots, and
evaluated with numpy over arrays of their instances' unknowns and parameters; their Jacobian
values are scattered into the same sparse pattern. The operations are those of the straight-line
code, in the same order, with the transcendental functions of ``math`` (numpy's own may differ
in the last bit): both give the same numbers, bit for bit.
"""

from __future__ import annotations

import copy
import dataclasses
import difflib
import functools
import itertools
import math
import operator
import threading
import warnings
from dataclasses import dataclass
from typing import Mapping

import numpy as np
from scipy.sparse import csc_matrix, csr_matrix

from . import codegen
from . import expr as E
from .errors import (CircuitError, InitializationError, ParameterError, StartValueWarning,
                     outside_stacklevel)

__all__ = ["System", "build_system", "ModeView", "RecompileWarning"]


class RecompileWarning(UserWarning):
    """A parameter change needed a new compilation (a structural parameter changed)."""


@dataclass
class _Entry:
    row: int
    col: int
    expr: E.Expr


class ModeView:
    """A component's view of the system's discrete modes: ``modes["open"] = 1.0``; ``t`` is the
    time of the event whose action receives it (None outside a run); ``starting`` is True
    where the action is applied at a run's start (an ``at_start`` event already due)."""

    def __init__(self, values: list, index: dict[str, int], owner: str):
        self._values = values
        self._index = index
        self._owner = owner
        self.t = None
        self.starting = False   # True while an at-start action is applied at a run's start
        #: ``parameter(field)``: the run's value of the owner's parameter ``field`` (set for
        #: at-start actions), or None
        self.parameter = None

    def __getitem__(self, name):
        return self._values[self._slot(name)]

    def __setitem__(self, name, value):
        self._values[self._slot(name)] = float(value)

    def _slot(self, name):
        try:
            return self._index[name]
        except KeyError:
            raise CircuitError(f"{self._owner} has no mode {name!r}; its modes are "
                               f"{sorted(self._index)}") from None


class System:
    """A compiled circuit: residual, Jacobian, events and metadata.

    Attributes
    ----------
    names : list of str
        Dotted names of the unknowns, in the order of ``y``.
    differential : ndarray of bool
        True where the variable's derivative appears (a state), False for algebraic variables.
    y0, yp0 : ndarray
        Start values (initial conditions of states, guesses for the rest) and derivative guesses.
    nominal : ndarray
        Typical magnitude of each variable, used to scale absolute tolerances.
    units : list of str
    equations : list of str
        A label per residual row naming the component (or node) it comes from.
    modes : list of float
        Current values of the discrete modes (changed by events).
    parameters : dict
        Runtime parameters by name (``"orifice.A"``): :class:`~pvgraph.component.ParameterInfo`
        with value, unit, description and, for a structural one, why. The generated functions
        take them as the vector ``P``; :meth:`with_params` runs the same code with other values.
    """

    DENSE_MAX = 120  # above this many unknowns the Jacobian is handed to the solver sparse
    index_reduction = None  # the compiler's IndexReduction (pvgraph.index_reduction)
    _vector = None          # rows evaluated as arrays (_ArrayPart), if any
    _vecP: list = []        # per row group: its parameter slot arrays and derived arrays
    _ev_vector = None       # events evaluated as arrays (_ArrayPart), if any
    _ev_vecP: list = []
    _cmod = None            # the C form of the generated functions (pvgraph.cbackend), if used
    _cst = None             # its buffers for this system's parameters (one per thread)
    #: unknown -> (the parameters it is fixed to an expression of, the labels of the
    #: equations reading its rate), for each unknown the compiler fixed to parameters whose
    #: rate the equations read (a position set by a constant, its velocity the position's
    #: rate): its rate is zero while the parameters are constants, so a parameter used as the
    #: input of a linear model may act through a rate the model does not hold (see
    #: :func:`pvgraph.analysis.linearize.linearize`)
    held_rates: dict = {}

    def __init__(self, name, names, differential, y0, nominal, units, descriptions, equations,
                 rows, cols, residual_fn, jac_fn, observed_fn, observed, event_fn, event_specs,
                 mode_names, mode_start, aliases, sources):
        self.name = name
        self.names = names
        self.n = len(names)
        self.index = dict(zip(names, range(len(names))))
        self.differential = np.asarray(differential, dtype=bool)
        self.algebraic = ~self.differential
        self.y0 = np.asarray(y0, dtype=float)
        self.yp0 = np.zeros(self.n)
        self.nominal = np.asarray(nominal, dtype=float)
        self.units = units
        self.descriptions = descriptions
        self.equations = equations
        self._rows = np.asarray(rows, dtype=np.int64)
        self._cols = np.asarray(cols, dtype=np.int64)
        self._res = residual_fn
        self._jac = jac_fn
        self._obs = observed_fn
        self.observed = observed  # name -> (unit, description)
        self._event_fn = event_fn
        self.event_specs = event_specs  # list of (path, EventSpec)
        self.mode_names = mode_names
        self.mode_start = list(mode_start)
        self.modes = list(mode_start)
        self.mode_log: list[tuple[float, tuple]] = []
        self._alias_exprs = aliases  # name -> (coef, target or None, offset); may be parametric
        self._alias_values = None
        self._P: list[float] = []
        self.parameters: dict = {}   # name -> ParameterInfo
        self._lazy: dict = {}        # generated on demand, shared by with_params copies
        self._circuit = None
        self._components: dict = {}
        self._models: dict = {}
        self._pindex: dict = {}
        self._tables: list = []
        self._derive = None
        self._nbase = 0
        self._sources = sources
        indptr = np.zeros(self.n + 1, dtype=np.int64)
        np.add.at(indptr, self._cols + 1, 1)
        self._indptr = np.cumsum(indptr)
        self.jac_sparsity = csc_matrix((np.ones(len(rows)), self._rows, self._indptr),
                                       shape=(self.n, self.n))
        self.counters = {"residual": 0, "jacobian": 0}

    # evaluation ---------------------------------------------------------------------------------
    def residual(self, t, y, yp):
        """F(t, y, y') as an array; NaN where an equation cannot be evaluated."""
        if self._cmod is not None:
            st = self._c_at(y, yp)
            st.module.residual(t, *st.args, st.res_ptr)
            return st.res_out.copy()
        try:
            if self._vector is not None:
                return self._array_residual(t, y, yp)
            return np.array(self._res(t, y.tolist(), yp.tolist(), self.modes, self._P))
        except (ValueError, ZeroDivisionError, OverflowError):
            return np.full(self.n, np.nan)

    def jacobian_values(self, t, y, yp, c):
        """Values of dF/dy + c dF/dy' on the fixed pattern (CSC order)."""
        if self._cmod is not None:
            st = self._c_at(y, yp)
            st.module.jacobian(t, *st.args, c, st.jac_ptr)
            return st.jac_out.copy()
        try:
            if self._vector is not None:
                return self._array_jacobian(t, y, yp, c)
            return np.array(self._jac(t, y.tolist(), yp.tolist(), self.modes, self._P, c))
        except (ValueError, ZeroDivisionError, OverflowError):
            return np.full(len(self._rows), np.nan)

    def _array_residual(self, t, y, yp):
        # Rows of repeated shapes are computed over arrays of their instances. numpy returns
        # NaN or inf where the straight-line code raises (a square root of a negative number,
        # a division by zero): such an entry becomes NaN, "cannot be evaluated", in its own row
        # (the straight-line code, stopped by the exception, makes every row NaN).
        part = self._vector
        y = np.asarray(y, dtype=float)
        yp = np.asarray(yp, dtype=float)
        out = np.empty(self.n)
        if len(part.scalar_rows):
            out[part.scalar_rows] = self._res(t, y.tolist(), yp.tolist(), self.modes, self._P)
        modes = np.asarray(self.modes, dtype=float) if part.uses_modes else None
        with np.errstate(all="ignore"):
            for g, P in zip(part.groups, self._vecP):
                Y, YP, D = g.gather(y, yp, modes)
                out[g.rows] = g.res_fn(t, Y, YP, D, P)[0]
            if part.linear is not None:
                out += part.linear.residual(y, yp)
        return _nan_where_not_finite(out)

    def _array_jacobian(self, t, y, yp, c):
        part = self._vector
        y = np.asarray(y, dtype=float)
        yp = np.asarray(yp, dtype=float)
        out = np.empty(len(self._rows))
        if len(part.scalar_pos):
            out[part.scalar_pos] = self._jac(t, y.tolist(), yp.tolist(), self.modes, self._P, c)
        modes = np.asarray(self.modes, dtype=float) if part.uses_modes else None
        with np.errstate(all="ignore"):
            for g, P in zip(part.groups, self._vecP):
                Y, YP, D = g.gather(y, yp, modes)
                for pos, vals in zip(g.jac_pos, g.jac_fn(t, Y, YP, D, P, c)):
                    out[pos] = vals
        if part.linear is not None:
            out[part.linear.pos] = part.linear.jacobian(c)
        return _nan_where_not_finite(out)

    def jacobian(self, t, y, yp, c):
        """dF/dy + c dF/dy' as a sparse CSC matrix."""
        return csc_matrix((self.jacobian_values(t, y, yp, c), self._rows, self._indptr),
                          shape=(self.n, self.n))

    def jacobian_dense(self, t, y, yp, c):
        """dF/dy + c dF/dy' as a dense array."""
        J = np.zeros((self.n, self.n))
        J[self._rows, self._cols] = self.jacobian_values(t, y, yp, c)
        return J

    def solver_jacobian(self):
        """The Jacobian callable to hand a solver: dense for small systems, sparse otherwise."""
        return self.jacobian_dense if self.n <= self.DENSE_MAX else self.jacobian

    # evaluation backends ------------------------------------------------------------------------
    @property
    def backend(self) -> str:
        """``"c"`` when the residual, Jacobian and events run as compiled C, else ``"python"``."""
        return "c" if self._cmod is not None else "python"

    def use_backend(self, backend: str = "c", *, required: bool = True) -> "System":
        """Evaluate the residual, Jacobian and events with ``backend``; returns the system.

        ``"c"``: the generated expressions as C, compiled once by the machine's C compiler and
        cached (see :mod:`pvgraph.cbackend`): the same numbers as the Python code, many times
        faster per call. ``"python"``: the generated Python code (no compiler needed).
        ``"auto"``: C where a compiler is found, else Python. With ``required=False`` a
        failure to build the C form warns and keeps Python. Systems whose repeated rows are
        evaluated as arrays (big ones, see ``array_rows`` of :func:`build_system`) keep that
        route with ``"auto"`` and refuse ``"c"``: compile them with ``array_rows=False`` (or
        ``compile(backend="c")``) for C. The C compiler takes about 0.5 s for the PVG 32 rig
        and a few ms per row in big systems (once: libraries are cached by their source).
        """
        from . import cbackend
        if backend not in ("c", "python", "auto"):
            raise ValueError(f"{self.name}: backend must be 'c', 'python' or 'auto', "
                             f"not {backend!r}")
        if backend == "python":
            self._cmod = self._cst = None
            return self
        if backend == "auto":
            required = False
            if cbackend.c_compiler() is None:
                return self
        exprs = self._lazy.get("c_exprs")
        if exprs is None and backend == "auto":
            return self     # rows evaluated as arrays: that route stays
        if exprs is None:
            err = cbackend.CBackendError(
                f"{self.name}: its repeated rows are evaluated as arrays ({self.n} unknowns); "
                f"compile with array_rows=False to run it as C")
            if required:
                raise err
            warnings.warn(f"{err}; using the Python code", RuntimeWarning, stacklevel=2)
            return self
        module = self._lazy.get("c_module")
        if module is None:
            module = cbackend.try_build(*exprs, name=self.name, required=required)
            if module is None:
                return self
            self._lazy["c_module"] = module
        self._cmod = module
        self._cst = None
        return self

    def _c_state(self):
        """This thread's :class:`~pvgraph.cbackend.CState` (buffers and parameters)."""
        st = self._cst
        me = threading.get_ident()
        if st is not None and st.thread == me:
            return st
        from .cbackend import CState
        states = self.__dict__.setdefault("_cstates", {})
        st = states.get(me)
        if st is None or st.module is not self._cmod:
            st = states[me] = CState(self._cmod, self._P, self.n, len(self.modes))
        self._cst = st
        return st

    def _c_at(self, y, yp):
        """This thread's C buffers holding y, y' and the modes."""
        st = self._c_state()
        st.y[:] = y
        st.yp[:] = yp
        if self.modes:
            st.d[:len(self.modes)] = self.modes
        return st

    def _c_events(self, t, y, yp):
        st = self._c_at(y, yp)
        st.module.events(t, *st.args, st.ev_ptr)
        return st.ev_out[:len(self.event_specs)].copy()

    # events and modes ---------------------------------------------------------------------------
    def reset_modes(self):
        """Restore the modes to their start values and clear the mode log."""
        self.modes[:] = self.mode_start
        self.mode_log = [(-math.inf, tuple(self.modes))]

    def apply_start_events(self, t, y, yp) -> list[str]:
        """Apply the actions of the ``at_start`` events already due at the start time ``t``.

        An event declared with ``at_start=True`` whose condition is at or past zero in its
        direction at ``t`` (``g >= 0`` for ``direction=1``) has its action applied now, in
        declaration order, until none is due any more (a ramp whose start and end both lie
        before ``t``). Such conditions are times (``t - t_switch``), compared with a few units
        of roundoff of ``t`` (``0.3 - (0.1 + 0.2)`` is due). Return the names of the events
        applied.
        """
        applied: list[str] = []
        slack = 8.0 * np.finfo(float).eps * max(1.0, abs(float(t)))
        y = np.asarray(y, dtype=float)
        yp = np.asarray(yp, dtype=float)
        for _ in range(len(self.event_specs) + 1):
            g = self.event_values(t, y, yp)
            due = [(k, path, spec) for k, (path, spec) in enumerate(self.event_specs)
                   if spec.at_start and spec.action is not None
                   and f"{path}.{spec.name}" not in applied
                   and (g[k] * (spec.direction or 1) >= -slack)]
            if not due:
                break
            for k, path, spec in due:
                view = self.mode_view(path)
                view.t = float(t)       # the action's time: the run's start
                view.starting = True
                view.parameter = functools.partial(self._owner_parameter, path)
                try:
                    spec.action(view)
                finally:
                    view.t = None
                    view.starting = False
                    view.parameter = None
                applied.append(f"{path}.{spec.name}")
            self.mode_log.append((float(t), tuple(self.modes)))
        return applied

    def _owner_parameter(self, owner: str, field: str):
        """The value of the runtime parameter ``owner.field`` of this system, or None."""
        info = self.parameters.get(f"{owner}.{field}")
        return None if info is None else info.value

    def mode_view(self, owner: str) -> ModeView:
        """The modes of component ``owner`` as a mutable mapping."""
        by_owner = self._lazy.get("modes_by_owner")
        if by_owner is None:     # once per compiled system: a view per event is then O(1)
            by_owner = self._lazy["modes_by_owner"] = {}
            for i, nm in enumerate(self.mode_names):
                path, _, mode = nm.rpartition(".#")
                by_owner.setdefault(path, {})[mode] = i
        return ModeView(self.modes, dict(by_owner.get(owner, {})), owner)

    def event_values(self, t, y, yp):
        """Every event function at one point."""
        if self._cmod is not None:
            return self._c_events(t, y, yp)
        if self._ev_vector is not None:
            return self._array_events(t, y, yp)
        return self._event_fn(t, y.tolist(), yp.tolist(), self.modes, self._P)

    def _array_events(self, t, y, yp):
        part = self._ev_vector
        y = np.asarray(y, dtype=float)
        yp = np.asarray(yp, dtype=float)
        out = np.empty(len(self.event_specs))
        if len(part.scalar_rows):
            out[part.scalar_rows] = self._event_fn(t, y.tolist(), yp.tolist(), self.modes,
                                                   self._P)
        modes = np.asarray(self.modes, dtype=float) if part.uses_modes else None
        with np.errstate(all="ignore"):
            for g, P in zip(part.groups, self._ev_vecP):
                Y, YP, D = g.gather(y, yp, modes)
                out[g.rows] = g.res_fn(t, Y, YP, D, P)[0]
        return out

    def solver_events(self):
        """The declared events as :class:`pvgraph.solver.Event` objects bound to this system."""
        from .solver import Event
        fn, modes, P = self._event_fn, self.modes, self._P
        if self._cmod is not None:
            g_all = self._c_events
        elif self._ev_vector is not None:
            g_all = self._array_events
        else:
            def g_all(t, y, yp):
                return fn(t, y.tolist(), yp.tolist(), modes, P)

        out = []
        for k, (path, spec) in enumerate(self.event_specs):
            out.append(Event(fun=self._event_component(k, g_all), direction=spec.direction,
                             terminal=spec.terminal,
                             action=self._event_action(path, spec), name=f"{path}.{spec.name}"))
        if self.index_reduction is not None:
            self.index_reduction.watch(out)
        return out

    def _run_events(self):
        """``solver_events()`` made once per backend: the events only read the system's
        modes, parameters and backend through the system, so runs share them."""
        cached = self.__dict__.get("_events_cache")
        if cached is None or cached[0] is not self._cmod or cached[1] is not self._ev_vector:
            cached = self.__dict__["_events_cache"] = (self._cmod, self._ev_vector,
                                                        self.solver_events())
        return list(cached[2])

    def index_report(self) -> str:
        """What index reduction did: differentiated equations, dummy derivatives, states."""
        if self.index_reduction is None:
            return "no index reduction: the system was not compiled from a circuit."
        return self.index_reduction.report()

    def _event_component(self, k, g_all):
        fn = self._event_fn
        modes = self.modes
        P = self._P

        def g(t, y, yp):
            if self._ev_vector is not None or self._cmod is not None:
                return g_all(t, y, yp)[k]
            return fn(t, y.tolist(), yp.tolist(), modes, P)[k]

        g.vector = (g_all, k)   # the solver evaluates every event in one call of g_all
        return g

    def _event_action(self, path, spec):
        if spec.action is None:
            return None
        view = self.mode_view(path)

        def act(t, y, yp):
            view.t = float(t)
            spec.action(view)
            self.mode_log.append((float(t), tuple(self.modes)))
            return None
        return act

    # names ------------------------------------------------------------------------------------
    @property
    def aliases(self) -> dict:
        """Eliminated variables: name -> ``(coef, target or None, offset)`` at these parameters."""
        if self._alias_values is None:
            P = self._P
            self._alias_values = {
                nm: (_num(c, P), t, _num(o, P)) for nm, (c, t, o) in self._alias_exprs.items()}
        return self._alias_values

    def resolve(self, name: str):
        """``(coef, index or None, offset)`` with ``name = coef * y[index] + offset``.

        ``name`` is an unknown, an eliminated alias or an exposed-port name
        (:meth:`exposed_names`); an unknown name raises ``KeyError`` with close matches.
        """
        if name in self.index:
            return 1.0, self.index[name], 0.0
        aliases = self.aliases
        if name in aliases:
            coef, target, off = aliases[name]
            return coef, (None if target is None else self.index[target]), off
        real = self._exposed().get(name)
        if real is not None and real not in self.observed:
            return self.resolve(real)
        raise KeyError(self._unknown(name))

    def resolve_name(self, name: str) -> str:
        """The canonical name of ``name``: itself for a name of :meth:`all_names`, the inner
        port variable for an exposed-port name (``"valve.P.p"`` -> ``"valve.spool.P.p"``).

        Every lookup by name (``Solution[...]``, ``sol.der``, operating points, linear models,
        sweep outputs, the command line) goes through this, so an exposed name gives exactly
        the values of its canonical variable. An unknown name raises ``KeyError`` with close
        matches, exposed names included.
        """
        if name in self.index or name in self._alias_exprs or name in self.observed:
            return name
        real = self._exposed().get(name)
        if real is None:
            raise KeyError(self._unknown(name))
        return real

    def exposed_names(self) -> dict[str, str]:
        """Names through the exposed ports of sub-circuits, ``{exposed name: canonical name}``.

        A sub-circuit ``valve`` exposing its part's port ``spool.P`` as ``P`` makes
        ``valve.P.p`` and ``valve.P.q`` names of ``valve.spool.P.p`` and ``valve.spool.P.q``
        (at any depth; a signal port's exposed name is the port itself). Where the inner node
        joins several ports, the flow ``valve.P.q`` is instead a derived output, the flow
        across the boundary (the sum of theirs; :func:`pvgraph.circuit.boundary_flows`). They are not in
        :meth:`all_names` (each variable is listed once, there, under its canonical name) but
        every lookup accepts them (:meth:`resolve_name`). Empty for a system not compiled
        from a circuit.
        """
        return dict(self._exposed())

    def _exposed(self) -> dict[str, str]:
        names = self._lazy.get("exposed_names")
        if names is None:
            raw = self._circuit.port_aliases() if self._circuit is not None else {}
            known = (self.index, self._alias_exprs, self.observed)
            names = {alias: real for alias, real in sorted(raw.items())
                     if not any(alias in k for k in known) and any(real in k for k in known)}
            self._lazy["exposed_names"] = names
        return names

    def _name_pool(self) -> list[str]:
        return list(self.index) + list(self._alias_exprs) + list(self.observed) + \
            list(self._exposed())

    def close_names(self, name: str, n: int = 3) -> list[str]:
        """Up to ``n`` names close to a misspelled ``name``: variables, aliases, derived
        outputs and exposed-port names (the suggestions of every unknown-name error)."""
        return difflib.get_close_matches(name, self._name_pool(), n=n, cutoff=0.6)

    def _unknown(self, name):
        if name in self.observed:
            reads = []
            try:
                reads = sorted({self.names[k] for op, k in
                                E.leaves(self._obs_exprs[name], ("y",))})
            except (KeyError, IndexError, TypeError, AttributeError):
                pass
            via = f" ({', '.join(reads[:4])})" if reads else ""
            return (f"{self.name}: {name!r} is a derived output, computed from the unknowns; "
                    f"it has no value of its own to set or solve for: use one of the variables "
                    f"it is computed from{via}.")
        under = sorted(n for n in self._name_pool() if n.startswith(f"{name}."))
        if under:
            more = f", ... ({len(under)} in all)" if len(under) > 6 else ""
            return (f"{self.name}: {name!r} is a component or a port, not a variable; the "
                    f"names under it: {', '.join(under[:6])}{more}.")
        close = self.close_names(name)
        hint = f" Close matches: {close}." if close else ""
        return f"{self.name}: no variable or output named {name!r}.{hint}"

    def unit(self, name: str) -> str:
        """The unit of a variable, alias, derived output or exposed name (SI)."""
        name = self.resolve_name(name)
        if name in self.observed:
            return self.observed[name][0]
        coef, idx, _ = self.resolve(name)
        # an alias keeps the unit its component declares: a rack position x = r phi is in m,
        # not in the rad of the angle it is expressed in
        own = self._alias_units.get(name)
        if own is not None:
            return own
        return "" if idx is None else self.units[idx]

    def all_names(self) -> list[str]:
        """Every variable once, by its canonical name: the unknowns (in the order of ``y``),
        the eliminated aliases, the derived outputs.

        Code that walks the variables (power per component, tables, CSV columns) relies on
        each being listed once; exposed-port names, which are second names of some of them,
        are in :meth:`exposed_names` and accepted by every lookup.
        """
        return list(self.names) + sorted(self._alias_exprs) + sorted(self.observed)

    def evaluate_observed(self, t, Y, YP, modes_per_time):
        """Derived outputs over a solution: dict name -> array (len(t))."""
        if not self.observed:
            return {}
        with np.errstate(all="ignore"):
            d = [np.asarray(m) for m in np.asarray(modes_per_time, dtype=float).T] \
                if len(self.mode_names) else []
            vals = self._observed_fn()(np.asarray(t), list(Y.T), list(YP.T), d, self._P)
        m = len(t)
        return {nm: np.broadcast_to(np.asarray(v, dtype=float), (m,)).copy()
                for nm, v in zip(self.observed, vals)}

    # parameters ---------------------------------------------------------------------------------
    @property
    def parameter_names(self) -> list[str]:
        """Names of the runtime parameters, in the order of the parameter vector."""
        return list(self.parameters)

    @property
    def parameter_values(self) -> dict[str, float]:
        """``{name: value}`` of every parameter."""
        return {nm: info.value for nm, info in self.parameters.items()}

    def parameter_table(self) -> str:
        """A plain-text table of the parameters: name, value, unit, runtime or structural."""
        rows = [f"{'parameter':40s} {'value':>12s} {'unit':>10s}  use"]
        for nm, info in self.parameters.items():
            use = ("structural: " + info.structural) if info.structural else \
                ("start value" if not info.in_equations else "runtime")
            value = f"{info.value:12.6g}" if isinstance(info.value, float) else \
                f"{f'({len(info.value)} values)':>12s}"
            rows.append(f"{nm:40s} {value} {info.unit:>10s}  {use}")
        return "\n".join(rows)

    def with_params(self, values: Mapping[str, float] | None = None, *,
                    recompile: bool = True, _starts_follow: bool = False) -> "System":
        """This system with other parameter values, sharing its compiled code.

        ``values`` maps parameter names (``"orifice.A"``: component path and field) to numbers
        (a list of ``(name, value)`` pairs is taken too).
        Values are validated by the component's parameter model (bounds, cross-field rules).
        A runtime parameter only changes the parameter vector (and the start values that depend
        on it). A structural parameter (one the equations turn into a plain number, or a field
        that is not numeric) needs a new compilation: with ``recompile=True`` that happens with
        a :class:`RecompileWarning` naming the parameters; with ``recompile=False`` a
        :class:`~pvgraph.errors.ParameterError` is raised.
        """
        from .circuit import parameter_values
        if not isinstance(recompile, (bool, np.bool_)):
            raise ParameterError(f"{self.name}: with_params(recompile=...) takes True or False, "
                                 f"got {recompile!r}")
        values = {} if values is None else parameter_values(
            values, f"{self.name}: with_params values")
        new = self._copy()
        if not values:
            return new
        updates = self._group_updates(values)
        models = {path: _updated_model(self._models[path], fields, path)
                  for path, fields in updates.items()}
        structural = []
        for path, fields in updates.items():
            for fname in fields:
                full = f"{path}.{fname}"
                info = self.parameters.get(full)
                if info is None:
                    structural.append(f"{full} (not a numeric parameter of the compiled "
                                      f"equations)")
                elif info.structural:
                    structural.append(f"{full} ({info.structural})")
        if structural:
            if not recompile or self._circuit is None:
                raise ParameterError(
                    f"{self.name}: cannot change structural parameter(s) without compiling "
                    "again: " + "; ".join(structural) + ". Use with_params(..., "
                    "recompile=True) or build and compile the circuit with the new values.")
            warnings.warn(RecompileWarning(
                f"{self.name}: compiling again, structural parameter(s) changed: "
                + "; ".join(structural)), stacklevel=2)
            return self._recompiled(models).use_backend(self.backend)
        started = {}
        for path, model in models.items():
            comp = self._components[path]
            old_starts = _starts_of(comp, self._models[path]) if any(
                self.parameters[f"{path}.{f}"].in_starts for f in updates[path]) else None
            for fname in updates[path]:
                full = f"{path}.{fname}"
                value = _field_value(model, fname)
                k = self._pindex[full]
                new._P[k] = value
                new.parameters[full] = dataclasses.replace(self.parameters[full], value=value)
            if old_starts is not None:
                started.update(new._apply_starts(path, old_starts, _starts_of(comp, model)))
            new._models[path] = model
        changed = {f"{path}.{f}" for path, fields in updates.items() for f in fields}
        for tab in self._tables:
            xs, ys = tab.sources
            if xs in changed or ys in changed:
                try:
                    new._P[tab.slot] = tab.with_values(
                        x=new._P[self._pindex[xs]] if xs else None,
                        y=new._P[self._pindex[ys]] if ys else None)
                except ValueError as exc:
                    raise ParameterError(f"{self.name}: {exc}") from None
        new._alias_values = None
        new._update_derived()
        reduction = getattr(new, "index_reduction", None)
        if reduction is not None and (started or reduction.given):
            # as a fresh compilation would: the given starts hold under the new values (a rack
            # position given stays where it is when the pinion's radius changes, the pinion
            # angle moves)
            try:
                reduction.restart(new, started)
            except InitializationError:
                if started and not _starts_follow:
                    raise    # start values given with these parameters contradict
                # the starts given when building no longer fit the joint's new ratio (a sweep
                # over a lever ratio with both ends placed): the states keep theirs and the
                # others follow; simulate(start=...), if it follows, wins, imposed there with
                # the starts this change gave
                new.y0, new.yp0 = self.y0.copy(), self.yp0.copy()
                if _starts_follow:
                    new._pending_starts = started
                else:
                    states = ", ".join(n for n, _ in reduction.states[:4])
                    warnings.warn(StartValueWarning(
                        f"{self.name}: with the new value of {', '.join(sorted(changed))} the "
                        f"start values given when building no longer fit the constraints "
                        f"(rigid joints); the states ({states}) keep their start values and the "
                        f"variables tied to them follow. Give consistent values with "
                        f"simulate(start=...) where that is not meant."),
                        stacklevel=outside_stacklevel())
        return new

    def _update_derived(self):
        """Recompute the parametric subexpressions hoisted out of the generated functions."""
        if self._derive is None:
            return
        try:
            values = self._derive(0.0, None, None, None, self._P)
            if self._vector is not None or self._ev_vector is not None:
                self._vecP, self._ev_vecP = self._array_params()
        except (ValueError, ZeroDivisionError, OverflowError) as exc:
            raise ParameterError(f"{self.name}: the parameter values give an invalid derived "
                                 f"quantity ({exc}); check the values just set") from None
        self._P[self._nbase:] = values
        self._cst = None
        self.__dict__.pop("_cstates", None)

    def _array_params(self):
        """Parameter and derived arrays of the row groups of the residual and the events."""
        P = np.array([v if isinstance(v, (int, float)) else np.nan
                      for v in self._P[:len(self.parameters)]], dtype=float)
        out = []
        for part in (self._vector, self._ev_vector):
            per_group = []
            for g in part.groups if part is not None else ():
                with np.errstate(all="ignore"):
                    Pg = g.params(P)
                if not all(np.all(np.isfinite(a)) for a in Pg[len(g.index["param"]):]):
                    raise ValueError(f"a non-finite value in {g.label}")
                per_group.append(Pg)
            out.append(per_group)
        return out

    def params_from(self, circuit) -> dict[str, float]:
        """The runtime parameter values of ``circuit``, built like the one compiled.

        Building a circuit is cheap, compiling it is not: build the circuit with other values,
        then ``system.with_params(system.params_from(circuit))`` runs it without compiling.
        Raises :class:`~pvgraph.errors.ParameterError` if the circuit differs in anything but
        runtime parameter values (another component, a structural parameter).
        """
        from .compiler import _flatten
        leaves = dict(_flatten(circuit))
        if leaves.keys() != self._components.keys():
            missing = sorted(set(self._components) ^ set(leaves))[:5]
            raise ParameterError(f"{self.name}: the circuit {circuit.name!r} has other "
                                 f"components than the compiled one: {missing}")
        out = {}
        diffs = []
        runtime = self._runtime_fields
        for path, comp in leaves.items():
            base = self._models[path]
            if type(comp) is not type(self._components[path]) or \
                    type(comp.params) is not type(base):
                diffs.append(f"{path} is a {type(comp).__name__}")
                continue
            if comp._start != self._components[path]._start:
                diffs.append(f"{path} has other start values")
            if comp.params == base:
                continue
            fields = runtime.get(path, set())
            for fname, value, old in _field_diffs(comp.params, base):
                if fname in fields:
                    out[f"{path}.{fname}"] = value
                else:
                    diffs.append(f"{path}.{fname} = {value!r} (compiled with {old!r})")
        if not diffs and self._circuit is not None and \
                _topology(circuit) != self._compiled_topology():
            diffs.append("its connections or exposed ports differ")
        if diffs:
            raise ParameterError(f"{self.name}: the circuit differs structurally from the "
                                 f"compiled one: " + "; ".join(diffs[:8]) +
                                 ". Compile it instead.")
        return out

    def _compiled_topology(self):
        """The connections and exposed ports of the compiled circuit (read at the first
        :meth:`params_from`)."""
        got = getattr(self, "_topology_key", None)
        if got is None:
            got = self._topology_key = _topology(self._circuit)
        return got

    @property
    def _runtime_fields(self) -> dict[str, set]:
        fields = self._lazy.get("runtime_fields")
        if fields is None:
            fields = {}
            for info in self.parameters.values():
                if not info.structural:
                    fields.setdefault(info.owner, set()).add(info.field)
            self._lazy["runtime_fields"] = fields
        return fields

    def parameter_jacobian(self, t, y, yp, names=None) -> np.ndarray:
        """dF/dp at ``(t, y, yp)`` as a dense ``(n, len(names))`` array (default: all)."""
        fn = self._lazy.get("dFdp")
        if fn is None:
            fn = self._lazy["dFdp"] = self._generate_dfdp()
        cols = self._param_columns(names)
        vals = np.array(fn(t, y.tolist(), yp.tolist(), self.modes, self._P), dtype=float)
        rows, pcols = self._lazy["dFdp_pattern"]
        J = np.zeros((self.n, len(self.parameters)))
        np.add.at(J, (rows, pcols), vals)
        return J[:, cols]

    def output_gradient(self, name: str, t, y, yp, names=None):
        """Partial derivatives of a named quantity: ``(d/dy (n,), d/dp (len(names),))``.

        ``name`` is an unknown, an eliminated alias or a derived output; the parameters default
        to all. Used for sensitivities of outputs: ``d out/dp = d/dy dy/dp + d/dp``.
        """
        cols = self._param_columns(names)
        gy = np.zeros(self.n)
        gp = np.zeros(len(self.parameters))
        name = self.resolve_name(name)
        if name in self.index:
            gy[self.index[name]] = 1.0
            return gy, gp[cols]
        env = _Env(t, y, yp, self.modes, self._P)
        if name in self._alias_exprs:
            coef, target, off = self._alias_exprs[name]
            yt = 0.0 if target is None else y[self.index[target]]
            if target is not None:
                gy[self.index[target]] = _num(coef, self._P)
            for (op, k), d in _param_grad(coef).items():
                gp[k] += E.evaluate(d, env) * yt
            for (op, k), d in _param_grad(off).items():
                gp[k] += E.evaluate(d, env)
            return gy, gp[cols]
        if name in self.observed:
            expr = self._obs_exprs[name]
            for (op, k), d in E.gradient(expr, ("y", "param")).items():
                v = E.evaluate(d, env)
                if op == "y":
                    gy[k] += v
                else:
                    gp[k] += v
            return gy, gp[cols]
        raise KeyError(self._unknown(name))

    def observed_gradient(self, name: str, t, y, yp):
        """Partial derivatives of the derived output ``name`` with respect to the unknowns
        and their rates at ``(t, y, yp)``: ``(d/dy (n,), d/dy' (n,))``."""
        name = self.resolve_name(name)
        if name not in self.observed:
            raise KeyError(f"{name!r} is not a derived output of {self.name}")
        env = _Env(t, y, yp, self.modes, self._P)
        gy, gyp = np.zeros(self.n), np.zeros(self.n)
        for (op, k), d in E.gradient(self._obs_exprs[name], ("y", "yp")).items():
            (gy if op == "y" else gyp)[k] += E.evaluate(d, env)
        return gy, gyp

    def _param_columns(self, names):
        if names is None:
            return list(range(len(self.parameters)))
        cols = []
        for nm in names:
            if nm not in self._pindex:
                raise ParameterError(self._unknown_parameter(nm))
            why = getattr(self.parameters.get(nm), "structural", "")
            if why:
                raise ParameterError(
                    f"{self.name}: parameter {nm!r} is structural ({why}): the compiled "
                    f"equations hold it as a number, so their derivative with respect to it "
                    f"is not known; differentiate rebuilt circuits instead (linearize_circuit, "
                    f"finite differences)")
            cols.append(self._pindex[nm])
        return cols

    def _generate_dfdp(self):
        entries = []
        exprs = self._lazy.pop("residual_exprs", None)
        if exprs is None:   # rows of array groups are rebuilt from their templates
            scalar_rows, scalar_res = self._lazy.pop("residual_scalar")
            exprs = [None] * self.n
            for i, r in zip(scalar_rows, scalar_res):
                exprs[i] = r
            for g in self._vector.groups:
                for i, r in zip(g.rows.tolist(), g.instances()):
                    exprs[i] = r
        for i, r in enumerate(exprs):
            for (op, k), d in E.gradient(r, ("param",)).items():
                if not E.is_const(d, 0.0):
                    entries.append((i, k, d))
        self._lazy["dFdp_pattern"] = (np.array([r for r, _, _ in entries], dtype=np.int64),
                                      np.array([k for _, k, _ in entries], dtype=np.int64))
        src, tabs = codegen.generate("param_jacobian", [d for _, _, d in entries],
                                     extra_args=("P",))
        self._sources.append(src)
        return codegen.compile_function("param_jacobian", src, tabs)

    def _unknown_parameter(self, name):
        close = difflib.get_close_matches(name, list(self.parameters), n=3, cutoff=0.6)
        hint = f" Close matches: {close}." if close else ""
        return (f"{self.name}: no parameter named {name!r}.{hint} Parameters are named "
                f"<component path>.<field>; system.parameter_names lists them.")

    def _group_updates(self, values):
        """``{component path: {field: value}}``; unknown names raise with close matches."""
        out: dict[str, dict] = {}
        for name, value in values.items():
            if not isinstance(name, str):
                raise ParameterError(f"{self.name}: parameter names are strings, got {name!r}")
            path, fname = self._split_name(name)
            out.setdefault(path, {})[fname] = value
        return out

    def _split_name(self, name):
        if name in self.parameters:
            info = self.parameters[name]
            return info.owner, info.field
        parts = name.split(".")
        for k in range(len(parts) - 1, 0, -1):
            path = ".".join(parts[:k])
            if path in self._components:
                fname = ".".join(parts[k:])
                if _has_field(self._components[path].params, fname):
                    return path, fname
        pool = list(self.parameters) + [
            f"{path}.{f}" for path, c in self._components.items()
            for f in type(c.params).model_fields]
        close = difflib.get_close_matches(name, list(dict.fromkeys(pool)), n=3, cutoff=0.6)
        hint = f" Close matches: {close}." if close else ""
        raise ParameterError(f"{self.name}: no parameter named {name!r}.{hint} Parameters are "
                             f"named <component path>.<field>; system.parameter_names lists "
                             f"the runtime ones.")

    def _apply_starts(self, path, old, new):
        changed = {}
        for key, value in new.items():
            if old.get(key) == value:
                continue
            changed[f"{path}.{key}"] = float(value)
            try:
                coef, idx, off = self.resolve(f"{path}.{key}")
            except KeyError:
                continue
            if idx is not None and coef != 0.0:
                self.y0[idx] = (value - off) / coef
        return changed

    def _copy(self) -> "System":
        new = copy.copy(self)
        new._cst = None
        new.__dict__.pop("_cstates", None)
        new.__dict__.pop("_events_cache", None)     # bound to this system
        new._P = list(self._P)
        new.parameters = dict(self.parameters)
        new._models = dict(self._models)
        new.modes = list(self.mode_start)
        new.mode_log = [(-math.inf, tuple(new.modes))]
        new.counters = {k: 0 for k in self.counters}
        new.y0 = self.y0.copy()
        new.yp0 = self.yp0.copy()
        return new

    def _recompiled(self, models, **options):
        """The circuit compiled again with the components' parameter models of this system
        updated by ``models`` (``{path: model}``); ``options`` go to ``compile_circuit``."""
        from .compiler import compile_circuit
        comps = self._components
        merged = {path: m for path, m in self._models.items() if m is not comps[path].params}
        merged.update(models)
        saved = {path: comps[path].params for path in merged}
        try:
            for path, model in merged.items():
                comps[path].params = model
            system = compile_circuit(self._circuit, **options)
            system.__dict__.pop("_known_roles", None)   # needed by Circuit.compile only
            return system
        finally:
            for path, model in saved.items():
                comps[path].params = model

    @property
    def _obs_exprs(self) -> dict:
        """Derived outputs by name, as expressions of the unknowns and parameters."""
        exprs = self._lazy.get("observed_exprs")
        if exprs is None:
            names, raw, leaf = self._lazy.pop("observed_raw", ((), (), None))
            exprs = self._lazy["observed_exprs"] = dict(zip(names, E.substitute(list(raw), leaf)))
        return exprs

    def _observed_fn(self):
        fn = self._lazy.get("observed_fn")
        if fn is None:
            exprs = self._obs_exprs
            names = list(exprs)
            exprs = list(exprs.values())
            src, tabs = codegen.generate("observed", exprs, flavour="array", extra_args=("P",),
                                         comments=names)
            self._lazy["observed_src"] = src
            fn = self._lazy["observed_fn"] = codegen.compile_function("observed", src, tabs)
        return fn

    def source(self) -> str:
        """The generated Python source of the residual, Jacobian, events and outputs."""
        head = "".join(f"# P[{k}] = {nm} [{info.unit}]\n"
                       for k, (nm, info) in enumerate(self.parameters.items()))
        if self.observed:
            self._observed_fn()
        extra = [self._lazy[k] for k in ("observed_src",) if k in self._lazy]
        return head + "\n" + "\n\n".join(list(self._sources) + extra)

    def __repr__(self):
        return (f"<System {self.name}: {self.n} unknowns ({int(self.differential.sum())} "
                f"differential), {len(self._rows)} Jacobian non-zeros, {len(self.event_specs)} "
                f"events>")


def _nan_where_not_finite(values):
    bad = ~np.isfinite(values)
    if bad.any():
        values[bad] = np.nan
    return values


# helpers for parameters ----------------------------------------------------------------------

def _hoist(groups, base):
    """Move the largest parametric subexpressions of ``groups`` (lists of roots) out.

    Returns the rewritten groups, where each such subexpression is the leaf ``P[base + k]``,
    and the list of the subexpressions (for the ``derive`` function that computes them).
    """
    roots = [r for g in groups for r in g]
    order = E.postorder(roots)
    fixed_leaves = E.FIXED_LEAVES
    fixed: dict[int, bool] = {}
    hoist: set[int] = set()
    for node in order:
        args = node.args
        if not args:
            fixed[id(node)] = node.op in fixed_leaves
            continue
        flags = [fixed[id(a)] for a in args]
        if all(flags):
            fixed[id(node)] = True
            continue
        fixed[id(node)] = False
        for a, f in zip(args, flags):   # a parametric child of a varying node: hoist it
            if f and a.args:
                hoist.add(id(a))
    for r in roots:
        if fixed[id(r)] and r.args:
            hoist.add(id(r))
    derived: list = []
    memo: dict[int, E.Expr] = {}
    for node in order:
        k = id(node)
        if k in hoist:
            memo[k] = E.Expr("param", (), base + len(derived))
            derived.append(node)
        elif fixed[k] or not node.args:
            memo[k] = node
        else:
            args = tuple([memo[id(a)] for a in node.args])
            same = True
            for x, y in zip(args, node.args):
                if x is not y:
                    same = False
                    break
            memo[k] = node if same else E.Expr(node.op, args, node.value)
    return [[memo[id(r)] for r in g] for g in groups], derived


def _num(x, P) -> float:
    return x if isinstance(x, float) else E.evaluate(x, P)


class _Env:
    """Leaf values for :func:`pvgraph.expr.evaluate` at one point of a run."""

    def __init__(self, t, y, yp, modes, P):
        self.t, self.y, self.yp, self.modes, self.P = t, y, yp, modes, P

    def __getitem__(self, k):
        return self.P[k]

    def table(self, tab):
        return self.P[tab.slot]

    def leaf(self, node):
        op = node.op
        if op == "y":
            return float(self.y[node.value])
        if op == "yp":
            return float(self.yp[node.value])
        if op == "time":
            return float(self.t)
        if op == "mode":
            return float(self.modes[node.value])
        raise TypeError(f"cannot evaluate the leaf {node.op}")


def _param_grad(x) -> dict:
    if isinstance(x, float):
        return {}
    return E.gradient(x, ("param",))


def _has_field(model, dotted: str) -> bool:
    *groups, leaf = dotted.split(".")
    for g in groups:
        if g not in type(model).model_fields:
            return False
        model = getattr(model, g)
        if not hasattr(type(model), "model_fields"):
            return False
    return leaf in type(model).model_fields


def _field_value(model, dotted: str):
    for part in dotted.split("."):
        model = getattr(model, part)
    return model


def _updated_model(model, fields: dict, path: str):
    """A validated copy of a component's parameter model with dotted ``fields`` replaced."""
    from pydantic import ValidationError

    from .component import _describe_validation
    data = model.model_dump()
    for dotted, value in fields.items():
        *groups, leaf = dotted.split(".")
        node = data
        for g in groups:
            node = node[g]
        node[leaf] = value
    try:
        return type(model).model_validate(data)
    except ValidationError as exc:
        raise ParameterError(_describe_validation(path, exc, list(type(model).model_fields),
                                                  fields, type(model))) \
            from None


def _topology(circuit):
    """Components (path, type), connections and exposed ports of ``circuit``, to any depth,
    without its name: equal for two circuits of one structure."""
    from .circuit import _structure_key
    return _structure_key(circuit, {})[2:]


def _field_diffs(new, old, prefix=""):
    """``(dotted field, new value, old value)`` of the fields where two models differ."""
    out = []
    for name in type(old).model_fields:
        a, b = getattr(new, name), getattr(old, name)
        if a == b:
            continue
        if hasattr(type(a), "model_fields") and type(a) is type(b):
            out.extend(_field_diffs(a, b, f"{prefix}{name}."))
        else:
            out.append((prefix + name, a, b))
    return out


def _starts_of(comp, model) -> dict:
    """The start values ``comp`` takes from the parameter model ``model``."""
    values = {}
    for name, var in type(comp).variables.items():
        values[name] = var.start(model) if callable(var.start) else var.start
    values.update(comp.starts(model))
    values.update(comp._start)
    return values


def build_system(name, equations, infos, subs, observed, events, mode_names, mode_start,
                 parameters=None, tables=(), array_rows=None, provenance=None):
    """Number the unknowns and parameters, differentiate, generate code, run the checks.

    ``parameters`` maps the names of the runtime parameters to their
    :class:`~pvgraph.component.ParameterInfo`, in the order of the parameter vector.
    ``array_rows``: None evaluates row shapes repeated at least ``ARRAY_MIN_GROUP`` times as
    arrays in systems of at least ``ARRAY_MIN_ROWS`` rows; True does so for every shape shared
    by two rows or more; False never (straight-line code only).
    ``provenance``: the compiler's record of rows that are one graph up to their names
    (``rows[id(row)] -> (row, key, names, ...)``, see :class:`pvgraph.compiler._Provenance`),
    whose row shapes are then found once per key.
    """
    from .compiler import check_structure

    parameters = dict(parameters or {})
    pindex = dict(zip(parameters, range(len(parameters))))
    tables = list(tables)
    for j, tab in enumerate(tables):  # runtime tables follow the parameters in P
        tab.slot = len(parameters) + j
    names = [nm for nm in infos if nm not in subs]
    index = dict(zip(names, range(len(names))))
    mode_index = {nm: j for j, nm in enumerate(mode_names)}

    def param_leaf(node):
        if node.op == "param" and isinstance(node.value, str):
            return E.Expr("param", (), pindex[node.value])
        return None

    def numbered(x):
        if isinstance(x, float):
            return x
        if x.op == "param":    # a parameter leaf (the common case), as substitute makes it
            got = param_leaf(x)
            return x if got is None else got
        return E.substitute([x], param_leaf)[0]

    subs = {nm: (numbered(c), t, numbered(o)) for nm, (c, t, o) in subs.items()}

    def term(coef):
        return coef if isinstance(coef, E.Expr) else E.const(coef)

    def leaf(node):
        if node.op == "sym":
            if node.value in index:
                return E.Expr("y", (), index[node.value])
            if node.value in mode_index:
                return E.Expr("mode", (), mode_index[node.value])
            if node.value in subs:
                coef, target, off = subs[node.value]
                if target is None:
                    return term(off)
                return term(coef) * E.Expr("y", (), index[target]) + off
        if node.op == "der":
            if node.value in index:
                return E.Expr("yp", (), index[node.value])
            if node.value in subs:
                coef, target, _ = subs[node.value]
                return E.ZERO if target is None else term(coef) * E.Expr("yp", (),
                                                                          index[target])
        return param_leaf(node)

    def compiled_leaf(node):
        # the (kind, payload) of the single compiled leaf a traced leaf becomes, if it is one
        op = node.op
        if op == "sym":
            if node.value in index:
                return "y", index[node.value]
            if node.value in mode_index:
                return "mode", mode_index[node.value]
        elif op == "der":
            if node.value in index:
                return "yp", index[node.value]
        elif op == "param" and isinstance(node.value, str):
            return "param", pindex[node.value]
        return None

    raw = [eq.expr for eq in equations]
    labels = [eq.label for eq in equations]
    del equations

    # rows of one shape repeated often enough are evaluated as arrays over their instances
    # (templated from the traced rows directly); the others get straight-line code
    shape_cache: dict = {}
    # what a name is to compiled_leaf, in the low three bits: 1 an unknown, 2 a mode, 4 a
    # parameter (summed), and above them its number as that (a name of one kind only)
    code: dict[str, int] = dict(zip(pindex, range(4, 8 * len(pindex) + 4, 8)))
    several = index.keys() & code.keys()
    code.update(zip(index, range(1, 8 * len(index) + 1, 8)))
    for nm in several:
        code[nm] = 5
    for nm, j in mode_index.items():
        c = code.get(nm)
        code[nm] = (j << 3) | 2 if c is None else (c & 7) | 2

    def category_of(nm):
        return code.get(nm, 0) & 7
    # id(row) -> (row, key, names, ...), as provenance.get(row) reads it
    prov_rows = provenance.rows if provenance is not None else None

    def shape_of(row):
        # rows of one provenance key and one kind of compiled leaf per name have one shape;
        # their slots read the same names (by their place in the key's names)
        p = prov_rows.get(id(row)) if prov_rows is not None else None
        if p is None or p[0] is not row:
            return codegen.row_shape(row, compiled_leaf)
        _, key, names = p[:3]
        kinds = tuple(map(category_of, names))
        hit = shape_cache.get((key, kinds))
        if hit is None:
            got = codegen.row_shape(row, compiled_leaf)
            if got is None:
                shape_cache[(key, kinds)] = (None, None)
                return None
            place = {}
            for c, nm in enumerate(names):
                if nm in index:
                    place["y", index[nm]] = place["yp", index[nm]] = c
                if nm in mode_index:
                    place["mode", mode_index[nm]] = c
                if nm in pindex:
                    place["param", pindex[nm]] = c
            shape_cache[(key, kinds)] = (got[0], {kind: [place[kind, v] for v in vals]
                                                  for kind, vals in got[1].items()})
            return got
        shape, slots = hit
        if shape is None:
            return None
        return shape, _Slots(names, slots, lookup)

    lookup = {"y": index, "yp": index, "param": pindex, "mode": mode_index}

    def shapes_of(rows):
        """``(shapes, blocks)``: :func:`shape_of` of each row, but the rows of one provenance
        key whose names are of one kind per place share one shape and are given together, as
        blocks ``(shape, positions, payloads)`` (``payloads[kind]``: the payload of each slot
        of that kind, a row per position; their place in ``shapes`` holds ``IN_BLOCK``). The
        kinds of the names of a key's rows are looked up together."""
        if prov_rows is None:
            return [shape_of(r) for r in rows], []
        out = [None] * len(rows)
        blocks = []
        by_key: dict = {}     # (key, number of names) -> (positions, names of each row)
        for i, row in enumerate(rows):
            p = prov_rows.get(id(row))
            if p is None or p[0] is not row:
                out[i] = codegen.row_shape(row, compiled_leaf)
                continue
            names = p[2]
            b = by_key.get((p[1], len(names)))
            if b is None:
                b = by_key[p[1], len(names)] = ([], [])
            b[0].append(i)
            b[1].append(names)
        for (key, width), (at, names_of) in by_key.items():
            codes = np.fromiter(map(code.get, itertools.chain.from_iterable(names_of),
                                    itertools.repeat(0)), dtype=np.int64,
                                count=width * len(at)).reshape(len(at), width)
            kinds = codes & 7
            alike = (kinds == kinds[0]).all(axis=1)
            if not np.isin(kinds[0], (0, 1, 2, 4)).all():
                alike[:] = False    # a name of several kinds: row by row
            if alike[0]:    # the first row computes (or finds) the shape of the alike rows
                shape_of(rows[at[0]])
                shape, slots = shape_cache[key, tuple(kinds[0].tolist())]
                if shape is not None:   # their slot payloads, as arrays
                    mine = np.asarray(at, dtype=np.int64)[alike]
                    got = codes[alike]
                    blocks.append((shape, mine, {kind: got[:, places] >> 3
                                                 for kind, places in slots.items()}))
                    for i in mine.tolist():
                        out[i] = IN_BLOCK
            for j in np.flatnonzero(~alike).tolist():
                out[at[j]] = shape_of(rows[at[j]])
        return out, blocks

    groups, scalar_rows = _array_groups(raw, array_rows, compiled_leaf, shapes_of=shapes_of)
    scalar_raw = [raw[i] for i in scalar_rows] if groups else list(raw)
    # long sums of unknowns with constant coefficients (the flow balance of a node joining many
    # ports) are kept as a sparse matrix rather than as straight-line code; rows -> {column:
    # [dF/dy, dF/dy']} of those terms, the rest of the row staying in scalar_raw
    linear: dict[int, dict] = {}
    if array_rows is True or (array_rows is None and len(raw) >= ARRAY_MIN_ROWS):
        for k, i in enumerate(scalar_rows):
            got = _split_linear(scalar_raw[k], index, subs)
            if got is not None:
                scalar_raw[k], linear[i] = got
    scalar_res = E.substitute(scalar_raw, leaf)
    del scalar_raw

    # every partial derivative of a row in one reverse pass over it
    inc_y: list = [None] * len(raw)
    inc_yp: list = [None] * len(raw)
    entries = []
    lin_entries: list = []    # (row, column, dF/dy, dF/dy') of the sparse sums, constants
    for i, r in zip(scalar_rows, scalar_res):
        grads = E.gradient(r, ("y", "yp"))
        dy, dyp = {}, {}
        for (op, k), d in grads.items():
            if op == "y":
                dy[k] = d
            else:
                dyp[k] = d
        terms = linear.get(i)
        if terms:
            # a column the rest of the row reads takes the constant into its expression;
            # the others are constant entries of their own
            for j, (a, b) in terms.items():
                if j in dy or j in dyp:
                    if a:
                        dy[j] = dy.get(j, E.ZERO) + a
                    if b:
                        dyp[j] = dyp.get(j, E.ZERO) + b
                    continue
                lin_entries.append((i, j, a, b))
            inc_y[i] = sorted(dy.keys() | {j for j, (a, _) in terms.items() if a})
            inc_yp[i] = sorted(dyp.keys() | {j for j, (_, b) in terms.items() if b})
        else:
            inc_y[i] = sorted(dy)
            inc_yp[i] = sorted(dyp)
        for j in sorted(dy.keys() | dyp.keys()):
            d = dy.get(j, E.ZERO)
            if j in dyp:
                d = d + E.CJ * dyp[j]
            entries.append(_Entry(i, j, d))
    for g in groups:
        g.differentiate()
        for row, ys, yps in zip(g.rows.tolist(), g.payload_rows("y"), g.payload_rows("yp")):
            inc_y[row] = sorted(ys)
            inc_yp[row] = sorted(yps)
    differential = np.zeros(len(names), dtype=bool)
    differential[np.fromiter(itertools.chain.from_iterable(inc_yp), dtype=np.int64)] = True
    check_structure(names, labels, inc_y, inc_yp, differential)
    del inc_y, inc_yp
    arrays = bool(groups or linear)
    if not arrays:
        entries.sort(key=lambda en: (en.col, en.row))

    # events: repeated shapes as arrays too
    ev_raw = [ev.condition for _, ev in events]
    ev_groups, ev_scalar = _array_groups(ev_raw, array_rows, compiled_leaf, len(raw),
                                         shapes_of=shapes_of)
    ev_exprs = E.substitute([ev_raw[i] for i in ev_scalar], leaf) if ev_scalar else []

    # parametric subexpressions (constants and parameters only) are computed once per parameter
    # set, into P after the parameters and runtime tables, not at every call
    obs_names = list(observed)
    base = len(parameters) + len(tables)
    groups_h = [scalar_res, [en.expr for en in entries], ev_exprs]
    (res_h, jac_h, ev_h), derived = _hoist(groups_h, base)
    der_src, der_tabs = codegen.generate("derive", derived, extra_args=("P",))
    derive_fn = codegen.compile_function("derive", der_src, der_tabs)

    res_src, res_tabs = codegen.generate("residual", res_h,
                                         comments=[labels[i] for i in scalar_rows],
                                         extra_args=("P",))
    jac_src, jac_tabs = codegen.generate(
        "jacobian", jac_h, extra_args=("P", "c"),
        comments=[f"d/d {names[en.col]} of row {en.row}" for en in entries])
    residual_fn = codegen.compile_function("residual", res_src, res_tabs)
    jac_fn = codegen.compile_function("jacobian", jac_src, jac_tabs)

    ev_labels = [f"{p}.{ev.name}" for p, ev in events]
    ev_src, ev_tabs = codegen.generate("events", ev_h, extra_args=("P",),
                                       comments=[ev_labels[i] for i in ev_scalar])
    event_fn = codegen.compile_function("events", ev_src, ev_tabs)

    observed_fn = None   # generated when first needed (results are often read by name only)
    sources = [der_src, res_src, jac_src, ev_src]

    if arrays:
        rows, cols, vector = _array_layout(entries, groups, scalar_rows, lin_entries,
                                           len(names))
        for k, g in enumerate(groups):
            sources.append(g.generate(f"{k}", labels))
        if linear:
            sources.append(_linear_source(linear, labels, names))
    else:
        rows, cols, vector = [en.row for en in entries], [en.col for en in entries], None
    ev_vector = None
    if ev_groups:
        ev_vector = _ArrayPart(ev_groups, np.asarray(ev_scalar, dtype=np.int64), None)
        for k, g in enumerate(ev_groups):
            sources.append(g.generate(f"events_{k}", ev_labels, jacobian=False))

    meta = list(map(operator.attrgetter("start", "nominal", "unit", "description"),
                    map(infos.__getitem__, names)))
    starts, nominals, units, descriptions = ([m[k] for m in meta] for k in range(4))
    system = System(
        name, names, differential, starts, nominals, units, descriptions, labels,
        rows, cols, residual_fn, jac_fn,
        observed_fn, {nm: (observed[nm][1], observed[nm][2]) for nm in obs_names}, event_fn,
        events, mode_names, mode_start, subs, sources)
    system._alias_units = {nm: infos[nm].unit for nm in subs}
    system._vector = vector
    system._ev_vector = ev_vector
    system.parameters = parameters
    system._pindex = pindex
    system._P = [info.value if isinstance(info.value, tuple) else float(info.value)
                 for info in parameters.values()] + tables + [0.0] * len(derived)
    system._tables = tables
    system._derive = derive_fn
    system._nbase = base
    if not arrays and not ev_groups:   # the C route (pvgraph.cbackend) writes these
        system._lazy["c_exprs"] = (res_h, jac_h, ev_h)
    system._update_derived()
    # for dF/dp, numbered and differentiated when first asked
    if groups:
        system._lazy["residual_scalar"] = (scalar_rows, scalar_res)
    else:
        system._lazy["residual_exprs"] = scalar_res
    # derived outputs are numbered and generated when first read
    system._lazy["observed_raw"] = (obs_names, [observed[nm][0] for nm in obs_names], leaf)
    system._models = {}
    system.reset_modes()
    return system


# rows evaluated as arrays ----------------------------------------------------------------------

#: a circuit with at least this many residual rows evaluates repeated row shapes as arrays
ARRAY_MIN_ROWS = 1000
#: ... a shape shared by at least this many rows
ARRAY_MIN_GROUP = 32
#: ... and a sum of at least this many unknowns with constant coefficients as a sparse matrix
LINEAR_MIN_TERMS = 32


class _ArrayRows:
    """Residual rows of one shape: one template, evaluated over arrays of their instances.

    ``rows`` are the row numbers; ``index[kind][s]`` is the array of payloads (unknown,
    parameter or mode numbers) slot ``s`` of that kind takes in each instance. Built from
    the group's members (see :func:`_slot_arrays`) and the row ``expr`` of its first
    member.
    """

    def __init__(self, members, expr, leaf_of=None):
        self.rows, self.index, first = _slot_arrays(members)
        self.template = codegen.template(expr, first, leaf_of)
        self.label = ""     # a row of the group, for messages
        self.nderived = 0
        self.columns = []   # (kind, slot) of each Jacobian column of the template
        self.jac = []       # d row / d column (+ c d row / d column') per column
        self.res_fn = self.jac_fn = self.der_fn = None
        self.jac_pos: list = []

    def instances(self):
        """The rows as expressions of the unknowns and parameters, rebuilt from the template."""
        order = E.postorder([self.template])
        payload = {kind: np.stack(idx, axis=1).tolist() if idx else None
                   for kind, idx in self.index.items()}
        out = []
        for k in range(len(self.rows)):
            memo: dict[int, E.Expr] = {}
            for node in order:
                if node.args:
                    memo[id(node)] = E.Expr(node.op, tuple([memo[id(a)] for a in node.args]),
                                            node.value)
                elif node.op in codegen.SLOT_LEAVES:
                    memo[id(node)] = E.Expr(node.op, (), payload[node.op][k][node.value])
                else:
                    memo[id(node)] = node
            out.append(memo[id(self.template)])
        return out

    def payload_rows(self, kind):
        """Per instance, the payloads of the slots of ``kind`` (a list per row)."""
        idx = self.index[kind]
        if not idx:
            return [()] * len(self.rows)
        return np.stack(idx, axis=1).tolist()

    def differentiate(self):
        """The template's partial derivatives, merged per unknown as in scalar rows."""
        grads = E.gradient(self.template, ("y", "yp"))
        dy = {k: d for (op, k), d in grads.items() if op == "y"}
        dyp = {k: d for (op, k), d in grads.items() if op == "yp"}
        pairs = self._pairs()
        merged = {s: y for s, y in pairs.items() if y >= 0}
        for s in sorted(dy):
            d = dy[s]
            for sp, sy in merged.items():
                if sy == s and sp in dyp:
                    d = d + E.CJ * dyp[sp]
            self.columns.append(("y", s))
            self.jac.append(d)
        for sp in sorted(dyp):
            if sp in merged:
                continue
            self.columns.append(("yp", sp))
            self.jac.append(E.ZERO + E.CJ * dyp[sp])

    def _pairs(self):
        """Derivative slot -> value slot reading the same unknown (-1: none), from instance 0."""
        ys = {int(a[0]): s for s, a in enumerate(self.index["y"])}
        return {s: ys.get(int(a[0]), -1) for s, a in enumerate(self.index["yp"])}

    def generate(self, k, labels, jacobian=True):
        """Compile the template's residual, Jacobian and derived parameters; return the source.

        ``k`` names the functions (``residual_k``...); ``labels`` are the rows' labels.
        """
        nparam = len(self.index["param"])
        self.label = labels[self.rows[0]]
        (res_h, jac_h), derived = _hoist([[self.template], self.jac], nparam)
        self.nderived = len(derived)
        head = (f"# rows of shape {k}: {len(self.rows)} instances, e.g. {self.label}; "
                f"y[s] is the array of slot s over the instances")
        parts = [("derive", derived, ("P",)), ("residual", res_h, ("P",))]
        if jacobian:
            parts.append(("jacobian", jac_h, ("P", "c")))
        srcs = []
        for what, roots, extra in parts:
            fname = f"{what}_{k}"
            src, tabs = codegen.generate(fname, roots, flavour="rows", extra_args=extra)
            setattr(self, f"{what[:3]}_fn", codegen.compile_function(fname, src, tabs))
            srcs.append(src)
        return head + "\n" + "\n\n".join(srcs)

    def gather(self, y, yp, modes):
        """The slot arrays of one call: ``(y, yp, modes)`` lists."""
        return ([y[i] for i in self.index["y"]], [yp[i] for i in self.index["yp"]],
                [modes[i] for i in self.index["mode"]] if self.index["mode"] else ())

    def params(self, P):
        """Parameter slot arrays followed by the derived parametric arrays (``P`` numeric)."""
        base = [P[i] for i in self.index["param"]]
        if not self.nderived:
            return base
        return base + [np.broadcast_to(np.asarray(v, dtype=float), self.rows.shape)
                       for v in self.der_fn(0.0, None, None, None, base)]


class _Slots:
    """The payloads of a row's slots, per kind, as the names of its provenance key's places:
    ``slots[kind]`` lists the place of each slot's name, ``lookup[kind]`` numbers names."""

    __slots__ = ("names", "slots", "lookup")

    def __init__(self, names, slots, lookup):
        self.names = names
        self.slots = slots
        self.lookup = lookup

    def __getitem__(self, kind):
        number, names = self.lookup[kind], self.names
        return [number[names[c]] for c in self.slots[kind]]


#: the place in :func:`build_system`'s row shapes of a row given in a block
IN_BLOCK = object()


def _slot_arrays(members):
    """``(rows, index, first)`` of the members of a group of rows of one shape: the row
    numbers in order, ``{kind: [payload of slot s in each row (an array), ...]}`` and the
    payloads of the first row (``{kind: list}``). A member is a row ``(number, leaves)``
    (leaves as :func:`pvgraph.codegen.row_shape` gives them, or :class:`_Slots`, looked up in
    bulk per provenance key) or a block ``(numbers, payloads)`` (see ``shapes_of`` in
    :func:`build_system`)."""
    single = [(i, lv) for i, lv in members if i.__class__ is int]
    parts = [at for at, _ in members if at.__class__ is not int]
    rows = np.sort(np.concatenate([np.fromiter((i for i, _ in single), dtype=np.int64,
                                               count=len(single))] + parts))
    head = int(rows[0])
    first = next((lv for i, lv in single if i == head), None)
    if first is None:
        first = next({kind: p[0].tolist() for kind, p in payloads.items()}
                     for at, payloads in members if at.__class__ is not int and at[0] == head)
    elif first.__class__ is _Slots:
        first = {kind: first[kind] for kind in codegen.SLOT_LEAVES}
    n = len(rows)
    out = {kind: [np.empty(n, dtype=np.int64) for _ in range(len(first[kind]))]
           for kind in codegen.SLOT_LEAVES}
    for at, payloads in members:
        if at.__class__ is int:
            continue
        pos = np.searchsorted(rows, at)
        for kind in codegen.SLOT_LEAVES:
            got = payloads[kind]
            for s in range(got.shape[1]):
                out[kind][s][pos] = got[:, s]
    batches: dict[int, tuple] = {}
    where = np.searchsorted(rows, [i for i, _ in single]).tolist()
    for k, (_, lv) in zip(where, single):
        if lv.__class__ is _Slots:
            b = batches.get(id(lv.slots))
            if b is None:
                b = batches[id(lv.slots)] = (lv.slots, lv.lookup, [], [])
            b[2].append(k)
            b[3].append(lv.names)
        else:
            for kind in codegen.SLOT_LEAVES:
                for s, v in enumerate(lv[kind]):
                    out[kind][s][k] = v
    for slots, lookup, at, names in batches.values():
        at = np.asarray(at, dtype=np.int64)
        for kind in codegen.SLOT_LEAVES:
            number = lookup[kind].__getitem__
            for s, c in enumerate(slots[kind]):
                out[kind][s][at] = np.fromiter(map(number, map(operator.itemgetter(c), names)),
                                               dtype=np.int64, count=len(names))
    return rows, out, first


class _ArrayPart:
    """How a system's residual (or events) and Jacobian values are assembled from row groups.

    ``scalar_rows`` are the rows of the straight-line code, ``scalar_pos`` the places of its
    Jacobian values in the pattern.
    """

    def __init__(self, groups, scalar_rows, scalar_pos=None):
        self.groups = groups
        self.scalar_rows = scalar_rows
        self.scalar_pos = scalar_pos
        self.uses_modes = any(g.index["mode"] for g in groups)
        self.linear = None      # _SparseSums, if any


def _array_groups(exprs, array_rows, leaf_of=None, n_rows=None, shapes_of=None):
    """Split rows into groups of one shape (evaluated as arrays) and the rest.

    ``n_rows`` (default ``len(exprs)``) is the size of the system, for the automatic choice;
    ``shapes_of(rows)`` gives :func:`pvgraph.codegen.row_shape` of each row, and blocks of
    rows of one shape (see ``shapes_of`` in :func:`build_system`; default: each row's shape
    computed). Groups are listed in the order of their first rows.
    """
    size = len(exprs) if n_rows is None else n_rows
    if not exprs or array_rows is False or (array_rows is None and size < ARRAY_MIN_ROWS):
        return [], list(range(len(exprs)))
    min_group = 2 if array_rows is True else ARRAY_MIN_GROUP
    by_shape: dict = {}     # shape -> [first row, number of rows, members]
    of_object: dict = {}    # id(shape) -> its entry (rows of one block share the object)
    scalar = []
    if shapes_of is None:
        shapes, blocks = [codegen.row_shape(r, leaf_of) for r in exprs], []
    else:
        shapes, blocks = shapes_of(exprs)

    def entry(shape, first):
        got = of_object.get(id(shape))
        if got is None:
            got = by_shape.get(shape)
            if got is None:
                got = by_shape[shape] = [first, 0, []]
            of_object[id(shape)] = got
        return got
    for i, shape in enumerate(shapes):
        if shape is None:
            scalar.append(i)
        elif shape is not IN_BLOCK:
            got = entry(shape[0], i)
            got[1] += 1
            got[2].append((i, shape[1]))
    for shape, at, payloads in blocks:
        got = entry(shape, int(at[0]))
        got[0] = min(got[0], int(at[0]))
        got[1] += len(at)
        got[2].append((at, payloads))
    groups = []
    for first, count, members in sorted(by_shape.values(), key=operator.itemgetter(0)):
        if count < min_group:
            for at, _ in members:
                scalar.extend([at] if at.__class__ is int else at.tolist())
            continue
        groups.append(_ArrayRows(members, exprs[first], leaf_of))
    scalar.sort()
    return groups, scalar


def _array_layout(entries, groups, scalar_rows, lin_entries=(), n=0):
    """The Jacobian pattern (CSC order) of scalar entries, groups and the constant entries of
    sparse sums (``(row, column, dF/dy, dF/dy')``, ``n`` unknowns), and where each goes."""
    rows = [np.array([en.row for en in entries], dtype=np.int64)]
    cols = [np.array([en.col for en in entries], dtype=np.int64)]
    for g in groups:
        for kind, s in g.columns:
            rows.append(g.rows)
            cols.append(g.index[kind][s])
    lin = np.array(lin_entries, dtype=float).reshape(-1, 4)
    rows.append(lin[:, 0].astype(np.int64))
    cols.append(lin[:, 1].astype(np.int64))
    all_rows, all_cols = np.concatenate(rows), np.concatenate(cols)
    order = np.lexsort((all_rows, all_cols))
    pos = np.empty(len(order), dtype=np.int64)
    pos[order] = np.arange(len(order))
    start = len(entries)
    for g in groups:
        for _ in g.columns:
            g.jac_pos.append(pos[start:start + len(g.rows)])
            start += len(g.rows)
    part = _ArrayPart(groups, np.asarray(scalar_rows, dtype=np.int64), pos[:len(entries)])
    if len(lin):
        part.linear = _SparseSums(lin, n, pos[start:])
    return all_rows[order], all_cols[order], part


class _SparseSums:
    """The terms ``a y[j] + b y'[j]`` (``a``, ``b`` numbers) of long sums, as sparse matrices
    ``A`` and ``B``: the residual adds ``A y + B y'``, the Jacobian holds ``a + c b`` at
    ``pos``."""

    def __init__(self, lin, n, pos):
        r, j = lin[:, 0].astype(np.int64), lin[:, 1].astype(np.int64)
        self.A = csr_matrix((lin[:, 2], (r, j)), shape=(n, n))
        self.B = csr_matrix((lin[:, 3], (r, j)), shape=(n, n))
        self.B.eliminate_zeros()
        self.has_b = self.B.nnz > 0
        self.a, self.b, self.pos = lin[:, 2].copy(), lin[:, 3].copy(), pos

    def residual(self, y, yp):
        return self.A @ y + self.B @ yp if self.has_b else self.A @ y

    def jacobian(self, c):
        return self.a + c * self.b if self.has_b else self.a


def _split_linear(row, index, subs):
    """``(rest, terms)``: ``row`` as ``rest + sum_j (a_j y[j] + b_j y'[j])`` with numbers
    ``a_j``, ``b_j`` (``terms[j] = [a_j, b_j]``), or None where the row's top-level sum has
    fewer than :data:`LINEAR_MIN_TERMS` such terms. ``row`` reads variable names (``sym``,
    ``der``): ``index`` numbers the unknowns, ``subs`` the eliminated ones (``name ->
    (coefficient, target, offset)``); a name eliminated with a parametric coefficient stays
    in ``rest``."""
    if row.op not in ("add", "sub"):
        return None
    terms: dict[int, list] = {}
    rest = []
    offset = 0.0
    count = 0
    stack = [(row, 1.0)]
    while stack:
        node, s = stack.pop()
        op = node.op
        if op == "add" or op == "sub":
            a, b = node.args
            stack.append((b, s if op == "add" else -s))
            stack.append((a, s))
            continue
        if op == "neg":
            stack.append((node.args[0], -s))
            continue
        if op == "mul" and (node.args[0].op == "const" or node.args[1].op == "const"):
            a, b = node.args
            k, other = (a.value, b) if a.op == "const" else (b.value, a)
            stack.append((other, s * k))
            continue
        if op == "const":
            offset += s * node.value
            continue
        if op == "sym" or op == "der":
            nm = node.value
            j = index.get(nm)
            coef = 1.0
            if j is None:
                sub = subs.get(nm)
                if sub is None or sub[0].__class__ is not float or \
                        (op == "sym" and sub[2].__class__ is not float):
                    rest.append((node, s))
                    continue
                coef, target, off = sub
                if op == "sym":
                    offset += s * off
                if target is None:
                    continue
                j = index[target]
            got = terms.get(j)
            if got is None:
                got = terms[j] = [0.0, 0.0]
            got[0 if op == "sym" else 1] += s * coef
            count += 1
            continue
        rest.append((node, s))
    if count < LINEAR_MIN_TERMS:
        return None
    out = E.const(offset)
    for node, s in rest:
        out = out + (node if s == 1.0 else (-node if s == -1.0 else s * node))
    return out, terms


def _linear_source(linear, labels, names):
    """Comment lines telling the rows whose long sums are sparse matrices."""
    lines = ["# sums evaluated as sparse matrices (A y + B y'), added to the rows above:"]
    for i, terms in linear.items():
        shown = ", ".join(f"{a:+g} {names[j]}" for j, (a, _) in list(terms.items())[:3] if a)
        lines.append(f"#   row {i} ({labels[i]}): {len(terms)} terms, {shown}, ...")
    return "\n".join(lines)
