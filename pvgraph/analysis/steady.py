"""Steady operating points: solve F(t, y, 0) = 0.

Newton's method with a backtracking line search on the scaled residual, using the exact
Jacobian ``dF/dy`` of the compiled system. If Newton stalls, pseudo-transient continuation
follows the circuit's own dynamics (implicit Euler steps of growing size ``dtau``, the Jacobian
``dF/dy + dF/dy'/dtau``) towards an equilibrium and Newton is tried again from there.

Cyclic coordinates: an angle [rad] that enters the equations only through its derivative (a
shaft turning at a steady speed, ``der(phi) = w``) has no steady value, only a steady rate. Such states are found from the Jacobian (a zero column of ``dF/dy`` with a non-zero
column of ``dF/dy'``); for them the unknown is the rate ``y'`` and the value stays at its
start, so a pump on a ``SpeedSource`` or a motor turning an inertia has an operating point.

Scaling: variables by ``system.nominal``; residual rows by ``max_j |dF_i/dy_j| nominal_j`` at
the start point (the size of the row's terms), so the tolerance is relative.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..errors import InitializationError, PvgraphError
from ..system import System

__all__ = ["OperatingPoint", "steady_state"]


@dataclass
class OperatingPoint:
    """A steady state of ``system``: ``y`` with ``yp = 0``; ``op["name"]`` looks up by name.

    ``info["cyclic"]`` names the states that only enter through their rate (shaft angles): for
    them ``yp`` holds the steady rate and ``y`` the start value; sensitivities hold them fixed.
    """

    y: np.ndarray
    yp: np.ndarray
    system: System
    t: float = 0.0
    residual_norm: float = 0.0
    iterations: int = 0
    method: str = "newton"
    info: dict = field(default_factory=dict)
    _observed: dict | None = field(default=None, repr=False, compare=False)

    def __getitem__(self, name: str) -> float:
        """The value of an unknown, an eliminated alias or a derived output (``v.observe``)."""
        if name in self.system.observed:
            if self._observed is None:
                self._observed = self.system.evaluate_observed(
                    np.array([self.t]), self.y[None, :], self.yp[None, :], [self.system.modes])
            return float(self._observed[name][0])
        coef, idx, off = self.system.resolve(name)
        return float(off if idx is None else coef * self.y[idx] + off)

    def state_sensitivity(self, params=None) -> np.ndarray:
        """dy/dp at this steady state, ``(n, len(params))``: the solution of F_y S = -F_p.

        ``F_p`` is the compiled parameter derivative dF/dp; one factorisation of F_y serves
        every parameter. ``params`` defaults to every runtime parameter of the system.
        """
        s = self.system
        Fp = s.parameter_jacobian(self.t, self.y, self.yp, params)
        return self.solve_linear(-Fp)

    def solve_linear(self, rhs) -> np.ndarray:
        """Solve ``F_y X = rhs`` with the steady Jacobian ``F_y = dF/dy`` at this point."""
        s = self.system
        if self.info.get("cyclic"):
            # the rates of cyclic states stand in for their values, which stay put (dy = 0)
            cyc = [s.names.index(nm) for nm in self.info["cyclic"]]
            J = s.jacobian_dense(self.t, self.y, self.yp, 0.0)
            J[:, cyc] = (s.jacobian_dense(self.t, self.y, self.yp, 1.0) - J)[:, cyc]
            x = np.linalg.solve(J, rhs)
            x[cyc] = 0.0
            return x
        if s.n <= s.DENSE_MAX:
            J = s.jacobian_dense(self.t, self.y, self.yp, 0.0)
            return np.linalg.solve(J, rhs)
        from scipy.sparse.linalg import splu
        lu = splu(s.jacobian(self.t, self.y, self.yp, 0.0).tocsc())
        return lu.solve(np.asarray(rhs, dtype=float))

    def sensitivity(self, outputs, params=None, *, dy_dp=None) -> np.ndarray:
        """d output / d parameter at this steady state, ``(len(outputs), len(params))``.

        ``outputs`` are names of unknowns, aliases or derived outputs; ``params`` parameter
        names (default: all). The steady state moves with the parameters: ``d out/dp =
        d out/dy dy/dp + d out/dp`` with ``dy/dp = -F_y^-1 F_p`` (:meth:`state_sensitivity`).
        """
        s = self.system
        S = self.state_sensitivity(params) if dy_dp is None else dy_dp
        rows = []
        for name in outputs:
            gy, gp = s.output_gradient(name, self.t, self.y, self.yp, params)
            rows.append(gy @ S + gp)
        return np.array(rows).reshape(len(rows), S.shape[1])


class _CyclicView:
    """``system`` with the rates of its cyclic states as unknowns in place of their values."""

    def __init__(self, system, cyc, y_start):
        self._s, self.cyc = system, cyc
        self.y_fix = np.asarray(y_start, dtype=float)[cyc].copy()
        self.n, self.equations = system.n, system.equations
        self.names = list(system.names)
        for j in cyc:
            self.names[j] = f"der({system.names[j]})"
        self.nominal = np.asarray(system.nominal, dtype=float)

    def split(self, z, zp=None):
        """``(y, y')`` of the system for the unknowns ``z`` (rates of cyclic states held)."""
        y = np.array(z, dtype=float)
        yp = np.zeros(self.n) if zp is None else np.array(zp, dtype=float)
        yp[self.cyc] = y[self.cyc]
        y[self.cyc] = self.y_fix
        return y, yp

    def residual(self, t, z, zp):
        y, yp = self.split(z, zp)
        return self._s.residual(t, y, yp)

    def jacobian_dense(self, t, z, zp, c):
        y, yp = self.split(z, zp)
        J0 = self._s.jacobian_dense(t, y, yp, 0.0)
        Jyp = self._s.jacobian_dense(t, y, yp, 1.0) - J0
        J = J0 + c * Jyp
        J[:, self.cyc] = Jyp[:, self.cyc]
        return J


def _sparse(system) -> bool:
    """Work on sparse Jacobians (a dense solve costs n^3: 6.5 s at 2000 unknowns)."""
    return system.n > getattr(system, "DENSE_MAX", np.inf) and hasattr(system, "jacobian")


def _jacobian(system, t, y, yp, c):
    """dF/dy + c dF/dy': dense for small systems, CSR above ``DENSE_MAX`` unknowns."""
    if _sparse(system):
        return sp.csr_matrix(system.jacobian(t, y, yp, c))
    return system.jacobian_dense(t, y, yp, c)


def _nonzero_columns(J) -> np.ndarray:
    if sp.issparse(J):
        return np.asarray(abs(J).sum(axis=0)).ravel() != 0.0
    return np.any(J != 0.0, axis=0)


def _cyclic_states(system, t, y) -> np.ndarray:
    """Angles [rad] entering F only through their derivative (at y and at a nearby point).

    Only angles: a pressure or a position rising for ever is no operating point.
    """
    n = system.n
    angle = np.array([u == "rad" for u in system.units], dtype=bool)
    if not angle.any():
        return np.zeros(0, dtype=np.intp)
    zero = np.zeros(n)
    J0 = _jacobian(system, t, y, zero, 0.0)
    Jyp = _jacobian(system, t, y, zero, 1.0) - J0
    scale = np.where(system.nominal > 0, system.nominal, 1.0)
    shift = 1e-3 * scale * np.cos(np.arange(n) + 0.5)
    J1 = _jacobian(system, t, y + shift, zero, 0.0)
    flat = ~_nonzero_columns(J0) & ~_nonzero_columns(J1)
    return np.flatnonzero(flat & angle & _nonzero_columns(Jyp))


class _Scaled:
    def __init__(self, system, t, y):
        self.s, self.t = system, t
        self.xs = np.where(system.nominal > 0, system.nominal, 1.0)
        J = _jacobian(system, t, y, np.zeros(system.n), 0.0)
        if sp.issparse(J):
            J = abs(J) @ sp.diags(self.xs)
            J.data = np.where(np.isfinite(J.data), J.data, 0.0)
            rs = np.asarray(J.max(axis=1).todense()).ravel()
        else:
            rs = np.nanmax(np.abs(J) * self.xs[None, :], axis=1) if system.n else np.zeros(0)
        rs = np.where(np.isfinite(rs) & (rs > 0), rs, 1.0)
        self.rs = rs

    def F(self, y, yp=None):
        yp = np.zeros(self.s.n) if yp is None else yp
        return self.s.residual(self.t, y, yp) / self.rs

    def norm(self, y, yp=None):
        f = self.F(y, yp)
        return float(np.max(np.abs(f))) if np.all(np.isfinite(f)) else np.inf


def _solve(J, rhs):
    if sp.issparse(J):
        from scipy.sparse.linalg import splu
        if not np.all(np.isfinite(J.data)):
            raise np.linalg.LinAlgError("non-finite Jacobian")
        try:
            dy = splu(J.tocsc()).solve(rhs)
        except RuntimeError as exc:          # "Factor is exactly singular"
            raise np.linalg.LinAlgError(str(exc)) from None
    else:
        dy = np.linalg.solve(J, rhs)
    if not np.all(np.isfinite(dy)):
        raise np.linalg.LinAlgError("non-finite step")
    return dy


def _newton(sc, y, tol, max_iter, c=0.0, y_prev=None):
    """Damped Newton on F(t, y, c (y - y_prev)) = 0 (c = 0: the steady state).

    Returns ``(y, norm, iterations, converged)``.
    """
    s = sc.s
    n = s.n

    def yp_of(yy):
        return np.zeros(n) if c == 0.0 else c * (yy - y_prev)

    fn = sc.norm(y, yp_of(y))
    for it in range(1, max_iter + 1):
        if fn <= tol:
            return y, fn, it - 1, True
        J = _jacobian(s, sc.t, y, yp_of(y), c)
        J = sp.diags(1.0 / sc.rs) @ J if sp.issparse(J) else J / sc.rs[:, None]
        try:
            dy = _solve(J, -sc.F(y, yp_of(y)))
        except np.linalg.LinAlgError:
            return y, fn, it, False
        lam = 1.0
        while lam > 1e-8:
            y_new = y + lam * dy
            fn_new = sc.norm(y_new, yp_of(y_new))
            if fn_new <= (1.0 - 1e-4 * lam) * fn:
                break
            lam *= 0.5
        else:
            # no descent left: round-off. On a continuation step (c > 0) the terms c (y - y_prev)
            # set a floor of about eps c |y|, above a tight tolerance; the step is good enough
            return y, fn, it, c != 0.0 and fn <= 1e-6
        step = np.max(np.abs(lam * dy) / (np.abs(y) + sc.xs)) if n else 0.0
        y, fn = y_new, fn_new
        if step < 1e-14 and fn <= max(tol, 1e-6):  # round-off floor of the residual
            return y, fn, it, True
    return y, fn, max_iter, fn <= tol


def _continuation(sc, y, tol, max_steps=400, dtau0=1e-6, dtau_max=1e6):
    """Pseudo-transient continuation: implicit Euler steps with growing ``dtau``."""
    dtau = dtau0
    f0 = sc.norm(y)
    steps = 0
    while steps < max_steps and dtau < dtau_max * 10:
        steps += 1
        y_new, _, _, ok = _newton(sc, y.copy(), 1e-10, 8, c=1.0 / dtau, y_prev=y)
        if not ok:
            dtau *= 0.25
            if dtau < 1e-14:
                break
            continue
        f1 = sc.norm(y_new)
        y = y_new
        if f1 <= tol:
            break
        # switched evolution relaxation: grow dtau as the steady residual falls
        dtau = min(dtau * min(10.0, max(1.5, f0 / max(f1, 1e-300))), dtau_max)
        f0 = f1
    return y, steps


def _culprits(system, sc, y, k=6):
    f = sc.F(y)
    f = np.where(np.isfinite(f), f, np.inf)
    J = _jacobian(system, sc.t, y, np.zeros(system.n), 0.0)
    Jyp = _jacobian(system, sc.t, y, np.zeros(system.n), 1.0) - J
    if sp.issparse(J):          # only the rows named below, dense
        J, Jyp = _Rows(J), _Rows(Jyp)
    lines = []
    for i in np.argsort(-np.abs(f))[:k]:
        if f[i] == 0.0:
            break
        row = np.abs(J[i]) * sc.xs
        cols = [system.names[j] for j in np.argsort(-row)[:3] if row[j] > 0]
        what = "variables"
        if not cols:  # only derivatives enter: this state can never settle
            cols = [system.names[j] for j in np.flatnonzero(np.abs(Jyp[i]) > 0)[:3]]
            what = "no steady value of"
        if not cols:
            lines.append(f"  {system.equations[i]}: scaled residual {f[i]:.3g}; it depends on "
                         f"no unknown here: the equations contradict each other (a loop of "
                         f"gain exactly 1, two sources fixing one quantity)")
            continue
        lines.append(f"  {system.equations[i]}: scaled residual {f[i]:.3g}; "
                     f"{what} {', '.join(cols)}")
    return lines


class _Rows:
    """Dense rows of a sparse matrix on demand (``J[i]``)."""

    def __init__(self, J):
        self.J = sp.csr_matrix(J)

    def __getitem__(self, i):
        return self.J.getrow(i).toarray().ravel()


def steady_state(system: System, *, y0=None, t: float = 0.0, tol: float = 1e-9,
                 max_iter: int = 50, continuation: bool = True,
                 params=None) -> OperatingPoint:
    """Solve ``F(t, y, 0) = 0`` for a steady operating point of ``system``.

    Parameters
    ----------
    y0 : array, optional
        Start guess (default ``system.y0``), e.g. the end of a settling simulation.
    tol : float
        Tolerance on the max-norm of the scaled residual.
    continuation : bool
        Fall back to pseudo-transient continuation when Newton fails.
    params : dict, optional
        Parameter values by name, applied with :meth:`System.with_params` (no compilation);
        the operating point's ``system`` carries them.

    Raises
    ------
    InitializationError
        No steady state found; the message names the equations with the largest scaled
        residual and the variables they depend on most.
    """
    from ..circuit import Circuit
    from ..simulate import _full_vector
    if isinstance(system, Circuit):
        system = system.compile()
    if not isinstance(system, System):
        raise PvgraphError(f"steady_state() takes a System or a Circuit, got "
                           f"{type(system).__name__}")
    if params:
        system = system.with_params(params)
    y = _full_vector(system, system.y0 if y0 is None else y0, "y0")
    if system.n == 0:
        return OperatingPoint(y, np.zeros(0), system, t, 0.0, 0, "trivial")
    cyc = _cyclic_states(system, t, y)
    problem = _CyclicView(system, cyc, y) if len(cyc) else system
    if len(cyc):
        y[cyc] = 0.0                      # the unknowns there are the rates
    sc = _Scaled(problem, t, y)
    y1, fn, its, ok = _newton(sc, y.copy(), tol, max_iter)
    method = "newton"
    total = its
    if not ok and continuation:
        y2, steps = _continuation(sc, y.copy(), tol)
        y1, fn, its, ok = _newton(sc, y2, tol, max_iter)
        total += steps + its
        method = "continuation"
    if not ok:
        lines = _culprits(problem, sc, y1)
        raise InitializationError(
            f"{system.name}: no steady state found (scaled residual {fn:.3g} > {tol:g} after "
            f"{total} iterations; Newton{' and continuation' if continuation else ''} failed). "
            f"Largest residuals:\n" + "\n".join(lines) +
            "\nCheck that every volume has an outlet and every mass a restoring force.")
    yp1 = np.zeros(system.n)
    info = {}
    if len(cyc):
        y1, yp1 = problem.split(y1)
        info["cyclic"] = [system.names[j] for j in cyc]
    _check_pressures(system, y1)
    return OperatingPoint(y1, yp1, system, t, fn, total, method, info)


def _check_pressures(system, y):
    """Warn of a steady pressure beyond the physical range (as ``simulate`` does along a
    run): a source into a dead end balanced only by a leakage gap."""
    import warnings

    from ..errors import PlausibilityWarning
    from ..simulate import PRESSURE_LIMIT
    cols = [j for j, unit in enumerate(system.units) if unit == "Pa"]
    worst = sorted(((abs(float(y[j])), system.names[j]) for j in cols
                    if not abs(y[j]) <= PRESSURE_LIMIT), reverse=True)
    if worst:
        listed = "; ".join(f"{n} is {v / 1e5:.3g} bar" for v, n in worst[:3])
        warnings.warn(PlausibilityWarning(
            f"{system.name}: implausible steady pressure (beyond {PRESSURE_LIMIT / 1e5:.0f} "
            f"bar): {listed}. A flow source or pump feeding a closed valve or a dead end holds "
            f"a steady state only through leakage; add a relief valve or an outlet."),
            stacklevel=3)
