"""Steady states of turning machines with more than one shaft: the shafts' common rotation
drifts at a steady rate while twists, gear constraints and torques hold constant values.

Closed forms: a torque T on inertia J1 joined to J2 (bearing friction b) turns both at
w = T / b; through two ideal rack-pinions (r1 on J1, r2 on J2) w1 = T / (b (r1/r2)^2),
w2 = w1 r1 / r2, rack force T / r1."""

import math

import numpy as np
import pytest

from pydantic import Field

import pvgraph.expr as E
from pvgraph import Circuit, Component, Mechanical, Params
from pvgraph.analysis import steady_state
from pvgraph.analysis.linearize import linearize, linearize_circuit
from pvgraph.components.mechanical import (Inertia, Mass, RackPinion, ShaftSpringDamper,
                                           TorqueSource)
from pvgraph.components.mechanical.rotational import Rotational
from pvgraph.errors import InitializationError

J1, J2, T, B = 0.1, 0.4, 2.0, 0.01
K_SH, D_SH = 100.0, 1.0
R1, R2 = 0.05, 0.02


def two_inertias(b=B, torque=T):
    c = Circuit("two")
    ts = c.add("ts", TorqueSource(T=torque))
    i1 = c.add("i1", Inertia(J=J1))
    i2 = c.add("i2", Inertia(J=J2, b=b))
    sh = c.add("sh", ShaftSpringDamper(k=K_SH, d=D_SH))
    c.connect(ts.shaft, i1.shaft, sh.a)
    c.connect(sh.b, i2.shaft)
    return c


def gears(k=None, d=50.0):
    c = Circuit("gears")
    ts = c.add("ts", TorqueSource(T=T))
    i1 = c.add("i1", Inertia(J=J1))
    i2 = c.add("i2", Inertia(J=J2, b=B))
    p1 = c.add("p1", RackPinion(r=R1))
    p2 = c.add("p2", RackPinion(r=R2, k=k, d=(d if k else 0.0)))
    c.connect(ts.shaft, i1.shaft, p1.shaft)
    c.connect(p1.flange, p2.flange)
    c.connect(p2.shaft, i2.shaft)
    return c


def test_two_inertias_on_an_elastic_shaft_turn_at_torque_over_friction():
    s = two_inertias().compile()
    op = steady_state(s)
    w = T / B                                                  # 200 rad/s
    assert op["i1.w"] == pytest.approx(w, rel=1e-9)
    assert op["i2.w"] == pytest.approx(w, rel=1e-9)
    k1, k2 = s.names.index("i1.shaft.phi"), s.names.index("i2.shaft.phi")
    assert op.yp[k1] == pytest.approx(w, rel=1e-9) and op.yp[k2] == pytest.approx(w, rel=1e-9)
    assert abs(op["sh.b.tau"]) == pytest.approx(T, rel=1e-9)    # the shaft carries T = b w
    assert op["i1.shaft.phi"] - op["i2.shaft.phi"] == pytest.approx(T / K_SH, rel=1e-9)
    # all other rates vanish: the speeds and the shaft torque are steady
    others = [j for j in range(s.n) if j not in (k1, k2)]
    assert np.all(op.yp[others] == 0.0)
    assert len(op.info["cyclic"]) == 1
    (drift,) = op.info["drift"]
    assert drift["i1.shaft.phi"] == pytest.approx(1.0, rel=1e-12)
    assert drift["i2.shaft.phi"] == pytest.approx(1.0, rel=1e-12)
    assert np.max(np.abs(s.residual(0.0, op.y, op.yp))) < 1e-9 * T


@pytest.mark.parametrize("k", [None, 1e6])
def test_gear_train_turns_at_the_reflected_friction(k):
    """Ideal gears (index-reduced: the state is der(i2.shaft.phi)) and compliant ones."""
    s = gears(k).compile()
    op = steady_state(s)
    w1 = T / (B * (R1 / R2) ** 2)                              # 32 rad/s
    assert op["i1.w"] == pytest.approx(w1, rel=1e-9)
    assert op["i2.w"] == pytest.approx(w1 * R1 / R2, rel=1e-9)
    assert op["p2.flange.f"] == pytest.approx(T / R1, rel=1e-9)      # 40 N on the rack
    assert op.yp[s.names.index("i1.shaft.phi")] == pytest.approx(w1, rel=1e-9)
    assert op.yp[s.names.index("i2.shaft.phi")] == pytest.approx(w1 * R1 / R2, rel=1e-9)
    (drift,) = op.info["drift"]
    ratio = drift["i1.shaft.phi"] / drift["i2.shaft.phi"]
    assert ratio == pytest.approx(R2 / R1, rel=1e-12)
    if k is None:
        assert op["der(i2.shaft.phi)"] == pytest.approx(w1 * R1 / R2, rel=1e-9)
        assert op["der(i2.w)"] == pytest.approx(0.0, abs=1e-9)
        assert R1 * op["i1.shaft.phi"] == pytest.approx(R2 * op["i2.shaft.phi"], abs=1e-12)
    else:                                   # the mesh is compressed by f / k
        gap = R1 * op["i1.shaft.phi"] - R2 * op["i2.shaft.phi"]
        assert abs(gap) == pytest.approx(T / R1 / k, rel=1e-9)


@pytest.mark.parametrize("k", [None, 1e7])
def test_a_pinion_driving_a_damped_rack_turns_and_moves_steadily(k):
    """Torque T on a pinion r, ideal mesh, rack mass with viscous b_m: T = r b_m v, v = r w."""
    r, bm = 0.05, 100.0
    c = Circuit("rack")
    ts = c.add("ts", TorqueSource(T=T))
    i = c.add("i", Inertia(J=J1))
    p = c.add("p", RackPinion(r=r, k=k, d=(20.0 if k else 0.0)))
    m = c.add("m", Mass(m=5.0, b=bm))
    c.connect(ts.shaft, i.shaft, p.shaft)
    c.connect(p.flange, m.flange)
    s = c.compile()
    op = steady_state(s)
    w = T / (bm * r * r)                                      # 8 rad/s
    assert op["i.w"] == pytest.approx(w, rel=1e-9)
    assert op["m.v"] == pytest.approx(r * w, rel=1e-9)
    coef, idx, _ = s.resolve("m.flange.x")           # the rack position drifts at r w
    assert coef * op.yp[idx] == pytest.approx(r * w, rel=1e-9)
    assert op["m.flange.f"] == pytest.approx(bm * r * w, rel=1e-9)     # 40 N = b_m v
    assert op["p.flange.f"] == pytest.approx(-bm * r * w, rel=1e-9)
    if k is not None:      # the rack position is an unknown of its own, drifting with phi
        (drift,) = op.info["drift"]
        assert drift["m.flange.x"] / drift["i.shaft.phi"] == pytest.approx(r, rel=1e-12)
        gap = op["m.flange.x"] - r * op["i.shaft.phi"]
        assert gap == pytest.approx(-T / r / k, rel=1e-9)          # mesh force T / r


def test_steady_speed_sensitivity_to_the_torque_is_one_over_friction():
    op = steady_state(two_inertias().compile())
    sens = op.sensitivity(["i1.w", "i2.w", "sh.b.tau"], ["ts.T"])[:, 0]
    assert sens[0] == pytest.approx(1.0 / B, rel=1e-9)
    assert sens[1] == pytest.approx(1.0 / B, rel=1e-9)
    assert abs(sens[2]) == pytest.approx(1.0, rel=1e-9)


def test_two_inertia_linear_model_has_the_closed_form_poles():
    """State [twist, w1, w2]: twist' = w1 - w2, J1 w1' = -k twist - d (w1 - w2),
    J2 w2' = k twist + d (w1 - w2) - b w2; the common angle (a zero pole) is left out."""
    s = two_inertias().compile()
    op = steady_state(s)
    model = linearize(s, op, None, ["i1.w", "i2.w"])
    A = np.array([[0.0, 1.0, -1.0],
                  [-K_SH / J1, -D_SH / J1, D_SH / J1],
                  [K_SH / J2, D_SH / J2, -(D_SH + B) / J2]])
    want = np.sort_complex(np.linalg.eigvals(A))
    got = np.sort_complex(model.poles())
    assert len(got) == 3
    np.testing.assert_allclose(got, want, rtol=1e-9)
    assert sorted(model.state_names) == sorted(
        ["i1.w", "i2.w", "i2.shaft.phi - i1.shaft.phi"])


@pytest.mark.parametrize("k", [None, 1e6])
def test_gear_train_linear_model_poles(k):
    s = gears(k).compile()
    op = steady_state(s)
    model = linearize(s, op, None, ["i1.w"])
    if k is None:                 # one inertia J2 + J1 (r2/r1)^2 against b
        (pole,) = model.poles()
        assert pole.real == pytest.approx(-B / (J2 + J1 * (R2 / R1) ** 2), rel=1e-9)
        assert pole.imag == 0.0
        return
    d = 50.0
    # q = r1 phi1 - r2 phi2 (mesh compression), f = k q + d q'
    A = np.array([[0.0, R1, -R2],
                  [-R1 * k / J1, -R1 * R1 * d / J1, R1 * R2 * d / J1],
                  [R2 * k / J2, R2 * R1 * d / J2, -(R2 * R2 * d + B) / J2]])
    want = np.sort_complex(np.linalg.eigvals(A))
    got = np.sort_complex(model.poles())
    assert len(got) == 3
    np.testing.assert_allclose(got, want, rtol=1e-9)


def test_an_output_reading_the_angle_keeps_the_drift_state():
    s = two_inertias().compile()
    op = steady_state(s)
    model = linearize(s, op, None, ["i1.shaft.phi"])
    assert len(model.state_names) == 4
    assert np.min(np.abs(model.poles())) < 1e-9 * np.max(np.abs(model.poles()))


def test_a_torque_on_inertias_without_friction_has_no_steady_state():
    c = Circuit("one")
    ts = c.add("ts", TorqueSource(T=T))
    i = c.add("i", Inertia(J=J1))
    c.connect(ts.shaft, i.shaft)
    with pytest.raises(InitializationError, match=r"no steady value of i\.w") as err:
        steady_state(c.compile())
    assert "a torque on a free inertia" in str(err.value)
    with pytest.raises(InitializationError, match="no steady state found"):
        steady_state(two_inertias(b=0.0).compile())


def test_linearize_circuit_gives_the_speed_gain_of_the_torque():
    """d w / d T = 1 / b in steady state, through the spring: DC gain 100 rad/s per N m."""
    model = linearize_circuit(lambda u: two_inertias(torque=u["T"]), {"T": T},
                              ["i1.w", "i2.w"])
    np.testing.assert_allclose(model.dc_gain()[:, 0], [1.0 / B, 1.0 / B], rtol=1e-6)
    assert len(model.poles()) == 3 and np.all(model.poles().real < 0.0)


class CrankParams(Params):
    r: float = Field(..., gt=0.0, description="Crank radius [m]")


class Crank(Component):
    """Ideal crank ``x = r sin(phi)``: the slider oscillates, so the shaft cannot turn at a
    steady speed (the torque it takes varies with the angle)."""

    Params = CrankParams
    ports = {"shaft": Rotational("crank shaft"), "flange": Mechanical("slider")}

    def equations(self, v, p):
        return [v.flange.x - p.r * E.sin(v.shaft.phi),
                v.shaft.tau + p.r * E.cos(v.shaft.phi) * v.flange.f]


def test_a_crank_is_no_drift_direction():
    """The angle enters through sin(phi): turning it changes F, so no steady state exists."""
    c = Circuit("crank")
    ts = c.add("ts", TorqueSource(T=0.5))
    i = c.add("i", Inertia(J=0.01, b=0.01))
    cr = c.add("cr", Crank(r=0.1))
    m = c.add("m", Mass(m=2.0, b=10.0))
    c.connect(ts.shaft, i.shaft, cr.shaft)
    c.connect(cr.flange, m.flange)
    with pytest.raises(InitializationError, match="no steady state found"):
        steady_state(c.compile())


def test_a_crank_turns_through_its_dead_centres_and_starts_from_its_slider():
    """x = r sin(phi): the angle stays the state (the slider's position turns back at the dead
    centres, where it could not be one), so a torque keeps the crank turning; a slider start
    x0 = 0.05 m given moves the angle to a consistent one, r sin(phi) = x0 (phi = pi/6)."""
    from pvgraph.simulate import simulate
    c = Circuit("crank")
    ts = c.add("ts", TorqueSource(T=0.5))
    i = c.add("i", Inertia(J=0.01, b=0.01))
    cr = c.add("cr", Crank(r=0.1))
    m = c.add("m", Mass(m=2.0, b=10.0, x0=0.05))
    c.connect(ts.shaft, i.shaft, cr.shaft)
    c.connect(cr.flange, m.flange)
    s = c.compile()
    assert {"i.shaft.phi", "i.w"} <= {n for n, d in zip(s.names, s.differential) if d}
    sol = simulate(s, 3.0, rtol=1e-7)
    assert sol["m.flange.x"][0] == pytest.approx(0.05, abs=1e-9)
    assert sol["i.shaft.phi"][0] == pytest.approx(math.pi / 6, abs=1e-8)
    assert sol.final("i.shaft.phi") > 4 * math.pi          # past several dead centres
    # the constraint holds to the Newton tolerance of the algebraic position
    assert np.max(np.abs(sol["m.flange.x"] - 0.1 * np.sin(sol["i.shaft.phi"]))) < 1e-6


class SliderCrankParams(Params):
    r: float = Field(..., gt=0.0, description="Crank radius [m]")
    l: float = Field(..., gt=0.0, description="Rod length [m]")


class SliderCrank(Component):
    """x = r cos(phi) + sqrt(l^2 - r^2 sin^2 phi): top dead centre at phi = 0."""

    Params = SliderCrankParams
    ports = {"shaft": Rotational("crank"), "flange": Mechanical("slider")}

    def equations(self, v, p):
        s, c = E.sin(v.shaft.phi), E.cos(v.shaft.phi)
        root = E.sqrt(p.l ** 2 - p.r ** 2 * s * s)
        return [v.flange.x - (p.r * c + root),
                v.shaft.tau + (-p.r * s - p.r ** 2 * s * c / root) * v.flange.f]


@pytest.mark.parametrize("rod, phi", [(0.22, 0.844641), (0.3, math.pi)])
def test_a_slider_held_at_its_start_moves_the_crank_to_the_nearest_angle(rod, phi):
    """Slider built at x0 = 0.25 m = r + l (top dead centre, r = 0.05, l = 0.2), the rod made
    longer at run time: the slider stays, the crank turns to the nearest angle with
    r cos(phi) + sqrt(l^2 - r^2 sin^2 phi) = 0.25 (0.8446 rad for l = 0.22, the bottom dead
    centre pi for l = 0.3), not whole turns beyond."""
    from pvgraph.simulate import simulate
    c = Circuit("sc")
    i = c.add("i", Inertia(J=0.01))
    sc = c.add("sc", SliderCrank(r=0.05, l=0.2))
    m = c.add("m", Mass(m=1.0, x0=0.25))
    c.connect(i.shaft, sc.shaft)
    c.connect(sc.flange, m.flange)
    sol = simulate(c.compile(), 1e-4, params={"sc.l": rod})
    assert sol["m.flange.x"][0] == pytest.approx(0.25, abs=1e-9)
    assert sol["i.shaft.phi"][0] == pytest.approx(phi, abs=1e-3)


class DrumParams(Params):
    r: float = Field(..., gt=0.0, description="Radius [m]")
    e: float = Field(0.0, ge=0.0, description="Eccentricity [m]")


class Drum(Component):
    """A cable drum with a slight eccentricity: x = r phi + e sin(phi)."""

    Params = DrumParams
    ports = {"shaft": Rotational("drum"), "flange": Mechanical("cable end")}

    def equations(self, v, p):
        return [v.flange.x - (p.r * v.shaft.phi + p.e * E.sin(v.shaft.phi)),
                v.shaft.tau + (p.r + p.e * E.cos(v.shaft.phi)) * v.flange.f]


@pytest.mark.parametrize("x", [1.0, 5.0])
def test_a_cable_start_far_out_winds_the_drum_on(x):
    """x = 0.01 phi + 0.001 sin(phi) started at x = 1 m or 5 m: the drum turns to the root
    (about 100 and 500 rad), the steps towards it growing as they are taken whole."""
    from scipy.optimize import brentq

    from pvgraph.simulate import simulate
    c = Circuit("drum")
    j = c.add("J", Inertia(J=0.01))
    d = c.add("d", Drum(r=0.01, e=0.001))
    m = c.add("m", Mass(m=2.0))
    c.connect(j.shaft, d.shaft)
    c.connect(d.flange, m.flange)
    want = brentq(lambda ph: 0.01 * ph + 0.001 * math.sin(ph) - x, 0.0, 1e4)
    sol = simulate(c.compile(), 1e-6, start={"m.flange.x": x})
    assert sol["m.flange.x"][0] == pytest.approx(x, abs=1e-9)
    assert sol["J.shaft.phi"][0] == pytest.approx(want, abs=1e-6)
