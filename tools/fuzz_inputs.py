"""Fuzz the front end: mutated .pntc files and scenes, each checked in a worker with a deadline.

    python tools/fuzz_inputs.py                    # 10,000 .pntc mutants, 1,000 scene mutants
    python tools/fuzz_inputs.py --pntc 500 --scenes 100 --seed 3 --timeout 10

Each mutant replaces one file of a copy of a bundled example folder (examples/*, stdlib
modules copied beside them) and is checked the way `gnpp check` and `gnpp solve` load it:
`check_files([domain, problem])` (what `load_problem` runs too). Counted:

- uncaught: any exception (`check_files` reports every user error as a diagnostic);
- hang: no answer within `--timeout` seconds (the worker is killed and restarted);
- unlocated: an error diagnostic without file:line:col;
- oversized: a rendered report larger than 64 KB (output growing with the input's length).

Why a separate worker process instead of hypothesis: a hang must be killed from outside (a
blocking `open` of a FIFO, a loop inside a C extension), and 11,000 cases must not share one
interpreter's state. The mutation operators are those of the reviewer's report in issue 21
(deep nesting, huge numbers, NUL and invalid UTF-8 bytes, long names and lines, long lists,
device/FIFO/secret paths) plus generic ones (truncate, delete, insert a token, duplicate a line,
swap names, flip a byte). Exit status 1 if any count is non-zero.
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import random
import re
import shutil
import sys
import tempfile
import time
import traceback
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = {"planar": ("domain.pntc", "p3_occupied.pntc", "p3_occupied.yaml"),
           "lab": ("domain.pntc", "lab1.pntc", "lab.yaml"),
           "mobile": ("domain.pntc", "pick_place.pntc", "sorting.yaml")}
OVERSIZED = 64 * 1024

TOKENS = ["(", ")", "{", "}", "'", ",", ":", "=", ":=", "->", "=>", "==", "<=", "not", "rule",
          "state", "traj", "x", "1.5", '"', "[", "]", "with", "forall", "tags", "#", "\n", "-",
          "world(", "exists", "none", "object", "; ", ".", "..", "\t", "é", "\x00", "1e99999",
          "R[1e400]", "R[" + "9" * 5000 + "]", "9" * 5000, "1e-400", "nan", "inf", "0/0", "sqrt(-1)",
          "use " + "m" * 300 + "\n", "a" * 10000, "\ufeff", "\r", "\r\n", "\\", "`", "$", "@"]
YAML_TOKENS = ["- ", ": [", "{a: ", "&x", "*x", "!!python/object:os.system", "\"\n", ".nan", ".inf",
               "-.inf", "1e400", "[" * 2000, "{" * 2000, "\x00", "? ", "!!binary", "~", "null",
               "urdf: \"/dev/zero\"", "urdf: \"a\\0b\"", "file: /etc/shadow", "shape: mesh",
               "radius: .nan", "pose: [.nan, 0, 0]", "size: [1e308, 1e308]", "&a [*a]",
               "9" * 5000, "\t", "%YAML 1.1\n", "---\n", "...\n", "<<: *x"]
SCENE_PATHS = ["/dev/zero", "/etc/shadow", "/etc/passwd", ".", "..", "/", "fifo", "a\x00b", "x" * 300,
               "/proc/self/mem", "/dev/stdin", "domain.pntc"]


def mutate(text: str, rng: random.Random, scene: bool) -> bytes:
    """One mutant (bytes: some operators write invalid UTF-8)."""
    ops = ["truncate", "delete", "insert", "insert", "dupline", "swap", "nest", "longlist",
           "longline", "bytes", "path", "repeat", "number", "name"]
    op = rng.choice(ops)
    n = len(text)
    tokens = YAML_TOKENS + TOKENS[:20] if scene else TOKENS
    i = rng.randint(0, n)
    if op == "truncate":
        out = text[:i]
    elif op == "delete":
        out = text[:i] + text[min(n, i + rng.randint(1, 60)):]
    elif op == "insert":
        out = text[:i] + rng.choice(tokens) + text[i:]
    elif op == "dupline":
        lines = text.splitlines(keepends=True) or [""]
        k = rng.randrange(len(lines))
        out = "".join(lines[:k + 1] + [lines[k]] * rng.choice([1, 2, 50]) + lines[k + 1:])
    elif op == "swap":
        words = sorted(set(re.findall(r"[A-Za-z_]\w*", text)))
        out = text.replace(rng.choice(words), rng.choice(words)) if len(words) > 1 else text
    elif op == "nest":
        k = rng.choice([50, 300, 1000, 5000])
        opener = rng.choice(["[", "(", "-", "not ", "{", "[1, "] if not scene else ["[", "{", "- "])
        closer = {"[": "]", "(": ")", "{": "}", "[1, ": "]"}.get(opener, "")
        inner = rng.choice(["x", "1", ""])
        out = text[:i] + opener * k + inner + closer * rng.choice([0, k]) + text[i:]
    elif op == "longlist":
        item = rng.choice(["b1, ", "x x, ", "1, ", "!, ", "b1 : block ", "parent(b1) = s1 ", "q, "])
        out = text[:i] + item * rng.choice([100, 4000]) + text[i:]
    elif op == "longline":
        out = text[:i] + rng.choice(["x", "a b ", "@", "1+"]) * rng.choice([10_000, 100_000]) + text[i:]
    elif op == "bytes":
        raw = bytearray(text.encode("utf-8"))
        j = rng.randrange(len(raw) + 1)
        raw[j:j] = rng.choice([b"\xff", b"\xc3\x28", b"\x00", b"\xed\xa0\x80", b"\xe2\x82"])
        return bytes(raw)
    elif op == "path":
        p = rng.choice(SCENE_PATHS)
        if scene:
            out = re.sub(r"(urdf|file):\s*\S+", lambda m: f"{m.group(1)}: \"{p}\"", text, count=1) \
                if re.search(r"(urdf|file):", text) else text + f"\nobjects:\n  m: {{shape: mesh, file: \"{p}\"}}\n"
        else:
            out = re.sub(r'scene\s+"[^"]*"', f'scene "{p}"', text) if "scene" in text else \
                text + f'\nuse {p if p.isidentifier() else "m" * 300}\n'
    elif op == "number":     # one numeric literal replaced by an extreme one
        nums = list(re.finditer(r"(?<![\w.])\d+(\.\d+)?(e-?\d+)?", text))
        big = rng.choice(["1e400", "9" * 5000, "0", "1e-400", ".nan", ".inf", "-.inf", "nan", "-1", "1e308",
                          "99999999999999999999", "0.0000001"])
        if nums:
            m = rng.choice(nums)
            out = text[:m.start()] + big + text[m.end():]
        else:
            out = text
    elif op == "name":       # one name replaced by a very long one
        words = list(re.finditer(r"[A-Za-z_]\w*", text))
        if words:
            m = rng.choice(words)
            out = text[:m.start()] + rng.choice(["n" * 300, "N" * 10_000, "é" * 200]) + text[m.end():]
        else:
            out = text
    else:  # repeat a slice many times
        j = min(n, i + rng.randint(1, 40))
        out = text[:i] + text[i:j] * rng.choice([20, 500]) + text[j:]
    return out.encode("utf-8", errors="surrogateescape")


def _check(folder: str, target: str, data: bytes, problem: str) -> dict:
    """Run the front end on one mutant in a scratch copy of the example folder."""
    from gnppdsl.ir.resolve import check_files

    src = ROOT / "examples" / folder
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        for f in src.iterdir():
            if f.is_file():
                shutil.copy(f, d / f.name)
        fifo = d / "fifo"
        os.mkfifo(fifo)
        (d / target).write_bytes(data)
        out = {"unlocated": 0, "uncaught": None, "size": 0}
        try:
            report = check_files([str(d / "domain.pntc"), str(d / problem)])
            text = report.render()
            out["size"] = len(text)
            out["unlocated"] = sum(1 for e in report.reporter.errors if e.span is None)
            if out["unlocated"]:
                out["example"] = next(e.message for e in report.reporter.errors if e.span is None)[:200]
        except Exception as exc:  # noqa: BLE001 - that is what we count
            tb = traceback.extract_tb(exc.__traceback__)
            where = f"{Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else "?"
            out["uncaught"] = f"{type(exc).__name__} at {where}: {str(exc)[:60]}"
        return out


def _worker(conn) -> None:
    while True:
        job = conn.recv()
        if job is None:
            return
        conn.send(_check(*job))


def _cases(n_pntc: int, n_scene: int, seed: int):
    rng = random.Random(seed)
    names = list(FOLDERS)
    stdlib = sorted((ROOT / "stdlib").glob("*.pntc"))
    for k in range(n_pntc + n_scene):
        folder = rng.choice(names)
        dom, prob, scene = FOLDERS[folder]
        if k >= n_pntc:
            target, is_scene = scene, True
            text = (ROOT / "examples" / folder / scene).read_text()
        else:
            is_scene = False
            target = rng.choice([dom, prob, prob, "module"])
            if target == "module":     # a stdlib module shadowed by a mutated copy beside the domain
                mod = rng.choice(stdlib)
                target, text = mod.name, mod.read_text()
            else:
                text = (ROOT / "examples" / folder / target).read_text()
        yield ("scene" if is_scene else "pntc"), (folder, target, mutate(text, rng, is_scene), prob)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pntc", type=int, default=10_000)
    ap.add_argument("--scenes", type=int, default=1_000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timeout", type=float, default=10.0)
    ap.add_argument("--workers", type=int, default=1, help="worker processes (the cases are the same)")
    ap.add_argument("--max-seconds", type=float, default=0.0,
                    help="stop starting cases after this long (0: run them all); the report counts the cases run")
    ap.add_argument("--save", type=Path, default=None,
                    help="write each hanging or failing mutant to this directory (to reproduce and profile it)")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    os.environ["XDG_CACHE_HOME"] = tempfile.mkdtemp(prefix="gnpp-fuzz-cache-")   # keep ~/.cache clean
    ctx = mp.get_context("fork")
    counts: dict[str, Counter] = {"pntc": Counter(), "scene": Counter()}
    kinds: Counter = Counter()
    t0 = time.time()

    def start():
        a, b = ctx.Pipe()
        p = ctx.Process(target=_worker, args=(b,), daemon=True)
        p.start()
        return p, a

    def save(group: str, job, why: str) -> None:
        if args.save is None:
            return
        args.save.mkdir(parents=True, exist_ok=True)
        k = sum(counts[g]["cases"] for g in counts)
        name = f"s{args.seed}-{k:05d}-{why}-{job[0]}-{job[3]}-{job[1]}"
        (args.save / name).write_bytes(job[2])

    def record(group: str, job, res) -> None:
        c = counts[group]
        if res is None:
            c["hang"] += 1
            kinds[f"hang: {job[0]}/{job[1]}"] += 1
            save(group, job, "hang")
            return
        if res["uncaught"]:
            c["uncaught"] += 1
            kinds[res["uncaught"]] += 1
            save(group, job, "uncaught")
        if res["unlocated"]:
            c["unlocated"] += 1
            kinds["unlocated: " + re.sub(r"/tmp/\S+/", "", res.get("example", ""))[:80]] += 1
            save(group, job, "unlocated")
        if res["size"] > OVERSIZED:
            c["oversized"] += 1
            save(group, job, "oversized")

    workers = [start() for _ in range(max(1, args.workers))]
    busy: dict[int, tuple] = {}              # worker index -> (group, job, started)
    cases = _cases(args.pntc, args.scenes, args.seed)
    done = 0
    pending = True
    while pending or busy:
        if pending and args.max_seconds and time.time() - t0 > args.max_seconds:
            pending = False                  # report what was covered (the counts say how many)
        for k in range(len(workers)):
            if k not in busy and pending:
                try:
                    group, job = next(cases)
                except StopIteration:
                    pending = False
                    break
                counts[group]["cases"] += 1
                workers[k][1].send(job)
                busy[k] = (group, job, time.time())
        for k, (group, job, started) in list(busy.items()):
            proc, conn = workers[k]
            if conn.poll(0.01):
                record(group, job, conn.recv())
            elif time.time() - started > args.timeout:
                proc.kill()
                proc.join()
                workers[k] = start()
                record(group, job, None)
            else:
                continue
            del busy[k]
            done += 1
            if not args.quiet and done % 500 == 0:
                print(f"{done} cases, {time.time() - t0:.0f} s", file=sys.stderr, flush=True)
    for proc, conn in workers:
        conn.send(None)
        proc.join(5)
    shutil.rmtree(os.environ["XDG_CACHE_HOME"], ignore_errors=True)
    for group, c in counts.items():
        print(f"{group:6s}: {c['cases']} cases, {c['uncaught']} uncaught exceptions, {c['hang']} hangs "
              f"(> {args.timeout:g} s), {c['unlocated']} with unlocated errors, "
              f"{c['oversized']} reports > {OVERSIZED // 1024} KB")
    for k, n in kinds.most_common(30):
        print(f"  {n:5d}  {k}")
    print(f"{time.time() - t0:.0f} s")
    bad = sum(c[k] for c in counts.values() for k in ("uncaught", "hang", "unlocated", "oversized"))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
