"""docs/api.md works as written: its ```python blocks run in order in one namespace, from a
directory holding only a link to `examples/` (their own asserts check the results)."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_api_doc_blocks_run(tmp_path, monkeypatch):
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "api.md").read_text(), re.S)
    assert len(blocks) >= 6
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for k, code in enumerate(blocks):
        exec(compile(code, f"docs/api.md block {k + 1}", "exec"), namespace)
    assert Path("out/api_p3.html").is_file() and Path("out/api_csv/g.csv").is_file()
    assert len(namespace["pngs"]) == 6 and namespace["pngs"][-1].endswith("plan.gif")   # 5 keyframes + GIF
