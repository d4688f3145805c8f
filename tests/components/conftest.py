"""Shared fixtures of the component tests: DAE point checks, a solver bench, force laws."""

from __future__ import annotations

import numpy as np
import pytest


class DaeChecks:
    """Build (y, yp) from values by dotted name and check a compiled system there."""

    FD_STEP = 1e-6  # relative central-difference step

    @staticmethod
    def point(system, values=None, ders=None):
        """``(y, yp)``: the system's start values with ``values`` / ``ders`` set by name."""
        y = np.array(system.y0, dtype=float)
        yp = np.zeros(system.n)
        for target, given in ((y, values or {}), (yp, ders or {})):
            for name, value in given.items():
                coef, idx, off = system.resolve(name)
                if idx is None:  # fixed by the circuit: the given value must agree
                    assert target is yp or np.isclose(off, value, rtol=1e-12, atol=1e-15), \
                        f"{name} is fixed to {off!r} by the circuit, not {value!r}"
                    continue
                target[idx] = (value - (off if target is y else 0.0)) / coef
        return y, yp

    def residual(self, system, t=0.0, values=None, ders=None):
        """Residual vector at the point given by name."""
        y, yp = self.point(system, values, ders)
        return system.residual(t, y, yp)

    def check_jacobian(self, system, t=0.0, values=None, ders=None, c=37.0, rtol=1e-6,
                       h_abs=None):
        """Assert the compiled dF/dy + c dF/dy' equals central finite differences.

        The step is ``h_abs`` or ``FD_STEP`` relative to each variable's size; take ``h_abs``
        well below the width of any smoothing in the equations.
        """
        y, yp = self.point(system, values, ders)
        J = system.jacobian_dense(t, y, yp, c)
        fd = np.zeros_like(J)
        for j in range(system.n):
            h = h_abs or self.FD_STEP * max(abs(y[j]), system.nominal[j])
            e = np.zeros(system.n)
            e[j] = h
            fd[:, j] = (system.residual(t, y + e, yp) - system.residual(t, y - e, yp)) / (2 * h)
            fd[:, j] += c * (system.residual(t, y, yp + e)
                             - system.residual(t, y, yp - e)) / (2 * h)
        tol = rtol * (np.abs(J) + np.abs(J).max(axis=1, keepdims=True)) + 1e-9
        np.testing.assert_array_less(np.abs(J - fd), tol,
                                     err_msg=f"Jacobian of {system.name} differs from finite "
                                             f"differences:\n{J}\nvs\n{fd}")


    @staticmethod
    def row(system, label_start):
        """Index of the residual row whose label starts with ``label_start``."""
        rows = [i for i, lab in enumerate(system.equations) if lab.startswith(label_start)]
        assert len(rows) == 1, f"rows starting with {label_start!r}: {system.equations}"
        return rows[0]


@pytest.fixture
def dae():
    return DaeChecks()


@pytest.fixture
def sim():
    """``pvgraph.simulate.simulate``, or a skip while the solver is not available."""
    try:
        from pvgraph.solver import solve_dae  # noqa: F401
    except ImportError as exc:
        pytest.skip(f"the solver is not available yet: {exc}")
    from pvgraph.simulate import simulate
    return simulate


def force_law(make, x, v=0.0):
    """The force ``flange.f`` a one-flange component needs at position ``x``, velocity ``v``.

    Evaluates the component's own residual on a force bench compiled without alias elimination:
    with ``flange.f = 0`` its equation reads ``-F(x, v)``.
    """
    from pvgraph.testing import Force, bench_circuit
    system = bench_circuit(make(), flange=Force(0.0)).compile(eliminate_aliases=False)
    y, yp = DaeChecks.point(system, {"dut.flange.x": x, "dut.flange.f": 0.0},
                            {"dut.flange.x": v})
    return -system.residual(0.0, y, yp)[DaeChecks.row(system, "dut equation 1")]


@pytest.fixture
def law():
    return force_law
