"""The layers of DESIGN.md, checked on the source: one import direction, no package cycles, bpy in one place,
no function-level imports of project modules, and the bottom packages import without Blender."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("reconstruction", "scenes", "harness", "reports")
#: bottom to top; a module may import modules of its own layer or of layers below it
LAYERS = ["reconstruction", "scenes", "harness.data", "harness.render", "reports", "harness.jobs", "harness.cli"]
#: third-party packages a layer must never import
FORBIDDEN = {
    "reconstruction": {"bpy", "pandas", "matplotlib", "OpenEXR", "dask", "distributed"},
    "scenes": {"bpy", "pandas", "matplotlib", "cv2"},
    "harness.data": {"bpy", "pandas", "matplotlib"},
    "harness.render": {"pandas", "matplotlib"},
    "reports": {"bpy"},
}
BPY_MODULE = "harness.render.cycles"


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def layer_of(module: str) -> int:
    if module == "harness":  # the package itself only holds __version__: the bottom of the harness layers
        return LAYERS.index("harness.data")
    best = max((x for x in LAYERS if module == x or module.startswith(x + ".")), key=len, default=None)
    if best is None:
        raise AssertionError(f"module {module} is in no layer of DESIGN.md")
    return LAYERS.index(best)


def source_files() -> list[Path]:
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


def imports(path: Path):
    """``(module imported, line, at module level?)`` for every import statement of ``path``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    top = {id(n) for n in tree.body}
    # imports under a module-level `if TYPE_CHECKING:` or try/except count as module level
    for n in tree.body:
        if isinstance(n, ast.If | ast.Try):
            top.update(id(x) for x in ast.walk(n))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno, id(node) in top
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module, node.lineno, id(node) in top
            for alias in node.names:  # `from harness.render import cycles` imports harness.render.cycles
                yield f"{node.module}.{alias.name}", node.lineno, id(node) in top


def is_project(module: str) -> bool:
    return module.split(".")[0] in PACKAGES


def test_every_module_is_in_a_layer():
    for path in source_files():
        layer_of(module_name(path))


def test_imports_run_one_way():
    """A module imports only its own layer or the layers below it (DESIGN.md's table)."""
    bad = []
    for path in source_files():
        mod = module_name(path)
        mine = layer_of(mod)
        for target, line, _ in imports(path):
            if is_project(target) and _resolves(target) and layer_of(_resolves(target)) > mine:
                bad.append(f"{path.relative_to(ROOT)}:{line}: {mod} ({LAYERS[mine]}) imports {target} "
                           f"({LAYERS[layer_of(_resolves(target))]})")
    assert not bad, "imports against the layer direction:\n" + "\n".join(bad)


def _resolves(target: str) -> str | None:
    """The longest prefix of ``target`` that is a project module or package (``from x import name`` also
    yields ``x.name``, which may be a function rather than a module)."""
    parts = target.split(".")
    for k in range(len(parts), 0, -1):
        cand = ROOT.joinpath(*parts[:k])
        if cand.with_suffix(".py").is_file() or (cand / "__init__.py").is_file():
            return ".".join(parts[:k])
    return None


def test_no_function_level_project_imports():
    """Project modules are imported at module top only (the one lazy load of the Cycles backend goes through
    importlib, so that importing the CLI never loads bpy)."""
    bad = [f"{p.relative_to(ROOT)}:{line}: {t}" for p in source_files() for t, line, top in imports(p)
           if is_project(t) and not top]
    assert not bad, "function-level imports of project modules:\n" + "\n".join(bad)


def test_third_party_imports_respect_the_layers():
    bad = []
    for path in source_files():
        mod = module_name(path)
        layer = LAYERS[layer_of(mod)]
        for target, line, _ in imports(path):
            root = target.split(".")[0]
            if root == "bpy" and mod != BPY_MODULE:
                bad.append(f"{path.relative_to(ROOT)}:{line}: imports bpy (only {BPY_MODULE} may)")
            elif root in FORBIDDEN.get(layer, set()):
                bad.append(f"{path.relative_to(ROOT)}:{line}: {layer} must not import {root}")
    assert not bad, "\n".join(sorted(set(bad)))


def test_no_cycles_between_subpackages():
    """Second-level packages (reconstruction.camera, reconstruction.flow, harness.jobs, ...) form a DAG."""
    def unit(module: str) -> str:
        parts = module.split(".")
        return ".".join(parts[:2]) if len(parts) > 1 else parts[0]

    graph: dict[str, set[str]] = {}
    for path in source_files():
        src = unit(module_name(path))
        for target, _, _ in imports(path):
            res = _resolves(target) if is_project(target) else None
            if res and unit(res) != src:
                graph.setdefault(src, set()).add(unit(res))
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> None:
        state[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                raise AssertionError("import cycle: " + " -> ".join(stack[stack.index(m):] + [m]))
            if m not in state:
                visit(m)
        stack.pop()
        state[n] = 2

    for n in sorted(graph):
        if n not in state:
            visit(n)


@pytest.mark.parametrize("package", ["reconstruction", "scenes", "reports", "harness.cli"])
def test_packages_import_without_blender(package):
    """Importing the package (and every module under it) in a fresh interpreter loads no bpy."""
    mods = [module_name(p) for p in source_files() if module_name(p).startswith(package)
            and module_name(p) != BPY_MODULE and p.name != "__main__.py"]
    code = ("import importlib, sys\n"
            f"for m in {mods!r}:\n    importlib.import_module(m)\n"
            "assert 'bpy' not in sys.modules, 'bpy was imported'\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
