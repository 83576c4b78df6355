"""The module library: loading .pntc files and modules, `use`, the standard library, shared pieces.

Why one `ModuleLibrary` (the base of `workspace.Workspace`): modules are shared by domains (the
prelude by all of them), so they are parsed and resolved once per run and cached by path; every
phase reports to one `Reporter`, so `gnpp check a.pntc b.pntc` lists every error of every file
together.

This module knows files and modules (and the pieces every resolver shares: value spaces,
signatures, constants, template bodies, which declaration goes where); what a domain or a
problem means is in `resolve_domain` and `resolve_problem`, which read this library, and
`workspace.Workspace` hands them the parsed file. Why the cut here: the resolvers call back
into the shared pieces, so those sit below them and the workspace that starts them sits above
(no import cycle).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from gnppdsl.ir import builtins as B
from gnppdsl.ir import model as M
from gnppdsl.ir.builtins import Space
from gnppdsl.ir.expr import Param
from gnppdsl.ir.typecheck import ANY, INT, OBJ, STRING, VAL, Checker, Scope, Ty, fold
from gnppdsl.lang import ast
from gnppdsl.lang.diagnostics import Reporter, did_you_mean
from gnppdsl.lang.parser import parse_file

PRELUDE = "prelude"
VALUE_SPACES = {"R", "SE2", "SE3", "quat", "joints"}
RESERVED_TYPE_NAMES = VALUE_SPACES | {"value", "string", "int", "bool", "none", "true", "false"}


def _sig_ty(p: M.Signature) -> Ty:
    if p.kind == "object":
        return OBJ((p.type or M.ROOT_TYPE,))
    if p.kind == "string":
        return STRING
    if p.kind == "any":
        return ANY
    if p.space.kind == "int":
        return INT
    return VAL(p.space)


@dataclass
class ModuleEnv:
    """A module resolved independently of any domain (templates are checked per domain)."""

    name: str
    path: str
    file: ast.FileAst
    uses: list["ModuleEnv"] = field(default_factory=list)
    consts: dict[str, object] = field(default_factory=dict)
    scene_attrs: dict[str, M.SceneAttr] = field(default_factory=dict)
    primitives: dict[str, M.Primitive] = field(default_factory=dict)
    templates: dict[str, ast.TemplateDecl] = field(default_factory=dict)   # short name -> ast

    def closure(self) -> list["ModuleEnv"]:
        """This module and everything it uses, transitively (each once)."""
        out: list[ModuleEnv] = []
        todo = [self]
        while todo:
            m = todo.pop()
            if any(m is x for x in out):
                continue
            out.append(m)
            todo.extend(m.uses)
        return out


def note_param(err, seen: set[str], name: ast.Name) -> None:
    """Record one parameter name of a declaration, reporting a repeat (shared by template
    signatures and typed rule/action parameters, so both say the same thing)."""
    if name.value in seen:
        err(name.span, f"parameter '{name.value}' is declared twice", "duplicate")
    seen.add(name.value)


class ModuleLibrary:
    """Loads .pntc files and modules and holds the pieces every resolver shares; all
    diagnostics go to `self.reporter`. `workspace.Workspace` adds domains and problems."""

    def __init__(self, reporter: Reporter | None = None, stdlib: Path | None = None) -> None:
        self.reporter = reporter or Reporter()
        self._stdlib = stdlib
        self._asts: dict[str, ast.FileAst | None] = {}
        self._modules: dict[str, ModuleEnv | None] = {}
        self._loading: set[str] = set()

    # ------------------------------------------------------------------ files
    @property
    def stdlib(self) -> Path:
        if self._stdlib is None:
            from gnppdsl.resources import stdlib_dir

            self._stdlib = stdlib_dir()
        return self._stdlib

    def parse(self, path: str | Path) -> ast.FileAst | None:
        key = str(Path(path))
        if key not in self._asts:
            self._asts[key] = parse_file(key, self.reporter)
        return self._asts[key]

    def err(self, span, msg, kind="error", hint=None):
        self.reporter.error(span, msg, kind, hint)

    # ------------------------------------------------------------------ modules
    def find_module(self, name: str, from_dir: Path) -> Path | None:
        from gnppdsl.inputs import is_regular_file

        for d in (from_dir, self.stdlib):
            p = d / f"{name}.pntc"
            if is_regular_file(p):          # False, not OSError, for a 300-character name
                return p
        return None

    def available_modules(self, from_dir: Path) -> list[str]:
        names = []
        for d in (from_dir, self.stdlib):
            try:
                names.extend(p.stem for p in d.glob("*.pntc"))
            except OSError:
                pass
        return names

    def use(self, name: ast.Name, from_dir: Path) -> ModuleEnv | None:
        path = self.find_module(name.value, from_dir)
        if path is None:
            self.err(name.span, f"unknown module '{name.value}'", "unknown-module",
                     did_you_mean(name.value, self.available_modules(from_dir))
                     or f"modules are looked up in {from_dir} and {self.stdlib}")
            return None
        return self.module_at(path, name)

    def module_at(self, path: Path, name: ast.Name | None = None) -> ModuleEnv | None:
        key = str(path)
        if key in self._modules:
            return self._modules[key]
        if key in self._loading:
            self.err(name.span if name else None, f"module '{path.stem}' uses itself (cycle)", "cycle")
            return None
        self._loading.add(key)
        try:
            f = self.parse(path)
            env = None
            if f is not None:
                if f.header.kind != "module":
                    self.err(name.span if name else f.header.span,
                             f"'{path.name}' is a {f.header.kind}, not a module", "not-a-module")
                else:
                    if name is not None and f.header.name.value != name.value:
                        self.err(f.header.name.span, f"module file '{path.name}' declares "
                                 f"module '{f.header.name.value}'", "module-name",
                                 f"write `module {name.value}`")
                    env = self._resolve_module(f)
            self._modules[key] = env
            return env
        finally:
            self._loading.discard(key)

    def prelude(self) -> ModuleEnv | None:
        p = self.stdlib / f"{PRELUDE}.pntc"
        if not p.is_file():
            self.err(None, f"the standard library has no {PRELUDE}.pntc ({self.stdlib})", "missing-file")
            return None
        return self.module_at(p)

    def _uses(self, f: ast.FileAst) -> list[ModuleEnv]:
        here = Path(f.path).parent
        mods: list[ModuleEnv] = []
        if f.header.name.value != PRELUDE:
            pre = self.prelude()
            if pre is not None:
                mods.append(pre)
        for d in f.items:
            if isinstance(d, ast.UseDecl):
                for n in d.names:
                    m = self.use(n, here)
                    if m is not None and not any(m is x for x in mods):
                        mods.append(m)
        return mods

    def _resolve_module(self, f: ast.FileAst) -> ModuleEnv:
        env = ModuleEnv(f.header.name.value, f.path, f)
        env.uses = self._uses(f)
        allowed = (ast.UseDecl, ast.ConstDecl, ast.TemplateDecl, ast.SceneAttrDecl, ast.PrimitiveDecl)
        self._reject(f, allowed, "a module")
        qconsts = qualified_consts(env.uses)
        env.consts = self._consts(f, qconsts, {})
        for d in f.items:
            if isinstance(d, ast.SceneAttrDecl):
                self._add_unique(env.scene_attrs, d.name, M.SceneAttr(
                    d.name.value, self._signature(d.params, None), self._space(d.space, None, result=True),
                    env.name, d.span), "scene attribute")
            elif isinstance(d, ast.PrimitiveDecl):
                self._add_unique(env.primitives, d.name, M.Primitive(
                    d.name.value, self._signature(d.params, None), self._space(d.space, None, result=True),
                    env.name, d.span), "primitive")
            elif isinstance(d, ast.TemplateDecl):
                if d.name.value in env.templates:
                    self.err(d.name.span, f"template '{d.name.value}' is declared twice", "duplicate")
                env.templates[d.name.value] = d
        return env

    def check_module(self, path: str | Path) -> M.Module | None:
        """Resolve a module on its own (templates checked in an open world)."""
        env = self.module_at(Path(path))
        if env is None:
            return None
        attrs, prims = merged_decls(env.closure())
        templates = {}
        for short, decl in env.templates.items():
            # the world space (SE2 or SE3) is the using domain's: accept either
            best = None
            for world in (B.SE2, B.SE3):
                rep = Reporter()
                scope = Scope(consts=dict(env.consts), qconsts=qualified_consts(env.uses), scene_attrs=attrs,
                              primitives=prims, open_world=True, world_space=world)
                t = self._template(decl, env.name, scope, None, reporter=rep)
                if best is None or len(rep.errors) < len(best[1].errors):
                    best = (t, rep)
            templates[f"{env.name}.{short}"] = best[0]
            for dgn in best[1].diagnostics:
                self.reporter.add(dgn)
        return M.Module(env.name, env.path, tuple(m.name for m in env.uses), dict(env.consts),
                        templates, dict(env.scene_attrs), dict(env.primitives), env.file.header.span)

    # ------------------------------------------------------------------ shared pieces
    def _reject(self, f: ast.FileAst, allowed: tuple, what: str) -> None:
        for d in f.items:
            if not isinstance(d, allowed):
                word = _decl_word(d)
                self.err(d.span, f"'{word}' is not allowed in {what}", "misplaced",
                         _where_allowed(word))

    def _add_unique(self, table: dict, name: ast.Name, value, what: str) -> None:
        if name.value in table:
            self.err(name.span, f"{what} '{name.value}' is declared twice", "duplicate")
        else:
            table[name.value] = value

    def _consts(self, f: ast.FileAst, qconsts: dict, objects: dict) -> dict:
        consts: dict[str, object] = {}
        for d in f.items:
            if not isinstance(d, ast.ConstDecl):
                continue
            scope = Scope(consts=dict(consts), qconsts=qconsts, objects=objects, allow_prime=False,
                          prime_context="in a constant")
            x, t = Checker(scope, self.reporter).expr(d.expr)
            if t.kind == "error":
                continue
            v = fold(x)
            if v is not None:
                val: object = v
            elif hasattr(x, "items") and all(fold(i) is not None for i in x.items):
                val = tuple(fold(i) for i in x.items)
            else:
                self.err(d.expr.span, "a constant must be a number or a vector of numbers",
                         "const")
                continue
            if d.name.value in consts or d.name.value == "pi":
                self.err(d.name.span, f"constant '{d.name.value}' is declared twice", "duplicate")
            consts[d.name.value] = val
        return consts

    def _space(self, s: ast.SpaceAst, params: tuple[str, ...] | None, result: bool = False,
               allow_object: bool = False) -> Space | None:
        """A value space; None for `value` (any). Errors are reported."""
        n = s.name.value
        if n == "R":
            if s.arg is not None:
                self.err(s.span, "write R[n] for a vector space", "space")
            if s.dim is not None and s.dim < 1:
                self.err(s.span, "a vector space needs at least one dimension", "space")
            return B.R(s.dim or 1)
        if s.dim is not None or (s.arg is not None and n != "joints"):
            self.err(s.span, f"'{n}' takes no {'[n]' if s.dim is not None else 'argument'}", "space")
        if n in ("SE2", "SE3"):
            return B.SE2 if n == "SE2" else B.SE3
        if n == "quat":
            return B.QUAT
        if n == "int":
            return Space("int", 1)
        if n == "joints":
            robot = s.arg.value if s.arg is not None else None
            if params is not None and robot is None:
                self.err(s.span, "write joints(r) with r a parameter of this declaration", "space")
            if params is not None and robot is not None and robot not in params:
                self.err(s.arg.span, f"'{robot}' is not a parameter here", "unknown-name",
                         did_you_mean(robot, params))
            return Space("joints", 0, robot)
        if n == "value" and (result or allow_object):
            return None
        if n == "object" and result:
            return Space("object", 1)
        self.err(s.name.span, f"unknown space '{n}'", "unknown-space",
                 did_you_mean(n, ["R", "SE2", "SE3", "quat", "joints"])
                 or "spaces are R, R[n], SE2, SE3, quat, joints(r)")
        return B.SCALAR

    def _signature(self, params: tuple[ast.SigParam, ...], types: dict | None) -> tuple[M.Signature, ...]:
        out = []
        seen: set[str] = set()
        for p in params:
            note_param(self.err, seen, p.name)
            n = p.space.name.value
            if n == "value":
                out.append(M.Signature(p.name.value, "any", span=p.span))
            elif n == "string":
                out.append(M.Signature(p.name.value, "string", span=p.span))
            elif n in VALUE_SPACES or n == "int":
                out.append(M.Signature(p.name.value, "value", space=self._space(p.space, None),
                                       span=p.span))
            else:
                if p.space.dim is not None or p.space.arg is not None:
                    self.err(p.space.span, f"unknown space '{n}'", "unknown-space")
                elif types is not None and n not in types:
                    self.err(p.space.name.span, f"unknown type or space '{n}'", "unknown-type",
                             did_you_mean(n, list(types) + ["R", "SE2", "SE3", "quat", "joints", "value"]))
                out.append(M.Signature(p.name.value, "object", type=n, span=p.span))
        return tuple(out)

    def _template(self, d: ast.TemplateDecl, module: str, scope: Scope, types: dict | None,
                  reporter: Reporter | None = ...) -> M.Template:
        """Check a template body in `scope`; `reporter=None` discards the diagnostics."""
        rep = self.reporter if reporter is ... else (reporter or Reporter())
        sig = self._signature(d.params, types)
        scope.params = {p.name: (Param(p.name), _sig_ty(p)) for p in sig}
        scope.allow_prime = True
        body = Checker(scope, rep).statements(d.body)
        return M.Template(f"{module}.{d.name.value}", sig, body, frozenset(t.value for t in d.tags),
                          module, scope.used_prime, d.span)

    def _parse_kind(self, path: str | Path, kind: str) -> ast.FileAst | None:
        """The parsed file if it is a `kind` file ("domain" / "problem"), else None (reported)."""
        f = self.parse(path)
        if f is not None and f.header.kind != kind:
            self.err(f.header.span, f"expected a {kind} file, but this is a {f.header.kind}",
                     f"not-a-{kind}")
            return None
        return f

    def find_domain(self, f: ast.FileAst, candidates: list[str] | None = None) -> str | None:
        """Domain discovery: given files, `domain.pntc` next to the problem, any sibling file
        declaring `domain NAME`."""
        want = f.header.domain.value
        here = Path(f.path).parent
        ordered = sorted(candidates or [], key=lambda c: Path(c).resolve().parent != here.resolve())
        for c in ordered:                       # given files, those next to the problem first
            g = self.parse(c)
            if g is not None and g.header.kind == "domain" and g.header.name.value == want:
                return c
        seen_domains = []
        first = here / "domain.pntc"
        siblings = [first] if first.is_file() else []
        try:
            siblings += sorted(p for p in here.glob("*.pntc") if p != first)
        except OSError:
            pass
        for p in siblings:
            if str(p) == f.path:
                continue
            head = peek_header(p)
            if head is None:
                continue
            kind, name = head
            if kind == "domain":
                seen_domains.append(name)
                if name == want:
                    return str(p)
        self.err(f.header.domain.span, f"cannot find domain '{want}'", "missing-domain",
                 did_you_mean(want, seen_domains)
                 or f"put it in {here / 'domain.pntc'} or pass the domain file: gnpp check DOMAIN PROBLEM")
        return None


_HEADER = re.compile(r"^\s*(domain|problem|module)\s+([A-Za-z_]\w*)", re.M)


def peek_header(path: Path) -> tuple[str, str] | None:
    """The header of a file without parsing it all (comments skipped)."""
    from gnppdsl.inputs import InputError, read_bytes

    try:                                 # regular files only: a FIFO named x.pntc must not block
        data = read_bytes(path)
    except InputError:
        return None
    for line in data.decode("utf-8", errors="replace").splitlines():
        s = line.split("#", 1)[0].strip()
        if not s:
            continue
        m = _HEADER.match(s)
        return (m.group(1), m.group(2)) if m else None
    return None


def qualified_consts(mods: list[ModuleEnv]) -> dict:
    out = {}
    for m in mods:
        for k, v in m.consts.items():
            out[f"{m.name}.{k}"] = v
    return out


def merged_decls(mods: list[ModuleEnv]) -> tuple[dict, dict]:
    attrs: dict = {}
    prims: dict = {}
    for m in mods:
        attrs.update(m.scene_attrs)
        prims.update(m.primitives)
    return attrs, prims


DECL_WORDS = {
    ast.UseDecl: "use", ast.TypeDecl: "type", ast.ConstDecl: "const", ast.ConstantsDecl: "constants",
    ast.StateDecl: "state", ast.DerivedDecl: "derived", ast.ActionDecl: "action",
    ast.FrameDecl: "frame", ast.TemplateDecl: "template", ast.SceneAttrDecl: "scene",
    ast.PrimitiveDecl: "primitive", ast.RuleDecl: "rule", ast.RelaxationsDecl: "relaxations",
    ast.SolverDecl: "solver", ast.ReachabilityDecl: "reachability", ast.SceneRef: "scene",
    ast.AvoidDecl: "avoid",
    ast.ObjectsDecl: "objects", ast.InitDecl: "init", ast.GoalDecl: "goal",
}


def _decl_word(d) -> str:
    if isinstance(d, ast.ContinuousDecl):
        return "traj" if d.traj else "continuous"
    return DECL_WORDS.get(type(d), type(d).__name__)


def _where_allowed(word: str) -> str:
    if word in ("objects", "init", "goal"):
        return f"'{word}' belongs in a problem file"
    if word == "scene":
        return "a problem names its scene with `scene \"file.yaml\"`; domains and modules declare attributes with `scene name(o: object) : R`"
    if word in ("template", "const", "primitive", "use"):
        return f"'{word}' belongs in a domain or a module"
    if word in ("solver", "relaxations", "reachability"):
        return f"'{word}' belongs in a domain or a problem"
    return f"'{word}' belongs in a domain file"
