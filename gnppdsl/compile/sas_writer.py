"""Write a `SASTask` as Fast Downward's `.sas` text (translator output format, version 3).

Why our own writer: the SAS+ task is the compiler's primary output and Fast Downward is the
independent oracle that checks it (tests run FD's search on this text). The format is documented
at https://www.fast-downward.org/TranslatorOutputFormat; the points that matter here:

- A variable lists its axiom layer (-1 for state variables) and one `Atom`/`NegatedAtom` name per
  value. Derived variables (our `axiom_layer >= 0`) default to value 0 ("false"); their value in
  `begin_state` is that default.
- An operator has *prevail* conditions (variables it reads but does not change) and effects
  `cond... var pre post`; `pre` (-1 = any) is an unconditional precondition even when the
  effect is conditional. Our `Operator.pre` holds both kinds, so each precondition on a variable
  the operator also changes moves into that variable's effects.
- Axiom rules `conditions; var default derived`; layers must be stratified (a rule in layer L may
  test a derived variable of layer L only for its derived value, lower layers for any value).
  `check_axiom_layers` verifies this before writing, because FD otherwise silently
  computes wrong derived values.
- FD rejects operators without effects. An operator whose effects are all no-ops can never
  change the state, so it is left out (FD's own translator drops them too).
"""
from __future__ import annotations

from gnppdsl.compile.sas import Operator, SASTask

__all__ = ["write_sas", "operator_sections", "check_axiom_layers", "atom_name"]


def atom_name(var_name: str, value: str) -> str:
    """The `Atom` text FD prints in plans and logs for one fact."""
    if value == "true":
        return f"Atom {var_name}"
    if value == "false":
        return f"NegatedAtom {var_name}"
    return f"Atom {var_name}={value}"


def _clean(text: str) -> str:
    # FD reads names line by line; a newline would break the format.
    return " ".join(text.split())


def check_axiom_layers(task: SASTask) -> None:
    """Raise ValueError if the axioms are not stratified by the variables' axiom layers."""
    for ax in task.axioms:
        head = task.variables[ax.var]
        if not head.is_derived:
            raise ValueError(f"axiom derives state variable {head.name}")
        if ax.value == 0:
            raise ValueError(f"axiom derives the default value of {head.name}")
        for v, val in ax.conditions:
            cv = task.variables[v]
            if not cv.is_derived:
                continue
            if cv.axiom_layer > head.axiom_layer:
                raise ValueError(
                    f"axiom for {head.name} (layer {head.axiom_layer}) reads {cv.name} "
                    f"of higher layer {cv.axiom_layer}")
            if cv.axiom_layer == head.axiom_layer and val == 0:
                raise ValueError(
                    f"axiom for {head.name} tests {cv.name} for its default value in the same "
                    f"layer {head.axiom_layer} (negation needs a lower layer)")


def operator_sections(op: Operator) -> tuple[list[tuple[int, int]], list[tuple[tuple[tuple[int, int], ...], int, int, int]]]:
    """Split an operator into FD prevail conditions and effects `(conds, var, pre, post)`.

    A precondition on a variable the operator changes becomes the `pre` of that variable's
    effects (FD treats it as an unconditional precondition either way); a no-op unconditional
    effect (`v := x` when `pre` already requires `v = x`) is dropped, since FD's translator
    never emits those either.
    """
    pre = dict(op.pre)
    effects = []
    for eff in op.effects:
        if not eff.conditions and pre.get(eff.var) == eff.value:
            continue
        effects.append(eff)
    changed = {e.var for e in effects}
    prevail = sorted((v, val) for v, val in pre.items() if v not in changed)
    out = []
    for eff in effects:
        out.append((tuple(sorted(eff.conditions)), eff.var, pre.get(eff.var, -1), eff.value))
    return prevail, out


def write_sas(task: SASTask) -> str:
    """The whole task as `.sas` text (version 3, with action costs: integers, scaled by
    `SASTask.cost_scale` when some cost is not)."""
    check_axiom_layers(task)
    lines: list[str] = ["begin_version", "3", "end_version", "begin_metric", "1", "end_metric"]
    lines.append(str(len(task.variables)))
    for i, var in enumerate(task.variables):
        lines += ["begin_variable", f"var{i}", str(var.axiom_layer), str(len(var.values))]
        lines += [_clean(atom_name(var.name, val)) for val in var.values]
        lines.append("end_variable")
    lines.append("0")  # mutex groups: optional, FD only uses them for some heuristics
    lines.append("begin_state")
    lines += [str(task.initial[i] if not v.is_derived else 0) for i, v in enumerate(task.variables)]
    lines.append("end_state")
    lines += ["begin_goal", str(len(task.goal.facts))]
    lines += [f"{v} {val}" for v, val in task.goal.facts]
    lines.append("end_goal")
    scale = task.cost_scale()
    sections = [(op, *operator_sections(op)) for op in task.operators]
    sections = [sec for sec in sections if sec[2]]
    lines.append(str(len(sections)))
    for op, prevail, effects in sections:
        lines += ["begin_operator", _clean(op.name), str(len(prevail))]
        lines += [f"{v} {val}" for v, val in prevail]
        lines.append(str(len(effects)))
        for conds, var, pre, post in effects:
            cond_txt = " ".join(f"{v} {val}" for v, val in conds)
            lines.append(" ".join(x for x in (str(len(conds)), cond_txt, f"{var} {pre} {post}") if x))
        lines += [str(task.integer_cost(op.cost, scale)), "end_operator"]
    lines.append(str(len(task.axioms)))
    for ax in task.axioms:
        lines += ["begin_rule", str(len(ax.conditions))]
        lines += [f"{v} {val}" for v, val in ax.conditions]
        lines += [f"{ax.var} 0 {ax.value}", "end_rule"]
    return "\n".join(lines) + "\n"
