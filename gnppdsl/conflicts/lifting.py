"""Lifted conflicts: one infeasible subgraph, every symmetric instance of it (issue 19).

Why: a conflict <p_0 .. p_L> names objects (`parent(b1) = pad1`), so the planner learns "b1
does not fit on pad1 while o1 was never moved" and proposes b2 on pad1 next, which fails for
the same geometric reason. When the objects are interchangeable for the infeasible subgraph M
-- equal geometry, and the scene data folded into M's factors (poses, sizes) equal too -- the
renamed conflict is just as sound, and learning all instances at once makes the number of
conflicts grow with the kinds of geometric failure rather than with the objects.

Soundness (paper 000, Prop. 7.1 and Theorem 7.1): an instance may only forbid plans whose
graph-NLP contains an NLP isomorphic to M. Nothing here assumes a symmetry; each candidate
renaming π of the conflict's objects is checked by the factory itself:
1. the plan's states around the conflict are renamed by π (a bijection between objects of one
   type with equal `object_key`) and the factory (the map Π) builds their factors;
2. the factors that are π's images of M's (same rule, template, renamed bindings, same
   relative step) are matched to M by a label-preserving isomorphism (networkx VF2) of the
   anonymous semantic graphs (`semantic.anonymous_graph`: template, arity, body text with
   objects replaced by their geometry and every folded number exact; variable kind, space,
   dimension, bounds; slots on the edges). Isomorphic: the image M' is the same NLP as M up to
   renaming variables, hence infeasible (the same verdict the original conflict rests on);
3. the instance is `to_partial_states(M')`, the union of the generators of M''s own factors,
   so by factor time-invariance (Property 4.2) every plan containing it contains M'. The
   renamed states only serve to let the factory produce M'; they need not be reachable.
A renaming whose image differs in any number (another initial pose, another pad position,
another arm base) fails step 2 and yields nothing: lifting is conservative by construction.

Cost: one factory call (`rule_factors`: the renamed rules only) on a window of L + 3 states per candidate renaming (single swaps of
one conflict object with each object of its type and geometry, then their combinations, at
most `limit`), no NLP.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

from gnppdsl.compile.factors import FactorInstance
from gnppdsl.compile.ground import var_name
from gnppdsl.compile.sas import PartialState, SASTask
from gnppdsl.compile.semantics import derive
from gnppdsl.conflicts.mapping import to_partial_states
from gnppdsl.conflicts.semantic import SemanticGraph, anonymous_graph, body_objects, monomorphism

LIFT_MATCH_BUDGET = 20_000
"""Candidate pairs VF2 may test per renaming in `Lifter._check` (after the named image failed);
then the renaming yields no instance (sound: fewer instances)."""

Conflict = tuple[PartialState, ...]
State = Sequence[int]


def parse_name(name: str) -> tuple[str, tuple[str, ...]]:
    """`parent(b1)` -> ("parent", ("b1",)); `frozen` -> ("frozen", ()) (see `ground.var_name`)."""
    if not name.endswith(")") or "(" not in name:
        return name, ()
    head, args = name[:-1].split("(", 1)
    return head, tuple(a.strip() for a in args.split(",")) if args.strip() else ()


@dataclass
class LiftStats:
    candidates: int = 0          # renamings checked with the factory
    instances: int = 0           # instances found beyond the original conflicts


@dataclass
class Lifter:
    """Symmetric instances of conflicts in one compiled problem (factory = the map Π)."""

    factory: object                          # GraphNLPFactory: `factors(states)`
    task: SASTask
    object_types: Mapping[str, str]          # problem object -> its declared type
    object_key: Callable[[str], str]         # geometry identity (`solve.compiled.object_keys`)
    limit: int = 64                          # renamings checked per conflict
    stats: LiftStats = field(default_factory=LiftStats)
    renamable: dict = field(default_factory=dict)   # last `instances` call: object -> objects it was lifted onto
    images: dict = field(default_factory=dict)      # last `instances` call: instance -> its factors π(M)
                                                    # (steps from the conflict's first; the original: M)

    def __post_init__(self) -> None:
        self._index = {v.name: i for i, v in enumerate(self.task.variables)}
        self._parsed = [parse_name(v.name) for v in self.task.variables]

    # ---- public ------------------------------------------------------------------------
    def instances(self, states: Sequence[State], factors: Sequence[FactorInstance]) -> list[Conflict]:
        """The conflict of `factors` (an infeasible subgraph of the plan with full states
        `states`) followed by every further instance found (each checked as the module says)."""
        factors = tuple(factors)
        original = to_partial_states(factors)
        out = [original]
        first = min(f.step for f in factors)
        last = first + len(original) - 1
        window = [tuple(s) for s in states[first:min(last + 3, len(states))]]
        shifted = [f.shifted(-first) for f in factors]
        pattern = anonymous_graph(shifted, self.object_key)
        objs = self._conflict_objects(factors, original)
        self.images = {original: tuple(shifted)}
        self.windows = {original: window}         # the full states each image's steps index
        choices = {o: [c for c in self.object_types if c != o and self.object_types[c] == self.object_types[o]
                       and self.object_key(c) == self.object_key(o) != "-"] for o in objs}
        valid: dict[str, list[str]] = {o: [] for o in objs}
        checked = 0
        for o in objs:                                   # single swaps first
            for c in choices[o]:
                if checked >= self.limit:
                    break
                checked += 1
                inst = self._check({o: c}, window, shifted, pattern)
                if inst is not None:
                    valid[o].append(c)
                    if inst not in out:
                        out.append(inst)
                        self.images[inst] = self._image
                        self.windows[inst] = getattr(self, "_window", None)
        self.renamable = {o: list(v) for o, v in valid.items()}
        movable = [o for o in objs if valid[o]]
        if len(movable) >= 2:                            # then their combinations
            for combo in itertools.product(*[[o] + valid[o] for o in movable]):
                if checked >= self.limit:
                    break
                mapping = {o: c for o, c in zip(movable, combo) if o != c}
                if len(mapping) < 2 or len(set(combo)) != len(combo):
                    continue
                checked += 1
                inst = self._check(mapping, window, shifted, pattern)
                if inst is not None and inst not in out:
                    out.append(inst)
                    self.images[inst] = self._image
                    self.windows[inst] = getattr(self, "_window", None)
        self.stats.candidates += checked
        self.stats.instances += len(out) - 1
        return out

    def window(self, states: Sequence[State], factors: Sequence[FactorInstance]
               ) -> tuple[list[tuple[int, ...]], list[FactorInstance]]:
        """The plan's states around the conflict of `factors` (L + 3 of them, as `instances`
        renames) and the factors shifted to start at step 0 of that window."""
        first = min(f.step for f in factors)
        last = first + len(to_partial_states(factors)) - 1
        window = [tuple(s) for s in states[first:min(last + 3, len(states))]]
        return window, [f.shifted(-first) for f in factors]

    def objects(self, factors: Sequence[FactorInstance]) -> list[str]:
        """The problem objects a conflict's factors name (bindings, bodies, variables, facts)."""
        return self._conflict_objects(factors, to_partial_states(factors))

    def image(self, mapping: dict[str, str], window: list[tuple[int, ...]],
              shifted: Sequence[FactorInstance]) -> tuple[list[FactorInstance], list[tuple[int, ...]]] | None:
        """π(M) as the factory builds it, *not* checked to be the same NLP as M (the caller
        solves it: `gnppdsl.conflicts.batch`): for each factor of M the factors of the renamed
        window with its rule, template, renamed bindings and step. None when one of M's
        factors has no image (the renamed NLP would lack a constraint of M) or when a
        generator of the image does not hold in the renamed window. With the image: the renamed
        window (its states, in which the image is the factory's, for lifting it in turn)."""
        perm = _complete(mapping)
        renamed = [self._rename_state(s, perm) for s in window]
        keys = {(f.rule, f.template, tuple((k, perm.get(o, o)) for k, o in f.bindings), f.step) for f in shifted}
        wanted = sorted({(r, b, st) for r, _, b, st in keys})
        image = [f for f in self.factory.rule_factors(renamed, wanted)
                 if (f.rule, f.template, f.bindings, f.step) in keys]
        if {(f.rule, f.template, f.bindings, f.step) for f in image} != keys:
            return None
        seq = to_partial_states(image)
        start = min(f.step for f in image)
        if start + len(seq) > len(renamed):
            return None
        derived = [derive(self.factory.task, st) for st in renamed]
        if not all(p.holds_in(derived[start + l]) for l, p in enumerate(seq)):
            return None
        return image, renamed

    def renamings(self, seq: Conflict, limit: int = 256) -> list[Conflict]:
        """The partial states `seq` renamed by bijections of its objects onto objects of the same
        declared type and geometry (the renamings `instances` tries, also those of several
        objects at once, at most `limit`), renamed fact by fact, *not* checked: a cheap
        necessary condition for a plan to hold a symmetric instance of `seq` (the lazy batch's
        `Batcher.hits`). Whether it is one is `instances`' factory and isomorphism test."""
        objs = sorted({n for p in seq for v, x in p.facts
                       for n in (*self._parsed[v][1], self.task.variables[v].values[x])
                       if n in self.object_types})
        key = self.object_key
        choices = [[o] + [c for c in self.object_types if c != o and self.object_types[c] == self.object_types[o]
                          and key(c) == key(o) != "-"] for o in objs]
        out: list[Conflict] = []
        for combo in itertools.islice(itertools.product(*choices), 1, limit + 1):   # 0: identity
            if len(set(combo)) != len(combo):
                continue
            perm = _complete({o: c for o, c in zip(objs, combo) if o != c})
            renamed = self._rename_conflict(seq, perm)
            if renamed is not None and renamed != seq:
                out.append(renamed)
        return out

    # ---- internals ---------------------------------------------------------------------
    def _rename_fact(self, v: int, x: int, perm: dict[str, str]) -> tuple[int, int] | None:
        """π(pred(args) = value) = (pred(π(args)) = π(value)) as (variable, value index); None
        when the renamed variable is not in the task or the renamed value not in its domain."""
        pred, args = self._parsed[v]
        w = self._index.get(var_name(pred, tuple(perm.get(a, a) for a in args)))
        if w is None:
            return None
        value = self.task.variables[v].values[x]
        values = self.task.variables[w].values
        target = perm.get(value, value)
        if target not in values:
            return None
        return w, values.index(target)

    def _rename_conflict(self, seq: Conflict, perm: dict[str, str]) -> Conflict | None:
        """π(seq) fact by fact (`_rename_fact`); None when a renamed fact is not in the task."""
        out = []
        for p in seq:
            facts = [self._rename_fact(v, x, perm) for v, x in p.facts]
            if None in facts:
                return None
            out.append(PartialState.of(facts))
        return tuple(out)

    def _conflict_objects(self, factors: Sequence[FactorInstance], seq: Conflict) -> list[str]:
        names: set[str] = set()
        for f in factors:
            names.update(o for _, o in f.bindings)
            names.update(body_objects(f.body))
            for v in f.variables:
                names.update(v.args)
        for p in seq:
            for v, x in p.facts:
                names.update(self._parsed[v][1])
                names.add(self.task.variables[v].values[x])
        return sorted(n for n in names if n in self.object_types)

    def _check(self, mapping: dict[str, str], window: list[tuple[int, ...]],
               shifted: list[FactorInstance], pattern) -> Conflict | None:
        """The instance of M under the renaming `mapping` (its partial states), or None: the
        renamed window's factors (`rule_factors`) must hold a set that is the same NLP as M.
        First the factors π maps M's onto by name (rule, template, renamed bindings, step),
        checked to be the same NLP as M under that very correspondence (`_same_nlp`: linear);
        only if that fails, a label-preserving monomorphism of M into the renamed factors
        (`semantic.monomorphism`: its necessary conditions first, then VF2 within
        LIFT_MATCH_BUDGET tested pairs). Why: VF2 alone enumerated monomorphisms without end
        when none exists (clutter_6 with its obstacles named in another order: one lifting of a
        94-factor conflict ran for minutes, the solve hit its time limit); answering None when the
        budget runs out is sound (lifting only learns fewer instances)."""
        perm = _complete(mapping)
        renamed = [self._rename_state(s, perm) for s in window]
        wanted = {(f.rule, tuple((k, perm.get(o, o)) for k, o in f.bindings), f.step) for f in shifted}
        templates = {f.template for f in shifted}
        candidates = [f for f in self.factory.rule_factors(renamed, sorted(wanted)) if f.template in templates]
        if len(candidates) < len(shifted):
            return None
        image = _named_image(shifted, candidates, perm)
        if image is None or not _same_nlp(shifted, image, self.object_key):
            image = self._matched_image(candidates, pattern)
        if image is None:
            return None
        seq = to_partial_states(image)
        start = min(f.step for f in image)
        if start + len(seq) > len(renamed):
            return None
        derived = [derive(self.factory.task, st) for st in renamed[start:start + len(seq)]]
        if not all(p.holds_in(derived[l]) for l, p in enumerate(seq)):
            return None                              # cannot happen: generators hold where made
        self._image = tuple(image)
        self._window = renamed
        return seq

    def _matched_image(self, candidates: list[FactorInstance], pattern) -> list[FactorInstance] | None:
        """The factors of the first label-preserving monomorphism of M's anonymous graph into the
        candidates' (`semantic.monomorphism`, at most LIFT_MATCH_BUDGET tested pairs), if they
        alone are the same NLP as M (no further incidences), else None."""
        from networkx.algorithms import isomorphism     # with the semantic graphs (`semantic._nx`)

        target = anonymous_graph(candidates, self.object_key)
        match = monomorphism(SemanticGraph.from_graph(pattern), SemanticGraph.from_graph(target),
                             budget=LIFT_MATCH_BUDGET)
        if match is None:
            return None
        image = [candidates[n[1]] for n in match if n[0] == "h"]
        if not isomorphism.GraphMatcher(anonymous_graph(image, self.object_key), pattern,
                                        node_match=_same_label, edge_match=_same_slots).is_isomorphic():
            return None
        return image

    def _rename_state(self, state: tuple[int, ...], perm: dict[str, str]) -> tuple[int, ...]:
        """π(s): the value of variable pred(π(args)) is π(value of pred(args)) (`_rename_fact`,
        perm a bijection); variables whose preimage is not in the task, or whose renamed value is
        not in its domain, keep theirs (the factory's generators, not this state, define the
        instance)."""
        out = list(state)
        for v, x in enumerate(state):
            image = self._rename_fact(v, x, perm)
            if image is not None:
                out[image[0]] = image[1]
        return tuple(out)


def _complete(mapping: dict[str, str]) -> dict[str, str]:
    """A bijection extending `mapping` (injective): images that are not sources map back to the
    sources that are not images, in sorted order (the renaming of the whole state)."""
    perm = dict(mapping)
    free_targets = sorted(set(mapping.values()) - set(mapping))
    free_sources = sorted(set(mapping) - set(mapping.values()))
    perm.update(zip(free_targets, free_sources))
    return perm



def _named_image(shifted: Sequence[FactorInstance], candidates: Sequence[FactorInstance],
                 perm: dict[str, str]) -> list[FactorInstance] | None:
    """For each factor of M the one candidate with its rule, template, renamed bindings and step
    (in M's order); None when one has none or several, or two share one."""
    by_key: dict[tuple, list[FactorInstance]] = {}
    for g in candidates:
        by_key.setdefault((g.rule, g.template, g.bindings, g.step), []).append(g)
    image = []
    for f in shifted:
        found = by_key.get((f.rule, f.template, tuple((k, perm.get(o, o)) for k, o in f.bindings), f.step), ())
        if len(found) != 1:
            return None
        image.append(found[0])
    return image if len({id(g) for g in image}) == len(image) else None


def _same_nlp(factors: Sequence[FactorInstance], image: Sequence[FactorInstance], object_key) -> bool:
    """Are `image` and `factors` the same NLP under the correspondence factors[i] -> image[i] and,
    slot by slot, their variables? Checked on the anonymous graphs (`semantic.anonymous_graph`):
    that correspondence must be a bijection of the vertices that keeps every label and every
    edge with its slots, with as many edges on both sides -- an isomorphism, so the same
    verdict as one VF2 would find."""
    a, b = anonymous_graph(factors, object_key), anonymous_graph(image, object_key)
    if a.number_of_nodes() != b.number_of_nodes() or a.number_of_edges() != b.number_of_edges():
        return False
    node = {}
    for i, (f, g) in enumerate(zip(factors, image)):
        node[("h", i)] = ("h", i)
        if len(f.variables) != len(g.variables):
            return False
        for v, w in zip(f.variables, g.variables):
            x, y = ("x", v.key, v.step), ("x", w.key, w.step)
            if node.setdefault(x, y) != y:
                return False
    if len(node) != a.number_of_nodes() or len(set(node.values())) != len(node):
        return False
    if any(a.nodes[n]["label"] != b.nodes[m]["label"] for n, m in node.items()):
        return False
    return all(b.has_edge(node[u], node[v]) and b.edges[node[u], node[v]]["slots"] == d["slots"]
               for u, v, d in a.edges(data=True))


def _same_label(a: dict, b: dict) -> bool:
    return a["label"] == b["label"]


def _same_slots(a: dict, b: dict) -> bool:
    return a["slots"] == b["slots"]
