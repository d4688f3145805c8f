"""Robertson's reactions to t = 4e10 over a sweep of tolerances, and parity with SUNDIALS IDA.

The reference y(4e10) comes from scipy's Radau IIA at rtol 1e-12 (``ROBER_Y_4E10``, see
``testset.py``), an independent code that reproduces the test set's published y(1e11).
Errors are measured in tolerance units |y - y_ref| / (atol + rtol |y_ref|).
"""

import itertools

import numpy as np
import pytest

from pvgraph.solver import solve_dae
from pvgraph.solver.testset import ROBER, ROBER_Y_4E10, rober_jacobian, rober_residual

T_END = 4e10
RTOLS = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8]
ATOLS = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
# the loose-tolerance case that drifts to y1 = -6e5 without constraints
LOOSE = (1e-4, (1e-6, 1e-10, 1e-6))


def _atol(atol, mixed):
    """Scalar atol for all three, or the mixed (atol, 1e-4 atol, atol) that resolves y2."""
    return np.array([atol, 1e-4 * atol, atol]) if mixed else np.full(3, atol)


def _solve(rtol, atol, **kw):
    return solve_dae(rober_residual, (0.0, T_END), ROBER.y0, ROBER.yp0, rtol=rtol,
                     atol=atol, jac=rober_jacobian, algebraic=[2], max_steps=10**5, **kw)


def _tolerance_units(y, rtol, atol):
    return np.max(np.abs(y - ROBER_Y_4E10) / (atol + rtol * np.abs(ROBER_Y_4E10)))


def test_reference_at_4e10_follows_the_large_time_asymptote():
    # y1 = 1 / (4.8e-4 t) once y2 = 4e-6 y1 is in quasi-steady state (y1' = -3e7 y2^2);
    # the published y(1e11) obeys it to 4e-6, the 4e10 value to 3e-6
    assert ROBER.y_ref[0] * 4.8e-4 * ROBER.t_span[1] == pytest.approx(1.0, rel=1e-5)
    assert ROBER_Y_4E10[0] * 4.8e-4 * T_END == pytest.approx(1.0, rel=1e-4)
    assert ROBER_Y_4E10[1] == pytest.approx(4e-6 * ROBER_Y_4E10[0], rel=1e-4)
    assert ROBER_Y_4E10.sum() == pytest.approx(1.0, abs=1e-14)


def _ida_with_stop(rtol, atol, constraints=False):
    """SUNDIALS IDA stepped to a stop time at T_END (as pvgraph), analytic Jacobian."""
    ida = pytest.importorskip("sksundae.ida")

    def resfn(t, y, yp, res):
        res[:] = rober_residual(t, y, yp)

    def jacfn(t, y, yp, res, cj, jj):
        jj[:, :] = rober_jacobian(t, y, yp, cj)

    extra = {"constraints_idx": [0, 1, 2], "constraints_type": [1, 1, 1]} if constraints else {}
    solver = ida.IDA(resfn, jacfn=jacfn, rtol=rtol, atol=np.asarray(atol, dtype=float),
                     algebraic_idx=[2], max_num_steps=10**5, **extra)
    solver.init_step(0.0, ROBER.y0, ROBER.yp0)
    t, steps = 0.0, 0
    while t < T_END * (1.0 - 1e-14):
        out = solver.step(T_END, method="onestep", tstop=T_END)
        assert out.success
        t = float(np.ravel(out.t)[-1])
        steps += 1
    return steps, np.ravel(out.y)[-3:]


@pytest.mark.parametrize("rtol, atol", [LOOSE, (1e-6, (1e-10,) * 3)])
def test_same_steps_and_values_as_sundials_ida(rtol, atol):
    # Same Jacobian, same stop time: the loose run that drifts to y1 = -6e5 is IDA's own
    # result step for step (632 steps), not a pvgraph defect; so is the accurate one.
    steps, y_ida = _ida_with_stop(rtol, atol)
    res = _solve(rtol, np.asarray(atol))
    assert res.stats["nsteps"] == steps
    np.testing.assert_allclose(res.y[-1], y_ida, rtol=1e-5, atol=1e-20)
    if (rtol, atol) == LOOSE:
        assert res.y[-1, 0] < -1e5       # the drift documented in solve_dae(nonnegative=)


def _sweep_cases(full):
    cases = list(itertools.product(RTOLS, ATOLS, (False, True)))
    if full:
        return cases
    # the loose case and a diagonal of the grid, both atol forms
    return [(1e-4, 1e-6, True), (1e-2, 1e-5, False), (1e-3, 1e-4, False),
            (1e-5, 1e-6, False), (1e-6, 1e-8, True), (1e-8, 1e-10, True)]


def _check_nonnegative_run(rtol, atol_value, mixed):
    atol = _atol(atol_value, mixed)
    res = _solve(rtol, atol, nonnegative=True)
    assert res.t[-1] == T_END
    assert res.y.min() >= 0.0
    # mass balance, to the Newton tolerance: a step's correction is scaled by
    # 2 / (1 + cj ratio) with an old iteration matrix, so even a linear row holds only as
    # well as the iteration converged, in units of rtol |y3| + atol (worst 1.8 units)
    np.testing.assert_allclose(res.y.sum(axis=1), 1.0, rtol=0.0, atol=5.0 * (rtol + atol_value))
    # worst over the 98 runs of the full sweep: 1.7 tolerance units
    assert _tolerance_units(res.y[-1], rtol, atol) <= 2.5
    if atol_value <= 1e-9:
        # the tolerance resolves y1 ~ 5e-8: within 10 % of the reference
        assert res.y[-1, 0] / ROBER_Y_4E10[0] == pytest.approx(1.0, abs=0.1)


@pytest.mark.parametrize("rtol, atol, mixed", _sweep_cases(full=False))
def test_declared_nonnegative_stays_physical_and_within_tolerance(rtol, atol, mixed):
    _check_nonnegative_run(rtol, atol, mixed)


@pytest.mark.slow
@pytest.mark.parametrize("rtol, atol, mixed", _sweep_cases(full=True))
def test_declared_nonnegative_sweep_of_all_tolerances(rtol, atol, mixed):
    _check_nonnegative_run(rtol, atol, mixed)


@pytest.mark.slow
@pytest.mark.parametrize("rtol, atol", list(itertools.product(RTOLS, ATOLS)))
def test_default_options_with_one_atol_stay_within_tolerance(rtol, atol):
    # Without constraints, one atol for all three: negative excursions stay within atol
    # (worst -0.94 atol) and the end value within 2 tolerance units (worst 1.6). This is
    # what the method gives here (IDA's identical), not a guarantee: the mixed atol of
    # LOOSE drifts away (test above).
    a = np.full(3, atol)
    res = _solve(rtol, a)
    assert res.y.min() >= -atol
    assert _tolerance_units(res.y[-1], rtol, a) <= 2.5


def test_ode_form_to_1e11_with_differenced_jacobian_and_zero_start_rates():
    """Robertson as three ODEs, no Jacobian given, y'(0) = 0 as guess, atol 1e-14 on y2, to
    the test set's end 1e11: the consistent start differences y2' with an increment of
    sqrt(eps) * atol / (rtol * t_span) ~ 1e-24, far below the rounding of its row; the lost
    column is retried larger rather than read as a singular matrix. The end is the test set's
    published y(1e11) within one tolerance unit."""
    def residual(t, y, yp):
        y1, y2, y3 = y
        return yp - np.array([-0.04 * y1 + 1e4 * y2 * y3,
                              0.04 * y1 - 1e4 * y2 * y3 - 3e7 * y2 ** 2, 3e7 * y2 ** 2])
    atol = np.array([1e-12, 1e-14, 1e-12])
    sol = solve_dae(residual, (0.0, 1e11), [1.0, 0.0, 0.0], [0.0, 0.0, 0.0], rtol=1e-6,
                    atol=atol)
    err = np.abs(sol.y[-1] - ROBER.y_ref) / (atol + 1e-6 * np.abs(ROBER.y_ref))
    assert np.all(err < 1.0), err


def test_ida_backend_without_a_jacobian_follows_robertson_to_1e11():
    # IDA's own difference quotients perturb y2 ~ 1e-13 by ~atol = 1e-6: the column of
    # 6e7 y2 was wrong by orders of magnitude and the run ended at y1 = -4.8e7 with
    # success. The backend now differences as the built-in solver does (increments from
    # atol / rtol and the value); reference: the test set's published y(1e11)
    pytest.importorskip("sksundae")
    from pvgraph.solver import solve_dae_sundials
    ref = np.array([2.083340149701255e-8, 8.333360770334713e-14, 0.9999999791665050])
    for rtol, atol in ((1e-3, 1e-6), (1e-4, 1e-8)):
        sol = solve_dae_sundials(rober_residual, (0.0, 1e11), ROBER.y0, ROBER.yp0, rtol=rtol,
                                 atol=atol, algebraic=[2])
        assert sol.success
        units = np.abs(sol.y[-1] - ref) / (atol + rtol * np.abs(ref))
        assert np.max(units) < 10.0, (rtol, atol, sol.y[-1])
