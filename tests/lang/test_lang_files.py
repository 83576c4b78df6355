"""Files a user names or gnpp writes: only regular files read, nothing echoed from a file that
is not one the user writes, atomic writes that never follow a symbolic link, a parse cache that
never runs code.

Oracles: markers written here (a secret line, a marker file a planted pickle would create, a
symlink target's bytes) and the file system's own view (`os.lstat`, modes); no check reads
back through the code under test.
"""
from __future__ import annotations

import os
import pickle
import shutil
import stat
from pathlib import Path

import pytest

import gnppdsl.lang.parser as parser_mod
from gnppdsl.cli.main import main
from gnppdsl.errors import UserError
from gnppdsl.ir.resolve import check_files
from gnppdsl.outputs import write_atomic

ROOT = Path(__file__).resolve().parents[2]
UNCACHED_CACHE_DIR = parser_mod._cache_dir.__wrapped__       # before the fixture replaces it
PLANAR = ROOT / "examples" / "planar"


@pytest.fixture(autouse=True)
def _no_ast_cache(monkeypatch):
    monkeypatch.setattr(parser_mod, "_cache_dir", lambda: None)


def _problem_with_scene(tmp_path: Path, scene: str) -> tuple[Path, Path]:
    d = tmp_path / "ex"
    if d.exists():
        shutil.rmtree(d)
    shutil.copytree(PLANAR, d)
    p = d / "p1_one_block.pntc"
    p.write_text(p.read_text().replace('scene "p1_one_block.yaml"', f'scene "{scene}"'))
    return d, p


def _scene_errors(tmp_path, scene: str):
    d, p = _problem_with_scene(tmp_path, scene)
    report = check_files([str(d / "domain.pntc"), str(p)])
    errs = report.reporter.errors
    assert errs and all(e.span is not None and e.span.file == str(p) and e.span.line == 5 for e in errs), \
        [(e.span, e.message) for e in errs]
    return errs, report.render()


def test_devices_fifos_directories_are_not_read(tmp_path):
    errs, _ = _scene_errors(tmp_path, "/dev/zero")                # refused by its name: no suffix
    assert "scene file" in errs[0].message
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    errs, _ = _scene_errors(tmp_path, str(fifo))                   # would block forever if opened
    assert "FIFO" in errs[0].message
    (tmp_path / "dir.yaml").mkdir()
    errs, _ = _scene_errors(tmp_path, str(tmp_path / "dir.yaml"))
    assert "directory" in errs[0].message


def test_other_files_are_never_echoed(tmp_path):
    secret = tmp_path / "shadow"
    secret.write_text("root:SECRET-MARKER-1234:19000:0:99999:7:::\n")
    _, out = _scene_errors(tmp_path, str(secret))
    assert "SECRET-MARKER" not in out


def test_size_limit(tmp_path, monkeypatch):
    import gnppdsl.inputs as inputs

    d, p = _problem_with_scene(tmp_path, "p1_one_block.yaml")
    sources = [*d.glob("*.pntc"), *(ROOT / "stdlib").glob("*.pntc")]
    limit = max(f.stat().st_size for f in sources) + 1
    with open(d / "p1_one_block.yaml", "a") as fh:
        fh.write("#" * limit + "\n")                       # the scene alone is over the limit
    monkeypatch.setattr(inputs, "MAX_INPUT_BYTES", limit)
    errs = check_files([str(d / "domain.pntc"), str(p)]).reporter.errors
    assert [(e.span.file, e.span.line) for e in errs] == [(str(p), 5)]
    assert "larger than the limit" in errs[0].message


def test_source_size_limit(tmp_path, monkeypatch):
    """A .pntc over `MAX_SOURCE_BYTES` is refused unread, at its 1:1 (named on the command line
    or `use`d), its text never echoed; the bundled sources are all under the limit."""
    import gnppdsl.inputs as inputs

    d, p = _problem_with_scene(tmp_path, "p1_one_block.yaml")
    biggest = max(f.stat().st_size for f in [*(ROOT / "examples").rglob("*.pntc"),
                                             *(ROOT / "stdlib").glob("*.pntc")])
    assert biggest < inputs.MAX_SOURCE_BYTES
    monkeypatch.setattr(inputs, "MAX_SOURCE_BYTES", (d / "domain.pntc").stat().st_size + 1)
    with open(p, "a") as fh:
        fh.write("# " + "SECRET-MARKER " * 400 + "\n")
    report = check_files([str(d / "domain.pntc"), str(p)])
    errs = report.reporter.errors
    assert [(e.span.file, e.span.line, e.span.column) for e in errs] == [(str(p), 1, 1)]
    assert "larger than the limit" in errs[0].message
    assert "SECRET-MARKER" not in report.render()
    (d / "big.pntc").write_text("module big\n# " + "x" * (d / "domain.pntc").stat().st_size + "\n")
    shutil.copy(PLANAR / "p1_one_block.pntc", p)
    dom = d / "domain.pntc"
    dom.write_text(dom.read_text().replace("use planar\n", "use planar, big\n"))
    monkeypatch.setattr(inputs, "MAX_SOURCE_BYTES", dom.stat().st_size + 1)
    errs = check_files([str(dom), str(p)]).reporter.errors
    assert [(e.span.file, e.span.line) for e in errs] == [(str(d / "big.pntc"), 1)], errs


def test_scene_and_urdf_paths_are_relative_to_the_naming_file(tmp_path, monkeypatch):
    d, p = _problem_with_scene(tmp_path, "scenes/s.yaml")
    (d / "scenes").mkdir()
    shutil.move(str(d / "p1_one_block.yaml"), d / "scenes" / "s.yaml")
    monkeypatch.chdir(tmp_path)                                     # not the problem's directory
    assert check_files([str(d / "domain.pntc"), str(p)]).ok
    scene = d / "scenes" / "s.yaml"
    scene.write_text(scene.read_text().replace("kind: planar", 'kind: urdf, urdf: "a\\0b.urdf"'))
    report = check_files([str(d / "domain.pntc"), str(p)])
    errs = report.reporter.errors
    assert errs and all(e.span is not None and e.span.file == str(scene) for e in errs)
    assert any("NUL" in e.message for e in errs), [e.message for e in errs]


def test_nan_in_a_scene_is_located(tmp_path):
    d, p = _problem_with_scene(tmp_path, "p1_one_block.yaml")
    scene = d / "p1_one_block.yaml"
    text = scene.read_text().replace("radius: 0.05", "radius: .nan")
    scene.write_text(text)
    errs = check_files([str(d / "domain.pntc"), str(p)]).reporter.errors
    line = next(i for i, s in enumerate(text.splitlines(), 1) if ".nan" in s)
    assert [(e.span.file, e.span.line) for e in errs] == [(str(scene), line)]
    assert "finite" in errs[0].message


def test_atomic_write_never_follows_a_symlink(tmp_path):
    target = tmp_path / "precious"
    target.write_text("keep me")
    (tmp_path / "res.json.tmp").symlink_to(target)                 # the old predictable temp name
    write_atomic(tmp_path / "res.json", "{}", "--json")
    assert target.read_text() == "keep me" and (tmp_path / "res.json").read_text() == "{}"
    (tmp_path / "link.json").symlink_to(target)
    with pytest.raises(UserError, match="symbolic link"):
        write_atomic(tmp_path / "link.json", "{}", "--json")
    assert target.read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.json", "precious", "res.json", "res.json.tmp"]


def test_cli_outputs_refuse_symlinks(tmp_path, capsys):
    target = tmp_path / "precious"
    target.write_text("keep me")
    (tmp_path / "out").symlink_to(tmp_path)
    code = main(["compile", str(PLANAR / "p1_one_block.pntc"), "-o", str(tmp_path / "out")])
    assert code == 2 and "symbolic link" in capsys.readouterr().err
    (tmp_path / "r.json").symlink_to(target)
    code = main(["solve", str(PLANAR / "p1_one_block.pntc"), "--json", str(tmp_path / "r.json")])
    assert code == 2 and "symbolic link" in capsys.readouterr().err
    assert target.read_text() == "keep me"


def test_render_forgets_only_its_own_old_keyframes(tmp_path):
    from gnppdsl.geometry.render import render_keyframes
    from gnppdsl.ir.scene import load_scene_file

    scene = load_scene_file(PLANAR / "p1_one_block.yaml")
    out = tmp_path / "frames"
    first = render_keyframes(scene, None, [{}] * 4, str(out), size=60)
    (out / "keyframe_007.png").write_bytes(b"the user's own file")
    second = render_keyframes(scene, None, [{}] * 2, str(out), size=60)
    names = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    assert len(first) == 4 and len(second) == 2
    assert names == ["keyframe_000.png", "keyframe_001.png", "keyframe_007.png"]
    assert (out / "keyframe_007.png").read_bytes() == b"the user's own file"


class _Evil:
    def __reduce__(self):
        return (os.system, (f"touch {os.environ['GNPP_TEST_MARKER']}",))


def test_planted_cache_file_never_runs(tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv("XDG_CACHE_HOME", str(cache))
    monkeypatch.delenv("GNPP_NO_CACHE", raising=False)
    monkeypatch.setattr(parser_mod, "_cache_dir", UNCACHED_CACHE_DIR)
    marker = tmp_path / "pwned"
    monkeypatch.setenv("GNPP_TEST_MARKER", str(marker))
    path = str(PLANAR / "domain.pntc")
    key = parser_mod._cache_key((PLANAR / "domain.pntc").read_text(), path)
    d = parser_mod._cache_dir()
    assert d == cache / "gnppdsl" / "ast"
    assert stat.S_IMODE(os.lstat(d).st_mode) == 0o700
    assert stat.S_IMODE(os.lstat(cache / "gnppdsl").st_mode) == 0o700
    evil = pickle.dumps(_Evil())
    for name in (f"{key}.pickle", f"{key}.json"):          # the old name and the new one
        (d / name).write_bytes(evil)
    assert check_files([path]).ok
    assert not marker.exists()
