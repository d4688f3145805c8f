"""Bari IVP Test Set: pvgraph's solver against SUNDIALS IDA at equal tolerances.

Both solvers get the same residual, analytic Jacobian and consistent initial values, and the
same error-test configuration (no suppressed algebraic variables, scikit-sundae's setting).
The accuracy measure is the test set's mixed significant correct digits (mescd) at t_end.
"""

import numpy as np
import pytest

from pvgraph.solver import solve_dae
from pvgraph.solver.testset import AKZO, PROBLEMS, TRANSISTOR, mescd


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
    # step growth right after a failure (IDA's rule) costs residual calls here (1.35x IDA's
    # at 1e-6) but saves half the steps at 1e-8 (benchmarks/RESULTS.md)
    assert ours.stats["nre"] <= 1.4 * ida.stats["nre"]


@pytest.mark.slow
@pytest.mark.parametrize("tol", [1e-7, 1e-8])
def test_transistor_amplifier_tight_tolerances(tol):
    compare_with_ida(TRANSISTOR, tol)


def test_akzo_with_suppressed_algebraic_variable():
    res = solve_dae(AKZO.residual, AKZO.t_span, AKZO.y0, AKZO.yp0, rtol=1e-6, atol=1e-6,
                    jac=AKZO.jac, algebraic=AKZO.algebraic, suppress_alg=True)
    assert mescd(res.y[-1], AKZO.y_ref, 1e-6, 1e-6) > 5.0


def test_akzo_with_finite_difference_jacobian():
    res = solve_dae(AKZO.residual, AKZO.t_span, AKZO.y0, AKZO.yp0, rtol=1e-6, atol=1e-6,
                    calc_initial=None)
    assert mescd(res.y[-1], AKZO.y_ref, 1e-6, 1e-6) > 5.5
    s = res.stats
    assert s["nre"] <= s["nni"] + 6 * s["nje"] + 5


# mescd at rtol 1e-6 with the test set's atol, default options and the analytic Jacobian;
# the bounds sit about half a digit below what both pvgraph and SUNDIALS IDA reach.
MESCD_AT_1E6 = {"hires": 5.0, "pollution": 5.5, "orego": 4.5, "vdpol": 4.0, "e5": 1.5,
                "rober": 6.5, "akzo": 5.5, "transistor": 5.3, "ring": 1.9}


@pytest.mark.parametrize("key", [k for k, p in PROBLEMS.items() if not p.slow])
def test_testset_problem_to_published_reference(key):
    p = PROBLEMS[key]
    tol = 1e-6
    res = solve_dae(p.residual, p.t_span, p.y0, p.yp0, rtol=tol, atol=p.atol(tol), jac=p.jac,
                    algebraic=p.algebraic, max_steps=10**6)
    assert res.t[-1] == p.t_span[1]
    assert mescd(res.y[-1], p.y_ref, p.atol(tol), tol) > MESCD_AT_1E6[key]


@pytest.mark.slow
@pytest.mark.parametrize("key", [k for k, p in PROBLEMS.items() if p.slow])
def test_long_testset_problem_to_published_reference(key):
    test_testset_problem_to_published_reference(key)


@pytest.mark.parametrize("key", ["hires", "pollution", "orego", "rober"])
def test_testset_problem_against_ida(key):
    p = PROBLEMS[key]
    sk = pytest.importorskip("sksundae")
    assert sk is not None
    from pvgraph.solver import solve_dae_sundials
    tol = 1e-6
    kw = dict(rtol=tol, atol=p.atol(tol), jac=p.jac, calc_initial=None, max_steps=10**6)
    ours = solve_dae(p.residual, p.t_span, p.y0, p.yp0, suppress_alg=False, **kw)
    ida = solve_dae_sundials(p.residual, p.t_span, p.y0, p.yp0, **kw)
    m_ours = mescd(ours.y[-1], p.y_ref, p.atol(tol), tol)
    m_ida = mescd(ida.y[-1], p.y_ref, p.atol(tol), tol)
    assert m_ours >= m_ida - 0.5
    assert ours.stats["nsteps"] <= 1.3 * ida.stats["nsteps"] + 10


def test_new_problems_start_consistent_with_exact_jacobians():
    for key in ("hires", "pollution", "orego", "vdpol", "e5", "rober", "ring"):
        p = PROBLEMS[key]
        assert np.max(np.abs(p.residual(0.0, p.y0, p.yp0))) < 1e-12
        t, c = 0.25 * p.t_span[1] * 1e-3, 7.0
        y = p.y0 + 0.01 * (1.0 + np.arange(p.y0.size) / p.y0.size) * 1e-2
        j = p.jac(t, y, p.yp0, c)
        for k in range(y.size):
            d = np.zeros_like(y)
            d[k] = 1e-7
            fd = (p.residual(t, y + d, p.yp0 + c * d) - p.residual(t, y - d, p.yp0 - c * d)) / 2e-7
            np.testing.assert_allclose(j[:, k], fd, rtol=1e-5, atol=1e-6 * np.abs(j).max(),
                                       err_msg=f"{key} column {k}")
