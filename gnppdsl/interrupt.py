"""SIGINT, SIGTERM and the whole-run time limit: end a solve within a second, keep what it found.

Why a module of its own, at the bottom of the layers: the signal arrives wherever the process
happens to be, and ipopt (through casadi) and clingo run native code. A Python handler runs
only when native code returns to Python, and an exception raised inside a casadi callback
(ipopt's iteration callback, a Python distance query) is caught by casadi and lost: SIGINT was
swallowed in 3 of 5 trials and the run went on to exit 0. So the handler only records the
request, and the code that runs the native searches looks at it:
- ipopt's iteration callback (`gnppdsl.nlp.feasibility._Monitor`) stops the run at the next
  iteration, and `check()` after the run raises `Interrupted` in plain Python;
- the clingo poll (`gnppdsl.logic.planner`, every 50 ms) cancels the search and raises;
- elsewhere inside `interruptible()` (the CLI's whole run: loading, grounding, building
  casadi Functions) the handler raises at once, as Python does with KeyboardInterrupt; an
  exception that casadi turns into another one on the way out still ends the run as a stop
  (the CLI looks at `pending()`), and the subgraph database stores nothing once a stop is
  pending, so no verdict computed after the request is kept.
The time limit: `arm_time_limit(seconds)` sets a real-time alarm (SIGALRM) for the whole run,
loading and grounding included, handled the same way with reason "time_limit", so the limit
holds even where the loop's own deadline checks do not reach.
`Interrupted` derives from BaseException so that no `except Exception` on the way swallows it;
the loop turns it into a result with status "interrupted" (or "time_limit") and the CLI writes
that result to `--json` and exits 130 (SIGINT), 143 (SIGTERM) or 1 (time limit).
"""
from __future__ import annotations

import signal
import threading
from contextlib import contextmanager
from typing import Iterator

#: exit status per reason, as a shell reports a process ended by that signal (128 + number)
EXIT_CODES = {"SIGINT": 130, "SIGTERM": 143, "time_limit": 1}


class Interrupted(BaseException):
    """The run was asked to stop: `reason` is "SIGINT", "SIGTERM" or "time_limit"."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason

    @property
    def exit_code(self) -> int:
        return EXIT_CODES.get(self.reason, 1)

    def describe(self) -> str:
        return "time limit reached" if self.reason == "time_limit" else f"interrupted by {self.reason}"


_state = {"reason": None, "raise_now": 0, "installed": False, "last": None, "early": None}


def pending() -> str | None:
    """The reason of a stop request not yet acted on, or None (cheap: called per iteration)."""
    return _state["reason"]


def check() -> None:
    """Raise `Interrupted` if a stop was requested (call it where native code has returned)."""
    if _state["reason"] is not None:
        raise Interrupted(_state["reason"])


def request(reason: str) -> None:
    """Ask the run to stop (what the signal handlers do; tests call it directly). Raises at
    once inside `interruptible()`."""
    if _state["reason"] is None:
        _state["reason"] = reason
    if _state["raise_now"]:
        raise Interrupted(_state["reason"])


def last_stop() -> str | None:
    """The stop request of the last `handlers()` block that ended, or None."""
    return _state["last"]


def clear() -> None:
    _state["reason"] = None


@contextmanager
def interruptible() -> Iterator[None]:
    """The run of a command: a signal raises `Interrupted` where the code is, as
    KeyboardInterrupt would, except inside `native()`."""
    check()
    _state["raise_now"] += 1
    try:
        yield
    finally:
        _state["raise_now"] -= 1


@contextmanager
def native() -> Iterator[None]:
    """An ipopt run or a clingo search (native code that calls back into Python): a signal
    only sets the flag, which the iteration callback and the poll look at; leaving the block
    raises `Interrupted`."""
    saved = _state["raise_now"]
    _state["raise_now"] = 0
    try:
        yield
    finally:
        _state["raise_now"] = saved
    check()


def _handler(signum, frame) -> None:  # noqa: ARG001 - the signal module's signature
    request("time_limit" if signum == signal.SIGALRM else signal.Signals(signum).name)


def _early_handler(signum, frame) -> None:  # noqa: ARG001
    if _state["reason"] is None:
        _state["reason"] = signal.Signals(signum).name


def early() -> None:
    """From the process's start (`gnpp` builds its parser, 0.6 s of imports under load) until
    a command installs `handlers()` or `release_early()` is called, SIGINT and SIGTERM are
    only recorded: measured with benchmarks/bench_signals.py, a SIGTERM in that window ended
    the process with -15, no message and no `--json`. Main thread only."""
    if threading.current_thread() is not threading.main_thread() or _state["early"] is not None:
        return
    _state["early"] = {s: signal.signal(s, _early_handler) for s in (signal.SIGINT, signal.SIGTERM)}


def release_early(keep: bool) -> str | None:
    """The previous handlers back. A request recorded meanwhile is returned; with `keep`
    (a command about to enter `handlers()`, which acts on it at its first `check()`) it stays
    pending, otherwise it is cleared and the caller ends the command."""
    saved = _state["early"]
    if saved is None:
        return None
    _state["early"] = None
    for s, h in saved.items():
        signal.signal(s, h)
    reason = _state["reason"]
    if not keep:
        clear()
    _state["carried"] = keep and reason is not None
    return reason


def drop_carried() -> None:
    """Forget a request `release_early(keep=True)` kept that no `handlers()` took over (the
    command failed before its run): it must not stop the next command of this process."""
    if _state.get("carried"):
        _state["carried"] = False
        clear()


@contextmanager
def handlers() -> Iterator[None]:
    """SIGINT, SIGTERM and SIGALRM handled as above for the duration of the block (the CLI's
    run); the previous handlers and no alarm afterwards. Only in the main thread (signal
    handlers can be installed nowhere else); elsewhere a no-op."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    carried = _state["reason"] if _state.get("carried") else None   # a request from `early()`
    clear()
    _state["reason"] = carried
    _state["carried"] = False
    _state["last"] = None
    old = {s: signal.signal(s, _handler) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGALRM)}
    _state["installed"] = True
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        for s, h in old.items():
            signal.signal(s, h)
        _state["installed"] = False
        _state["last"] = _state["reason"]
        clear()


def arm_time_limit(seconds: float) -> None:
    """A real-time alarm `seconds` from now (within `handlers()`): the hard end of the run."""
    if _state["installed"]:
        signal.setitimer(signal.ITIMER_REAL, max(1e-3, float(seconds)))
