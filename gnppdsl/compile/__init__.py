"""gnppdsl.compile: grounding, the SAS+ task, its `.sas` / PDDL writers, the graph-NLP factory.

Modules (imported on demand, so `import gnppdsl.compile` stays cheap):
- `sas`        the SAS+ task contract (`SASTask`, `PartialState`, ...);
- `ground`     bindings of typed parameters, rule grounding (`ground_rules`);
- `task`       IR -> `SASTask` (`build_task`);
- `semantics`  derived values, successor states, plan parsing (`plan_states`, `parse_plan`);
- `sas_writer` Fast Downward `.sas` text (`write_sas`);
- `pddl`       PDDL domain + problem of the ground task (`write_pddl`);
- `pddl_lifted` lifted PDDL of the domain as written (`write_lifted_pddl`);
- `factors`    graph-NLP vertices (`VarInstance`, `FactorInstance`);
- `factory`    the map Π on a state sequence (`GraphNLPFactory`).
"""
from __future__ import annotations

from gnppdsl.lazy import lazy_getattr

_EXPORTS = {
    "build_task": "gnppdsl.compile.task",
    "write_sas": "gnppdsl.compile.sas_writer",
    "write_pddl": "gnppdsl.compile.pddl",
    "write_lifted_pddl": "gnppdsl.compile.pddl_lifted",
    "GraphNLPFactory": "gnppdsl.compile.factory",
    "ground_rules": "gnppdsl.compile.ground",
    "plan_states": "gnppdsl.compile.semantics",
    "parse_plan": "gnppdsl.compile.semantics",
}

__all__ = sorted(_EXPORTS)


__getattr__ = lazy_getattr(__name__, _EXPORTS)
