"""The benchmark grid of `gnpp bench`: cells (problem x algorithm x seed), where they run, the CSV journal.

Paper 000's Table I is six algorithms x 15 problems x 10 seeds with up to 100 s each: about a day
of CPU on one core, so a sweep has to survive being interrupted and has to spread over machines.
Three pieces make that so:

- `Cell` and `RunSettings`: one run and the settings every run of a sweep shares, plain data that
  crosses process and machine boundaries as JSON (no pickled solver state).
- `CsvJournal`: the CSV is the sweep's only state. Every finished run is appended and fsync'ed as
  it arrives, so a sweep killed at any moment keeps every finished run; started again on the same
  file it runs only the cells that have no row yet (resume).
- Executors: `run_serial` runs the cells in this process, one problem parsed once and compiled
  afresh for every run (no Ray needed: the default); `run_on_ray` hands each cell to a Ray task
  (`--workers N` starts a local Ray, `--address` joins a cluster) that runs it in a child process
  of its own, with its own wall-clock cap and memory cap, so a run that hangs, crashes or runs out
  of memory becomes a row saying so and never takes the sweep down. Ray's own task timeouts and
  memory monitor act on the worker process (killing it loses the row and Ray retries or fails the
  task); a child process with `setrlimit` and a `subprocess` timeout gives every failure a row.
"""
from __future__ import annotations

import csv
import io
import json
import os
import resource
import subprocess
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable, Iterable, Iterator

from gnppdsl.errors import UserError

CSV_FIELDS = ("problem", "file", "algorithm", "instance", "seed", "status", "solved", "verified",
              "nlp_solves", "ipopt_runs", "nlp_time", "logic_time", "total_time", "cpu_time", "plans",
              "conflicts", "db_feasible_hits", "db_infeasible_hits", "reused_solutions", "N0", "N", "steps",
              "cost", "plan_cost", "proved_optimal", "base_path_length", "max_violation", "kernels_native",
              "kernels_compiled", "message")

# statuses a run can end with besides the solver's own (solved, no_plan, timeout, ...)
RUN_TIMEOUT = "killed_timeout"      # the child exceeded its wall-clock cap and was killed
RUN_MEMORY = "killed_memory"        # the child ran out of its memory cap
RUN_CRASHED = "crashed"             # the child died otherwise (signal, interpreter error)
RUN_ERROR = "error"                 # the problem or the options were refused (a user error)


@dataclass(frozen=True)
class RunSettings:
    """What every run of one sweep shares (the bench's command-line options)."""
    time_limit: float
    max_horizon: int | None = None
    order: str | None = None
    jit: bool = False
    distance_curvature: bool | None = None
    kinematic_curvature: bool | str | None = None
    planner: str | None = None            # logic mode (None: the problem's setting, else auto)
    anytime: float | None = None          # seconds of the anytime phase (`--anytime`)
    run_timeout: float | None = None      # wall-clock cap of an isolated run (None: derived)
    memory_mb: int | None = None          # address-space cap of an isolated run (None: none)

    @property
    def hard_timeout(self) -> float:
        """Wall-clock cap of an isolated run: the solver's own limit plus loading and slack."""
        if self.run_timeout is not None:
            return self.run_timeout
        return 2.0 * self.time_limit + 60.0


@dataclass(frozen=True)
class Cell:
    """One run of the grid: a problem file, an algorithm label (`gnpp_trn`, `oneway`), a seed,
    and the randomised instance of the problem (None: its scene as written)."""
    file: str
    algorithm: str
    seed: int
    instance: int | None = None

    @property
    def key(self) -> tuple[str, str, str, str]:
        return (self.file, self.algorithm, str(self.seed), "" if self.instance is None else str(self.instance))


def failure_row(cell: Cell, status: str, message: str, problem: str = "") -> dict:
    """A row for a run that produced no solver result (refused, killed, crashed)."""
    row = {k: "" for k in CSV_FIELDS}
    row.update(problem=problem or Path(cell.file).stem, file=cell.file, algorithm=cell.algorithm,
               instance=cell.instance, seed=cell.seed, status=status, solved=False, message=message)
    return row


def result_row(cell: Cell, res) -> dict:
    """The CSV row of a finished solve (`gnppdsl.solve.result.Result`)."""
    s = res.stats
    bases = [v.get("base") for v in res.path_length.values() if v.get("base") is not None]
    anytime = res.anytime or {}
    return {
        "problem": res.problem, "file": cell.file, "algorithm": cell.algorithm, "instance": cell.instance,
        "seed": cell.seed, "status": res.status, "solved": res.solved,
        "verified": None if res.verification is None else bool(res.verification.get("ok")),
        "steps": s.N, "cost": anytime.get("cost", s.cost), "plan_cost": s.plan_cost,
        "proved_optimal": anytime.get("proved_optimal"),
        "base_path_length": round(sum(bases), 4) if bases else None,
        "nlp_solves": s.nlp_solves, "ipopt_runs": s.ipopt_runs,
        "nlp_time": round(s.nlp_time, 4), "logic_time": round(s.logic_time, 4),
        "total_time": round(s.total_time, 4), "cpu_time": round(s.cpu_time, 4), "plans": s.plans,
        "conflicts": s.conflicts, "db_feasible_hits": s.db_feasible_hits,
        "db_infeasible_hits": s.db_infeasible_hits, "reused_solutions": s.reused_solutions,
        # N0 only when the logic mode proved the first plan shortest (docs/design.md, "Logic modes")
        "N0": s.N0 if s.N0_shortest is not False else None, "N": s.N, "max_violation": s.max_violation, "kernels_native": s.kernels_native,
        "kernels_compiled": s.kernels_compiled, "message": res.message,
    }


# ------------------------------------------------------------------ the CSV journal

class CsvJournal:
    """The sweep's CSV: rows read back for resuming, new rows appended durably as they arrive.

    An existing file is resumed, never truncated (nothing a user saved is overwritten unasked);
    a file that is not a bench CSV of this layout is refused before anything is written. A row
    cut short by a kill in the middle of a write (no final newline) is dropped and its cell run
    again.
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self.rows: list[dict] = []
        self._fd: int | None = None
        if self.path.is_symlink():
            raise UserError(f"--csv {path}: is a symbolic link; give the file itself")
        if self.path.exists():
            if not self.path.is_file():
                raise UserError(f"--csv {path}: not a regular file")
            self._read_existing()

    def _read_existing(self) -> None:
        data = self.path.read_bytes()
        if not data.strip():
            return
        complete = data if data.endswith(b"\n") else data[: data.rfind(b"\n") + 1]
        try:
            text = complete.decode("utf-8")
        except UnicodeDecodeError:
            raise UserError(f"--csv {self.path}: not a gnpp bench CSV (not UTF-8 text); "
                            f"choose another file") from None
        reader = csv.DictReader(io.StringIO(text))
        if tuple(reader.fieldnames or ()) != CSV_FIELDS:
            raise UserError(f"--csv {self.path}: not a gnpp bench CSV of this version (its header is "
                            f"{','.join(reader.fieldnames or ())[:120]!r}); choose another file")
        self.rows = [dict(r) for r in reader if None not in r.values()]
        self._truncate_to = len(complete) if len(complete) != len(data) else None

    def done(self) -> set[tuple[str, str, str, str]]:
        return {row_key(r) for r in self.rows}

    def open(self) -> "CsvJournal":
        flags = os.O_WRONLY | os.O_CREAT | os.O_APPEND | getattr(os, "O_NOFOLLOW", 0)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)    # `--csv out/x.csv` on a fresh clone
            self._fd = os.open(self.path, flags, 0o644)
            if getattr(self, "_truncate_to", None) is not None:
                os.ftruncate(self._fd, self._truncate_to)
            if os.fstat(self._fd).st_size == 0:
                self._write(",".join(CSV_FIELDS) + "\r\n")
        except OSError as exc:
            raise UserError(f"--csv {self.path}: {exc.strerror or exc}") from None
        return self

    def append(self, row: dict) -> None:
        buf = io.StringIO()
        csv.DictWriter(buf, fieldnames=CSV_FIELDS).writerow(
            {k: ("" if row.get(k) is None else row.get(k, "")) for k in CSV_FIELDS})
        self._write(buf.getvalue())
        self.rows.append({k: str("" if row.get(k) is None else row.get(k, "")) for k in CSV_FIELDS})

    def _write(self, text: str) -> None:
        assert self._fd is not None, "journal not opened"
        os.write(self._fd, text.encode("utf-8"))
        os.fsync(self._fd)

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def row_key(row: dict) -> tuple[str, str, str, str]:
    """The `Cell.key` a CSV row (or a fresh row) belongs to."""
    inst = row.get("instance")
    return (row["file"], row["algorithm"], str(row["seed"]), "" if inst in (None, "") else str(inst))


# ------------------------------------------------------------------ running one cell

def solve_cell(cell: Cell, settings: RunSettings, compiled=None, progress=None) -> dict:
    """Run one cell in this process and return its row (a refused problem or option: an error
    row); `progress` is the solver's progress callback (the bench status line's live counters)."""
    import gnppdsl                      # the public API: the command line solves through it
    from gnppdsl.cli.algorithms import parse_algorithms

    try:
        spec = parse_algorithms(cell.algorithm)[0]
        if compiled is None:
            compiled = gnppdsl.load_and_compile([cell.file], instance=cell.instance)
        options = gnppdsl.SolveOptions.from_settings(
            compiled.problem.settings, algorithm=spec.algorithm, switches=spec.switches,
            time_limit=settings.time_limit, seed=cell.seed, max_horizon=settings.max_horizon,
            order=settings.order, jit=settings.jit, distance_curvature=settings.distance_curvature,
            kinematic_curvature=settings.kinematic_curvature, planner=settings.planner, anytime=settings.anytime,
        )
        # every run compiles its own templates: runs share nothing, so no algorithm or seed is
        # timed with the templates an earlier one compiled
        compiled.compilers.clear()
        return result_row(cell, gnppdsl.solve_problem(compiled, options, progress=progress))
    except UserError as err:
        name = getattr(getattr(compiled, "problem", None), "name", "")
        return failure_row(cell, RUN_ERROR, str(err), problem=name)


def _limit_memory(memory_mb: int | None) -> Callable[[], None] | None:
    if not memory_mb:
        return None

    def apply() -> None:          # runs in the child between fork and exec
        limit = int(memory_mb) * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    return apply


# how running out of an address-space cap shows in a child's stderr: Python, C++, libc, OpenBLAS
_OUT_OF_MEMORY = ("memoryerror", "bad_alloc", "cannot allocate memory", "memory allocation", "out of memory")


def solve_cell_isolated(cell: Cell, settings: RunSettings) -> dict:
    """Run one cell in a child process with a wall-clock and a memory cap; every ending is a row."""
    payload = json.dumps({"cell": asdict(cell), "settings": asdict(settings)})
    env = dict(os.environ)
    env.setdefault("OMP_NUM_THREADS", "1")
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    try:
        proc = subprocess.run([sys.executable, "-m", "gnppdsl.cli.sweep_child"], input=payload,
                              capture_output=True, text=True, timeout=settings.hard_timeout, env=env,
                              preexec_fn=_limit_memory(settings.memory_mb))
    except subprocess.TimeoutExpired:
        return failure_row(cell, RUN_TIMEOUT, f"killed after {settings.hard_timeout:g} s wall clock")
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    if proc.returncode == 0 and lines:
        return json.loads(lines[-1])
    tail = (proc.stderr.strip().splitlines() or ["no output"])[-1][:300]
    if any(sign in proc.stderr.lower() for sign in _OUT_OF_MEMORY):
        return failure_row(cell, RUN_MEMORY, f"out of its {settings.memory_mb} MB memory cap: {tail}")
    return failure_row(cell, RUN_CRASHED, f"exit {proc.returncode}: {tail}")


# ------------------------------------------------------------------ executors

def run_serial(cells: list[Cell], settings: RunSettings, on_row: Callable[[dict], None],
               on_error: Callable[[str, UserError], None],
               progress_for: Callable[[Cell], Callable[[str], None]] | None = None) -> None:
    """Every cell in this process (no Ray needed), each problem (instance) loaded once and
    compiled afresh for every run; `progress_for(cell)` gives each run's progress callback (live
    plans / NLPs). Why afresh: a `Compiled` keeps what its solves instantiated (the factory's
    factor instances, their numeric programs), so a second seed on the same one skipped work the
    first paid (lab2: 0.78 -> 0.39 s CPU) and a serial sweep read faster than the same sweep on
    Ray, whose every run is a new process. The solver's modules are imported before the first
    run (`preload_solver`), as the isolated child does."""
    import gnppdsl
    from gnppdsl.solve.compiled import compile_problem

    preload_solver()
    by_file: dict[tuple[str, int | None], list[Cell]] = {}
    for c in cells:
        by_file.setdefault((c.file, c.instance), []).append(c)
    for (file, instance), group in by_file.items():
        try:
            compiled = gnppdsl.load_and_compile([file], instance=instance)
        except UserError as err:            # one broken problem does not stop the benchmark
            on_error(file, err)
            for c in group:
                on_row(failure_row(c, RUN_ERROR, str(err)))
            continue
        problem = compiled.problem
        for k, c in enumerate(group):
            # the loaded one for the first run, then dropped: no earlier run's instances stay alive
            fresh, compiled = (compiled if k == 0 else compile_problem(problem)), None
            on_row(solve_cell(c, settings, fresh, progress_for(c) if progress_for else None))
            del fresh


# the packages whose modules a solve imports on first use (`gnppdsl.lazy` keeps the command
# line's start fast); `gnppdsl.geometry.render` and the command line itself are not a solve's
SOLVER_PACKAGES = ("gnppdsl.compile", "gnppdsl.logic", "gnppdsl.conflicts", "gnppdsl.nlp",
                   "gnppdsl.geometry", "gnppdsl.reach", "gnppdsl.solve")


def preload_solver() -> None:
    """Import every module of the solver's packages before a timed run. Why: a run's CPU time
    is the solve's (`stats.cpu_time` starts with it), and the modules it imports lazily (87 on
    lab2, 0.08-0.27 s) are process start-up, paid by the first run of a serial sweep only but by
    every isolated run on Ray; importing them first times both executors alike."""
    import importlib
    import pkgutil

    for name in SOLVER_PACKAGES:
        pkg = importlib.import_module(name)
        for mod in pkgutil.iter_modules(pkg.__path__, name + "."):
            if mod.name != "gnppdsl.geometry.render":
                importlib.import_module(mod.name)


def run_on_ray(cells: list[Cell], settings: RunSettings, on_row: Callable[[dict], None],
               workers: int | None, address: str | None) -> None:
    """Every cell as a Ray task (one CPU each) running it isolated; rows handed over as they finish."""
    try:
        import ray
    except ImportError:
        raise UserError("--workers/--address need Ray: pip install 'gnppdsl[sweep]' (or: pip install ray)") from None
    os.environ.setdefault("RAY_AUTH_MODE", "disabled")
    init = dict(include_dashboard=False, log_to_driver=False, configure_logging=False)
    started_here = not ray.is_initialized()
    if started_here:
        try:
            if address:
                ray.init(address=address, **init)
            else:
                ray.init(num_cpus=workers, **init)
        except Exception as exc:             # Ray raises ConnectionError, RuntimeError, ValueError...
            where = f"--address {address}" if address else f"--workers {workers}"
            raise UserError(f"{where}: could not start or join Ray: {exc}") from None
    try:
        task = ray.remote(num_cpus=1, max_retries=0)(solve_cell_isolated)
        pending = {task.remote(c, settings): c for c in cells}
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                cell = pending.pop(ref)
                try:
                    row = ray.get(ref)
                except Exception as exc:     # the Ray worker itself died (node lost, OOM killer)
                    row = failure_row(cell, RUN_CRASHED, f"ray task failed: {type(exc).__name__}: {exc}"[:300])
                on_row(row)
    finally:
        if started_here:
            ray.shutdown()


def grid(files: Iterable[Path], labels: Iterable[str], seeds: int,
         instances: Iterable[int | None] = (None,)) -> Iterator[Cell]:
    """Cells in the order of the table: problem, then instance, then algorithm, then seed."""
    labels, instances = list(labels), list(instances)
    for f in files:
        for k in instances:
            for a in labels:
                for s in range(seeds):
                    yield Cell(str(f), a, s, k)
