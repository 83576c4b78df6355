"""Progress of long work: a live status line on a terminal, plain lines otherwise.

Why our own ~100 lines instead of rich or tqdm: the line shows counters the solver already keeps
(`Stats`: plans tried, conflicts, NLPs) against the time limit, not a bar of known length (a
GNPP solve does not know how many plans it will try), and it must share the terminal with
`--verbose` messages (cleared, message printed, redrawn). rich's `Live` would do the redraw but
is not a dependency of the project; tqdm's bar needs a total. Both would add a package for a
single line of ANSI (carriage return + erase-line).

- On a terminal (`stream.isatty()`): one line, redrawn by a ticker thread every `interval`
  seconds (the time keeps running during a long NLP) and at every solver event.
- Not a terminal (a pipe, a CI log): one plain line per plan tried, so a log shows progress
  without control characters and without flooding.
- `--quiet`: the CLI does not create a status at all.
"""
from __future__ import annotations

import re
import sys
import threading
import time
from typing import Any, Callable, TextIO

_PLAN = re.compile(r"^plan #(\d+) \(length (\d+)\)")


class StatusLine:
    """One line on a terminal, redrawn by a ticker thread; subclasses say what it shows."""

    def __init__(self, stream: TextIO | None = None, tty: bool | None = None, interval: float = 0.25) -> None:
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty() if tty is None else tty
        self.interval = interval
        self.t0 = time.perf_counter()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._shown = False

    def text(self) -> str:
        raise NotImplementedError

    def _draw(self) -> None:
        self.stream.write("\r" + self.text() + "\x1b[K")
        self.stream.flush()
        self._shown = True

    def _clear(self) -> None:
        if self.tty and self._shown:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self._shown = False

    def _tick(self) -> None:
        while not self._stop.wait(self.interval):
            with self._lock:
                self._draw()

    def __enter__(self):
        if self.tty:
            self._thread = threading.Thread(target=self._tick, name="gnpp-status", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        with self._lock:
            self._clear()


class SolveStatus(StatusLine):
    """The solver's `progress` callback for `gnpp solve`; `watch(stats)` gives it the live `Stats`."""

    def __init__(self, label: str, time_limit: float | None = None, stream: TextIO | None = None,
                 tty: bool | None = None, echo: Callable[[str], None] | None = None,
                 interval: float = 0.25, spent: float = 0.0) -> None:
        super().__init__(stream, tty, interval)
        self.label = label
        self.time_limit = time_limit           # the user's limit, which loading counts against
        self.spent = spent                     # seconds of it spent before the solve (loading)
        self.echo = echo                       # --verbose: every solver message, printed whole
        self.stats: Any = None
        self.plans = 0                         # counted from the messages until stats are watched
        self.conflicts = 0
        self.length = None

    # -- the solver's side -----------------------------------------------------------------
    def watch(self, stats: Any) -> None:
        self.stats = stats

    def __call__(self, msg: str) -> None:
        m = _PLAN.match(msg)
        if m:
            self.plans, self.length = int(m.group(1)), int(m.group(2))
        elif msg.lstrip().startswith("conflict ("):
            self.conflicts += 1
        with self._lock:
            if self.echo is not None:
                self._clear()
                self.echo(msg)
            if self.tty:
                self._draw()
            elif m:
                self.stream.write(self.text() + "\n")
                self.stream.flush()

    # -- text ------------------------------------------------------------------------------
    def text(self) -> str:
        s = self.stats
        plans = s.plans if s is not None else self.plans
        conflicts = s.conflicts if s is not None else self.conflicts
        parts = [f"{self.label}: plans {plans}" + (f" (length {self.length})" if self.length is not None else ""),
                 f"conflicts {conflicts}"]
        if s is not None:
            parts.append(f"NLPs {s.nlp_solves}")
        elapsed = self.spent + time.perf_counter() - self.t0
        parts.append(f"{elapsed:.1f} s" + (f" of {self.time_limit:g} s" if self.time_limit else ""))
        return " · ".join(parts)


class BenchStatus(StatusLine):
    """`gnpp bench`: runs done of all and the time left, the plans and NLPs of the run in
    progress (live, through `run_progress`, when runs are solved in this process) and per
    finished run (from the rows: what a run costs, also with Ray where only rows come back).
    A terminal line or nothing extra (the per-run lines bench prints are the plain form)."""

    def __init__(self, total: int, stream: TextIO | None = None, tty: bool | None = None,
                 interval: float = 0.5) -> None:
        super().__init__(stream, tty, interval)
        self.total = total
        self.done = 0
        self.last = ""
        self.plans = 0                         # sums over the finished runs' rows
        self.nlps = 0
        self.counted = 0                       # runs whose rows were given
        self.current: _RunProgress | None = None

    def run_progress(self, label: str) -> "_RunProgress":
        """The `progress` callback of the run about to start (`solve_problem(progress=...)`)."""
        self.current = _RunProgress(self, label)
        return self.current

    def text(self) -> str:
        elapsed = time.perf_counter() - self.t0
        eta = ""
        if 0 < self.done < self.total:
            eta = f", about {elapsed / self.done * (self.total - self.done):.0f} s left"
        parts = [f"bench: {self.done} of {self.total} runs"]
        if self.current is not None:
            parts.append(self.current.text())
        elif self.last:
            parts.append("last " + self.last)
        if self.counted:
            parts.append(f"per run {self.plans / self.counted:.1f} plans, {self.nlps / self.counted:.1f} NLPs")
        return " · ".join(parts) + f" · {elapsed:.0f} s{eta}"

    def print_row(self, text: str, row: dict | None = None) -> None:
        """A finished run's line, printed above the status line; `row` (the CSV row) adds its
        plans and NLPs to the per-run figures."""
        self.done += 1
        self.last = text.split(":")[0].strip()
        if row is not None:
            self.counted += 1
            self.plans += int(row.get("plans") or 0)
            self.nlps += int(row.get("nlp_solves") or 0)
        self.current = None
        with self._lock:
            self._clear()
            self.stream.write(text + "\n")
            if self.tty:
                self._draw()
            self.stream.flush()


class _RunProgress:
    """The solver's `progress` for one bench run: the live `Stats` (plans, NLPs) it is given
    by `watch`, redrawn on the bench line at each solver message."""

    def __init__(self, owner: BenchStatus, label: str) -> None:
        self.owner, self.label, self.stats = owner, label, None

    def watch(self, stats: Any) -> None:
        self.stats = stats

    def __call__(self, msg: str) -> None:  # noqa: ARG002 - the counters live in `stats`
        if self.owner.tty:
            with self.owner._lock:
                self.owner._draw()

    def text(self) -> str:
        s = self.stats
        if s is None:
            return f"now {self.label}"
        return f"now {self.label}: plans {s.plans}, NLPs {s.nlp_solves}"
