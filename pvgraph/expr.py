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
"""

from __future__ import annotations

import bisect
import math
from typing import Iterable

import numpy as np

__all__ = [
    "Expr", "Table", "const", "as_expr", "sqrt", "exp", "log", "tanh", "sin", "cos", "atan",
    "fabs", "where", "minimum", "maximum", "clip", "interp", "is_const", "leaves",
    "differentiate",
]

# Operators and their arity. Leaves: const, sym (a named variable before compilation), der (its
# time derivative), y / yp (compiled unknown i and its derivative), time, mode (discrete state).
UNARY = ("neg", "sqrt", "exp", "log", "tanh", "sin", "cos", "atan", "abs")
BINARY = ("add", "sub", "mul", "div", "pow", "lt", "le", "gt", "ge")
COMPARISONS = ("lt", "le", "gt", "ge")
LEAVES = ("const", "sym", "der", "y", "yp", "time", "mode", "cj")


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

    def __bool__(self):
        raise TypeError(
            "an equation branched on a symbolic value with a Python `if` (or `and`/`or`/`min`/"
            "`max`); the branch would be frozen at compile time. Use pvgraph.expr.where(), "
            "minimum()/maximum(), a smooth law from pvgraph.laws, or declare an event.")

    def __float__(self):
        if self.op == "const":
            return float(self.value)
        raise TypeError(f"cannot convert a symbolic expression to float: {self!r}")

    def __repr__(self):
        return to_text(self)


class Table:
    """A 1-D lookup table y(x) for :func:`interp`.

    ``method="linear"`` interpolates linearly; ``"pchip"`` uses a monotone piecewise cubic
    (Fritsch-Carlson), continuously differentiable, which Newton iterations prefer. Outside
    ``[x[0], x[-1]]`` the end values are held (a saturating table) unless ``extrapolate=True``,
    which continues the end segments linearly.
    """

    __slots__ = ("x", "y", "method", "extrapolate", "name", "_xl", "_yl", "_dl", "_n")

    def __init__(self, x, y, *, method: str = "pchip", extrapolate: bool = False,
                 name: str = "table"):
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
        """Derivative dy/dx at a scalar ``xv``."""
        xl, yl = self._xl, self._yl
        if xv <= xl[0] or xv >= xl[-1]:
            if not self.extrapolate:
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
    """A constant node."""
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
    if is_const(a) and is_const(b):
        return const(a.value + b.value)
    if is_const(a, 0.0):
        return b
    if is_const(b, 0.0):
        return a
    if b.op == "neg":
        return _sub(a, b.args[0])
    return Expr("add", (a, b))


def _sub(a, b):
    if is_const(a) and is_const(b):
        return const(a.value - b.value)
    if is_const(b, 0.0):
        return a
    if is_const(a, 0.0):
        return _neg(b)
    if b.op == "neg":
        return _add(a, b.args[0])
    if a is b:
        return ZERO
    return Expr("sub", (a, b))


def _mul(a, b):
    if is_const(a) and is_const(b):
        return const(a.value * b.value)
    if is_const(a, 0.0) or is_const(b, 0.0):
        return ZERO
    if is_const(a, 1.0):
        return b
    if is_const(b, 1.0):
        return a
    if is_const(a, -1.0):
        return _neg(b)
    if is_const(b, -1.0):
        return _neg(a)
    if is_const(b):
        a, b = b, a  # constants first: reads like physics, k * x
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

def postorder(roots: Iterable[Expr]):
    """Every node reachable from ``roots``, children before parents, each once."""
    seen: set[int] = set()
    order: list[Expr] = []
    for root in roots:
        stack = [(root, False)]
        while stack:
            node, expanded = stack.pop()
            if expanded:
                order.append(node)
                continue
            if id(node) in seen:
                continue
            seen.add(id(node))
            stack.append((node, True))
            for arg in reversed(node.args):
                if id(arg) not in seen:
                    stack.append((arg, False))
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
