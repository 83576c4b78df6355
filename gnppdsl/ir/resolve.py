"""Name resolution and checking: lang.ast files -> `gnppdsl.ir.model` (Domain, Problem, Module).

The public names of the resolver, re-exported from the modules that do the work (one job each):

    modules           ModuleLibrary, ModuleEnv: files, modules, `use`, the standard library,
                      the pieces every resolver shares (spaces, signatures, constants, templates)
    workspace         Workspace: a ModuleLibrary that resolves domain and problem files
    resolve_domain    DomainResolver: a domain's types, declarations, frames, templates
    resolve_logic     LogicResolver: terms, literals, formulas, effects, actions
    resolve_rules     RuleResolver: rule patterns, `where`, template calls
    resolve_settings  solver / relaxations / reachability blocks
    resolve_problem   ProblemResolver: objects, init, goal, scene of a problem
    check             check_files, CheckReport, expand_paths: what `gnpp check` runs

The expression half (template bodies, frames, template-call arguments) is delegated to
`gnppdsl.ir.typecheck`.
"""
from __future__ import annotations

from gnppdsl.ir.check import CheckReport, check_files, expand_paths
from gnppdsl.ir.modules import ModuleEnv
from gnppdsl.ir.workspace import Workspace

__all__ = ["Workspace", "ModuleEnv", "CheckReport", "check_files", "expand_paths"]
