"""The package layout the design promises (docs/architecture.md): what flies (`fdir_service`) imports
nothing of the lab (`sim_bridge`), no module of either package takes part in an import circle, and
every estimation function fits on a screen."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("fdir_service", "sim_bridge")


def _modules() -> dict[str, Path]:
    """Module name -> file, for every module of both packages (generated MAVLink code excluded)."""
    out = {}
    for pkg in PACKAGES:
        for path in (ROOT / pkg).rglob("*.py"):
            if "generated" in path.parts:
                continue
            rel = path.relative_to(ROOT).with_suffix("")
            parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
            out[".".join(parts)] = path
    return out


def _imported(nodes, modules: dict[str, Path]) -> set[str]:
    """The project modules the import statements among `nodes` name (`from pkg import sub` is
    `pkg.sub`)."""
    found = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            subs = {f"{node.module}.{a.name}" for a in node.names}
            found |= (subs & set(modules)) or {node.module}
    return {m for m in found if m in modules}


def _imports(path: Path, modules: dict[str, Path]) -> set[str]:
    """Every project module a file imports, anywhere in it."""
    return _imported(ast.walk(ast.parse(path.read_text())), modules)


def _module_level_imports(path: Path, modules: dict[str, Path]) -> set[str]:
    """The project modules imported when the file is imported (its top-level import statements)."""
    return _imported(ast.parse(path.read_text()).body, modules)


def test_the_flying_package_imports_nothing_of_the_lab():
    modules = _modules()
    offenders = {name: sorted(m for m in _imports(path, modules) if m.startswith("sim_bridge"))
                 for name, path in modules.items() if name.startswith("fdir_service")}
    assert {k: v for k, v in offenders.items() if v} == {}


def test_no_module_level_import_circles():
    modules = _modules()
    graph = {name: _module_level_imports(path, modules) - {name} for name, path in modules.items()}
    # a package's __init__ importing its own submodules is how Python packages re-export: not a circle
    graph = {name: {m for m in deps if not m.startswith(name + ".")} for name, deps in graph.items()}
    circles = []
    state: dict[str, int] = {}

    def visit(node: str, stack: list[str]) -> None:
        state[node] = 1
        for dep in sorted(graph[node]):
            if state.get(dep) == 1:
                circles.append(stack[stack.index(dep):] + [dep])
            elif dep not in state:
                visit(dep, stack + [dep])
        state[node] = 2

    for name in sorted(graph):
        if name not in state:
            visit(name, [name])
    assert circles == []


@pytest.mark.parametrize("limit", [50])
def test_estimation_functions_fit_on_a_screen(limit):
    long = []
    for path in (ROOT / "fdir_service" / "estimation").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = node.end_lineno - node.lineno + 1
                if n > limit:
                    long.append((path.name, node.name, n))
    assert long == []


def test_particle_filter_step_has_no_branch_on_a_filter_kind():
    """`ParticleFilter.step` runs the same sequence for every recipe: its only branches are on the
    data of the step (a sentinel or proposal log-weight present, resampling due, covariance asked)."""
    src = (ROOT / "fdir_service" / "estimation" / "particle.py").read_text()
    cls = next(n for n in ast.parse(src).body if isinstance(n, ast.ClassDef) and n.name == "ParticleFilter")
    step = next(n for n in cls.body if isinstance(n, ast.FunctionDef) and n.name == "step")
    tests = [n.test for n in ast.walk(step) if isinstance(n, ast.If | ast.IfExp | ast.While)]
    names = {n.attr if isinstance(n, ast.Attribute) else n.id for t in tests for n in ast.walk(t)
             if isinstance(n, ast.Attribute | ast.Name)}
    assert names <= {"bonus", "move_lw", "resampled", "self", "p", "output_covariance", "regulariser",
                     "needs_covariance"}, names
    assert len(tests) <= 4
