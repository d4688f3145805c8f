"""solve_dae on linear ODEs in implicit form with analytic solutions.

Errors are measured in units of the requested tolerance, err / (rtol |y| + atol), and the
cost counters are bounded.
"""

import numpy as np
import pytest

from pvgraph.solver import solve_dae

RTOLS = [1e-4, 1e-6, 1e-8]
# step budgets, about 1.4x what the solver (and SUNDIALS IDA) needs today
DECAY_STEPS = {1e-4: 100, 1e-6: 170, 1e-8: 350}
STIFF_STEPS = {1e-4: 150, 1e-6: 260, 1e-8: 570}
OSC_STEPS = {1e-4: 125, 1e-6: 270, 1e-8: 410}


def decay(t, y, yp):
    return yp + y


def tol_units(y, y_exact, rtol, atol):
    return np.max(np.abs(y - y_exact) / (rtol * np.abs(y_exact) + atol))


A_STIFF = np.array([[-500.5, 499.5], [499.5, -500.5]])      # eigenvalues -1 and -1000


def stiff(t, y, yp):
    return yp - A_STIFF @ y


def stiff_exact(t):
    t = np.asarray(t)[:, None]
    return np.exp(-t) * np.array([1.0, 1.0]) + np.exp(-1000.0 * t) * np.array([1.0, -1.0])


def oscillator(t, y, yp):
    return np.array([yp[0] - y[1], yp[1] + y[0]])


def test_scalar_decay_error_in_tolerance_units_and_costs():
    t_eval = np.linspace(0.0, 10.0, 41)
    errors = []
    for rtol in RTOLS:
        atol = rtol * 1e-2
        res = solve_dae(decay, (0.0, 10.0), [1.0], [-1.0], rtol=rtol, atol=atol, t_eval=t_eval)
        err = tol_units(res.y[:, 0], np.exp(-t_eval), rtol, atol)
        assert err < 20.0, (rtol, err)
        errors.append(np.max(np.abs(res.y[:, 0] - np.exp(-t_eval))))
        s = res.stats
        assert s["nsteps"] < DECAY_STEPS[rtol]
        assert s["nje"] < 0.35 * s["nsteps"] + 5
        assert s["nlu"] <= s["nje"] + 1
        assert s["nre"] <= 2 * s["nsteps"] + s["nje"] + 10
    assert errors[0] > errors[1] > errors[2]


def test_scalar_decay_matches_at_internal_steps():
    res = solve_dae(decay, (0.0, 5.0), [1.0], [-1.0], rtol=1e-7, atol=1e-10)
    assert res.t[0] == 0.0 and res.t[-1] == 5.0
    assert np.all(np.diff(res.t) > 0.0)
    assert tol_units(res.y[:, 0], np.exp(-res.t), 1e-7, 1e-10) < 20.0
    assert tol_units(res.yp[:, 0], -np.exp(-res.t), 1e-5, 1e-8) < 50.0


@pytest.mark.parametrize("rtol", RTOLS)
def test_stiff_2x2(rtol):
    atol = rtol * 1e-2
    t_eval = np.array([1e-3, 1e-2, 0.1, 0.5, 1.0, 2.0, 5.0])
    res = solve_dae(stiff, (0.0, 5.0), [2.0, 0.0], [-1001.0, 999.0], rtol=rtol, atol=atol,
                    t_eval=t_eval)
    assert tol_units(res.y, stiff_exact(t_eval), rtol, atol) < 30.0
    s = res.stats
    # stiffness must not dictate the step: an explicit method would need >= 5000 steps
    assert s["nsteps"] < STIFF_STEPS[rtol]
    assert s["nje"] < 0.3 * s["nsteps"] + 5
    assert s["ncfn"] <= 2


def test_stiff_error_decreases_with_tolerance():
    t_eval = np.array([0.5, 1.0, 2.0])
    errs = []
    for rtol in [1e-4, 1e-6, 1e-8]:
        res = solve_dae(stiff, (0.0, 2.0), [2.0, 0.0], [-1001.0, 999.0], rtol=rtol,
                        atol=rtol * 1e-2, t_eval=t_eval)
        errs.append(np.max(np.abs(res.y - stiff_exact(t_eval))))
    assert errs[0] > 10 * errs[1] > 100 * errs[2]


@pytest.mark.parametrize("rtol", RTOLS)
def test_harmonic_oscillator(rtol):
    atol = rtol * 1e-2
    t_eval = np.linspace(0.0, 10.0, 21)
    res = solve_dae(oscillator, (0.0, 10.0), [1.0, 0.0], [0.0, -1.0], rtol=rtol, atol=atol,
                    t_eval=t_eval)
    exact = np.column_stack([np.cos(t_eval), -np.sin(t_eval)])
    # the global error of a BDF method grows over ~1.6 periods; allow 50 tolerance units
    assert np.max(np.abs(res.y - exact)) < 50.0 * (rtol + atol)
    assert res.stats["nsteps"] < OSC_STEPS[rtol]


def test_dense_output_and_t_eval_agree():
    res = solve_dae(oscillator, (0.0, 6.0), [1.0, 0.0], [0.0, -1.0], rtol=1e-8, atol=1e-10,
                    dense_output=True)
    tq = np.linspace(0.0, 6.0, 37)
    y = res.sol(tq)
    assert y.shape == (37, 2)
    assert np.max(np.abs(y - np.column_stack([np.cos(tq), -np.sin(tq)]))) < 1e-6
    assert res.sol(1.0).shape == (2,)
    assert np.allclose(res.sol.derivative(1.0), [-np.sin(1.0), -np.cos(1.0)], atol=1e-5)


def test_max_step_and_first_step():
    res = solve_dae(decay, (0.0, 1.0), [1.0], [-1.0], max_step=0.01, first_step=1e-4)
    h = np.diff(res.t)
    assert h[0] == pytest.approx(1e-4)
    assert np.max(h) <= 0.01 * (1 + 1e-12)
    assert res.stats["nsteps"] >= 100


def test_max_order_one_needs_more_steps():
    r5 = solve_dae(decay, (0.0, 5.0), [1.0], [-1.0], rtol=1e-6)
    r1 = solve_dae(decay, (0.0, 5.0), [1.0], [-1.0], rtol=1e-6, max_order=1)
    assert r1.stats["nsteps"] > 5 * r5.stats["nsteps"]
    assert abs(r1.y[-1, 0] - np.exp(-5.0)) < 1e-3
