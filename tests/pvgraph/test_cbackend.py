"""The C route for the generated functions: the numbers of the Python code, bit for bit.

Needs a C compiler on the machine (skipped without one); compiled libraries go to a temporary
cache folder per test session.
"""

from __future__ import annotations

import math
import threading
import warnings

import numpy as np
import pytest

from pvgraph import Circuit, cbackend
from pvgraph import expr as E
from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
from pvgraph.errors import PvgraphError
from pvgraph.simulate import simulate
from pvgraph.units import bar, litre, lpm, mm2

needs_cc = pytest.mark.skipif(cbackend.c_compiler() is None, reason="no C compiler")
pytestmark = needs_cc


@pytest.fixture(autouse=True)
def _cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("PVGRAPH_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "pv-c-cache"))
    monkeypatch.delenv("PVGRAPH_BACKEND", raising=False)


def pump_volume_orifice(Q=lpm(10), A=mm2(2.0), V=litre(0.5)):
    c = Circuit("pvo")
    pump = c.add("pump", FlowSource(Q=Q))
    node = c.add("node", VolumeNode(V=V))
    o = c.add("o", Orifice(A=A))
    tank = c.add("tank", Tank())
    c.connect(pump.port, node.port, o.a)
    c.connect(o.b, tank.port)
    return c


def _call(module, fn, n_out, y, yp=None, P=(), c=None, modes=()):
    st = cbackend.CState(module, list(P), len(y), len(modes))
    st.y[:] = y
    st.yp[:] = np.zeros(len(y)) if yp is None else yp
    st.d[:len(modes)] = modes
    out = {"res": st.res_out, "jac": st.jac_out, "ev": st.ev_out}[fn]
    ptr = {"res": st.res_ptr, "jac": st.jac_ptr, "ev": st.ev_ptr}[fn]
    f = {"res": module.residual, "jac": module.jacobian, "ev": module.events}[fn]
    bad = f(0.25, *st.args, ptr) if c is None else f(0.25, *st.args, c, ptr)
    return out[:n_out].copy(), bad


@pytest.mark.parametrize("method", ["linear", "pchip"])
@pytest.mark.parametrize("extrapolate", [False, True])
def test_table_lookups_equal_the_python_table(method, extrapolate):
    # knots of uneven spacing and a non-monotone stretch (pchip's zero slopes there)
    x = np.array([-1.0, 0.0, 0.3, 1.0, 2.5, 4.0])
    yv = np.array([2.0, 0.5, 0.9, 0.9, -1.0, 3.0])
    tab = E.Table(x, yv, method=method, extrapolate=extrapolate, name="t")
    y0 = E.Expr("y", (), 0)
    module = cbackend.build([E.interp(tab, y0)], [E.Expr("interp_d", (y0,), tab)], [],
                            name="table test")
    span = x[-1] - x[0]
    points = np.concatenate([np.linspace(-2.5, 5.5, 401), x, x + 1e-13 * span,
                             x - 1e-13 * span, x + 1e-11 * span, [np.nextafter(4.0, 5.0)]])
    for xv in points:
        v, _ = _call(module, "res", 1, [xv])
        s, _ = _call(module, "jac", 1, [xv], c=0.0)
        assert v[0] == tab.value(float(xv)), (xv, v[0], tab.value(float(xv)))
        assert s[0] == tab.slope(float(xv)), (xv, s[0], tab.slope(float(xv)))


def test_runtime_parameters_and_the_orifice_law():
    # steady state of a pump into an orifice: Q = Cd A sqrt(2 p / rho), both routes, two areas
    c = pump_volume_orifice()
    py = c.compile()
    cc = c.compile(backend="c")
    assert py.backend == "python" and cc.backend == "c"
    for A in (mm2(2.0), mm2(3.5)):
        sp = simulate(py.with_params({"o.A": A}), 5.0)
        # the same numbers with the same LU (the C route defaults to the C sparse LU)
        sc = simulate(cc.with_params({"o.A": A}), 5.0, linear_solver="lapack")
        assert np.array_equal(sp.y, sc.y) and sp.stats["nsteps"] == sc.stats["nsteps"]
        sc = simulate(cc.with_params({"o.A": A}), 5.0)
        P = cc.parameters
        Cd, rho = P["o.Cd"].value, P["o.rho"].value
        dp = sc["o.dp"][-1]
        assert sc["o.q"][-1] == pytest.approx(lpm(10), rel=1e-5)     # settled: Q in = Q out
        # the turbulent law, which the orifice's transition form meets within 0.3 % here
        assert lpm(10) == pytest.approx(Cd * A * math.sqrt(2 * dp / rho), rel=3e-3)


def test_the_rig_gives_the_same_steps_and_numbers():
    from pvgraph.circuits.pvg32.parameters import report_tuned
    from pvgraph.circuits.rig import build_rig, laminar_load
    p = report_tuned()
    rig = build_rig(p, load=laminar_load(p, L1="small", L3="small", t_switch=0.01),
                    U_input=4.24)
    py = rig.compile()
    cc = py.with_params({}).use_backend("c")
    t_eval = np.linspace(0.0, 0.3, 31)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # the rig's cavitation notes
        a = simulate(py, 0.3, rtol=1e-6, t_eval=t_eval)
        b = simulate(cc, 0.3, rtol=1e-6, t_eval=t_eval, linear_solver="lapack")
        c = simulate(cc, 0.3, rtol=1e-6, t_eval=t_eval)          # the C sparse LU
        ref = simulate(cc, 0.3, rtol=1e-9, t_eval=t_eval)
    assert a.stats == b.stats
    assert np.array_equal(a.y, b.y)

    def error(run):     # largest error in units of rtol 1e-6 of each variable's range
        scale = 1e-6 * (np.abs(ref.y) + np.abs(ref.y).max(axis=0)) + 1e-12
        return np.max(np.abs(run.y - ref.y) / scale)
    # the LU changes the result by about as much as the solver's own error (463 and 537
    # units of rtol, both runs through the rig's cavitating start), and the C LU's run is as
    # accurate as LAPACK's, to the spread of two runs
    assert error(c) <= 1.25 * error(a)
    assert np.max(np.abs(c.y - a.y) / (1e-6 * (np.abs(ref.y) + np.abs(ref.y).max(axis=0))
                                       + 1e-12)) < 1.5 * error(a)
    y, yp = a.y[-1], a.yp[-1]
    assert np.array_equal(py.residual(0.3, y, yp), cc.residual(0.3, y, yp))
    assert np.array_equal(py.jacobian_values(0.3, y, yp, 250.0),
                          cc.jacobian_values(0.3, y, yp, 250.0))
    assert np.array_equal(np.asarray(py.event_values(0.3, y, yp)), cc.event_values(0.3, y, yp))
    assert len(cc.event_specs) > 0 and len(cc.modes) > 0


def test_an_entry_that_cannot_be_evaluated_is_nan_in_its_own_row():
    y0, y1 = E.Expr("y", (), 0), E.Expr("y", (), 1)
    module = cbackend.build([E.sqrt(y0), y1 * 2.0, E.log(y1), 1.0 / y0], [], [], name="nan")
    out, bad = _call(module, "res", 4, [-1.0, 3.0])
    assert bad == 1 and math.isnan(out[0]) and out[1] == 6.0
    assert out[2] == math.log(3.0) and out[3] == -1.0
    out, bad = _call(module, "res", 4, [0.0, 0.0])
    assert bad == 2 and out[0] == 0.0 and out[1] == 0.0 and math.isnan(out[2])
    assert math.isnan(out[3])


def test_where_takes_one_branch_and_pow_follows_python():
    y0 = E.Expr("y", (), 0)
    roots = [E.where(y0 > 0.0, E.sqrt(y0), -E.sqrt(-y0)), y0 ** 3.0, y0 ** 0.5, E.tanh(y0),
             E.exp(y0), E.fabs(y0), E.atan(y0), E.sin(y0), E.cos(y0)]
    module = cbackend.build(roots, [], [], name="ops")
    for v in (-2.7, -0.3, 0.0, 0.3, 1.7, 10.0):
        out, _ = _call(module, "res", len(roots), [v])
        ref = [math.sqrt(v) if v > 0 else -math.sqrt(-v), v ** 3.0,
               v ** 0.5 if v >= 0 else math.nan, math.tanh(v), math.exp(v), abs(v),
               math.atan(v), math.sin(v), math.cos(v)]
        for got, want in zip(out, ref):
            assert got == want or (math.isnan(got) and math.isnan(want)), (v, got, want)


def test_threads_share_a_system():
    c = pump_volume_orifice()
    cc = c.compile(backend="c")
    y = cc.y0 + 1e5
    want = c.compile().residual(0.0, y, cc.yp0)
    results = []

    def work(k):
        ys = y * (1.0 + 0.01 * k)
        for _ in range(200):
            r = cc.residual(0.0, ys, cc.yp0)
        results.append((k, r))

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    py = c.compile()
    for k, r in results:
        assert np.array_equal(r, py.residual(0.0, y * (1.0 + 0.01 * k), cc.yp0))
    assert np.array_equal(cc.residual(0.0, y, cc.yp0), want)


def test_threads_simulate_one_system_with_the_c_step_and_lu():
    # runs of one C-route system in threads (a threaded sweep): each run has its own step
    # state and LU contexts, so each gives the numbers of the same run alone
    cc = pump_volume_orifice().compile(backend="c")
    areas = [mm2(a) for a in (1.5, 2.0, 2.5, 3.0)]
    alone = [simulate(cc.with_params({"o.A": A}), 0.5) for A in areas]
    got = {}

    def work(k):
        for _ in range(3):
            got[k] = simulate(cc.with_params({"o.A": areas[k]}), 0.5)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(len(areas))]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    for k, ref in enumerate(alone):
        assert got[k].stats == ref.stats and np.array_equal(got[k].y, ref.y)
        assert ref.stats["nlu"] > 0


def test_the_cache_serves_a_second_compilation(monkeypatch):
    c = pump_volume_orifice(A=mm2(1.234))
    first = c.compile(backend="c")
    calls = []
    real = cbackend.subprocess.run

    def spy(*a, **kw):
        calls.append(a)
        return real(*a, **kw)
    monkeypatch.setattr(cbackend.subprocess, "run", spy)
    second = pump_volume_orifice(A=mm2(2.5)).compile(backend="c")   # other runtime values
    assert calls == []
    assert second._cmod.path == first._cmod.path


def test_bad_choices_and_a_missing_compiler_are_named(monkeypatch):
    c = pump_volume_orifice()
    with pytest.raises(ValueError, match="'python', 'c' or 'auto'"):
        c.compile(backend="fortran")
    monkeypatch.setenv("PVGRAPH_BACKEND", "cuda")
    with pytest.raises(ValueError, match="PVGRAPH_BACKEND"):
        c.compile()
    monkeypatch.delenv("PVGRAPH_BACKEND")
    monkeypatch.setenv("CC", "/nonexistent/cc-for-test")
    monkeypatch.setenv("PVGRAPH_CACHE_DIR", str(cbackend.cache_dir()) + "-empty")
    with pytest.raises(PvgraphError, match="cc-for-test"):
        pump_volume_orifice(A=mm2(7.0)).compile(backend="c")
    with pytest.warns(RuntimeWarning, match="using the Python code"):
        s = pump_volume_orifice(A=mm2(7.0)).compile(backend="auto")
    assert s.backend == "python"


def test_big_systems_keep_array_rows_with_auto_and_refuse_plain_c():
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from bench_scaling import chain
    big = chain(400).compile()          # 1200 rows: repeated rows as arrays
    with pytest.raises(PvgraphError, match="array_rows=False"):
        big.use_backend("c")
    assert big.use_backend("auto").backend == "python"


def test_environment_variable_selects_the_backend(monkeypatch):
    monkeypatch.setenv("PVGRAPH_BACKEND", "c")
    s = pump_volume_orifice(A=mm2(2.2)).compile()
    assert s.backend == "c"
    assert s.use_backend("python").backend == "python"
    ref = pump_volume_orifice(A=mm2(2.2)).compile(backend="python")
    assert np.array_equal(s.residual(0.0, ref.y0 + bar(3), ref.yp0),
                          ref.residual(0.0, ref.y0 + bar(3), ref.yp0))


def test_the_cache_keeps_the_most_recently_used_libraries(monkeypatch, tmp_path):
    import os
    import time
    monkeypatch.setenv("PVGRAPH_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(cbackend, "CACHE_MAX_FILES", 3)
    paths = []
    for k in range(3):
        # another structure each time: a fixed number is a constant of the source
        y0 = E.Expr("y", (), 0)
        paths.append(cbackend.build([y0 * float(k + 7)], [], [], name=f"lib{k}").path)
        os.utime(paths[-1], (time.time() - 100 + k, time.time() - 100 + k))
    again = cbackend.build([E.Expr("y", (), 0) * 7.0], [], [], name="again")  # lib0 used again
    assert again.path == paths[0]
    cbackend.build([E.Expr("y", (), 0) * 99.0], [], [], name="new")   # a fourth: one goes
    left = sorted(p.name for p in tmp_path.glob("pv_*"))
    assert len(left) == 3
    assert paths[0].name in left and paths[1].name not in left and paths[2].name in left
