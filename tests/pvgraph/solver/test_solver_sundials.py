"""The SUNDIALS IDA backend: same API, same answers, clear message when missing."""

import sys

import numpy as np
import pytest

from pvgraph.solver import Event, solve_dae, solve_dae_sundials

A = np.array([[-500.5, 499.5], [499.5, -500.5]])


def stiff(t, y, yp):
    return yp - A @ y


def test_missing_scikit_sundae_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "sksundae", None)
    with pytest.raises(ImportError, match=r"pvgraph\[sundials\]"):
        solve_dae_sundials(stiff, (0.0, 1.0), [2.0, 0.0], [-1001.0, 999.0])


@pytest.mark.parametrize("rtol", [1e-5, 1e-8])
def test_backends_agree_on_a_linear_problem(rtol):
    pytest.importorskip("sksundae")
    atol = 1e-2 * rtol
    t_eval = np.array([0.01, 0.1, 1.0, 3.0])
    kw = dict(rtol=rtol, atol=atol, t_eval=t_eval)
    ours = solve_dae(stiff, (0.0, 3.0), [2.0, 0.0], [-1001.0, 999.0], **kw)
    ida = solve_dae_sundials(stiff, (0.0, 3.0), [2.0, 0.0], [-1001.0, 999.0], **kw)
    np.testing.assert_array_equal(ida.t, t_eval)
    diff = np.abs(ours.y - ida.y) / (rtol * np.abs(ida.y) + atol)
    assert diff.max() < 20.0


def test_sundials_backend_events_and_actions():
    pytest.importorskip("sksundae")

    def ball(t, y, yp):
        return np.array([yp[0] - y[1], yp[1] + 9.81])

    def bounce(t, y, yp):
        return np.array([0.0, -0.8 * y[1]]), np.array([-0.8 * y[1], -9.81])

    ground = Event(lambda t, y, yp: y[0], direction=-1, action=bounce, name="ground")
    kw = dict(events=[ground], rtol=1e-8, atol=1e-10, algebraic=None)
    ours = solve_dae(ball, (0.0, 5.0), [10.0, 0.0], [0.0, -9.81], **kw)
    ida = solve_dae_sundials(ball, (0.0, 5.0), [10.0, 0.0], [0.0, -9.81], **kw)
    np.testing.assert_allclose(ida.t_events, ours.t_events, atol=1e-6)
    assert [e.name for e in ida.events] == ["ground", "ground"]
    np.testing.assert_allclose(ida.y[-1], ours.y[-1], atol=1e-5)


def test_sundials_backend_evaluates_events_of_one_vector_function_in_one_call():
    """Forty level crossings of y' = 1, given as entries of one vector function (as a compiled
    system gives its events): IDA's root function calls it once per evaluation, not once per
    event, and every crossing is found at its closed-form time y = level."""
    pytest.importorskip("sksundae")
    levels = 0.025 * np.arange(1, 41)
    calls = {"all": 0, "one": 0}

    def g_all(t, y, yp):
        calls["all"] += 1
        return y[0] - levels

    def entry(k):
        def g(t, y, yp):
            calls["one"] += 1
            return g_all(t, y, yp)[k]
        g.vector = (g_all, k)
        return g
    events = [Event(entry(k), direction=1, name=f"level{k}") for k in range(len(levels))]
    res = solve_dae_sundials(lambda t, y, yp: yp - 1.0, (0.0, 1.5), [0.0], [1.0],
                             events=events, rtol=1e-10, atol=1e-12, algebraic=None)
    np.testing.assert_allclose(res.t_events, levels, atol=1e-8)
    assert calls["one"] == 0 and calls["all"] > 0


@pytest.mark.parametrize("kwargs, match", [
    ({"y0": [], "yp0": []}, "y0 is empty"),
    ({"t_span": (0.0, 1.0, 2.0)}, r"t_span must be two numbers"),
    ({"atol": np.inf}, r"atol must be positive and finite"),
    ({"max_steps": 0}, "max_steps must be a positive integer"),
    ({"residual": lambda t, y, yp: np.array([1.0, 2.0])}, r"residual returned shape \(2,\)"),
])
def test_sundials_backend_checks_its_arguments_as_the_built_in_one(kwargs, match):
    pytest.importorskip("sksundae")
    from pvgraph.solver import solve_dae_sundials
    args = {"residual": lambda t, y, yp: yp + y, "t_span": (0.0, 1.0), "y0": [1.0],
            "yp0": [-1.0], **kwargs}
    with pytest.raises(ValueError, match=match):
        solve_dae_sundials(args.pop("residual"), args.pop("t_span"), args.pop("y0"),
                           args.pop("yp0"), **args)


def test_sundials_backend_stops_where_ida_no_longer_advances_t():
    """A cylinder fed 0.1 L/s against its stop at rtol 1e-8: IDA's step falls below the
    rounding of t at the impact and every further step returns success at that same t. The
    backend ran on for ever there (such steps were not counted, so max_steps never came); it
    now stops after 500 of them, saying where; the built-in solver runs through the impact."""
    pytest.importorskip("sksundae")
    import warnings

    from pvgraph import Circuit
    from pvgraph.components import Cylinder, FlowSource, Mass, Tank
    from pvgraph.errors import SolverError
    from pvgraph.simulate import simulate
    c = Circuit("cyl")
    c.add("src", FlowSource(Q=1e-4))
    c.add("tank", Tank())
    c.add("cyl", Cylinder(A_A=1e-3, A_rod=5e-4, stroke=0.1, V_dead_A=1e-5, V_dead_B=1e-5,
                          beta=7e8))
    c.add("mass", Mass(m=5.0, b=5e4))
    c.connect("src.port", "cyl.A")
    c.connect("cyl.B", "tank.port")
    c.connect("cyl.flange", "mass.flange")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(SolverError, match=r"step fell below the rounding of t at t = "
                                              r"1\.0007\d*: 500 steps in a row"):
            simulate(c, 1.02, rtol=1e-8, solver="ida", max_wall_time=120)
        sol = simulate(c, 1.02, rtol=1e-8, t_eval=[1.01, 1.02])
    # on the stop from t = stroke A_A / Q = 1.0 s (plus the oil compressed), then
    # dp/dt = beta Q / V_A of the closed chamber: 7e8 * 1e-4 / (1e-5 + 1e-4) Pa/s
    slope = (sol["cyl.A.p"][1] - sol["cyl.A.p"][0]) / 0.01
    assert slope == pytest.approx(7e8 * 1e-4 / 1.1e-4, rel=0.02)
    assert sol["mass.flange.x"][-1] == pytest.approx(0.1, abs=1e-4)


def test_sundials_backend_stops_a_sliding_mode_at_once():
    """x' = -sign(x) switched by an event on x with no hysteresis reaches 0 at t = 1 and
    switches there without end: both backends stop naming the event (IDA ran to max_steps,
    15 s for 20 000 steps)."""
    pytest.importorskip("sksundae")
    from pvgraph.errors import SolverError
    state = {"s": 1.0}

    def flip(t, y, yp):
        state["s"] = -state["s"]
        return y, np.array([-state["s"]])
    relay = Event(lambda t, y, yp: y[0], 0, False, flip, "relay")
    for solve in (solve_dae, solve_dae_sundials):
        state["s"] = 1.0
        with pytest.raises(SolverError, match=r"event 'relay' fired 50 times in a row between "
                                              r"t = 1 and 1"):
            solve(lambda t, y, yp: np.array([yp[0] + state["s"]]), (0.0, 2.0), [1.0], [-1.0],
                  rtol=1e-6, atol=1e-9, events=[relay], max_steps=20000)
