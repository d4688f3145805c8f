"""Index reduction: Pantelides' algorithm and dummy derivatives.

Users join parts the way they are physically joined: two masses on one flange, a mass moved by a
position source, a gas volume whose pressure is tied to a line volume. Such circuits are DAEs of
index above one: some equations constrain differential variables without containing a derivative
that could be solved from them. This module turns them into index-one DAEs the solvers take.

Algorithm
---------
1. *Detection* (linear cost). One maximum bipartite matching of the equations onto the highest
   derivatives (``der(x)`` of differential variables, ``y`` of algebraic ones). A perfect matching
   means index <= 1 and nothing is done. If the matching on all of ``y, y'`` (the pencil) is not
   perfect either, the system is structurally singular and is left untouched for the compiler's
   structural check to refuse by name.
2. *Pantelides* [1]_. For every equation left unmatched, search an augmenting path through the
   highest derivatives; when none exists, every equation on the search tree is differentiated and
   every variable on it gets a derivative one order higher; repeat until the equation is matched.
   Differentiation is symbolic on the expression graph: the total time derivative
   ``d/dt f = df/dt + sum_i df/dz_i z_i'`` (:func:`time_derivative`), where ``z_i`` ranges over
   the unknowns and their derivatives of every order and signal sources contribute their
   explicit time functions. Leaves that are neither an unknown nor time (constants, discrete
   modes, parameters) are constant in time.
3. *Dummy derivatives* (Mattsson-Soderlind) [2]_. Starting from the most differentiated
   equations, the Jacobian of each level's differentiated equations with respect to the highest
   derivatives in them is evaluated at the start values, split into its connected blocks, and in
   each block as many columns as equations are chosen by QR with column pivoting. Rows are scaled
   to unit maximum, columns by the variable's nominal magnitude, by ``ORDER_PREFERENCE`` per
   derivative order above one (a second derivative of a position is made a dummy before a mass's
   own velocity loses its state), by ``START_PREFERENCE`` (variables with a start value the
   user gave keep their state) and by ``ANGLE_PREFERENCE`` (shaft angles and speeds keep their
   state, as Modelica's revolute joints prefer theirs: a crank turns on for ever, the position
   of the slider it drives is bounded and its derivative vanishes at the dead centres). The
   entries read the parameters' values; a block of numbers and parameters only (a gear's or a
   lever's ratio, constant through a run) keeps the matching's choice where that is regular.
   The chosen derivatives become *dummy derivatives*: plain algebraic unknowns. The next level
   down uses the equations one differentiation lower and the anti-derivatives of the dummies
   chosen. A block singular at the start values is refused with
   the equations' names (redundant constraints); one whose entries cannot be evaluated there is
   chosen structurally (a matching in the same preference order).
4. *First-order form.* For each variable ``x`` with derivatives ``x, x', ..., x^(k)`` of which
   ``x^(d), ..., x^(k)`` are dummies: ``x, ..., x^(d-2)`` are states, ``x^(d-1)`` is the
   derivative of the last one (``der`` in the residual), an intermediate ``x^(j)`` gets the
   equation ``der(x^(j-1)) = x^(j)``. New unknowns are named ``der(x)`` and ``der(x, j)``.

Where a chosen pivot block (of at most ``MONITOR_MAX_BLOCK`` rows) is not constant, two events
watch its determinant. Below ``SWITCH_RATIO`` of its start value :func:`pvgraph.simulate`
chooses the states again at that instant and goes on with them where another choice is
better conditioned there (dynamic state selection, :mod:`pvgraph._state_switch`); below
``PIVOT_RATIO`` (with no better choice, or with ``switch_states=False``) the run stops with a
:class:`~pvgraph.errors.SolverError` naming the dummy derivatives, the states and the time.

The start values a user gives (parameters such as ``x0``, ``v0``, ``w0`` that differ from their
defaults, ``start=`` entries, ``simulate(start=...)``, runtime parameters) must satisfy the
constraints that were hidden in the original equations. A given value on a chosen state holds
it; a given value on a variable the constraints determine (a velocity whose derivative became a
dummy, the second of two rigidly joined masses) moves the states not held, with the smallest
change, so that the consistent values at the start take it (:meth:`IndexReduction.impose`).
Given values that contradict each other through the constraints are refused with the value the
constraints force and the given values that fixed it.

References
----------
.. [1] C. C. Pantelides, "The consistent initialization of differential-algebraic systems",
   SIAM J. Sci. Stat. Comput. 9 (1988) 213-231.
.. [2] S. E. Mattsson, G. Soderlind, "Index reduction in differential-algebraic equations using
   dummy derivatives", SIAM J. Sci. Comput. 14 (1993) 677-692.
"""

from __future__ import annotations

import itertools
import math
import sys
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.linalg import qr
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching

from . import expr as E
from .component import EventSpec
from .errors import InitializationError, SolverError, StructureError, StructureWarning, \
    outside_stacklevel

__all__ = ["time_derivative", "reduce_index", "IndexReduction", "derivative_name", "given_starts"]

MAX_DIFFERENTIATIONS = 8     # an equation differentiated more often means a modelling error
PIVOT_RATIO = 0.1            # a pivot block's |det| below this fraction of its start value
                             # ends a run
SWITCH_RATIO = 0.3           # ... below this one the states are chosen again (simulate):
                             # a Cartesian pendulum's phase error after 3 swings from 1.8 rad
                             # at rtol 1e-6 is 7.8e-3 m switching at 0.1, 3.8e-4 at 0.3
PIVOT_RANK_TOL = 1e-9        # relative size of the last pivot of a numerically full-rank block
MONITOR_MAX_BLOCK = 8        # larger non-constant pivot blocks are not watched (their
                             # determinant's graph grows as m 2^m: 1024 products at 8)
START_PREFERENCE = {0: 1.0, 1: 0.7, 2: 0.4}   # column weights: given starts stay states
ANGLE_PREFERENCE = 1e-6      # column weight of an angle or angular speed: they stay states
ORDER_PREFERENCE = 1e4       # column weight per derivative order above one: dummy those first,
                             # rather than make a velocity a second state beside the mass's own
START_RTOL = 1e-6            # relative mismatch between a given start and a consistent value
IC_MAX_ITERS = 30            # Newton iterations of the start-value check
STEP_HALVINGS = 30           # halvings of a step moving the states towards given start values
NUDGE = 1e-2                 # move of the free states (in nominal units) off a singular start
_SINGULAR = "met only where the constraints are singular"
SINGULAR_END = 1e-10        # smallest singular value of the given values' sensitivity where
                             # they are met, relative to the largest (below: a singular meeting)
ANGLE_STEP = 0.5             # [rad] first limit of an angle's move in one step towards given
                             # starts (doubled after each whole step taken)
IC_TOL = 1e-10               # relative Newton step accepted as converged there
EVENT_OWNER = "index_reduction"
NAMES_IN_MESSAGES = 12       # conflicting start values listed in one message
EQUATION_TEXT = 90           # characters of an equation's text shown in the report


def derivative_name(name: str, order: int) -> str:
    """Name of the unknown holding the ``order``-th time derivative: ``der(x)``, ``der(x, 2)``."""
    if order == 0:
        return name
    return f"der({name})" if order == 1 else f"der({name}, {order})"


def time_derivative(e: E.Expr, derivative_of) -> E.Expr:
    """Total time derivative of ``e``: ``df/dt + sum_i df/dz_i * z_i'``.

    ``derivative_of(leaf)`` returns the expression of a leaf's time derivative, or ``None`` for a
    leaf constant in time. ``time`` leaves differentiate to one without asking.
    """
    memo: dict[int, E.Expr] = {}
    for node in E.postorder([e]):
        if node.op == "interp_d" and node.value.method != "linear" and not E.is_const(
                node.args[0]):
            raise StructureError(
                f"index reduction would differentiate the slope of table {node.value.name!r} "
                f"({node.value.method}); only linear tables have a second derivative (zero "
                f"between the knots). Use method='linear' or a smooth expression, or add "
                f"compliance (a spring, a volume) so the table is not differentiated twice.")
        if node.args:
            continue
        if node.op == "time":
            memo[id(node)] = E.ONE
        elif node.op == "const":
            memo[id(node)] = E.ZERO
        else:
            d = derivative_of(node)
            memo[id(node)] = E.ZERO if d is None else d
    # every leaf is seeded, so the partial derivative "with respect to nothing" is the total one
    return E.differentiate(e, ("__total_time_derivative__", None), memo)


# the result -------------------------------------------------------------------------------------

@dataclass
class _Block:
    level: int
    equations: list[str]
    dummies: list[str]
    det: E.Expr | None = None     # symbolic determinant of the pivot block (if watched)
    det0: float | None = None


@dataclass
class IndexReduction:
    """What index reduction did to a compiled circuit (empty when nothing was needed)."""

    differentiated: list[tuple[str, int, str]] = field(default_factory=list)  # label, times, text
    dummies: list[tuple[str, str]] = field(default_factory=list)         # (unknown, owner)
    states: list[tuple[str, str]] = field(default_factory=list)          # (state, owner)
    algebraic: list[tuple[str, str]] = field(default_factory=list)       # demoted to algebraic
    blocks: list[_Block] = field(default_factory=list)
    unwatched: list[str] = field(default_factory=list)
    involved: set = field(default_factory=set)
    given: dict = field(default_factory=dict)

    @property
    def reduced(self) -> bool:
        return bool(self.differentiated)

    def report(self) -> str:
        """Text listing the differentiated equations, the dummy derivatives and the states."""
        if not self.reduced:
            return "no index reduction: the DAE has index one or zero as written."
        lines = ["index reduction (Pantelides, dummy derivatives):",
                 "differentiated equations:"]
        for label, times, text in self.differentiated:
            lines.append(f"  {label}: {_times(times)}    0 = {text}")
        lines.append("dummy derivatives (algebraic unknowns replacing derivatives):")
        lines.extend(f"  {name}  [{owner}]" for name, owner in self.dummies)
        lines.append("states chosen among the constrained variables:")
        lines.extend(f"  {name}  [{owner}]" for name, owner in self.states)
        if not self.states:
            lines.append("  (none: the constraints prescribe their motion)")
        if self.algebraic:
            lines.append("made algebraic by the constraints:")
            lines.extend(f"  {name}  [{owner}]" for name, owner in self.algebraic)
        watched = [b for b in self.blocks if b.det is not None]
        if watched:
            lines.append(f"watched during the run (states chosen again if |det| < "
                         f"{SWITCH_RATIO:g} of its start value and another choice is better "
                         f"there, stops below {PIVOT_RATIO:g}):")
            lines.extend(f"  pivot on {', '.join(b.dummies)}" for b in watched)
        if self.unwatched:
            lines.append("not watched (block larger than "
                         f"{MONITOR_MAX_BLOCK}): " + ", ".join(self.unwatched))
        return "\n".join(lines)

    __str__ = report

    # after the System exists ------------------------------------------------------------------
    def attach(self, system):
        """Give ``system`` this reduction (its ``index_report()`` and pivot watch) and check
        the start values against the constraints."""
        system.index_reduction = self
        if self.reduced:
            self._check_start(system)
        return system

    def watch(self, events):
        """Give the pivot-watch events of ``events`` the action that stops the run."""
        for ev in events:
            if ev.name.startswith(EVENT_OWNER + ".pivot_"):
                ev.action = _PivotLost(self, int(ev.name.rsplit("_", 1)[1]))
        return events

    def pivot_lost(self, k: int, t: float):
        """The error that ends a run where watched pivot block ``k`` became ill-conditioned."""
        block = [b for b in self.blocks if b.det is not None][k]
        return SolverError(
            f"at t = {t:.6g} s the dummy derivatives {', '.join(block.dummies)} can no longer "
            f"be solved from {'; '.join(block.equations)} (the pivot determinant fell below "
            f"{PIVOT_RATIO:g} of its start value): the choice of states "
            f"({', '.join(n for n, _ in self.states)}) would have to change. Start from a "
            f"configuration near the one at this time, or add compliance (a spring, a volume) "
            f"to remove the rigid constraint.", t=float(t), culprits=list(block.dummies))

    def _check_start(self, system):
        """Honour the given start values (see :meth:`impose`) in ``system.y0`` at ``t = 0``."""
        self.impose(system, self.given, system.y0, system.yp0)

    def restart(self, system, changed):
        """After runtime parameters changed start values (``{full name: value}``): impose the
        start values a fresh compilation would, on ``system.y0``."""
        if not self.reduced:
            return
        given = dict(self.given)
        given.update(changed)
        self.impose(system, given, system.y0, system.yp0)

    def impose(self, system, given, y, yp, t0=0.0):
        """Make the start vector ``y`` take the start values ``given`` (``{name: value}``) of
        the variables the constraints tie together, in place.

        A given value on a state (or an alias of one) holds that state. A given value on a
        variable the constraints determine (a mass's velocity whose derivative became a dummy,
        the second of two rigidly joined masses) moves the states not held, with the smallest
        change (Gauss-Newton on the consistent values at ``t0``). Given values the constraints
        then contradict raise :class:`~pvgraph.errors.InitializationError`, naming each with
        the value it is given and the value the constraints force.
        """
        if not self.reduced or not given:
            return y
        involved = self._involved_indices(system)
        differential = ~np.asarray(system.algebraic)
        held: dict[int, tuple] = {}
        bad = []
        loose = []      # (name, value, coef, idx, off) on variables the constraints determine
        for name, value in given.items():
            try:
                coef, idx, off = system.resolve(name)
            except KeyError:
                continue
            if idx is None or idx not in involved or coef == 0.0:
                continue
            value = float(value)
            if differential[idx]:
                target = (value - off) / coef
                if idx in held:
                    other, v_other, c_other, o_other = held[idx]
                    forced = coef * y[idx] + off
                    if abs(forced - value) > START_RTOL * max(abs(value), abs(forced),
                                                              system.nominal[idx]):
                        bad.append((name, value, forced, f"with {other} = {v_other:.6g}"))
                    continue
                held[idx] = (name, value, coef, off)
                y[idx] = target
            else:
                loose.append((name, value, coef, idx, off))
        if loose:
            free = np.array(sorted(j for j in involved if differential[j] and j not in held),
                            dtype=int)
            bad.extend(self._solve_loose(system, loose, free, y, yp, t0))
        if bad and all(why is _SINGULAR for *_, why in bad):
            raise InitializationError(
                f"{system.name}: the start values "
                f"{', '.join(f'{n} = {v:.6g}' for n, v, *_ in bad[:NAMES_IN_MESSAGES])} can be "
                f"met together only where the constraints are singular: the speed the states "
                f"need there grows without bound (a speed given at a dead centre, where the "
                f"position no longer moves with the angle). Give a speed that configuration "
                f"allows, or a position off the dead centre.")
        if bad:
            listed = "; ".join(f"{n} = {v:.6g} given, the constraints force {f:.6g}"
                               + (f" ({why})" if why else "")
                               for n, v, f, why in bad[:NAMES_IN_MESSAGES])
            states = ", ".join(f"{n} = {y[system.index[n]]:.6g}"
                               for n, _ in self.states if n in system.index)
            raise InitializationError(
                f"{system.name}: start values conflict with the constraints hidden in the circuit "
                f"(rigid joints, position sources): {listed}. With the states {states}, the "
                f"differentiated equations ({'; '.join(d[0] for d in self.differentiated[:4])}) "
                f"fix these values. Give consistent start values, or give them on one of the "
                f"joined variables only.")
        return y

    def _involved_indices(self, system):
        names = set(self.involved)
        for n, _ in self.states:
            names.add(n)
        for n, _ in self.dummies:
            names.add(n)
        return {system.index[n] for n in names if n in system.index}

    def _solve_loose(self, system, loose, free, y, yp, t0):
        """Move the free states so the variables of ``loose`` take their given values; return
        the ones that cannot (name, given, forced, reason)."""
        targets = np.array([v for _, v, _, _, _ in loose])
        coefs = np.array([c for _, _, c, _, _ in loose])
        idxs = np.array([j for _, _, _, j, _ in loose], dtype=int)
        offs = np.array([o for _, _, _, _, o in loose])
        scale = np.maximum(np.abs(targets), system.nominal[idxs])
        angles = np.array([system.units[j] == "rad" for j in free], dtype=bool)
        reach = ANGLE_STEP
        start_free = y[free].copy()
        rows = None
        nudged = False
        yc, ypc, ok = _consistent_values(system, t0, y, yp)
        if not ok:
            return []   # the solver's own initialisation will report what is wrong
        for _ in range(IC_MAX_ITERS):
            r = (coefs * yc[idxs] + offs - targets) / scale
            if free.size == 0:
                rows = []
                break
            G = self._sensitivity(system, t0, yc, ypc, free, idxs) * (coefs / scale)[:, None]
            Gs = G * system.nominal[free][None, :]
            tol = PIVOT_RANK_TOL * max(1.0, np.max(np.abs(Gs)))
            if rows is None:   # the given values that fix independent directions, in order
                rows = []
                for k in range(len(loose)):
                    trial = rows + [k]
                    if np.linalg.matrix_rank(Gs[trial], tol=tol) == len(trial):
                        rows = trial
                dropped = [k for k in range(len(loose)) if k not in rows]
                if not nudged and np.any(np.abs(r[dropped]) > START_RTOL):
                    # the start sits where a given variable does not move with the states (a
                    # crank at its dead centre, a pendulum at the bottom given its height):
                    # step off it and look again
                    nudged, rows, before = True, None, y[free].copy()
                    y[free] += NUDGE * system.nominal[free]
                    yc, ypc, ok = _consistent_values(system, t0, y, yp)
                    if not ok:
                        return []
                    continue
            if not rows or np.all(np.abs(r[rows]) <= START_RTOL * 1e-3):
                break
            step = np.linalg.lstsq(Gs[rows], -r[rows], rcond=None)[0] * system.nominal[free]
            # an angle moves by at most ``reach`` per step, doubled after each such step taken
            # whole: near a dead centre the first step would otherwise throw a crank turns away
            # to an equivalent configuration, while a drum wound on reaches its 500 rad
            turn = np.abs(step[angles]).max() if angles.any() else 0.0
            limited = turn > reach
            if limited:
                step *= reach / turn
            # a step the constraints cannot follow (past the reach of a link) or that does not
            # bring the given values closer is halved
            base, size, lam = y[free].copy(), np.linalg.norm(r[rows]), 1.0
            for _ in range(STEP_HALVINGS):
                y[free] = base + lam * step
                yc2, ypc2, ok = _consistent_values(system, t0, y, yp)
                if ok and np.linalg.norm(((coefs * yc2[idxs] + offs - targets)
                                          / scale)[rows]) < size:
                    yc, ypc = yc2, ypc2
                    if limited and lam == 1.0:
                        reach *= 2.0
                    break
                lam *= 0.5
            else:
                y[free] = base
                break
        if nudged and not rows:     # stepping off did not help: back where it was
            y[free] = before
            yc, ypc, _ = _consistent_values(system, t0, y, yp)
        elif nudged and free.size:
            # the states the given values do not depend on (a velocity, for a given position)
            # go back to where they were
            unused = np.all(np.abs(Gs) <= tol, axis=0)
            if unused.any():
                y[free[unused]] = before[unused]
                yc, ypc, _ = _consistent_values(system, t0, y, yp)
        rows = rows or []
        if rows and free.size:
            # reached only where the given values stop moving with the states (a speed given
            # at a dead centre, met by a speed growing without bound): a contradiction
            G = self._sensitivity(system, t0, yc, ypc, free, idxs) * (coefs / scale)[:, None]
            sv = np.linalg.svd(G[rows] * system.nominal[free][None, :], compute_uv=False)
            if sv[-1] < SINGULAR_END * sv[0]:
                y[free] = start_free
                yc, ypc, _ = _consistent_values(system, t0, y, yp)
                return [(name, value, coef * yc[idx] + off, _SINGULAR)
                        for name, value, coef, idx, off in loose]
        bad = []
        fixing = ", ".join(f"{loose[k][0]} = {loose[k][1]:.6g}" for k in rows)
        for k, (name, value, coef, idx, off) in enumerate(loose):
            forced = coef * yc[idx] + off
            if abs(forced - value) > START_RTOL * max(abs(value), abs(forced),
                                                      system.nominal[idx]):
                bad.append((name, value, forced, f"with {fixing}" if k not in rows and fixing
                            else ""))
        return bad

    @staticmethod
    def _sensitivity(system, t0, y, yp, free, idxs):
        """d y[idxs] / d y[free] of the consistent values (states ``free`` moved, the others
        held): the implicit function theorem on the residual."""
        alg = np.asarray(system.algebraic)
        J0 = system.jacobian_dense(t0, y, yp, 0.0)
        J1 = system.jacobian_dense(t0, y, yp, 1.0)
        M = np.where(alg[None, :], J0, J1 - J0)
        du = -np.linalg.solve(M, J0[:, free])       # d(y_alg, yp_diff) / d y_free
        out = np.zeros((len(idxs), len(free)))
        pos = {int(j): k for k, j in enumerate(free)}
        for r, j in enumerate(idxs):
            if alg[j]:
                out[r] = du[j]
            elif int(j) in pos:
                out[r, pos[int(j)]] = 1.0
        return out


class _PivotLost:
    def __init__(self, reduction, k):
        self.reduction = reduction
        self.k = k

    def __call__(self, t, y, yp):
        raise self.reduction.pivot_lost(self.k, t)


def _times(k):
    return "once" if k == 1 else "twice" if k == 2 else f"{k} times"


# entry point --------------------------------------------------------------------------------------

def reduce_index(equations, infos, subs, events, observed, given=None, incidence=None,
                 params=None, choice_point=None):
    """Reduce the index of the compiled equations if needed.

    Parameters
    ----------
    equations : list
        Objects with ``expr``, ``origin`` and ``label`` (the compiler's equations), in terms of
        ``sym``/``der`` leaves of the unknowns (``infos`` names not in ``subs``).
    infos : dict
        Variable metadata (the compiler's ``VarInfo``); new unknowns are added in place.
    subs : dict
        The eliminated aliases.
    events : list of (path, EventSpec)
    observed : dict name -> (expr, unit, description)
    given : dict, optional
        Start values given by the user (by full name), checked against the constraints.
    incidence : list, optional
        ``(values read, derivatives read)`` (sets of names) of each equation, if known (the
        compiler's, from alias elimination); otherwise read from the expressions.
    params : dict, optional
        The runtime parameters' values by name, for the numbers of the constraint Jacobians
        at the start (a constraint ``(x/L)^2 + (y/L)^2 = 1`` reads ``L``).
    choice_point : dict, optional
        Values of the unknowns and their derivatives (``"der(x)"``, ``"der(x, 2)"``) at which
        the states are chosen, instead of the start values (a run changing its states where
        the choice made at the start became ill-conditioned, see
        :mod:`pvgraph._state_switch`); the start-value preferences then do not apply.

    Returns
    -------
    equations, events, observed, IndexReduction
    """
    unknowns = [nm for nm in infos if nm not in subs]
    n = len(unknowns)
    if len(equations) != n or n == 0:
        return equations, events, observed, IndexReduction()
    pos = dict(zip(unknowns, range(n)))
    inc_y, inc_yp = [], []
    if incidence is None:
        incidence = []
        for eq in equations:
            lv = E.leaves(eq.expr, ("sym", "der"))
            incidence.append(({v for op, v in lv if op == "sym"},
                              {v for op, v in lv if op == "der"}))
    number = pos.__getitem__
    for syms, ders in incidence:
        # the common case (every name an unknown) in one pass, the same sets either way
        try:
            inc_y.append(set(map(number, syms)))
        except KeyError:
            inc_y.append({pos[v] for v in syms if v in pos})
        try:
            inc_yp.append(set(map(number, ders)))
        except KeyError:
            inc_yp.append({pos[v] for v in ders if v in pos})
    differential = np.zeros(n, dtype=bool)
    differential[np.fromiter(itertools.chain.from_iterable(inc_yp), dtype=np.int64)] = True
    differentials = set(np.flatnonzero(differential).tolist())
    highest = [b | (a - differentials) for a, b in zip(inc_y, inc_yp)]
    if _perfect(highest, n):
        return equations, events, observed, IndexReduction()
    if not _perfect([a | b for a, b in zip(inc_y, inc_yp)], n):
        return equations, events, observed, IndexReduction()  # singular: refused downstream
    return _Reducer(equations, infos, unknowns, events, observed, given or {},
                    params or {}, choice_point).run()


def _perfect(cols, n):
    rows = np.repeat(np.arange(len(cols)), [len(c) for c in cols])
    flat = np.fromiter(itertools.chain.from_iterable(cols), dtype=np.int64, count=len(rows))
    m = csr_matrix((np.ones(len(rows)), (rows, flat)), shape=(len(cols), n))
    match = maximum_bipartite_matching(m, perm_type="column")
    return bool(np.all(match >= 0))


class _Reducer:
    """Pantelides' algorithm and the dummy-derivative selection on one system."""

    def __init__(self, equations, infos, unknowns, events, observed, given, params=None,
                 choice_point=None):
        self.orig = equations
        self.choice_point = choice_point
        self.params = params or {}
        self.infos = infos
        self.unknowns = unknowns
        self.events = events
        self.observed = observed
        self.given = given
        # variables: (base, order) nodes
        self.var_key: list[tuple[str, int]] = []
        self.var_id: dict[tuple[str, int], int] = {}
        self.var_diff: list[int] = []
        self.var_name: dict[str, int] = {}
        for nm in unknowns:
            self._var(nm, 0)
        # equations
        self.eq_expr: list[E.Expr] = []
        self.eq_inc: list[set] = []
        self.eq_diff: list[int] = []
        self.eq_src: list[tuple[int, int]] = []   # (original index, times differentiated)
        for k, eq in enumerate(equations):
            self._add_eq(self._internal(eq.expr), (k, 0))

    # bookkeeping --------------------------------------------------------------------------------
    def _var(self, base, order):
        key = (base, order)
        v = self.var_id.get(key)
        if v is None:
            v = len(self.var_key)
            self.var_key.append(key)
            self.var_id[key] = v
            self.var_diff.append(-1)
            self.var_name[derivative_name(base, order)] = v
            if order > 0:
                self.var_diff[self._var(base, order - 1)] = v
        return v

    def _internal(self, e):
        """Equation with every derivative as a named leaf (``der(x)`` -> sym ``der(x)``)."""
        def leaf(node):
            if node.op == "der" and (node.value, 0) in self.var_id:
                v = self._var(node.value, 1)
                return E.Expr("sym", (), derivative_name(*self.var_key[v]))
            return None
        return E.substitute([e], leaf)[0]

    def _add_eq(self, expr, src):
        k = len(self.eq_expr)
        self.eq_expr.append(expr)
        self.eq_inc.append({self.var_name[v] for op, v in E.leaves(expr, ("sym",))
                            if v in self.var_name})
        self.eq_diff.append(-1)
        self.eq_src.append(src)
        return k

    def _differentiate(self, k):
        if self.eq_diff[k] >= 0:
            return self.eq_diff[k]
        src, times = self.eq_src[k]
        if times + 1 > MAX_DIFFERENTIATIONS:
            raise StructureError(
                f"{self.orig[src].label} would have to be differentiated more than "
                f"{MAX_DIFFERENTIATIONS} times to reduce the index; the circuit constrains its "
                f"variables in a way no physical system does. Check for a position source "
                f"feeding a chain of rigid joints or a source fixing a quantity another fixes.")

        def d_leaf(node):
            if node.op == "sym" and node.value in self.var_name:
                base, order = self.var_key[self.var_name[node.value]]
                v = self._var(base, order + 1)
                return E.Expr("sym", (), derivative_name(*self.var_key[v]))
            return None
        d = time_derivative(self.eq_expr[k], d_leaf)
        k2 = self._add_eq(d, (src, times + 1))
        self.eq_diff[k] = k2
        return k2

    # Pantelides ---------------------------------------------------------------------------------
    def pantelides(self):
        n_orig = len(self.eq_expr)
        assign = {}   # var -> eq, on highest derivatives
        cols = [[v for v in inc if self.var_diff[v] < 0] for inc in self.eq_inc]
        match = _matching(cols, len(self.var_key))
        for e, v in enumerate(match):
            if v >= 0:
                assign[v] = e
        matched_eq = {e for e in assign.values()}
        limit = sys.getrecursionlimit()
        sys.setrecursionlimit(max(limit, 4 * len(self.var_key) + 1000))
        try:
            for k in range(n_orig):
                if k in matched_eq:
                    continue
                e = k
                while True:
                    vmark, emark = set(), set()
                    if self._augment(e, assign, vmark, emark):
                        break
                    for v in vmark:
                        b, o = self.var_key[v]
                        self._var(b, o + 1)
                    for q in sorted(emark):
                        self._differentiate(q)
                    for v in vmark:
                        q2 = self.eq_diff[assign[v]]
                        dv = self.var_diff[v]
                        if dv in self.eq_inc[q2]:
                            assign[dv] = q2
                    e = self.eq_diff[e]
        finally:
            sys.setrecursionlimit(limit)

    def _augment(self, e, assign, vmark, emark):
        emark.add(e)
        inc = self.eq_inc[e]
        for v in inc:
            if self.var_diff[v] < 0 and v not in assign:
                assign[v] = e
                return True
        for v in inc:
            if self.var_diff[v] < 0 and v not in vmark:
                vmark.add(v)
                if self._augment(assign[v], assign, vmark, emark):
                    assign[v] = e
                    return True
        return False

    # dummy derivatives -------------------------------------------------------------------------
    def dummy_derivatives(self):
        inv_eq = {d: k for k, d in enumerate(self.eq_diff) if d >= 0}
        inv_var = {d: v for v, d in enumerate(self.var_diff) if d >= 0}
        values = self._start_point()
        eqs = [k for k in range(len(self.eq_expr)) if self.eq_diff[k] < 0 and k in inv_eq]
        cand = sorted({v for k in eqs for v in self.eq_inc[k]
                       if self.var_diff[v] < 0 and self.var_key[v][1] >= 1})
        dummies: set[int] = set()
        blocks = []
        level = 0
        while eqs:
            level += 1
            chosen_all = []
            for part_eqs, part_cand in _components(eqs, cand, self.eq_inc):
                names = [derivative_name(*self.var_key[v]) for v in part_cand]
                jac = [[E.differentiate(self.eq_expr[k], ("sym", nm))
                        if v in self.eq_inc[k] else E.ZERO
                        for v, nm in zip(part_cand, names)] for k in part_eqs]
                chosen = self._choose(part_eqs, part_cand, jac, values)
                chosen_all.extend(part_cand[j] for j in chosen)
                blocks.append((level, part_eqs, [part_cand[j] for j in chosen],
                               [[jac[i][j] for j in chosen] for i in range(len(part_eqs))]))
            dummies.update(chosen_all)
            eqs = [inv_eq[k] for k in eqs if inv_eq[k] in inv_eq]
            cand = sorted(inv_var[v] for v in chosen_all if self.var_key[inv_var[v]][1] >= 1)
        return dummies, blocks, values

    def _start_point(self):
        values = {}
        for v, (base, order) in enumerate(self.var_key):
            values[derivative_name(base, order)] = self.infos[base].start if order == 0 else 0.0
        if self.choice_point is not None:
            for name in values:
                got = self.choice_point.get(name)
                if got is not None and math.isfinite(got):
                    values[name] = float(got)
        return values

    def _choose(self, eqs, cand, jac, values):
        """Columns (indices into cand) of a well-conditioned square block, one per equation."""
        m = len(eqs)
        try:
            H = np.array([[_evaluate(d, values, self.params) for d in row] for row in jac],
                         dtype=float)
        except (_NotEvaluable, ValueError, ZeroDivisionError, OverflowError):
            H = None
        if H is not None and np.all(np.isfinite(H)):
            scale_rows = np.max(np.abs(H), axis=1, keepdims=True)
            scale_rows[scale_rows == 0.0] = 1.0
            Hs = H / scale_rows
            w = np.array([self.infos[self.var_key[v][0]].nominal * self._preference(v)
                          * self._angle_weight(v)
                          * ORDER_PREFERENCE ** (self.var_key[v][1] - 1) for v in cand])
            plain = Hs * np.array([self.infos[self.var_key[v][0]].nominal for v in cand])
            Hs = Hs * w
            _, R, piv = qr(Hs, pivoting=True, mode="economic")
            if len(piv) >= m and abs(R[m - 1, m - 1]) > PIVOT_RANK_TOL * abs(R[0, 0]):
                entries = [d for row in jac for d in row]
                if any(E.leaves(d, ("param",)) for d in entries) and \
                        not any(E.leaves(d, ("sym", "der")) for d in entries):
                    # entries of numbers and parameters (a gear's, a lever's ratio): constant
                    # through a run, so any regular choice serves; the matching's is kept
                    # where it is regular (the parameters' values only check the block)
                    got = self._structural(jac, cand)
                    if got is not None and np.linalg.matrix_rank(
                            Hs[:, got], tol=PIVOT_RANK_TOL * abs(R[0, 0])) == m:
                        return got
                return sorted(int(j) for j in piv[:m])
            # the preferences spread the columns over many decades (an angular speed's
            # derivative at 1e-6 beside a position's second derivative at 1e4): the block
            # they choose may be regular all the same, which the columns at their nominal
            # scales tell; else the best-conditioned choice at those scales
            if len(piv) >= m:
                got = self._regular(plain, piv[:m]) or self._regular(
                    plain, qr(plain, pivoting=True, mode="economic")[2][:m])
                if got is not None:
                    return got
            raise StructureError(
                "index reduction: the hidden constraints "
                + "; ".join(self._label(k) for k in eqs)
                + " cannot be solved for the derivatives "
                + ", ".join(derivative_name(*self.var_key[v]) for v in cand)
                + " at the start values: the equations repeat or contradict each other (two "
                  "components fixing the same quantity), or the start point is a singular "
                  "configuration. Remove the redundant constraint or change the start values. "
                  "Two rigid paths between the same bodies (gears or racks in parallel, a ring "
                  "of gears) leave the force shared between them undetermined: give one of "
                  "them a mesh stiffness (k).")
        # not evaluable at the start: a structural choice
        got = self._structural(jac, cand)
        if got is None:
            raise StructureError(
                "index reduction: the differentiated equations "
                + "; ".join(self._label(k) for k in eqs)
                + " cannot be solved for any of the derivatives "
                + ", ".join(derivative_name(*self.var_key[v]) for v in cand))
        return got

    @staticmethod
    def _regular(plain, cols):
        """``cols`` sorted if the square block ``plain[:, cols]`` is regular (its smallest
        singular value above PIVOT_RANK_TOL times its largest), else None."""
        cols = [int(j) for j in cols]
        if len(cols) != plain.shape[0]:
            return None
        sv = np.linalg.svd(plain[:, cols], compute_uv=False)
        return sorted(cols) if sv[-1] > PIVOT_RANK_TOL * sv[0] else None

    def _structural(self, jac, cand):
        """A choice of columns by matching alone, in the preference order (or None)."""
        cols = [[j for j, d in enumerate(row) if not E.is_const(d, 0.0)] for row in jac]
        order = sorted(range(len(cand)), key=lambda j: (-self.var_key[cand[j]][1],
                                                        -self._preference(cand[j])))
        rank = {j: r for r, j in enumerate(order)}
        cols = [sorted(c, key=lambda j: rank[j]) for c in cols]
        match = _matching(cols, len(cand))
        if np.any(match < 0):
            return None
        return sorted(int(j) for j in match)

    def _preference(self, v):
        if self.choice_point is not None:     # chosen where the run is: conditioning alone
            return 1.0
        base = self.var_key[v][0]
        prio = 2 if base in self.given else self.infos[base].start_priority
        return START_PREFERENCE.get(prio, 1.0)

    def _angle_weight(self, v):
        return ANGLE_PREFERENCE if self.infos[self.var_key[v][0]].unit in ("rad", "rad/s") \
            else 1.0

    def _label(self, k):
        src, times = self.eq_src[k]
        label = self.orig[src].label
        if times == 0:
            return label
        k = "" if times == 1 else str(times)
        return f"d{k}/dt{k} of {label}"

    # assembly ---------------------------------------------------------------------------------
    def run(self):
        self.pantelides()
        dummies, blocks, values = self.dummy_derivatives()
        top = {}   # base -> highest order
        first_dummy = {}
        for v, (base, order) in enumerate(self.var_key):
            top[base] = max(top.get(base, 0), order)
            if v in dummies:
                first_dummy[base] = min(first_dummy.get(base, order), order)
        d_of = {b: first_dummy.get(b, top[b] + 1) for b in top}

        def final_leaf(base, order):
            d = d_of[base]
            name = derivative_name(base, order)
            if order >= 1 and order == d - 1:
                return E.Expr("der", (), derivative_name(base, order - 1))
            return E.Expr("sym", (), name)

        def leaf(node):
            if node.op == "sym" and node.value in self.var_name:
                return final_leaf(*self.var_key[self.var_name[node.value]])
            return None

        make = type(self.orig[0])
        out = []
        for k, expr in enumerate(self.eq_expr):
            src, times = self.eq_src[k]
            eq = self.orig[src]
            new = E.substitute([expr], leaf)[0]
            out.append(make(new, eq.origin, self._label(k)) if times else
                       make(new, eq.origin, eq.label))
        # new unknowns and the equations chaining the states
        for base in top:
            d = d_of[base]
            info = self.infos[base]
            for order in range(1, top[base] + 1):
                if order == d - 1:
                    continue
                name = derivative_name(base, order)
                unit = _per_time(info.unit, order)
                self.infos[name] = replace(
                    info, name=name, unit=unit, start=0.0, start_priority=0,
                    description=f"{_ordinal(order)} time derivative of {base}"
                                + (" (dummy derivative)" if order >= d else ""))
                if order <= d - 2:
                    out.append(make(E.Expr("der", (), derivative_name(base, order - 1))
                                    - E.Expr("sym", (), name), info.owner,
                                    f"{name} is the time derivative of "
                                    f"{derivative_name(base, order - 1)}"))

        def user_leaf(node):
            if node.op == "der" and node.value in top:
                return final_leaf(node.value, 1)
            return None
        new_events = []
        for path, ev in self.events:
            cond = E.substitute([ev.condition], user_leaf)[0]
            new_events.append((path, replace(ev, condition=cond) if cond is not ev.condition
                               else ev))
        new_observed = {}
        for nm, (expr, unit, desc) in self.observed.items():
            new_observed[nm] = (E.substitute([expr], user_leaf)[0], unit, desc)

        result = IndexReduction(given=dict(self.given))
        chains = {}
        for k, (src, times) in enumerate(self.eq_src):
            chains[src] = max(chains.get(src, 0), times)
        result.differentiated = [(self.orig[s].label, t, _short(E.to_text(self.orig[s].expr)))
                                 for s, t in sorted(chains.items()) if t]
        _warn_switched(self.orig, chains)
        involved = {base for k, (src, _) in enumerate(self.eq_src) if chains[src]
                    for v in self.eq_inc[k] for base in [self.var_key[v][0]]}
        result.involved = involved
        for v in sorted(dummies, key=lambda v: self.var_key[v]):
            base, order = self.var_key[v]
            result.dummies.append((derivative_name(base, order), self.infos[base].owner))
        for base in sorted(involved):
            d = d_of[base]
            owner = self.infos[base].owner
            for order in range(0, d - 1):
                result.states.append((derivative_name(base, order), owner))
            if d == 1 and top[base] >= 1:
                result.algebraic.append((base, owner))
        watched = 0
        for level, eqs, chosen, block in blocks:
            b = _Block(level, [self._label(k) for k in eqs],
                       [derivative_name(*self.var_key[v]) for v in chosen])
            # a pivot of numbers and parameters only (a gear's ratio) cannot change in a run
            if any(E.leaves(x, ("sym", "der")) for row in block for x in row):
                if len(chosen) <= MONITOR_MAX_BLOCK:
                    det = _det(block)
                    try:
                        det0 = _evaluate(det, values, self.params)
                    except (_NotEvaluable, ValueError, ZeroDivisionError, OverflowError):
                        det0 = math.nan
                    if math.isfinite(det0) and det0 != 0.0:
                        b.det = E.substitute([det], leaf)[0]
                        b.det0 = det0
                        ratio = b.det * (1.0 / det0)
                        new_events.append((EVENT_OWNER, EventSpec(
                            f"pivot_{watched}", ratio - PIVOT_RATIO, direction=-1)))
                        new_events.append((EVENT_OWNER, EventSpec(
                            f"switch_{watched}", ratio - SWITCH_RATIO, direction=-1)))
                        watched += 1
                else:
                    result.unwatched.extend(b.dummies)
            result.blocks.append(b)
        return out, new_events, new_observed, result


def _warn_switched(equations, chains):
    """Warn of each equation index reduction differentiates that reads an event-switched mode.

    Its derivatives are taken with the modes held (and a linear table's slope is piecewise
    constant), so where a switch makes its value jump (a step driving a position source) or
    its slope jump (a ramp, a table's knot), the run re-initialises there: the position or
    velocity jumps, and the impulse that jump takes (an unbounded force over no time) is in
    no result."""
    for src, times in sorted(chains.items()):
        if not times:
            continue
        eq = equations[src]
        modes = sorted({nm for _, nm in E.leaves(eq.expr, ("sym",)) if ".#" in nm})
        tables = sorted({node.value.name for node in E.postorder([eq.expr])
                         if node.op == "interp" and node.value.method == "linear"}) \
            if times >= 2 else []
        if not modes and not tables:
            continue
        what = []
        if modes:
            what.append(f"the event-switched mode{'s' if len(modes) > 1 else ''} "
                        f"{', '.join(modes)}")
        if tables:
            what.append(f"the linear table{'s' if len(tables) > 1 else ''} "
                        f"{', '.join(repr(t) for t in tables)} (its slope jumps at its knots)")
        warnings.warn(StructureWarning(
            f"index reduction differentiates {eq.label} {_times(times)}, and it reads "
            f"{' and '.join(what)}: where a switch or a knot makes its value or its slope jump "
            f"(a step, a ramp or a table driving a position or velocity source on a mass), "
            f"the run re-initialises there, and the impulse "
            f"of that jump is not represented (the force shows none). Drive the source with a "
            f"smooth signal (a Sine, a filtered step) or put compliance (a spring, a volume) "
            f"between the source and the mass."), stacklevel=outside_stacklevel())


def _per_time(unit, order):
    """``unit`` divided by ``s^order``: ``m`` -> ``m/s^2``, ``m/s`` -> ``m/s^2``."""
    if not unit:
        return f"1/s^{order}" if order > 1 else "1/s"
    base, k = unit, 0
    if unit.endswith("/s"):
        base, k = unit[:-2], 1
    elif "/s^" in unit and unit.rsplit("/s^", 1)[1].isdigit():
        base, tail = unit.rsplit("/s^", 1)
        k = int(tail)
    k += order
    return f"{base}/s" if k == 1 else f"{base}/s^{k}"


def _short(text, width=EQUATION_TEXT):
    return text if len(text) <= width else text[:width - 3] + "..."


def _ordinal(k):
    return {1: "first", 2: "second", 3: "third"}.get(k, f"{k}th")


def _components(eqs, cand, inc):
    """Split (equations, candidate columns) into the connected blocks of their incidence."""
    parent = {("v", v): ("v", v) for v in cand}
    parent.update({("e", k): ("e", k) for k in eqs})

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a
    cset = set(cand)
    for k in eqs:
        for v in inc[k]:
            if v in cset:
                parent[find(("v", v))] = find(("e", k))
    groups: dict = {}
    for k in eqs:
        groups.setdefault(find(("e", k)), ([], []))[0].append(k)
    for v in cand:
        root = find(("v", v))
        if root in groups:
            groups[root][1].append(v)
    return list(groups.values())


def _matching(cols, n_var):
    """Equation -> column maximum matching (-1 where unmatched)."""
    rows = np.repeat(np.arange(len(cols)), [len(c) for c in cols])
    flat = np.fromiter(itertools.chain.from_iterable(cols), dtype=np.int64, count=len(rows))
    m = csr_matrix((np.ones(len(rows)), (rows, flat)), shape=(len(cols), max(n_var, 1)))
    return maximum_bipartite_matching(m, perm_type="column")


def _det(block):
    """Symbolic determinant of a square block: Laplace expansion along the rows, each minor
    (the last rows on a set of columns) built once and shared, so the graph has at most
    m 2^(m-1) products for m rows, not m! (zero entries add none)."""
    m = len(block)
    memo: dict[int, E.Expr] = {}

    def minor(row, cols):
        """The determinant of rows ``row..m-1`` on the columns in the bit set ``cols``."""
        if row == m:
            return E.ONE
        got = memo.get(cols)
        if got is not None:
            return got
        total = E.ZERO
        sign = 1.0
        for j in range(m):
            if not cols >> j & 1:
                continue
            entry = block[row][j]
            if not E.is_const(entry, 0.0):
                term = entry * minor(row + 1, cols & ~(1 << j))
                total = total + term if sign > 0 else total - term
            sign = -sign
        memo[cols] = total
        return total
    return minor(0, (1 << m) - 1)


# numbers at the start point -------------------------------------------------------------------

class _NotEvaluable(Exception):
    pass


_FUNCS = {"sqrt": math.sqrt, "exp": math.exp, "log": math.log, "tanh": math.tanh,
          "sin": math.sin, "cos": math.cos, "atan": math.atan, "abs": abs}


def _evaluate(e: E.Expr, values: dict, params=None) -> float:
    """Value of ``e`` at ``t = 0`` with named leaves from ``values`` (modes and others 0) and
    runtime parameters from ``params`` (by name)."""
    val: dict[int, float] = {}
    for node in E.postorder([e]):
        op = node.op
        a = [val[id(x)] for x in node.args]
        if op == "const":
            r = node.value
        elif op == "sym":
            r = values.get(node.value, 0.0)
        elif op == "time":
            r = 0.0
        elif op == "param" and params and isinstance(node.value, str) and \
                isinstance(params.get(node.value), (int, float)):
            r = params[node.value]
        elif op == "add":
            r = a[0] + a[1]
        elif op == "sub":
            r = a[0] - a[1]
        elif op == "mul":
            r = a[0] * a[1]
        elif op == "div":
            r = a[0] / a[1]
        elif op == "pow":
            r = a[0] ** a[1]
        elif op == "neg":
            r = -a[0]
        elif op == "lt":
            r = float(a[0] < a[1])
        elif op == "le":
            r = float(a[0] <= a[1])
        elif op == "gt":
            r = float(a[0] > a[1])
        elif op == "ge":
            r = float(a[0] >= a[1])
        elif op == "where":
            r = a[1] if a[0] else a[2]
        elif op == "interp":
            r = node.value.value(a[0])
        elif op == "interp_d":
            r = node.value.slope(a[0])
        elif op in _FUNCS:
            r = _FUNCS[op](a[0])
        else:
            raise _NotEvaluable(op)
        val[id(node)] = float(r)
    return val[id(e)]


def _consistent_values(system, t0=0.0, y=None, yp=None):
    """Consistent y at ``t0`` with the differential states held at their start values (those
    of ``y``, ``yp`` if given, else the system's).

    Newton on the algebraic y and the derivatives of the states (the unknowns of IDA's
    ``calc_initial="algebraic"``); returns ``(y, yp, converged)``.
    """
    y = (system.y0 if y is None else y).copy()
    yp = (system.yp0 if yp is None else yp).copy()
    alg = system.algebraic
    for _ in range(IC_MAX_ITERS):
        r = system.residual(t0, y, yp)
        if not np.all(np.isfinite(r)):
            return y, yp, False
        J0 = system.jacobian_dense(t0, y, yp, 0.0)
        J1 = system.jacobian_dense(t0, y, yp, 1.0)
        M = np.where(alg[None, :], J0, J1 - J0)   # column j: dF/dy_j or dF/dy'_j
        try:
            dz = np.linalg.solve(M, r)
        except np.linalg.LinAlgError:
            return y, yp, False
        z = np.where(alg, y, yp)
        y[alg] -= dz[alg]
        yp[~alg] -= dz[~alg]
        if np.all(np.abs(dz) <= IC_TOL * np.maximum(np.abs(z), system.nominal)):
            return y, yp, True
    return y, yp, False


def given_starts(leaves) -> dict[str, float]:
    """Start values the user gave, by full name: every ``start=`` entry and the values derived
    from parameters (``x0``, ``v0``, ``p0``, ...) that differ from what the parameters'
    defaults give (the compiler's rule, see ``pvgraph.compiler._declare_variables``)."""
    from .compiler import _declare_variables
    given: dict[str, float] = {}
    infos: dict = {}
    registry: dict = {}
    for path, comp in leaves:
        _declare_variables(path, comp, infos, registry, {}, given)
    return given
