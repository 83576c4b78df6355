"""`gnpp check`: check domains, problems, modules and scenes together, one report for all.

Separate because it is the only place that decides what a list of paths means (directories
expand to their .pntc files; a problem's domain is looked for among the given files first)
and it never raises: every mistake of every file ends up in the `CheckReport`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from gnppdsl.ir.modules import peek_header
from gnppdsl.ir.workspace import Workspace
from gnppdsl.lang.diagnostics import Reporter


@dataclass
class CheckReport:
    """Result of checking files: diagnostics (rendered by `render()`) and what was checked."""

    reporter: Reporter
    counts: dict[str, int]
    files: list[str]
    problems: list = field(default_factory=list)   # resolved problems (M.Problem), for later stages

    @property
    def ok(self) -> bool:
        return not self.reporter.has_errors()

    def render(self) -> str:
        return self.reporter.render()

    def summary(self) -> str:
        parts = [f"{n} {k}{'s' if n != 1 else ''}" for k, n in self.counts.items() if n]
        what = ", ".join(parts) if parts else f"{len(self.files)} file{'s' * (len(self.files) != 1)}"
        n_err = len(self.reporter.errors)
        n_warn = len(self.reporter.diagnostics) - n_err
        warn = f", {n_warn} warning{'s' if n_warn != 1 else ''}" if n_warn else ""
        if n_err:
            return f"{n_err} error{'s' if n_err != 1 else ''}{warn} in {what}"
        return f"ok: {what} checked{warn}"


def expand_paths(paths) -> list[str]:
    """Files as given; directories expand to their *.pntc files (sorted)."""
    out: list[str] = []
    for p in paths:
        pp = Path(p)
        if pp.is_dir():
            out.extend(str(x) for x in sorted(pp.glob("*.pntc")))
        else:
            out.append(str(pp))
    return out


def check_files(paths) -> CheckReport:
    """Check domains, problems, modules (.pntc) and scenes (.yaml); never raises for bad input."""
    ws = Workspace()
    files = expand_paths(paths)
    counts = {"domain": 0, "problem": 0, "module": 0, "scene": 0}
    problems = []
    for path in files:
        suffix = Path(path).suffix.lower()
        if suffix in (".yaml", ".yml"):
            from gnppdsl.ir.scene import load_scene

            counts["scene"] += 1
            load_scene(path, ws.reporter)
            continue
        if suffix != ".pntc":
            if Path(path).exists():
                ws.err(None, f"{path}: not a .pntc or scene .yaml file", "file-kind")
            else:
                ws.err(None, f"file not found: {path}", "missing-file")
            continue
        f = ws.parse(path)
        if f is None:
            continue
        kind = f.header.kind
        counts[kind] += 1
        if kind == "domain":
            ws.domain(path)
        elif kind == "module":
            ws.check_module(path)
        else:
            domains = [c for c in files if c != path and (peek_header(Path(c)) or ("",))[0] == "domain"]
            dom_path = ws.find_domain(f, domains)
            if dom_path is not None:
                problem = ws.problem(path, dom_path)
                if problem is not None:
                    problems.append(problem)
    return CheckReport(ws.reporter, counts, files, problems)
