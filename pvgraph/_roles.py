"""Port roles of the no-pressure-reference check, read once per component template.

The check of :func:`pvgraph.circuit._pressure_islands` needs, per component, which ports a
flow path joins, which ports fix the pressure level and which are volumes (its *port roles*),
from the leaves of the component's residuals traced with numbers. Instances built from one
template (:mod:`pvgraph._templates`) are one symbolic graph up to the names of their leaves,
so their roles follow from the template's graph, by port name, wherever tracing with numbers
keeps the same leaves.

Tracing with numbers is the symbolic graph with each parameter a number and the folding of
:mod:`pvgraph.expr` run again. That folding drops a variable's leaf only where an operand
made of parameters takes a special value: a product with 0, a quotient of 0, a power to 0,
and, through the identities it then finds (``1 * x - x``, ``neg(neg(x))``), a sum with 0, a
product with +-1, a quotient by +-1, a power to 1; where a ``where`` condition is made of
parameters only, a branch is picked; where both branches are, they may fold into one; a
parametric base of a power is a logarithm when traced with numbers. So, per instance, every
operand made of parameters is evaluated (over the instances of a template at once, as arrays):
an instance keeps the template's roles when none of those values is special or not finite
(a non-finite value is an error or another graph when traced with numbers); a template with a
parametric condition, a parametric power base or a table look-up keeps none. One instance of
each template is traced with numbers as a check; the instances not covered are traced as
before.
"""

from __future__ import annotations

import operator

import numpy as np

from . import expr as E

#: operand values at which tracing with numbers may fold leaves away (see the module docstring)
_SPECIAL = (0.0, 1.0, -1.0, 0.5)

_ARRAY_OPS = {
    "neg": np.negative, "sqrt": np.sqrt, "exp": np.exp, "log": np.log, "tanh": np.tanh,
    "sin": np.sin, "cos": np.cos, "atan": np.arctan, "abs": np.abs, "add": np.add,
    "sub": np.subtract, "mul": np.multiply, "div": np.divide, "pow": np.power,
    "lt": np.less, "le": np.less_equal, "gt": np.greater, "ge": np.greater_equal,
}


def _operands(residuals):
    """``(order, checked)`` of a template's residuals: the nodes made of parameters (with at
    least one parameter leaf), children first, and those whose value decides a fold (the
    operands of nodes not made of parameters; by id); None where no instance can keep the
    template's roles."""
    fixed: dict[int, bool] = {}     # id -> made of constants and parameters only
    has_param: dict[int, bool] = {}
    order = []
    checked: dict[int, E.Expr] = {}
    for node in E.postorder(list(residuals)):
        op = node.op
        if op in ("interp", "interp_d"):
            return None
        if not node.args:
            fixed[id(node)] = op in E.FIXED_LEAVES
            has_param[id(node)] = op == "param"
            continue
        if op not in _ARRAY_OPS and op != "where":
            return None
        kids_fixed = [fixed[id(a)] for a in node.args]
        fixed[id(node)] = all(kids_fixed)
        has_param[id(node)] = any(has_param[id(a)] for a in node.args)
        if fixed[id(node)]:
            if has_param[id(node)]:
                if op == "where":
                    return None     # a branch picked by parameters
                order.append(node)
            continue
        for k, a in enumerate(node.args):
            if not (kids_fixed[k] and has_param[id(a)]):
                continue
            if op == "where" and (k == 0 or all(kids_fixed[1:])):
                return None     # a parametric condition, or branches that may fold into one
            if op == "pow" and k == 0:
                return None     # a parametric base: exp(x * log(base)) traced with numbers
            checked[id(a)] = a
    return order, checked


def _kept(order, checked, columns, n):
    """Boolean mask of the instances whose operands in ``checked`` are neither special nor
    non-finite and whose values made of parameters are all finite; ``order`` and ``checked``
    as :func:`_operands` gives them, ``columns``: parameter name -> its values (an array)."""
    ok = np.ones(n, dtype=bool)
    val: dict[int, np.ndarray] = {}

    def value(node):
        if node.op == "const":
            return node.value
        if node.op == "param":
            return columns[node.value]
        return val[id(node)]
    with np.errstate(all="ignore"):
        for node in order:
            got = np.asarray(_ARRAY_OPS[node.op](*map(value, node.args)), dtype=float)
            val[id(node)] = got
            ok &= np.isfinite(got)
        for col in columns.values():
            ok &= np.isfinite(col)
        for node in checked.values():
            got = value(node)
            for special in _SPECIAL:
                ok &= got != special
    return ok


def template_roles(instances, registry, roles_of, traced_roles) -> dict:
    """``{path: port roles}`` of the template-built instances whose numeric trace keeps the
    template's leaves.

    ``instances``: template -> ``[(path, component), ...]`` built from it (the template's own
    instance first); ``registry``: parameter name -> :class:`~pvgraph.component.
    ParameterInfo`; ``roles_of(residuals, comp, path)``: the roles read from residuals (None
    for a component without hydraulic ports); ``traced_roles(comp, path)``: the roles of a
    numeric trace (the check).
    """
    out = {}
    for tpl, members in instances.items():
        comp0 = members[0][1]
        roles = roles_of(tpl.residuals, comp0, tpl.path)
        if roles is None or any(kind != "leaf" for _, kind, _, _ in tpl.reads):
            continue
        found = _operands(tpl.residuals)
        if found is None:
            continue
        order, checked = found
        params = {n.value for n in E.postorder(list(tpl.residuals)) if n.op == "param"}
        head = tpl.path + "."
        paths = [p for p, _ in members]
        models = [c.params for _, c in members]
        columns = {}
        for nm in params:
            if nm.startswith(head):
                # the value registered for the instance's parameter: its model's field
                field = operator.attrgetter(registry[nm].field)
                columns[nm] = np.fromiter(map(field, models), dtype=float, count=len(paths))
            else:
                columns[nm] = np.full(len(paths), float(registry[nm].value))
        ok = _kept(order, checked, columns, len(paths))
        if not ok.any():
            continue
        first = int(np.argmax(ok))
        path0, comp0 = members[first]
        if traced_roles(comp0, path0) != roles:
            continue
        for k in np.flatnonzero(ok):
            out[paths[k]] = roles
    return out
