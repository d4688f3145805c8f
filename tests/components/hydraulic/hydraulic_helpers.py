"""Shared helpers of the hydraulic component tests: operating points, Jacobian check, drives."""

from __future__ import annotations

import numpy as np
import pytest

from pvgraph.component import Component, Mechanical, Params, Variable, der
from pvgraph.testing import bench_circuit


def value(system, y, name):
    """A variable's value at ``y``, also for names the compiler eliminated."""
    coef, idx, off = system.resolve(name)
    return off if idx is None else coef * y[idx] + off


def vector(system, values: dict):
    """``y`` from values given by name for every unknown of ``system``."""
    missing = [n for n in system.names if n not in values]
    assert not missing, f"no value for the unknowns {missing}"
    return np.array([values[n] for n in system.names], dtype=float)


def fixed_observed(component, names, **boundaries):
    """Observed outputs of ``component`` on a bench where every port is fixed (no unknowns)."""
    system = bench_circuit(component, **boundaries).compile()
    y = np.zeros((1, system.n)) + system.y0
    out = system.evaluate_observed(np.zeros(1), y, np.zeros_like(y),
                                   np.asarray([system.mode_start], dtype=float))
    return [float(out[f"dut.{n}"][0]) for n in names]


def jacobian_fd_error(system, t=0.05, c=30.0, seed=0):
    """Largest relative difference of dF/dy + c dF/dy' from central finite differences."""
    rng = np.random.default_rng(seed)
    y = system.y0 + 0.1 * system.nominal * rng.uniform(0.5, 1.0, system.n)
    yp = system.nominal * rng.normal(size=system.n)
    J = system.jacobian_dense(t, y, yp, c)
    J_fd = np.zeros_like(J)
    for j in range(system.n):
        h = 1e-6 * max(abs(y[j]), system.nominal[j])
        e = np.zeros(system.n)
        e[j] = h
        J_fd[:, j] = (system.residual(t, y + e, yp + c * e)
                      - system.residual(t, y - e, yp - c * e)) / (2 * h)
    scale = np.abs(J_fd).max(axis=1, keepdims=True) + 1e-300
    return float(np.max(np.abs(J - J_fd) / scale))


class VelocityDriveParams(Params):
    x0: float = 0.0
    v: float = 0.0


class VelocityDrive(Component):
    """Test drive: moves its flange at constant velocity from x0 (a position ramp).

    A ``Position(lambda t: ...)`` bench source cannot drive a component that uses der(x): the
    compiler rejects the algebraic x = x(t) as index two. Integrating the velocity keeps x a
    state.
    """

    Params = VelocityDriveParams
    ports = {"flange": Mechanical("driven flange")}

    def starts(self, p):
        return {"flange.x": p.x0}

    def equations(self, v, p):
        return [der(v.flange.x) - p.v]


class MassDamperParams(Params):
    m: float
    b: float
    x0: float = 0.0


class MassDamper(Component):
    """Test load: ``m der(v) = flange.f - b v``, ``der(x) = v``."""

    Params = MassDamperParams
    ports = {"flange": Mechanical("the mass")}
    variables = {"v": Variable("m/s", 0.0, 0.01, "velocity")}

    def starts(self, p):
        return {"flange.x": p.x0}

    def equations(self, v, p):
        return [der(v.flange.x) - v.v, p.m * der(v.v) - (v.flange.f - p.b * v.v)]


def _solver_available():
    try:
        from pvgraph.solver import solve_dae  # noqa: F401
    except ImportError:
        return False
    return True


requires_solver = pytest.mark.skipif(not _solver_available(),
                                     reason="pvgraph.solver.solve_dae is not available yet")
