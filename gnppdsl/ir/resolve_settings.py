"""Settings blocks (`solver { ... }`, `relaxations { ... }`, `reachability NAME { ... }`) ->
`model.SolverSettings`, `Relaxation`, `Reachability`.

Separate because domains and problems both have these blocks (a problem's override the
domain's): each function takes its owner `res` (a `DomainResolver` or a `ProblemResolver`)
and uses only its `err`, `tags_seen`, actions and continuous variables.
"""
from __future__ import annotations

from gnppdsl.ir import model as M
from gnppdsl.lang import ast
from gnppdsl.lang.diagnostics import did_you_mean

MEASURES = ("travel",)


def _setting_value(res, s: ast.Setting, want: type):
    v = s.value
    if want is bool:
        if v.kind != "name" or v.value not in ("true", "false"):
            res.err(v.span, f"'{s.key.value}' must be true or false", "setting")
            return None
        return v.value == "true"
    if want in (int, float):
        if v.kind != "number":
            res.err(v.span, f"'{s.key.value}' must be a number", "setting")
            return None
        if want is int and not float(v.value).is_integer():
            res.err(v.span, f"'{s.key.value}' must be an integer", "setting")
            return None
        return want(v.value)
    if want is str:
        if v.kind not in ("string", "name"):
            res.err(v.span, f"'{s.key.value}' must be a name or a string", "setting")
            return None
        return v.value
    return v


def _new_known_key(res, s, fields, seen, block: str) -> bool:
    """A `key = value` of a settings block is usable: a known key, not set before in the block.
    Reports the problem (with a did-you-mean hint) otherwise."""
    k = s.key.value
    if k not in fields:
        res.err(s.key.span, f"unknown {block} setting '{k}'", "unknown-setting",
                did_you_mean(k, fields) or "settings: " + ", ".join(fields))
        return False
    if k in seen:
        res.err(s.key.span, f"'{k}' is set twice", "duplicate")
        return False
    return True


def settings_solver(res, d: ast.SolverDecl, base: M.SolverSettings) -> M.SolverSettings:
    vals = {}
    for s in d.settings:
        k = s.key.value
        if not _new_known_key(res, s, M.SOLVER_FIELDS, vals, "solver"):
            continue
        if k == "kinematic_curvature":       # true, false or auto
            if s.value.kind not in ("name", "string") or s.value.value not in M.KINEMATIC_CURVATURE_VALUES:
                res.err(s.value.span, "'kinematic_curvature' must be true, false or auto", "setting")
                continue
            vals[k] = M.KINEMATIC_CURVATURE_VALUES[s.value.value]
            continue
        v = _setting_value(res, s, M.SOLVER_FIELDS[k])
        if v is None:
            continue
        if k == "algorithm" and v not in M.SOLVER_ALGORITHMS:
            res.err(s.value.span, f"unknown algorithm '{v}'", "setting",
                    did_you_mean(v, M.SOLVER_ALGORITHMS) or "one of " + ", ".join(M.SOLVER_ALGORITHMS))
            continue
        if k == "nlp" and v not in M.SOLVER_NLPS:
            res.err(s.value.span, f"unknown NLP solver '{v}'", "setting",
                    did_you_mean(v, M.SOLVER_NLPS) or "one of " + ", ".join(M.SOLVER_NLPS))
            continue
        if k == "order" and v not in M.SOLVER_ORDERS:
            res.err(s.value.span, f"unknown order '{v}'", "setting",
                    did_you_mean(v, M.SOLVER_ORDERS) or "one of " + ", ".join(M.SOLVER_ORDERS))
            continue
        if k == "planner" and v not in M.SOLVER_PLANNERS:
            res.err(s.value.span, f"unknown planner '{v}'", "setting",
                    did_you_mean(v, M.SOLVER_PLANNERS) or "one of " + ", ".join(M.SOLVER_PLANNERS))
            continue
        if k == "switches" and (set(v) - set("trng") or len(set(v)) != len(v)):
            res.err(s.value.span, f"switches are letters among t, r, n, g (each once), got '{v}'", "setting")
            continue
        problem = M.setting_problem(k, v)
        if problem is not None:
            res.err(s.value.span, f"'{k}' = {v} {problem}", "setting")
            continue
        vals[k] = v
    return base.merged(**vals)


def settings_relaxations(res, d: ast.RelaxationsDecl) -> tuple[M.Relaxation, ...]:
    out = []
    known = sorted(res.tags_seen)
    for item in d.items:
        if any(r.name == item.name.value for r in out):
            res.err(item.name.span, f"relaxation '{item.name.value}' is declared twice", "duplicate")
            continue
        ok = True
        for t in item.drop:
            if t.value not in res.tags_seen:
                res.err(t.span, f"unknown tag '{t.value}'", "unknown-tag",
                        did_you_mean(t.value, known) or ("tags in use: " + ", ".join(known) if known
                                                         else "no declaration has tags"))
                ok = False
        if ok:
            out.append(M.Relaxation(item.name.value, frozenset(t.value for t in item.drop), item.span))
    return tuple(out)


def _numbers(res, v: ast.Value, n: int | None, what: str):
    if v.kind != "list" or any(x.kind != "number" for x in v.value) or (n is not None and len(v.value) != n):
        res.err(v.span, f"'{what}' must be a list of {n if n else 'some'} numbers", "setting")
        return None
    return tuple(float(x.value) for x in v.value)


def settings_reachability(res, d: ast.ReachabilityDecl) -> M.Reachability | None:
    kw: dict = {}
    for s in d.settings:
        k = s.key.value
        if not _new_known_key(res, s, M.REACHABILITY_FIELDS, kw, "reachability"):
            continue
        if k == "workspace":
            v = s.value
            if v.kind != "list" or len(v.value) != 2:
                res.err(v.span, "'workspace' is [[lower...], [upper...]]", "setting")
                continue
            lo, hi = _numbers(res, v.value[0], None, k), _numbers(res, v.value[1], None, k)
            if lo is None or hi is None:
                continue
            if len(lo) != len(hi) or len(lo) not in (2, 3) or any(a > b for a, b in zip(lo, hi)):
                res.err(v.span, "'workspace' needs lower <= upper bounds of equal length (2 or 3)", "setting")
                continue
            kw[k] = (lo, hi)
        elif k == "weights":
            w = _numbers(res, s.value, 3, k)
            if w is not None:
                kw[k] = w
        else:
            v = _setting_value(res, s, M.REACHABILITY_FIELDS[k])
            if v is None:
                continue
            if isinstance(v, (int, float)) and v < 0 or k in ("samples", "neighbours") and v < 1:
                res.err(s.value.span, f"'{k}' = {v} is out of range", "setting")
                continue
            kw[k] = v
    if "robot" not in kw:
        res.err(d.name.span, f"reachability '{d.name.value}' needs `robot = NAME`", "setting")
        return None
    heur = []
    actions = getattr(res, "actions", None) or getattr(getattr(res, "dom", None), "actions", {})
    for h in d.heuristics:
        a = actions.get(h.action.value)
        if a is None:
            res.err(h.action.span, f"unknown action '{h.action.value}'", "unknown-name",
                    did_you_mean(h.action.value, actions))
            continue
        if len(h.params) != len(a.params):
            res.err(h.span, f"action '{a.name}' has {len(a.params)} parameters, got {len(h.params)}", "arity")
            continue
        if h.measure.value not in MEASURES:
            res.err(h.measure.span, f"unknown heuristic measure '{h.measure.value}'", "unknown-name",
                    did_you_mean(h.measure.value, MEASURES) or "measures: " + ", ".join(MEASURES))
            continue
        names = [p.value for p in h.params]
        bad = [x for x in h.args if x.value not in names]
        if bad:
            res.err(bad[0].span, f"'{bad[0].value}' is not a parameter of this heuristic", "unknown-name",
                    did_you_mean(bad[0].value, names))
            continue
        if len(h.args) != 2:
            res.err(h.span, "travel(r, x) takes a robot and a target", "arity")
            continue
        heur.append(M.Heuristic(a.name, tuple(names), h.measure.value, tuple(x.value for x in h.args), h.span))
    warm = []
    cont = getattr(res, "continuous", None) or getattr(getattr(res, "dom", None), "continuous", {})
    for w in d.warmstarts:
        c = cont.get(w.traj.value)
        if c is None or not c.traj:
            res.err(w.traj.span, f"'{w.traj.value}' is not a trajectory", "unknown-name",
                    did_you_mean(w.traj.value, [k for k, v in cont.items() if v.traj]))
            continue
        if len(w.args) != len(c.params):
            res.err(w.span, f"trajectory '{c.name}' takes {len(c.params)} arguments, got {len(w.args)}", "arity")
            continue
        warm.append(M.Warmstart(c.name, tuple(x.value for x in w.args), w.span))
    return M.Reachability(d.name.value, heuristics=tuple(heur), warmstarts=tuple(warm), span=d.span, **kw)
