"""Count the test suite's tests by the kind of oracle they check against (issue 25).

Kinds:
- independent: the test compares the code under test with something that shares no code with it
  (Fast Downward, brute force written from the SAS+ semantics, pinocchio, coal, finite
  differences, scipy, clingo run on emitted text, a separate interpreter or reference file, the
  Lab verifier, a hand-derived closed form);
- same-path: the project's own code confirms itself (it asserts on the code's own outputs, or
  re-checks them with the project's own evaluator / solver);
- crash-only: nothing is asserted beyond "it does not raise".

Heuristic (documented so the numbers can be reproduced and argued with): for every collected
test item (parametrisations count separately, as pytest counts them) the source of the test
function is joined with the source of the module-level helpers it calls, transitively, in its own
module and in the sibling helper modules of its directory (files not named test_*.py). Then
- no `assert`, `pytest.raises`, `pytest.fail` or `pytest.warns` in that text -> crash-only;
- a word from INDEPENDENT in that text -> independent;
- otherwise same-path.
OVERRIDES lists tests whose kind a manual reading found different from the heuristic, each with
the reason; they are applied after it.

Usage: python tools/oracle_census.py [--by-file] [--list KIND]   (from the repository root)
"""
from __future__ import annotations

import argparse
import ast
import re
import subprocess
import sys
from collections import Counter, defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# Words whose presence means the test checks against something outside the code under test.
INDEPENDENT = [
    r"\bfd_oracle\b", r"\blogic_fd\b", r"\brun_fd\b", r"fast_downward", r"\bfd_plan", r"\bdownward\b",
    r"\bbrute", r"\bsas_semantics\b", r"\bpinocchio\b", r"\bpin\.", r"\bcoal\.", r"\bhppfcl\b",
    r"finite.difference", r"central.difference", r"\bfinite_diff", r"\bnumeric_grad", r"\bfd_grad",
    r"\bfd_jac", r"\b_fd\(", r"\bscipy\b", r"\bminimize\(", r"\bclingo\.Control", r"\bpddl\.parse",
    r"\bparse_domain\b", r"\bparse_problem\b", r"\bbody_eval\b", r"\bplanar_reference\b",
    r"\bevaluate_reference\b", r"\bir_oracle\b", r"\bindependent\b", r"\bverify_lab\b",
    r"\bLabVerifier\b", r"\bclosed.form\b", r"\bby hand\b", r"\bhand.derived\b", r"\bexpected\.yaml\b",
    r"\breach_checks\b", r"\bsympy\b",
]
ASSERTS = re.compile(r"\bassert\b|pytest\.raises|pytest\.fail|pytest\.warns|\bcheck_\w+\(|\bassert_\w+\(")

# Manual reading: (node id prefix, kind, reason).
OVERRIDES: list[tuple[str, str, str]] = [
    ("tests/lang/test_lang_fuzz.py::", "same-path",
     "properties between two entry points of the same front end (check_files <=> load_problem) "
     "and diagnostics located inside the mutated files: consistency, not an outside oracle "
     "(before issue 25 these 6 tests asserted nothing: crash-only)"),
]
# Before numbers (issue 25): `git show 536863e:tools/oracle_census.py` run at that commit.


def _collect() -> list[str]:
    out = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-o", "addopts=", "-p", "no:cacheprovider"],
                         cwd=ROOT, capture_output=True, text=True, env={**__import__("os").environ,
                                                                       "GNPP_SLOW": "1", "PYTHONPATH": str(ROOT)})
    return [line.strip() for line in out.stdout.splitlines() if "::" in line]


class _Module:
    def __init__(self, path: Path):
        self.path = path
        self.source = path.read_text()
        tree = ast.parse(self.source)
        self.defs: dict[str, str] = {}
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                self.defs.setdefault(node.name, ast.get_source_segment(self.source, node) or "")


_modules: dict[Path, _Module] = {}


def _module(path: Path) -> _Module:
    if path not in _modules:
        _modules[path] = _Module(path)
    return _modules[path]


def _text_of(path: Path, func: str) -> str:
    """The test's source plus the helpers it reaches in its module and its directory's helpers."""
    mod = _module(path)
    helpers = [mod] + [_module(p) for p in sorted(path.parent.glob("*.py"))
                       if not p.name.startswith("test_") and p != path]
    seen, todo, parts = set(), [func], []
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        for m in helpers:
            if name in m.defs:
                seg = m.defs[name]
                parts.append(seg)
                todo.extend(re.findall(r"\b([A-Za-z_]\w*)\b", seg))
                break
    return "\n".join(parts)


def classify(nodeid: str) -> str:
    for prefix, kind, _ in OVERRIDES:
        if nodeid.startswith(prefix):
            return kind
    file, _, rest = nodeid.partition("::")
    func = rest.split("[")[0].split("::")[-1]
    text = _text_of(ROOT / file, func)
    if not ASSERTS.search(text):
        return "crash-only"
    if any(re.search(p, text, re.IGNORECASE) for p in INDEPENDENT):
        return "independent"
    return "same-path"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--by-file", action="store_true")
    ap.add_argument("--list", metavar="KIND")
    args = ap.parse_args()
    ids = _collect()
    kinds = {i: classify(i) for i in ids}
    total = Counter(kinds.values())
    if args.by_file:
        per = defaultdict(Counter)
        for i, k in kinds.items():
            per[i.split("::")[0]][k] += 1
        for f in sorted(per):
            c = per[f]
            print(f"{f:60s} ind {c['independent']:4d}  same {c['same-path']:4d}  crash {c['crash-only']:4d}")
    if args.list:
        for i, k in kinds.items():
            if k == args.list:
                print(i)
    n = len(ids)
    print(f"tests {n}: " + ", ".join(f"{k} {total[k]} ({100 * total[k] / max(n, 1):.0f} %)"
                                     for k in ("independent", "same-path", "crash-only")))


if __name__ == "__main__":
    main()
