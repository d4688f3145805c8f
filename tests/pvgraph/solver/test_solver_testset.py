"""Bari IVP Test Set: pvgraph's solver against SUNDIALS IDA at equal tolerances.

Both solvers get the same residual, analytic Jacobian and consistent initial values, and the
same error-test configuration (no suppressed algebraic variables, scikit-sundae's setting).
The accuracy measure is the test set's mixed significant correct digits (mescd) at t_end.
"""

import numpy as np
import pytest

from pvgraph.solver import solve_dae
from pvgraph.solver.testset import AKZO, TRANSISTOR, mescd


def solve(solver, problem, tol, **kw):
    return solver(problem.residual, problem.t_span, problem.y0, problem.yp0, rtol=tol,
                  atol=tol, jac=problem.jac, calc_initial=None, max_steps=10**6, **kw)


def compare_with_ida(problem, tol):
    sk = pytest.importorskip("sksundae")
    assert sk is not None
    from pvgraph.solver import solve_dae_sundials

    ours = solve(solve_dae, problem, tol)
    ida = solve(solve_dae_sundials, problem, tol)
    m_ours = mescd(ours.y[-1], problem.y_ref, tol, tol)
    m_ida = mescd(ida.y[-1], problem.y_ref, tol, tol)
    assert ours.t[-1] == problem.t_span[1]
    assert m_ours >= m_ida - 0.5, (m_ours, m_ida)
    return ours, ida, m_ours


def test_mescd_definition():
    ref = np.array([1.0, 2.0, 3.0])
    assert mescd(ref, ref, 1e-6, 1e-6) == np.inf
    # |err| / (atol/rtol + |ref|) = 0.1 / (1 + 3) on the worst component
    assert mescd([1.0, 2.0, 3.1], ref, 1e-3, 1e-3) == pytest.approx(-np.log10(0.1 / 4.0))


def test_reference_problems_start_consistent():
    for p in (AKZO, TRANSISTOR):
        r = p.residual(0.0, p.y0, p.yp0)
        assert np.max(np.abs(r)) < 1e-9
        # the analytic Jacobian matches finite differences
        c = 7.0
        j = p.jac(0.0, p.y0, p.yp0, c)
        for k in range(p.y0.size):
            dy = np.zeros_like(p.y0)
            dy[k] = 1e-6 * max(1e-3, abs(p.y0[k]))
            fd = (p.residual(0.0, p.y0 + dy, p.yp0 + c * dy)
                  - p.residual(0.0, p.y0 - dy, p.yp0 - c * dy)) / (2.0 * dy[k])
            np.testing.assert_allclose(j[:, k], fd, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("tol", [1e-4, 1e-6, 1e-8])
def test_akzo_nobel_against_ida(tol):
    ours, ida, m = compare_with_ida(AKZO, tol)
    assert m > -np.log10(tol) - 1.0
    assert ours.stats["nsteps"] <= 1.2 * ida.stats["nsteps"] + 5


@pytest.mark.parametrize("tol", [1e-4, 1e-6])
def test_transistor_amplifier_against_ida(tol):
    ours, ida, m = compare_with_ida(TRANSISTOR, tol)
    assert m > -np.log10(tol) - 1.0
    assert ours.stats["nre"] <= 1.3 * ida.stats["nre"]


@pytest.mark.slow
@pytest.mark.parametrize("tol", [1e-7, 1e-8])
def test_transistor_amplifier_tight_tolerances(tol):
    compare_with_ida(TRANSISTOR, tol)


def test_akzo_with_suppressed_algebraic_variable():
    res = solve_dae(AKZO.residual, AKZO.t_span, AKZO.y0, AKZO.yp0, rtol=1e-6, atol=1e-6,
                    jac=AKZO.jac, algebraic=AKZO.algebraic)
    assert mescd(res.y[-1], AKZO.y_ref, 1e-6, 1e-6) > 5.0


def test_akzo_with_finite_difference_jacobian():
    res = solve_dae(AKZO.residual, AKZO.t_span, AKZO.y0, AKZO.yp0, rtol=1e-6, atol=1e-6,
                    calc_initial=None)
    assert mescd(res.y[-1], AKZO.y_ref, 1e-6, 1e-6) > 5.5
    s = res.stats
    assert s["nre"] <= s["nni"] + 6 * s["nje"] + 5
