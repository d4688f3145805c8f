"""Runtime parameters: one compiled system runs with other parameter values, against analytic
results and against systems compiled with those values; structural parameters are named and
recompiled (or refused); dF/dp and steady-state sensitivities match finite differences."""

import math
import warnings

import numpy as np
import pytest

from pvgraph.components import FlowSource, LaminarOrifice, Orifice, PressureSource, Tank, VolumeNode
from pvgraph import Circuit
from pvgraph.analysis import calibrate, steady_state
from pvgraph.errors import ParameterError
from pvgraph.simulate import simulate
from pvgraph.system import RecompileWarning
from pvgraph.units import bar, litre, lpm, lpm_per_bar, mm2

from test_compiler import BETA, K, Q, V, demo


def turbulent_bench(p_s=bar(100), A=mm2(3.0), K_load=lpm_per_bar(0.25)):
    """Pressure source -> orifice A -> node -> laminar K -> tank."""
    c = Circuit("bench")
    src = c.add("src", PressureSource(p0=p_s))
    orf = c.add("orifice", Orifice(A=A, rho=870.0))
    node = c.add("node", VolumeNode(V=1e-4))
    lam = c.add("load", LaminarOrifice(K=K_load))
    tank = c.add("tank", Tank())
    c.connect(src.port, orf.a)
    c.connect(orf.b, node.port, lam.a)
    c.connect(lam.b, tank.port)
    return c


def test_parameters_carry_values_units_and_descriptions():
    s = demo().compile()
    info = s.parameters["orifice.K"]
    assert info.value == pytest.approx(K) and info.unit == "m^3/(s Pa)"
    assert info.description == LaminarOrifice.Params.model_fields["K"].description
    assert s.parameter_values["pump.Q"] == pytest.approx(Q)
    assert not info.structural and info.in_equations


def test_runtime_value_gives_the_analytic_transient_without_compiling():
    """V/beta dp/dt = Q - K p with another K and V: p(t) = Q/K (1 - exp(-t/tau))."""
    s = demo().compile()
    K2, V2 = 2.0 * K, 0.5 * V
    tau = V2 / (BETA * K2)
    t = np.linspace(0.0, 5 * tau, 11)
    sol = simulate(s, 5 * tau, rtol=1e-8, t_eval=t, params={"orifice.K": K2, "node.V": V2})
    exact = Q / K2 * (1.0 - np.exp(-t / tau))
    assert np.max(np.abs(sol["node.port.p"] - exact)) < 1e-5 * Q / K2
    assert sol.system.parameter_values["orifice.K"] == K2
    assert s.parameter_values["orifice.K"] == pytest.approx(K)   # the original is untouched
    # derived outputs see the new value: the orifice carries K2 * p
    assert sol["orifice.q"][-1] == pytest.approx(K2 * sol["node.port.p"][-1], rel=1e-12)


def test_with_params_matches_a_system_compiled_with_those_values():
    s = turbulent_bench().compile()
    moved = s.with_params({"orifice.A": mm2(5.0), "src.p0": bar(150), "load.K":
                           lpm_per_bar(0.4)})
    fresh = turbulent_bench(bar(150), mm2(5.0), lpm_per_bar(0.4)).compile()
    rng = np.random.default_rng(2)
    y = fresh.y0 + fresh.nominal * rng.uniform(0.1, 1.0, fresh.n)
    yp = fresh.nominal * rng.normal(size=fresh.n)
    assert moved.names == fresh.names
    np.testing.assert_allclose(moved.residual(0.0, y, yp), fresh.residual(0.0, y, yp),
                               rtol=1e-13, atol=0.0)
    np.testing.assert_allclose(moved.jacobian_values(0.0, y, yp, 30.0),
                               fresh.jacobian_values(0.0, y, yp, 30.0), rtol=1e-13, atol=0.0)
    # the source pressure is an eliminated alias with a runtime value
    assert moved.resolve("src.port.p") == (0.0, None, bar(150))


def test_steady_state_with_params_is_the_closed_form():
    """Laminar drain: p = Q / K for any K, no compilation."""
    s = demo().compile()
    for K2 in (0.5 * K, 3.0 * K):
        op = steady_state(s, params={"orifice.K": K2}, tol=1e-12)
        assert op["node.port.p"] == pytest.approx(Q / K2, rel=1e-10)


def test_start_values_follow_their_parameters():
    c = demo()
    c._components["node"]._start.clear()
    s = c.compile()
    moved = s.with_params({"node.p0": bar(7)})
    assert moved.y0[moved.index["node.port.p"]] == pytest.approx(bar(7))
    assert s.y0[s.index["node.port.p"]] == 0.0


def test_unknown_parameter_suggests_close_names():
    s = demo().compile()
    with pytest.raises(ParameterError, match=r"orifice\.K"):
        s.with_params({"orifice.k": 1e-10})
    with pytest.raises(ParameterError, match="no parameter named 'nothing.at_all'"):
        simulate(s, 1.0, params={"nothing.at_all": 1.0})


def test_parameter_values_are_a_mapping_or_name_value_pairs_everywhere():
    """with_params, Circuit.set_parameters, simulate and steady_state take a mapping or a list
    of (name, value) pairs alike; one name, a list of names or None is refused by name (a
    dict() ValueError or an AttributeError before), and recompile= must be a bool (any
    truthy value meant True)."""
    s = demo().compile()
    by_pairs = s.with_params([("orifice.K", 2 * K)])
    assert by_pairs.parameter_values["orifice.K"] == 2 * K
    c = demo()
    c.set_parameters([("orifice.K", 3 * K)])
    assert c.compile().parameter_values["orifice.K"] == 3 * K
    assert steady_state(s, params=[("orifice.K", 2 * K)], tol=1e-12)["node.port.p"] == \
        pytest.approx(Q / (2 * K), rel=1e-9)
    for bad in (["orifice.K"], "orifice.K=1e-10", [("orifice.K", 1.0, 2.0)]):
        with pytest.raises(ParameterError, match="with_params values must be a mapping"):
            s.with_params(bad)
        with pytest.raises(ParameterError, match="set_parameters: values must be a mapping"):
            c.set_parameters(bad)
    with pytest.raises(ParameterError, match="set_parameters: values must be a mapping.*None"):
        c.set_parameters(None)
    with pytest.raises(ParameterError, match="check_parameters: values must be a mapping"):
        c.check_parameters(["orifice.K"])
    with pytest.raises(ParameterError, match="simulate: params must be a mapping"):
        simulate(s, 1.0, params=["orifice.K"])
    with pytest.raises(ParameterError, match=r"recompile=...\) takes True or False, got 'no'"):
        s.with_params({"orifice.K": 2 * K}, recompile="no")
    # a name twice in the pairs (a generated table): refused, where the last one won silently
    twice = [("orifice.K", 2 * K), ("orifice.K", 3 * K)]
    with pytest.raises(ParameterError, match=r"steady_state: params: parameters given twice: "
                                             r"\['orifice.K'\]"):
        steady_state(s, params=twice)
    with pytest.raises(ParameterError, match="given twice"):
        simulate(s, 1.0, params=twice)


def test_invalid_value_is_rejected_by_the_parameter_model():
    s = demo().compile()
    with pytest.raises(ParameterError, match="orifice"):
        s.with_params({"orifice.K": -1.0})


def test_structural_parameter_recompiles_with_a_warning_or_is_refused():
    """VolumeNode compares ``air`` with zero in Python: changing it changes the equations."""
    s = demo().compile()
    assert "compared with ==" in s.parameters["node.air"].structural
    with pytest.raises(ParameterError, match=r"node\.air"):
        s.with_params({"node.air": 0.01}, recompile=False)
    with pytest.warns(RecompileWarning, match=r"node\.air"):
        moved = s.with_params({"node.air": 0.01, "orifice.K": 2 * K})
    assert moved.parameter_values["node.air"] == 0.01
    assert moved.parameter_values["orifice.K"] == 2 * K
    # the steady state does not depend on the compressibility: p = Q / K
    assert steady_state(moved, tol=1e-12)["node.port.p"] == pytest.approx(Q / (2 * K), rel=1e-9)
    assert s.parameters["node.air"].value == 0.0          # the original circuit is unchanged


def test_params_from_reads_a_rebuilt_circuit_and_refuses_structure():
    s = turbulent_bench().compile()
    values = s.params_from(turbulent_bench(bar(80), mm2(4.0)))
    assert values == {"src.p0": bar(80), "orifice.A": mm2(4.0)}
    other = turbulent_bench()
    other._components["node"] = VolumeNode(V=1e-4, air=0.02)
    with pytest.raises(ParameterError, match=r"node\.air"):
        s.params_from(other)


def test_parameter_jacobian_matches_finite_differences():
    s = turbulent_bench().compile()
    rng = np.random.default_rng(5)
    y = s.y0 + s.nominal * rng.uniform(0.2, 2.0, s.n)
    yp = s.nominal * rng.normal(size=s.n)
    names = ["orifice.A", "orifice.Cd", "orifice.rho", "load.K", "node.V", "src.p0"]
    J = s.parameter_jacobian(0.0, y, yp, names)
    for k, nm in enumerate(names):
        v = s.parameters[nm].value
        h = 1e-6 * abs(v)
        up = s.with_params({nm: v + h}).residual(0.0, y, yp)
        down = s.with_params({nm: v - h}).residual(0.0, y, yp)
        fd = (up - down) / (2 * h)
        np.testing.assert_allclose(J[:, k], fd, rtol=1e-6, atol=1e-9 * np.max(np.abs(fd)))


def test_steady_sensitivity_is_the_closed_form_and_matches_resolving():
    """Laminar drain: p = Q/K, so dp/dK = -Q/K^2 and dp/dQ = 1/K exactly."""
    s = demo().compile()
    op = steady_state(s, tol=1e-12)
    S = op.sensitivity(["node.port.p", "orifice.q"], ["orifice.K", "pump.Q", "node.V"])
    assert S[0, 0] == pytest.approx(-Q / K**2, rel=1e-10)
    assert S[0, 1] == pytest.approx(1.0 / K, rel=1e-10)
    assert S[0, 2] == 0.0                                    # a volume sets no steady value
    assert S[1, 0] == pytest.approx(0.0, abs=1e-12)          # all the pump flow drains
    assert S[1, 1] == pytest.approx(1.0, rel=1e-10)
    # the turbulent bench against re-solved steady states
    s = turbulent_bench().compile()
    op = steady_state(s, tol=1e-13)
    names = ["orifice.A", "load.K", "src.p0"]
    S = op.sensitivity(["node.port.p", "load.a.q"], names)
    for k, nm in enumerate(names):
        v = s.parameters[nm].value
        h = 1e-5 * v
        up = steady_state(s, params={nm: v + h}, tol=1e-13, y0=op.y)
        down = steady_state(s, params={nm: v - h}, tol=1e-13, y0=op.y)
        for j, out in enumerate(["node.port.p", "load.a.q"]):
            fd = (up[out] - down[out]) / (2 * h)
            assert S[j, k] == pytest.approx(fd, rel=1e-6)


SUPPLIES = [bar(v) for v in (20, 60, 120, 200, 250)]


def test_calibration_with_exact_sensitivities_agrees_with_finite_differences():
    """The same fit with the model's steady-state sensitivities and with finite differences:
    estimates agree to 1e-3 of the interval half-width, standard errors to 1 %."""
    system = turbulent_bench().compile()
    A_true, K_true = mm2(3.0), lpm_per_bar(0.25)
    rng = np.random.default_rng(4)

    class Model:
        def __init__(self):
            self.warm = None

        def ops(self, theta):
            out = []
            for ps in SUPPLIES:
                op = steady_state(system, params={"src.p0": ps, "orifice.A": theta["A"],
                                                  "load.K": theta["K"]}, tol=1e-13)
                out.append(op)
            return out

        def __call__(self, theta):
            return np.array([op["node.port.p"] / 1e5 for op in self.ops(theta)])

        def jacobian(self, theta):
            return np.array([op.sensitivity(["node.port.p"], ["orifice.A", "load.K"])[0] / 1e5
                             for op in self.ops(theta)])

    model = Model()
    y = model({"A": A_true, "K": K_true}) + rng.normal(0.0, 0.3, len(SUPPLIES))
    params = {"A": (mm2(2.0), mm2(0.5), mm2(20.0)), "K": (lpm_per_bar(0.4), lpm_per_bar(0.05),
                                                          lpm_per_bar(2.0))}
    exact = calibrate(model, y, params, sigma=0.3, absolute_sigma=True, xtol=1e-10,
                      ftol=1e-10)
    fd = calibrate(model.__call__, y, params, sigma=0.3, absolute_sigma=True, xtol=1e-10,
                   ftol=1e-10)
    assert exact.njev > 0 and fd.njev == 0
    half = (fd.ci_high - fd.ci_low) / 2
    assert np.all(np.abs(exact.estimates - fd.estimates) < 1e-3 * half)
    np.testing.assert_allclose(exact.std_errors, fd.std_errors, rtol=1e-2)
    for name, true in (("A", A_true), ("K", K_true)):
        lo, hi = exact.interval(name)
        assert lo < true < hi


def test_trace_time_math_on_parameters_stays_symbolic():
    """The orifice computes sqrt(2/rho) and its transition pressure with math.*: still runtime."""
    s = turbulent_bench().compile()
    for nm in ("orifice.A", "orifice.rho", "orifice.Cd"):
        assert not s.parameters[nm].structural, nm
    assert math.sqrt(4.0) == 2.0           # math is itself again after compiling


def test_events_are_evaluated_together_and_follow_runtime_parameters():
    """Three sources switching on at 0.1, 0.2, 0.3 s: each event fires at its time, every
    evaluation of the events is one call of the generated function, and a runtime change of a
    switching time moves its event."""
    from test_simulate import SwitchedSource
    c = Circuit("switched")
    node = c.add("node", VolumeNode(V=V))
    srcs = [c.add(f"src{k}", SwitchedSource(t_step=0.1 * (k + 1), Q=Q / 3)) for k in range(3)]
    orf = c.add("orifice", LaminarOrifice(K=K))
    c.connect(node.port, orf.a, *[s.port for s in srcs])
    c.connect(orf.b, c.add("tank", Tank()).port)
    system = c.compile()
    calls = [0]
    generated = system._event_fn

    def counting(*args):
        calls[0] += 1
        return generated(*args)
    system._event_fn = counting
    sol = simulate(system, 0.4, rtol=1e-8)
    assert [round(e.t, 9) for e in sol.events] == [0.1, 0.2, 0.3]
    # a call per point for all three events, plus one per root-finding iterate: well under one
    # call per event per point
    assert calls[0] < 0.6 * sol.stats["nroot"]
    moved = simulate(system, 0.4, rtol=1e-8, params={"src1.t_step": 0.25})
    assert [round(e.t, 9) for e in moved.events] == [0.1, 0.25, 0.3]
