"""Signal sources: values in time, the step's event at exactly its time, validation."""

import numpy as np
import pytest

from pvgraph.components.signal import Constant, FirstOrderLag, Ramp, Sine, Step, TimeTable
from pvgraph import Circuit, ParameterError


def _through_lag(source, tau=0.02):
    """A circuit with ``source`` driving a first-order lag (so there is a state to integrate)."""
    c = Circuit("src")
    src = c.add("src", source)
    lag = c.add("lag", FirstOrderLag(tau=tau))
    c.connect(src.y, lag.u)
    return c


def test_constant_residual(dae):
    system = _through_lag(Constant(k=2.5)).compile(eliminate_aliases=False)
    r = dae.residual(system, values={"src.y": 2.5, "lag.u": 2.5, "lag.y": 1.0},
                     ders={"lag.y": (2.5 - 1.0) / 0.02})
    np.testing.assert_allclose(r, 0.0, atol=1e-12)


def test_step_happens_exactly_at_its_time(sim):
    t_step = 0.1234567
    sol = sim(_through_lag(Step(height=2.0, offset=-1.0, t_step=t_step)), 0.3, rtol=1e-7)
    (event,) = sol.events
    assert event.name == "src.step"
    assert event.t == pytest.approx(t_step, abs=1e-12)
    before, after = sol.t < t_step, sol.t > t_step
    assert np.all(sol["src.y"][before] == -1.0) and np.all(sol["src.y"][after] == 1.0)
    # the lag starts from its value just before the step: no smearing across it
    t = sol.t[after]
    y0 = -1.0 * (1.0 - np.exp(-t_step / 0.02))
    exact = 1.0 + (y0 - 1.0) * np.exp(-(t - t_step) / 0.02)
    np.testing.assert_allclose(sol["lag.y"][after], exact, atol=2e-5)


@pytest.mark.parametrize("solver", ["pvgraph", "ida"])
def test_run_starting_at_the_step_time_starts_with_the_new_value(solver):
    # the value at t_step is the new one, also for a run that begins there (or after it)
    from pvgraph.simulate import simulate
    circuit = _through_lag(Step(height=2.0, offset=-1.0, t_step=0.25))
    for t0 in (0.25, 0.4):
        sol = simulate(circuit, t0 + 0.1, t_start=t0, rtol=1e-7, solver=solver,
                       start={"lag.y": 0.0})
        assert sol.t[0] == t0
        np.testing.assert_array_equal(sol["src.y"], 1.0)
        # the lag then rises from 0 towards the new value 1: y = 1 - exp(-(t - t0)/tau)
        np.testing.assert_allclose(sol["lag.y"], 1.0 - np.exp(-(sol.t - t0) / 0.02), atol=1e-5)
        assert not sol.events


def test_run_starting_inside_a_ramp_starts_on_it():
    from pvgraph.simulate import simulate
    circuit = _through_lag(Ramp(height=4.0, duration=0.2, offset=1.0, t_start=0.1))
    sol = simulate(circuit, 0.5, t_start=0.2, rtol=1e-7)
    assert [e.name for e in sol.events] == ["src.end"]
    np.testing.assert_allclose(sol["src.y"], 1.0 + 4.0 * np.clip((sol.t - 0.1) / 0.2, 0, 1),
                               atol=1e-6)
    sol = simulate(circuit, 0.5, t_start=0.3, rtol=1e-7)   # starts at the end of the ramp
    assert all(e.t == 0.3 for e in sol.events)   # 0.3 - (0.1 + 0.2) < 0 by one roundoff
    np.testing.assert_allclose(sol["src.y"], 5.0, atol=1e-9)


def test_step_at_time_zero_is_already_up(dae):
    system = _through_lag(Step(height=3.0, t_step=0.0)).compile()
    assert not system.event_specs
    assert system.resolve("src.y") == (0.0, None, 3.0)


def test_ramp_values_and_events(sim):
    # algebraic outputs are exact to the Newton tolerance (about 1e-7 here), hence atol=1e-6
    sol = sim(_through_lag(Ramp(height=4.0, duration=0.2, offset=1.0, t_start=0.1)), 0.5,
              rtol=1e-7)
    assert [e.name for e in sol.events] == ["src.start", "src.end"]
    assert [e.t for e in sol.events] == pytest.approx([0.1, 0.3], abs=1e-12)
    expected = 1.0 + 4.0 * np.clip((sol.t - 0.1) / 0.2, 0.0, 1.0)
    np.testing.assert_allclose(sol["src.y"], expected, atol=1e-6)


def test_time_table_interpolates_and_holds(sim):
    """Every row on the table. Each knot is an event, located inside the step that passed
    it: the row just before it (its left limit) is that step's interpolant of y, which
    spans the knot's kink, so it is held to the tolerance's scale only; the row after is
    solved at the restart."""
    t_tab, y_tab = (0.0, 0.1, 0.25, 0.4), (0.0, 2.0, -1.0, 0.5)
    sol = sim(_through_lag(TimeTable(t=t_tab, y=y_tab)), 0.6, rtol=1e-7)
    exact = np.interp(sol.t, t_tab, y_tab)
    left = np.zeros(sol.t.size, dtype=bool)
    left[:-1] = sol.t[:-1] == sol.t[1:]         # a row followed by one at the same time
    assert np.count_nonzero(left) == 3          # the knots at 0.1, 0.25, 0.4
    np.testing.assert_allclose(sol["src.y"][~left], exact[~left], atol=1e-6)
    np.testing.assert_allclose(sol["src.y"][left], exact[left], atol=1e-3)
    assert sol.final("src.y") == pytest.approx(0.5, abs=1e-12)  # held at the last value


def test_sine_values(sim):
    sol = sim(_through_lag(Sine(amplitude=2.0, f=3.0, phase=0.4, offset=0.5)), 0.5, rtol=1e-7)
    np.testing.assert_allclose(sol["src.y"], 0.5 + 2.0 * np.sin(6 * np.pi * sol.t + 0.4),
                               atol=1e-6)


@pytest.mark.parametrize("cls, kwargs, field", [
    (Constant, {}, "k"), (Constant, {"k": float("nan")}, "k"),
    (Step, {"t_step": -1.0}, "t_step"), (Ramp, {"duration": 0.0}, "duration"),
    (Ramp, {"duration": 1.0, "t_start": -0.1}, "t_start"),
    (TimeTable, {"t": (0.0,), "y": (1.0,)}, "t"),
    (TimeTable, {"t": (0.0, 1.0), "y": (1.0, 2.0, 3.0)}, "t has 2 points but y has 3"),
    (TimeTable, {"t": (0.0, 0.0), "y": (1.0, 2.0)}, "t must be strictly increasing"),
    (TimeTable, {"t": (0.0, 1.0), "y": (1.0, 2.0), "method": "cubic"}, "method"),
    (Sine, {"f": 0.0}, "f"),
])
def test_bad_parameters_name_the_field(cls, kwargs, field):
    with pytest.raises(ParameterError, match=field):
        cls(**kwargs)


@pytest.mark.parametrize("source", [
    lambda: Step(t_step=0.1), lambda: Ramp(duration=0.5, t_start=0.2),
    lambda: TimeTable(t=(0.0, 1.0, 2.0), y=(0.0, 1.0, 0.0), method="pchip"),
    lambda: Sine(f=2.0),
])
def test_jacobian_matches_finite_differences(dae, source):
    system = _through_lag(source()).compile()
    for t in (0.05, 0.3, 0.7):
        dae.check_jacobian(system, t=t, values={"lag.y": 0.3}, ders={"lag.y": 1.0})


def test_a_signal_value_given_with_a_unit_is_taken_in_si():
    """Signals carry SI values: a set point of "100 bar" is 1e7, "20 L/min" 3.33e-4 m^3/s, a
    gain of "2 bar/mm" 2e8 Pa/m; a word that is no unit is refused by name."""
    from pvgraph.components import Gain
    assert Step(height="100 bar", t_step="100 ms").params.height == pytest.approx(1e7)
    assert Constant(k="20 L/min").params.k == pytest.approx(20.0 / 60000.0)
    assert Gain(k="2 bar/mm").params.k == pytest.approx(2e8)
    with pytest.raises(ParameterError, match=r"k = '3 furlong'.*unknown unit 'furlong'"):
        Constant(k="3 furlong")


@pytest.mark.parametrize("rtol", [1e-2, 1e-6, 1e-10])
def test_pulse_train_stops_at_every_edge_at_any_tolerance(rtol):
    """A 1 kHz pulse train at 30 % duty into an integrator: 2000 edges in 1 s, the integral
    0.3 (the duty) to 1e-9 at every tolerance. A condition on cos(2 pi f t) was missed where
    a step spanned a period (y(1 s) = 1.0 at rtol 1e-2, 0.03 at 1e-6)."""
    from pvgraph.components.signal import Integrator, Pulse
    from pvgraph.simulate import simulate
    c = Circuit("pwm")
    c.add("pwm", Pulse(period="1 ms", duty=0.3))
    c.add("i", Integrator())
    c.connect("pwm.y", "i.u")
    sol = simulate(c, 1.0, rtol=rtol, t_eval=[0.5, 1.0])
    assert sol["i.y"][-1] == pytest.approx(0.3, abs=1e-9)
    assert len(sol.events) == 2000
    assert [e.t for e in sol.events[:3]] == pytest.approx([3e-4, 1e-3, 1.3e-3], abs=1e-15)


def test_pulse_offset_height_and_first_rise():
    """Off (-1) until the first rise at 50 ms, then +1 for a quarter of each 100 ms: over 1 s
    the integral is -0.05 before it, 9 periods of (0.025 - 0.075) and a last half period
    (0.025 on, 0.025 off)."""
    from pvgraph.components.signal import Integrator, Pulse
    from pvgraph.simulate import simulate
    c = Circuit("pwm")
    c.add("pwm", Pulse(period=0.1, duty=0.25, t_start=0.05, height=2.0, offset=-1.0))
    c.add("i", Integrator())
    c.connect("pwm.y", "i.u")
    sol = simulate(c, 1.0, t_eval=[0.04, 0.06, 0.08, 1.0])
    assert list(sol["pwm.y"][:3]) == [-1.0, 1.0, -1.0]
    assert sol["i.y"][-1] == pytest.approx(-0.05 + 9 * (0.025 - 0.075) + 0.0, abs=1e-9)
    with pytest.raises(ParameterError, match="duty"):
        Pulse(period=0.1, duty=1.0)


@pytest.mark.parametrize("t0, on", [(0.0005, 0.0), (0.0015, 0.0), (0.0002, 1.0), (0.5, 1.0)])
def test_a_run_started_inside_a_pulse_train_starts_where_the_train_is(t0, on):
    """A 1 ms, 30 % train run from t0 for 10 ms: off at 0.5 ms and 1.5 ms, on at 0.2 ms and at
    0.5 s (a rise), 20 edges and the integral 0.003 (it stayed on, no edge, 0.010)."""
    from pvgraph.components.signal import Integrator, Pulse
    from pvgraph.simulate import simulate
    c = Circuit("pwm")
    c.add("pwm", Pulse(period="1 ms", duty=0.3))
    c.add("i", Integrator())
    c.connect("pwm.y", "i.u")
    sol = simulate(c, t0 + 0.01, t_start=t0, t_eval=[t0, t0 + 0.01])
    assert sol["pwm.y"][0] == on
    assert sol["i.y"][-1] - sol["i.y"][0] == pytest.approx(0.003, abs=1e-9)
    assert len(sol.events) == 20


def test_a_sine_source_bounds_the_steps_so_no_pulse_is_stepped_over():
    """A 200 Hz pressure (20 +- 50 bar) through a check valve into 0.1 L bled to tank: the
    node pumps up to a mean of 63.085 bar (rtol 1e-8). At rtol 1e-4 whole openings of the
    valve fell between steps (the source drives algebraic parts only) and the mean came out
    60.82 bar; the Sine's max_step_hint (a tenth of its period) bounds the steps."""
    from pvgraph.components import CheckValve, LaminarOrifice, PressureInput, Tank, VolumeNode
    from pvgraph.simulate import simulate
    c = Circuit("pulsation")
    c.add("sine", Sine(f=200.0, amplitude=50e5, offset=20e5))
    c.add("src", PressureInput())
    c.add("cv", CheckValve(A=2e-6))
    c.add("n", VolumeNode(V=1e-4, beta=7e8))
    c.add("bleed", LaminarOrifice(K=1e-12))
    c.add("tank", Tank())
    c.connect("sine.y", "src.u")
    c.connect("src.port", "cv.a")
    c.connect("cv.b", "n.port", "bleed.a")
    c.connect("bleed.b", "tank.port")
    sol = simulate(c, 1.0, rtol=1e-4, t_eval=np.linspace(0.9, 1.0, 2001))
    assert np.mean(sol["n.port.p"]) == pytest.approx(63.085e5, abs=0.2e5)


@pytest.mark.parametrize("period", [0.2, 0.25])
def test_a_pulse_period_changed_at_run_time_gives_that_train(period):
    """A 0.1 s train compiled once, run with the period as a runtime parameter (a sweep of
    the PWM period): the train of that period, 30 % on, so the integral over 1 s is 0.3 and
    2 edges per period. The start-of-run catch-up ran at every edge with the compiled period
    and undid them (0.25 s: one pulse, then nothing)."""
    from pvgraph.components.signal import Integrator, Pulse
    from pvgraph.simulate import simulate
    c = Circuit("pwm")
    c.add("pwm", Pulse(period=0.1, duty=0.3))
    c.add("i", Integrator())
    c.connect("pwm.y", "i.u")
    s = c.compile()
    sol = simulate(s, 1.0, params={"pwm.period": period}, t_eval=[1.0])
    assert sol.final("i.y") == pytest.approx(0.3, abs=1e-9)
    assert len(sol.events) == round(2 / period)      # the rise at 0 applied at start, at 1 s


def test_a_late_start_with_a_period_changed_at_run_time_starts_where_that_train_is():
    """Built with a 0.1 s period, run with 0.2 s from t = 0.25 s: at 0.25 s the 0.2 s train
    is on (0.05 s into its 0.06 s pulse), and its mean over the run is the duty, 0.3."""
    from pvgraph.components.signal import Integrator, Pulse
    from pvgraph.simulate import simulate
    c = Circuit("pwm")
    c.add("pwm", Pulse(period=0.1, duty=0.3))
    c.add("i", Integrator())
    c.connect("pwm.y", "i.u")
    sol = simulate(c.compile(), 1.25, t_start=0.25, params={"pwm.period": 0.2},
                   t_eval=[0.25, 1.25])
    assert sol["pwm.y"][0] == 1.0
    assert (sol["i.y"][-1] - sol["i.y"][0]) == pytest.approx(0.3, abs=1e-9)


@pytest.mark.parametrize("solver", ["pvgraph", "ida"])
@pytest.mark.parametrize("t0", [0.0, 2.0005])
def test_a_short_plateau_of_a_time_table_is_not_stepped_over(solver, t0):
    """A command of 0 until 2 s, up to 1 in 1 ms, held 50 ms, down in 1 ms, into a lag of
    10 ms at rest: the run took 11 steps and saw nothing (the integral of y 0 against
    0.051, on both solvers). Every knot where the table turns is now an event. A run
    starting inside the rise starts at the next one ahead."""
    if solver == "ida":
        pytest.importorskip("sksundae")
    from pvgraph.simulate import simulate
    tt = (0.0, 2.0, 2.001, 2.051, 2.052, 5.0)
    c = Circuit("tt")
    c.add("src", TimeTable(t=tt, y=(0.0, 0.0, 1.0, 1.0, 0.0, 0.0)))
    c.add("lag", FirstOrderLag(tau=0.01))
    c.connect("src.y", "lag.u")
    sol = simulate(c, 5.0, t_start=t0, rtol=1e-6, solver=solver)
    area = 0.051 - (0.5 * 0.5 ** 2 * 1e-3 if t0 > 0 else 0.0)   # the part of the rise before t0
    assert np.trapezoid(sol["lag.y"], sol.t) == pytest.approx(area, rel=2e-3)
    assert sol["lag.y"].max() == pytest.approx(1.0 - np.exp(-5.0), abs=2e-3)
    corners = (2.0, 2.001, 2.051, 2.052)        # where the table turns (not its flat ends)
    assert [e.t for e in sol.events if e.name.endswith("knot")] == pytest.approx(
        [tk for tk in corners if tk > t0], abs=1e-9)


def test_a_logged_trace_in_a_time_table_costs_no_event_per_sample():
    """A sampled smooth signal (2001 samples of sin 2 pi t + 0.5 sin 14 pi t over 2 s) into a
    lag: every knot an event made the run 36 times longer (2000 restarts) and 20 001 samples
    ran out of steps. Only the knots where a table turns are events (none here); the error
    test follows the trace, within 1e-4 of the lag's exact response to the interpolated
    input (scipy, rtol 1e-10)."""
    from scipy.integrate import solve_ivp
    from pvgraph.simulate import simulate
    t = np.linspace(0.0, 2.0, 2001)
    y = np.sin(2 * np.pi * t) + 0.5 * np.sin(14 * np.pi * t)
    c = Circuit("trace")
    c.add("src", TimeTable(t=tuple(t), y=tuple(y)))
    c.add("lag", FirstOrderLag(tau=0.05))
    c.connect("src.y", "lag.u")
    sol = simulate(c, 2.0)
    assert not [e for e in sol.events if e.name.endswith("knot")][1:]
    ref = solve_ivp(lambda s, x: [(np.interp(s, t, y) - x[0]) / 0.05], (0.0, 2.0), [0.0],
                    rtol=1e-10, atol=1e-12, max_step=1e-3)
    assert sol.final("lag.y") == pytest.approx(ref.y[0, -1], abs=1e-4)
