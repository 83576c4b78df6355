"""Collision-avoidance factors the active set adds to a plan's graph-NLP, one pair of bodies at a
keyframe, a waypoint or a segment midpoint (`gnppdsl.solve.active_set`).

Why a function over the factory's resolution and not a template: the pairs are those the
independent verification finds near at a solution, which no rule lists; resolving them with the
factory's own machinery (`world` along the kinematic chain of the step, `with` substitutions of
the trajectories, the facts read recorded) gives them generating partial states like every
other factor, so a conflict with them maps back to partial states (Property 4.2).
"""
from __future__ import annotations

import math
from typing import Sequence

from gnppdsl.compile.factors import FactorInstance
from gnppdsl.compile.factory import GraphNLPFactory, _compact_slots, _Ctx, _Factor, _Skip
from gnppdsl.compile.sas import PartialState
from gnppdsl.ir.expr import Call, Constraint, CVar, Index, Num, Obj, Str, Vec


def pair_factor(factory: GraphNLPFactory, states: Sequence[Sequence[int]], step: int, a: str | tuple[str, str],
                b: str | tuple[str, str], margin: float, waypoint: float | None = None,
                rule: str = "avoid") -> FactorInstance | None:
    """One collision-avoidance factor `sdist(a, b) >= margin` at keyframe `step`, or along
    the motion s_step -> s_step+1 at `waypoint` k (every robot at `path(r)[k]`; k + 0.5:
    the midpoint of waypoints k and k+1, what a consumer replaying the motion linearly
    passes through). Bodies: an object name or (robot, link); a scene object the problem
    does not declare is a static obstacle at its scene pose. Resolved like a template call
    (`world` along the kinematic chain of s_step; the facts read join the generating
    partial state), so conflicts with it map back to partial states as usual. Why here and
    not a template in a domain: the active set (`gnppdsl.solve.active_set`) adds the pairs
    the verification finds near, which no rule lists. None when the motion does not exist
    (the last step) or both bodies are static. The states are derived once per plan
    (`GraphNLPFactory.derived_states`), not per factor."""
    full = factory.derived_states(states)

    def fixed(x) -> bool:
        return not isinstance(x, tuple) and x not in factory.problem.objects

    if fixed(a) and fixed(b):
        return None
    acc = _Factor()
    ctx = _Ctx(full, step, where=f"{rule} {a} / {b} at step {step}")
    tags = {"collision"}
    try:
        if waypoint is not None:
            tags.add("traj")
            k0 = int(math.floor(waypoint))
            subst = dict(ctx.subst)
            for cv, traj, types in _motions(factory):
                for robot in factory.scene.robots if factory.scene is not None else ():
                    if robot not in factory.problem.objects or \
                            not set(factory.domain.ancestors(factory.problem.objects[robot])) & set(types):
                        continue
                    at = Index(CVar(traj, (Obj(robot),)), Num(k0))
                    if waypoint != k0:
                        nxt = Index(CVar(traj, (Obj(robot),)), Num(k0 + 1))
                        at = Call("mul", (Num(0.5), Call("add", (at, nxt))))
                    subst[factory._cvar_key(CVar(cv, (Obj(robot),)), ctx, acc, check=False)] = \
                        factory._resolve(at, ctx, acc)
            ctx = ctx.child(subst=subst)
        parts: list = []
        for x in (a, b):
            if fixed(x):
                parts += [Obj(x), Vec(tuple(Num(float(v)) for v in factory._scene_pose(x, ctx, Obj(x))))]
            elif isinstance(x, tuple):
                parts += factory._body_and_pose(Call("link", (Obj(x[0]), Str(x[1]))), ctx, acc)
            else:
                parts += factory._body_and_pose(Obj(x), ctx, acc)
    except _Skip:
        return None
    lhs = Call("sdist2" if factory._dimension() == 2 else "sdist", tuple(parts))
    body, used = _compact_slots((Constraint(lhs, ">=", Num(float(margin))),))
    variables = tuple(factory._var_instance(acc.slots[j], None) for j in used)
    name = lambda x: "/".join(x) if isinstance(x, tuple) else x      # noqa: E731
    return FactorInstance(template=rule, rule=rule, bindings=(("a", name(a)), ("b", name(b)))
                          + ((("w", f"{waypoint:g}"),) if waypoint is not None else ()),
                          tags=frozenset(tags), step=step, span=1,
                          generator=(PartialState.of(acc.consulted[0].items()),),
                          variables=variables, body=body)

def _motions(factory: GraphNLPFactory) -> list[tuple[str, str, tuple[str, ...]]]:
    """(configuration variable, trajectory variable, their parameter's types) triples: `q(r)` and `path(r)` declared
    over the same parameter types and space (a trajectory is the motion of that variable)."""
    out = []
    for t in factory.domain.continuous.values():
        if not t.traj:
            continue
        for c in factory.domain.continuous.values():
            if not c.traj and c.space == t.space and len(t.params) == 1 and \
                    [p.types for p in c.params] == [p.types for p in t.params]:
                out.append((c.name, t.name, t.params[0].types))
                break
    return out
