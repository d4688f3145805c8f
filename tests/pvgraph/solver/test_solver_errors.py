"""Failures raise SolverError / InitializationError naming the time and the variables."""

import numpy as np
import pytest

from pvgraph.errors import InitializationError, SolverError
from pvgraph.solver import solve_dae


def test_nan_residual_names_time_and_variable():
    def fun(t, y, yp):
        # the model is undefined after t = 1 (a square root of a negative number)
        return np.array([yp[0] + y[0], y[1] - np.sqrt(1.0 - t)])

    with pytest.raises(SolverError) as info:
        solve_dae(fun, (0.0, 2.0), [1.0, 1.0], [-1.0, 0.0], algebraic=[1],
                  var_names=["piston.x", "valve.q"])
    err = info.value
    assert err.t == pytest.approx(1.0, abs=1e-3)
    assert "t = 1" in str(err) or "t = 0.99" in str(err)
    assert "valve.q" in str(err)
    assert err.culprits == ["valve.q"]
    assert err.h is not None and err.h < 1e-3


def test_singular_problem_names_the_undetermined_variable():
    def fun(t, y, yp):
        # a duplicated equation: nothing determines c separately from b
        return np.array([yp[0] + y[0], y[1] - y[2], y[1] - y[2]])

    with pytest.raises(SolverError) as info:
        solve_dae(fun, (0.0, 1.0), [1.0, 1.0, 1.0], [-1.0, 0.0, 0.0], calc_initial=None,
                  var_names=["a", "b", "c"])
    err = info.value
    assert "t = 0" in str(err)
    assert "singular" in str(err)
    assert err.culprits == ["c"]


def test_max_steps_is_reported():
    with pytest.raises(SolverError, match="max_steps"):
        solve_dae(lambda t, y, yp: yp + y, (0.0, 100.0), [1.0], [-1.0], max_steps=5)


def test_nonfinite_initial_residual_is_an_initialization_error():
    with pytest.raises(InitializationError, match="equation 0"):
        solve_dae(lambda t, y, yp: yp + np.log(y - 1.0), (0.0, 1.0), [0.5], [0.0],
                  calc_initial=None)


def test_bad_arguments():
    fun = lambda t, y, yp: yp + y       # noqa: E731
    with pytest.raises(ValueError):
        solve_dae(fun, (1.0, 0.0), [1.0], [-1.0])
    with pytest.raises(ValueError):
        solve_dae(fun, (0.0, 1.0), [1.0], [-1.0, 0.0])
    with pytest.raises(ValueError):
        solve_dae(fun, (0.0, 1.0), [1.0], [-1.0], atol=0.0)
    with pytest.raises(ValueError):
        solve_dae(fun, (0.0, 1.0), [1.0], [-1.0], calc_initial="yp")


def test_an_atol_of_the_wrong_length_is_named():
    with pytest.raises(ValueError, match=r"atol must be a number or have one entry per variable "
                                         r"\(1\), got shape \(2,\)"):
        solve_dae(lambda t, y, yp: np.array([yp[0] + y[0]]), (0.0, 1.0), [1.0], [-1.0],
                  atol=[1e-8, 1e-8])
    sol = solve_dae(lambda t, y, yp: np.array([yp[0] + y[0]]), (0.0, 1.0), [1.0], [-1.0],
                    atol=[1e-10], rtol=1e-8)
    assert sol.y[-1, 0] == pytest.approx(np.exp(-1.0), rel=1e-6)
