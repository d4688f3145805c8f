"""A DAE written as a Python function, compiled like a circuit.

A residual ``F(t, y, y') = 0`` written against a math-like module (``lib.exp``, ``lib.sqrt``,
... and arithmetic, as one writes it for ``math`` or CasADi) is traced once with symbolic
unknowns and compiled by the same code generator as a circuit: exact sparse Jacobian, shared
subexpressions computed once, and optionally the C route (:mod:`pvgraph.cbackend`) with the
solver's step in C (:mod:`pvgraph.solver.cstep`)::

    def robertson(t, y, yp, lib):
        y1, y2, y3 = y
        return [yp[0] + 0.04 * y1 - 1e4 * y2 * y3,
                yp[1] - 0.04 * y1 + 1e4 * y2 * y3 + 3e7 * y2 ** 2,
                y1 + y2 + y3 - 1.0]

    system = compile_dae(robertson, [1.0, 0.0, 0.0], names=["y1", "y2", "y3"], backend="c")
    sol = solve_dae(system.residual, (0.0, 40.0), system.y0, system.yp0,
                    jac=system.solver_jacobian())

The function must not branch on the unknowns with Python ``if`` (use ``lib.where(cond, a,
b)``); it is traced once, not called at every step.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from . import expr as E
from .errors import PvgraphError, StructureError

__all__ = ["compile_dae", "LIB"]

#: the functions a traced residual can call, as ``lib.<name>``
LIB = SimpleNamespace(sqrt=E.sqrt, exp=E.exp, log=E.log, tanh=E.tanh, sin=E.sin, cos=E.cos,
                      atan=E.atan, fabs=E.fabs, abs=E.fabs, where=E.where, fmin=E.minimum,
                      fmax=E.maximum, pi=math.pi, e=math.e)


class _Lib:
    """``LIB`` with an error that names what a residual asked for and does not exist."""

    def __getattr__(self, name):
        try:
            return getattr(LIB, name)
        except AttributeError:
            raise PvgraphError(
                f"compile_dae: the residual calls lib.{name}, which a traced residual cannot "
                f"use; available: {', '.join(sorted(vars(LIB)))}") from None


def compile_dae(residual, y0, yp0=None, *, names=None, name: str = "dae",
                backend: str = "python", nominal=None):
    """Trace ``residual(t, y, yp, lib)`` and compile it to a :class:`~pvgraph.system.System`.

    Parameters
    ----------
    residual : callable
        ``residual(t, y, yp, lib) -> sequence of n expressions``; ``y`` and ``yp`` are
        sequences of n symbols, ``t`` the time, ``lib`` a namespace of functions (:data:`LIB`).
    y0, yp0 : array_like
        Start values (``yp0`` default zeros); ``system.y0`` and ``system.yp0`` hold them.
    names : list of str, optional
        Names of the unknowns (default ``y0``, ``y1``, ...), used in results and messages.
    backend : {"python", "c", "auto"}
        How the residual, Jacobian and events are evaluated (see ``System.use_backend``).
    nominal : array_like, optional
        Typical magnitudes (default ``max(|y0|, 1)``).

    Raises
    ------
    PvgraphError
        Wrong lengths, an unknown ``lib`` function, a Python branch on an unknown, or a
        residual that is not a structurally regular index-one system (named rows and
        unknowns).
    """
    from .compiler import VarInfo, _Equation
    from .system import build_system

    y0 = np.asarray(y0, dtype=float).ravel()
    n = y0.size
    if n == 0:
        raise PvgraphError("compile_dae: y0 is empty")
    yp0 = np.zeros(n) if yp0 is None else np.asarray(yp0, dtype=float).ravel()
    if yp0.size != n:
        raise PvgraphError(f"compile_dae: yp0 has {yp0.size} values, y0 has {n}")
    names = [f"y{i}" for i in range(n)] if names is None else [str(s) for s in names]
    if len(names) != n or len(set(names)) != n:
        raise PvgraphError(f"compile_dae: names must be {n} distinct names, got {names!r}")
    nominal = (np.maximum(np.abs(y0), 1.0) if nominal is None
               else np.asarray(nominal, dtype=float).ravel())
    y = [E.Expr("sym", (), nm) for nm in names]
    yp = [E.Expr("der", (), nm) for nm in names]
    try:
        rows = list(residual(E.Expr("time"), y, yp, _Lib()))
    except TypeError as exc:
        raise PvgraphError(f"compile_dae: tracing {getattr(residual, '__name__', residual)} "
                           f"failed ({exc}); it must take (t, y, yp, lib) and use lib's "
                           f"functions and arithmetic only") from None
    if len(rows) != n:
        raise PvgraphError(f"compile_dae: the residual returned {len(rows)} rows for {n} "
                           f"unknowns")
    infos = {nm: VarInfo(nm, "", float(y0[i]), float(nominal[i]), "", name, 2)
             for i, nm in enumerate(names)}
    equations = [_Equation(E.as_expr(r), name, f"{name} row {i}") for i, r in enumerate(rows)]
    try:
        system = build_system(name, equations, infos, {}, {}, [], [], [], array_rows=False)
    except StructureError as exc:
        text = str(exc)
        if ". Typical causes:" not in text:
            raise
        raise StructureError(
            text.split(". Typical causes:")[0] + ". compile_dae takes DAEs of "
            "index one (each algebraic equation solvable for the algebraic unknowns); index "
            "reduction is done for circuits only. Differentiate the constraint until it "
            "determines the unknowns left (a pendulum's x^2 + y^2 = L^2 twice: the "
            "acceleration-level form), or build the model as a circuit.") from None
    system.yp0 = yp0.copy()
    return system.use_backend(backend)
