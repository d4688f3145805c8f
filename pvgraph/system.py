"""The compiled DAE system F(t, y, y') = 0 of a circuit.

A :class:`System` holds generated functions for the residual, the Jacobian values on a fixed
sparse pattern (dF/dy + c dF/dy'), event functions and derived outputs, together with everything
needed to address results by name: variable names, units, nominal magnitudes, the split into
differential and algebraic variables, and the aliases removed by the compiler.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csc_matrix

from . import codegen
from . import expr as E
from .errors import CircuitError

__all__ = ["System", "build_system", "ModeView"]


@dataclass
class _Entry:
    row: int
    col: int
    expr: E.Expr


class ModeView:
    """A component's view of the system's discrete modes: ``modes["open"] = 1.0``."""

    def __init__(self, values: list, index: dict[str, int], owner: str):
        self._values = values
        self._index = index
        self._owner = owner

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
    """

    DENSE_MAX = 120  # above this many unknowns the Jacobian is handed to the solver sparse

    def __init__(self, name, names, differential, y0, nominal, units, descriptions, equations,
                 rows, cols, residual_fn, jac_fn, observed_fn, observed, event_fn, event_specs,
                 mode_names, mode_start, aliases, sources):
        self.name = name
        self.names = names
        self.n = len(names)
        self.index = {nm: i for i, nm in enumerate(names)}
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
        self.aliases = aliases  # name -> (coef, target or None, offset)
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
        try:
            return np.array(self._res(t, y.tolist(), yp.tolist(), self.modes))
        except (ValueError, ZeroDivisionError, OverflowError):
            return np.full(self.n, np.nan)

    def jacobian_values(self, t, y, yp, c):
        """Values of dF/dy + c dF/dy' on the fixed pattern (CSC order)."""
        try:
            return np.array(self._jac(t, y.tolist(), yp.tolist(), self.modes, c))
        except (ValueError, ZeroDivisionError, OverflowError):
            return np.full(len(self._rows), np.nan)

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

    # events and modes ---------------------------------------------------------------------------
    def reset_modes(self):
        """Restore the modes to their start values and clear the mode log."""
        self.modes[:] = self.mode_start
        self.mode_log = [(-math.inf, tuple(self.modes))]

    def mode_view(self, owner: str) -> ModeView:
        """The modes of component ``owner`` as a mutable mapping."""
        prefix = owner + ".#"
        index = {nm[len(prefix):]: i for i, nm in enumerate(self.mode_names)
                 if nm.startswith(prefix)}
        return ModeView(self.modes, index, owner)

    def event_values(self, t, y, yp):
        """Every event function at one point."""
        return self._event_fn(t, y.tolist(), yp.tolist(), self.modes)

    def solver_events(self):
        """The declared events as :class:`pvgraph.solver.Event` objects bound to this system."""
        from .solver import Event
        out = []
        for k, (path, spec) in enumerate(self.event_specs):
            out.append(Event(fun=self._event_component(k), direction=spec.direction,
                             terminal=spec.terminal,
                             action=self._event_action(path, spec), name=f"{path}.{spec.name}"))
        return out

    def _event_component(self, k):
        fn = self._event_fn
        modes = self.modes

        def g(t, y, yp):
            return fn(t, y.tolist(), yp.tolist(), modes)[k]
        return g

    def _event_action(self, path, spec):
        if spec.action is None:
            return None
        view = self.mode_view(path)

        def act(t, y, yp):
            spec.action(view)
            self.mode_log.append((float(t), tuple(self.modes)))
            return None
        return act

    # names ------------------------------------------------------------------------------------
    def resolve(self, name: str):
        """``(coef, index or None, offset)`` with ``name = coef * y[index] + offset``."""
        if name in self.index:
            return 1.0, self.index[name], 0.0
        if name in self.aliases:
            coef, target, off = self.aliases[name]
            return coef, (None if target is None else self.index[target]), off
        raise KeyError(self._unknown(name))

    def _unknown(self, name):
        import difflib
        pool = list(self.index) + list(self.aliases) + list(self.observed)
        close = difflib.get_close_matches(name, pool, n=3)
        hint = f" Close matches: {close}." if close else ""
        return f"{self.name}: no variable or output named {name!r}.{hint}"

    def unit(self, name: str) -> str:
        if name in self.observed:
            return self.observed[name][0]
        coef, idx, _ = self.resolve(name)
        if idx is None:
            return self._alias_units.get(name, "")
        return self.units[idx]

    def all_names(self) -> list[str]:
        """Every addressable name: unknowns, eliminated aliases and derived outputs."""
        return list(self.names) + sorted(self.aliases) + sorted(self.observed)

    def evaluate_observed(self, t, Y, YP, modes_per_time):
        """Derived outputs over a solution: dict name -> array (len(t))."""
        if not self.observed:
            return {}
        with np.errstate(all="ignore"):
            d = [np.asarray(m) for m in np.asarray(modes_per_time, dtype=float).T] \
                if len(self.mode_names) else []
            vals = self._obs(np.asarray(t), list(Y.T), list(YP.T), d)
        m = len(t)
        return {nm: np.broadcast_to(np.asarray(v, dtype=float), (m,)).copy()
                for nm, v in zip(self.observed, vals)}

    def source(self) -> str:
        """The generated Python source of the residual, Jacobian, events and outputs."""
        return "\n\n".join(self._sources)

    def __repr__(self):
        return (f"<System {self.name}: {self.n} unknowns ({int(self.differential.sum())} "
                f"differential), {len(self._rows)} Jacobian non-zeros, {len(self.event_specs)} "
                f"events>")


def build_system(name, equations, infos, subs, observed, events, mode_names, mode_start):
    """Number the unknowns, generate code and run the structural checks."""
    from .compiler import check_structure

    names = [nm for nm in infos if nm not in subs]
    index = {nm: i for i, nm in enumerate(names)}
    mode_index = {nm: j for j, nm in enumerate(mode_names)}

    def leaf(node):
        if node.op == "sym":
            if node.value in index:
                return E.Expr("y", (), index[node.value])
            if node.value in mode_index:
                return E.Expr("mode", (), mode_index[node.value])
            if node.value in subs:
                coef, target, off = subs[node.value]
                if target is None:
                    return E.const(off)
                return E.const(coef) * E.Expr("y", (), index[target]) + off
        if node.op == "der":
            if node.value in index:
                return E.Expr("yp", (), index[node.value])
            if node.value in subs:
                coef, target, _ = subs[node.value]
                return E.ZERO if target is None else E.const(coef) * E.Expr("yp", (),
                                                                            index[target])
        return None

    res_exprs = E.substitute([eq.expr for eq in equations], leaf)
    labels = [eq.label for eq in equations]
    inc_y, inc_yp = [], []
    for r in res_exprs:
        lv = E.leaves(r, ("y", "yp"))
        inc_y.append(sorted(v for op, v in lv if op == "y"))
        inc_yp.append(sorted(v for op, v in lv if op == "yp"))
    differential = np.zeros(len(names), dtype=bool)
    for cols in inc_yp:
        differential[cols] = True
    check_structure(names, labels, inc_y, inc_yp, differential)

    entries = []
    memo_y: dict[int, dict] = {}
    memo_yp: dict[int, dict] = {}
    for i, r in enumerate(res_exprs):
        for j in sorted(set(inc_y[i]) | set(inc_yp[i])):
            dy = E.differentiate(r, ("y", j), memo_y.setdefault(j, {})) \
                if j in inc_y[i] else E.ZERO
            dyp = E.differentiate(r, ("yp", j), memo_yp.setdefault(j, {})) \
                if j in inc_yp[i] else E.ZERO
            entries.append(_Entry(i, j, dy + E.CJ * dyp))
    entries.sort(key=lambda en: (en.col, en.row))

    res_src, res_tabs = codegen.generate("residual", res_exprs, comments=labels)
    jac_src, jac_tabs = codegen.generate(
        "jacobian", [en.expr for en in entries], extra_args=("c",),
        comments=[f"d/d {names[en.col]} of row {en.row}" for en in entries])
    residual_fn = codegen.compile_function("residual", res_src, res_tabs)
    jac_fn = codegen.compile_function("jacobian", jac_src, jac_tabs)

    ev_exprs = E.substitute([ev.condition for _, ev in events], leaf) if events else []
    ev_src, ev_tabs = codegen.generate("events", ev_exprs,
                                       comments=[f"{p}.{ev.name}" for p, ev in events])
    event_fn = codegen.compile_function("events", ev_src, ev_tabs)

    obs_names = list(observed)
    obs_exprs = E.substitute([observed[nm][0] for nm in obs_names], leaf) if obs_names else []
    obs_src, obs_tabs = codegen.generate("observed", obs_exprs, flavour="array",
                                         comments=obs_names)
    observed_fn = codegen.compile_function("observed", obs_src, obs_tabs)

    system = System(
        name, names, differential,
        [infos[nm].start for nm in names], [infos[nm].nominal for nm in names],
        [infos[nm].unit for nm in names], [infos[nm].description for nm in names], labels,
        [en.row for en in entries], [en.col for en in entries], residual_fn, jac_fn,
        observed_fn, {nm: (observed[nm][1], observed[nm][2]) for nm in obs_names}, event_fn,
        events, mode_names, mode_start, dict(subs), [res_src, jac_src, ev_src, obs_src])
    system._alias_units = {nm: infos[nm].unit for nm in subs}
    system.reset_modes()
    return system
