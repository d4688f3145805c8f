"""The BDF step in C for systems whose residual is compiled C (``cstep.c``).

With the residual, Jacobian and events compiled to C (:mod:`pvgraph.cbackend`), most of a
run's time is the solver's own Python: a step of :class:`~pvgraph.solver.ida.IDAIntegrator`
makes about 25 numpy calls. :class:`CStepIntegrator` performs ``step()`` -- prediction,
Newton iteration, error test, failures with their step and order reductions, order and step
selection, history update and error weights -- in one C call that evaluates the compiled
residual directly. A dense iteration matrix from the compiled Jacobian
(``System.jacobian_dense``, the one ``simulate`` uses up to ``System.DENSE_MAX`` unknowns) is
evaluated by the compiled ``pv_jacobian`` and factorised in C too -- by LAPACK, or by the
sparse LU of :mod:`pvgraph.solver.clu` when the run's ``LUSolver`` is of kind ``"c"`` (the
C route's default, also for systems above ``DENSE_MAX``) -- counted in the
evaluator's ``nje`` and the LU solver's ``nlu``; any other matrix (finite differences, sparse)
is evaluated and factorised by the Python code (``_setup``, called back from C), and so is a
matrix with a non-finite entry or a zero pivot, to report it. Errors are raised by the Python
code, with the same messages.

Around the step, for the integration loop of ``solve_dae``: when the events are the system's
compiled ones, the kernel evaluates them at the end of each step (``pv_events``) and applies
``EventTracker.crossings``' candidate test; when no value was zero before the step and none
can have changed sign, the loop takes the new values from it instead of evaluating them
itself (:meth:`CStepIntegrator.events_quiet`); otherwise the Python code evaluates and
decides as before. The interpolant of the last step (outputs at ``t_eval``, event location)
is evaluated in C as well. Between steps that need the Python code (a candidate crossing, an
event action, a pause for output rows), the integration loop itself runs in C
(:meth:`CStepIntegrator.advance`, ``pv_advance``): steps, the events' bookkeeping, the outputs
(interpolated at ``t_eval`` or every step) and the end-of-interval test, as the Python loop
does them, so a run without eventful steps makes one call into C.

The numbers are the Python step's, bit for bit: every operation is the one numpy performs, in
the same order, and the library routines are the very ones numpy and scipy call (numpy's BLAS
``ddot``, ``daxpy`` and ``dgemv``, scipy's LAPACK ``dgetrf`` and ``dgetrs``; see ``cstep.c``).
On loading, the kernel's BLAS and LAPACK calls are checked against numpy and scipy on random
data; any mismatch, a missing compiler or a missing routine leaves the Python step in use.

It applies when the residual is a C-route :meth:`System.residual <pvgraph.system.System>`
of at least 2 unknowns and no variable is declared non-negative. Dense iteration matrices
(up to ``System.DENSE_MAX`` unknowns) are solved in C with the LU factors; sparse ones
(SuperLU) are solved by the Python code, called back once per Newton iteration.
``solve_dae(..., c_step=False)`` (and ``simulate``) keeps the Python step; ``c_step=True``
requires the C step.
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np

from pvgraph.cbackend import LoadOnce
from pvgraph.errors import SolverError
from pvgraph.solver.ida import (HARMONIC, JACOBIAN_FAIL, MAX_ORDER, SETUP_FAIL, SOLVER_NAME,
                                min_step_reason,
                                IDAIntegrator, _nonfinite_entries)

__all__ = ["CStepIntegrator", "kernel", "c_system_of", "c_run"]

STEP_OK, STEP_HMIN, STEP_ERR_FAILS, STEP_CONV_FAILS, STEP_PYERR = range(5)
FAIL_BY_PYTHON = -1

_i64, _dbl, _vp = ctypes.c_int64, ctypes.c_double, ctypes.c_void_p


class _State(ctypes.Structure):
    """The kernel's state (``pv_state`` in cstep.c)."""

    _fields_ = (
        [(k, _i64) for k in ("n", "maxord", "has_mask", "no_growth", "iterate_retry", "blas64")]
        + [(k, _dbl) for k in ("rtol", "hmax_inv", "inv_n")]
        + [(k, _vp) for k in ("phi", "ewt", "ewt_err", "mask", "atol", "harmonic", "yy", "yp",
                              "ee", "eew", "r", "delta", "dw", "work", "failvec", "sq", "res",
                              "d", "P", "T", "ddot", "dgemv", "daxpy", "dgetrs", "setup",
                              "solve", "lu", "piv")]
        + [(k, _dbl) for k in ("t_bound", "tn", "hh", "hused", "cj", "cjlast", "cjold", "ck",
                               "ss", "t_old", "ee_norm")]
        + [("psi", _dbl * 8)]
        + [(k, _dbl * 8) for k in ("c_psi", "c_sigma", "c_beta", "c_gamma")]
        + [(k, _dbl) for k in ("c_cj", "c_ck")]
        + [(k, _i64) for k in ("has_coeffs", "kk", "kused", "phase", "ns", "nst_restart",
                               "force_setup", "nst", "nre", "nni", "netf", "ncfn", "nsetups",
                               "fail_kind", "fail_serial")]
        + [(k, _dbl) for k in ("err_t", "err_h")]
        + [(k, _i64) for k in ("err_count", "err_status")]
        + [(k, _vp) for k in ("jac", "dgetrf", "rows", "cols", "jout", "c_lu", "c_piv")]
        + [(k, _i64) for k in ("nnz", "c_setups")]
        + [(k, _vp) for k in ("ev", "ev_idx", "ev_buf", "g_old", "g_new")]
        + [(k, _i64) for k in ("ev_m", "ev_state")]
        + [(k, _vp) for k in ("lu_ctx", "lu_factor", "lu_solve")]
        + [("lu_c", _i64)])


class _Run(ctypes.Structure):
    """The integration loop's arguments and results (``pv_run`` in cstep.c)."""

    _fields_ = ([("nst_limit", _i64)] + [(k, _dbl) for k in ("t_end", "end_tol")]
                + [("t_eval", _vp)] + [(k, _i64) for k in ("n_eval", "i_eval")]
                + [(k, _vp) for k in ("out_t", "out_y", "out_yp")]
                + [(k, _i64) for k in ("cap", "count", "quiet", "step_code")]
                + [(k, _vp) for k in ("g_pair0", "g_pair1")])


ADV_END, ADV_PAUSE, ADV_EVENTS, ADV_FAIL = range(4)


_SETUP = ctypes.CFUNCTYPE(ctypes.c_int, _dbl, _dbl, _dbl)
_SOLVE = ctypes.CFUNCTYPE(ctypes.c_int)


class _Kernel:
    """The compiled step and the BLAS / LAPACK routines it calls."""

    def __init__(self, step, interp, advance, ddot, dgemv, daxpy, dgetrs, dgetrf, blas64):
        self.step = step
        self.interp = interp
        self.advance = advance
        self.ddot, self.dgemv, self.daxpy, self.dgetrs = ddot, dgemv, daxpy, dgetrs
        self.dgetrf = dgetrf
        self.blas64 = blas64


def kernel():
    """The loaded step kernel, or None (no compiler, no BLAS routines, a failed self-check)."""
    return _kernel.get()


def kernel_error():
    """Why the kernel could not be loaded (None when it was)."""
    return None if kernel() is not None else _kernel.error


def _numpy_blas():
    """(ddot, dgemv, daxpy, 64-bit integers) of the BLAS numpy's dot calls."""
    from numpy._core import _multiarray_umath
    lib = ctypes.CDLL(_multiarray_umath.__file__)
    for prefix, suffix, wide in (("scipy_cblas_", "64_", True), ("cblas_", "64_", True),
                                 ("scipy_cblas_", "", False), ("cblas_", "", False)):
        try:
            fns = [ctypes.cast(getattr(lib, f"{prefix}{name}{suffix}"), _vp).value
                   for name in ("ddot", "dgemv", "daxpy")]
        except AttributeError:
            continue
        return (*fns, wide)
    raise OSError("numpy's CBLAS routines (cblas_ddot, cblas_dgemv, cblas_daxpy) not found")


def _scipy_lapack(name):
    """Address of the LAPACK routine scipy.linalg's wrappers call (scipy.linalg.cython_lapack)."""
    from scipy.linalg import cython_lapack
    cap = cython_lapack.__pyx_capi__[name]
    get_name = ctypes.pythonapi.PyCapsule_GetName
    get_name.restype = ctypes.c_char_p
    get_name.argtypes = [ctypes.py_object]
    get_ptr = ctypes.pythonapi.PyCapsule_GetPointer
    get_ptr.restype = _vp
    get_ptr.argtypes = [ctypes.py_object, ctypes.c_char_p]
    return get_ptr(cap, get_name(cap))


def _load():
    from pvgraph import cbackend
    source = (Path(__file__).with_name("cstep.c")).read_text()
    lib = ctypes.CDLL(str(cbackend.compiled(source, "the BDF step kernel", opt="-O3")))
    step = lib.pv_step
    step.argtypes = [ctypes.POINTER(_State)]
    step.restype = ctypes.c_int
    interp = lib.pv_interpolate
    interp.argtypes = [ctypes.POINTER(_State), _dbl, _vp, _vp]
    interp.restype = None
    advance = lib.pv_advance
    advance.argtypes = [ctypes.POINTER(_State), ctypes.POINTER(_Run)]
    advance.restype = ctypes.c_int
    k = _Kernel(step, interp, advance, *_numpy_blas()[:3], _scipy_lapack("dgetrs"),
                _scipy_lapack("dgetrf"),
                _numpy_blas()[3])
    _self_check(k)
    return k


_kernel = LoadOnce(_load)


def _self_check(k):
    """The kernel's BLAS and LAPACK calls give numpy's and scipy's numbers on random data."""
    from pvgraph.solver.linalg import LUSolver
    itype = _i64 if k.blas64 else ctypes.c_int
    ddot = ctypes.CFUNCTYPE(_dbl, itype, _vp, itype, _vp, itype)(k.ddot)
    gemv = ctypes.CFUNCTYPE(None, ctypes.c_int, ctypes.c_int, itype, itype, _dbl, _vp, itype,
                            _vp, itype, _dbl, _vp, itype)(k.dgemv)
    axpy = ctypes.CFUNCTYPE(None, itype, _dbl, _vp, itype, _vp, itype)(k.daxpy)
    ip = ctypes.POINTER(ctypes.c_int)
    getrs = ctypes.CFUNCTYPE(None, ctypes.c_char_p, ip, ip, _vp, ip, _vp, _vp, ip, ip)(k.dgetrs)
    getrf = ctypes.CFUNCTYPE(None, ip, ip, _vp, ip, _vp, ip)(k.dgetrf)
    rng = np.random.default_rng(7)
    for n in (2, 7, 33, 91, 120):
        v = rng.standard_normal(n) * 10.0 ** rng.integers(-6, 6, n)
        if 0.0 + ddot(n, v.ctypes.data, 1, v.ctypes.data, 1) != np.dot(v, v):
            raise ValueError("the kernel's ddot differs from numpy's dot")
        for kk in range(1, MAX_ORDER + 2):        # predictor and interpolant blocks
            phi = rng.standard_normal((kk, n))
            g = rng.standard_normal(kk)
            out = np.zeros(n)
            if kk == 1:
                axpy(n, g[0], phi.ctypes.data, 1, out.ctypes.data, 1)
            else:
                gemv(101, 112, kk, n, 1.0, phi.ctypes.data, n, g.ctypes.data, 1, 0.0,
                     out.ctypes.data, 1)
            if not np.array_equal(out, np.dot(g, phi)):
                raise ValueError("the kernel's gemv/axpy differs from numpy's dot")
        m = rng.standard_normal((n, n)) + n * np.eye(n)
        b = rng.standard_normal(n)
        lu = LUSolver()
        lu.factor(m.copy())
        x = b.copy()
        ni, one, info = ctypes.c_int(n), ctypes.c_int(1), ctypes.c_int(0)
        piv = np.add(lu._piv, 1, dtype=np.int32)
        getrs(ctypes.c_char_p(b"N"), ctypes.byref(ni), ctypes.byref(one),
              lu._lu.ctypes.data, ctypes.byref(ni), piv.ctypes.data, x.ctypes.data,
              ctypes.byref(ni), ctypes.byref(info))
        if not np.array_equal(x, lu.solve(b)):
            raise ValueError("the kernel's dgetrs differs from scipy's getrs")
        for a in (m, np.where(rng.random((n, n)) < 0.8, 0.0, m),
                  np.vstack([m[:-1], m[:1]])):            # sparse; singular (a repeated row)
            f = np.asfortranarray(a)
            ipiv = np.zeros(n, dtype=np.int32)
            getrf(ctypes.byref(ni), ctypes.byref(ni), f.ctypes.data, ctypes.byref(ni),
                  ipiv.ctypes.data, ctypes.byref(info))
            lu = LUSolver()
            ref = lu.factor(a.copy())
            if not (info.value == ref and np.array_equal(f, lu._lu)
                    and np.array_equal(ipiv, lu._piv + 1)):
                raise ValueError("the kernel's dgetrf differs from scipy's getrf")


def c_system_of(fun):
    """The System whose C-route residual ``fun`` is (a bound ``System.residual``), or None."""
    owner = getattr(fun, "__self__", None)
    if owner is None or getattr(owner, "_cmod", None) is None:
        return None
    from pvgraph.system import System
    if not isinstance(owner, System) or getattr(fun, "__func__", None) is not System.residual:
        return None
    return owner


def _address(module, name):
    """The address of a compiled module's function (remembered on the module)."""
    known = module.__dict__.setdefault("_pv_addresses", {})
    addr = known.get(name)
    if addr is None:
        addr = known[name] = ctypes.cast(getattr(module, name), _vp).value
    return addr


def _field(name):
    def get(self):
        return getattr(self._s, name)

    def put(self, value):
        setattr(self._s, name, value)
    return property(get, put)


class CStepIntegrator(IDAIntegrator):
    """:class:`IDAIntegrator` whose ``step()`` runs in C (same arguments plus the system).

    The scalar state lives in the kernel's structure (the attributes below read and write
    it), the history ``phi``, the weights and ``ee`` in arrays shared with the kernel; ``yy``
    and ``yp`` are fresh arrays after every step, as with the Python step.

    ``dense_setup`` (True): evaluate and factorise a dense compiled Jacobian in C; False
    calls the Python code back for every iteration matrix. ``step_events`` (True): evaluate
    compiled event functions after each step in C (:meth:`watch_events`). ``c_interpolate``
    (True): ``interpolate`` (outputs, event location) in C. ``c_loop`` (True): ``solve_dae``
    runs its loop in C between eventful steps (:meth:`advance`).
    """

    dense_setup = True
    step_events = True
    c_interpolate = True
    c_loop = True

    tn, t_bound, hh, hused = _field("tn"), _field("t_bound"), _field("hh"), _field("hused")
    cj, cjlast, cjold, ck = _field("cj"), _field("cjlast"), _field("cjold"), _field("ck")
    ss, t_old, _ee_norm = _field("ss"), _field("t_old"), _field("ee_norm")
    kk, kused, phase, ns = _field("kk"), _field("kused"), _field("phase"), _field("ns")
    nst_restart, nst, nre, nni = (_field("nst_restart"), _field("nst"), _field("nre"),
                                  _field("nni"))
    netf, ncfn, nsetups = _field("netf"), _field("ncfn"), _field("nsetups")

    @property
    def force_setup(self):
        return bool(self._s.force_setup)

    @force_setup.setter
    def force_setup(self, value):
        self._s.force_setup = bool(value)

    @property
    def psi(self):
        return self._s.psi[:MAX_ORDER + 2]

    @psi.setter
    def psi(self, value):
        self._s.psi[:MAX_ORDER + 2] = [float(v) for v in value]

    @property
    def _coeffs(self):
        return None

    @_coeffs.setter
    def _coeffs(self, value):
        if value is None:
            self._s.has_coeffs = 0
        else:
            raise ValueError("the C step computes its own coefficients")

    def __init__(self, kern, system, fun, n, rtol, atol, error_mask, jacobian, lu, max_order,
                 max_step, var_names, no_growth_after_failure, newton_iterate_retry):
        self._s = s = _State()
        self._kernel = kern
        self._system = system
        super().__init__(fun, n, rtol, atol, error_mask, jacobian, lu, max_order, max_step,
                         var_names, no_growth_after_failure, None, newton_iterate_retry)
        # the arrays the kernel shares, views of one buffer (their addresses computed once)
        sizes = (("ewt", n), ("ewt_err", n if error_mask is not None else 0), ("mask", n),
                 ("atol", n), ("harmonic", 8), ("yy", n), ("yp", n), ("eew", n), ("r", n),
                 ("delta", n), ("dw", n), ("work", 2 * n), ("failvec", n), ("sq", n),
                 ("iy", n), ("iyp", n))
        self._buf = buf = np.zeros(sum(size for _, size in sizes))
        base = buf.ctypes.data
        at = 0
        for name, size in sizes:
            if size:
                setattr(self, "_" + name, buf[at:at + size])
                if name not in ("iy", "iyp"):           # the interpolant's outputs
                    setattr(s, name, base + 8 * at)
            at += size
        if error_mask is None:
            self._ewt_err = self._ewt
            s.ewt_err = s.ewt
            self._mask[:] = 1.0
        else:
            self._ewt_err[:] = 1.0
            self._mask[:] = error_mask
        self._ewt[:] = 1.0
        self._atol[:] = atol
        self._harmonic[:len(HARMONIC)] = HARMONIC
        self._lu_keep = None
        self._piv1 = None
        self._exc = None
        s.n, s.maxord = n, max_order
        s.has_mask = error_mask is not None
        s.no_growth, s.iterate_retry = self.no_growth, self.iterate_retry
        s.blas64 = kern.blas64
        s.rtol, s.hmax_inv, s.inv_n = float(rtol), float(self.hmax_inv), float(self.inv_n)
        for name in ("phi", "ee"):
            setattr(s, name, getattr(self, name).ctypes.data)
        s.res = _address(system._cmod, "residual")
        s.ddot, s.dgemv, s.daxpy, s.dgetrs = kern.ddot, kern.dgemv, kern.daxpy, kern.dgetrs
        self._setup_cb = _SETUP(self._setup_from_c)
        s.setup = ctypes.cast(self._setup_cb, _vp).value
        self._solve_cb = _SOLVE(self._solve_from_c)
        s.solve = ctypes.cast(self._solve_cb, _vp).value
        s.fail_kind = FAIL_BY_PYTHON
        if self.dense_setup and _compiled_dense_jacobian(system, jacobian):
            nnz = len(system._rows)
            self._rows = np.ascontiguousarray(system._rows, dtype=np.int64)
            self._cols = np.ascontiguousarray(system._cols, dtype=np.int64)
            self._jout = np.zeros(max(1, nnz))
            self._c_lu = np.zeros((n, n), order="F")
            self._c_piv = np.zeros(n, dtype=np.int32)
            s.nnz = nnz
            s.jac = _address(system._cmod, "jacobian")
            s.dgetrf = kern.dgetrf
            for name in ("rows", "cols", "jout", "c_lu", "c_piv"):
                setattr(s, name, getattr(self, "_" + name).ctypes.data)
            if lu.kind == "c":
                clu = lu.c_factoriser(n)
                s.lu_ctx, s.lu_factor, s.lu_solve = clu.ctx, clu.factor_address, \
                    clu.solve_address
        self._cst = None
        self._sref = ctypes.byref(s)
        self._tracker = None
        self._iaddr = (base + 8 * (at - 2 * n), base + 8 * (at - n))

    def _set_weights(self, y):
        """As IDAIntegrator's, into the arrays the kernel shares."""
        w = self._ewt
        np.abs(y, out=w)
        w *= self.rtol
        w += self.atol
        np.divide(1.0, w, out=w)
        self.ewt = w
        if self.error_mask is None:
            self.ewt_err = w
        else:
            self.ewt_err = np.multiply(w, self.error_mask, out=self._ewt_err)

    def _setup_from_c(self, tn, cj, hh):
        """``_setup`` after its counters: evaluate and factorise J; 0, 1 (J not finite),
        2 (singular), 3 (an exception, re-raised by ``step``)."""
        try:
            m = self.jacobian.iteration_matrix(tn, self._yy, self._yp, self._r, cj, self.ewt,
                                               hh)
            bad = _nonfinite_entries(m)
            if bad is not None:
                self._fail = (JACOBIAN_FAIL, bad)
                return 1
            info = self.lu.factor(m)
            if info != 0:
                self._fail = (SETUP_FAIL, info)
                return 2
            lu = self.lu._lu
            self._s.lu_c = 0
            if self.lu._splu is not None:
                self._lu_keep = self._piv1 = None
                self._s.lu = self._s.piv = None       # solved by _solve_from_c
                return 0
            if lu is None and self.lu._clu is not None:     # the C sparse LU's factors
                clu = self.lu._clu
                self._lu_keep = self._piv1 = None
                self._s.lu = self._s.piv = None
                s = self._s
                s.lu_ctx, s.lu_factor, s.lu_solve = clu.ctx, clu.factor_address, \
                    clu.solve_address
                s.lu_c = 1
                return 0
            if lu.dtype != np.float64 or not lu.flags.f_contiguous:
                raise SolverError("the C step needs LAPACK's column-major LU factors")
            self._lu_keep = lu
            self._piv1 = np.add(self.lu._piv, 1, dtype=np.int32)
            self._s.lu = lu.ctypes.data
            self._s.piv = self._piv1.ctypes.data
            return 0
        except BaseException as exc:       # noqa: BLE001 - re-raised by step()
            self._exc = exc
            return 3

    def _solve_from_c(self):
        """The sparse (SuperLU) solve with the residual: 0, or 3 (an exception)."""
        try:
            self._delta[:] = self.lu.solve(self._r)
            return 0
        except BaseException as exc:       # noqa: BLE001 - re-raised by step()
            self._exc = exc
            return 3

    def interpolate(self, t):
        """(y, y') at t in the last step (``result.interpolate``, in C)."""
        if not self.c_interpolate:
            return IDAIntegrator.interpolate(self, t)
        self._kernel.interp(self._sref, t, *self._iaddr)
        return self._iy.copy(), self._iyp.copy()

    def watch_events(self, tracker):
        """Evaluate ``tracker``'s event functions at the end of every step in C, if they are
        this system's compiled ones (:meth:`events_quiet` then tells the result); True if so.
        """
        from pvgraph.system import System
        vector = tracker._vector
        if not self.step_events or vector is None or not tracker.m:
            return False
        g_all, idx = vector
        system = self._system
        if (getattr(g_all, "__self__", None) is not system
                or getattr(g_all, "__func__", None) is not System._c_events
                or idx.min() < 0 or idx.max() >= min(len(system.event_specs),
                                                     system._cmod.n_ev)):
            return False
        s = self._s
        self._ev_idx = np.ascontiguousarray(idx, dtype=np.int64)
        self._ev_buf = np.zeros(system._cmod.n_ev)
        self._g_pair = (np.zeros(tracker.m), np.zeros(tracker.m))
        self._g_addr = tuple(g.ctypes.data for g in self._g_pair)
        s.ev = _address(system._cmod, "events")
        s.ev_idx, s.ev_buf = self._ev_idx.ctypes.data, self._ev_buf.ctypes.data
        s.ev_m = tracker.m
        s.g_old = s.g_new = None
        self._g_bound = self._g_new = None
        self._tracker = tracker
        return True

    def _bind_events(self, g):
        """Let the kernel read the values before the step from ``g`` (the tracker's ``g``)."""
        s = self._s
        pair, addr = self._g_pair, self._g_addr
        k = 0 if g is pair[1] else 1            # write into the other array of the pair
        self._g_new = pair[k]
        s.g_new = addr[k]
        if g is pair[1 - k]:
            s.g_old = addr[1 - k]
        elif (isinstance(g, np.ndarray) and g.dtype == np.float64 and g.shape == pair[0].shape
              and g.flags.c_contiguous):
            s.g_old = g.ctypes.data
        else:
            s.g_old = None                        # not evaluated: the Python code does it
        self._g_bound = g

    def events_quiet(self):
        """After a step: True if the kernel found no candidate crossing (see
        ``EventTracker.crossings``); the tracker then holds the values at the step's end and
        counts them as ``evaluate`` does. False: the Python code evaluates and decides."""
        if self._s.ev_state != 1:
            return False
        tracker = self._tracker
        tracker.nroot += tracker.m
        g = tracker.g = self._g_new
        # the next step reads these values and writes the other array of the pair
        k = 0 if g is self._g_pair[1] else 1
        s = self._s
        s.g_old = s.g_new
        s.g_new = self._g_addr[k]
        self._g_new = self._g_pair[k]
        self._g_bound = g
        return True

    def _before(self):
        """Point the kernel at this thread's C buffers, the current modes and the events'
        values before the step."""
        s = self._s
        system = self._system
        st = system._c_state()
        if st is not self._cst:
            self._cst = st
            s.d, s.P = st.d.ctypes.data, st.P.ctypes.data
            s.T = ctypes.addressof(st.T)
        if system.modes:
            st.d[:len(system.modes)] = system.modes
        tracker = self._tracker
        if tracker is not None and tracker.g is not self._g_bound:
            self._bind_events(tracker.g)
        return s.fail_serial

    def _after(self, code, serial):
        """Counters, failure records and errors after the kernel's step(s)."""
        s = self._s
        if s.c_setups:
            # the counters of the evaluator and the LU solver the C setups stand for
            self.jacobian.nje += s.c_setups
            self.lu.nlu += s.c_setups
            s.c_setups = 0
        if s.fail_serial != serial and s.fail_kind != FAIL_BY_PYTHON:
            self._fail = (int(s.fail_kind), self._failvec.copy())
        if code == STEP_OK:
            self.yy = self._yy.copy()
            self.yp = self._yp.copy()
            return
        if code == STEP_PYERR:
            exc, self._exc = self._exc, None
            raise exc
        if code == STEP_HMIN:
            self._raise(min_step_reason(s.err_t), s.err_t, s.err_h)
        if code == STEP_ERR_FAILS:
            self._raise(f"the local error test failed {s.err_count} times in one step",
                        s.err_t, s.err_h, self._fail[1],
                        "the weighted error estimate is dominated by")
        if code == STEP_CONV_FAILS:
            self._raise_newton(int(s.err_status), int(s.err_count), s.err_t, s.err_h)
        raise SolverError(f"{SOLVER_NAME}: the C step returned {code}", t=s.tn, h=s.hh)

    def step(self):
        """Take one successful step towards ``t_bound``; raise SolverError on failure."""
        serial = self._before()
        self._after(self._kernel.step(self._sref), serial)

    def can_advance(self, tracker):
        """Can :meth:`advance` run the integration loop for these events (None: none)?"""
        return self.c_loop and self.c_interpolate and (tracker is None
                                                       or self._tracker is tracker)

    def advance(self, run):
        """Take steps in C as the integration loop of ``solve_dae`` would while no event
        function can have crossed zero, writing the outputs (``pv_advance`` in cstep.c);
        ``run`` is a :class:`_Run`. Returns ADV_END, ADV_PAUSE or ADV_EVENTS (the last step
        taken, its events, outputs and end test left to the caller); raises SolverError as
        ``step`` does."""
        serial = self._before()
        tracker = self._tracker
        if tracker is not None:
            run.g_pair0, run.g_pair1 = self._g_addr
        run.quiet = 0
        status = self._kernel.advance(self._sref, ctypes.byref(run))
        if run.quiet:
            # what events_quiet did after each of these steps
            s = self._s
            tracker.nroot += tracker.m * run.quiet
            k = 0 if s.g_old == self._g_addr[0] else 1
            tracker.g = self._g_bound = self._g_pair[k]
            self._g_new = self._g_pair[1 - k]
        self._after(run.step_code if status == ADV_FAIL else STEP_OK, serial)
        return status


RUN_ROWS = 256      # output rows of the loop in C between two visits of the Python loop


def c_run(integ, n, t_end, t_eval, nst_limit):
    """The arguments of :meth:`CStepIntegrator.advance` for ``solve_dae``'s loop: outputs at
    ``t_eval`` (rows of arrays of all of them) or at every step (blocks of RUN_ROWS rows;
    the caller takes them and resets ``count``), the step limit ``nst_limit``."""
    from pvgraph.solver.ida import UROUND
    from pvgraph.solver.solve import END_FUZZ
    run = _Run()
    run.nst_limit = nst_limit
    run.t_end, run.end_tol = t_end, END_FUZZ * UROUND
    if t_eval is not None:
        run.t_eval_array = t_eval = np.ascontiguousarray(t_eval, dtype=float)
        run.t_eval, run.n_eval = t_eval.ctypes.data, t_eval.size
        rows = t_eval.size
    else:
        run.t_eval, run.n_eval = None, 0
        rows = RUN_ROWS
        run.t_rows = np.empty(rows)
        run.out_t = run.t_rows.ctypes.data
    run.y_rows, run.yp_rows = np.empty((rows, n)), np.empty((rows, n))
    run.out_y, run.out_yp = run.y_rows.ctypes.data, run.yp_rows.ctypes.data
    run.cap = rows
    return run


def _compiled_dense_jacobian(system, jacobian):
    """Is the iteration matrix the system's compiled Jacobian (``jacobian_dense``, or
    ``jacobian`` made dense for the C sparse LU), so pv_jacobian can evaluate it in C?"""
    from pvgraph.solver.linalg import _compiled_owner
    return (_compiled_owner(jacobian.jac) is system
            and not jacobian.sparse and not jacobian.detect
            and system._cmod.n_jac == len(system._rows) == len(system._cols))


def make_integrator(c_step, fun, n, rtol, atol, error_mask, jacobian, lu, max_order, max_step,
                    var_names, no_growth_after_failure, nonnegative, newton_iterate_retry):
    """A CStepIntegrator where it applies (and ``c_step`` is not False), else IDAIntegrator."""
    why = None
    system = c_system_of(fun)
    kern = None
    if c_step is False:
        why = "c_step=False"
    elif system is None:
        why = "the residual is not a System's C-route residual"
    elif n < 2:
        why = "a single unknown"
    elif nonnegative is not None:
        why = "variables are declared non-negative"
    else:
        kern = kernel()
        if kern is None:
            why = f"the step kernel is not available ({kernel_error()})"
    if kern is None:
        if c_step:
            raise ValueError(f"c_step=True but the C step does not apply: {why}")
        return IDAIntegrator(fun, n, rtol, atol, error_mask, jacobian, lu, max_order, max_step,
                             var_names, no_growth_after_failure, nonnegative,
                             newton_iterate_retry)
    return CStepIntegrator(kern, system, fun, n, rtol, atol, error_mask, jacobian, lu,
                           max_order, max_step, var_names, no_growth_after_failure,
                           newton_iterate_retry)
