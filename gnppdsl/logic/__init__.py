"""gnppdsl.logic: the logic half of the planner (paper 000, Sec. V and VII, Appendix B).

    IncrementalPlanner(task)            clingo multi-shot planner: shortest_plan, next_plan,
                                        optimal_plan, add_conflict, block_plan (planner)
    Plan, PlanResult, Status            results as values ("no plan up to H", time limit)
    encode_task(task)                   the ASP program (encoding; `gnpp compile --emit asp`)
    forbid_sequence(s)(task, seq)       Appendix B as SAS+ -> SAS+ (reformulation)
    validate_plan(task, plan, conflicts) independent SAS+ semantics (validate)
    read_conflicts / parse_conflicts / write_conflicts   conflict files (conflict_io)
    mutexes(task)                       h^2 invariants used by the encoding (mutex)
    generators                          tasks and conflicts for tests and benchmarks

Names are loaded lazily so that importing a submodule stays cheap (clingo, numpy).
"""
from __future__ import annotations

from gnppdsl.lazy import lazy_getattr

_WHERE = {
    "IncrementalPlanner": "gnppdsl.logic.planner", "Plan": "gnppdsl.logic.planner",
    "PlanResult": "gnppdsl.logic.planner", "Status": "gnppdsl.logic.planner",
    "encode_task": "gnppdsl.logic.encoding",
    "forbid_sequence": "gnppdsl.logic.reformulation", "forbid_sequences": "gnppdsl.logic.reformulation",
    "validate_plan": "gnppdsl.logic.validate", "ValidationResult": "gnppdsl.logic.validate",
    "read_conflicts": "gnppdsl.logic.conflict_io", "parse_conflicts": "gnppdsl.logic.conflict_io",
    "write_conflicts": "gnppdsl.logic.conflict_io", "format_conflict": "gnppdsl.logic.conflict_io",
    "mutexes": "gnppdsl.logic.mutex",
}

__all__ = sorted(_WHERE)


__getattr__ = lazy_getattr(__name__, _WHERE)
