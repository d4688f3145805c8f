"""Steady operating points: solve F(t, y, y') = 0 with y' = 0, or at a steady rate of turning.

Newton's method with a backtracking line search on the scaled residual, using the exact
Jacobian ``dF/dy`` of the compiled system. If Newton stalls, pseudo-transient continuation
follows the circuit's own dynamics (implicit Euler steps of growing size ``dtau``, the Jacobian
``dF/dy + dF/dy'/dtau``) towards an equilibrium and Newton is tried again from there.

Turning machines: a shaft turning at a steady speed has no steady angle, only a steady rate.
A drift direction ``d`` is a motion of the unknowns that leaves F unchanged (``dF/dy d = 0``
at the start and at two nearby points) and turns an angle [rad], moving only angles and
positions [m]: one shaft (``d`` = its angle), shafts joined by springs, dampers or gears (the
common rotation, in the gear ratios), a rack driven by a pinion. At the operating point the
unknowns drift along ``d`` at a steady rate (``y' = G v``, ``y'' = 0``) while every other
unknown stays constant; the unknowns solved for are the rates ``v`` at one pivot angle per
direction (held at its start value) and every other unknown (a second angle settles at its
twist). A pump on a ``SpeedSource``, a motor turning an inertia or a gear train has an
operating point; a torque on a free inertia still has none.

Scaling: variables by ``system.nominal``; residual rows by ``max_j |dF_i/dy_j| nominal_j`` at
the start point (the size of the row's terms), so the tolerance is relative.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..errors import InitializationError, PvgraphError
from ..system import System

__all__ = ["OperatingPoint", "steady_state"]


@dataclass
class OperatingPoint:
    """A steady state of ``system``: ``y`` with ``yp = 0``; ``op["name"]`` looks up by name.

    On a turning machine ``yp`` holds the steady rates of the drifting angles (and positions
    tied to them); ``info["cyclic"]`` names one pivot angle per drift direction (held at its
    start value; sensitivities hold it fixed) and ``info["drift"]`` gives each direction as
    ``{name: coefficient}`` with 1 at its pivot (``yp = coefficient * yp[pivot]``).
    ``info["undetermined"]`` names the unknowns no steady equation reads (a free mass's
    position, a rod at rest): they keep their start values, and any other value is as steady.
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

    def poles(self) -> np.ndarray:
        """The poles of the circuit linearised here [1/s] (eigenvalues of the state matrix of
        :func:`~pvgraph.analysis.linearize`): all with negative real parts where the steady
        state is stable."""
        from .linearize import linearize
        got = self.info.get("poles")
        if got is None and not self.system.differential.any():
            got = np.zeros(0, dtype=complex)    # no state, no pole
        if got is None:
            got = linearize(self.system, self, None, [self.system.names[0]],
                            warn_stops=False).poles()
            self.info["poles"] = got
        return np.asarray(got)

    def state_sensitivity(self, params=None) -> np.ndarray:
        """dy/dp at this steady state, ``(n, len(params))``: the solution of F_y S = -F_p.

        ``F_p`` is the compiled parameter derivative dF/dp; one factorisation of F_y serves
        every parameter. ``params`` defaults to every runtime parameter of the system.
        """
        from ..simulate import _name_list
        s = self.system
        params = None if params is None else _name_list(params, "state_sensitivity: params")
        Fp = s.parameter_jacobian(self.t, self.y, self.yp, params)
        return self.solve_linear(-Fp)

    def drift_matrix(self):
        """``(G, piv)``: the drift directions as columns of ``G`` (n, m), each 1 at its pivot
        angle ``piv[k]`` (``info["cyclic"]``); ``yp = G yp[piv]`` at this point."""
        names = self.system.names
        cyc = np.array([names.index(nm) for nm in self.info.get("cyclic", ())], dtype=np.intp)
        G = np.zeros((self.system.n, len(cyc)))
        drift = self.info.get("drift") or [{names[j]: 1.0} for j in cyc]
        for k, d in enumerate(drift):
            for nm, v in d.items():
                G[names.index(nm), k] = v
        return G, cyc

    def solve_linear(self, rhs) -> np.ndarray:
        """Solve ``F_y X = rhs`` with the steady Jacobian ``F_y = dF/dy`` at this point."""
        s = self.system
        if self.info.get("cyclic"):
            # the steady rates of the drift directions stand in for the pivot angles, which
            # stay put (dy = 0 there)
            G, cyc = self.drift_matrix()
            J = s.jacobian_dense(self.t, self.y, self.yp, 0.0)
            Jyp = s.jacobian_dense(self.t, self.y, self.yp, 1.0) - J
            J[:, cyc] = Jyp @ G
            x = np.linalg.solve(J, rhs)
            x[cyc] = 0.0
            return x
        if self.info.get("undetermined"):
            return self._solve_holding(rhs)
        if s.n <= s.DENSE_MAX:
            J = s.jacobian_dense(self.t, self.y, self.yp, 0.0)
            return np.linalg.solve(J, rhs)
        from scipy.sparse.linalg import splu
        lu = splu(s.jacobian(self.t, self.y, self.yp, 0.0).tocsc())
        return lu.solve(np.asarray(rhs, dtype=float))

    def _solve_holding(self, rhs) -> np.ndarray:
        """``F_y X = rhs`` with the undetermined unknowns (``info["undetermined"]``: a rod
        held by a closed oil column, a shaft at rest between closed ports) held where they
        are: F_y is singular there, one equation per such unknown repeats the others, and the
        rest determine everything else (least squares of the consistent system, checked)."""
        s = self.system
        held = [s.names.index(nm) for nm in self.info["undetermined"]]
        keep = np.setdiff1d(np.arange(s.n), held)
        if s.n > 40 * s.DENSE_MAX:
            raise PvgraphError(f"{s.name}: sensitivities at a steady state with undetermined "
                               f"unknowns ({', '.join(self.info['undetermined'][:3])}) are "
                               f"solved dense, up to {40 * s.DENSE_MAX} unknowns; this system "
                               f"has {s.n}")
        J = s.jacobian_dense(self.t, self.y, self.yp, 0.0)
        b = np.asarray(rhs, dtype=float)
        sub, *_ = np.linalg.lstsq(J[:, keep], b, rcond=None)
        miss = J[:, keep] @ sub - b
        scale = np.abs(J[:, keep]) @ np.abs(sub) + np.abs(b)
        if np.any(np.abs(miss) > 1e-8 * np.max(scale, axis=0) + 1e-300):
            raise PvgraphError(
                f"{s.name}: the steady state holds {', '.join(self.info['undetermined'][:3])} "
                f"undetermined (nothing fixes {'it' if len(held) == 1 else 'them'}), and the "
                f"change asked for moves the equation that would: there is no steady "
                f"sensitivity (the point stops being steady); simulate instead")
        out = np.zeros((s.n,) + b.shape[1:])
        out[keep] = sub
        return out

    def sensitivity(self, outputs, params=None, *, dy_dp=None) -> np.ndarray:
        """d output / d parameter at this steady state, ``(len(outputs), len(params))``.

        ``outputs`` are names of unknowns, aliases or derived outputs; ``params`` parameter
        names (default: all). The steady state moves with the parameters: ``d out/dp =
        d out/dy dy/dp + d out/dp`` with ``dy/dp = -F_y^-1 F_p`` (:meth:`state_sensitivity`).
        """
        from ..simulate import _name_list
        s = self.system
        outputs = _name_list(outputs, "sensitivity: outputs")
        params = None if params is None else _name_list(params, "sensitivity: params")
        S = self.state_sensitivity(params) if dy_dp is None else dy_dp
        rows = []
        for name in outputs:
            gy, gp = s.output_gradient(name, self.t, self.y, self.yp, params)
            rows.append(gy @ S + gp)
        return np.array(rows).reshape(len(rows), S.shape[1])


class _DriftView:
    """``system`` with the steady rates of its drift directions as unknowns.

    ``G`` (n, m) holds the drift directions, each with coefficient 1 at its pivot unknown
    ``piv[k]`` (an angle). The unknowns ``z`` are ``y`` except ``z[piv]``, the pivots' rates:
    ``y' = G z[piv]`` (plus the pseudo-time rate of the others during continuation) and
    ``y[piv]`` stays at its start value; the other unknowns of a direction (a second angle
    joined by a spring or a gear, a rack's position) are solved for.
    """

    def __init__(self, system, G, piv, y_start):
        self._s, self.G, self.cyc = system, np.asarray(G, dtype=float), np.asarray(piv)
        self.y_fix = np.asarray(y_start, dtype=float)[self.cyc].copy()
        self.n, self.equations = system.n, system.equations
        self.names = list(system.names)
        for j in self.cyc:
            self.names[j] = f"der({system.names[j]})"
        self.nominal = np.asarray(system.nominal, dtype=float)
        self.DENSE_MAX = getattr(system, "DENSE_MAX", np.inf)
        n = system.n
        self._keep = np.ones(n)
        self._keep[self.cyc] = 0.0
        rows, k = np.nonzero(self.G)
        self._Gs = sp.csr_matrix((self.G[rows, k], (rows, self.cyc[k])), shape=(n, n))

    def split(self, z, zp=None):
        """``(y, y')`` of the system for the unknowns ``z`` (drift rates at the pivots)."""
        y = np.array(z, dtype=float)
        yp = np.zeros(self.n) if zp is None else np.array(zp, dtype=float)
        yp[self.cyc] = 0.0
        yp += self.G @ y[self.cyc]
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
        J[:, self.cyc] = Jyp @ self.G
        return J

    def jacobian(self, t, z, zp, c):
        y, yp = self.split(z, zp)
        J0 = sp.csr_matrix(self._s.jacobian(t, y, yp, 0.0))
        Jyp = sp.csr_matrix(self._s.jacobian(t, y, yp, 1.0)) - J0
        return sp.csr_matrix((J0 + c * Jyp) @ sp.diags(self._keep) + Jyp @ self._Gs)


class _StartView:
    """The consistent-start problem of ``system`` at ``t``: unknowns ``z``, the algebraic
    variables' values and the differential ones' rates, the states held at ``y``."""

    def __init__(self, system, t, y):
        self._s, self.t = system, t
        self.alg = np.asarray(system.algebraic, dtype=bool)
        self.y = np.asarray(y, dtype=float).copy()
        self.n, self.equations, self.names = system.n, system.equations, list(system.names)
        self.nominal = np.asarray(system.nominal, dtype=float)

    def split(self, z):
        y, yp = self.y.copy(), np.zeros(self.n)
        y[self.alg] = z[self.alg]
        yp[~self.alg] = z[~self.alg]
        return y, yp

    def residual(self, t, z, zp):
        return self._s.residual(self.t, *self.split(z))

    def jacobian_dense(self, t, z, zp, c):
        y, yp = self.split(z)
        J0 = self._s.jacobian_dense(self.t, y, yp, 0.0)
        J = self._s.jacobian_dense(self.t, y, yp, 1.0) - J0     # dF/dy'
        J[:, self.alg] = J0[:, self.alg]
        return J


def limited_start(system, t, y, yp, tol=1e-9):
    """``(y, y')`` consistent at ``t`` with the states of ``y`` kept, by Newton with limited
    steps (as :func:`steady_state`'s fallback), or None. For a start the consistent
    initialisation's Newton misses from a valve closed at the start (its flat leakage) where
    the load moves, so that no steady state exists to start from."""
    if system.n > getattr(system, "DENSE_MAX", np.inf):
        return None
    view = _StartView(system, t, y)
    z = np.asarray(y, dtype=float).copy()
    z[~view.alg] = np.asarray(yp, dtype=float)[~view.alg]
    z1, fn, _, _ = _newton(_Scaled(view, t, z), z, tol, LIMITED_MAX_ITER, limited=True)
    if not np.isfinite(fn):
        return None
    _, z2, _, ok, _ = _rescaled(view, t, z1, tol, 50)
    return view.split(z2) if ok else None


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


def _drift_directions(system, t, y):
    """Directions ``d`` along which the unknowns may move at a steady rate: ``F(t, y + s d,
    y')`` does not depend on ``s`` (``dF/dy d = 0`` at ``y`` and at two nearby points), ``d``
    holds an angle [rad] and only angles and positions [m] (a shaft turning for ever, a
    second shaft joined to it by a spring or a gear, a rack it drives).

    Only angles: a pressure or a position rising for ever on its own is no operating point.
    Returns ``(G, piv)``: ``G`` (n, m) the directions, each 1 at its pivot angle ``piv[k]``
    (a differential state where possible).
    """
    n = system.n
    units = list(system.units)
    angle = np.array([u == "rad" for u in units], dtype=bool)
    none = (np.zeros((n, 0)), np.zeros(0, dtype=np.intp))
    if not angle.any():
        return none
    cand = np.flatnonzero(angle | np.array([u == "m" for u in units], dtype=bool))
    scale = np.where(system.nominal > 0, system.nominal, 1.0)
    zero = np.zeros(n)
    wave = np.cos(np.arange(n) + 0.5)
    points = [(y, zero), (y + 1e-3 * scale * wave, 1e-3 * scale * np.sin(np.arange(n) + 0.5)),
              (y + np.where(angle, 0.37 * wave, 0.0), zero)]
    blocks, Jyp = [], None
    for k, (yy, ypp) in enumerate(points):
        try:
            J0 = _jacobian(system, t, yy, ypp, 0.0)
            if k == 0:
                Jyp = _jacobian(system, t, yy, ypp, 1.0) - J0
        except (ArithmeticError, ValueError, PvgraphError):
            continue
        Jc = J0[:, cand]
        Jc = Jc.toarray() if sp.issparse(Jc) else np.asarray(Jc)
        if np.all(np.isfinite(Jc)):
            blocks.append(Jc)
    if not blocks:
        return none
    Jc = np.vstack(blocks) * scale[cand][None, :]
    Jc = Jc[np.any(Jc != 0.0, axis=1)]
    Jc = Jc / np.max(np.abs(Jc), axis=1, keepdims=True) if len(Jc) else Jc
    if len(Jc):
        _, sv, Vt = np.linalg.svd(Jc, full_matrices=True)
        rank = int(np.sum(sv > 1e-9 * sv[0])) if sv.size and sv[0] > 0 else 0
        N = Vt[rank:].T                                  # null space, scaled coordinates
    else:
        N = np.eye(len(cand))
    if N.shape[1] == 0:
        return none
    # keep the directions that turn an angle (a position drifting alone is no steady state)
    ang = angle[cand]
    if not ang.any():
        return none
    _, sa, Wt = np.linalg.svd(N[ang], full_matrices=True)
    m = int(np.sum(sa > 1e-6))
    if m == 0:
        return none
    D = N @ Wt[:m].T * scale[cand][:, None]               # back to unknowns' units
    D[np.abs(D) < 1e-12 * np.max(np.abs(D), axis=0, keepdims=True)] = 0.0
    # pivots: angles, differential states first, chosen by column-pivoted QR
    from scipy.linalg import qr
    rows = np.flatnonzero(ang)
    diff = np.asarray(getattr(system, "differential", np.ones(n, bool)), bool)[cand[rows]]
    weight = np.where(diff, 1.0, 1e-3) / scale[cand[rows]]
    _, _, perm = qr((D[rows] * weight[:, None]).T, pivoting=True, mode="economic")
    prow = rows[perm[:m]]
    G_c = D @ np.linalg.inv(D[prow])
    G_c[np.abs(G_c) < 1e-12] = 0.0
    G = np.zeros((n, m))
    G[cand] = G_c
    piv = cand[prow]
    # a direction must reach the equations through its rate, or nothing fixes the rate
    if Jyp is not None:
        JG = Jyp @ G
        JG = np.asarray(JG)
        ok = np.any(JG != 0.0, axis=0)
        G, piv = G[:, ok], piv[ok]
    order = np.argsort(piv)
    return G[:, order], piv[order]


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
        if not f.size:
            return 0.0
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


LIMIT_NOMINALS = 10.0      # a limited Newton step moves an unknown by at most this many
                           # nominal values (10 x 10 bar for a pressure), or by its own size
LIMITED_MAX_ITER = 200
CONTACT_NEWTON_ITERS = 30  # Newton iterations per continuation step, second attempt


def _newton(sc, y, tol, max_iter, c=0.0, y_prev=None, limited=False):
    """Damped Newton on F(t, y, c (y - y_prev)) = 0 (c = 0: the steady state).

    ``limited``: no unknown moves by more than ``max(10 nominal, |y|)`` in one step (the
    voltage limiting of circuit simulators). From a valve closed at the start, its leakage's
    slope sends the first full step a million times too far, past the opening, where the
    next step throws it back; limited, the pressure climbs (doubling at most) until the valve
    opens, and Newton converges from there.

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
        if limited:
            reach = np.max(np.abs(dy) / np.maximum(LIMIT_NOMINALS * sc.xs, np.abs(y)))
            lam = min(1.0, 1.0 / reach) if reach > 0.0 else 1.0
        # limited steps cross a flat stretch (a closed valve's leakage) where the residual
        # hardly falls: any fall is taken there
        sufficient = 0.0 if limited else 1e-4
        lam_min = 1e-8 * lam
        while lam > lam_min:
            y_new = y + lam * dy
            fn_new = sc.norm(y_new, yp_of(y_new))
            if fn_new <= (1.0 - sufficient * lam) * fn and (not limited or fn_new < fn):
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


def _rescaled(problem, t, y, tol, max_iter, polish=True):
    """``(scaling, y, norm, converged, iterations)`` with the rows scaled at ``y``: ``y`` as
    it is where its residual is within ``tol`` so scaled, else (``polish``) after Newton."""
    sc = _Scaled(problem, t, y)
    fn = sc.norm(y)
    if fn <= tol or not polish:
        return sc, y, fn, fn <= tol, 0
    y2, fn2, its, ok = _newton(sc, y.copy(), tol, max_iter)
    return sc, y2, fn2, ok, its


def _continuation(sc, y, tol, max_steps=400, dtau0=1e-6, dtau_max=1e6, newton_iters=8):
    """Pseudo-transient continuation: implicit Euler steps with growing ``dtau``."""
    dtau = dtau0
    f0 = sc.norm(y)
    steps = 0
    while steps < max_steps and dtau < dtau_max * 10:
        steps += 1
        y_new, _, _, ok = _newton(sc, y.copy(), 1e-10, newton_iters, c=1.0 / dtau, y_prev=y)
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
    if not (isinstance(tol, (int, float)) and 0.0 < tol < 1.0):
        raise PvgraphError(f"steady_state: tol must lie in (0, 1), got {tol!r}")
    if not (isinstance(max_iter, int) and max_iter >= 1):
        raise PvgraphError(f"steady_state: max_iter must be a positive integer, got "
                           f"{max_iter!r}")
    if not (isinstance(t, (int, float)) and math.isfinite(t)):
        raise PvgraphError(f"steady_state: t must be a finite time [s], got {t!r}")
    if params is not None:
        from ..circuit import parameter_values
        params = parameter_values(params, "steady_state: params")
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
    G, cyc = _drift_directions(system, t, y)
    problem = _DriftView(system, G, cyc, y) if len(cyc) else system
    if len(cyc):
        y[cyc] = 0.0                      # the unknowns there are the rates
    sc = _Scaled(problem, t, y)
    y1, fn, its, ok = _newton(sc, y.copy(), tol, max_iter)
    method = "newton"
    total = its
    # After each stage that misses, the rows are scaled again where it stopped: they were
    # scaled by their slopes at the start, which can be far smaller than at the answer (a
    # valve closed at the start: its flow's slope is its leakage's; a rod carried onto its end
    # stop: the stop's stiffness), so a residual at rounding level is seen as such there.
    if not ok and np.isfinite(fn):
        here = _rescaled(problem, t, y1, tol, max_iter)
        total += here[4]
        if here[3]:
            sc, y1, fn, ok = here[:4]
    if not ok and continuation:
        y2, steps = _continuation(sc, y.copy(), tol)
        y1, fn, its, ok = _newton(sc, y2, tol, max_iter)
        total += steps + its
        method = "continuation"
        if not ok and np.isfinite(fn):
            here = _rescaled(problem, t, y1, tol, max_iter, polish=False)
            if here[3]:
                sc, y1, fn, ok = here[:4]
    if not ok:
        # valves closed at the start, with no volume to make continuation's steps gentle
        # (a flow source straight into a check valve that cracks at 50 bar): Newton with
        # limited steps, then polished with the rows scaled where it ended
        y2, fn2, its2, _ = _newton(sc, y.copy(), tol, LIMITED_MAX_ITER, limited=True)
        total += its2
        if np.isfinite(fn2):
            here = _rescaled(problem, t, y2, tol, max_iter)
            total += here[4]
            if here[3]:
                (sc, y1, fn, ok), method = here[:4], "limited newton"
    if not ok and continuation:
        # a load carried onto its end stop: the implicit Euler step that meets the stop's
        # stiffness needs more Newton iterations than a step in free travel
        y2, steps = _continuation(sc, y.copy(), tol, newton_iters=CONTACT_NEWTON_ITERS)
        y3, fn3, its3, ok3 = _newton(sc, y2, tol, max_iter)
        total += steps + its3
        if ok3:
            y1, fn, ok, method = y3, fn3, True, "continuation"
        elif np.isfinite(fn3):
            here = _rescaled(problem, t, y3, tol, max_iter, polish=False)
            if here[3]:
                (sc, y1, fn, ok), method = here[:4], "continuation"
    if not ok:
        lines = _culprits(problem, sc, y1)
        raise InitializationError(
            f"{system.name}: no steady state found (scaled residual {fn:.3g} > {tol:g} after "
            f"{total} iterations; Newton{' and continuation' if continuation else ''} failed). "
            f"Largest residuals:\n" + "\n".join(lines) +
            "\nCheck that every volume has an outlet and every mass a restoring force" +
            (" (or, on a turning shaft, a friction or load torque: a torque on a free inertia "
             "speeds it up for ever)." if any(u == "rad" for u in system.units) else ".") +
            (" A load that comes to rest against an end stop is held only in contact: start "
             "its mass at the stop (x0), or from the end of a settling run, "
             "steady_state(system, y0=sol.y[-1]). A mass that keeps moving at a steady speed "
             "(a force against a damper) has no steady position: steady_state looks for rest "
             "(only shaft angles may turn on); simulate it to its steady speed." if any(
                 u == "m" and nm.endswith(".x") for u, nm in zip(system.units, system.names))
             else ""))
    yp1 = np.zeros(system.n)
    info = {}
    if len(cyc):
        y1, yp1 = problem.split(y1)
        info["cyclic"] = [system.names[j] for j in cyc]
        info["drift"] = [{system.names[i]: float(G[i, k]) for i in np.flatnonzero(G[:, k])}
                         for k in range(len(cyc))]
    free = _undetermined(system, t, y1, yp1, cyc)
    if free:
        info["undetermined"] = free
    _check_pressures(system, y1)
    op = OperatingPoint(y1, yp1, system, t, fn, total, method, info)
    _check_stability(op)
    return op


#: steady states of systems up to this many unknowns are checked for stability (a dense
#: linearisation: about 1 ms at 100 unknowns, 0.12 s at 600, some seconds at 2000); bigger
#: ones are checked on request, ``op.poles()``
STABILITY_MAX_N = 1000


def _check_stability(op) -> None:
    """Warn where the steady state is unstable: a pole of the linearisation with a positive
    real part (a simulation from it oscillates or runs away instead of staying). The poles
    are kept in ``op.info["poles"]``."""
    import warnings

    from ..errors import PlausibilityWarning
    system = op.system
    if not 0 < system.n <= STABILITY_MAX_N or not system.differential.any():
        return
    try:
        poles = op.poles()
    except (PvgraphError, np.linalg.LinAlgError, ValueError):
        return
    op.info["poles"] = poles
    if not len(poles):
        return
    # a zero pole (a free position, a drifting angle) is neutral, not unstable: the bar is
    # above the rounding of a double zero pole, sqrt(eps |A|) (a free mass: x' = v, v' = 0)
    bar = max(1e-3, 10.0 * math.sqrt(np.finfo(float).eps * float(np.abs(poles).max())))
    bad = poles[poles.real > bar]
    if not len(bad):
        return
    worst = bad[np.argmax(bad.real)]
    if abs(worst.imag) > bar:
        how = (f"{worst.real:.3g} +- {abs(worst.imag):.3g}j 1/s: an oscillation at "
               f"{abs(worst.imag) / (2.0 * math.pi):.3g} Hz that grows")
    else:
        how = f"{worst.real:.3g} 1/s: a departure that grows with time constant " \
              f"{1.0 / worst.real:.3g} s"
    warnings.warn(PlausibilityWarning(
        f"{system.name}: the steady state found is unstable (pole {how}; {len(bad)} unstable "
        f"pole{'s' if len(bad) > 1 else ''} of {len(poles)}, op.poles()). The equations balance "
        f"there, but the circuit does not stay: a simulation from it oscillates or runs away. "
        f"Compliance or damping where the loop is stiff (a volume on a valve's port, a "
        f"damper on a spool) steadies it; simulate to see what it does instead."),
        stacklevel=3)


def _undetermined(system, t, y, yp, cyclic) -> list[str]:
    """The unknowns no steady equation reads (a column of dF/dy that is zero at the operating
    point): a free mass's position, a rod at rest whose chambers' volumes only matter while
    the pressures change. They keep their start values; any other value is as steady."""
    J = _jacobian(system, t, y, yp, 0.0)
    if sp.issparse(J):
        J = sp.csc_matrix(J)
        J.data = np.where(np.isfinite(J.data), J.data, 1.0)
        used = np.asarray(abs(J).max(axis=0).todense()).ravel() > 0.0
    else:
        used = np.any(np.abs(np.nan_to_num(J, nan=1.0)) > 0.0, axis=0)
    skip = set(int(j) for j in cyclic)
    return [system.names[j] for j in np.flatnonzero(~used) if int(j) not in skip]


P_ATM = 101325.0                  # [Pa] the atmosphere that gauge pressures are read from
VAPOUR_GAUGE = -P_ATM + 2000.0    # [Pa] mineral oil's vapour pressure (2 kPa), as gauge


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
            f"bar): {listed}. A flow source or pump pushes its flow through whatever is open: "
            f"an outlet too small for it (an orifice or valve sized for less flow), or a "
            f"closed valve or dead end that only leakage passes; give the flow a way out "
            f"sized for it, or a relief valve. Where such "
            f"a pressure is meant (an intensifier's area ratio), raise "
            f"pvgraph.simulate.PRESSURE_LIMIT."),
            stacklevel=3)
    # pressures are gauge: below -p_atm + p_vap the oil would have to carry tension. A run
    # stops there (every chamber limits its pressure at the vapour pressure); the steady
    # equations of a node balance its flows only and do not
    vacuum = sorted((float(y[j]), system.names[j]) for j in cols
                    if y[j] < VAPOUR_GAUGE and system.names[j].endswith(".p"))
    if vacuum:
        listed = "; ".join(f"{n} is {v / 1e5:.4g} bar gauge ({(v + P_ATM) / 1e5:.3g} bar "
                           f"absolute)" for v, n in vacuum[:3])
        warnings.warn(PlausibilityWarning(
            f"{system.name}: steady pressure below the oil's vapour pressure: {listed}. No "
            f"oil holds it: the oil cavitates there and this steady state is not physical. "
            f"Something draws more flow from that node than reaches it (a pump's or a "
            f"cylinder's suction behind a valve that needs a pressure drop to open); feed it "
            f"from tank directly or through a make-up check valve."), stacklevel=3)


def reduce_drift(op: OperatingPoint, A, B, C, x):
    """Take the steady drift of a turning machine out of a linear model ``x' = A x + B u``,
    ``y = C x`` at ``op`` (``x`` the indices of the states in ``op.system``).

    A drift direction ``d`` (``op.info["drift"]``) is a zero-eigenvalue mode, ``A d = 0``:
    the whole machine turned by an angle is again a steady state. Where the outputs do not
    see it (``C d = 0``), the state ``x_p`` of the pivot is dropped and the others become
    ``x_i - (d_i / d_p) x_p``: a shaft joined to another by a spring keeps its twist
    ``phi1 - phi2``, a bare angle (``d = e_p``) just leaves the model.
    Returns ``(A, B, C, x, names)``.
    """
    system = op.system
    names = [system.names[k] for k in x]
    A, B, C, x = np.array(A, float), np.array(B, float), np.array(C, float), np.asarray(x)
    if not op.info.get("cyclic"):
        return A, B, C, x, names
    G, _ = op.drift_matrix()
    for k in range(G.shape[1]):
        d = G[x, k]
        if not np.any(d):
            continue
        size = np.linalg.norm(d)
        if (np.linalg.norm(A @ d) > 1e-8 * max(np.linalg.norm(A), 1.0) * size
                or np.linalg.norm(C @ d) > 1e-12 * max(np.linalg.norm(C), 1.0) * size):
            continue              # not a mode of this model, or an output reads the angle
        p = int(np.argmax(np.abs(d) * np.asarray(system.differential, float)[x]))
        if d[p] == 0.0:
            continue
        ratio = d / d[p]
        keep = np.array([r for r in range(len(x)) if r != p], dtype=np.intp)
        A = (A - np.outer(ratio, A[p]))[np.ix_(keep, keep)]
        B = (B - np.outer(ratio, B[p]))[keep]
        C = C[:, keep]
        pname = names[p]
        for r in np.flatnonzero(ratio):
            if r != p:
                f = ratio[r]
                names[r] = (f"{names[r]} - {pname}" if f == 1.0 else
                            f"{names[r]} - {f:.6g}*{pname}")
        names = [names[r] for r in keep]
        x = x[keep]
    return A, B, C, x, names
