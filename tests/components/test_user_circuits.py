"""Machine-designer circuits built from the library as the README shows, against closed forms.

Each circuit is written the way a user writes it (units as strings, ports joined as they are
piped) and checked against the hand calculation of the part's documented law, with the
documented smoothing taken into account where it matters.
"""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from pvgraph import Circuit
from pvgraph.analysis import linearize_circuit, steady_state
from pvgraph.components import (CheckValve, CounterbalanceValve, Cylinder, DirectionalValve43,
                                FixedDisplacementPump, FlowInput, FlowSource, GasAccumulator,
                                HydraulicMotor, Inertia, Mass, Orifice, PiLine, Plug,
                                PressureSource, PressureReducingValve, ReliefValve, SpeedSource,
                                Step, Tank, TimeTable, VolumeNode)
from pvgraph.components.hydraulic import segmented_line
from pvgraph.simulate import simulate

RHO, CD, BETA, P_ATM = 870.0, 0.6, 7e8, 101325.0
LPM = 1.0 / 60000.0


def turbulent(A, dp, dp_t):
    """Report eq. A.4 as documented: q = Cd A sqrt(2/rho) dp / (dp^2 + dp_t^2)^(1/4)."""
    return CD * A * math.sqrt(2.0 / RHO) * dp / (dp * dp + dp_t * dp_t) ** 0.25


def drop(A, q, dp_t):
    """The pressure drop that passes ``q`` through ``A`` by :func:`turbulent`."""
    return brentq(lambda dp: turbulent(A, dp, dp_t) - q, 0.0, 1e9, xtol=1e-9, rtol=1e-14)


# --- 1. fixed pump at 1500 rpm into a relief valve -------------------------------------------
RELIEF = dict(p_crack="150 bar", A_s="20 mm^2", k="20 N/mm", x_max="2 mm", w="5 mm")


def pump_relief(w0="1500 rpm"):
    c = Circuit("relief")
    motor = c.add("motor", SpeedSource(w0=w0))
    pump = c.add("pump", FixedDisplacementPump(D="10 cm^3/rev"))
    node = c.add("node", VolumeNode(V="0.5 L"))
    rv = c.add("rv", ReliefValve(**RELIEF))
    tank = c.add("tank", Tank())
    c.connect(motor.shaft, pump.shaft)
    c.connect(tank.port, pump.a, rv.T)
    c.connect(pump.b, node.port, rv.P)
    return c


D_P = 10e-6 / (2 * math.pi)                             # 10 cm^3/rev
K_P = (1 - 0.95) * D_P * 157.08 / 2e7                    # pump leakage, rated at 200 bar


def relief_flow(dp, pc=150e5):
    """The documented static relief law (inside the stroke, seat smoothing -eps/2)."""
    A_s, k, x_max, wg = 20e-6, 2e4, 2e-3, 5e-3
    kf = 2 * CD * wg * math.cos(math.radians(69.0))      # flow-force stiffness per Pa
    x = A_s * (dp - pc) / (k + kf * dp) - 5e-4 * x_max
    return turbulent(1e-11 + wg * x, dp, 1e4)


def relief_closed_form():
    """Steady pressure of the pump + relief circuit from the documented laws."""
    w = 1500 * 2 * math.pi / 60
    dp = brentq(lambda dp: relief_flow(dp) - (D_P * w - K_P * dp), 150e5 + 1e3, 170e5,
                xtol=1e-6)
    return dp, D_P * w - K_P * dp, D_P


def test_pump_at_1500_rpm_into_relief_valve():
    dp, Q, D = relief_closed_form()
    assert 150e5 < dp < 170e5                            # between cracking and full stroke
    system = pump_relief().compile()
    op = steady_state(system)
    assert op.info["cyclic"] == ["pump.shaft.phi"]
    assert op["node.port.p"] == pytest.approx(dp, rel=1e-7)
    assert op["rv.q"] == pytest.approx(Q, rel=1e-6)
    assert op["pump.shaft.tau"] == pytest.approx(D * dp / 0.92, rel=1e-6)   # T = D dp / eta_hm
    sol = simulate(system, t_end=0.5)
    assert sol.final("node.port.p") == pytest.approx(dp, rel=1e-5)


def test_relief_steady_state_sensitivity_to_the_setting():
    """d p / d p_crack at the pump's operating point: 1 plus the slope of the leak, exactly."""
    dp, Q, _ = relief_closed_form()
    op = steady_state(pump_relief().compile())
    sens = op.sensitivity(["node.port.p"], ["rv.p_crack"])[0, 0]
    h = 1e3
    RELIEF["p_crack"] = 150e5 + h
    try:
        dp2 = steady_state(pump_relief().compile())["node.port.p"]
    finally:
        RELIEF["p_crack"] = "150 bar"
    assert sens == pytest.approx((dp2 - dp) / h, rel=1e-4)


def test_pump_relief_linear_model_from_the_valve_slope():
    """Node pole -(beta/V) (dq/dp + K), gain dp/dw = D / (dq/dp + K); the angle is left out."""
    dp, _, _ = relief_closed_form()
    slope = (relief_flow(dp + 10.0) - relief_flow(dp - 10.0)) / 20.0 + K_P
    model = linearize_circuit(lambda u: pump_relief(u["w0"]), {"w0": 50 * math.pi},
                              ["node.port.p"])
    assert model.state_names == ["node.port.p"]
    (pole,) = model.poles()
    assert pole.real == pytest.approx(-(BETA / 0.5e-3) * slope, rel=1e-5)
    gain = (model.C @ np.linalg.solve(-model.A, model.B) + model.D)[0, 0]
    assert gain == pytest.approx(D_P / slope, rel=1e-5)


# --- 2. pump -> 4/3 valve -> cylinder -> mass ---------------------------------------------------
A_A, A_ROD, B_LOAD, Q_CYL = 1963.5e-6, 615.75e-6, 2e4, 10 * LPM


def cylinder_circuit():
    c = Circuit("cyl")
    pump = c.add("pump", FlowSource(Q="10 L/min"))
    tank = c.add("tank", Tank())
    rv = c.add("rv", ReliefValve(p_crack="200 bar", A_s="20 mm^2", k="20 N/mm", x_max="2 mm",
                                 w="5 mm"))
    hose = c.add("hose", VolumeNode(V="0.2 L"))
    valve = c.add("valve", DirectionalValve43(A_max="20 mm^2"))
    cmd = c.add("cmd", Step(offset=1.0, height=-2.0, t_step=1.0))    # extend, then retract
    cyl = c.add("cyl", Cylinder(A_A="1963.5 mm^2", A_rod="615.75 mm^2", stroke="0.5 m",
                                V_dead_A="0.05 L", V_dead_B="0.05 L"))
    load = c.add("load", Mass(m="200 kg", b=B_LOAD, x0=0.1))
    c.connect(pump.port, hose.port, rv.P, valve.P)
    c.connect(valve.T, rv.T, tank.port)
    c.connect(cmd.y, valve.u)
    c.connect(valve.A, cyl.A)
    c.connect(valve.B, cyl.B)
    c.connect(cyl.flange, load.flange)
    return c


def test_cylinder_extends_at_q_over_a_and_retracts_at_q_over_annulus():
    sol = simulate(cylinder_circuit(), t_end=1.5)
    A_B = A_A - A_ROD
    v = sol.der("cyl.flange.x")
    i_ext, i_ret = np.searchsorted(sol.t, 0.9), np.searchsorted(sol.t, 1.45)
    assert v[i_ext] == pytest.approx(Q_CYL / A_A, rel=1e-4)
    assert v[i_ret] == pytest.approx(-Q_CYL / A_B, rel=1e-4)
    # extending: the rod side meters out through B -> T; p_A carries the load b v and p_B A_B
    for i, q_in, q_out, A_in, A_out, F in (
            (i_ext, Q_CYL, Q_CYL * A_B / A_A, A_A, A_B, B_LOAD * Q_CYL / A_A),
            (i_ret, Q_CYL, Q_CYL * A_A / A_B, A_B, A_A, B_LOAD * Q_CYL / A_B)):
        p_out = drop(20e-6, q_out, 1e4)
        p_in = (F + p_out * A_out) / A_in
        inlet, outlet = ("cyl.A.p", "cyl.B.p") if i == i_ext else ("cyl.B.p", "cyl.A.p")
        assert sol[outlet][i] == pytest.approx(p_out, abs=2e3)        # 0.02 bar
        assert sol[inlet][i] == pytest.approx(p_in, abs=2e3)
        assert sol["valve.P.p"][i] == pytest.approx(p_in + drop(20e-6, q_in, 1e4), abs=2e3)


# --- 3. hydraulic motor on an inertia with bearing friction ------------------------------------
D_M = 10e-6 / (2 * math.pi)
B_ROT = 0.92 * D_M * 2e7 / 157.08        # friction that puts the motor on its rated point


def motor_circuit(Q):
    c = Circuit("motor")
    src = c.add("src", FlowSource(Q=Q))
    node = c.add("node", VolumeNode(V="0.1 L"))
    motor = c.add("motor", HydraulicMotor(D="10 cm^3/rev"))
    load = c.add("load", Inertia(J="0.01 kg m^2", b=B_ROT))
    tank = c.add("tank", Tank())
    c.connect(src.port, node.port, motor.A)
    c.connect(motor.B, tank.port)
    c.connect(motor.shaft, load.shaft)
    return c


def test_motor_speed_and_torque_at_the_rated_point():
    Q = D_M * 157.08 / 0.95
    system = motor_circuit(Q).compile()
    op = steady_state(system)
    assert op["load.w"] == pytest.approx(0.95 * Q / D_M, rel=1e-8)       # w = eta_v Q / D
    assert op["node.port.p"] == pytest.approx(2e7, rel=1e-7)             # T = eta_hm D dp = b w
    sol = simulate(system, t_end=1.0)
    assert sol.final("load.w") == pytest.approx(157.08, rel=1e-5)


def test_motor_off_the_rated_point_follows_the_leakage_law():
    Q = 8 * LPM
    K = (1 / 0.95 - 1) * D_M * 157.08 / 2e7
    w = Q / (D_M + K * B_ROT / (0.92 * D_M))     # q = D w + K dp with eta_hm D dp = b w
    op = steady_state(motor_circuit(Q).compile())
    assert op["load.w"] == pytest.approx(w, rel=1e-8)
    assert op["node.port.p"] == pytest.approx(B_ROT * w / (0.92 * D_M), rel=1e-6)   # |dp| rounded by dp_eps


# --- 4. gas accumulator charged through an orifice, then discharged ----------------------------
def accumulator_circuit(n):
    c = Circuit("acc")
    flow = c.add("flow", TimeTable(t=[0.0, 1.0, 1.0001, 1.5], y=[1e-4, 1e-4, -1e-4, -1e-4]))
    src = c.add("src", FlowInput())
    node = c.add("node", VolumeNode(V="0.05 L", p0="50 bar"))
    orifice = c.add("orifice", Orifice(A="5 mm^2"))
    acc = c.add("acc", GasAccumulator(V0="1 L", p_pre="50 bar", n=n))
    c.connect(flow.y, src.u)
    c.connect(src.port, node.port, orifice.a)
    c.connect(orifice.b, acc.port)
    return c


@pytest.mark.filterwarnings("ignore::pvgraph.errors.PlausibilityWarning")   # no tank: closed
@pytest.mark.parametrize("n", [1.0, 1.4])
def test_accumulator_follows_the_polytrope(n):
    sol = simulate(accumulator_circuit(n), t_end=1.5, rtol=1e-8)
    dp_b = 1e-3 * (50e5 + P_ATM)
    for t, V_in in ((1.0, 1e-4), (1.5, 0.5e-4)):
        i = np.searchsorted(sol.t, t - 1e-9)
        V_oil = sol["acc.V_oil"][i]
        assert V_oil == pytest.approx(V_in, rel=2e-3)     # the rest compresses the node's oil
        p = (50e5 + P_ATM) * (1e-3 / (1e-3 - V_oil)) ** n - P_ATM
        assert abs(sol["acc.port.p"][i] - p) < dp_b
        assert sol["acc.p_gas"][i] == pytest.approx(p, rel=1e-9)


# --- 5. pressure-reducing, check and counterbalance valves -------------------------------------
def test_pressure_reducing_valve_holds_its_setting():
    c = Circuit("prv")
    supply = c.add("supply", PressureSource(p0="200 bar"))
    prv = c.add("prv", PressureReducingValve(p_set="50 bar", A_max="10 mm^2"))
    node = c.add("node", VolumeNode(V="0.1 L"))
    load = c.add("load", Orifice(A="1 mm^2"))
    tank = c.add("tank", Tank())
    c.connect(supply.port, prv.P)
    c.connect(prv.A, node.port, load.a)
    c.connect(load.b, tank.port)
    op = steady_state(c.compile())
    dp_t_load = load.params.transition()

    def balance(p):
        s = min(max((p - 45e5) / 5e5, 0.0), 1.0)
        A = 1e-11 + 10e-6 * (1 - s * s * (3 - 2 * s))
        return turbulent(A, 200e5 - p, 1e4) - turbulent(1e-6, p, dp_t_load)

    p = brentq(balance, 1e5, 199e5, xtol=1e-6)
    assert 45e5 <= p <= 50e5
    assert op["node.port.p"] == pytest.approx(p, rel=1e-9)


def test_check_valve_blocks_reverse_flow_to_its_leakage():
    c = Circuit("check")
    high = c.add("high", PressureSource(p0="100 bar"))
    check = c.add("check", CheckValve(A="5 mm^2", p_crack="1 bar"))
    tank = c.add("tank", Tank())
    c.connect(tank.port, check.a)
    c.connect(check.b, high.port)
    op = steady_state(c.compile())
    assert op["check.q"] == pytest.approx(-turbulent(1e-12, 100e5, 1e3), rel=1e-9)


def test_counterbalance_valve_holds_a_hanging_mass_to_its_leakage():
    c = Circuit("boom")
    tank = c.add("tank", Tank())
    cbv = c.add("cbv", CounterbalanceValve(p_set="70 bar", A_max="20 mm^2", A_check="20 mm^2"))
    p_load = 1000 * 9.81 / A_A
    cyl = c.add("cyl", Cylinder(A_A=A_A, A_rod="615.75 mm^2", stroke="0.5 m", V_dead_A="0.05 L",
                                V_dead_B="0.05 L", p0_A=p_load))
    mass = c.add("mass", Mass(m="1000 kg", g=-9.81, x0=0.2))
    c.connect(tank.port, cbv.valve, cbv.pilot, cyl.B)       # valve side open to tank: worst case
    c.connect(cbv.load, cyl.A)
    c.connect(cyl.flange, mass.flange)
    sol = simulate(c, t_end=2.0)
    late = sol.t > 0.5
    creep = np.polyfit(sol.t[late], sol["cyl.flange.x"][late], 1)[0]
    leak = 2 * turbulent(1e-11, p_load, 1e4)
    assert sol.final("cyl.A.p") == pytest.approx(p_load, rel=1e-3)
    assert creep == pytest.approx(-leak / A_A, rel=0.01)


# --- 6. line friction --------------------------------------------------------------------------
HP = 128 * RHO * 3.2e-5 * 5.0 * (5 * LPM) / (math.pi * 0.01 ** 4)   # 128 mu L Q / (pi d^4)


def line_circuit(line):
    c = Circuit("line")
    src = c.add("src", FlowSource(Q="5 L/min"))
    c.add("line", line)
    tank = c.add("tank", Tank())
    c.connect(src.port, c["line"].a)
    c.connect(c["line"].b, tank.port)
    return c


@pytest.mark.parametrize("friction, rel", [("laminar", 1e-12), ("blended", 1e-5)])
def test_pi_line_laminar_pressure_drop(friction, rel):
    op = steady_state(line_circuit(PiLine(l="5 m", d="10 mm", friction=friction)).compile())
    assert op["line.a.p"] == pytest.approx(HP, rel=rel)      # Re = 332: laminar


def test_segmented_line_takes_units_and_has_the_same_drop():
    line = segmented_line(4, l="5 m", d="10 mm", friction="laminar")
    op = steady_state(line_circuit(line).compile())
    assert op["line.a.p"] == pytest.approx(HP, rel=1e-12)


# --- 7. linearisation of a volume and an orifice -----------------------------------------------
def test_volume_orifice_pole():
    def build(u):
        c = Circuit("vo")
        pump = c.add("pump", FlowSource(Q=u["Q"]))
        node = c.add("node", VolumeNode(V="0.5 L"))
        orifice = c.add("orifice", Orifice(A="2 mm^2"))
        tank = c.add("tank", Tank())
        c.connect(pump.port, node.port, orifice.a)
        c.connect(orifice.b, tank.port)
        return c

    Q = 10 * LPM
    model = linearize_circuit(build, {"Q": Q}, ["node.port.p"])
    dp = drop(2e-6, Q, build({"Q": Q})["orifice"].params.transition())
    (pole,) = model.poles()
    assert pole.real == pytest.approx(-(BETA / 0.5e-3) * Q / (2 * dp), rel=1e-5)


# --- machine-scale positions ---------------------------------------------------------------------
def test_a_load_resting_on_a_stop_two_metres_up():
    """Stops and grounds take machine-scale positions: a load rests m g / k into its stop."""
    from pvgraph.components import EndStop, Fixed, TwoFlangeSpring
    c = Circuit("stop")
    body = c.add("body", Mass(m="100 kg", g=-9.81, x0=1.6))   # starts 0.1 m above it
    stop = c.add("stop", EndStop(x_min=1.5, x_max=3.0, k=1e7, d=2e4))
    c.connect(body.flange, stop.flange)
    op = steady_state(c.compile())
    # m g / k = 98.1 um into the stop; the rounding (eps = 0.1 um) moves it by 2.5e-11 m
    assert op["body.flange.x"] == pytest.approx(1.5 - 100 * 9.81 / 1e7, abs=1e-10)
    c = Circuit("hang")
    top = c.add("top", Fixed(x0=2.5))
    spring = c.add("spring", TwoFlangeSpring(k=1e4))
    body = c.add("body", Mass(m="10 kg", g=-9.81, x0=2.5))
    c.connect(body.flange, spring.a)
    c.connect(spring.b, top.flange)
    op = steady_state(c.compile())
    assert op["body.flange.x"] == pytest.approx(2.5 - 10 * 9.81 / 1e4, abs=1e-12)


def test_pressure_compensated_pump_holds_its_cut_off_band():
    """eps = 1 - ramp(p; p_c - dp_reg, dp_reg) and q = eps D w - K dp, through an orifice."""
    from pvgraph.components import PressureCompensatedPump
    c = Circuit("pc")
    motor = c.add("motor", SpeedSource(w0="1500 rpm"))
    pump = c.add("pump", PressureCompensatedPump(D="28 cm^3/rev", p_c="200 bar"))
    node = c.add("node", VolumeNode(V="1 L"))
    load = c.add("load", Orifice(A="2 mm^2"))
    tank = c.add("tank", Tank())
    c.connect(motor.shaft, pump.shaft)
    c.connect(tank.port, pump.a, load.b)
    c.connect(pump.b, node.port, load.a)
    op = steady_state(c.compile())
    D, w = 28e-6 / (2 * math.pi), 50 * math.pi
    K = 0.05 * D * 157.08 / 2e7
    p, eps = op["node.port.p"], op["pump.eps"]
    assert 195e5 < p < 200e5
    s = (p - 195e5) / 5e5
    assert eps == pytest.approx(1 - s * s * (3 - 2 * s), rel=1e-9)
    assert eps * D * w - K * p == pytest.approx(turbulent(2e-6, p, load.params.transition()),
                                                rel=1e-9)


def test_machine_circuits_round_trip_through_a_model_file(tmp_path):
    """Export to TOML and back: the same equations give the same operating point and run."""
    from pvgraph import modelfile
    dp, _, _ = relief_closed_form()
    modelfile.save(pump_relief(), tmp_path / "relief.toml")
    op = steady_state(modelfile.load(tmp_path / "relief.toml").compile())
    assert op["node.port.p"] == pytest.approx(dp, rel=1e-7)
    modelfile.save(cylinder_circuit(), tmp_path / "cyl.json")
    sol = simulate(modelfile.load(tmp_path / "cyl.json"), t_end=1.5)
    assert sol.der("cyl.flange.x")[np.searchsorted(sol.t, 1.45)] == \
        pytest.approx(-Q_CYL / (A_A - A_ROD), rel=1e-4)


# --- hydraulic spring: a mass on a cylinder with both ports blocked --------------------------
def blocked_cylinder(v0=0.0):
    """Cap side at 50 bar, rod side at the pressure that balances it, 500 kg on the rod."""
    a_b = A_A - A_ROD
    c = Circuit("hydraulic_spring")
    cyl = c.add("cyl", Cylinder(A_A=A_A, A_rod=A_ROD, stroke="0.5 m", V_dead_A="0.05 L",
                                V_dead_B="0.05 L", p0_A="50 bar", p0_B=50e5 * A_A / a_b))
    mass = c.add("mass", Mass(m="500 kg", x0=0.2, v0=v0))
    plug_a, plug_b = c.add("plug_a", Plug()), c.add("plug_b", Plug())
    c.connect(cyl.A, plug_a.port)
    c.connect(cyl.B, plug_b.port)
    c.connect(cyl.flange, mass.flange)
    return c, cyl


def hydraulic_spring_frequency(cyl, x):
    """omega = sqrt(beta (A_A^2 / V_A + A_B^2 / V_B) / m): both oil columns as springs."""
    a_b = A_A - A_ROD
    v_a, v_b = 0.05e-3 + A_A * x, 0.05e-3 + a_b * (0.5 - x)
    return math.sqrt(cyl.params.beta * (A_A ** 2 / v_a + a_b ** 2 / v_b) / 500.0)


def test_blocked_cylinder_rings_at_the_hydraulic_spring_frequency():
    from pvgraph.analysis.linearize import linearize
    c, cyl = blocked_cylinder()
    system = c.compile()
    op = steady_state(system)
    assert op["mass.flange.x"] == pytest.approx(0.2, abs=1e-12)     # balanced as built
    w = hydraulic_spring_frequency(cyl, 0.2)
    eig = np.linalg.eigvals(linearize(system, op, None, ["mass.flange.x"]).A)
    ringing = eig[np.abs(eig.imag) > 1.0]
    assert len(ringing) == 2
    assert np.abs(ringing.imag) == pytest.approx([w, w], rel=1e-9)
    assert np.abs(ringing.real).max() < 1e-9 * w          # no damping in the model: none


def test_blocked_cylinder_oscillates_with_the_period_and_amplitude_of_the_spring():
    # a 1 mm/s push: amplitude v0 / omega (~7.5 um), far inside the linear range
    c, cyl = blocked_cylinder(v0=1e-3)
    w = hydraulic_spring_frequency(cyl, 0.2)
    period = 2 * math.pi / w
    sol = simulate(c, t_end=10 * period, rtol=1e-9, atol=1e-12,
                   t_eval=np.linspace(0.0, 10 * period, 4001))
    x = sol["mass.flange.x"] - 0.2
    up = np.flatnonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))      # upward zero crossings
    t_up = sol.t[up] - x[up] * (sol.t[up + 1] - sol.t[up]) / (x[up + 1] - x[up])
    assert np.diff(t_up) == pytest.approx(period, rel=1e-4)
    assert np.abs(x).max() == pytest.approx(1e-3 / w, rel=1e-3)


def test_position_servo_with_a_pi_controller_settles_on_its_set_point():
    """A servo valve, a cylinder on a damped mass, a position sensor and a PI controller with
    its output limited to the full spool stroke: the integral leaves no steady error, so the
    steady state puts the rod at the set point, 200 mm, and a run settles there."""
    from pvgraph.components import PID, PositionSensor, PressureSource, ServoValve, Step
    from pvgraph.units import cm2
    c = Circuit("servo")
    sv = c.add("sv", ServoValve(Q_nom="20 L/min"))
    c.connect(c.add("ps", PressureSource(p0="150 bar")).port, sv.P)
    c.connect(c.add("t", Tank()).port, sv.T)
    cyl = c.add("cyl", Cylinder(A_A=cm2(20), A_rod=cm2(10), stroke=0.5, V_dead_A=1e-5,
                                V_dead_B=1e-5))
    c.connect(sv.A, cyl.A)
    c.connect(sv.B, cyl.B)
    c.add("m", Mass(m=100.0, b=2000.0))
    pos = c.add("pos", PositionSensor())
    c.connect(cyl.flange, "m.flange", pos.flange)
    pid = c.add("pid", PID(Kp=20.0, Ki=5.0, y_min=-1.0, y_max=1.0))
    c.connect(c.add("ref", Step(height=0.2)).y, pid.r)
    c.connect(pos.y, pid.m)
    c.connect(pid.y, sv.i)
    op = steady_state(c.compile())
    assert op["m.flange.x"] == pytest.approx(0.2, abs=1e-12)
    assert op["cyl.B.p"] == pytest.approx(2.0 * op["cyl.A.p"], rel=1e-9)  # p_A A_A = p_B A_B
    sol = simulate(c, 20.0, rtol=1e-8, t_eval=[0.5, 20.0])
    assert sol["pid.y"].max() <= 1.0 + 1e-7
    assert sol["m.flange.x"][-1] == pytest.approx(0.2, abs=1e-4)


def _flow_divider(inertia):
    """20 L/min into two 10 cm^3/rev motors on one shaft, each out through its own orifice."""
    from pvgraph.components import HydraulicMotor
    c = Circuit("divider")
    n = c.add("n", VolumeNode(V="0.1 L"))
    c.connect(c.add("src", FlowSource(Q="20 L/min")).port, n.port)
    t = c.add("t", Tank())
    for k, area in ((1, "5 mm^2"), (2, "10 mm^2")):
        m = c.add(f"m{k}", HydraulicMotor(D="10 cm^3/rev", eta_v=1.0, eta_hm=1.0))
        v = c.add(f"v{k}", VolumeNode(V="0.1 L"))
        o = c.add(f"o{k}", Orifice(A=area))
        c.connect(n.port, m.A)
        c.connect(m.B, v.port, o.a)
        c.connect(o.b, t.port)
    shaft = ["m1.shaft", "m2.shaft"]
    if inertia:
        shaft.append(c.add("j", Inertia(J=1e-2)).shaft)
    c.connect(*shaft)
    return c


def test_rotary_flow_divider_splits_evenly_and_balances_the_pressures():
    """Ideal motors of one displacement on one shaft pass equal flows whatever their loads, and
    the shaft's torque balance sets the inlet at the mean of the outlets: q1 = q2 = 10 L/min,
    p_n = (p_1 + p_2) / 2 with p_k the orifice law's drop for 10 L/min."""
    from pvgraph.laws import orifice_flow, orifice_transition_pressure
    op = steady_state(_flow_divider(inertia=True).compile())
    q = 10.0 / 60e3
    assert op["o1.q"] == pytest.approx(q, rel=1e-9)
    assert op["o2.q"] == pytest.approx(q, rel=1e-9)
    p = {}
    for k, area in ((1, 5e-6), (2, 10e-6)):
        dp_t = orifice_transition_pressure(0.6, math.sqrt(4 * area / math.pi), 870.0, 3.2e-5,
                                           100.0)   # the Orifice's default transition
        p[k] = brentq(lambda dp: orifice_flow(0.6, area, dp, 870.0, dp_t) - q, 1.0, 1e8,
                      xtol=1e-9)
        assert op[f"v{k}.port.p"] == pytest.approx(p[k], rel=1e-9)
    assert op["n.port.p"] == pytest.approx(0.5 * (p[1] + p[2]), rel=1e-9)


def test_flow_divider_without_inertia_is_told_to_add_one():
    from pvgraph.errors import InitializationError
    with pytest.raises(InitializationError, match=r"the shaft joining m1.shaft, m2.shaft"
                                                  r".*Put an Inertia"):
        simulate(_flow_divider(inertia=False), 0.1)


@pytest.mark.parametrize("p_crack_bar", [20.0, 50.0])
@pytest.mark.parametrize("load", [None, 5e-6])
def test_flow_source_straight_into_a_back_pressure_check_valve(p_crack_bar, load):
    """20 L/min straight into a check valve cracking at 20 or 50 bar (no volume on the node),
    then to tank or through a 5 mm^2 orifice: the inlet sits where the valve's opening law
    passes the flow, over the load's drop. From the closed valve (its leakage's slope)
    Newton's first step overshoots a million times; steady_state and simulate get there."""
    from pvgraph.laws import orifice_flow
    Q, p_crack, dp_open, A = 20 / 60e3, p_crack_bar * 1e5, 1e5, 20e-6

    def valve_q(dp):
        s = min(max((dp - p_crack) / dp_open, 0.0), 1.0)
        return orifice_flow(0.6, 1e-12 + (A - 1e-12) * s * s * (3 - 2 * s), dp, 870.0, 1e3)

    p_load = 0.0
    c = Circuit("bp")
    c.add("src", FlowSource(Q="20 L/min"))
    c.add("chk", CheckValve(A=A, p_crack=p_crack, dp_open=dp_open))
    c.add("tank", Tank())
    c.connect("src.port", "chk.a")
    if load is None:
        c.connect("chk.b", "tank.port")
    else:
        c.add("load", Orifice(A=load, dp_t=1e4))
        c.connect("chk.b", "load.a")
        c.connect("load.b", "tank.port")
        p_load = brentq(lambda p: orifice_flow(0.6, load, p, 870.0, 1e4) - Q, 0.0, 1e9,
                        xtol=1e-6)
    hand = p_load + brentq(lambda dp: valve_q(dp) - Q, p_crack, p_crack + dp_open, xtol=1e-6)
    op = steady_state(c.compile())
    assert op["src.port.p"] == pytest.approx(hand, rel=1e-9)
    sol = simulate(c, 0.01)
    assert sol.final("src.port.p") == pytest.approx(hand, rel=1e-9)


def _clamp(x0, b):
    """10 bar on the cap side of a 20/10 cm^2 cylinder, the rod on a 10 kg mass."""
    c = Circuit("clamp")
    c.add("ps", PressureSource(p0="10 bar"))
    c.add("t", Tank())
    c.add("cyl", Cylinder(A_A="20 cm^2", A_rod="10 cm^2", stroke="0.5 m", V_dead_A="0.05 L",
                          V_dead_B="0.05 L"))
    c.add("m", Mass(m=10.0, x0=x0, b=b))
    c.connect("ps.port", "cyl.A")
    c.connect("cyl.B", "t.port")
    c.connect("cyl.flange", "m.flange")
    return c


@pytest.mark.parametrize("x0", [0.2, 0.45, 0.5])
def test_steady_state_of_a_rod_pressed_onto_its_end_stop(x0):
    """The rod comes to rest on the stop with the stop carrying A_A p = 2000 N: x = stroke +
    F/k_stop + eps_stop/2 (the cylinder's stop law), from a start anywhere in the stroke."""
    op = steady_state(_clamp(x0, b=1000.0).compile())
    assert op["m.flange.x"] == pytest.approx(0.5 + 2000.0 / 1e9 + 0.5e-6, abs=1e-12)
    assert op["cyl.F_stop"] == pytest.approx(2000.0, rel=1e-9)


def test_undamped_rod_pressed_onto_its_stop_is_told_how_to_start():
    from pvgraph.errors import InitializationError
    with pytest.raises(InitializationError, match=r"against an end stop .* start its mass at "
                                                  r"the stop \(x0\)"):
        steady_state(_clamp(0.2, b=0.0).compile())


def _extend_on_a_free_load():
    """A 10 cm^3/rev pump at 1500 rpm, 150 bar relief, a closed-centre 4/3 valve switched to
    P -> A at 0.1 s, a 50/35.4 mm cylinder on a free 50 kg load: the rod overruns its supply
    at the switch and chamber A cavitates for a moment."""
    from pvgraph.components import FixedDisplacementPump, SpeedSource, Step
    c = Circuit("machine")
    c.add("motor", SpeedSource(w0="1500 rpm"))
    c.add("pump", FixedDisplacementPump(D="10 cm^3/rev", eta_v=1.0))
    c.add("tank", Tank())
    c.add("line", VolumeNode(V="0.2 L"))
    c.add("relief", ReliefValve(p_crack="150 bar", A_s="20 mm^2", k="20 N/mm", x_max="2 mm",
                                w="10 mm", theta=math.pi / 2))
    c.add("valve", DirectionalValve43(A_max="20 mm^2"))
    c.add("cmd", Step(height=1.0, t_step=0.1))
    c.add("cyl", Cylinder(A_A="19.635 cm^2", A_rod="9.8175 cm^2", stroke="200 mm",
                          V_dead_A="20 cm^3", V_dead_B="20 cm^3"))
    c.add("load", Mass(m="50 kg", b="100 N s/m"))
    c.connect("motor.shaft", "pump.shaft")
    c.connect("pump.a", "tank.port", "relief.T", "valve.T")
    c.connect("pump.b", "line.port", "relief.P", "valve.P")
    c.connect("cmd.y", "valve.u")
    c.connect("valve.A", "cyl.A")
    c.connect("valve.B", "cyl.B")
    c.connect("cyl.flange", "load.flange")
    return c


@pytest.mark.parametrize("rtol", [2e-5, 8e-6, 5e-6, 1e-6])
def test_a_chamber_that_cavitates_for_a_moment_gives_one_result_at_any_tolerance(rtol):
    """At every tolerance the rod extends and rests on its 200 mm stop, with the line at the
    relief's pressure and the rod where the solution converges at rtol 1e-9 (116.78 mm at
    1 s; 110.49 mm while the cavity was a compliance of the whole chamber, which lost 12 of
    the 400 cm^3 fed as the chamber grew). A cavitating chamber's compliance that grew to
    1e3 /Pa once made chamber A swallow the pump's 15 L/min at 8e-6 and 5e-6: the rod never
    moved."""
    import warnings

    from pvgraph.errors import PlausibilityWarning
    system = _extend_on_a_free_load().compile()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PlausibilityWarning)    # the cavitation, by name
        sol = simulate(system, 3.0, rtol=rtol, t_eval=[1.0, 3.0])
    assert sol["cyl.flange.x"][0] == pytest.approx(0.11678, abs=4.5e-3)   # 0.3-3.9 mm off
    assert sol["cyl.flange.x"][1] == pytest.approx(0.2 + 1e-6 * 30, abs=5e-5)   # on the stop
    assert sol["line.port.p"][1] == pytest.approx(152.2373e5, rel=1e-4)


def _pump_into_a_free_rod(m="100 kg", b=2000.0):
    """20 L/min straight into a 50/28 mm cylinder (20 cm^3 dead volumes) on a mass, B to tank,
    from rest: the start kicks the mass ahead of its supply and chamber A cavitates."""
    from pvgraph.components import FlowSource
    c = Circuit("cyl")
    c.add("pump", FlowSource(Q="20 L/min"))
    c.add("cyl", Cylinder(A_A=math.pi * 0.05 ** 2 / 4, A_rod=math.pi * 0.028 ** 2 / 4,
                          stroke="300 mm", V_dead_A="20 cm^3", V_dead_B="20 cm^3"))
    c.add("m", Mass(m=m, b=b))
    c.add("t", Tank())
    c.connect("cyl.flange", "m.flange")
    c.connect("pump.port", "cyl.A")
    c.connect("cyl.B", "t.port")
    return c


@pytest.mark.parametrize("rtol, within", [(2e-5, 7e-3), (1e-5, 7e-3), (1e-6, 5e-4),
                                           (1e-7, 1e-4)])
def test_a_cavity_that_collapses_again_and_again_keeps_its_oil(rtol, within):
    """On 100 kg with little damping (zeta 0.009) chamber A's cavity collapses in impacts
    again and again; the rod cannot run ahead of the oil fed and ends at (Q t - oil
    compressed) / A_A = 169.76 mm at 1 s where the run converges (rtol 1e-9: 0.0003 cm^3 of
    333 unaccounted), closer the tighter the tolerance (the cavity hangs on the pressure's
    error). With the cavity a compliance of the whole chamber, at 2e-5 the rod reached its
    300 mm stop (370 cm^3 of oil made: a corrector root that kept the cavity open over a
    collapse), and the run converged to 168.33 mm (2.8 cm^3 lost)."""
    import warnings

    from pvgraph.errors import PlausibilityWarning
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PlausibilityWarning)    # the cavitation, by name
        sol = simulate(_pump_into_a_free_rod(), 1.0, rtol=rtol, t_eval=[0.5, 1.0])
    x = sol["m.flange.x"][1]
    # no further than the oil fed, to 2e-5 m (0.04 cm^3: rtol 1e-7 ends 1.0e-5 m past it,
    # with and without a restart at each cavity edge)
    assert x < 20 / 60e3 * 1.0 / (math.pi * 0.05 ** 2 / 4) + 2e-5
    assert x == pytest.approx(0.169764, abs=within)


def test_a_chamber_growing_while_it_cavitates_takes_no_oil_it_has_no_room_for():
    """500 kg on little damping: the start kicks the rod 100 mm ahead of its oil, the cavity
    refills by 0.8 s and the chamber fills again. The cavity was a compliance of the whole
    chamber volume, so as the chamber grew at the vapour pressure it took oil it had no room
    for: 79 of 333 cm^3 lost, the rod stopped at 136 mm and ran back at 0.07 m/s against the
    running pump. With the cavity a fraction of the volume (the oil fills the rest) the oil is
    where the rod says, A_A x >= Q t - compression at every moment (to 0.5 cm^3), and the
    rod keeps going."""
    import warnings

    from pvgraph.errors import PlausibilityWarning
    t = np.linspace(0.0, 1.0, 201)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PlausibilityWarning)
        sol = simulate(_pump_into_a_free_rod(m="500 kg", b=100.0), 1.0, rtol=1e-7, t_eval=t)
    A_A = math.pi * 0.05 ** 2 / 4
    beta = 7e8
    V_A = 20e-6 + A_A * sol["m.flange.x"]
    oil = 20 / 60e3 * t - V_A / beta * sol["cyl.A.p"]      # fed, less what compression holds
    void = A_A * sol["m.flange.x"] + 20e-6 - 20e-6 - oil
    assert np.min(void) > -0.5e-6                           # never less room than oil
    assert np.all(np.diff(sol["m.flange.x"][100:]) > -1e-6)  # the rod does not run back
    assert sol["m.flange.x"][-1] > 0.16


def test_a_pump_straight_into_a_counterbalance_check_lifts_its_load():
    """10 L/min straight (no volume) through a counterbalance valve's free-flow check into a
    cylinder lifting 1000 kg: no steady state exists to start from (the load moves), and the
    consistent start's Newton meets the closed check's flat leakage; limited steps get it
    there. The rod rises at Q/A_A with p_A = (m g + b v)/A_A."""
    c = Circuit("lift")
    c.add("src", FlowSource(Q="10 L/min"))
    c.add("cb", CounterbalanceValve(p_set="150 bar", A_max="15 mm^2", A_check="20 mm^2",
                                    ratio=3.0, p_check="5 bar"))
    c.add("cyl", Cylinder(A_A="20 cm^2", A_rod="10 cm^2", stroke=1.0, V_dead_A="0.05 L",
                          V_dead_B="0.05 L", p0_A="49 bar"))
    c.add("m", Mass(m=1000.0, g=-9.81, b=2e5, x0=0.2))
    c.add("t", Tank())
    c.connect("src.port", "cb.valve")
    c.connect("cb.load", "cyl.A")
    c.connect("cyl.B", "t.port", "cb.pilot")
    c.connect("cyl.flange", "m.flange")
    sol = simulate(c, 2.0, t_eval=[1.0, 2.0])
    v = 10 / 60e3 / 20e-4
    np.testing.assert_allclose(sol["m.v"], v, rtol=1e-6)
    np.testing.assert_allclose(sol["cyl.A.p"], (1000 * 9.81 + 2e5 * v) / 20e-4, rtol=1e-6)


def _valve_into_counterbalance(volume=None):
    """Pump, relief and hose, a 4/3 valve (centred until 0.5 s, then lowering) piped straight
    to a counterbalance valve holding 1000 kg on a 63/36 mm cylinder; ``volume``: a
    VolumeNode on the node between the valves (none: an algebraic pressure there)."""
    c = Circuit("cbv")
    pump, tank = c.add("pump", FlowSource(Q="10 L/min")), c.add("tank", Tank())
    rv = c.add("rv", ReliefValve(p_crack="200 bar", A_s="20 mm^2", k="20 N/mm", x_max="2 mm",
                                 w="5 mm"))
    hose = c.add("hose", VolumeNode(V="0.2 L"))
    valve = c.add("valve", DirectionalValve43(A_max="20 mm^2"))
    cmd = c.add("cmd", TimeTable(t=[0, 0.5, 0.52, 5], y=[0, 0, -1, -1]))
    cbv = c.add("cbv", CounterbalanceValve(p_set="60 bar", A_max="20 mm^2", A_check="20 mm^2",
                                           ratio=3))
    A_A, A_R = math.pi / 4 * 0.063 ** 2, math.pi / 4 * 0.036 ** 2
    cyl = c.add("cyl", Cylinder(A_A=A_A, A_rod=A_R, stroke="500 mm", V_dead_A="0.05 L",
                                V_dead_B="0.05 L"))
    load = c.add("load", Mass(m="1000 kg", g="-9.81 m/s^2", x0="400 mm", b="5 kN s/m"))
    c.connect(pump.port, hose.port, rv.P, valve.P)
    c.connect(valve.T, rv.T, tank.port)
    c.connect(cmd.y, valve.u)
    if volume is None:
        c.connect(valve.A, cbv.valve)
    else:
        node = c.add("node", VolumeNode(V=volume))
        c.connect(valve.A, node.port, cbv.valve)
    c.connect(cbv.load, cyl.A)
    c.connect(valve.B, cyl.B, cbv.pilot)
    c.connect(cyl.flange, load.flange)
    return c, Q_10 / (A_A - A_R)


Q_10 = 10.0 * LPM


@pytest.mark.filterwarnings("ignore")
def test_a_valve_piped_straight_into_a_counterbalance_valve_runs():
    """The node between a centred 4/3 valve and a closed counterbalance valve has no volume:
    its pressure is set by leaks until the free-flow check cracks, where Newton from the leak
    side jumps 1e14 Pa. The run goes on past it (the algebraic pressure solved with a line
    search a step further, nrescue > 0) and lowers the load at the speed of the circuit with a
    10 cm^3 volume on that node (the pump's flow into the annulus, Q / A_B, less the valve's
    hunting), within 2 %."""
    c, v_ideal = _valve_into_counterbalance()
    start = {"cyl.A.p": "31.5 bar"}
    sol = simulate(c, 1.5, rtol=1e-6, start=start)
    assert sol.stats.get("nrescue", 0) > 0
    speed = (sol.at("cyl.flange.x", 1.5) - sol.at("cyl.flange.x", 1.0)) / 0.5
    vol, _ = _valve_into_counterbalance("10 cm^3")
    ref = simulate(vol, 1.5, rtol=1e-6, start=start)
    ref_speed = (ref.at("cyl.flange.x", 1.5) - ref.at("cyl.flange.x", 1.0)) / 0.5
    assert speed == pytest.approx(ref_speed, rel=0.02)
    assert -v_ideal < speed < -0.9 * v_ideal


def test_a_run_past_a_rescue_says_it_may_have_left_the_circuits_solution():
    """The valve piped into the counterbalance valve, started from rest (no start value), has
    an algebraic pressure between valves with no volume. Either the run goes past a rescue
    and says it may follow another solution (with the cavitation's first hard floor it kept
    its load up at 0.398 m), lowering the load as the circuit with the advised 1 cm^3 on that
    node does, to 3 mm (this limit cycle's own spread at rtol 1e-6: 2.6 mm from its converged
    319.7 mm); or it stops naming that node and the volume it needs. Since the solver restarts
    at each cavity edge it stops, at t = 0.173 s."""
    import warnings

    from pvgraph.errors import PlausibilityWarning, SolverError
    c, _ = _valve_into_counterbalance()
    well_posed = simulate(_valve_into_counterbalance("1 cm^3")[0], 1.5)
    assert well_posed.final("cyl.flange.x") < 0.33              # lowered from 0.4 m
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        try:
            sol = simulate(c, 1.5, t_eval=[1.5])
        except SolverError as exc:
            assert "'valve.A.p' has no volume on its node" in str(exc)
            assert "A VolumeNode on that node" in str(exc)
            return
    told = [str(w.message) for w in seen if issubclass(w.category, PlausibilityWarning)]
    assert any("may follow another solution" in m and "a VolumeNode on that node" in m
               for m in told)
    assert sol.stats["nrescue"] >= 1
    assert sol.final("cyl.flange.x") == pytest.approx(well_posed.final("cyl.flange.x"),
                                                      abs=3e-3)
