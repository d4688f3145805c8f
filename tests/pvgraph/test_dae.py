"""compile_dae: a residual written as a function, traced and compiled like a circuit."""

from __future__ import annotations

import numpy as np
import pytest

from pvgraph import cbackend
from pvgraph.dae import compile_dae
from pvgraph.errors import PvgraphError, StructureError
from pvgraph.solver import solve_dae
from pvgraph.solver.testset import HIRES, PROBLEMS, ROBER, mescd

needs_cc = pytest.mark.skipif(cbackend.c_compiler() is None, reason="no C compiler")


@pytest.fixture(autouse=True)
def _cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("PVGRAPH_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "pv-c-cache"))


@pytest.mark.parametrize("key", sorted(k for k, p in PROBLEMS.items() if p.residual_lib))
def test_traced_test_set_residuals_equal_the_hand_written_ones(key):
    p = PROBLEMS[key]
    system = compile_dae(p.residual_lib, p.y0, p.yp0, names=p.var_names)
    assert system.names == list(p.var_names)
    rng = np.random.default_rng(7)
    y = p.y0 * (1.0 + 0.01 * rng.standard_normal(p.y0.size)) + 1e-3
    yp = p.yp0 + 0.01
    t = 0.37 * p.t_span[1]
    r_hand = np.asarray(p.residual(t, y, yp))
    r = system.residual(t, y, yp)
    scale = np.abs(r_hand).max()
    assert np.abs(r - r_hand).max() <= 1e-13 * scale
    J_hand = p.jac(t, y, yp, 3.0)
    J_hand = J_hand.toarray() if hasattr(J_hand, "toarray") else np.asarray(J_hand)
    J = system.jacobian_dense(t, y, yp, 3.0)
    assert np.abs(J - J_hand).max() <= 1e-13 * np.abs(J_hand).max()
    algebraic = sorted(np.flatnonzero(system.algebraic).tolist())
    assert algebraic == sorted(p.algebraic or [])


@needs_cc
def test_hires_compiled_to_c_meets_the_reference_and_matches_the_python_code():
    p = HIRES
    py = compile_dae(p.residual_lib, p.y0, p.yp0, names=p.var_names, name="hires")
    cc = compile_dae(p.residual_lib, p.y0, p.yp0, names=p.var_names, name="hires", backend="c")
    assert cc.backend == "c"
    tol = 1e-6
    runs = []
    for s in (py, cc):
        runs.append(solve_dae(s.residual, p.t_span, p.y0, p.yp0, rtol=tol, atol=p.atol(tol),
                              jac=s.solver_jacobian(), calc_initial=None,
                              linear_solver="lapack"))
    a, b = runs
    assert a.stats == b.stats and np.array_equal(a.y, b.y)   # C route and C step: same numbers
    assert mescd(b.y[-1], p.y_ref, p.atol(tol), tol) > 5.5     # IDA and IDAS: 5.66
    # the C route's default, the C sparse LU: the same accuracy
    c = solve_dae(cc.residual, p.t_span, p.y0, p.yp0, rtol=tol, atol=p.atol(tol),
                  jac=cc.solver_jacobian(), calc_initial=None)
    assert mescd(c.y[-1], p.y_ref, p.atol(tol), tol) > 5.5


@needs_cc
def test_robertson_dae_with_its_conservation_row():
    p = ROBER
    s = compile_dae(p.residual_lib, p.y0, p.yp0, names=p.var_names, backend="c")
    assert s.algebraic.tolist() == [False, False, True]
    tol = 1e-8
    for linear_solver in ("lapack", "c"):
        sol = solve_dae(s.residual, p.t_span, p.y0, p.yp0, rtol=tol, atol=p.atol(tol),
                        jac=s.solver_jacobian(), algebraic=p.algebraic, calc_initial=None,
                        linear_solver=linear_solver)
        assert mescd(sol.y[-1], p.y_ref, p.atol(tol), tol) > 7.0
        # y1 + y2 + y3 = 1 holds to the tolerance (rtol 1e-8 of y3 ~ 1), not to rounding:
        # IDA's corrector scales its Newton corrections by 2 / (1 + cj / cj_old) when cj
        # has changed since the iteration matrix was made, which leaves a fraction of the
        # linear row's residual (worst 1e-10 with LAPACK's LU, 5e-9 with the C LU's steps)
        assert np.abs(sol.y.sum(axis=1) - 1.0).max() < tol


def test_where_and_time_are_traced():
    # y' = -y for t < 1, y' = 0 after: y(2) = exp(-1)
    def f(t, y, yp, lib):
        return [yp[0] + lib.where(t < 1.0, y[0], 0.0)]
    s = compile_dae(f, [1.0], [-1.0])
    sol = solve_dae(s.residual, (0.0, 2.0), s.y0, s.yp0, rtol=1e-10, atol=1e-12,
                    jac=s.solver_jacobian(), calc_initial=None, max_step=0.01)
    assert sol.y[-1, 0] == pytest.approx(np.exp(-1.0), rel=1e-5)


def test_bad_residuals_are_named():
    def erf_user(t, y, yp, lib):
        return [yp[0] - lib.erf(y[0])]
    with pytest.raises(PvgraphError, match=r"lib\.erf.*available: .*exp"):
        compile_dae(erf_user, [0.0])

    def branching(t, y, yp, lib):
        return [yp[0] - (1.0 if y[0] > 0 else -1.0)]
    with pytest.raises(PvgraphError, match="where"):
        compile_dae(branching, [0.0])

    def short(t, y, yp, lib):
        return [yp[0] - y[1]]
    with pytest.raises(PvgraphError, match="returned 1 rows for 2 unknowns"):
        compile_dae(short, [0.0, 1.0])
    with pytest.raises(PvgraphError, match="yp0 has 3 values"):
        compile_dae(short, [0.0, 1.0], [0.0, 0.0, 0.0])
    with pytest.raises(PvgraphError, match="distinct names"):
        compile_dae(short, [0.0, 1.0], names=["a", "a"])

    def singular(t, y, yp, lib):       # y[1] appears nowhere: structurally singular
        return [yp[0] + y[0], y[0] - 1.0]
    with pytest.raises(StructureError, match="y1"):
        compile_dae(singular, [1.0, 0.0])


def test_an_index_three_pendulum_is_refused_with_advice_for_a_dae():
    """x' = u, y' = v, u' = -lam x, v' = -lam y - g, 0 = x^2 + y^2 - 1: the multiplier lam
    appears in no algebraic equation (index three). The refusal names the row and lam and
    tells a DAE's author what to do, not a circuit's."""
    def residual(t, y, yp, lib):
        x, yy, u, v, lam = y[0], y[1], y[2], y[3], y[4]
        return [yp[0] - u, yp[1] - v, yp[2] + lam * x, yp[3] + lam * yy + 9.81,
                x * x + yy * yy - 1.0]
    with pytest.raises(StructureError) as info:
        compile_dae(residual, [1.0, 0.0, 0.0, 0.0, 0.0])
    msg = str(info.value)
    assert "dae row 4" in msg
    assert "Unknowns left without an equation: y4" in msg
    assert "index one" in msg and "acceleration-level" in msg
    assert "VolumeNode" not in msg
