"""Compiling a problem for the loop: a `.pntc` problem (and its domain) -> `Compiled`: the IR
problem, its SAS+ task, the graph-NLP factory, the scene's geometry, the relaxation levels, and the
fingerprint and object identities the subgraph database keys on.

Why apart from the loop: compiling does not depend on how a problem is solved, and one `Compiled`
serves many solves (seeds, algorithms, `gnpp bench`), which share its template compiler.
"""
from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

from gnppdsl.compile.sas import SASTask
from gnppdsl.errors import UserError
from gnppdsl.ir.model import Problem

if TYPE_CHECKING:  # pragma: no cover  (casadi, pinocchio: imported when a problem is compiled)
    from gnppdsl.compile.factory import GraphNLPFactory
    from gnppdsl.geometry.context import GeometryContext
    from gnppdsl.nlp.body_compiler import BodyCompiler
    from gnppdsl.nlp.subgraph import Relaxation


@dataclass
class Compiled:
    """A loaded problem with its SAS+ task, graph-NLP factory, geometry and relaxations."""

    problem: Problem
    task: SASTask
    factory: GraphNLPFactory
    geometry: GeometryContext | None = None
    relaxations: tuple[Relaxation, ...] = ()     # loose -> tight
    fingerprint: str = ""
    object_key: Callable[[str], str] | None = None   # object name -> geometry identity (`object_keys`)
    # jit mode -> the BodyCompiler its solves share (see `body_compiler`)
    compilers: dict[str, BodyCompiler] = field(default_factory=dict, repr=False, compare=False)

    def body_compiler(self, jit_mode: str) -> BodyCompiler:
        """The template compiler (gnppdsl.nlp.body_compiler.BodyCompiler) shared by every solve
        of this problem in this process. Why shared: building a template's casadi Function and
        its SX Jacobian and Hessian depends only on the factor body and the geometry, not on the
        solve, and it is a large part of a robot solve (lab2, seed 1: 2.9 of 4.8 s CPU); a
        second solve of the same problem (another seed, algorithm or time limit: `gnpp bench`,
        library users) then compiles nothing. One compiler per jit mode (`gnppdsl.nlp.jit`),
        since those with kernels hold compiled code; in the background mode a compiler is built
        again once kernels it queued have been compiled, so that the next solve uses them."""
        hit = self.compilers.get(jit_mode)
        if hit is not None and hit.kernels is not None and hit.kernels.newly_ready():
            hit = None
        if hit is None:
            from gnppdsl.nlp import jit
            from gnppdsl.nlp.body_compiler import BodyCompiler

            old = self.compilers.get(jit_mode)
            kernels = old.kernels if old is not None else jit.kernel_cache(jit_mode)
            hit = self.compilers[jit_mode] = BodyCompiler(self.geometry, kernels=kernels)
        return hit

    @property
    def name(self) -> str:
        return getattr(self.problem, "name", "problem")

    @property
    def domain_name(self) -> str:
        dom = getattr(self.problem, "domain", None)
        return getattr(dom, "name", "domain")


def load_and_compile(paths: Sequence[str] | str, instance: int | None = None) -> Compiled:
    """Load a problem (its domain found next to it, or given first), compile task and factory.
    `instance`: the randomised instance of that seed (`gnppdsl.ir.instances.draw_instance`)."""
    paths = [paths] if isinstance(paths, (str, Path)) else list(paths)
    from gnppdsl.inputs import SOURCE_SUFFIXES, InputError, check_suffix, read_text

    for p in paths:                 # regular .pntc files of bounded size (`gnppdsl.inputs`)
        try:
            check_suffix(p, SOURCE_SUFFIXES, "problem or domain")
            read_text(p)
        except InputError as exc:
            raise UserError(f"{p}: {exc.message}") from None
    if len(paths) > 2:
        raise UserError("give a problem file, optionally preceded by its domain file")
    from gnppdsl.ir import load_problem

    if len(paths) == 2:
        # either order: the problem is the file that declares `problem NAME for DOMAIN`
        first_is_problem = _PROBLEM_HEADER.search(read_text(paths[0])) is not None
        prob_path, dom_path = (paths[0], paths[1]) if first_is_problem else (paths[1], paths[0])
        problem = load_problem(prob_path, dom_path)
    else:
        problem = load_problem(paths[0])
    if instance is not None:
        from gnppdsl.ir.instances import draw_instance

        problem = draw_instance(problem, instance)
    return compile_problem(problem)


_PROBLEM_HEADER = re.compile(r"^\s*problem\s+\w+\s+for\s+\w+", re.MULTILINE)


def compile_problem(problem: Problem) -> Compiled:
    from gnppdsl.compile.factory import GraphNLPFactory
    from gnppdsl.compile.task import build_task
    from gnppdsl.nlp.subgraph import Relaxation

    from gnppdsl.compile.factory import scene_robot_dims

    task = build_task(problem)
    geometry = None
    robot_dims = None
    if getattr(problem, "scene", None) is not None:
        from gnppdsl.geometry.context import GeometryContext

        geometry = GeometryContext(problem.scene)
        fallback = scene_robot_dims(problem)

        def robot_dims(robot: str):
            # joint dimension and limits from the pinocchio model for URDF robots
            if robot in geometry.models:
                return geometry.robot_dims(robot)
            return fallback(robot)
    factory = GraphNLPFactory(problem, task, robot_dims=robot_dims)
    relaxations = tuple(Relaxation.of(r.name, r.drop) for r in (problem.relaxations or problem.domain.relaxations))
    return Compiled(problem, task, factory, geometry, relaxations, fingerprint(problem), object_keys(problem))


def fingerprint(problem: Problem) -> str:
    """Hash of what the semantic labels of factors do not capture: the domain's templates,
    rules, frames and continuous declarations, and the scene's shapes and robot models (sdist /
    fk read them at solve time). Poses are folded into factor bodies as constants, so they are
    not needed here. Stable across processes (no hash-randomised set order, no spans)."""
    dom = problem.domain
    parts = [dom.templates, dom.rules, dom.frames, dom.continuous]
    scene = getattr(problem, "scene", None)
    if scene is not None:
        parts.append(scene.dimension)
        parts.append(scene.ignore_collisions)
    return hashlib.sha256(canonical(parts).encode()).hexdigest()[:24]


def object_keys(problem: Problem) -> Callable[[str], str]:
    """Geometry identity of each scene entity (shape; robot model), for factor labels in the
    subgraph database: a factor naming `b1` in `sdist` only matches a factor naming an object
    `b1` of the same shape. Poses are not included (they are constants in the bodies)."""
    scene = getattr(problem, "scene", None)
    keys: dict[str, str] = {}
    if scene is not None:
        for n, o in scene.objects.items():
            keys[n] = hashlib.sha256(canonical(o.shape).encode()).hexdigest()[:12]
        for n, r in scene.robots.items():
            keys[n] = hashlib.sha256(canonical((r.kind, r.model, r.urdf, r.srdf, r.ee, r.locked, r.shape,
                                                r.package_dirs)).encode()).hexdigest()[:12]
    return lambda name: keys.get(name, "-")


_COMPARED: dict[type, tuple[str, ...] | None] = {}


def _compared_fields(cls: type) -> tuple[str, ...] | None:
    """The names of a dataclass's `compare=True` fields, None for other types; per type, once.
    Why: `dataclasses.fields` per node was ~40 % of `fingerprint` (6,000 nodes on the Lab
    domain, every `load_and_compile`)."""
    hit = _COMPARED.get(cls, ())
    if hit != ():
        return hit
    import dataclasses

    names = tuple(f.name for f in dataclasses.fields(cls) if f.compare) if dataclasses.is_dataclass(cls) else None
    _COMPARED[cls] = names
    return names


def canonical(obj: object) -> str:
    """A deterministic text form of nested dataclasses / containers (sets sorted, spans and
    other `compare=False` fields left out)."""
    fields = None if isinstance(obj, type) else _compared_fields(type(obj))
    if fields is not None:
        return f"{type(obj).__name__}(" + ",".join(f"{f}={canonical(getattr(obj, f))}" for f in fields) + ")"
    if isinstance(obj, dict):
        return "{" + ",".join(sorted(f"{canonical(k)}:{canonical(v)}" for k, v in obj.items())) + "}"
    if isinstance(obj, (set, frozenset)):
        return "{" + ",".join(sorted(canonical(x) for x in obj)) + "}"
    if isinstance(obj, (list, tuple)):
        return "[" + ",".join(canonical(x) for x in obj) + "]"
    return repr(obj)
