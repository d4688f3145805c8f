"""Linear state-space models of a compiled DAE at an operating point.

At a steady state (``y' = 0``) the DAE ``F(t, y, y', u) = 0`` linearises to::

    J_yp[:, x] dx' + J_y[:, x] dx + J_y[:, z] dz + F_u du = 0

with ``x`` the differential variables (``system.differential``) and ``z`` the algebraic ones.
The compiler guarantees index one, so ``M = [J_yp[:, x], J_y[:, z]]`` is regular and
``[dx'; dz] = -M^-1 (J_y[:, x] dx + F_u du)`` gives ``A, B`` (rows of ``dx'``) and the algebraic
response (rows of ``dz``) from which any named output's ``C, D`` follow.

Inputs
------
A compiled system has its parameters folded into the generated code, so an input cannot be
perturbed inside it. Inputs are therefore given either

- directly as residual sensitivities ``dF/du`` (``linearize(system, op, {"u": column}, ...)``),
- or, most conveniently, by a *builder*: :func:`linearize_circuit` takes
  ``build(u: dict) -> Circuit``, compiles ``build(u0)``, finds its steady state and obtains
  ``dF/du`` by central differences of the residuals of ``build(u0 +- du)`` evaluated at that
  same operating point (the systems share their unknowns, since only constants change; this is
  checked).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from ..errors import PvgraphError
from ..system import System
from .steady import OperatingPoint, steady_state

__all__ = ["LinearModel", "linearize", "linearize_circuit", "input_sensitivity"]

_C_BIG = 2.0 ** 30  # c used to split dF/dy' from dF/dy without cancellation


@dataclass
class LinearModel:
    """``x' = A x + B u``, ``y = C x + D u`` in deviations from an operating point."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    state_names: list
    input_names: list
    output_names: list
    op: OperatingPoint | None = None

    def _idx(self, key, names, what):
        if isinstance(key, (int, np.integer)):
            return int(key)
        try:
            return names.index(key)
        except ValueError:
            raise KeyError(f"no {what} named {key!r}; the {what}s are {names}") from None

    def poles(self) -> np.ndarray:
        """Eigenvalues of ``A``, sorted by decreasing real part (the dominant ones first)."""
        ev = np.linalg.eigvals(self.A) if self.A.size else np.zeros(0)
        return ev[np.argsort(-ev.real, kind="stable")]

    def dc_gain(self) -> np.ndarray:
        """Steady-state gain ``D - C A^-1 B`` (outputs x inputs)."""
        return self.D - self.C @ np.linalg.solve(self.A, self.B)

    def tf(self, output=0, input=0):
        """``(num, den)`` of the transfer function from ``input`` to ``output`` (scipy.signal)."""
        from scipy import signal
        i = self._idx(output, self.output_names, "output")
        j = self._idx(input, self.input_names, "input")
        num, den = signal.ss2tf(self.A, self.B, self.C[i:i + 1], self.D[i:i + 1], input=j)
        return num[0], den

    def to_control(self):
        """The model as a python-control ``StateSpace`` (imported lazily).

        python-control forbids '.' in signal names, so dots become '_' there.
        """
        import control

        def clean(names):
            return [str(nm).replace(".", "_") for nm in names]
        return control.ss(self.A, self.B, self.C, self.D, inputs=clean(self.input_names),
                          outputs=clean(self.output_names), states=clean(self.state_names))

    def step(self, t, output=0, input=0, amplitude=1.0) -> np.ndarray:
        """Response of ``output`` to a step of size ``amplitude`` in ``input`` at t = 0."""
        from scipy import signal
        i = self._idx(output, self.output_names, "output")
        j = self._idx(input, self.input_names, "input")
        sys = signal.StateSpace(self.A, self.B[:, j:j + 1], self.C[i:i + 1], self.D[i:i + 1, j:j + 1])
        _, yout, _ = signal.lsim(sys, np.full(len(t), amplitude), t)
        return np.asarray(yout).reshape(-1)


def _jacobians(system, op):
    t, y, yp = op.t, op.y, np.zeros(system.n)
    J_y = system.jacobian_dense(t, y, yp, 0.0)
    J_yp = (system.jacobian_dense(t, y, yp, _C_BIG) - J_y) / _C_BIG
    if not (np.all(np.isfinite(J_y)) and np.all(np.isfinite(J_yp))):
        raise PvgraphError(f"{system.name}: the Jacobian is not finite at the operating point")
    return J_y, J_yp


def linearize(system: System, op: OperatingPoint, inputs: Mapping[str, np.ndarray] | None,
              outputs: Sequence[str], *, states: str = "differential") -> LinearModel:
    """Linearise ``system`` at ``op``.

    Parameters
    ----------
    inputs : mapping name -> array (n,)
        Residual sensitivity ``dF/du`` of each input (see :func:`input_sensitivity`).
    outputs : names
        Any unknown or eliminated alias of the system (states, algebraic variables).
    """
    inputs = dict(inputs or {})
    n = system.n
    x = np.flatnonzero(system.differential)
    z = np.flatnonzero(system.algebraic)
    J_y, J_yp = _jacobians(system, op)
    F_u = np.column_stack([np.asarray(v, dtype=float).reshape(n) for v in inputs.values()]) \
        if inputs else np.zeros((n, 0))
    M = np.hstack([J_yp[:, x], J_y[:, z]])
    try:
        S = -np.linalg.solve(M, np.hstack([J_y[:, x], F_u]))
    except np.linalg.LinAlgError as exc:
        raise PvgraphError(f"{system.name}: [dF/dx', dF/dz] is singular at the operating "
                           f"point; the DAE is not index one there ({exc})") from None
    nx = len(x)
    A, B = S[:nx, :nx], S[:nx, nx:]
    Zx, Zu = S[nx:, :nx], S[nx:, nx:]
    pos_x = {int(k): r for r, k in enumerate(x)}
    pos_z = {int(k): r for r, k in enumerate(z)}
    C = np.zeros((len(outputs), nx))
    D = np.zeros((len(outputs), len(inputs)))
    for r, name in enumerate(outputs):
        if name in system.observed:
            raise KeyError(f"{name!r} is a derived output; linearise one of the variables it "
                           f"is computed from instead")
        coef, idx, _ = system.resolve(name)
        if idx is None:
            continue
        if idx in pos_x:
            C[r, pos_x[idx]] = coef
        else:
            C[r] = coef * Zx[pos_z[idx]]
            D[r] = coef * Zu[pos_z[idx]]
    return LinearModel(A, B, C, D, [system.names[k] for k in x], list(inputs), list(outputs),
                       op)


def input_sensitivity(build: Callable[[dict], object], u0: Mapping[str, float], name: str,
                      op: OperatingPoint, *, eps_rel: float = 1e-5,
                      du: float | None = None) -> np.ndarray:
    """``dF/du`` of input ``name`` by central differences of rebuilt systems at ``op``."""
    u0 = dict(u0)
    h = du if du is not None else eps_rel * (abs(u0[name]) if u0[name] != 0.0 else 1.0)
    cols = []
    for sign in (1.0, -1.0):
        u = dict(u0)
        u[name] = u0[name] + sign * h
        s = _as_system(build(u))
        if s.names != op.system.names:
            raise PvgraphError(f"changing input {name!r} changed the unknowns of the compiled "
                               f"system; linearise a build whose structure does not depend on it")
        cols.append(s.residual(op.t, op.y, op.yp))
    return (cols[0] - cols[1]) / (2.0 * h)


def _as_system(target):
    return target if isinstance(target, System) else target.compile()


def linearize_circuit(build: Callable[[dict], object], u0: Mapping[str, float],
                      outputs: Sequence[str], *, y0=None, eps_rel: float = 1e-5,
                      du: Mapping[str, float] | None = None, tol: float = 1e-9,
                      op: OperatingPoint | None = None) -> LinearModel:
    """Compile ``build(u0)``, find its steady state (from ``y0``) and linearise it.

    ``build`` maps a dict of input values to a Circuit (or System); the inputs of the model are
    the keys of ``u0``, in order.
    """
    system = _as_system(build(dict(u0)))
    if op is None:
        op = steady_state(system, y0=y0, tol=tol)
    du = dict(du or {})
    cols = {nm: input_sensitivity(build, u0, nm, op, eps_rel=eps_rel, du=du.get(nm))
            for nm in u0}
    return linearize(system, op, cols, outputs)
