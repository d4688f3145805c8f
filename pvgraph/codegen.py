"""Emit flat Python functions from expression graphs.

The compiled residual and Jacobian are straight-line Python over floats: one function, no calls
back into the component objects, shared subexpressions computed once (common subexpressions are
found structurally across every equation of the circuit). ``System.source()`` prints the text.

Two flavours: ``"scalar"`` for the solver (``math`` functions on Python floats, the fastest way
to evaluate small expressions in CPython) and ``"array"`` for post-processing a whole solution at
once (``numpy`` functions on arrays of time points).

Big circuits repeat a few equation shapes thousands of times (every orifice of a manifold, every
segment of a line). :func:`row_shape` gives a residual row's shape (its graph with the variables,
derivatives, parameters and modes numbered by first appearance) and the leaves it reads; rows of
one shape are emitted once, as a :func:`template` in the array flavour, and evaluated over arrays
of their instances' values (see :mod:`pvgraph.system`).
"""

from __future__ import annotations

import math

import numpy as np

from .expr import Expr, postorder

__all__ = ["generate", "compile_function", "row_shape", "schedule", "template"]

# A node that would nest deeper than this is stored in a temporary, to keep generated lines short
# and well inside the parser's nesting limit.
MAX_INLINE_DEPTH = 12

_SCALAR_FUNCS = {"sqrt": "_sqrt", "exp": "_exp", "log": "_log", "tanh": "_tanh", "sin": "_sin",
                 "cos": "_cos", "atan": "_atan", "abs": "abs"}
_ARRAY_FUNCS = {"sqrt": "_np.sqrt", "exp": "_np.exp", "log": "_np.log", "tanh": "_np.tanh",
                "sin": "_np.sin", "cos": "_np.cos", "atan": "_np.arctan", "abs": "_np.abs"}
# rows evaluated over arrays of instances: numpy arithmetic, square root and absolute value (exact
# like Python's), and the transcendental functions of ``math`` element by element, so that every
# instance gets the very numbers of the straight-line code (numpy's own exp, tanh, ... may differ
# from ``math``'s in the last bit)
_ROWS_FUNCS = {"sqrt": "_np.sqrt", "exp": "_mexp", "log": "_mlog", "tanh": "_mtanh",
               "sin": "_msin", "cos": "_mcos", "atan": "_matan", "abs": "_np.abs"}
_INFIX = {"add": "+", "sub": "-", "mul": "*", "div": "/", "pow": "**",
          "lt": "<", "le": "<=", "gt": ">", "ge": ">="}


def generate(name: str, roots: list[Expr], *, flavour: str = "scalar",
             extra_args: tuple[str, ...] = (), comments: list[str] | None = None):
    """Source text of ``def name(t, y, yp, d, *extra_args)`` returning the list of ``roots``.

    ``flavour``: ``"scalar"`` (Python floats), ``"array"`` (numpy on arrays of time points) or
    ``"rows"`` (arrays of instances, the numbers of the scalar flavour; no table look-ups).

    Returns ``(source, tables)``: the text and the :class:`~pvgraph.expr.Table` objects it
    references (to be bound as ``_tab0``, ``_tab1``, ... in its namespace).
    """
    funcs = {"scalar": _SCALAR_FUNCS, "array": _ARRAY_FUNCS, "rows": _ROWS_FUNCS}[flavour]
    rep, key_of, uses = schedule(roots)

    tables: list = []
    table_names: dict[int, str] = {}

    def expression(node, a):
        op = node.op
        if op in _INFIX:
            return f"({a[0]} {_INFIX[op]} {a[1]})"
        if op == "neg":
            return f"(-{a[0]})"
        if op == "where":
            if flavour == "scalar":
                return f"({a[1]} if {a[0]} else {a[2]})"
            return f"_np.where({a[0]}, {a[1]}, {a[2]})"
        if op in ("interp", "interp_d"):
            tab = node.value
            if tab.slot is not None:  # a runtime table: it lives in the parameter vector
                table_names[id(tab)] = f"P[{tab.slot}]"
            elif id(tab) not in table_names:
                table_names[id(tab)] = f"_tab{len(tables)}"
                tables.append(tab)
            method = {("interp", "scalar"): "value", ("interp_d", "scalar"): "slope",
                      ("interp", "array"): "values", ("interp_d", "array"): "slopes"}
            return f"{table_names[id(tab)]}.{method[(op, flavour)]}({a[0]})"
        return f"{funcs[op]}({a[0]})"

    tables: list = []
    text, body = straight_line(rep, key_of, uses, _float, expression,
                               lambda tmp, s: f"    {tmp} = {s}")

    out = []
    for i, r in enumerate(roots):
        line = f"        {text[key_of[id(r)]]},"
        if comments is not None:
            line += f"  # {comments[i]}"
        out.append(line)
    params = ", ".join(("t", "y", "yp", "d") + tuple(extra_args))
    src = [f"def {name}({params}):"]
    src.extend(body)
    src.append("    return [")
    src.extend(out)
    src.append("    ]")
    return "\n".join(src) + "\n", tables


def schedule(roots: list[Expr]):
    """The distinct subexpressions of ``roots`` in evaluation order, found structurally.

    Returns ``(rep, key_of, uses)``: one representative node per distinct subexpression,
    children before parents; ``key_of[id(node)]`` the position of any node's representative;
    ``uses[k]`` how often representative ``k`` is read (by other nodes and as a root). Equal
    subtrees share one key, so generated code computes them once.
    """
    key_of: dict[int, int] = {}
    table: dict[tuple, int] = {}
    rep: list[Expr] = []
    for node in postorder(roots):
        if node.op == "const":
            sig = ("const", node.value)
        elif node.op in ("y", "yp", "mode", "time", "sym", "der", "cj", "param"):
            sig = (node.op, node.value)
        elif node.op in ("interp", "interp_d"):
            sig = (node.op, id(node.value), key_of[id(node.args[0])])
        else:
            sig = (node.op,) + tuple(key_of[id(a)] for a in node.args)
        k = table.get(sig)
        if k is None:
            k = table[sig] = len(rep)
            rep.append(node)
        key_of[id(node)] = k

    uses = [0] * len(rep)
    for node in rep:
        for a in node.args:
            uses[key_of[id(a)]] += 1
    for r in roots:
        uses[key_of[id(r)]] += 1
    return rep, key_of, uses


def straight_line(rep, key_of, uses, literal, expression, assign,
                  max_depth: int = MAX_INLINE_DEPTH):
    """Texts of the nodes :func:`schedule` returned, and the lines computing the temporaries.

    A node read more than once, or nested deeper than ``max_depth``, is computed once into a
    temporary ``_0``, ``_1``, ... (``assign(name, text)`` writes that line); the others are
    written inline. ``expression(node, arg_texts)`` writes an operation, ``literal(value)`` a
    constant. Returns ``(text, body)``: per node the text that reads it, and the lines.
    """
    text = [""] * len(rep)
    depth = [0] * len(rep)
    body: list[str] = []
    for k, node in enumerate(rep):
        leaf = leaf_text(node, literal)
        if leaf is not None:
            text[k] = leaf
            continue
        args = [key_of[id(a)] for a in node.args]
        s = expression(node, [text[i] for i in args])
        depth[k] = 1 + max((depth[i] for i in args), default=0)
        if uses[k] > 1 or depth[k] > max_depth:
            tmp = f"_{len(body)}"
            body.append(assign(tmp, s))
            text[k] = tmp
            depth[k] = 0
        else:
            text[k] = s
    return text, body


def leaf_text(node: Expr, literal) -> str | None:
    """The text of a leaf in generated code (Python and C read them alike), or None.

    ``literal(value)`` writes a constant. Arguments: ``t``, ``y``, ``yp``, modes ``d``,
    parameters ``P`` and the Jacobian's ``c``.
    """
    op = node.op
    if op == "const":
        return literal(node.value)
    if op in ("y", "yp"):
        return f"{op}[{node.value}]"
    if op == "mode":
        return f"d[{node.value}]"
    if op == "param":
        return f"P[{node.value}]"
    if op == "time":
        return "t"
    if op == "cj":
        return "c"
    if op in ("sym", "der"):
        raise ValueError(f"unresolved symbol {node.value!r} reached code generation")
    return None


def _float(v: float) -> str:
    if math.isnan(v):
        return "_nan"
    if math.isinf(v):
        return "_inf" if v > 0 else "(-_inf)"
    return repr(float(v))


def _elementwise(fn):
    """``fn`` of ``math`` applied to each element of an array; NaN where it raises."""
    def safe(x):
        try:
            return fn(x)
        except (ValueError, OverflowError):
            return math.nan
    ufunc = np.frompyfunc(safe, 1, 1)

    def apply(x):
        out = ufunc(x)
        return out.astype(float) if isinstance(out, np.ndarray) else float(out)
    apply.__name__ = fn.__name__
    return apply


_ROWS_NAMESPACE = {f"_m{fn.__name__}": _elementwise(fn)
                   for fn in (math.exp, math.log, math.tanh, math.sin, math.cos, math.atan)}


def compile_function(name: str, source: str, tables: list):
    """Execute generated ``source`` and return the function ``name`` defined in it."""
    namespace = {
        "_sqrt": math.sqrt, "_exp": math.exp, "_log": math.log, "_tanh": math.tanh,
        "_sin": math.sin, "_cos": math.cos, "_atan": math.atan, "_np": np,
        "_nan": math.nan, "_inf": math.inf, **_ROWS_NAMESPACE,
    }
    for i, tab in enumerate(tables):
        namespace[f"_tab{i}"] = tab
    code = compile(source, f"<pvgraph generated {name}>", "exec")
    exec(code, namespace)  # noqa: S102 - the source is generated by pvgraph from expressions
    return namespace[name]



#: leaves a row template takes per instance (from arrays gathered at each call)
SLOT_LEAVES = ("y", "yp", "param", "mode")


def _compiled_leaf(node):
    return (node.op, node.value) if node.op in SLOT_LEAVES else None


#: rows whose left-most chain of sums is longer than this are not templated (see row_shape)
MAX_SHAPE_CHAIN = 64


def long_sum(root: Expr) -> bool:
    """True where ``root``'s chain of left operands of sums is longer than
    :data:`MAX_SHAPE_CHAIN` (a node's flow balance of many ports), found without walking it
    further."""
    node, depth = root, 0
    while node.op == "add" or node.op == "sub":
        depth += 1
        if depth > MAX_SHAPE_CHAIN:
            return True
        node = node.args[0]
    return False


def row_shape(root: Expr, leaf_of=None):
    """``(shape, leaves)`` of a residual row, or None for a row that is not templated.

    ``shape`` is hashable and equal for two rows exactly when they are the same graph (node for
    node, shared nodes included) over the same constants, with leaves numbered per kind in order
    of first appearance: one template computes both. ``leaves`` maps each kind of
    :data:`SLOT_LEAVES` to its payloads in slot order. ``leaf_of(node)`` gives the
    ``(kind, payload)`` a leaf stands for (default: compiled leaves stand for themselves), or
    None for a leaf that is not one of them. Rows with such leaves or table look-ups (a table
    per instance) return None.
    """
    leaf_of = leaf_of or _compiled_leaf
    if long_sum(root):   # a shape of its own: not walked
        return None
    # the shape is a flat token sequence: an operation followed by its children's positions,
    # "const" and its value, a leaf kind and its slot (prefix-free, since arities are fixed).
    # Nodes are numbered in the order of :func:`~pvgraph.expr.postorder` (depth first,
    # children left to right, each once), walked here in the same loop that writes the tokens.
    num: dict[int, int] = {}
    sig: list = []
    put = sig.append
    slots: dict[tuple, int] = {}
    leaves: dict[str, list] = {"y": [], "yp": [], "param": [], "mode": []}

    def leaf(node):
        op = node.op
        if op == "const":
            v = node.value
            put("const")
            put(v if v != 0.0 else repr(v))
            return True
        if op == "time":
            put("time")
            return True
        key = leaf_of(node)
        if key is None:
            return False
        s = slots.get(key)
        if s is None:
            group = leaves[key[0]]
            s = slots[key] = len(group)
            group.append(key[1])
        put(key[0])
        put(s)
        return True

    if not root.args:
        if not leaf(root):
            return None
    else:
        seen = {id(root)}
        add = seen.add
        stack = [(root, iter(root.args))]
        push, pop = stack.append, stack.pop
        while stack:
            node, children = stack[-1]
            for a in children:
                if id(a) not in seen:
                    add(id(a))
                    if a.args:
                        push((a, iter(a.args)))
                        break
                    num[id(a)] = len(num)
                    if not leaf(a):
                        return None
            else:
                pop()
                op = node.op
                if op == "interp" or op == "interp_d":
                    return None
                num[id(node)] = len(num)
                put(op)
                for a in node.args:
                    put(num[id(a)])
    # which derivative slots read the same unknown as a value slot (their Jacobian entries merge)
    pairs = tuple(slots.get(("y", v), -1) for v in leaves["yp"])
    return (tuple(sig), pairs), leaves


def template(root: Expr, leaves: dict, leaf_of=None) -> Expr:
    """A copy of ``root`` (node for node, no folding) whose leaves are slots, not payloads.

    ``leaves`` and ``leaf_of`` are those of :func:`row_shape` for ``root``: a leaf standing
    for ``y[j]`` becomes ``y[s]`` where ``j`` is the payload of slot ``s``, and so on for
    ``yp``, ``param`` and ``mode``.
    """
    leaf_of = leaf_of or _compiled_leaf
    slot = {(op, v): s for op, vals in leaves.items() for s, v in enumerate(vals)}
    memo: dict[int, Expr] = {}
    for node in postorder([root]):
        if node.args:
            memo[id(node)] = Expr(node.op, tuple([memo[id(a)] for a in node.args]), node.value)
        elif node.op in ("const", "time"):
            memo[id(node)] = node
        else:
            key = leaf_of(node)
            memo[id(node)] = Expr(key[0], (), slot[key])
    return memo[id(root)]
