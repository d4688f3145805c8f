"""The BDF step in C (pvgraph.solver.cstep) against the Python step, its oracle.

Both steps must take the same steps and give the same numbers bit for bit: every comparison
is ``np.array_equal`` / ``==`` on the solver statistics and outputs. Needs a C compiler
(skipped without one).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from pydantic import Field

from pvgraph import Circuit, Component, Params, cbackend
from pvgraph import expr as E
from pvgraph.component import Variable, der
from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
from pvgraph.errors import SolverError
from pvgraph.simulate import simulate
from pvgraph.solver import cstep, solve_dae
from pvgraph.units import litre, lpm, mm2

pytestmark = pytest.mark.skipif(cbackend.c_compiler() is None, reason="no C compiler")


@pytest.fixture(autouse=True)
def _cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("PVGRAPH_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "pv-c-cache"))


@pytest.fixture
def c_steps(monkeypatch):
    """Counts the steps the C kernel takes (one at a time, or in the loop in C)."""
    count = {"n": 0}
    step, advance = cstep.CStepIntegrator.step, cstep.CStepIntegrator.advance

    def counted(self):
        count["n"] += 1
        return step(self)

    def counted_advance(self, run):
        before = self.nst
        try:
            return advance(self, run)
        finally:
            count["n"] += self.nst - before

    monkeypatch.setattr(cstep.CStepIntegrator, "step", counted)
    monkeypatch.setattr(cstep.CStepIntegrator, "advance", counted_advance)
    return count


def both(run):
    """(Python step, C step) results of ``run(c_step)``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")      # the rig's cavitation notes
        return run(False), run(None)


def assert_identical(a, b):
    assert a.stats == b.stats
    assert np.array_equal(a.t, b.t)
    assert np.array_equal(a.y, b.y)
    assert np.array_equal(a.yp, b.yp)
    assert [(e.t, e.name) for e in a.events] == [(e.t, e.name) for e in b.events]


def test_the_kernel_loads_and_its_blas_is_numpys():
    # the load runs the self-check: ddot / daxpy / dgemv give np.dot's numbers on random data
    assert cstep.kernel() is not None, cstep.kernel_error()


def _pump_volume_orifice():
    """A 10 l/min pump into 0.5 l and a 2 mm^2 orifice to tank."""
    c = Circuit("pvo")
    node = c.add("node", VolumeNode(V=litre(0.5)))
    o = c.add("o", Orifice(A=mm2(2.0)))
    c.connect(c.add("pump", FlowSource(Q=lpm(10))).port, node.port, o.a)
    c.connect(o.b, c.add("tank", Tank()).port)
    return c


def test_pump_volume_orifice_step_input(c_steps):
    # a 10 l/min pump switched on at t = 0 (from p = 0) into 0.5 l and a 2 mm^2 orifice:
    # the pressure settles where the orifice passes the pump flow, Q = Cd A sqrt(2 dp / rho)
    s = _pump_volume_orifice().compile(backend="c")
    a, b = both(lambda cs: simulate(s, 2.0, rtol=1e-7, c_step=cs))
    assert_identical(a, b)
    assert c_steps["n"] == b.stats["nsteps"] > 50
    P = s.parameters
    dp = b["o.dp"][-1]
    assert b["o.q"][-1] == pytest.approx(lpm(10), rel=1e-5)
    assert lpm(10) == pytest.approx(P["o.Cd"].value * mm2(2.0) * math.sqrt(
        2 * dp / P["o.rho"].value), rel=3e-3)
    # every internal step output, and the dense output between steps
    a, b = both(lambda cs: solve_dae(s.residual, (0.0, 0.05), s.y0, s.yp0, rtol=1e-6,
                                     jac=s.solver_jacobian(), jac_sparsity=s.jac_sparsity,
                                     algebraic=s.algebraic, dense_output=True, c_step=cs))
    assert_identical(a, b)
    t = np.linspace(0.0, 0.05, 97)
    assert np.array_equal(a.sol(t), b.sol(t))


@pytest.fixture(scope="module")
def rig():
    from pvgraph.circuits.pvg32.parameters import report_tuned
    from pvgraph.circuits.rig import build_rig, laminar_load
    p = report_tuned()
    return build_rig(p, load=laminar_load(p, L1="small", L3="small", t_switch=0.01),
                     U_input=4.24).compile(backend="c")


def test_mixed_matrices_of_a_compiled_jacobian_on_its_entries(rig):
    # the initialisation's matrices (column j: dF/dy_j or dF/dy'_j) built from the
    # Jacobian's entries are the dense formula's bit for bit, on both routes
    from pvgraph.solver.linalg import JacobianEvaluator
    rng = np.random.default_rng(3)
    y = rig.y0 * (1.0 + 0.01 * rng.standard_normal(rig.n))
    yp = rng.standard_normal(rig.n)
    for s in (rig, rig.with_params({}).use_backend("python")):
        jac = JacobianEvaluator(s.residual, s.n, s.jacobian_dense, s.jac_sparsity)
        for _ in range(3):
            cy = (rng.random(s.n) < 0.5).astype(float)
            cyp = 1.0 - cy
            fast = jac.mixed_matrix(0.1, y, yp, None, cy, cyp, np.ones(s.n))
            j0, j1 = s.jacobian_dense(0.1, y, yp, 0.0), s.jacobian_dense(0.1, y, yp, 1.0)
            assert np.array_equal(fast, j0 * cy + (j1 - j0) * cyp)
            assert np.count_nonzero(fast) > s.n


def test_rig_test_2_with_events_and_mode_changes(rig, c_steps):
    # PVG 32 rig test 2 for 0.3 s (91 unknowns, dense iteration matrix): the load valve
    # switches at 10 ms, chambers cavitate (mode changes), error-test failures occur
    t_eval = np.linspace(0.0, 0.3, 31)
    a, b = both(lambda cs: simulate(rig, 0.3, rtol=1e-6, t_eval=t_eval, c_step=cs))
    assert_identical(a, b)
    assert rig.n <= rig.DENSE_MAX and c_steps["n"] == b.stats["nsteps"]
    assert b.stats["netf"] > 0 and b.stats["nroot"] > 0 and len(b.events) > 0
    assert a._mode_log == b._mode_log and len(b._mode_log) > 2
    # a different tolerance and every internal step as output
    a, b = both(lambda cs: simulate(rig, 0.05, rtol=1e-4, c_step=cs))
    assert_identical(a, b)


@pytest.mark.parametrize("linear_solver", ["lapack", "c"])
def test_machine_cycle_window(c_steps, linear_solver, monkeypatch):
    # the machine (184 unknowns) over the first lift: the voltage ramps at 0.2 s and 0.3 s;
    # "lapack": a sparse iteration matrix, SuperLU's solves called back from C; "c": the
    # compiled Jacobian made dense and factorised by the C sparse LU inside the C step
    from pvgraph.circuits.machine import RTOL, build_machine
    from pvgraph.solver import clu
    calls = {"n": 0}
    factor = clu.SparseLU.factor

    def counted(self, m):              # factorisations by the Python code
        calls["n"] += 1
        return factor(self, m)

    monkeypatch.setattr(clu.SparseLU, "factor", counted)
    s = build_machine().compile(backend="c")
    assert s.n > s.DENSE_MAX
    t_eval = np.linspace(0.0, 0.4, 81)
    runs = []
    for cs in (False, None):
        calls["n"] = 0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            runs.append(simulate(s, 0.4, rtol=RTOL, t_eval=t_eval, c_step=cs,
                                 linear_solver=linear_solver))
        runs[-1].python_factors = calls["n"]
    a, b = runs
    assert_identical(a, b)
    assert c_steps["n"] == b.stats["nsteps"] > 100
    assert b.stats["ncfn"] + b.stats["netf"] > 0
    if linear_solver == "c":
        # the Python step factorises every matrix itself (and the starts'), the C step
        # only the starts' matrices and those solving the event functions' algebraic variables
        assert a.python_factors > b.stats["nlu"] > 20 > \
            b.python_factors - b.stats.get("nlu_events", 0)
    else:
        assert a.python_factors == b.python_factors == 0


@pytest.mark.parametrize("case", ["rig, dense differences", "machine, detected pattern"])
def test_difference_jacobians_and_step_options(rig, case, c_steps):
    # the Jacobian by finite differences (the residual called back from the setup), a dense
    # one for the rig and, for the machine, a pattern detected from dense differences and
    # then SuperLU; lower maximum order, a step limit and a given first step
    if case.startswith("rig"):
        s, t_end, extra = rig, 0.05, {}
    else:
        from pvgraph.circuits.machine import build_machine
        s, t_end = build_machine().compile(backend="c"), 0.1
        extra = dict(max_order=3, max_step=1e-3, first_step=1e-5)

    def run(cs):
        s.reset_modes()
        return solve_dae(s.residual, (0.0, t_end), s.y0, s.yp0, rtol=1e-5,
                         atol=1e-5 * s.nominal, algebraic=s.algebraic, var_names=s.names,
                         events=s.solver_events(), suppress_alg=True,
                         no_growth_after_failure=True, newton_iterate_retry=True,
                         c_step=cs, **extra)

    a, b = both(run)
    assert_identical(a, b)
    assert b.stats["nre"] > 2 * b.stats["nni"]        # most residuals went to differences
    assert c_steps["n"] == b.stats["nsteps"] > 100


class DrainParams(Params):
    rate: float = Field(..., gt=0.0, description="Fall rate of the level [m/s]")


class SqrtDrain(Component):
    """A level falling at a constant rate and its square root: h' = -rate, s = sqrt(h).

    Once h < 0 the square root cannot be evaluated (NaN in C).
    """

    Params = DrainParams
    ports = {}
    variables = {"h": Variable("m", lambda p: 1.0, 1.0, "level"),
                 "s": Variable("m", lambda p: 1.0, 1.0, "square root of the level")}

    def equations(self, v, p):
        return [der(v.h) + p.rate, v.s * v.s - v.h * E.sqrt(v.h) / E.sqrt(v.h)]


def test_a_residual_that_becomes_nan_fails_with_the_same_message(c_steps):
    c = Circuit("drain")
    c.add("d", SqrtDrain(rate=1.0))
    s = c.compile(backend="c")
    msgs = []
    for cs in (False, None):
        with pytest.raises(SolverError) as info:
            simulate(s, 3.0, rtol=1e-6, c_step=cs)
        msgs.append(str(info.value))
    assert msgs[0] == msgs[1]
    assert "the residual is not finite" in msgs[0] and "(rows of 'd.s')" in msgs[0]
    assert "at t = 1 " in msgs[0]          # h = 1 - t reaches zero at t = 1
    assert c_steps["n"] > 0


STATE = ("tn", "t_old", "hh", "hused", "kk", "kused", "phase", "ns", "nst_restart", "cj",
         "cjlast", "cjold", "ss", "force_setup", "_ee_norm", "nst", "nre", "nni", "netf", "ncfn",
         "nsetups", "psi")
ARRAYS = ("phi", "ee", "ewt", "ewt_err", "yy", "yp")


def test_the_integrator_state_after_every_step(rig):
    # the two integrators stepped side by side from the same start, with a restart (as after
    # an event) half way: every attribute interpolate, reinit, events and outputs read
    from pvgraph.simulate import simulate as sim
    from pvgraph.solver.linalg import JacobianEvaluator, LUSolver
    y0 = sim(rig, 1e-3, rtol=1e-6).y[-1]
    yp0 = np.zeros(rig.n)
    rig.reset_modes()
    atol = 1e-6 * rig.nominal
    integ = {}
    for cs in (False, True):
        jac = JacobianEvaluator(rig.residual, rig.n, rig.solver_jacobian(), rig.jac_sparsity,
                                typical=atol / 1e-6)
        integ[cs] = cstep.make_integrator(
            cs, rig.residual, rig.n, 1e-6, atol, rig.differential.astype(float), jac,
            LUSolver(), 5, None, rig.names, True, None, True)
        integ[cs].reinit(0.0, y0, yp0, 0.2)
    assert type(integ[True]) is cstep.CStepIntegrator
    assert type(integ[False]) is not cstep.CStepIntegrator
    for k in range(150):
        if k == 75:
            t = integ[False].tn
            for it in integ.values():
                y, yp = it.interpolate(t)
                it.reinit(t, y, yp, 0.2)
        for it in integ.values():
            it.step()
        a, b = integ[False], integ[True]
        for name in STATE:
            assert getattr(a, name) == getattr(b, name), (k, name)
        for name in ARRAYS:
            assert np.array_equal(getattr(a, name), getattr(b, name)), (k, name)
        tm = 0.5 * (a.t_old + a.tn)
        assert all(np.array_equal(u, v) for u, v in zip(a.interpolate(tm), b.interpolate(tm)))
    assert a.netf > 0 and a.phase == 1


def test_c_step_true_where_it_does_not_apply_is_refused():
    def f(t, y, yp):
        return yp + y

    with pytest.raises(ValueError, match="C step does not apply"):
        solve_dae(f, (0.0, 1.0), [1.0, 2.0], [-1.0, -2.0], c_step=True)
    # and the Python step runs it without the option
    r = solve_dae(f, (0.0, 1.0), [1.0, 2.0], [-1.0, -2.0], rtol=1e-8, atol=1e-10)
    assert r.y[-1] == pytest.approx([math.exp(-1.0), 2 * math.exp(-1.0)], rel=1e-6)


def test_without_a_compiler_the_python_step_runs(monkeypatch, c_steps):
    s = _pump_volume_orifice().compile(backend="c")
    ref = simulate(s, 0.5)
    monkeypatch.setattr(cstep, "_kernel", cbackend.LoadOnce(cstep._load))   # not loaded yet
    monkeypatch.setattr(cbackend, "c_compiler", lambda: None)
    got = simulate(s, 0.5)
    assert c_steps["n"] == ref.stats["nsteps"] > 0       # the first run only
    assert_identical(ref, got)
    assert "no C compiler" in cstep.kernel_error()
    with pytest.raises(ValueError, match="not available"):
        simulate(s, 0.5, c_step=True)


# ---------------------------------------------------------------- the dense setup in C

@pytest.fixture
def py_setups(monkeypatch):
    """Counts the iteration matrices the C step asks the Python code for."""
    count = {"n": 0}
    setup = cstep.CStepIntegrator._setup_from_c

    def counted(self, *a):
        count["n"] += 1
        return setup(self, *a)

    monkeypatch.setattr(cstep.CStepIntegrator, "_setup_from_c", counted)
    return count


def test_rig_dense_setup_in_c_against_the_callback_and_python(rig, py_setups, monkeypatch):
    # PVG 32 rig test 2 (dense 91 x 91, compiled Jacobian): the Python step, the C step with
    # the iteration matrix from the Python code, and with it evaluated and factorised in C
    t_eval = np.linspace(0.0, 0.2, 21)

    def run(cs):
        rig.reset_modes()
        return simulate(rig, 0.2, rtol=1e-6, t_eval=t_eval, c_step=cs)

    a, b = both(run)
    assert py_setups["n"] == 0 and b.stats["nlu"] > 10
    monkeypatch.setattr(cstep.CStepIntegrator, "dense_setup", False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        c = run(None)
    assert py_setups["n"] == c.stats["nlu"]       # the step's setups (the start has its own)
    assert_identical(a, b)
    assert_identical(a, c)
    assert b.stats["netf"] > 0 and b.stats["nroot"] > 0


class OverflowParams(Params):
    rate: float = Field(..., description="Rate of the level [1/s]")
    h0: float = Field(..., description="Start level [-]")


class LogisticTail(Component):
    """h' = rate and s = 1 / (1 + exp(h)): once exp(h) overflows s = 0 is still finite, but
    its derivative -s exp(h) / (1 + exp(h)) is 0 * inf = NaN."""

    Params = OverflowParams
    ports = {}
    variables = {"h": Variable("1", lambda p: p.h0, 1.0, "level"),
                 "s": Variable("1", lambda p: 0.0, 1.0, "logistic of the level")}

    def equations(self, v, p):
        return [der(v.h) - p.rate, v.s - 1.0 / (1.0 + E.exp(v.h))]


class VanishingCoefficient(Component):
    """h' = rate and (s - 1) exp(-exp(h)) = 0: the coefficient underflows to 0 once
    exp(h) > 745, and the column of s in the iteration matrix is exactly zero."""

    Params = OverflowParams
    ports = {}
    variables = {"h": Variable("1", lambda p: p.h0, 1.0, "level"),
                 "s": Variable("1", lambda p: 1.0, 1.0, "value fixed by the coefficient")}

    def equations(self, v, p):
        return [der(v.h) - p.rate, (v.s - 1.0) * E.exp(-E.exp(v.h))]


@pytest.mark.parametrize("cls, rate, h0, t_end, expect", [
    (LogisticTail, 10.0, 700.0, 2.0, "is not finite (NaN or inf) in equation(s) [1]"),
    (VanishingCoefficient, 1.0, 1.0, 10.0, "is singular in the column of 'x.s'")])
def test_jacobian_failures_in_the_c_setup_are_the_pythons(cls, rate, h0, t_end, expect,
                                                          py_setups, c_steps):
    # the C setup hands a non-finite matrix or a zero pivot to the Python code, which
    # reports it: same failure, same message, at the same t (h = h0 + rate t reaches the
    # overflow of exp(h) at 709.78, resp. the underflow of exp(-exp(h)) at h = 6.614)
    c = Circuit("fail")
    c.add("x", cls(rate=rate, h0=h0))
    s = c.compile(backend="c")
    assert s.n == 2
    msgs, ts = [], []
    for cs in (False, None):
        with pytest.raises(SolverError) as info:
            simulate(s, t_end, rtol=1e-6, c_step=cs)
        msgs.append(str(info.value))
        ts.append(info.value.t)
    assert msgs[0] == msgs[1] and ts[0] == ts[1]
    assert expect in msgs[0]
    # t is the last step's end: the step that fails crosses that point (an old matrix may
    # carry the steps a little past it), well before t_end
    h_fail = math.log(1.7976931348623157e308 if cls is LogisticTail else 745.1332)
    t_fail = (h_fail - h0) / rate
    assert t_fail - 1e-3 * t_end <= ts[0] < t_fail + 0.1 * t_end
    assert c_steps["n"] > 10 and py_setups["n"] > 0


# ---------------------------------------------------------------- events after the step in C

class RelayParams(Params):
    rate: float = Field(..., gt=0.0, description="Speed of the level [1/s]")


class Relay(Component):
    """A level x running up at ``rate`` to 1 and down to 0, switched by two events; its
    square s = x^2 (an algebraic unknown). ``held`` is exactly zero while running down (its
    sign at every step start comes from a probe inside the step)."""

    Params = RelayParams
    ports = {}
    modes = {"down": 0.0}
    variables = {"x": Variable("1", lambda p: 0.0, 1.0, "level"),
                 "s": Variable("1", lambda p: 0.0, 1.0, "square of the level")}

    def equations(self, v, p):
        down = v.mode("down")

        def to_down(modes):
            modes["down"] = 1.0

        def to_up(modes):
            modes["down"] = 0.0

        v.event("top", E.where(down < 0.5, v.x - 1.0, -1.0), direction=1, action=to_down)
        v.event("bottom", E.where(down > 0.5, -v.x, -1.0), direction=1, action=to_up)
        v.event("held", E.where(down > 0.5, 0.0, v.x - 2.0))
        return [der(v.x) - p.rate * (1.0 - 2.0 * down), v.s - v.x * v.x]


def test_events_after_the_step_in_c_with_mode_changes_and_zeros(monkeypatch):
    # the events' values at the step's end come from C while no sign can have changed; a
    # crossing, and a value exactly zero at the step start (every step while running down,
    # and each restart: the fired event's sign is unknown) go to the Python code
    calls = {"quiet": 0, "python": 0}
    quiet = cstep.CStepIntegrator.events_quiet

    def counted(self):
        out = quiet(self)
        calls["quiet" if out else "python"] += 1
        return out

    advance = cstep.CStepIntegrator.advance

    def counted_advance(self, run):         # steps found quiet in the loop in C
        out = advance(self, run)
        calls["quiet"] += run.quiet
        return out

    monkeypatch.setattr(cstep.CStepIntegrator, "events_quiet", counted)
    monkeypatch.setattr(cstep.CStepIntegrator, "advance", counted_advance)
    c = Circuit("relay")
    c.add("r", Relay(rate=1.0))
    s = c.compile(backend="c")
    t_eval = np.linspace(0.0, 4.5, 46)

    def run(cs):
        s.reset_modes()
        return simulate(s, 4.5, rtol=1e-8, t_eval=t_eval, c_step=cs)

    a, b = both(run)
    assert_identical(a, b)
    assert a._mode_log == b._mode_log
    assert [e.name for e in b.events] == ["r.top", "r.bottom", "r.top", "r.bottom"]
    # x = t up to 1, then 2 - t down to 0, ...: switches at t = 1, 2, 3, 4
    assert [e.t for e in b.events] == pytest.approx([1.0, 2.0, 3.0, 4.0], abs=1e-8)
    assert b["r.x"] == pytest.approx(np.abs(((t_eval + 1.0) % 2.0) - 1.0), abs=1e-7)
    assert calls["quiet"] > 10 and calls["python"] > 10
    # every internal step as output
    a, b = both(lambda cs: (s.reset_modes(), simulate(s, 4.5, rtol=1e-6, c_step=cs))[1])
    assert_identical(a, b)


def test_the_loop_in_c_flushes_outputs_and_stops_at_max_steps(monkeypatch, c_steps):
    # solve_dae's loop runs in C between eventful steps (CStepIntegrator.advance); its
    # output rows come in blocks (RUN_ROWS), and the step limit stops it where the Python
    # loop stops, with the same error
    monkeypatch.setattr(cstep, "RUN_ROWS", 7)
    s = _pump_volume_orifice().compile(backend="c")
    a, b = both(lambda cs: simulate(s, 2.0, rtol=1e-7, c_step=cs))
    assert_identical(a, b)
    assert c_steps["n"] == b.stats["nsteps"] > 7 * 20
    assert b.t.size == b.stats["nsteps"] + 1
    # many output times inside one step, and output times exactly at steps' ends
    t_steps = b.t[10:14]
    t_eval = np.unique(np.concatenate([np.linspace(0.0, 2.0, 4001), t_steps]))
    a, b = both(lambda cs: simulate(s, 2.0, rtol=1e-7, t_eval=t_eval, c_step=cs))
    assert_identical(a, b)
    assert np.array_equal(b.t, t_eval)
    errors = []
    for cs in (False, None):
        with pytest.raises(SolverError, match="max_steps = 30") as info:
            solve_dae(s.residual, (0.0, 2.0), s.y0, s.yp0, rtol=1e-7, max_steps=30,
                      jac=s.solver_jacobian(), jac_sparsity=s.jac_sparsity,
                      algebraic=s.algebraic, c_step=cs)
        errors.append(str(info.value))
    assert errors[0] == errors[1]
