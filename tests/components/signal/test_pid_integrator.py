"""Integrator, product and the PID controller against closed forms and scipy.signal."""

import numpy as np
import pytest
from scipy import signal

from pvgraph import Circuit, ParameterError
from pvgraph.components.signal import (PID, Constant, FirstOrderLag, Integrator, Product, Sine,
                                       Step)
from pvgraph.simulate import simulate


def test_integrator_of_a_constant_is_a_ramp_from_its_start():
    c = Circuit("int")
    i = c.add("i", Integrator(k=3.0, y0=1.0))
    c.connect(c.add("u", Constant(k=2.0)).y, i.u)
    t = np.array([0.1, 0.5, 2.0])
    sol = simulate(c, 2.0, rtol=1e-9, t_eval=t)
    np.testing.assert_allclose(sol["i.y"], 1.0 + 6.0 * t, rtol=1e-9)


def test_product_of_a_sine_and_a_constant():
    c = Circuit("prod")
    m = c.add("m", Product(k=0.5))
    c.connect(c.add("s", Sine(amplitude=2.0, f=1.0)).y, m.u1)
    c.connect(c.add("k", Constant(k=3.0)).y, m.u2)
    acc = c.add("acc", Integrator())
    c.connect(m.y, acc.u)
    t = np.linspace(0.05, 1.0, 7)
    sol = simulate(c, 1.0, rtol=1e-10, atol=1e-12, t_eval=t)
    # 0.5 * 3 * 2 sin(2 pi t) = 3 sin(2 pi t), integrated: 3 (1 - cos(2 pi t)) / (2 pi)
    np.testing.assert_allclose(sol["acc.y"], 3.0 * (1.0 - np.cos(2 * np.pi * t)) / (2 * np.pi),
                               rtol=1e-6, atol=1e-8)


def _loop(pid, K=2.0, tau=0.5, r=1.0):
    """PID around the plant K/(tau s + 1), set point a step to ``r`` at t = 0."""
    c = Circuit("loop")
    ctl = c.add("pid", pid)
    plant = c.add("plant", FirstOrderLag(k=K, tau=tau))
    c.connect(c.add("r", Step(t_step=0.0, height=r)).y, ctl.r)
    c.connect(plant.y, ctl.m)
    c.connect(ctl.y, plant.u)
    return c


@pytest.mark.parametrize("Kp, Ki, Kd, N", [(1.5, 0.0, 0.0, 100.0), (1.5, 4.0, 0.0, 100.0),
                                          (0.8, 3.0, 0.05, 40.0), (0.0, 2.0, 0.0, 100.0)])
def test_closed_loop_step_matches_the_transfer_function(Kp, Ki, Kd, N):
    """C(s) = Kp + Ki/s + Kd N s/(s + N) around G(s) = K/(tau s + 1): the step response of
    CG/(1 + CG), computed by scipy.signal from the polynomials."""
    K, tau = 2.0, 0.5
    sol = simulate(_loop(PID(Kp=Kp, Ki=Ki, Kd=Kd, N=N), K, tau), 3.0, rtol=1e-9, atol=1e-11,
                   t_eval=np.linspace(0.0, 3.0, 61))
    P = np.polynomial.polynomial
    # C = num_c / (s (s + N)), polynomials in increasing powers of s
    num_c = P.polyadd(P.polyadd(P.polymul([Kp], [0.0, N, 1.0]),
                                P.polymul([Ki], [N, 1.0])),
                      [0.0, 0.0, Kd * N])
    den_c = [0.0, N, 1.0]
    num_g, den_g = [K], [1.0, tau]
    num = P.polymul(num_c, num_g)
    den = P.polyadd(P.polymul(den_c, den_g), num)
    t_ref, y_ref = signal.step(signal.lti(num[::-1], den[::-1]), T=sol.t)
    np.testing.assert_allclose(sol["plant.y"], y_ref, atol=2e-6)
    late = simulate(_loop(PID(Kp=Kp, Ki=Ki, Kd=Kd, N=N), K, tau), 60.0, rtol=1e-9, atol=1e-11)
    if Ki > 0:      # the integral leaves no steady error
        assert late["plant.y"][-1] == pytest.approx(1.0, abs=1e-6)
    else:           # P only: y = K Kp / (1 + K Kp)
        assert late["plant.y"][-1] == pytest.approx(K * Kp / (1 + K * Kp), rel=1e-6)


def test_limited_pid_saturates_and_back_calculation_stops_windup():
    """With the output limited to 0.6 the plant can reach at most K * 0.6 = 1.2 > 1; without
    anti-windup (a very slow tracking time) the integral winds up and the response overshoots
    further than with the default tracking time."""
    runs = {}
    for name, Tt in (("tracked", None), ("wound up", 1e6)):
        pid = PID(Kp=0.5, Ki=5.0, y_min=-0.6, y_max=0.6, Tt=Tt)
        sol = simulate(_loop(pid), 8.0, rtol=1e-8, atol=1e-10, t_eval=np.linspace(0, 8.0, 801))
        assert sol["pid.y"].max() == pytest.approx(0.6, abs=1e-7)
        assert sol["pid.y"].min() >= -0.6 - 1e-7
        runs[name] = sol
    over_tracked = runs["tracked"]["plant.y"].max() - 1.0
    over_wound = runs["wound up"]["plant.y"].max() - 1.0
    assert over_wound > over_tracked + 0.05
    assert runs["tracked"]["plant.y"][-1] == pytest.approx(1.0, abs=1e-3)
    # while saturated the tracked integral stays where the unlimited output is near the limit
    assert runs["tracked"]["pid.I"].max() < runs["wound up"]["pid.I"].max() - 0.2


@pytest.mark.parametrize("kwargs, field", [
    ({"Kp": 0.0}, "Kp, Ki and Kd"), ({"Kp": -1.0}, "Kp"), ({"y_min": 1.0, "y_max": 0.0}, "y_min"),
    ({"N": 0.0}, "N"), ({"Tt": 0.0}, "Tt"),
])
def test_bad_pid_parameters_name_the_field(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        PID(**kwargs)


def test_a_start_of_an_absent_integral_and_a_negative_gain_are_refused_with_the_way_out():
    with pytest.raises(ParameterError, match=r"I0 = 0.7 starts an integral term, but Ki = 0"):
        PID(Kp=1.0, I0=0.7)
    with pytest.raises(ParameterError, match=r"Kp = -1.0: the gains are >= 0; for a "
                                             r"reverse-acting loop swap r and m"):
        PID(Kp=-1.0)


def test_a_tracking_time_without_its_integral_or_limits_is_refused():
    with pytest.raises(ParameterError, match=r"Tt tracks the integral .* needs Ki > 0 and "
                                             r"y_min or y_max"):
        PID(Kp=1.0, Tt=0.1)
    PID(Kp=1.0, Ki=1.0, y_max=1.0, Tt=0.1)


def test_a_pid_round_trips_through_a_model_file(tmp_path):
    from pvgraph.modelfile import load, save
    c = _loop(PID(Kp=0.8, Ki=3.0, y_min=-1.0, y_max=1.0))
    save(c, tmp_path / "loop.toml")
    back = load(tmp_path / "loop.toml")
    assert back["pid"].params == c["pid"].params
