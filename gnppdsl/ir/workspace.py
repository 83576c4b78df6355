"""The workspace: domains and problems resolved from files, over the module library.

`Workspace` is what callers load files with (`gnpp check`, `load_problem`): a
`modules.ModuleLibrary` (files, modules, `use`, the standard library, the shared pieces) that
also hands a domain file to `resolve_domain.DomainResolver` and a problem file to
`resolve_problem.ProblemResolver`, caching resolved domains by path. Why a module of its own:
the resolvers call back into the library, so the library sits below them and this, which
starts them, above them; the import direction stays one way without imports inside functions.
"""
from __future__ import annotations

from pathlib import Path

from gnppdsl.ir import model as M
from gnppdsl.ir.modules import ModuleLibrary
from gnppdsl.ir.resolve_domain import DomainResolver
from gnppdsl.ir.resolve_problem import ProblemResolver
from gnppdsl.lang.diagnostics import Reporter


class Workspace(ModuleLibrary):
    """Loads and resolves .pntc files; all diagnostics go to `self.reporter`."""

    def __init__(self, reporter: Reporter | None = None, stdlib: Path | None = None) -> None:
        super().__init__(reporter, stdlib)
        self._domains: dict[str, M.Domain | None] = {}

    def domain(self, path: str | Path) -> M.Domain | None:
        key = str(Path(path))
        if key not in self._domains:
            self._domains[key] = None
            f = self._parse_kind(key, "domain")
            if f is None:
                return None
            self._domains[key] = DomainResolver(self, f).run()
        return self._domains[key]

    def problem(self, path: str | Path, domain_path: str | Path | None = None) -> M.Problem | None:
        f = self._parse_kind(path, "problem")
        if f is None:
            return None
        if domain_path is None:
            domain_path = self.find_domain(f)
            if domain_path is None:
                return None
        dom = self.domain(domain_path)
        if dom is None:
            return None
        if dom.name != f.header.domain.value:
            self.err(f.header.domain.span, f"problem is for domain '{f.header.domain.value}', "
                     f"but {domain_path} declares domain '{dom.name}'", "wrong-domain")
            return None
        return ProblemResolver(self, f, dom).run()
