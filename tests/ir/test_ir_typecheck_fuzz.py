"""Property: random well-formed expressions over typed parameters either type-check to bodies
made only of monomorphic builtins and user-level calls, or produce diagnostics; never a crash.

The dimension of every successfully checked constraint side is recomputed here from the
builtins' documented shapes (an independent mini-evaluator) and must match on both sides.
"""
from __future__ import annotations

import tempfile
from pathlib import Path
from unittest.mock import patch

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import gnppdsl.lang.parser as parser_mod
from gnppdsl.ir import builtins as B
from gnppdsl.ir.expr import Call, Constraint, CVar, Index, Num, Param, Vec
from gnppdsl.ir.resolve import Workspace

HEAD = """domain d
type block
continuous pose(o: block) : SE2
frame o: block = pose(o)
template t(a: R, v: R[2], w: R[3], p: SE2, s: SE3, u: quat, o: block) {
  %s
}
"""
LEAVES = ["a", "v", "w", "p", "s", "u", "1", "2.5", "[1, 2]", "[1, 2, 3]", "world(o)", "pose(o)", "pi"]
UNARY = ["-%s", "norm(%s)", "inv(%s)", "pos(%s)", "rot(%s)", "sqrt(%s)", "sum(%s)", "%s[0]", "%s[0:2]", "(%s)"]
BINARY = ["%s + %s", "%s - %s", "%s * %s", "%s / %s", "%s ^ 2", "dot(%s, %s)", "cross(%s, %s)",
          "apply(%s, %s)", "concat(%s, %s)", "min(%s, %s)"]

expr = st.recursive(
    st.sampled_from(LEAVES),
    lambda inner: st.one_of(
        st.tuples(st.sampled_from(UNARY), inner).map(lambda t: t[0] % t[1]),
        st.tuples(st.sampled_from(BINARY), inner, inner).map(
            lambda t: t[0] % ((t[1], t[2]) if t[0].count("%s") == 2 else (t[1],)))),
    max_leaves=6)

DIM = {"a": 1, "v": 2, "w": 3, "p": 3, "s": 7, "u": 4}
SHAPE = {"compose_se2": 3, "inv_se2": 3, "pos_se2": 2, "angle_se2": 1, "apply_se2": 2,
         "compose_se3": 7, "inv_se3": 7, "pos_se3": 3, "rot_se3": 4, "apply_se3": 3, "quat_mul": 4,
         "quat_conj": 4, "quat_rotate": 3, "norm": 1, "sqnorm": 1, "sum": 1, "dot": 1, "cross": 3}


def dim(e) -> int:
    """Independent shape evaluation of a typed body (world poses are SE2 here)."""
    if isinstance(e, Num):
        return 1
    if isinstance(e, Vec):
        return len(e.items)
    if isinstance(e, Param):
        return DIM[e.name]
    if isinstance(e, CVar):
        return 3
    if isinstance(e, Index):
        return 1 if e.stop is None else int(e.stop.value - e.index.value)
    assert isinstance(e, Call)
    if e.fn == "world":
        return 3
    if e.fn in SHAPE:
        return SHAPE[e.fn]
    if e.fn == "concat":
        return sum(dim(a) for a in e.args)
    ds = [dim(a) for a in e.args]
    assert e.fn in ("add", "sub", "mul", "div", "pow", "neg", "sqrt", "min"), e.fn
    if e.fn in ("pow",):
        return ds[0]
    return max(ds)


def calls(e, out):
    if isinstance(e, Call):
        out.add(e.fn)
    for x in getattr(e, "args", ()) + getattr(e, "items", ()):
        calls(x, out)
    if isinstance(e, Index):
        calls(e.base, out)


@settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))
@given(expr, expr, st.sampled_from(["==", "<=", ">="]))
def test_random_expressions(lhs, rhs, op):
    with tempfile.TemporaryDirectory() as tmp, patch.object(parser_mod, "_cache_dir", lambda: None):
        p = Path(tmp) / "d.pntc"
        p.write_text(HEAD % f"{lhs} {op} {rhs}")
        ws = Workspace()
        dom = ws.domain(p)
        ws.reporter.render()
        if ws.reporter.has_errors():
            assert all(d.span is not None for d in ws.reporter.diagnostics)
            return
        (c,) = dom.templates["d.t"].body
        assert isinstance(c, Constraint) and c.op == op
        fns: set = set()
        calls(c.lhs, fns)
        calls(c.rhs, fns)
        assert fns <= set(B.BUILTINS) | {"world"}, fns
        dl, dr = dim(c.lhs), dim(c.rhs)
        assert dl == dr or 1 in (dl, dr), (lhs, rhs, dl, dr)
