"""The package's layering, read from the source with `ast` (nothing is imported):

* no import cycle among wbcbench's modules at module level (an import inside a function runs when the function
  is called and may point anywhere: it is deferred);
* counting the deferred imports too, no cycle through more than one package (the registries find their built-ins
  in tables of "module:Attr" strings, so that none imports upward to fill itself);
* no package importing, at module level, a package of its own tier or above (`TIERS`, lowest first), and the
  rules `NEVER` kept even by deferred imports;
* the registries' tables name what they say (each entry's class carries the entry's name), a lookup imports
  only the module it names, and the lower layers load no simulator (in fresh interpreters).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "wbcbench"

#: the packages and top-level modules of wbcbench, lowest first; a module may import, at module level, only from
#: its own package and from the tiers below its own (the members of one tier do not import one another). A
#: "package" here is a top-level module or sub-package of wbcbench, with all it contains (`teleop/*` is one),
#: except `UNITS`, which groups top-level modules into one package.
TIERS: tuple[tuple[str, ...], ...] = (
    ("side", "errors", "jit", "_lazy", "catalogue", "_version", "_markdown"),  # no dependency; catalogue: the registries'
                                                                  # built-in tables; _version: written by the build
    ("types", "config", "plugins"),                 # measurements, references, GRAVITY; YAML Section; entry points
    ("scene", "qp", "recorder", "summary"),         # terrain as data; QP solvers; the log format; summary.json
    ("robots", "tasks"),                            # the pinocchio model and profiles; the task library, kinematics
    ("estimation", "planning"),                     # estimators on a model; planners on a scene
    ("stabilizers", "sensing", "sim", "faults", "metrics", "teleop"),
    ("controllers",),                               # built from tasks, stabilizers, planners' references
    ("scenarios",),                                 # reference sources (planners, teleop), scene, metrics
    ("runner",),                                    # the run loop: runner.py, loop.py, loop_hooks.py, branching.py
    ("report", "study", "robustness", "viz", "doctor", "envelope"),  # applications reading and making runs;
                                                                     # install check
    ("cli",),
)

#: top-level modules that form one package of `TIERS`
UNITS = {"loop": "runner", "loop_hooks": "runner", "branching": "runner"}

#: imports that no module makes, not even inside a function: (importer, imported) packages, and why
NEVER: dict[tuple[str, str], str] = {
    ("controllers", "sim"): "a controller sees only a Measurement, never the simulator",
    ("planning", "sim"): "planners read the scene as data (scene.py), not the simulator",
    ("robots", "sim"): "the robot model is the controller side's",
    ("planning", "robots"): "planners take sizes, not a robot model",
    ("tasks", "robots"): "tasks take a pinocchio model, not a robot profile",
    ("tasks", "controllers"): "the task library is below every controller",
    ("qp", "robots"): "the QP layer knows no robot",
    ("metrics", "sim"): "metrics read logs",
    ("metrics", "controllers"): "metrics read logs",
}

#: module-level imports allowed against `TIERS`, each with its reason (none today)
EXCEPTIONS: dict[tuple[str, str], str] = {}


def _modules() -> dict[str, Path]:
    out = {}
    for path in ROOT.rglob("*.py"):
        parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _module_level_imports(tree: ast.Module) -> list[ast.stmt]:
    """The import statements run when the module is imported: its body's, and those in its top-level `if`, `try`
    and `with` blocks (not the `if TYPE_CHECKING:` branch, nor any function or class body's methods)."""
    found: list[ast.stmt] = []

    def walk(stmts: list[ast.stmt]) -> None:
        for s in stmts:
            if isinstance(s, (ast.Import, ast.ImportFrom)):
                found.append(s)
            elif isinstance(s, ast.If):
                if not _is_type_checking(s.test):
                    walk(s.body)
                walk(s.orelse)
            elif isinstance(s, ast.Try):
                walk(s.body)
                walk(s.orelse)
                walk(s.finalbody)
                for h in s.handlers:
                    walk(h.body)
            elif isinstance(s, ast.With):
                walk(s.body)
            elif isinstance(s, ast.ClassDef):
                walk([b for b in s.body if not isinstance(b, (ast.FunctionDef, ast.AsyncFunctionDef))])

    walk(tree.body)
    return found


def _all_imports(tree: ast.Module) -> list[ast.stmt]:
    return [n for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))]


def _targets(module: str, stmt: ast.stmt) -> set[str]:
    """The wbcbench modules `stmt` in `module` imports. ``from pkg import sub`` counts `pkg.sub`, and `pkg`
    itself unless `module` lies inside `pkg` and every name is a submodule (the package is then already being
    imported, its __init__ running or done)."""
    out = set()
    if isinstance(stmt, ast.Import):
        for a in stmt.names:
            if a.name in MODULES:
                out.add(a.name)
        return out
    if stmt.level:
        base = module.split(".") if MODULES[module].name == "__init__.py" else module.split(".")[:-1]
        base = base[:len(base) - (stmt.level - 1)]
        target = ".".join(base + ([stmt.module] if stmt.module else []))
    else:
        target = stmt.module or ""
    subs = {f"{target}.{a.name}" for a in stmt.names} & set(MODULES)
    out |= subs
    if target in MODULES and not (len(subs) == len(stmt.names) and module.startswith(target + ".")):
        out.add(target)
    return out


def _graph(deferred: bool) -> dict[str, set[str]]:
    graph = {}
    for module, path in MODULES.items():
        tree = ast.parse(path.read_text(), str(path))
        stmts = _all_imports(tree) if deferred else _module_level_imports(tree)
        graph[module] = set().union(*(_targets(module, s) for s in stmts)) - {module} if stmts else set()
    return graph


def _package(module: str) -> str:
    parts = module.split(".")
    name = parts[1] if len(parts) > 1 else "wbcbench"
    return UNITS.get(name, name)


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each as one cycle through them."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    comps: list[list[str]] = []
    counter = [0]
    sys.setrecursionlimit(max(10000, sys.getrecursionlimit()))

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                comps.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return [_one_cycle(graph, set(c)) for c in comps]


def _one_cycle(graph: dict[str, set[str]], comp: set[str]) -> list[str]:
    """A cycle through the first module of a strongly connected component (breadth-first, shortest)."""
    start = min(comp)
    prev = {start: None}
    queue = [start]
    while queue:
        v = queue.pop(0)
        for w in sorted(graph[v] & comp):
            if w == start:
                path = [v]
                while prev[path[-1]] is not None:
                    path.append(prev[path[-1]])
                return [*reversed(path), start]
            if w not in prev:
                prev[w] = v
                queue.append(w)
    return sorted(comp)


def _show(cycles: list[list[str]]) -> str:
    return "\n".join(" -> ".join(c) for c in cycles)


def test_the_table_names_every_package_once():
    listed = [p for tier in TIERS for p in tier]
    assert len(listed) == len(set(listed)), "a package is listed twice in TIERS"
    present = {_package(m) for m in MODULES} - {"wbcbench"}
    assert present <= set(listed), f"add to TIERS (tests/test_layering.py): {sorted(present - set(listed))}"
    assert set(listed) <= present, f"TIERS names packages that do not exist: {sorted(set(listed) - present)}"


def test_no_import_cycle_at_module_level():
    cycles = _cycles(_graph(deferred=False))
    assert not cycles, "import cycles among wbcbench's modules (module level):\n" + _show(cycles)


def test_no_cycle_through_packages_even_with_deferred_imports():
    cycles = [c for c in _cycles(_graph(deferred=True)) if len({_package(m) for m in c}) > 1]
    assert not cycles, ("import cycles through more than one package, counting imports inside functions (a "
                        "registry importing its built-ins? use a table of 'module:Attr' strings):\n" + _show(cycles))


def test_no_package_imports_its_tier_or_above():
    tier = {p: i for i, t in enumerate(TIERS) for p in t}
    bad = []
    for module, deps in sorted(_graph(deferred=False).items()):
        a = _package(module)
        for dep in sorted(deps):
            b = _package(dep)
            if a == b or b == "wbcbench" or (a, b) in EXCEPTIONS:
                continue
            if a == "wbcbench" or tier[b] >= tier[a]:
                bad.append(f"{module} -> {dep}  ({a}: tier {tier.get(a)}, {b}: tier {tier[b]})")
    assert not bad, "module-level imports against the layering (TIERS in tests/test_layering.py):\n" + "\n".join(bad)


def test_rules_kept_by_every_import():
    bad = [f"{m} -> {d}: {NEVER[(_package(m), _package(d))]}" for m, deps in sorted(_graph(deferred=True).items())
           for d in sorted(deps) if (_package(m), _package(d)) in NEVER]
    assert not bad, "\n".join(bad)


def test_no_private_name_imported_from_another_package():
    """A name or module starting with `_` is its package's own: no other package imports it (make it public). A
    private top-level module (`wbcbench._lazy`) is the whole package's."""
    bad = []
    for module, path in sorted(MODULES.items()):
        for stmt in _all_imports(ast.parse(path.read_text())):
            for target in _targets(module, stmt):
                if _package(target) == _package(module):
                    continue
                if any(part.startswith("_") for part in target.split(".")[2:]):
                    bad.append(f"{module}: imports the private module {target}")
                elif isinstance(stmt, ast.ImportFrom):
                    bad += [f"{module}: from {target} import {a.name}" for a in stmt.names
                            if a.name.startswith("_") and not a.name.endswith("__")
                            and f"{target}.{a.name}" not in MODULES]
    assert not bad, "private names imported across packages (make them public):\n" + "\n".join(bad)


def test_the_registries_tables_name_their_entries():
    from wbcbench.controllers.base import BUILTIN_CONTROLLERS, available_controllers
    from wbcbench.robots.profile import BUILTIN_ROBOTS, PROFILE_DIR
    from wbcbench.scenarios.base import BUILTIN_KINDS, available_kinds
    from wbcbench.stabilizers.base import BUILTIN_STABILIZERS, available_stabilizers
    from wbcbench.tasks.registry import BUILTIN_TASKS, task_types

    ctrls, kinds, stabs, tasks = available_controllers(), available_kinds(), available_stabilizers(), task_types()
    assert all(ctrls[n].name == n for n in BUILTIN_CONTROLLERS)
    assert all(kinds[n].kind == n for n in BUILTIN_KINDS)
    assert all(stabs[n].type == n for n in BUILTIN_STABILIZERS)
    assert all(tasks[n].yaml_type == n for n in BUILTIN_TASKS)
    assert sorted(BUILTIN_ROBOTS.values()) == sorted(p.name for p in PROFILE_DIR.glob("*.yaml"))


@pytest.mark.parametrize("lookup, loaded, not_loaded", [
    ("from wbcbench.controllers.base import controller_class as f; f('joint-pd')",
     "wbcbench.controllers.joint_pd", "wbcbench.controllers.ik"),
    ("from wbcbench.scenarios.base import kind_class as f; f('sway')",
     "wbcbench.scenarios.kinds", "wbcbench.scenarios.teleop_kind"),
    ("from wbcbench.stabilizers.base import stabilizer_class as f; f('dcm')",
     "wbcbench.stabilizers.balance", "wbcbench.stabilizers.teleop"),
])
def test_a_lookup_imports_only_what_it_names(lookup, loaded, not_loaded):
    code = f"import sys; {lookup}; print({loaded!r} in sys.modules, {not_loaded!r} in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=ROOT.parent).stdout.split()
    assert out == ["True", "False"]


# ---- in fresh interpreters: what importing a lower layer loads


def _modules_after(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys\nprint(' '.join(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True)
    return set(out.stdout.split())


def test_controllers_do_not_import_mujoco():
    mods = _modules_after("import wbcbench.controllers\nfrom wbcbench.controllers.base import available_controllers\n"
                          "available_controllers()")
    assert "wbcbench.controllers.inverse_dynamics" in mods and "wbcbench.controllers.ik" in mods
    assert "mujoco" not in mods
    assert not any(m.startswith("wbcbench.sim") for m in mods)


@pytest.mark.parametrize("package", ["wbcbench.planning", "wbcbench.tasks", "wbcbench.qp", "wbcbench.stabilizers",
                                     "wbcbench.estimation", "wbcbench.types"])
def test_lower_layers_do_not_import_the_simulator(package):
    mods = _modules_after(f"import {package}")
    assert "mujoco" not in mods and not any(m.startswith("wbcbench.sim") for m in mods), package
