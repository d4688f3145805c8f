"""Symbolic expressions: the small math vocabulary component equations are written in.

A component's ``equations`` method is called once, at compile time, with symbols instead of
numbers. Operator overloading records an expression graph. From that graph the compiler reads the
exact incidence of every equation, differentiates it for an exact sparse Jacobian, and emits flat
Python functions for the residual and the Jacobian values (see :mod:`pvgraph.codegen`).

The vocabulary: ``+ - * / **``, comparisons (only inside :func:`where`), :func:`sqrt`, :func:`exp`,
:func:`log`, :func:`tanh`, :func:`sin`, :func:`cos`, :func:`atan`, :func:`fabs`, :func:`where`,
:func:`minimum`, :func:`maximum`, :func:`clip` and table interpolation :func:`interp`. Smooth
regularisations of the hydraulic laws built from these live in :mod:`pvgraph.laws`.

An expression has no truth value: ``if p > 0:`` inside an equation raises, because a Python branch
on a variable would be taken once at trace time and silently frozen. Use :func:`where`, a smooth
law, or an event.

Parameters are leaves too (``param``): while a component is traced, its numeric parameters are
symbols whose values the compiled functions receive at run time, so one compiled system runs with
other parameter values (``math.sqrt`` and the other ``math`` functions of the vocabulary stay
symbolic while tracing). A parameter that the equations turn into a plain number (``float()``,
a Python ``if``/``min``/``max`` or ``==`` on it, a table built from it) is *structural*: its
value is baked into the compiled code and :class:`ParameterTrace` records it, so that changing it
later recompiles (or is refused) by name.
"""

from __future__ import annotations

import bisect
import math
import threading
from typing import Iterable

import numpy as np

__all__ = [
    "Expr", "Table", "const", "as_expr", "sqrt", "exp", "log", "tanh", "sin", "cos", "atan",
    "fabs", "where", "minimum", "maximum", "clip", "interp", "is_const", "leaves",
    "differentiate", "gradient", "evaluate", "ParameterTrace", "active_trace", "is_parametric",
]

# Operators and their arity. Leaves: const, sym (a named variable before compilation), der (its
# time derivative), y / yp (compiled unknown i and its derivative), time, mode (discrete state),
# param (a runtime parameter: its dotted name while tracing, its index once compiled).
UNARY = ("neg", "sqrt", "exp", "log", "tanh", "sin", "cos", "atan", "abs")
BINARY = ("add", "sub", "mul", "div", "pow", "lt", "le", "gt", "ge")
COMPARISONS = ("lt", "le", "gt", "ge")
LEAVES = ("const", "sym", "der", "y", "yp", "time", "mode", "cj", "param")
# leaves whose value does not change during a run: an expression of these only is a number for
# any one run (a "parametric" expression)
FIXED_LEAVES = ("const", "param")


class Expr:
    """A node of an expression graph.

    ``op`` names the operation, ``args`` holds child nodes and ``value`` the payload of leaves
    (a float for ``const``, a variable name for ``sym``/``der``, an index for ``y``/``yp``/``mode``,
    a :class:`Table` for ``interp``).
    """

    __slots__ = ("op", "args", "value")
    __array_priority__ = 1000  # numpy scalars defer to Expr in mixed arithmetic

    def __init__(self, op: str, args: tuple = (), value=None):
        self.op = op
        self.args = args
        self.value = value

    # arithmetic ---------------------------------------------------------------------------
    def __add__(self, other):
        return _add(self, as_expr(other))

    def __radd__(self, other):
        return _add(as_expr(other), self)

    def __sub__(self, other):
        return _sub(self, as_expr(other))

    def __rsub__(self, other):
        return _sub(as_expr(other), self)

    def __mul__(self, other):
        return _mul(self, as_expr(other))

    def __rmul__(self, other):
        return _mul(as_expr(other), self)

    def __truediv__(self, other):
        return _div(self, as_expr(other))

    def __rtruediv__(self, other):
        return _div(as_expr(other), self)

    def __neg__(self):
        return _neg(self)

    def __pos__(self):
        return self

    def __pow__(self, other):
        return _pow(self, as_expr(other))

    def __rpow__(self, other):
        base = as_expr(other)
        if is_const(base):
            return exp(self * math.log(base.value))
        return _pow(base, self)

    def __abs__(self):
        return fabs(self)

    # numpy's functions call these on objects: np.sin(v.x) in equations stays symbolic
    def sqrt(self):
        return sqrt(self)

    def exp(self):
        return exp(self)

    def log(self):
        return log(self)

    def tanh(self):
        return tanh(self)

    def sin(self):
        return sin(self)

    def cos(self):
        return cos(self)

    def arctan(self):
        return atan(self)

    # comparisons build condition nodes for `where`; equality keeps identity semantics so that
    # expressions can live in sets and dicts.
    def __lt__(self, other):
        return _cmp("lt", self, as_expr(other))

    def __le__(self, other):
        return _cmp("le", self, as_expr(other))

    def __gt__(self, other):
        return _cmp("gt", self, as_expr(other))

    def __ge__(self, other):
        return _cmp("ge", self, as_expr(other))

    __hash__ = object.__hash__

    def __eq__(self, other):
        # ``p.x == 0`` on a traced parameter compares values (a structural use); expressions
        # otherwise compare by identity so that they can live in sets and dicts
        if not isinstance(other, Expr) and active_trace() is not None and \
                isinstance(other, (int, float)) and is_parametric(self):
            return active_trace().number(self, "compared with ==") == other
        return self is other

    def __ne__(self, other):
        result = self.__eq__(other)
        return not result

    def __bool__(self):
        if active_trace() is not None and is_parametric(self):
            return bool(active_trace().number(self, "used in a Python `if`/`and`/`or`/"
                                                           "`min`/`max`"))
        raise TypeError(
            "an equation branched on a symbolic value with a Python `if` (or `and`/`or`/`min`/"
            "`max`); the branch would be frozen at compile time. Use pvgraph.expr.where(), "
            "minimum()/maximum(), a smooth law from pvgraph.laws, or declare an event.")

    def __float__(self):
        if self.op == "const":
            return float(self.value)
        if active_trace() is not None and is_parametric(self):
            return float(active_trace().number(self, "converted to a number (float(), "
                                                            "math.*, a table)"))
        raise TypeError(f"cannot convert a symbolic expression to float: {self!r}")

    def __int__(self):
        return int(float(self))

    def __index__(self):
        if active_trace() is not None and is_parametric(self):
            return int(active_trace().number(self, "used as an integer"))
        raise TypeError(f"cannot use a symbolic expression as an integer: {self!r}")

    def __round__(self, ndigits=None):
        return round(float(self), ndigits)

    def __repr__(self):
        return to_text(self)


_LOCAL = threading.local()   # the trace active in this thread


def active_trace() -> "ParameterTrace | None":
    """The :class:`ParameterTrace` of the compilation running in this thread, if any."""
    return getattr(_LOCAL, "trace", None)


class ParameterTrace:
    """The parameter values of a compilation and the parameters used structurally.

    While active (``with ParameterTrace(values):``), a parametric expression (constants and
    parameters only) used as a Python number or truth value is evaluated with ``values`` and
    every parameter in it is recorded in :attr:`structural` with the reason, under the label
    of :attr:`where` (the component being traced).
    """

    def __init__(self, values: dict):
        self.values = values
        self.structural: dict[str, str] = {}
        self.where = ""
        self._leaves: dict[str, Expr] = {}
        self.tables: list = []    # runtime tables built from parameter arrays

    def leaf(self, name: str, value: float) -> "Expr":
        """The one parameter leaf named ``name`` (shared, so ``k - k`` folds to zero)."""
        node = self._leaves.get(name)
        if node is None:
            node = self._leaves[name] = Expr("param", (), name)
            self.values.setdefault(name, value)
        return node

    def __enter__(self):
        self._outer = active_trace()
        _LOCAL.trace = self
        if self._outer is None:
            _patch_math()
        return self

    def __exit__(self, *exc):
        _LOCAL.trace = self._outer
        if self._outer is None:
            _unpatch_math()

    def number(self, e: "Expr", how: str) -> float:
        """The value of the parametric expression ``e``; its parameters become structural."""
        for op, name in leaves(e, ("param",)):
            self.structural.setdefault(name, f"{how} in {self.where}" if self.where else how)
        return evaluate(e, self.values)


# While parameters are traced, the functions of the ``math`` module that the vocabulary has
# accept expressions and return expressions (``math.sqrt(2 / p.rho)`` in a component stays a
# function of the runtime parameter); on numbers they are the ``math`` functions themselves.
_MATH_NAMES = ("sqrt", "exp", "log", "tanh", "sin", "cos", "atan", "fabs")
_MATH_ORIGINAL = {name: getattr(math, name) for name in _MATH_NAMES}
_MATH_LOCK = threading.Lock()
_MATH_USERS = [0]   # compilations running (in any thread) that need the symbolic versions


def _symbolic_math(name, original):
    def fn(x, *rest):
        if isinstance(x, Expr) and not rest:
            return globals()[name](x)
        return original(x, *rest)
    fn.__name__ = name
    fn.__doc__ = original.__doc__
    return fn


_MATH_SYMBOLIC = {name: _symbolic_math(name, fn) for name, fn in _MATH_ORIGINAL.items()}


def _patch_math():
    with _MATH_LOCK:
        _MATH_USERS[0] += 1
        if _MATH_USERS[0] == 1:
            for name, fn in _MATH_SYMBOLIC.items():
                setattr(math, name, fn)


def _unpatch_math():
    with _MATH_LOCK:
        _MATH_USERS[0] -= 1
        if _MATH_USERS[0] == 0:
            for name, fn in _MATH_ORIGINAL.items():
                setattr(math, name, fn)


class ParamValues(tuple):
    """A parameter array (a tuple field of numbers) while tracing.

    Handed to :class:`Table` it makes a runtime table; read element by element (iterated,
    indexed, converted by numpy) it is a structural use, recorded like ``float()`` on a scalar.
    """

    def __new__(cls, values, name):
        self = super().__new__(cls, values)
        self.name = name
        self.raw = tuple(values)
        return self

    def _structural(self):
        trace = active_trace()
        if trace is not None:
            trace.structural.setdefault(
                self.name, f"read element by element in {trace.where}" if trace.where else
                "read element by element")

    def __iter__(self):
        self._structural()
        return iter(self.raw)

    def __getitem__(self, k):
        self._structural()
        return self.raw[k]

    def __reduce__(self):
        return (tuple, (self.raw,))


def is_parametric(e: "Expr") -> bool:
    """True if ``e`` depends on constants and parameters only (a number for any one run)."""
    if e.op in FIXED_LEAVES:
        return True
    if e.op in LEAVES:
        return False
    stack = list(e.args)
    seen = set()
    while stack:
        n = stack.pop()
        if id(n) in seen:
            continue
        seen.add(id(n))
        if n.op in LEAVES:
            if n.op not in FIXED_LEAVES:
                return False
            continue
        stack.extend(n.args)
    return True


class Table:
    """A 1-D lookup table y(x) for :func:`interp`.

    ``method="linear"`` interpolates linearly; ``"pchip"`` uses a monotone piecewise cubic
    (Fritsch-Carlson), continuously differentiable, which Newton iterations prefer. Outside
    ``[x[0], x[-1]]`` the end values are held (a saturating table) unless ``extrapolate=True``,
    which continues the end segments linearly.
    """

    __slots__ = ("x", "y", "method", "extrapolate", "name", "_xl", "_yl", "_dl", "_n",
                 "sources", "slot", "_on_knot")

    #: a point within this fraction of the span of an end knot is on the knot (:meth:`slope`)
    ON_KNOT = 1e-12

    def __init__(self, x, y, *, method: str = "pchip", extrapolate: bool = False,
                 name: str = "table"):
        # a table built from parameter arrays while tracing is a runtime table: the compiled
        # system rebuilds it when those parameters change (see ParamValues)
        self.sources = (x.name if isinstance(x, ParamValues) else None,
                        y.name if isinstance(y, ParamValues) else None)
        self.slot = None
        if isinstance(x, ParamValues):
            x = x.raw
        if isinstance(y, ParamValues):
            y = y.raw
        if any(self.sources) and active_trace() is not None:
            active_trace().tables.append(self)
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        if x.ndim != 1 or y.shape != x.shape or x.size < 2:
            raise ValueError(f"table {name!r}: x and y must be 1-D arrays of the same length "
                             f">= 2, got shapes {x.shape} and {y.shape}")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
            raise ValueError(f"table {name!r}: x and y must be finite")
        if np.any(np.diff(x) <= 0):
            raise ValueError(f"table {name!r}: x must be strictly increasing")
        if method not in ("linear", "pchip"):
            raise ValueError(f"table {name!r}: method must be 'linear' or 'pchip', not {method!r}")
        self.x, self.y, self.method, self.extrapolate, self.name = x, y, method, extrapolate, name
        self._xl = x.tolist()
        self._yl = y.tolist()
        self._dl = (_pchip_slopes(x, y) if method == "pchip" else
                    np.zeros_like(x)).tolist()
        self._n = x.size
        self._on_knot = self.ON_KNOT * float(x[-1] - x[0])

    def with_values(self, x=None, y=None) -> "Table":
        """A table like this one with other knots or values (same method and name)."""
        return Table(self.x if x is None else x, self.y if y is None else y,
                     method=self.method, extrapolate=self.extrapolate, name=self.name)

    def _segment(self, xv):
        return min(max(bisect.bisect_right(self._xl, xv) - 1, 0), self._n - 2)

    def value(self, xv: float) -> float:
        """Interpolated value at a scalar ``xv``."""
        xl, yl = self._xl, self._yl
        if xv <= xl[0] or xv >= xl[-1]:
            return self._outside(xv)
        i = self._segment(xv)
        h = xl[i + 1] - xl[i]
        s = (xv - xl[i]) / h
        if self.method == "linear":
            return yl[i] + s * (yl[i + 1] - yl[i])
        d0, d1 = self._dl[i] * h, self._dl[i + 1] * h
        s2, s3 = s * s, s * s * s
        return ((2 * s3 - 3 * s2 + 1) * yl[i] + (s3 - 2 * s2 + s) * d0
                + (-2 * s3 + 3 * s2) * yl[i + 1] + (s3 - s2) * d1)

    def slope(self, xv: float) -> float:
        """Derivative dy/dx at a scalar ``xv``.

        Exactly on an end knot of a held table the slope is the one of the table's inside,
        not the zero of the held outside: a state resting on the end (a start value, a spool
        on the last point of its area table) can only leave into the table, and Newton
        iterations starting there need that derivative (with the zero one the iteration
        matrix misses the table's whole influence and the corrector diverges). "On the knot"
        allows a few units of roundoff (``ON_KNOT`` times the table's span), since a value
        computed to rest on the knot lands on either side of it. Farther outside the held
        value has slope 0.
        """
        xl, yl = self._xl, self._yl
        if xv <= xl[0] or xv >= xl[-1]:
            if not self.extrapolate:
                at_first = abs(xv - xl[0]) <= self._on_knot
                if at_first or abs(xv - xl[-1]) <= self._on_knot:
                    i = 0 if at_first else self._n - 2
                    if self.method == "linear":
                        return (yl[i + 1] - yl[i]) / (xl[i + 1] - xl[i])
                    return self._dl[0] if at_first else self._dl[-1]
                return 0.0
            i = 0 if xv <= xl[0] else self._n - 2
            return (yl[i + 1] - yl[i]) / (xl[i + 1] - xl[i])
        i = self._segment(xv)
        h = xl[i + 1] - xl[i]
        if self.method == "linear":
            return (yl[i + 1] - yl[i]) / h
        s = (xv - xl[i]) / h
        d0, d1 = self._dl[i] * h, self._dl[i + 1] * h
        s2 = s * s
        return ((6 * s2 - 6 * s) * yl[i] + (3 * s2 - 4 * s + 1) * d0
                + (-6 * s2 + 6 * s) * yl[i + 1] + (3 * s2 - 2 * s) * d1) / h

    def _outside(self, xv):
        xl, yl = self._xl, self._yl
        if not self.extrapolate:
            return yl[0] if xv <= xl[0] else yl[-1]
        if xv <= xl[0]:
            return yl[0] + (xv - xl[0]) * (yl[1] - yl[0]) / (xl[1] - xl[0])
        return yl[-1] + (xv - xl[-1]) * (yl[-1] - yl[-2]) / (xl[-1] - xl[-2])

    def values(self, xs) -> np.ndarray:
        """Vectorised :meth:`value`."""
        xs = np.asarray(xs, dtype=float)
        return np.vectorize(self.value, otypes=[float])(xs)

    def slopes(self, xs) -> np.ndarray:
        """Vectorised :meth:`slope`."""
        xs = np.asarray(xs, dtype=float)
        return np.vectorize(self.slope, otypes=[float])(xs)

    def __call__(self, xv):
        if isinstance(xv, Expr):
            return interp(self, xv)
        if np.ndim(xv):
            return self.values(xv)
        return self.value(float(xv))

    def __repr__(self):
        return f"Table({self.name!r}, {self._n} points, {self.method})"


def _pchip_slopes(x, y):
    """Fritsch-Carlson monotone slopes at the knots (the scheme of scipy's PchipInterpolator)."""
    h = np.diff(x)
    delta = np.diff(y) / h
    d = np.zeros_like(y)
    if x.size == 2:
        d[:] = delta[0]
        return d
    for k in range(1, x.size - 1):
        if delta[k - 1] * delta[k] <= 0:
            d[k] = 0.0
        else:
            w1 = 2 * h[k] + h[k - 1]
            w2 = h[k] + 2 * h[k - 1]
            d[k] = (w1 + w2) / (w1 / delta[k - 1] + w2 / delta[k])
    d[0] = _pchip_end(h[0], h[1], delta[0], delta[1])
    d[-1] = _pchip_end(h[-1], h[-2], delta[-1], delta[-2])
    return d


def _pchip_end(h0, h1, m0, m1):
    """One-sided three-point end slope, limited to keep monotonicity."""
    d = ((2 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
    if np.sign(d) != np.sign(m0):
        return 0.0
    if np.sign(m0) != np.sign(m1) and abs(d) > abs(3 * m0):
        return 3 * m0
    return d


# construction with constant folding ---------------------------------------------------------

def const(value: float) -> Expr:
    """A constant node (a parametric expression, constant during a run, passes through)."""
    if isinstance(value, Expr) and is_parametric(value):
        return value
    return Expr("const", (), float(value))


ZERO = const(0.0)
ONE = const(1.0)
CJ = Expr("cj")  # the leading coefficient c in dF/dy + c*dF/dyp


def as_expr(value) -> Expr:
    """Wrap a number as a constant expression; pass expressions through."""
    if isinstance(value, Expr):
        return value
    if isinstance(value, (int, float, np.integer, np.floating)):
        return const(float(value))
    if isinstance(value, np.ndarray) and value.ndim == 0:
        return const(float(value))
    raise TypeError(f"cannot use a {type(value).__name__} in an equation: {value!r}")


def is_const(e: Expr, value: float | None = None) -> bool:
    """True if ``e`` is a constant (equal to ``value`` if given)."""
    return e.op == "const" and (value is None or e.value == value)


def _add(a, b):
    if a.op == "const":
        if b.op == "const":
            return const(a.value + b.value)
        if a.value == 0.0:
            return b
    elif b.op == "const" and b.value == 0.0:
        return a
    if b.op == "neg":
        return _sub(a, b.args[0])
    return Expr("add", (a, b))


def _sub(a, b):
    if b.op == "const":
        if a.op == "const":
            return const(a.value - b.value)
        if b.value == 0.0:
            return a
    elif a.op == "const" and a.value == 0.0:
        return _neg(b)
    if b.op == "neg":
        return _add(a, b.args[0])
    if a is b:
        return ZERO
    return Expr("sub", (a, b))


def _mul(a, b):
    if a.op == "const":
        if b.op == "const":
            return const(a.value * b.value)
        v = a.value
        if v == 0.0:
            return ZERO
        if v == 1.0:
            return b
        if v == -1.0:
            return _neg(b)
        return Expr("mul", (a, b))
    if b.op == "const":
        v = b.value
        if v == 0.0:
            return ZERO
        if v == 1.0:
            return a
        if v == -1.0:
            return _neg(a)
        return Expr("mul", (b, a))  # constants first: reads like physics, k * x
    if a.op == "neg" and b.op == "neg":
        return _mul(a.args[0], b.args[0])
    return Expr("mul", (a, b))


def _div(a, b):
    if is_const(b):
        if b.value == 0.0:
            raise ZeroDivisionError("division by a constant zero in an equation")
        if is_const(a):
            return const(a.value / b.value)
        return _mul(const(1.0 / b.value), a)
    if is_const(a, 0.0):
        return ZERO
    return Expr("div", (a, b))


def _neg(a):
    if is_const(a):
        return const(-a.value)
    if a.op == "neg":
        return a.args[0]
    return Expr("neg", (a,))


def _pow(a, b):
    if is_const(a) and is_const(b):
        return const(a.value ** b.value)
    if is_const(b, 1.0):
        return a
    if is_const(b, 0.0):
        return ONE
    if is_const(b, 0.5):
        return sqrt(a)
    return Expr("pow", (a, b))


def _cmp(op, a, b):
    return Expr(op, (a, b))


def _unary(op, fn):
    def build(x):
        x = as_expr(x)
        if is_const(x):
            return const(fn(x.value))
        return Expr(op, (x,))
    return build


sqrt = _unary("sqrt", math.sqrt)
exp = _unary("exp", math.exp)
log = _unary("log", math.log)
tanh = _unary("tanh", math.tanh)
sin = _unary("sin", math.sin)
cos = _unary("cos", math.cos)
atan = _unary("atan", math.atan)
fabs = _unary("abs", abs)
sqrt.__doc__ = "Square root."
exp.__doc__ = "Exponential."
log.__doc__ = "Natural logarithm."
tanh.__doc__ = "Hyperbolic tangent."
sin.__doc__ = "Sine."
cos.__doc__ = "Cosine."
atan.__doc__ = "Arc tangent."
fabs.__doc__ = "Absolute value (kinked at zero; prefer pvgraph.laws.smooth_abs in flow laws)."


def where(cond, a, b) -> Expr:
    """``a`` where ``cond`` holds, else ``b``.

    ``cond`` is a comparison (``x > 0``) or an expression read as true when non-zero (a mode).
    A switch on a continuous variable is a discontinuity for the solver unless both branches agree
    at the switching point; use it for kinks, for modes changed by events, or with care.
    """
    cond = as_expr(cond)
    a, b = as_expr(a), as_expr(b)
    if cond.op == "const":
        return a if cond.value else b
    if cond.op in COMPARISONS and is_const(cond.args[0]) and is_const(cond.args[1]):
        x, y = cond.args[0].value, cond.args[1].value
        holds = {"lt": x < y, "le": x <= y, "gt": x > y, "ge": x >= y}[cond.op]
        return a if holds else b
    if a is b:
        return a
    if is_const(a) and is_const(b) and a.value == b.value:
        return a
    return Expr("where", (cond, a, b))


def minimum(a, b) -> Expr:
    """Non-smooth minimum (kinked where a == b)."""
    a, b = as_expr(a), as_expr(b)
    return where(a < b, a, b)


def maximum(a, b) -> Expr:
    """Non-smooth maximum (kinked where a == b)."""
    a, b = as_expr(a), as_expr(b)
    return where(a > b, a, b)


def clip(x, lo, hi) -> Expr:
    """``x`` limited to ``[lo, hi]`` (kinked at the limits)."""
    return minimum(maximum(x, lo), hi)


def interp(table: Table, x) -> Expr:
    """Table lookup ``table(x)``; differentiable (its slope is a table of its own)."""
    x = as_expr(x)
    if is_const(x):
        return const(table.value(x.value))
    return Expr("interp", (x,), table)


# graph utilities ----------------------------------------------------------------------------

def postorder(roots: Iterable[Expr], limit: int | None = None):
    """Every node reachable from ``roots``, children before parents, each once.

    Depth first, children left to right. With ``limit``, ``None`` as soon as there are more
    than ``limit`` nodes.
    """
    seen: set[int] = set()
    order: list[Expr] = []
    add = seen.add
    emit = order.append
    for root in roots:
        if id(root) in seen:
            continue
        add(id(root))
        if not root.args:
            emit(root)
            continue
        # each frame holds a node and the iterator over its children; a leaf child is emitted
        # at once, an inner one gets a frame (the loop resumes the parent's iterator after it)
        stack = [(root, iter(root.args))]
        push = stack.append
        while stack:
            node, children = stack[-1]
            for a in children:
                if id(a) not in seen:
                    add(id(a))
                    if limit is not None and len(seen) > limit:
                        return None
                    if a.args:
                        push((a, iter(a.args)))
                        break
                    emit(a)
            else:
                stack.pop()
                emit(node)
        if limit is not None and len(seen) > limit:
            return None
    return order


def leaves(e: Expr, ops: tuple[str, ...]) -> list:
    """The distinct payloads of the leaves of kind ``ops`` (e.g. ``("sym", "der")``) in ``e``."""
    found = {}
    for node in postorder([e]):
        if node.op in ops:
            found[(node.op, node.value)] = None
    return list(found)


def substitute(roots: list[Expr], fn) -> list[Expr]:
    """Rebuild ``roots`` with every leaf replaced by ``fn(leaf)`` (``None`` keeps it).

    Rebuilding runs the constant folding again, so substituting constants simplifies.
    """
    memo: dict[int, Expr] = {}
    for node in postorder(roots):
        if node.op in LEAVES:
            new = fn(node)
            memo[id(node)] = node if new is None else new
            continue
        args = tuple(memo[id(a)] for a in node.args)
        if all(n is o for n, o in zip(args, node.args)):
            memo[id(node)] = node
        else:
            memo[id(node)] = rebuild(node, args)
    return [memo[id(r)] for r in roots]


def rebuild(node: Expr, args: tuple) -> Expr:
    """The node's operation applied to new arguments, with folding."""
    op = node.op
    if op == "add":
        return _add(*args)
    if op == "sub":
        return _sub(*args)
    if op == "mul":
        return _mul(*args)
    if op == "div":
        return _div(*args)
    if op == "pow":
        return _pow(*args)
    if op == "neg":
        return _neg(*args)
    if op in COMPARISONS:
        return _cmp(op, *args)
    if op == "where":
        return where(*args)
    if op == "interp":
        return interp(node.value, args[0])
    if op == "interp_d":
        return Expr("interp_d", args, node.value) if not is_const(args[0]) else \
            const(node.value.slope(args[0].value))
    return {"sqrt": sqrt, "exp": exp, "log": log, "tanh": tanh, "sin": sin, "cos": cos,
            "atan": atan, "abs": fabs}[op](args[0])


def differentiate(e: Expr, wrt: tuple[str, object], memo: dict | None = None) -> Expr:
    """Symbolic partial derivative of ``e`` with respect to the leaf ``wrt = (op, value)``.

    ``memo`` (keyed by node identity) may be shared between calls with the same ``wrt``.
    """
    memo = {} if memo is None else memo
    for node in postorder([e]):
        if id(node) in memo:
            continue
        memo[id(node)] = _derivative(node, wrt, memo)
    return memo[id(e)]


_NUMERIC = {"neg": lambda a: -a, "sqrt": math.sqrt, "exp": math.exp, "log": math.log,
            "tanh": math.tanh, "sin": math.sin, "cos": math.cos, "atan": math.atan, "abs": abs,
            "add": lambda a, b: a + b, "sub": lambda a, b: a - b, "mul": lambda a, b: a * b,
            "div": lambda a, b: a / b, "pow": lambda a, b: a ** b,
            "lt": lambda a, b: a < b, "le": lambda a, b: a <= b, "gt": lambda a, b: a > b,
            "ge": lambda a, b: a >= b}


def evaluate(e: Expr, params) -> float:
    """The number a parametric expression stands for; ``params[payload]`` gives parameters.

    Other leaves are read from ``params.leaf(node)`` where ``params`` has that method.
    """
    if e.op == "const":
        return e.value
    if e.op == "param":
        return params[e.value]
    val: dict[int, float] = {}
    for node in postorder([e]):
        op = node.op
        if op == "const":
            val[id(node)] = node.value
        elif op == "param":
            val[id(node)] = params[node.value]
        elif op in LEAVES:
            if not hasattr(params, "leaf"):
                raise TypeError(f"cannot evaluate {to_text(e)}: it depends on {to_text(node)}")
            val[id(node)] = params.leaf(node)
        elif op == "where":
            c, a, b = (val[id(x)] for x in node.args)
            val[id(node)] = a if c else b
        elif op in ("interp", "interp_d"):
            tab = node.value
            if tab.slot is not None and hasattr(params, "table"):
                tab = params.table(tab)
            xv = val[id(node.args[0])]
            val[id(node)] = tab.value(xv) if op == "interp" else tab.slope(xv)
        else:
            val[id(node)] = _NUMERIC[op](*(val[id(x)] for x in node.args))
    return float(val[id(e)])


def gradient(root: Expr, ops: tuple[str, ...] = ("y", "yp", "param")) -> dict:
    """Every partial derivative of ``root`` with respect to its leaves of kind ``ops``.

    One reverse (adjoint) pass over the graph of ``root``: the cost is linear in its size
    however many leaves it has, and the adjoints are dropped as soon as they are propagated.
    Returns ``{(op, payload): derivative}`` with an entry for every such leaf in ``root`` (the
    derivative may fold to zero).
    """
    order = postorder([root])
    # subtrees of constants and parameters only need no adjoints unless parameters are asked for
    skip: set[int] = set()
    if "param" not in ops:
        for node in order:
            if node.op in FIXED_LEAVES or (node.op not in LEAVES and
                                            all(id(a) in skip for a in node.args)):
                skip.add(id(node))
    adj: dict[int, Expr] = {id(root): ONE}
    grads: dict = {}
    for node in reversed(order):  # parents before children
        a = adj.pop(id(node), ZERO)
        op = node.op
        if op in LEAVES:
            if op in ops:
                key = (op, node.value)
                grads[key] = _add(grads[key], a) if key in grads else a
            continue
        if id(node) in skip:
            continue
        if is_const(a, 0.0):
            for x in node.args:  # keep the incidence of every leaf below
                _touch(adj, x)
            continue
        for child, contrib in _adjoints(node, a):
            if id(child) in skip:
                continue
            k = id(child)
            old = adj.get(k)
            adj[k] = contrib if old is None else _add(old, contrib)
        if op in ("where", "interp_d") or op in COMPARISONS:
            for x in node.args:
                _touch(adj, x)
    return grads


def _touch(adj, child):
    adj.setdefault(id(child), ZERO)


def _adjoints(node, a):
    """``(child, a * d node / d child)`` for the children of ``node``."""
    op = node.op
    x = node.args
    if op == "add":
        return ((x[0], a), (x[1], a))
    if op == "sub":
        return ((x[0], a), (x[1], _neg(a)))
    if op == "neg":
        return ((x[0], _neg(a)),)
    if op == "mul":
        return ((x[0], _mul(a, x[1])), (x[1], _mul(x[0], a)))
    if op == "div":
        return ((x[0], _div(a, x[1])), (x[1], _neg(_div(_mul(a, node), x[1]))))
    if op == "pow":
        base, expo = x
        out = [(base, _mul(a, _mul(expo, _pow(base, _sub(expo, ONE)))))]
        if not is_const(expo):
            out.append((expo, _mul(a, _mul(node, log(base)))))
        return out
    if op == "sqrt":
        return ((x[0], _div(_mul(const(0.5), a), node)),)
    if op == "exp":
        return ((x[0], _mul(a, node)),)
    if op == "log":
        return ((x[0], _div(a, x[0])),)
    if op == "tanh":
        return ((x[0], _mul(a, _sub(ONE, _mul(node, node)))),)
    if op == "sin":
        return ((x[0], _mul(a, cos(x[0]))),)
    if op == "cos":
        return ((x[0], _neg(_mul(a, sin(x[0])))),)
    if op == "atan":
        return ((x[0], _div(a, _add(ONE, _mul(x[0], x[0])))),)
    if op == "abs":
        return ((x[0], where(x[0] >= 0.0, a, _neg(a))),)
    if op == "where":
        return ((x[1], where(x[0], a, ZERO)), (x[2], where(x[0], ZERO, a)))
    if op == "interp":
        return ((x[0], _mul(a, Expr("interp_d", (x[0],), node.value))),)
    if op in COMPARISONS or op == "interp_d":
        return ()
    raise NotImplementedError(f"no derivative rule for {op!r}")


def _derivative(node, wrt, memo):
    op = node.op
    if op in LEAVES:
        return ONE if (op, node.value) == wrt else ZERO
    if op in COMPARISONS or op == "interp_d":
        return ZERO
    d = [memo[id(a)] for a in node.args]
    a = node.args
    if op == "add":
        return _add(d[0], d[1])
    if op == "sub":
        return _sub(d[0], d[1])
    if op == "neg":
        return _neg(d[0])
    if op == "mul":
        return _add(_mul(d[0], a[1]), _mul(a[0], d[1]))
    if op == "div":
        # (u/v)' = u'/v - (u/v) v'/v
        return _sub(_div(d[0], a[1]), _div(_mul(node, d[1]), a[1]))
    if op == "pow":
        base, expo = a
        if is_const(expo):
            return _mul(_mul(expo, _pow(base, const(expo.value - 1.0))), d[0])
        if is_const(d[1], 0.0):
            return _mul(_mul(expo, _pow(base, _sub(expo, ONE))), d[0])
        return _mul(node, _add(_mul(d[1], log(base)), _div(_mul(expo, d[0]), base)))
    if op == "sqrt":
        return _div(_mul(const(0.5), d[0]), node)
    if op == "exp":
        return _mul(node, d[0])
    if op == "log":
        return _div(d[0], a[0])
    if op == "tanh":
        return _mul(_sub(ONE, _mul(node, node)), d[0])
    if op == "sin":
        return _mul(cos(a[0]), d[0])
    if op == "cos":
        return _neg(_mul(sin(a[0]), d[0]))
    if op == "atan":
        return _div(d[0], _add(ONE, _mul(a[0], a[0])))
    if op == "abs":
        return where(a[0] >= 0.0, d[0], _neg(d[0]))
    if op == "where":
        return where(a[0], d[1], d[2])
    if op == "interp":
        if is_const(d[0], 0.0):
            return ZERO
        return _mul(Expr("interp_d", (a[0],), node.value), d[0])
    raise NotImplementedError(f"no derivative rule for {op!r}")


# printing -----------------------------------------------------------------------------------

_INFIX = {"add": "+", "sub": "-", "mul": "*", "div": "/", "pow": "**",
          "lt": "<", "le": "<=", "gt": ">", "ge": ">="}
_PREC = {"add": 1, "sub": 1, "mul": 2, "div": 2, "neg": 3, "pow": 4,
         "lt": 0, "le": 0, "gt": 0, "ge": 0}


def to_text(e: Expr, names=None, _prec=0) -> str:
    """Human-readable infix text of ``e`` (for messages and generated-code comments)."""
    op = e.op
    if op == "const":
        return repr(e.value)
    if op == "sym":
        return e.value
    if op == "der":
        return f"der({e.value})"
    if op in ("y", "yp"):
        label = names[e.value] if names else f"{op}[{e.value}]"
        return label if op == "y" else f"der({label})"
    if op == "time":
        return "t"
    if op == "mode":
        return f"mode[{e.value}]"
    if op == "cj":
        return "c"
    if op == "param":
        return e.value if isinstance(e.value, str) else f"P[{e.value}]"
    if op in _INFIX:
        p = _PREC[op]
        left = to_text(e.args[0], names, p)
        right = to_text(e.args[1], names, p + (op in ("sub", "div", "pow")))
        text = f"{left} {_INFIX[op]} {right}"
        return f"({text})" if p < _prec else text
    if op == "neg":
        return f"-{to_text(e.args[0], names, 3)}"
    if op == "where":
        return "where({}, {}, {})".format(*(to_text(a, names) for a in e.args))
    if op in ("interp", "interp_d"):
        return f"{op}({e.value.name}, {to_text(e.args[0], names)})"
    return f"{op}({to_text(e.args[0], names)})"
