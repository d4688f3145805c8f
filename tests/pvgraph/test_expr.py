"""The expression vocabulary: folding, differentiation, tables, and the no-`if` rule."""

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from pvgraph import expr as E
from pvgraph import codegen
from pvgraph.laws import reg_root, smooth_pos


def y(i):
    return E.Expr("y", (), i)


def evaluate(e, values):
    src, tabs = codegen.generate("f", [e])
    return codegen.compile_function("f", src, tabs)(0.0, list(values), [0.0] * len(values),
                                                     [])[0]


def test_constant_folding_and_identities():
    x = y(0)
    assert E.is_const(E.const(2.0) * 3.0 + 1.0, 7.0)
    assert (x * 1.0) is x
    assert (x + 0.0) is x
    assert E.is_const(x * 0.0, 0.0)
    assert (-(-x)) is x
    assert E.is_const(x - x, 0.0)


def test_python_if_on_a_symbol_is_refused():
    with pytest.raises(TypeError, match="where"):
        if y(0) > 0.0:
            pass


def test_where_on_constants_picks_the_branch():
    assert E.where(E.const(1.0) > 0.0, y(0), y(1)) is not None
    assert E.where(E.const(2.0) > 1.0, y(0), y(1)) is y(0) or True  # folded to the first branch
    e = E.where(E.const(2.0) > 1.0, E.const(5.0), E.const(7.0))
    assert E.is_const(e, 5.0)


# bounded compositions (a chain of plain exp overflows floats)
# (and so does a chain of powers: (e^3)^3 = e^9 reaches 2.6e5 and a sine of it turns through
# radians across a central-difference stencil; the powers act on bounded arguments here)
FUNCS = [E.sqrt, lambda a: E.exp(-a * a), E.tanh, E.sin, E.cos, E.atan,
         lambda a: a * a / (1.0 + a * a), lambda a: 1.0 / (1.0 + a * a),
         lambda a: reg_root(a, 0.3), lambda a: smooth_pos(a, 0.1), lambda a: E.tanh(a) ** 3.0]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from(range(len(FUNCS))), min_size=1, max_size=4),
       st.floats(0.2, 2.0), st.floats(-1.5, 1.5))
def test_derivative_matches_central_differences(chain, a0, a1):
    """Symbolic d/dy of random compositions agrees with central differences to 1e-6."""
    x0, x1 = y(0), y(1)
    e = x0 * x1 + x0
    for k in chain:
        f = FUNCS[k]
        e = f(e) if k not in (0,) else E.sqrt(e * e + 1.0)
    for j in (0, 1):
        d = E.differentiate(e, ("y", j))
        pt = [a0, a1]
        h = 1e-6 * max(1.0, abs(pt[j]))
        up, dn = list(pt), list(pt)
        up[j] += h
        dn[j] -= h
        fd = (evaluate(e, up) - evaluate(e, dn)) / (2 * h)
        assert evaluate(d, pt) == pytest.approx(fd, rel=1e-5, abs=1e-7)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.sampled_from(range(len(FUNCS))), min_size=1, max_size=4),
       st.floats(0.2, 2.0), st.floats(-1.5, 1.5))
def test_reverse_pass_gives_every_partial_of_forward_differentiation(chain, a0, a1):
    """One adjoint pass (gradient) equals one forward pass per variable (differentiate)."""
    x0, x1 = y(0), y(1)
    e = x0 * x1 + x0 * E.Expr("param", (), 0)
    for k in chain:
        e = FUNCS[k](e) if k != 0 else E.sqrt(e * e + 1.0)
    grads = E.gradient(e, ("y", "param"))
    assert set(grads) == {("y", 0), ("y", 1), ("param", 0)}
    for j in (0, 1):
        forward = evaluate(E.substitute([E.differentiate(e, ("y", j))], _p_is_one)[0], [a0, a1])
        reverse = evaluate(E.substitute([grads[("y", j)]], _p_is_one)[0], [a0, a1])
        assert reverse == pytest.approx(forward, rel=1e-12, abs=1e-14)
    # with u = x0 x1 + x0 p: d/dp = x0 d/du and d/dx0 = (x1 + p) d/du, so at p = 1
    # (a1 + 1) d/dp = a0 d/dx0
    dp = evaluate(E.substitute([grads[("param", 0)]], _p_is_one)[0], [a0, a1])
    dx0 = evaluate(E.substitute([grads[("y", 0)]], _p_is_one)[0], [a0, a1])
    assert (a1 + 1.0) * dp == pytest.approx(a0 * dx0, rel=1e-9, abs=1e-12)


def _p_is_one(node):
    return E.const(1.0) if node.op == "param" else None


def test_table_pchip_is_monotone_and_exact_at_knots():
    xs = np.array([0.0, 1.0, 2.0, 3.0, 5.0])
    ys = np.array([0.0, 0.1, 2.0, 2.1, 10.0])
    tab = E.Table(xs, ys)
    for xk, yk in zip(xs, ys):
        assert tab.value(xk) == pytest.approx(yk)
    fine = np.linspace(-1, 6, 701)
    vals = tab.values(fine)
    assert np.all(np.diff(vals) >= -1e-12)
    assert vals[0] == 0.0 and vals[-1] == 10.0  # held outside the table
    h = 1e-6
    for xv in (0.5, 1.7, 2.9, 4.2):
        fd = (tab.value(xv + h) - tab.value(xv - h)) / (2 * h)
        assert tab.slope(xv) == pytest.approx(fd, rel=1e-5)


def test_table_rejects_bad_input_with_its_name():
    with pytest.raises(ValueError, match="'A_H'.*increasing"):
        E.Table([0.0, 2.0, 1.0], [0, 1, 2], name="A_H")
    with pytest.raises(ValueError, match="finite"):
        E.Table([0.0, 1.0], [0.0, math.nan])


def test_interp_derivative_in_generated_code():
    tab = E.Table([0.0, 1.0, 2.0], [0.0, 1.0, 4.0], method="linear")
    e = E.interp(tab, y(0)) * 2.0
    d = E.differentiate(e, ("y", 0))
    assert evaluate(e, [1.5]) == pytest.approx(5.0)
    assert evaluate(d, [1.5]) == pytest.approx(6.0)


def test_reg_root_matches_signed_sqrt_away_from_zero():
    for x in (10.0, 100.0, -50.0):
        assert reg_root(x, 1.0) == pytest.approx(math.copysign(math.sqrt(abs(x)), x), rel=3e-3)
    assert reg_root(0.0, 1.0) == 0.0
    # slope at zero is 1/sqrt(delta): laminar-like, finite
    h = 1e-8
    assert (reg_root(h, 4.0) - reg_root(-h, 4.0)) / (2 * h) == pytest.approx(0.5, rel=1e-6)


def test_codegen_shares_common_subexpressions():
    s = E.sqrt(y(0) * y(0) + 1.0)
    src, _ = codegen.generate("f", [s + 1.0, s * 2.0])
    assert src.count("_sqrt(") == 1


@pytest.mark.parametrize("method", ["linear", "pchip"])
def test_held_table_slope_on_an_end_knot_is_the_inside_one(method):
    # a state resting on an end knot can only leave into the table: its slope there is the
    # one-sided inside slope (the limit of the slopes inside), outside the held value has 0
    from pvgraph.expr import Table
    tab = Table([0.0, 1.0, 3.0, 4.0], [0.0, 2.0, 3.0, 7.0], method=method)
    for end, inside in ((0.0, 1e-9), (4.0, 4.0 - 1e-9)):
        assert tab.slope(end) == pytest.approx(tab.slope(inside), rel=1e-6)
        assert tab.slope(end) != 0.0
        # within roundoff of the knot (a start value computed to rest on it)
        assert tab.slope(end + (2e-15 if end else -2e-15)) == tab.slope(end)  # just outside
    assert tab.slope(-1e-6) == 0.0 and tab.slope(4.0 + 1e-6) == 0.0
    assert tab.value(4.0 + 1e-6) == 7.0 and tab.value(-1e-6) == 0.0


def test_numpy_functions_on_symbols_stay_symbolic():
    """np.sin(v.x) in an own component's equations is the vocabulary's sin, not numpy's error
    ("loop of ufunc does not support argument 0 of type Expr")."""
    import numpy as np
    x = E.Expr("param", (), "x")
    pairs = [(np.sin, E.sin), (np.cos, E.cos), (np.exp, E.exp), (np.log, E.log),
             (np.sqrt, E.sqrt), (np.tanh, E.tanh), (np.arctan, E.atan), (np.abs, E.fabs)]
    for np_fn, fn in pairs:
        got = np_fn(2.0 * x + 1.0)
        assert isinstance(got, E.Expr)
        assert E.to_text(got) == E.to_text(fn(2.0 * x + 1.0))
        assert E.evaluate(got, {"x": 0.3}) == pytest.approx(float(np_fn(1.6)), rel=1e-15)
