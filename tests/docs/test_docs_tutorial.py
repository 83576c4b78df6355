"""docs/tutorial.md works as written: every file it shows (a fenced block after
`<!-- file: PATH -->`) is created and every command (`$ gnpp ...` lines of console blocks) is run
in order, in a fresh directory holding only a link to `examples/`; each must exit 0. Then the
outputs the text promises are checked (plan lengths, a learned conflict, CSV columns, pages)."""
from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

from gnppdsl.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "tutorial.md"


def tutorial_steps(text: str) -> list[tuple[str, str]]:
    """[("file", path + "\\n" + content) | ("run", command)] in document order."""
    steps = []
    lines = text.splitlines()
    i = 0
    pending_file = None
    while i < len(lines):
        line = lines[i]
        m = re.match(r"<!-- file: (\S+) -->", line.strip())
        if m:
            pending_file = m.group(1)
        elif line.startswith("```"):
            lang = line[3:].strip()
            j = i + 1
            while not lines[j].startswith("```"):
                j += 1
            body = lines[i + 1:j]
            if pending_file:
                steps.append(("file", pending_file + "\n" + "\n".join(body) + "\n"))
                pending_file = None
            elif lang == "console":
                steps += [("run", b[2:]) for b in body if b.startswith("$ ")]
            i = j
        i += 1
    return steps


def test_every_tutorial_command_runs(tmp_path, monkeypatch, capsys):
    steps = tutorial_steps(DOC.read_text())
    runs = [s for kind, s in steps if kind == "run"]
    assert len(runs) >= 8 and all(r.startswith("gnpp ") for r in runs)
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    monkeypatch.chdir(tmp_path)
    for kind, what in steps:
        if kind == "file":
            path, content = what.split("\n", 1)
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            Path(path).write_text(content)
            continue
        code = main(shlex.split(what)[1:])
        out = capsys.readouterr()
        assert code == 0, f"`{what}` exited {code}:\n{out.out[-2000:]}\n{out.err[-2000:]}"
    occupied = json.loads(Path("out/occupied.json").read_text())
    assert occupied["solved"] and occupied["stats"]["N0"] == 2 and occupied["stats"]["N"] == 4
    assert occupied["conflicts"]
    tower = json.loads(Path("out/tower.json").read_text())
    assert tower["solved"] and tower["plan"][-1].startswith("put(b3")
    header = Path("out/tower_csv/left_arm.csv").read_text().splitlines()[0]
    assert header == "time," + ",".join(f"panda_joint{k}" for k in range(1, 8))
    assert Path("out/tower.html").stat().st_size > 1e6 and Path("out/occupied.html").is_file()
    assert sorted(p.name for p in Path("out/pictures").iterdir() if not p.name.startswith("."))[:1] == ["keyframe_000.png"]   # (the dot file: --render's manifest of its own files)
    assert Path("out/pddl/domain.pddl").is_file()
