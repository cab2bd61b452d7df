"""Session 37 (approx37): no `pytest.approx` in tests/ whose tolerance is silently pytest's default abs=1e-12.

`pytest.approx(expected, rel=r)` accepts |actual - expected| <= max(r |expected|, 1e-12): when r |expected| is below
1e-12, the hidden absolute tolerance, not the stated rel, decides. In this project's SI units that is 1 pm on a
length, 1e-12 on a probability and (1 um)^2 on a variance in m^2: `approx(0.3e-6, rel=1e-12)` claims 3e-19 m and
tests 1e-12 m; `approx((0.71e-6) ** 2 * n)` (a sum of squares in m^2) accepted any value within 1e-12 m^2 of it.

The rule (a static one, so it cannot catch an expected value computed at run time; approx37's run-time audit did
those once, see the test files' `abs=0`): an `approx(...)` call without `abs=` whose expected value is a constant
expression (numbers, + - * / **, tuples and lists, `[x] * n`) must not hold a nonzero number e with
rel * |e| < 1e-12 (rel the call's `rel=`, else pytest's 1e-6). Such a call states its absolute tolerance:
`abs=0` when the rel is the claim, or an abs in the quantity's unit with the reason. Expected values of exactly
0 are left alone: there pytest's abs is visibly the only tolerance a relative comparison can have.
Why rel * |e| and not "a literal below 1e-6": it flags exactly the calls whose tolerance the hidden abs sets
(`approx(0.7, rel=1e-15)` is one, `approx(5e-7, rel=0.1)` is not), with the default rel included.
"""
import ast
import operator
import pathlib

import pytest

TESTS = pathlib.Path(__file__).resolve().parent
HIDDEN_ABS = 1e-12          # pytest.approx's DEFAULT_ABSOLUTE_TOLERANCE
DEFAULT_REL = 1e-6          # pytest.approx's DEFAULT_RELATIVE_TOLERANCE

_BIN = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
        ast.Pow: operator.pow}


def _const(node):
    """The value of a constant numeric expression (a number, or a list of them), else None."""
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
        return node.value
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        v = _const(node.operand)
        if isinstance(v, (int, float)):
            return -v if isinstance(node.op, ast.USub) else v
        return None
    if isinstance(node, (ast.Tuple, ast.List)):
        vals = [_const(e) for e in node.elts]
        return None if any(v is None for v in vals) else vals
    if isinstance(node, ast.BinOp) and type(node.op) in _BIN:
        a, b = _const(node.left), _const(node.right)
        if a is None or b is None:
            return None
        if isinstance(node.op, ast.Mult) and isinstance(a, list) and isinstance(b, int):
            return a * b
        if isinstance(a, list) or isinstance(b, list):
            return None
        try:
            return _BIN[type(node.op)](a, b)
        except (ZeroDivisionError, OverflowError):
            return None
    return None


def _numbers(v):
    return [x for e in v for x in _numbers(e)] if isinstance(v, list) else [v]


def hidden_abs_calls(source, name="<src>"):
    """(name:line, expected source) of every approx call in `source` whose tolerance the hidden abs decides."""
    tree = ast.parse(source)
    out = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call) or not node.args:
            continue
        f = node.func
        if (f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)) != "approx":
            continue
        kw = {k.arg: k.value for k in node.keywords}
        if "abs" in kw:
            continue
        rel = _const(kw["rel"]) if "rel" in kw else DEFAULT_REL
        expected = _const(node.args[0])
        if not isinstance(rel, (int, float)) or expected is None:
            continue
        if any(e != 0 and rel * abs(e) < HIDDEN_ABS for e in _numbers(expected)):
            out.append(f"{name}:{node.lineno}: approx({ast.get_source_segment(source, node.args[0])}, "
                       f"rel={rel}): the default abs=1e-12 sets this tolerance; say abs=")
    return out


def test_no_approx_in_tests_is_decided_by_the_hidden_abs():
    found = []
    for p in sorted(TESTS.rglob("*.py")):
        found += hidden_abs_calls(p.read_text(), str(p.relative_to(TESTS.parent)))
    assert not found, "\n".join(found)


@pytest.mark.parametrize("src, flagged", [
    ("approx(0.3e-6, rel=1e-12)", True),                 # claims 3e-19 m, tests 1e-12 m
    ("pytest.approx(0.305505e-6, rel=1e-6)", True),      # 3e-13 < 1e-12
    ("pytest.approx((0.71e-6) ** 2 * 100)", True),       # a variance in m^2: default rel, 5e-17
    ("approx([1e-3] * 3, rel=1e-12)", True),             # 1e-15 m per element
    ("approx((0.0, 8e-6), rel=1e-9)", True),             # the nonzero element: 8e-15
    ("approx(1e-7)", True),                              # default rel: 1e-13
    ("approx(0.3e-6, rel=1e-12, abs=0)", False),         # said
    ("approx(0.3e-6, rel=1e-12, abs=1e-15)", False),     # said, in the unit
    ("approx(2e-6)", False),                             # 2e-12 >= 1e-12: the rel decides
    ("approx(0.0)", False),                              # 0: the abs is visibly the only tolerance
    ("approx(x, rel=1e-12)", False),                     # not a constant: out of a static rule's reach
    ("approx(1.0, rel=1e-12)", False),                   # 1e-12: the rel (equal to the abs) decides
])
def test_the_guard_flags_what_it_says(src, flagged):
    """The rule's known answers: the guard would fail on each flagged call, and only on those."""
    assert bool(hidden_abs_calls(src)) is flagged
