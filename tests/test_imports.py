"""The package's import graph: every module imports alone, and no import cycle."""

from __future__ import annotations

import ast
import pkgutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pipeline

PACKAGE = Path(pipeline.__file__).parent


def _modules() -> list[str]:
    names = [m.name for m in pkgutil.walk_packages(pipeline.__path__, "pipeline.")]
    return ["pipeline", *(n for n in names if n != "pipeline.__main__")]


def _module_imports(name: str) -> set[str]:
    """The ``pipeline`` modules ``name`` imports, at module level or inside a function (a lazy
    import in a cycle is still a cycle), not under ``TYPE_CHECKING``."""
    rel = name.removeprefix("pipeline").lstrip(".").replace(".", "/")
    path = PACKAGE / rel / "__init__.py" if (PACKAGE / rel).is_dir() else PACKAGE / f"{rel}.py"
    tree = ast.parse(path.read_text())
    typing_only = {
        id(n)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
        for n in ast.walk(node)
    }
    out: set[str] = set()
    for node in ast.walk(tree):
        if id(node) in typing_only:
            continue
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("pipeline"):
            out.add(node.module)
            out.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("pipeline"))
    return out


def test_every_module_imports_alone():
    """In one interpreter, each module is imported with no ``pipeline`` module loaded before it,
    so an import that only works in some order fails here."""
    code = textwrap.dedent(
        f"""
        import importlib, sys
        failed = []
        for name in {_modules()!r}:
            for loaded in [m for m in sys.modules if m == "pipeline" or m.startswith("pipeline.")]:
                del sys.modules[loaded]
            try:
                importlib.import_module(name)
            except Exception as exc:
                failed.append(f"{{name}}: {{type(exc).__name__}}: {{exc}}")
        print("\\n".join(failed))
        sys.exit(1 if failed else 0)
        """
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr[-2000:]


def test_no_import_cycle():
    """Depth-first over the imports between the package's modules: no module is reached from
    itself (a package's ``__init__`` importing its own submodules excepted)."""
    mods = set(_modules())
    graph = {m: {d for d in _module_imports(m) if d in mods and d != m} for m in mods}
    for m, deps in graph.items():  # a package imports its submodules; they import the package
        graph[m] = {d for d in deps if not d.startswith(m + ".")}
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        path.append(m)
        for d in sorted(graph[m]):
            if state.get(d) == 1 and not m.startswith(d + "."):
                raise AssertionError(" -> ".join([*path[path.index(d) :], d]))
            if d not in state:
                visit(d)
        path.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
