"""calibrate(): recovers known parameters from synthetic noisy data within its intervals,
its 95 % intervals cover the truth about 95 % of the time, and it says which parameters the
data cannot determine."""

import math

import numpy as np
import pytest

from pvgraph.components import LaminarOrifice, Orifice, PressureSource, Tank, VolumeNode
from pvgraph import Circuit
from pvgraph.analysis import FitParameter, calibrate, steady_state
from pvgraph.analysis.calibrate import CalibrationError
from pvgraph.errors import ParameterError
from pvgraph.units import bar, lpm_per_bar, mm2, to_bar, to_lpm

T = np.linspace(0.0, 2.0, 25)


def _decay(theta):
    return theta["a"] * np.exp(-theta["b"] * T)


def test_exponential_recovered_within_interval():
    rng = np.random.default_rng(1)
    y = _decay({"a": 3.0, "b": 1.7}) + rng.normal(0.0, 0.05, T.size)
    fit = calibrate(_decay, y, {"a": (1.0, 0.0, 10.0), "b": (1.0, 0.0, 10.0)}, sigma=0.05,
                    absolute_sigma=True)
    assert fit.success and not fit.unidentifiable
    for name, true in (("a", 3.0), ("b", 1.7)):
        lo, hi = fit.interval(name)
        assert lo < true < hi
        assert hi - lo < 0.1 * true                     # informative, not vacuous
    # the fit explains the data to the noise level: chi-square per datum about 1
    assert fit.rms_weighted == pytest.approx(1.0, abs=0.35)
    assert fit.cost < 0.01 * fit.cost_initial


def test_interval_coverage_is_nominal():
    """Over 300 noisy replicates the 95 % intervals contain the true value 91-98.5 % of the time
    (binomial standard deviation 1.3 %); with sigma as relative weights (the default)."""
    rng = np.random.default_rng(7)
    hits = np.zeros(2)
    reps = 300
    for _ in range(reps):
        y = _decay({"a": 3.0, "b": 1.7}) + rng.normal(0.0, 0.1, T.size)
        fit = calibrate(_decay, y, {"a": (2.0, 0.0, 10.0), "b": (1.0, 0.0, 10.0)})
        hits += [fit.interval("a")[0] < 3.0 < fit.interval("a")[1],
                 fit.interval("b")[0] < 1.7 < fit.interval("b")[1]]
    coverage = hits / reps
    assert np.all(coverage > 0.91) and np.all(coverage < 0.985), coverage


def test_known_sigmas_give_normal_intervals_with_nominal_coverage():
    """With absolute_sigma the scale is known: half-widths are 1.96 standard errors (not
    Student's t of m - n degrees of freedom), and over 400 replicates of 6 points (t_4 would
    give 2.78 and about 99.5 %) the 95 % intervals cover 93-97 % (binomial sd 1.1 %)."""
    t6 = np.linspace(0.0, 2.0, 6)

    def decay6(theta):
        return theta["a"] * np.exp(-theta["b"] * t6)

    rng = np.random.default_rng(11)
    hits, reps = np.zeros(2), 400
    for _ in range(reps):
        y = decay6({"a": 3.0, "b": 1.7}) + rng.normal(0.0, 0.05, t6.size)
        fit = calibrate(decay6, y, {"a": (2.0, 0.0, 10.0), "b": (1.0, 0.0, 10.0)}, sigma=0.05,
                        absolute_sigma=True)
        lo, hi = fit.interval("a")
        assert (hi - lo) / 2.0 == pytest.approx(1.959964 * fit.std_errors[0], rel=1e-6)
        hits += [lo < 3.0 < hi, fit.interval("b")[0] < 1.7 < fit.interval("b")[1]]
    coverage = hits / reps
    assert np.all(coverage > 0.93) and np.all(coverage < 0.97), coverage


# -- a hydraulic circuit: supply -> orifice A -> node -> laminar K -> tank ----------------------
SUPPLIES = [bar(v) for v in (20, 40, 60, 90, 120, 160, 200, 250)]
A_TRUE, K_TRUE = mm2(3.0), lpm_per_bar(0.25)


def _node_values(ps, A, K):
    c = Circuit("bench")
    src = c.add("src", PressureSource(p0=ps))
    orf = c.add("orifice", Orifice(A=A, rho=870.0))
    node = c.add("node", VolumeNode(V=1e-4))
    lam = c.add("load", LaminarOrifice(K=K))
    tank = c.add("tank", Tank())
    c.connect(src.port, orf.a)
    c.connect(orf.b, node.port, lam.a)
    c.connect(lam.b, tank.port)
    op = steady_state(c.compile(), tol=1e-12)
    return op["node.port.p"], op["load.a.q"]


def _predict_p_and_q(theta):
    out = [_node_values(ps, theta["A"], theta["K"]) for ps in SUPPLIES]
    return np.array([to_bar(p) for p, _ in out] + [to_lpm(q) for _, q in out])


def _predict_p_only(theta):
    return np.array([to_bar(_node_values(ps, theta["A"], theta["K"])[0]) for ps in SUPPLIES])


PARAMS = [FitParameter("A", mm2(2.0), mm2(0.1), mm2(20.0), unit="mm^2", display=lambda v: v * 1e6),
          FitParameter("K", lpm_per_bar(0.4), lpm_per_bar(0.01), lpm_per_bar(5.0))]


def test_circuit_parameters_recovered_from_noisy_pressures_and_flows():
    rng = np.random.default_rng(3)
    clean = _predict_p_and_q({"A": A_TRUE, "K": K_TRUE})
    sigma = np.r_[np.full(len(SUPPLIES), 0.5), np.full(len(SUPPLIES), 0.2)]   # bar, L/min
    y = clean + rng.normal(0.0, sigma)
    fit = calibrate(_predict_p_and_q, y, PARAMS, sigma=sigma, absolute_sigma=True)
    assert fit.success and not fit.unidentifiable
    for name, true in (("A", A_TRUE), ("K", K_TRUE)):
        lo, hi = fit.interval(name)
        assert lo < true < hi, (name, lo, true, hi)
        assert (hi - lo) / true < 0.2
    assert abs(fit.correlation[0, 1]) < 1.0
    row = fit.table().splitlines()[2]                      # display units in the table
    assert "mm^2" in row and f"{fit['A'] * 1e6:.4g}" in row


def test_pressure_alone_cannot_separate_orifice_from_load():
    """At steady state K p = Cd A sqrt(2 (ps - p) / rho): p depends on A / K only, so the pressure
    data determine the ratio, not A and K. calibrate() must say so rather than print intervals."""
    y = _predict_p_only({"A": A_TRUE, "K": K_TRUE})
    fit = calibrate(_predict_p_only, y, PARAMS)
    assert set(fit.unidentifiable) == {"A", "K"}
    assert np.all(np.isinf(fit.ci_high - fit.ci_low))
    assert "not identifiable" in fit.table()
    # the ratio itself is recovered exactly (noise-free data)
    assert fit["A"] / fit["K"] == pytest.approx(A_TRUE / K_TRUE, rel=1e-5)


def test_a_parameter_the_data_do_not_see_is_flagged():
    y = _decay({"a": 3.0, "b": 1.7})
    fit = calibrate(lambda th: _decay(th) + 0.0 * th["c"], y,
                    {"a": (2.0, 0.0, 10.0), "b": (1.0, 0.0, 10.0), "c": (5.0, 0.0, 10.0)})
    assert fit.unidentifiable == ["c"]
    assert fit["a"] == pytest.approx(3.0, rel=1e-6) and math.isfinite(fit.std_errors[0])


def test_failing_model_steps_are_survived():
    """A prediction that raises (here: an impossible area) is a bad fit, not a crash."""
    y = _decay({"a": 3.0, "b": 1.7})

    def fragile(th):
        if th["b"] > 2.5:
            raise ParameterError("b beyond the model's range")
        return _decay(th)

    fit = calibrate(fragile, y, {"a": (1.0, 0.0, 10.0), "b": (0.5, 0.0, 10.0)})
    assert fit["b"] == pytest.approx(1.7, rel=1e-6)


@pytest.mark.parametrize("kwargs, match", [
    (dict(parameters={}), "no parameters"),
    (dict(parameters={"a": (20.0, 0.0, 10.0)}), "outside its bounds"),
    (dict(parameters={"a": (1.0, 5.0, 2.0)}), "not below"),
    (dict(parameters={"a": 1.0}, sigma=0.0), "sigma must be positive"),
    (dict(parameters={"a": 1.0}, measured=[1.0, np.nan]), "not finite"),
    (dict(parameters={"a": 1.0, "b": 1.0, "c": 1.0}, measured=[1.0, 2.0]), "cannot determine"),
])
def test_bad_setup_is_named(kwargs, match):
    args = dict(predict=lambda th: np.ones(2) * th.get("a", 1.0), measured=[1.0, 2.0])
    args.update(kwargs)
    with pytest.raises(CalibrationError, match=match):
        calibrate(**args)


def test_model_failing_at_start_is_reported():
    def broken(th):
        raise ParameterError("A: must be positive")
    with pytest.raises(CalibrationError, match="initial parameters: A: must be positive"):
        calibrate(broken, [1.0, 2.0], {"a": 1.0})


def test_quantities_in_a_parameter_mapping_are_si_inside_and_shown_in_their_unit():
    """``{"A": ("2 mm^2", "0.5 mm^2", 8e-6)}``: the model sees SI (a plain bound is SI), the
    table shows mm^2; a bound of another dimension is refused by name."""
    x = np.linspace(0.0, 1.0, 8)
    seen = []

    def predict(theta):
        seen.append(theta["A"])
        return theta["A"] * 1e6 * x + 1.0

    fit = calibrate(predict, 2.5 * x + 1.0, {"A": ("2 mm^2", "0.5 mm^2", 8e-6)})
    assert seen[0] == pytest.approx(2e-6, rel=1e-12)
    assert fit["A"] == pytest.approx(2.5e-6, rel=1e-6)
    row = fit.table().splitlines()[2].split()
    assert row[:4] == ["A", "mm^2", "2", "2.5"]
    with pytest.raises(CalibrationError, match="A lower bound = '1 bar' is a pressure"):
        calibrate(predict, x, {"A": ("2 mm^2", "1 bar", 8e-6)})
    with pytest.raises(CalibrationError, match=r"initial value or \(initial, lower, upper\)"):
        calibrate(predict, x, {"A": (1.0, 2.0)})


def test_system_checks_the_names_and_dimensions_of_the_parameters():
    """With system=, "2 mm" for an orifice's area is refused by dimension before the fit (it
    started at 2000 mm^2 and ended on its bound); a misspelt name is told with close matches;
    without it a failure at the start says how the quantity was read."""
    c = Circuit("orifice on a pressure source")
    src, o, t = c.add("src", PressureSource(p0=bar(50))), c.add("o", Orifice(A=mm2(2))), \
        c.add("t", Tank())
    c.connect(src.port, o.a)
    c.connect(o.b, t.port)
    s = c.compile()
    dps = [bar(10), bar(30), bar(50)]

    def predict(theta):
        return [steady_state(s, params={**theta, "src.p0": dp})["o.q"] for dp in dps]
    measured = predict({"o.A": mm2(2.2)})
    with pytest.raises(CalibrationError, match=r"'o.A': its values are given in 'mm' \(a "
                                               r"length\), but o.A is an area \[m\^2\]"):
        calibrate(predict, measured, {"o.A": ("2 mm", "0.5 mm", "8 mm")}, system=s)
    with pytest.raises(CalibrationError, match=r"'o.AA' is not a runtime parameter .* did you "
                                               r"mean 'o.A'"):
        calibrate(predict, measured, {"o.AA": 2e-6}, system=c)
    with pytest.raises(CalibrationError, match=r"converted to SI by their own unit: o.A = "
                                               r"200000 from 'bar'; calibrate\(\.\.\., "
                                               r"system=\.\.\.\) checks"):
        calibrate(predict, measured, {"o.A": ("2 bar", "1 bar", "3 bar")})
    fit = calibrate(predict, measured, {"o.A": ("2 mm^2", "0.5 mm^2", "8 mm^2")}, system=s)
    assert fit["o.A"] == pytest.approx(mm2(2.2), rel=1e-5)     # xtol 1e-6 of the search


@pytest.mark.parametrize("kwargs, match", [
    ({"sigma": [1.0, 2.0]}, "sigma has 2 values for 8 measurements"),
    ({"cov_step": 0.0}, r"cov_step must lie in \(0, 1\)"),
    ({"diff_step": -1e-3}, r"diff_step must lie in \(0, 1\)"),
    ({"max_nfev": 0}, "max_nfev must be a positive integer"),
    ({"sigma": [[1.0] * 8]}, r"one per measurement: shape \(8,\), got \(1, 8\)"),
    ({"sigma": "x"}, "sigma must be numbers, got 'x'"),
    ({"confidence": "0.9"}, r"confidence must lie in \(0, 1\), got '0.9'"),
    ({"labels": "abcdefgh"}, "1 labels for 8 measurements"),
    ({"parameters": ["a"]}, "parameters: give FitParameter objects or a mapping"),
    ({"measured": "abc"}, "measured must be numbers, got 'abc'"),
    ({"predict": lambda t: None}, "predict returned None; it must return 8 predictions"),
])
def test_bad_numerical_options_are_named_before_the_fit(kwargs, match):
    x = np.linspace(0.0, 1.0, 8)
    args = dict(predict=lambda t: t["a"] * x, measured=2.0 * x, parameters={"a": 1.0})
    args.update(kwargs)
    with pytest.raises(CalibrationError, match=match):
        calibrate(**args)


def test_fit_parameters_and_result_lookups_of_the_wrong_kind():
    """FitParameter("a", "1") names the parameter; the result's interval and table refuse
    unknown names and a non-mapping reference (AttributeError / silently ignored before),
    while a reference holding more names than were fitted still works."""
    with pytest.raises(CalibrationError, match="a: initial value '1' must be a number"):
        FitParameter("a", "1")
    x = np.linspace(0.0, 1.0, 8)
    fit = calibrate(lambda t: t["a"] * x, 2.0 * x, {"a": 1.0})
    assert fit["a"] == pytest.approx(2.0, rel=1e-6)
    with pytest.raises(KeyError, match=r"no fitted parameter 'b'; fitted: \['a'\]"):
        fit.interval("b")
    with pytest.raises(CalibrationError, match="reference must be a mapping"):
        fit.table("a")
    with pytest.raises(KeyError, match="the reference names no fitted parameter"):
        fit.table({"b": 1.0})
    with pytest.raises(KeyError, match=r"\('aa' \(did you mean 'a'\?\)"):
        fit.table({"aa": 1.0, "c": 2.0})
    row = fit.table({"a": 2.0, "c": 3.0}).splitlines()[2].split()
    assert row[0] == "a" and float(row[-1]) == 2.0


def test_an_offset_started_at_zero_is_identifiable_with_the_linear_theory_interval():
    """y = a x + b with b (an offset) started at 0: both are identifiable, and the standard
    errors are linear regression's, sigma^2 (X^T X)^-1, whatever the start (b's scale is then
    1 SI unit, whose Jacobian column is tiny next to a's)."""
    x = np.linspace(0.0, 10.0, 21)
    rng = np.random.default_rng(3)
    y = 3.0 * x + 1e4 + rng.normal(scale=50.0, size=x.size)
    X = np.column_stack([x, np.ones_like(x)])
    theory = 50.0 * np.sqrt(np.diag(np.linalg.inv(X.T @ X)))
    for b0 in (0.0, 5e3):
        res = calibrate(lambda th: th["a"] * x + th["b"], y,
                        [FitParameter("a", 1.0), FitParameter("b", b0)],
                        sigma=50.0, absolute_sigma=True)
        assert res.unidentifiable == []
        np.testing.assert_allclose(res.std_errors, theory, rtol=1e-4)


def test_as_many_data_as_parameters_gives_no_interval_and_says_why():
    x = np.array([1.0, 2.0])
    res = calibrate(lambda th: th["a"] * x + th["b"], [4.0, 7.0],
                    [FitParameter("a", 1.0), FitParameter("b", 0.5)])
    assert res.estimates == pytest.approx([3.0, 1.0], rel=1e-6)
    assert res.dof == 0 and res.unidentifiable == []
    assert np.all(np.isinf(res.std_errors))
    table = res.table()
    assert "no degree of freedom" in table and "not identifiable" not in table
    assert "give sigma with absolute_sigma=True" in table
    known = calibrate(lambda th: th["a"] * x + th["b"], [4.0, 7.0],
                      [FitParameter("a", 1.0), FitParameter("b", 0.5)], sigma=0.1,
                      absolute_sigma=True)
    X = np.column_stack([x, np.ones(2)])
    np.testing.assert_allclose(known.std_errors, 0.1 * np.sqrt(np.diag(np.linalg.inv(X.T @ X))),
                               rtol=1e-4)


def test_an_estimate_on_its_bound_is_warned_of():
    x = np.linspace(0.0, 1.0, 5)
    with pytest.warns(UserWarning, match=r"a ends on its upper bound 2.0"):
        res = calibrate(lambda th: th["a"] * x, 3.0 * x,
                        [FitParameter("a", 1.0, lower=0.0, upper=2.0)])
    assert res.estimates[0] == pytest.approx(2.0, rel=1e-6)


def test_a_search_stopped_before_the_optimum_says_so():
    """y = 2 exp(-3 x) from (1, 0.5) with max_nfev=3: the search stops far off (a = 1.31,
    b = -1.60, intervals excluding the truth); a warning and the table say it did not
    converge, where both read like a finished fit."""
    x = np.linspace(0.0, 1.0, 20)

    def predict(theta):
        return theta["a"] * np.exp(theta["b"] * x)
    with pytest.warns(UserWarning, match=r"calibrate: the search stopped before converging"):
        fit = calibrate(predict, 2.0 * np.exp(-3.0 * x), {"a": 1.0, "b": 0.5}, max_nfev=3)
    assert not fit.success
    assert "NOT CONVERGED: the search stopped before the optimum" in fit.table()
    done = calibrate(predict, 2.0 * np.exp(-3.0 * x), {"a": 1.0, "b": 0.5})
    assert done.success and "NOT CONVERGED" not in done.table()
    assert done["a"] == pytest.approx(2.0, rel=1e-5)
