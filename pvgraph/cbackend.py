"""The residual, Jacobian and event functions as C, built by the machine's C compiler.

An optional evaluation route for a compiled :class:`~pvgraph.system.System`: the same
expressions the Python code is generated from (after the same common-subexpression search and
the same hoisting of parametric subexpressions) are written as C, compiled once into a shared
library with the C compiler found on the machine (``$CC``, ``cc``, ``gcc`` or ``clang``) and
called through :mod:`ctypes`. Nothing extra is installed; without a compiler the Python code
runs as before.

The numbers are those of the Python code. Every operation is the IEEE one Python performs, in
the same order (the generated text keeps every parenthesis): the compiler is told not to
contract multiplications and additions (``-ffp-contract=off``) nor to reassociate, and the
functions are the C library's ``sqrt``, ``exp``, ``log``, ``tanh``, ``sin``, ``cos``, ``atan``
and ``pow`` that Python's :mod:`math` and ``**`` call. Table look-ups are the algorithm of
:class:`~pvgraph.expr.Table` written in C. Where the Python code raises (a square root of a
negative number, a division by zero), C produces NaN or infinity: such an entry is returned
as NaN in its own row (the Python code makes the whole residual NaN); both tell the solver
that the point cannot be evaluated. Where a temporary is computed for a branch of a ``where``
that is not taken, C carries its NaN harmlessly while the Python code fails the whole call:
the only case where the two differ, and C's answer is the right one.

Compiled libraries are cached by the hash of their source in ``$PVGRAPH_CACHE_DIR`` (default
``$XDG_CACHE_HOME/pvgraph`` or ``~/.cache/pvgraph``): a circuit compiled again with other
parameter values (runtime parameters are an argument, not part of the source) reuses the
library without calling the compiler.
"""

from __future__ import annotations

import ctypes
import hashlib
import math
import os
import shutil
import subprocess
import tempfile
import threading
import warnings
from pathlib import Path

import numpy as np

from .codegen import schedule, straight_line
from .expr import postorder
from .errors import PvgraphError

__all__ = ["c_compiler", "CBackendError", "CModule", "build", "cache_dir"]

#: flags that keep the compiled arithmetic the arithmetic of Python: no fused multiply-add,
#: no reassociation, IEEE semantics for NaN and infinity
CFLAGS = ["-O1", "-fPIC", "-shared", "-std=c99", "-ffp-contract=off", "-fno-fast-math",
          "-fno-unsafe-math-optimizations", "-fno-finite-math-only"]

_FUNCS = {"sqrt": "sqrt", "exp": "exp", "log": "log", "tanh": "tanh", "sin": "sin",
          "cos": "cos", "atan": "atan", "abs": "fabs"}
_INFIX = {"add": "+", "sub": "-", "mul": "*", "div": "/",
          "lt": "<", "le": "<=", "gt": ">", "ge": ">="}

# Table look-ups: the algorithm of pvgraph.expr.Table.value / .slope, operation for operation.
# A table is one array: [n, linear (1) or pchip (0), extrapolate (1/0), on-knot tolerance,
# x[0..n), y[0..n), d[0..n)] (d: the pchip slopes at the knots).
_PRELUDE = r"""
#include <math.h>

static int pv_segment(const double *x, int n, double xv)
{
    /* bisect_right(x, xv) - 1, clipped to [0, n - 2] */
    int lo = 0, hi = n;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (xv < x[mid]) hi = mid; else lo = mid + 1;
    }
    int i = lo - 1;
    if (i < 0) i = 0;
    if (i > n - 2) i = n - 2;
    return i;
}

static double pv_value(const double *T, double xv)
{
    int n = (int) T[0];
    const double *x = T + 4, *y = T + 4 + n, *d = T + 4 + 2 * n;
    if (xv <= x[0] || xv >= x[n - 1]) {
        if (T[2] == 0.0) return xv <= x[0] ? y[0] : y[n - 1];
        if (xv <= x[0]) return y[0] + (xv - x[0]) * (y[1] - y[0]) / (x[1] - x[0]);
        return y[n - 1] + (xv - x[n - 1]) * (y[n - 1] - y[n - 2]) / (x[n - 1] - x[n - 2]);
    }
    int i = pv_segment(x, n, xv);
    double h = x[i + 1] - x[i];
    double s = (xv - x[i]) / h;
    if (T[1] != 0.0) return y[i] + s * (y[i + 1] - y[i]);
    double d0 = d[i] * h, d1 = d[i + 1] * h;
    double s2 = s * s, s3 = s * s * s;
    return ((2 * s3 - 3 * s2 + 1) * y[i] + (s3 - 2 * s2 + s) * d0
            + (-2 * s3 + 3 * s2) * y[i + 1] + (s3 - s2) * d1);
}

static double pv_slope(const double *T, double xv)
{
    int n = (int) T[0];
    const double *x = T + 4, *y = T + 4 + n, *d = T + 4 + 2 * n;
    int linear = T[1] != 0.0;
    if (xv <= x[0] || xv >= x[n - 1]) {
        if (T[2] == 0.0) {
            int at_first = fabs(xv - x[0]) <= T[3];
            if (at_first || fabs(xv - x[n - 1]) <= T[3]) {
                int i = at_first ? 0 : n - 2;
                if (linear) return (y[i + 1] - y[i]) / (x[i + 1] - x[i]);
                return at_first ? d[0] : d[n - 1];
            }
            return 0.0;
        }
        int i = xv <= x[0] ? 0 : n - 2;
        return (y[i + 1] - y[i]) / (x[i + 1] - x[i]);
    }
    int i = pv_segment(x, n, xv);
    double h = x[i + 1] - x[i];
    if (linear) return (y[i + 1] - y[i]) / h;
    double s = (xv - x[i]) / h;
    double d0 = d[i] * h, d1 = d[i + 1] * h;
    double s2 = s * s;
    return ((6 * s2 - 6 * s) * y[i] + (3 * s2 - 4 * s + 1) * d0
            + (-6 * s2 + 6 * s) * y[i + 1] + (3 * s2 - 2 * s) * d1) / h;
}

static int pv_finish(double *out, int m)
{
    /* entries that cannot be evaluated become NaN; returns how many */
    int bad = 0;
    for (int i = 0; i < m; i++)
        if (!isfinite(out[i])) { out[i] = NAN; bad++; }
    return bad;
}
"""

_SIGNATURE = ("double t, const double *y, const double *yp, const double *d, const double *P, "
              "const double *const *T")


class CBackendError(PvgraphError):
    """The C route cannot be used (no compiler, a compilation failure, an unsupported system)."""


def c_compiler() -> str | None:
    """The C compiler to use: ``$CC`` if set, else ``cc``, ``gcc`` or ``clang`` on the PATH."""
    cc = os.environ.get("CC")
    if cc:
        return shutil.which(cc) or cc
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


def cache_dir() -> Path:
    """Where compiled libraries are kept (``$PVGRAPH_CACHE_DIR``, else the user cache)."""
    env = os.environ.get("PVGRAPH_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "pvgraph"


def _literal(v: float) -> str:
    if math.isnan(v):
        return "NAN"
    if math.isinf(v):
        return "INFINITY" if v > 0 else "(-INFINITY)"
    return repr(float(v))


class _Tables:
    """The tables the generated code reads, numbered: static ones and runtime slots of P."""

    def __init__(self):
        self.index: dict = {}     # id(table) or ("slot", k) -> position in T
        self.static: dict = {}    # position -> Table
        self.slots: dict = {}     # position -> slot in P

    def ref(self, tab) -> int:
        key = ("slot", tab.slot) if tab.slot is not None else id(tab)
        j = self.index.get(key)
        if j is None:
            j = self.index[key] = len(self.index)
            if tab.slot is not None:
                self.slots[j] = tab.slot
            else:
                self.static[j] = tab
        return j


#: a function gets at most about this many operations: compilers optimise a long function in
#: more than linear time (one function of 36 000 rows took gcc -O1 two minutes), chunks of this
#: size compile in linear time; subexpressions shared between chunks are computed in each
CHUNK_NODES = 2000


def emit(name: str, roots: list, tables: _Tables, *, jacobian: bool = False) -> str:
    """C text of ``int name(t, y, yp, d, P, T[, c], out)`` writing ``roots`` into ``out``.

    The function returns the number of entries that could not be evaluated (set to NaN). Long
    lists of roots are split into chunks of about :data:`CHUNK_NODES` operations, each a
    function of its own, called in order.
    """
    chunks, size, current = [], 0, []
    for r in roots:
        k = len(postorder([r], limit=CHUNK_NODES) or ()) or CHUNK_NODES
        if current and size + k > CHUNK_NODES:
            chunks.append(current)
            current, size = [], 0
        current.append(r)
        size += k
    if current or not chunks:
        chunks.append(current)
    if len(chunks) == 1:
        return _emit_one(name, roots, tables, jacobian)
    parts, calls, offset = [], [], 0
    for i, chunk in enumerate(chunks):
        parts.append(_emit_one(f"{name}_{i}", chunk, tables, jacobian, offset))
        calls.append(f"    _{name}_{i}(t, y, yp, d, P, T{', c' if jacobian else ''}, out);")
        offset += len(chunk)
    sig = _SIGNATURE + (", double c" if jacobian else "") + ", double *out"
    parts.append("\n".join([f"int {name}({sig})", "{", *calls,
                             f"    return pv_finish(out, {len(roots)});", "}"]) + "\n")
    return "\n".join(parts)


def _emit_one(name, roots, tables, jacobian, offset=None) -> str:
    """One C function writing ``roots`` to ``out`` (from ``offset`` on, as a chunk)."""
    rep, key_of, uses = schedule(roots)

    def expression(node, a):
        op = node.op
        if op in _INFIX:
            return f"({a[0]} {_INFIX[op]} {a[1]})"
        if op == "pow":
            return f"pow({a[0]}, {a[1]})"
        if op == "neg":
            return f"(-{a[0]})"
        if op == "where":
            return f"({a[0]} ? {a[1]} : {a[2]})"
        if op in ("interp", "interp_d"):
            fn = "pv_value" if op == "interp" else "pv_slope"
            return f"{fn}(T[{tables.ref(node.value)}], {a[0]})"
        if op in _FUNCS:
            return f"{_FUNCS[op]}({a[0]})"
        raise CBackendError(f"operation {op!r} has no C form")

    if not jacobian and any(node.op == "cj" for node in rep):
        raise CBackendError("the Jacobian's c appears outside the Jacobian")
    text, body = straight_line(rep, key_of, uses, _literal, expression,
                               lambda tmp, s: f"    const double {tmp} = {s};")
    sig = _SIGNATURE + (", double c" if jacobian else "") + ", double *out"
    if offset is None:
        lines = [f"int {name}({sig})", "{"]
    else:
        lines = [f"static void _{name}({sig})", "{"]
    lines.extend(body)
    base = offset or 0
    lines.extend(f"    out[{base + i}] = {text[key_of[id(r)]]};" for i, r in enumerate(roots))
    if offset is None:
        lines.append(f"    return pv_finish(out, {len(roots)});")
    lines.append("}")
    return "\n".join(lines) + "\n"


def _table_array(tab) -> np.ndarray:
    n = tab.x.size
    d = np.asarray(tab._dl, dtype=float)
    return np.concatenate([[float(n), 1.0 if tab.method == "linear" else 0.0,
                            1.0 if tab.extrapolate else 0.0, tab._on_knot],
                           tab.x, tab.y, d]).astype(float)


class CModule:
    """A compiled library: the residual, Jacobian and event functions of one system's code."""

    def __init__(self, path: Path, tables: _Tables, n_res: int, n_jac: int, n_ev: int,
                 source: str):
        self.path = path
        self.tables = tables
        self.n_res, self.n_jac, self.n_ev = n_res, n_jac, n_ev
        self.source = source
        lib = ctypes.CDLL(str(path))
        vp, dbl = ctypes.c_void_p, ctypes.c_double
        self.residual = lib.pv_residual
        self.jacobian = lib.pv_jacobian
        self.events = lib.pv_events
        for fn, extra in ((self.residual, []), (self.jacobian, [dbl]), (self.events, [])):
            fn.argtypes = [dbl, vp, vp, vp, vp, vp] + extra + [vp]
            fn.restype = ctypes.c_int
        self._lib = lib
        self._static = {j: _table_array(tab) for j, tab in tables.static.items()}


class CState:
    """One system's buffers for a :class:`CModule`: parameters, tables, arguments, outputs.

    Copies of a system (other parameter values) share the module and get a state of their own.
    """

    def __init__(self, module: CModule, P: list, n: int, n_modes: int):
        self.module = module
        self.thread = threading.get_ident()    # the thread these buffers belong to
        self.P = np.array([v if isinstance(v, float) else
                           (float(v) if isinstance(v, int) else math.nan) for v in P],
                          dtype=float)
        self._arrays = []
        ptrs = (ctypes.c_void_p * max(1, len(module.tables.index)))()
        for j, arr in module._static.items():
            ptrs[j] = arr.ctypes.data
        for j, slot in module.tables.slots.items():
            arr = _table_array(P[slot])
            self._arrays.append(arr)
            ptrs[j] = arr.ctypes.data
        self.T = ptrs
        self.y = np.zeros(n)
        self.yp = np.zeros(n)
        self.d = np.zeros(max(1, n_modes))
        self.res_out = np.empty(module.n_res)
        self.jac_out = np.empty(module.n_jac)
        self.ev_out = np.empty(max(1, module.n_ev))
        self.args = (self.y.ctypes.data, self.yp.ctypes.data, self.d.ctypes.data,
                     self.P.ctypes.data, ctypes.addressof(ptrs))
        self.res_ptr = self.res_out.ctypes.data
        self.jac_ptr = self.jac_out.ctypes.data
        self.ev_ptr = self.ev_out.ctypes.data


def source_text(res, jac, ev) -> tuple[str, _Tables]:
    """The whole C source for the hoisted residual, Jacobian and event expressions."""
    tables = _Tables()
    parts = [_PRELUDE,
             emit("pv_residual", res, tables),
             emit("pv_jacobian", jac, tables, jacobian=True),
             emit("pv_events", ev, tables)]
    return "\n".join(parts), tables


class LoadOnce:
    """A library loaded on first use, once per process: ``get()`` is the library or None,
    ``error`` why it could not be loaded (a missing compiler, a failed build or check)."""

    def __init__(self, load):
        self._load = load
        self._value = None
        self.error = None
        self._lock = threading.Lock()

    def get(self):
        if self._value is None and self.error is None:
            with self._lock:
                if self._value is None and self.error is None:
                    try:
                        self._value = self._load()
                    except Exception as exc:     # the caller falls back and reports it
                        self.error = f"{type(exc).__name__}: {exc}"
        return self._value


def build(res, jac, ev, *, name: str = "system") -> CModule:
    """Write, compile (or find in the cache) and load the C form of these expressions."""
    source, tables = source_text(res, jac, ev)
    path = compiled(source, name)
    return CModule(path, tables, len(res), len(jac), len(ev), source)


def compiled(source: str, name: str, opt: str = "-O1") -> Path:
    """The shared library of C ``source`` (``name`` for messages), built with CFLAGS by the
    machine's compiler, or found in the cache by the hash of source, compiler and flags.

    ``opt`` is the optimisation level: ``-O1`` for generated code (it can be megabytes; its
    build time grows fast with the level), ``-O3`` for the solver's fixed kernels. None of the
    levels reorders floating-point arithmetic (CFLAGS forbid it), so the numbers do not
    depend on it."""
    cc = c_compiler()
    if cc is None:
        raise CBackendError("no C compiler found (set CC, or install cc, gcc or clang); the "
                            "Python code runs without one")
    flags = [opt if f == "-O1" else f for f in CFLAGS]
    digest = hashlib.sha256("\0".join([source, cc] + flags).encode()).hexdigest()[:24]
    return _cached(digest, source, cc, name, flags)


def _cached(digest: str, source: str, cc: str, name: str, flags: list) -> Path:
    folder = cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f".w{os.getpid()}"
        probe.touch()
        probe.unlink()
    except OSError:
        folder = Path(tempfile.mkdtemp(prefix="pvgraph-c-"))   # a private folder instead
    lib = folder / f"pv_{digest}{'.dll' if os.name == 'nt' else '.so'}"
    if lib.exists():
        try:
            os.utime(lib)     # most recently used: kept by _trim
        except OSError:
            pass
        return lib
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        src = Path(tmp) / "system.c"
        src.write_text(source)
        out = Path(tmp) / "system.so"
        try:
            proc = subprocess.run([cc, *flags, "-o", str(out), str(src), "-lm"],
                                  capture_output=True, text=True)
        except OSError as exc:
            raise CBackendError(f"{name}: cannot run the C compiler {cc!r} ({exc.strerror}); "
                                f"set CC to a C compiler, or use the Python code") from None
        if proc.returncode != 0 or not out.exists():
            tail = "\n".join(proc.stderr.strip().splitlines()[-8:])
            raise CBackendError(f"{name}: the C compiler {cc} failed on the generated code "
                                f"(exit {proc.returncode}):\n{tail}")
        os.replace(out, lib)   # atomic: a concurrent build of the same source is harmless
    _trim(folder)
    return lib


#: the cache keeps this many libraries, the most recently used
CACHE_MAX_FILES = 400


def _trim(folder: Path) -> None:
    """Remove the least recently used libraries beyond :data:`CACHE_MAX_FILES`."""
    try:
        libs = sorted(folder.glob("pv_*"), key=lambda f: f.stat().st_mtime)
        for f in libs[:max(0, len(libs) - CACHE_MAX_FILES)]:
            f.unlink()
    except OSError:
        pass      # another process trims too, or a file is in use: next time


def try_build(res, jac, ev, *, name: str, required: bool):
    """:func:`build`, or None with a warning when ``required`` is False and it cannot be done."""
    try:
        return build(res, jac, ev, name=name)
    except CBackendError as exc:
        if required:
            raise
        warnings.warn(f"{exc}; using the Python code", RuntimeWarning, stacklevel=3)
        return None
