"""The layers of the code base, checked on the source (an AST walk):

* at the top level one import direction: ``reconstruction`` imports no other project package, ``scenes`` and
  ``reports`` import only ``reconstruction``, ``harness`` imports all three (``TOP_LEVEL``); the ``tools/`` folder
  (benchmarks, research scripts: not installed) may import every package, and no package imports it;
* inside, the layers ``LAYERS`` run one way (a module imports its own layer or the layers below it);
* no cycles between sub-packages, no function-level import statements of project modules, ``bpy`` in one
  module, ``reports`` touches no file, the bottom packages import without Blender, and no module reads
  ``sys.argv`` when it is imported.

An import is an ``import`` / ``from ... import`` statement (relative ones resolved against the module's
package) or a call of ``importlib.import_module`` / ``__import__`` with a string (a literal or a module-level
string constant): the lazy loads count for the direction too.
"""

from __future__ import annotations

import ast
import fnmatch
import keyword
import subprocess
import sys
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("reconstruction", "scenes", "reports", "harness")
#: the folder of the benchmarks and research scripts: not installed, run from the repository root, never imported
#: by the packages
TOOLS = "tools"
#: top-level package -> the other project packages it may import
TOP_LEVEL = {
    "reconstruction": set(),
    "scenes": {"reconstruction"},
    "reports": {"reconstruction"},
    "harness": {"reconstruction", "scenes", "reports"},
}
#: bottom to top; a module may import modules of its own layer or of layers below it
LAYERS = ["reconstruction", "scenes", "reports", "harness.data", "harness.render", "harness.runtime",
          "harness.commands", "harness.cli"]
#: modules a layer must never import (third-party, and for reports everything that reaches the file system)
FORBIDDEN = {
    "reconstruction": {"bpy", "pandas", "matplotlib", "OpenEXR", "dask", "distributed"},
    "scenes": {"bpy", "pandas", "matplotlib", "cv2"},
    "reports": {"bpy", "os", "pathlib", "shutil", "tempfile", "glob", "subprocess", "OpenEXR"},
    "harness.data": {"bpy", "matplotlib"},
    "harness.render": {"pandas", "matplotlib"},
}
#: calls that read or write files (``reports`` makes none of them)
FILE_CALLS = {"open", "read_text", "write_text", "read_bytes", "write_bytes", "read_csv", "read_json", "mkdir",
              "unlink", "rmdir", "touch", "iterdir", "glob", "rglob", "imread", "imwrite"}
BPY_MODULE = "harness.render.cycles"


@dataclass(frozen=True)
class Import:
    """One import found in a source file: the module named, its line, whether it is at module level, and
    whether it is a statement (``import`` / ``from``) or a dynamic load (``importlib.import_module``,
    ``__import__``)."""

    module: str
    line: int
    top: bool
    statement: bool = True


def module_name(path: Path, root: Path = ROOT) -> str:
    rel = path.relative_to(root).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def layer_of(module: str) -> int:
    if module == "harness":  # the package itself only holds __version__: the bottom of the harness layers
        return LAYERS.index("harness.data")
    best = max((x for x in LAYERS if module == x or module.startswith(x + ".")), key=len, default=None)
    if best is None:
        raise AssertionError(f"module {module} is in no layer of LAYERS")
    return LAYERS.index(best)


def source_files(root: Path = ROOT) -> list[Path]:
    return sorted(p for pkg in PACKAGES if (root / pkg).is_dir() for p in (root / pkg).rglob("*.py"))


def _string_constants(tree: ast.Module) -> dict[str, str]:
    """Module-level ``NAME = "text"`` assignments (e.g. ``EXECUTOR_MODULE = "harness.runtime.executor"``)."""
    out = {}
    for n in tree.body:
        value = n.value if isinstance(n, ast.Assign | ast.AnnAssign) else None
        targets = n.targets if isinstance(n, ast.Assign) else [n.target] if isinstance(n, ast.AnnAssign) else []
        if isinstance(value, ast.Constant) and isinstance(value.value, str):
            out.update({t.id: value.value for t in targets if isinstance(t, ast.Name)})
    return out


def _dynamic_target(call: ast.Call, constants: dict[str, str]) -> str | None:
    """The module a call ``importlib.import_module(x)`` / ``import_module(x)`` / ``__import__(x)`` loads, if ``x``
    is a string literal or a module-level string constant."""
    f = call.func
    name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else None
    if name not in ("import_module", "__import__") or not call.args:
        return None
    arg = call.args[0]
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        return arg.value
    if isinstance(arg, ast.Name):
        return constants.get(arg.id)
    return None


def imports_of(source: str, module: str, is_package: bool = False) -> Iterator[Import]:
    """Every import of the module ``module`` whose text is ``source`` (see the module doc); relative imports are
    resolved against the module's package (the module itself when ``is_package``, i.e. an ``__init__.py``)."""
    tree = ast.parse(source)
    top = {id(n) for n in tree.body}
    # imports under a module-level `if TYPE_CHECKING:` or try/except count as module level
    for n in tree.body:
        if isinstance(n, ast.If | ast.Try):
            top.update(id(x) for x in ast.walk(n))
    constants = _string_constants(tree)
    package = module.split(".") if is_package else module.split(".")[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield Import(alias.name, node.lineno, id(node) in top)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                if len(base) != len(package) - node.level + 1 or not base:
                    yield Import(f"<relative import beyond the top package in {module}>", node.lineno, True)
                    continue
                parent = ".".join(base + ([node.module] if node.module else []))
            else:
                parent = node.module or ""
            if node.module or node.level:
                yield Import(parent, node.lineno, id(node) in top)
            for alias in node.names:  # `from harness.render import cycles` imports harness.render.cycles
                yield Import(f"{parent}.{alias.name}", node.lineno, id(node) in top)
        elif isinstance(node, ast.Call):
            target = _dynamic_target(node, constants)
            if target:
                yield Import(target, node.lineno, id(node) in top, statement=False)


def imports(path: Path, root: Path = ROOT) -> Iterator[Import]:
    return imports_of(path.read_text(encoding="utf-8"), module_name(path, root), path.name == "__init__.py")


def is_project(module: str) -> bool:
    return module.split(".")[0] in PACKAGES


def _resolves(target: str, root: Path = ROOT) -> str | None:
    """The longest prefix of ``target`` that is a project module or package (``from x import name`` also
    yields ``x.name``, which may be a function rather than a module)."""
    parts = target.split(".")
    for k in range(len(parts), 0, -1):
        cand = root.joinpath(*parts[:k])
        if cand.with_suffix(".py").is_file() or (cand / "__init__.py").is_file():
            return ".".join(parts[:k])
    return None


def direction_violations(root: Path = ROOT) -> list[str]:
    """Every import against the direction, one line per statement: across top-level packages (:data:`TOP_LEVEL`;
    a project package that does not exist under ``root`` counts by its name) and between layers (:data:`LAYERS`)."""
    bad: dict[tuple[Path, int], str] = {}  # `from a.b import c` imports a.b and a.b.c: the first one found
    for path in source_files(root):
        mod = module_name(path, root)
        pkg = mod.split(".")[0]
        mine = layer_of(mod)
        where = path.relative_to(root)
        for imp in imports(path, root):
            if imp.module.startswith("<"):
                bad.setdefault((where, imp.line), f"{where}:{imp.line}: {imp.module}")
            elif imp.module.split(".")[0] == TOOLS:
                bad.setdefault((where, imp.line), f"{where}:{imp.line}: {mod} imports {imp.module} (the packages "
                                                  f"never import {TOOLS}/)")
            elif not is_project(imp.module):
                continue
            elif (other := imp.module.split(".")[0]) != pkg and other not in TOP_LEVEL[pkg]:
                allowed = ", ".join(sorted(TOP_LEVEL[pkg])) or "no project package"
                bad.setdefault((where, imp.line), f"{where}:{imp.line}: {mod} imports {imp.module} "
                                                  f"({pkg} may import only {allowed})")
            elif (target := _resolves(imp.module, root)) and layer_of(target) > mine:
                bad.setdefault((where, imp.line), f"{where}:{imp.line}: {mod} ({LAYERS[mine]}) imports "
                                                  f"{imp.module} ({LAYERS[layer_of(target)]})")
    return list(bad.values())


def test_every_module_is_in_a_layer():
    for path in source_files():
        layer_of(module_name(path))


def test_imports_run_one_way():
    """Top level: harness -> reports, scenes -> reconstruction; inside: each layer imports only the layers below."""
    bad = direction_violations()
    assert not bad, "imports against the layer direction:\n" + "\n".join(bad)


def _tree(tmp_path: Path, files: dict[str, str]) -> Path:
    for rel, text in {"reconstruction/__init__.py": "", "scenes/__init__.py": "", "reports/__init__.py": "",
                      "harness/__init__.py": "", "harness/data/__init__.py": "", "harness/data/errors.py": "",
                      "harness/commands/__init__.py": "", "harness/commands/report.py": "",
                      "harness/runtime/__init__.py": "", "harness/runtime/progress.py": "", **files}.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    return tmp_path


@pytest.mark.parametrize(("rel", "source", "culprit"), [
    ("reports/tables.py", "from harness.data.errors import UserError\n", "harness.data.errors"),
    ("reports/tables.py", "import harness.data\n", "harness.data"),
    ("reports/tables.py", "import importlib\nM = importlib.import_module('harness.data.errors')\n",
     "harness.data.errors"),
    ("reports/tables.py", "import importlib\nNAME = 'harness.commands'\n\n\ndef f():\n"
     "    return importlib.import_module(NAME)\n", "harness.commands"),
    ("reports/tables.py", "errors = __import__('harness.data.errors')\n", "harness.data.errors"),
    ("scenes/model.py", "from reports import tables\n", "reports"),
    ("reconstruction/x.py", "import scenes\n", "scenes"),
    ("harness/data/frame.py", "from ..commands import report\n", "harness.commands"),
    ("harness/data/frame.py", "from ..commands.report import build_report\n", "harness.commands.report"),
    ("harness/runtime/progress.py", "from harness.commands.report import build_report\n", "harness.commands.report"),
    ("harness/commands/report.py", "from tools.common import report_goals\n", "tools.common"),
    ("reports/tables.py", "import importlib\nM = importlib.import_module('tools.bench.pipeline')\n",
     "tools.bench.pipeline"),
])
def test_the_direction_check_catches_a_wrong_import(tmp_path, rel, source, culprit):
    """The checker run on a small synthetic tree: one wrong import (statement, relative, importlib or __import__)
    is reported, naming the file and what it imports; the same tree without it is clean."""
    root = _tree(tmp_path, {rel: "x = 1\n"})
    assert direction_violations(root) == []
    (root / rel).write_text(source)
    bad = direction_violations(root)
    assert len(bad) == 1 and bad[0].startswith(f"{rel}:") and f"imports {culprit} " in bad[0], bad


def test_relative_imports_resolve_against_the_package():
    mods = [i.module for i in imports_of("from . import exr\nfrom .atomic import write\n", "harness.data.frame")]
    assert mods == ["harness.data", "harness.data.exr", "harness.data.atomic", "harness.data.atomic.write"]
    mods = [i.module for i in imports_of("from .errors import UserError\n", "harness.data", is_package=True)]
    assert mods == ["harness.data.errors", "harness.data.errors.UserError"]


def _is_main_block(node: ast.AST) -> bool:
    """``if __name__ == "__main__":`` (what runs only when the module is the program)."""
    t = node.test if isinstance(node, ast.If) else None
    return (isinstance(t, ast.Compare) and isinstance(t.left, ast.Name) and t.left.id == "__name__"
            and len(t.comparators) == 1 and isinstance(t.comparators[0], ast.Constant)
            and t.comparators[0].value == "__main__")


def _import_time_nodes(tree: ast.Module) -> Iterator[ast.AST]:
    """Every node that runs when the module is imported: all but function bodies and the ``__main__`` block."""
    todo: list[ast.AST] = list(tree.body)
    while todo:
        node = todo.pop()
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda) or _is_main_block(node):
            continue
        yield node
        todo.extend(ast.iter_child_nodes(node))


def import_time_argv_reads(source: str) -> list[int]:
    """The lines of ``source`` that read ``sys.argv`` / ``sys.orig_argv`` when the module is imported."""
    names = ("argv", "orig_argv")
    return sorted(n.lineno for n in _import_time_nodes(ast.parse(source))
                  if (isinstance(n, ast.Attribute) and n.attr in names and isinstance(n.value, ast.Name)
                      and n.value.id == "sys")
                  or (isinstance(n, ast.ImportFrom) and n.module == "sys" and any(a.name in names for a in n.names)))


def test_nothing_reads_the_command_line_at_import_time():
    """What a process runs is read where it runs (a ``main``, an ``if __name__ == "__main__":`` block), never by
    importing a module: importing a package does the same whatever the program."""
    bad = [f"{p.relative_to(ROOT)}:{line}" for p in source_files() for line in
           import_time_argv_reads(p.read_text(encoding="utf-8"))]
    assert not bad, "sys.argv read at import time:\n" + "\n".join(bad)


@pytest.mark.parametrize(("source", "lines"), [
    ("import sys\nA = sys.argv[1:]\n", [2]),
    ("import sys\nif 'x' in sys.orig_argv:\n    pass\n", [2]),
    ("from sys import argv\n", [1]),
    ("import sys\n\n\ndef main():\n    return sys.argv\n", []),
    ("import sys\nif __name__ == '__main__':\n    print(sys.argv)\n", []),
])
def test_the_argv_check_catches_an_import_time_read(source, lines):
    assert import_time_argv_reads(source) == lines


def test_no_function_level_project_imports():
    """Project modules are imported at module top only (the lazy loads of the Cycles backend and of Dask go
    through importlib, so that importing the CLI never loads bpy or Dask)."""
    bad = [f"{p.relative_to(ROOT)}:{i.line}: {i.module}" for p in source_files() for i in imports(p)
           if i.statement and is_project(i.module) and not i.top]
    assert not bad, "function-level imports of project modules:\n" + "\n".join(bad)


def test_third_party_imports_respect_the_layers():
    bad = []
    for path in source_files():
        mod = module_name(path)
        layer = LAYERS[layer_of(mod)]
        for imp in imports(path):
            root = imp.module.split(".")[0]
            if root == "bpy" and mod != BPY_MODULE:
                bad.append(f"{path.relative_to(ROOT)}:{imp.line}: imports bpy (only {BPY_MODULE} may)")
            elif root in FORBIDDEN.get(layer, set()):
                bad.append(f"{path.relative_to(ROOT)}:{imp.line}: {layer} must not import {root}")
    assert not bad, "\n".join(sorted(set(bad)))


def file_access_calls(root: Path = ROOT) -> list[str]:
    """Every call in ``reports`` that reads or writes a file (:data:`FILE_CALLS`, or ``to_csv``/``to_json`` given a
    path or buffer)."""
    bad = []
    for path in source_files(root):
        if not module_name(path, root).startswith("reports"):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.Call):
                continue
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
            to_path = name in ("to_csv", "to_json") and bool(node.args or any(k.arg == "path_or_buf"
                                                                               for k in node.keywords))
            if name in FILE_CALLS or to_path:
                bad.append(f"{path.relative_to(root)}:{node.lineno}: calls {name}")
    return bad


def test_reports_touch_no_files():
    """reports is pure: arrays and DataFrames in, DataFrames, figures, bytes and text out."""
    bad = file_access_calls()
    assert not bad, "reports must not touch the file system:\n" + "\n".join(bad)


@pytest.mark.parametrize("source", ["def f(p):\n    return open(p).read()\n",
                                    "def f(p):\n    return p.read_text()\n",
                                    "def f(df, p):\n    df.to_csv(p, index=False)\n",
                                    "import pandas as pd\n\n\ndef f(p):\n    return pd.read_csv(p)\n"])
def test_the_file_check_catches_a_file_access(tmp_path, source):
    root = _tree(tmp_path, {"reports/tables.py": "def f(df):\n    return df.to_csv(index=False)\n"})
    assert file_access_calls(root) == []  # text out: fine
    (root / "reports/tables.py").write_text(source)
    assert [x.split(":")[0] for x in file_access_calls(root)] == ["reports/tables.py"]


def test_no_cycles_between_subpackages():
    """Second-level packages (reconstruction.camera, reconstruction.flow, harness.commands, ...) form a DAG."""
    def unit(module: str) -> str:
        parts = module.split(".")
        return ".".join(parts[:2]) if len(parts) > 1 else parts[0]

    graph: dict[str, set[str]] = {}
    for path in source_files():
        src = unit(module_name(path))
        for imp in imports(path):
            res = _resolves(imp.module) if is_project(imp.module) else None
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


def command_module(name: str) -> str:
    """The module of :mod:`harness.commands` (and of :mod:`harness.cli`) of the CLI command ``name``: the name
    itself, a Python keyword with a trailing underscore (``import`` -> ``import_``)."""
    return f"{name}_" if keyword.iskeyword(name) else name


def test_every_cli_command_has_its_command_module_and_every_command_module_a_cli_command():
    """``harness/commands/<name>.py`` for each command of ``harness.cli.COMMANDS``, and no other module there (what
    commands are built from is in ``harness/commands/parts/``); each CLI module calls its own command module."""
    from harness.cli import COMMANDS

    wanted = {command_module(name) for name in COMMANDS}
    present = {p.stem for p in (ROOT / "harness" / "commands").glob("*.py") if p.name != "__init__.py"}
    assert not wanted - present, f"CLI commands without a module in harness/commands/: {sorted(wanted - present)}"
    assert not present - wanted, f"modules of harness/commands/ that are no CLI command: {sorted(present - wanted)}"
    for name, cli_module in COMMANDS.items():
        path = ROOT.joinpath(*cli_module.__name__.split(".")).with_suffix(".py")
        own = f"harness.commands.{command_module(name)}"
        assert any(i.module == own for i in imports(path)), f"{path.relative_to(ROOT)} does not import {own}"


def tool_files(root: Path = ROOT) -> list[Path]:
    return sorted((root / TOOLS).rglob("*.py"))


def test_the_tools_are_not_installed():
    """``pyproject.toml`` installs the packages and not ``tools/`` (which is run from the repository root)."""
    include = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]["find"]["include"]
    assert all(any(fnmatch.fnmatch(p, pattern) for pattern in include) for p in PACKAGES), include
    assert not any(fnmatch.fnmatch(TOOLS, pattern) for pattern in include), include


def test_the_tools_import_only_the_packages_and_each_other():
    bad = [f"{p.relative_to(ROOT)}:{i.line}: {i.module}" for p in tool_files() for i in imports(p)
           if i.module.startswith("<")
           or ((ROOT / i.module.split(".")[0]).is_dir() and i.module.split(".")[0] not in (*PACKAGES, TOOLS))]
    assert not bad, "\n".join(bad)


@pytest.mark.slow
def test_the_tools_import_from_the_repository_root():
    """What ``make bench`` and ``make regress-update`` need: every tool module imports in a fresh interpreter started
    in the repository root (``python -m tools...`` puts it on ``sys.path``), and the command line is read by none
    of them (only a ``main`` or a ``__main__`` block reads it)."""
    mods = [module_name(p) for p in tool_files()]
    bad = [f"{p.relative_to(ROOT)}:{line}" for p in tool_files()
           for line in import_time_argv_reads(p.read_text(encoding="utf-8"))]
    assert not bad, "sys.argv read at import time:\n" + "\n".join(bad)
    code = f"import importlib\nfor m in {mods!r}:\n    importlib.import_module(m)\n"
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]


@pytest.mark.slow
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
