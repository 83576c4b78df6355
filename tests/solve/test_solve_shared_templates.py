"""Template Functions shared by the solves of one compiled problem (`Compiled.body_compiler`):
a second solve compiles nothing and returns the same plan and the same continuous values as
the first (the cache changes cost, not results), and its solution passes the independent
re-check. `gnpp bench` clears the cache before every run so that no run is timed with
templates an earlier one compiled. In jit's background mode the shared compiler is built again
once the kernels it queued are ready."""
from __future__ import annotations

from pathlib import Path

from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions
from solve_checks import check_solution


def _options(seed: int = 0) -> SolveOptions:
    return SolveOptions(switches="trn", time_limit=60, max_horizon=6, order="staged", seed=seed)


def test_a_second_solve_reuses_every_template_and_returns_the_same_solution():
    from solve_toy import occupied_problem

    compiled = occupied_problem(waypoints=8)
    first = solve_compiled(compiled, _options())
    assert first.solved and first.stats.N == 4, first.message
    from gnppdsl.nlp import jit

    compiler = compiled.body_compiler(jit.mode(_options().jit))
    built = compiler.compiled
    assert built > 0

    second = solve_compiled(compiled, _options())
    assert second.solved, second.message
    assert compiler.compiled == built                   # nothing compiled again
    assert second.plan == first.plan
    assert second.stats.nlp_solves == first.stats.nlp_solves
    assert second.to_json()["steps"] == first.to_json()["steps"]    # values and trajectories
    check_solution(compiled, second)

    other = solve_compiled(compiled, _options(seed=3))  # another seed: still nothing new to build
    assert other.solved, other.message
    assert compiler.compiled == built
    check_solution(compiled, other)


def test_gnpp_bench_compiles_templates_for_every_run(monkeypatch):
    from gnppdsl.solve import loop

    sizes = []
    real = loop.solve_compiled

    def spy(compiled, options, *a, **kw):
        sizes.append(len(compiled.compilers))           # what the run starts with
        return real(compiled, options, *a, **kw)

    monkeypatch.setattr(loop, "solve_compiled", spy)
    from gnppdsl.cli.main import main

    problem = Path(__file__).resolve().parents[2] / "examples" / "planar" / "p1_one_block.pntc"
    rc = main(["bench", str(problem), "--algorithms", "oneway,gnpp_trn",
               "--seeds", "2", "--time-limit", "30", "--quiet"])
    assert rc == 0
    assert sizes == [0, 0, 0, 0]


def test_the_shared_template_compiler_is_rebuilt_once_the_queued_kernels_are_ready():
    from solve_toy import occupied_problem

    from gnppdsl.nlp.body_compiler import BodyCompiler

    class Kernels:                                   # what body_compiler asks a KernelCache
        native = staticmethod(lambda f: f)
        ready = [False, True, False]

        def newly_ready(self):
            return self.ready.pop(0)

    compiled = occupied_problem(waypoints=4)
    kernels = Kernels()
    first = compiled.compilers["background"] = BodyCompiler(compiled.geometry, kernels=kernels)
    assert compiled.body_compiler("background") is first          # nothing ready yet
    second = compiled.body_compiler("background")                 # ready: built again
    assert second is not first and second.kernels is kernels
    assert compiled.body_compiler("background") is second
