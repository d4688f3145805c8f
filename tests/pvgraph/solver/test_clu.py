"""The C sparse LU with partial pivoting (pvgraph/solver/clu.c) against LAPACK and numpy."""

from __future__ import annotations

import ctypes
import warnings

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from pvgraph import cbackend
from pvgraph.solver import clu
from pvgraph.solver.linalg import LUSolver

pytestmark = pytest.mark.skipif(cbackend.c_compiler() is None, reason="no C compiler")

EPS = np.finfo(float).eps


@pytest.fixture(autouse=True)
def _cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("PVGRAPH_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "pv-c-cache"))


def backward_error(a, x, b):
    """||A x - b|| / (||A|| ||x|| + ||b||), infinity norms."""
    r = a @ x - b
    return np.linalg.norm(r, np.inf) / (np.linalg.norm(a, np.inf) * np.linalg.norm(x, np.inf)
                                        + np.linalg.norm(b, np.inf))


def random_sparse(n, density, rng):
    """A random sparse matrix with continuous values (no ties) and a diagonal on half the rows."""
    a = sp.random(n, n, density=density, random_state=rng,
                  data_rvs=lambda k: rng.uniform(-1.0, 1.0, k)).toarray()
    keep = rng.random(n) < 0.5
    a[keep, keep] += rng.uniform(0.5, 2.0, keep.sum())
    return a


def lapack_info_as_column(a, perm_c):
    """LAPACK's info on A[:, perm_c] told as a column of A (0 stays 0)."""
    _, _, info = sla.lapack.dgetrf(a[:, perm_c])
    return 0 if info == 0 else int(perm_c[info - 1]) + 1


@pytest.mark.parametrize("n", [1, 2, 7, 40, 91, 250])
@pytest.mark.parametrize("density", [0.02, 0.1, 0.5, 1.0])
def test_random_sparse_against_lapack(n, density):
    rng = np.random.default_rng(1000 * n + int(100 * density))
    a = random_sparse(n, density, rng)
    lu = clu.SparseLU(n, a != 0)
    info = lu.factor(a)
    # the status is LAPACK's on the same column order (structurally singular ones included)
    assert info == lapack_info_as_column(a, lu.perm_c)
    if info != 0:
        assert info > 0 and np.allclose(a[:, info - 1], 0.0) or np.linalg.matrix_rank(a) < n
        return
    b = rng.standard_normal(n)
    x = lu.solve(b)
    assert backward_error(a, x, b) <= 10 * EPS
    # the pivots are the ones getrf takes on A[:, perm_c] (no ties with continuous values)
    _, piv, _ = sla.lapack.dgetrf(a[:, lu.perm_c])
    assert np.array_equal(lu.ipiv, piv)
    x_ref = sla.lu_solve(sla.lu_factor(a), b)
    cond = np.linalg.cond(a, 1)
    assert np.allclose(x, x_ref, rtol=0.0, atol=100 * cond * EPS * np.abs(x_ref).max())
    assert np.allclose(x, np.linalg.solve(a, b), rtol=0.0,
                       atol=100 * cond * EPS * np.abs(x_ref).max())
    # the factors reproduce the permuted matrix
    low, upp = lu.factors()
    assert abs(low - sp.identity(n)).max() <= 1.0        # |l_ij| <= 1: partial pivoting
    pa = a[lu.perm_r][:, lu.perm_c]
    assert np.abs((low @ upp).toarray() - pa).max() <= 20 * n * EPS * np.abs(a).max()


@pytest.mark.parametrize("ordering", clu.ORDERINGS)
def test_each_ordering_solves_and_pivots_like_lapack(ordering):
    rng = np.random.default_rng(7)
    a = random_sparse(120, 0.04, rng) + np.diag(rng.uniform(1.0, 2.0, 120))
    lu = clu.SparseLU(120, a != 0, ordering=ordering)
    assert lu.factor(a) == 0
    _, piv, _ = sla.lapack.dgetrf(a[:, lu.perm_c])
    assert np.array_equal(lu.ipiv, piv)
    b = rng.standard_normal(120)
    assert backward_error(a, lu.solve(b), b) <= 10 * EPS
    if ordering == "NATURAL":
        assert np.array_equal(lu.perm_c, np.arange(120))


@pytest.mark.parametrize("ordering", clu.ORDERINGS)
def test_fill_of_an_arrow_matrix(ordering):
    # an arrow matrix pointing up-left (dense row and column 0, heaviest at (0, 0)) fills
    # completely when column 0 comes first, not at all when it comes last (minimum degree on
    # A + A^T does that): n - 1 + n - 1 + n entries in L + U. SuperLU on the same column
    # order fills no less.
    n = 60
    a = np.eye(n) * 4.0
    a[0, :] = 1.0
    a[:, 0] = 1.0
    a[0, 0] = 4.0 * n
    lu = clu.SparseLU(n, a != 0, ordering=ordering)
    assert lu.factor(a) == 0
    if ordering == "NATURAL":
        assert lu.nnz == n * n
    if ordering == "MMD_AT_PLUS_A":
        assert lu.perm_c[-1] == 0 and lu.nnz == 3 * n - 2
    ref = splu(sp.csc_matrix(a), permc_spec=ordering)
    assert lu.nnz <= ref.L.nnz + ref.U.nnz - n


def test_tiny_diagonal_is_pivoted_away():
    # [[1e-20, 1], [1, 1]] x = [1, 2]: x = (1 / (1 - 1e-20), (1 - 2e-20) / (1 - 1e-20)) ~ (1, 1);
    # elimination on the tiny diagonal would give x0 = 0
    a = np.array([[1e-20, 1.0], [1.0, 1.0]])
    lu = clu.SparseLU(2, perm_c=[0, 1])
    assert lu.factor(a) == 0
    assert np.array_equal(lu.ipiv, [1, 1])
    assert np.allclose(lu.solve([1.0, 2.0]), [1.0, 1.0], rtol=0.0, atol=4 * EPS)


@pytest.mark.parametrize("n", [2, 5, 33])
def test_zero_diagonals_and_permutation_matrices(n):
    rng = np.random.default_rng(n)
    perm = rng.permutation(n)
    while n > 1 and np.any(perm == np.arange(n)):
        perm = rng.permutation(n)
    a = np.zeros((n, n))
    a[np.arange(n), perm] = rng.uniform(1.0, 3.0, n)     # no diagonal entry at all
    for ordering in ("NATURAL", "COLAMD"):
        lu = clu.SparseLU(n, a != 0, ordering=ordering)
        assert lu.factor(a) == 0
        b = rng.standard_normal(n)
        x = lu.solve(b)
        x_exact = np.empty(n)
        x_exact[perm] = b / a[np.arange(n), perm]
        assert np.allclose(x, x_exact, rtol=EPS, atol=0.0)
        assert lu.nnz == n                      # a permuted diagonal: no fill, L = I


@pytest.mark.parametrize("n", [4, 20, 40])
def test_wilkinson_growth_and_lapack_ties(n):
    # 1 on the diagonal, -1 below, 1 in the last column: every pivot column ties (|1| = |-1|)
    # and LAPACK keeps the first row, so U's last column is 2^k (growth 2^(n-1))
    a = np.eye(n) - np.tril(np.ones((n, n)), -1)
    a[:, -1] = 1.0
    lu = clu.SparseLU(n, perm_c=np.arange(n))
    assert lu.factor(a) == 0
    _, piv, _ = sla.lapack.dgetrf(a)
    assert np.array_equal(lu.ipiv, piv) and np.array_equal(piv, np.arange(n))
    _, upp = lu.factors()
    assert np.array_equal(upp.toarray()[:, -1], 2.0 ** np.arange(n))
    b = np.ones(n)
    x = lu.solve(b)
    # exact solution: x = (0, ..., 0, 1)
    assert np.allclose(x, np.eye(n)[-1], rtol=0.0, atol=2.0 ** n * EPS)


@pytest.mark.parametrize("ordering", ["NATURAL", "COLAMD"])
def test_exactly_singular_matrices_give_lapacks_status(ordering):
    rng = np.random.default_rng(3)
    n = 30
    base = random_sparse(n, 0.2, rng) + np.diag(rng.uniform(1.0, 2.0, n))
    pattern = base != 0
    lu = clu.SparseLU(n, pattern, ordering=ordering)
    # a zero column j: status j + 1 whatever the order
    for j in (0, 11, n - 1):
        a = base.copy()
        a[:, j] = 0.0
        assert lu.factor(a) == j + 1
        assert lapack_info_as_column(a, lu.perm_c) == j + 1
    # a zero row: singular at a step LAPACK agrees on
    a = base.copy()
    a[17, :] = 0.0
    info = lu.factor(a)
    assert info > 0 and info == lapack_info_as_column(a, lu.perm_c)
    # rank deficient by two rows that only touch column 4 (integers: the cancellation is exact)
    a = base.copy()
    a[5, :] = 0.0
    a[9, :] = 0.0
    a[5, 4], a[9, 4] = 1.0, 3.0
    info = lu.factor(a)
    assert info > 0 and info == lapack_info_as_column(a, lu.perm_c)
    # after a failure the next good matrix factorises again
    assert lu.factor(base) == 0
    b = rng.standard_normal(n)
    assert backward_error(base, lu.solve(b), b) <= 10 * EPS


def test_solve_after_a_failed_factorisation_is_refused():
    from pvgraph.errors import SolverError
    lu = clu.SparseLU(3)
    with pytest.raises(SolverError, match="no successful factorisation"):
        lu.solve(np.ones(3))
    assert lu.factor(np.zeros((3, 3))) == 1
    with pytest.raises(SolverError, match="returned 1"):
        lu.solve(np.ones(3))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_entries_give_minus_one(bad):
    rng = np.random.default_rng(5)
    n = 25
    a = random_sparse(n, 0.2, rng) + np.eye(n)
    lu = clu.SparseLU(n, a != 0)
    for i, j in ((0, 0), (7, 19), (n - 1, n - 1), (3, 12)):
        m = a.copy()
        m[i, j] = bad
        assert lu.factor(m) == -1
    # a zero column met before the non-finite entry in the elimination order: still -1
    m = a.copy()
    m[:, lu.perm_c[0]] = 0.0
    m[2, lu.perm_c[-1]] = bad
    assert lu.factor(m) == -1
    assert lu.factor(a) == 0


def test_sizes_one_and_two():
    lu = clu.SparseLU(1)
    assert lu.factor(np.array([[4.0]])) == 0
    assert lu.solve([2.0]) == pytest.approx([0.5], rel=0, abs=0)
    assert lu.factor(np.array([[0.0]])) == 1
    assert lu.factor(np.array([[np.nan]])) == -1
    lu = clu.SparseLU(2, np.ones((2, 2)))
    a = np.array([[1.0, 2.0], [3.0, 4.0]])
    assert lu.factor(a) == 0
    # [[1, 2], [3, 4]] x = [5, 6]: x = (-4, 4.5)
    assert np.allclose(lu.solve([5.0, 6.0]), [-4.0, 4.5], rtol=4 * EPS, atol=0.0)
    assert lu.factor(np.array([[1.0, 2.0], [2.0, 4.0]])) in (1, 2)


def test_subnormal_and_negative_zero_entries():
    # the smallest subnormal is an entry (a pivot), -0.0 is not; in a block of zeros too
    n = 20
    a = np.eye(n)
    a[13, 13] = 5e-324
    a[3, 11] = -0.0
    lu = clu.SparseLU(n, perm_c=np.arange(n))
    assert lu.factor(a) == 0 and sla.lapack.dgetrf(a)[2] == 0
    assert lu.nnz == n
    b = np.ones(n)
    b[13] = 5e-324
    assert np.array_equal(lu.solve(b), np.ones(n))
    a[13, 13] = -0.0
    assert lu.factor(a) == 14 == sla.lapack.dgetrf(a)[2]


def test_pivots_at_the_ends_of_the_exponent_range_solve_exactly():
    # the solve multiplies by 1 / pivot where that is finite and divides below it (a
    # reciprocal of a subnormal overflows); powers of two make every quotient exact
    n = 6
    pivots = np.array([2.0 ** -1022, 2.0 ** 1023, 2.0 ** -1070, 1.0, -(2.0 ** -1000), 2.0 ** 900])
    a = np.diag(pivots)
    lu = clu.SparseLU(n, perm_c=np.arange(n))
    assert lu.factor(a) == 0
    x = np.array([3.0, -0.5, 7.0, 1.0, 2.0 ** 50, -(2.0 ** -60)])
    assert np.array_equal(lu.solve(a @ x), x)
    # and a general system with a badly scaled row keeps a backward error of a few eps
    rng = np.random.default_rng(5)
    m = rng.standard_normal((40, 40)) + 40 * np.eye(40)
    m[7] *= 1e-290
    b = rng.standard_normal(40)
    lu = clu.SparseLU(40, perm_c=np.arange(40))
    assert lu.factor(m) == 0
    xs = lu.solve(b.copy())
    assert np.allclose(xs, np.linalg.solve(m, b), rtol=1e-10, atol=0.0)


def test_entries_outside_the_pattern_are_factorised():
    # the kernel reads the structure from each matrix: the pattern only chose the column order
    rng = np.random.default_rng(11)
    n = 80
    a = random_sparse(n, 0.03, rng) + np.diag(rng.uniform(1.0, 2.0, n))
    lu = clu.SparseLU(n, a != 0)
    assert lu.factor(a) == 0
    nnz_before = lu.nnz
    extra = a.copy()
    extra[rng.integers(0, n, 60), rng.integers(0, n, 60)] = rng.uniform(-5.0, 5.0, 60)
    extra[:, 3] = rng.uniform(-1.0, 1.0, n)          # a full column
    assert lu.factor(extra) == 0
    b = rng.standard_normal(n)
    assert backward_error(extra, lu.solve(b), b) <= 10 * EPS
    _, piv, _ = sla.lapack.dgetrf(extra[:, lu.perm_c])
    assert np.array_equal(lu.ipiv, piv)
    assert lu.nnz > nnz_before
    # and a matrix with fewer entries than the pattern
    thin = np.diag(np.diag(a))
    assert lu.factor(thin) == 0 and lu.nnz == n
    assert np.allclose(lu.solve(b), b / np.diag(a), rtol=EPS, atol=0.0)


def test_input_is_not_modified_and_any_memory_order_is_accepted():
    rng = np.random.default_rng(2)
    a = random_sparse(50, 0.1, rng) + np.eye(50)
    lu = clu.SparseLU(50, a != 0)
    c_order, f_order = a.copy(), np.asfortranarray(a)
    assert lu.factor(c_order) == 0
    x1 = lu.solve(np.ones(50))
    assert lu.factor(f_order) == 0
    x2 = lu.solve(np.ones(50))
    assert np.array_equal(x1, x2)
    assert np.array_equal(c_order, a) and np.array_equal(f_order, a)


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="permutation"):
        clu.SparseLU(3, perm_c=[0, 0, 1])
    with pytest.raises(ValueError, match="shape"):
        clu.SparseLU(3).factor(np.eye(4))
    with pytest.raises(ValueError, match="right-hand side"):
        lu = clu.SparseLU(3)
        lu.factor(np.eye(3))
        lu.solve(np.ones(4))
    with pytest.raises(ValueError, match="right-hand side"):
        lu.solve(np.ones(1))           # no broadcasting
    with pytest.raises(ValueError, match="unknown column ordering"):
        clu.column_order(np.eye(3), "AMD")
    with pytest.raises(ValueError, match="1 <= n"):
        clu.SparseLU(0)
    with pytest.raises(ValueError, match="pattern has shape"):
        clu.SparseLU(3, np.eye(4))


def test_the_c_entry_points_by_address():
    # what C code elsewhere does: call pv_lu_factor / pv_lu_solve through function pointers
    rng = np.random.default_rng(4)
    n = 40
    a = np.asfortranarray(random_sparse(n, 0.1, rng) + np.eye(n))
    lu = clu.SparseLU(n, a != 0)
    factor = ctypes.CFUNCTYPE(ctypes.c_int64, ctypes.c_void_p, ctypes.c_void_p)(
        lu.factor_address)
    solve = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)(lu.solve_address)
    assert factor(lu.ctx, a.ctypes.data) == 0
    b = rng.standard_normal(n)
    x = b.copy()
    solve(lu.ctx, x.ctypes.data)
    assert backward_error(a, x, b) <= 10 * EPS
    a_zero = a.copy(order="F")
    a_zero[:, 6] = 0.0
    assert factor(lu.ctx, a_zero.ctypes.data) == 7


def test_without_a_compiler_it_reports_what_is_missing(monkeypatch):
    monkeypatch.setattr(clu, "_kernel", cbackend.LoadOnce(clu._load))   # not loaded yet
    monkeypatch.setattr(cbackend, "c_compiler", lambda: None)
    assert not clu.available()
    assert "no C compiler" in clu.load_error()
    with pytest.raises(cbackend.CBackendError, match="sparse LU kernel.*no C compiler"):
        clu.SparseLU(4)
    with pytest.raises(cbackend.CBackendError, match="kind='c'.*no C compiler"):
        LUSolver(kind="c")
    LUSolver()          # the default needs no compiler


def test_a_compiler_that_cannot_run_is_reported(monkeypatch, tmp_path):
    monkeypatch.setattr(clu, "_kernel", cbackend.LoadOnce(clu._load))   # not loaded yet
    monkeypatch.setenv("PVGRAPH_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    assert not clu.available()
    assert "cannot run the C compiler" in clu.load_error()
    with pytest.raises(cbackend.CBackendError, match="sparse LU kernel.*no-such-cc"):
        clu.SparseLU(4)


def test_lusolver_kind_c_against_lapack():
    rng = np.random.default_rng(8)
    n = 60
    a = random_sparse(n, 0.05, rng) + np.diag(rng.uniform(1.0, 2.0, n))
    lapack, c = LUSolver(), LUSolver(kind="c", pattern=sp.csc_matrix(a))
    b = rng.standard_normal(n)
    assert lapack.factor(a.copy()) == 0 and c.factor(a.copy()) == 0
    x_ref, x = lapack.solve(b), c.solve(b)
    assert np.allclose(x, x_ref, rtol=1e-12, atol=0.0)
    for m in (a.copy(), a.copy()):
        m[:, 9] = 0.0
        assert lapack.factor(m.copy()) == c.factor(m) == 10
    m = a.copy()
    m[1, 2] = np.nan
    assert c.factor(m) == -1
    # sparse matrices still go to SuperLU
    assert c.factor(sp.csc_matrix(a)) == 0
    assert np.allclose(c.solve(b), x_ref, rtol=1e-12, atol=0.0)
    assert c.factor(a.copy()) == 0 and np.allclose(c.solve(b), x_ref, rtol=1e-12, atol=0.0)
    assert c.nlu == lapack.nlu + 3
    with pytest.raises(ValueError, match="kind"):
        LUSolver(kind="dense")


@pytest.fixture(scope="module")
def rig():
    from pvgraph.circuits.pvg32.parameters import report_tuned
    from pvgraph.circuits.rig import build_rig, laminar_load
    p = report_tuned()
    return build_rig(p, load=laminar_load(p, L1="small", L3="small", t_switch=0.01),
                     U_input=4.24).compile()


def test_rig_iteration_matrix_against_dense_lapack(rig):
    # PVG 32 rig test 2 (91 unknowns): J = dF/dy + cj dF/dy' at a state 20 ms into the run,
    # for the step sizes the solver takes (cj = 1 / h from 1e-6 s to 1e-2 s)
    from pvgraph.simulate import simulate
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")          # the rig's cavitation notes
        res = simulate(rig, 0.02, rtol=1e-6)
    t, y, yp = float(res.t[-1]), res.y[-1], res.yp[-1]
    lu = clu.SparseLU(rig.n, rig.jac_sparsity)
    rng = np.random.default_rng(32)
    for cj in (1e6, 1e4, 1e2):
        j = rig.jacobian_dense(t, y, yp, cj)
        assert lu.factor(j) == 0
        b = rng.standard_normal(rig.n) * rig.nominal
        x = lu.solve(b)
        x_ref = sla.lu_solve(sla.lu_factor(j), b)
        assert np.linalg.norm(x - x_ref) <= 1e-12 * np.linalg.norm(x_ref)
        assert backward_error(j, x, b) <= 10 * EPS
        _, piv, _ = sla.lapack.dgetrf(j[:, lu.perm_c])
        assert np.array_equal(lu.ipiv, piv)
        # fill no worse than 1.2 x SuperLU's on the same matrix
        ref = splu(sp.csc_matrix(j))
        assert lu.nnz <= 1.2 * (ref.L.nnz + ref.U.nnz - rig.n)


def test_rig_steps_with_either_lu_agree(rig):
    # the BDF integrator stepped with getrf and with the C sparse LU: the same pivots, so
    # the same step sequence, and states equal to a small multiple of the tolerance
    from pvgraph.simulate import simulate
    from pvgraph.solver import cstep
    from pvgraph.solver.linalg import JacobianEvaluator
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        y0 = simulate(rig, 1e-3, rtol=1e-6).y[-1]
    rig.reset_modes()
    atol = 1e-6 * rig.nominal
    runs = {}
    for kind in ("lapack", "c"):
        jac = JacobianEvaluator(rig.residual, rig.n, rig.solver_jacobian(), rig.jac_sparsity,
                                typical=atol / 1e-6)
        lu = LUSolver(kind=kind, pattern=rig.jac_sparsity)
        it = cstep.make_integrator(False, rig.residual, rig.n, 1e-6, atol,
                                   rig.differential.astype(float), jac, lu, 5, None,
                                   rig.names, True, None, True)
        it.reinit(0.0, y0, np.zeros(rig.n), 0.2)
        for _ in range(60):
            it.step()
        runs[kind] = (it.tn, it.yy.copy(), it.nst, lu.nlu)
    (t_a, y_a, nst_a, nlu_a), (t_b, y_b, nst_b, nlu_b) = runs["lapack"], runs["c"]
    assert nst_a == nst_b == 60 and nlu_a == nlu_b > 5
    assert abs(t_a - t_b) <= 1e-9 * t_a
    assert np.all(np.abs(y_a - y_b) <= 1e-3 * (1e-6 * np.abs(y_a) + atol))


def test_machine_cycle_iteration_matrix_against_dense_lapack():
    # the machine of examples/machine_cycle.py (184 unknowns: SuperLU's size in the solver)
    from pvgraph.circuits.machine import build_machine
    from pvgraph.simulate import simulate
    s = build_machine().compile()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = simulate(s, 0.02, rtol=1e-5)
    t, y, yp = float(res.t[-1]), res.y[-1], res.yp[-1]
    lu = clu.SparseLU(s.n, s.jac_sparsity)
    rng = np.random.default_rng(184)
    for cj in (1e5, 1e3):
        j = s.jacobian_dense(t, y, yp, cj)
        assert lu.factor(j) == 0
        b = rng.standard_normal(s.n) * s.nominal
        x = lu.solve(b)
        x_ref = sla.lu_solve(sla.lu_factor(j), b)
        assert np.linalg.norm(x - x_ref) <= 1e-12 * np.linalg.norm(x_ref)
        _, piv, _ = sla.lapack.dgetrf(j[:, lu.perm_c])
        assert np.array_equal(lu.ipiv, piv)
        ref = splu(sp.csc_matrix(j))
        assert lu.nnz <= 1.2 * (ref.L.nnz + ref.U.nnz - s.n)


def assert_same_factorisation(lu, ref, b):
    """Bit-for-bit equality of two contexts' last factorisations and solves."""
    assert lu.info == ref.info
    if lu.info != 0:
        return
    assert np.array_equal(lu.ipiv, ref.ipiv) and np.array_equal(lu.perm_r, ref.perm_r)
    for x, y in zip(lu.factors(), ref.factors()):
        assert np.array_equal(x.toarray(), y.toarray())
    assert np.array_equal(lu.solve(b), ref.solve(b))


def test_reuse_of_the_last_structure_gives_the_factors_from_scratch():
    # a context that starts on its last structure against one that always searches: same
    # statuses, pivots, factors and solutions, bit for bit, through value changes, a pivot
    # change half way, structure changes, a singular and a non-finite matrix
    rng = np.random.default_rng(21)
    n = 70
    a = random_sparse(n, 0.05, rng) + np.diag(rng.uniform(1.0, 2.0, n))
    lu = clu.SparseLU(n, a != 0)
    ref = clu.SparseLU(n, perm_c=lu.perm_c, reuse=False)
    b = rng.standard_normal(n)
    sequence = [a]
    scaled = a * (1.0 + 1e-3 * (a != 0) * rng.standard_normal((n, n)))   # the same pivots
    sequence.append(scaled)
    assert lu.factor(a) == 0
    k = n // 2
    low, _ = lu.factors()
    rows_below = low.indices[low.indptr[k]:low.indptr[k + 1]]
    rows_below = rows_below[rows_below > k]
    assert rows_below.size > 0
    other = lu.perm_r[rows_below[0]]             # a row the pivot of step k was chosen over
    pivot_change = a.copy()
    pivot_change[other, lu.perm_c[k]] = 1e6 * (1.0 + abs(a[other, lu.perm_c[k]]))
    sequence += [pivot_change, a]
    more = a.copy()
    more[3, lu.perm_c[n - 5]] = 0.7                # an entry outside the structure
    fewer = a.copy()
    fewer[np.flatnonzero(a[:, lu.perm_c[n - 9]])[0], lu.perm_c[n - 9]] = 0.0   # one less
    moved = a.copy()                               # as many entries, one in another row
    col = lu.perm_c[n - 12]
    rows = np.flatnonzero(a[:, col])
    free = np.setdiff1d(np.arange(n), rows)
    moved[free[0], col], moved[rows[-1], col] = a[rows[-1], col], 0.0
    singular = a.copy()
    singular[:, lu.perm_c[40]] = 0.0
    nan = a.copy()
    nan[5, lu.perm_c[60]] = np.nan
    sequence += [more, a, fewer, fewer * 2.0, moved, singular, a, nan, a, a]
    restarts = []
    for m in sequence:
        info = lu.factor(m)
        assert info == ref.factor(m)
        restarts.append(lu.restart)
        assert_same_factorisation(lu, ref, b)
        if info == 0:
            assert backward_error(m, lu.solve(b), b) <= 10 * EPS
    # every path was taken: reused whole (-1), searched from a middle step, from scratch (0)
    assert restarts[1] == -1 and restarts[-1] == -1 and lu.nreused >= 3
    assert restarts[2] == k                        # the pivot changed at step k
    assert restarts[4] == n - 5 and restarts[6] == n - 9 and restarts[8] == n - 12
    assert ref.nreused == 0 and ref.restart == 0
    # the pivot change is LAPACK's
    _, piv, _ = sla.lapack.dgetrf(pivot_change[:, lu.perm_c])
    assert ref.factor(pivot_change) == 0 and np.array_equal(ref.ipiv, piv)


def test_reuse_on_rig_matrices_along_a_run(rig):
    # iteration matrices of the rig at the states and step sizes of a run: the C context that
    # reuses its structure and one that does not agree bit for bit
    from pvgraph.simulate import simulate
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = simulate(rig, 0.05, rtol=1e-6)
    lu = clu.SparseLU(rig.n, rig.jac_sparsity)
    ref = clu.SparseLU(rig.n, perm_c=lu.perm_c, reuse=False)
    b = rig.nominal.copy()
    idx = np.linspace(0, len(res.t) - 1, 25).astype(int)
    for i, cj in zip(idx, np.geomspace(1e6, 1e2, idx.size)):
        j = rig.jacobian_dense(float(res.t[i]), res.y[i], res.yp[i], cj)
        assert lu.factor(j) == ref.factor(j) == 0
        assert_same_factorisation(lu, ref, b)
    assert lu.nreused >= 10


def test_solve_dae_takes_the_c_lu_on_a_python_residual_with_the_same_accuracy(monkeypatch):
    # HIRES (IVP Test Set, 8 unknowns, hand-written numpy residual, difference Jacobian):
    # linear_solver="c" factorises with the C sparse LU; the accuracy against the published
    # reference is LAPACK's (IDA and IDAS reach 5.66 digits at rtol 1e-6)
    from pvgraph.solver import solve_dae
    from pvgraph.solver.testset import HIRES as p, mescd
    factored = {"c": 0}
    factor = clu.SparseLU.factor

    def counted(self, m):
        factored["c"] += 1
        return factor(self, m)

    monkeypatch.setattr(clu.SparseLU, "factor", counted)
    tol = 1e-6
    digits = {}
    for kind in ("lapack", "c"):
        sol = solve_dae(p.residual, p.t_span, p.y0, p.yp0, rtol=tol, atol=p.atol(tol),
                        calc_initial=None, linear_solver=kind)
        digits[kind] = mescd(sol.y[-1], p.y_ref, p.atol(tol), tol)
        if kind == "lapack":
            assert factored["c"] == 0
    assert factored["c"] >= sol.stats["nlu"] > 10
    assert digits["c"] > 5.5 and abs(digits["c"] - digits["lapack"]) < 0.2
    with pytest.raises(ValueError, match="linear_solver must be None, 'lapack' or 'c'"):
        solve_dae(p.residual, p.t_span, p.y0, p.yp0, linear_solver="klu")
