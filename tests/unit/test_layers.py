"""The package's layers: no module imports a higher layer, and no two modules import each other.

Every import of every module of ``src/asphalt_nscd`` counts: at module level and inside
functions, relative and absolute; ``from . import x`` and ``from pkg import x`` name the
submodule ``pkg.x`` when it exists. Layers, lowest first::

    io < lab < rheology < nscd < sample < harmonic < campaign < diagnosis < forecast < figures < top

``io`` holds the package's two base modules, ``io`` (files, errors, termination) and
``config`` (the workflow's configuration files). ``top`` is the package itself: ``asphalt_nscd/__init__``, ``cli``, ``__main__`` and ``plan``
(the workflow's plan), which may import any layer. A module may import its own layer and
lower ones; within a layer the import graph must have no cycle.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from asphalt_nscd import STAGES

ROOT = Path(__file__).resolve().parents[2] / "src"
PACKAGE = "asphalt_nscd"
LAYERS = ("io", *STAGES)
TOP = len(LAYERS)
#: top-level modules of the lowest layer
BASE_MODULES = ("io", "config")


def module_files(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name -> file, for every ``.py`` file of the package under ``root``."""
    mods = {}
    for f in sorted((root / PACKAGE).rglob("*.py")):
        parts = f.relative_to(root).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        mods[".".join(parts)] = f
    return mods


def layer(module: str) -> int:
    """Index of ``module``'s layer in :data:`LAYERS`; :data:`TOP` for the package level."""
    parts = module.split(".")
    if len(parts) > 1 and parts[1] in BASE_MODULES:
        return 0
    return LAYERS.index(parts[1]) if len(parts) > 1 and parts[1] in LAYERS else TOP


def imports(module: str, path: Path, modules: dict[str, Path]) -> list[tuple[int, str]]:
    """(line, imported module of the package) for every import statement of ``module``."""
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    found = []

    def resolve(name: str) -> str | None:  # the longest prefix of name that is a module
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                base_name = ".".join(base + ([node.module] if node.module else []))
            else:
                base_name = node.module or ""
            names = [f"{base_name}.{a.name}" if f"{base_name}.{a.name}" in modules else base_name for a in node.names]
        else:
            continue
        for name in dict.fromkeys(names):
            if name == PACKAGE or name.startswith(PACKAGE + "."):
                target = resolve(name)
                if target is not None and target != module and (node.lineno, target) not in found:
                    found.append((node.lineno, target))
    return found


def import_graph(root: Path = ROOT) -> dict[str, list[tuple[int, str]]]:
    """Module -> its (line, imported module) pairs, over the package under ``root``."""
    modules = module_files(root)
    return {m: imports(m, f, modules) for m, f in modules.items()}


def upward_imports(graph) -> list[str]:
    """One message per import of a higher layer: 'module:line imports target (layer a < b)'."""
    return [
        f"{m}:{line} imports {t} (layer {_name(layer(m))} below {_name(layer(t))})"
        for m, edges in sorted(graph.items())
        for line, t in edges
        if layer(t) > layer(m)
    ]


def _name(index: int) -> str:
    return LAYERS[index] if index < TOP else "top"


def import_cycles(graph) -> list[str]:
    """One message per strongly connected component of more than one module: its imports
    that stay inside the component, each as 'module:line -> target'."""
    index, low, stack, on_stack, sccs = {}, {}, [], set(), []
    counter = [0]

    def visit(v):  # Tarjan's algorithm; the graph has some hundred modules
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for _, w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            scc = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                scc.append(w)
                if w == v:
                    break
            if len(scc) > 1:
                sccs.append(sorted(scc))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    messages = []
    for scc in sorted(sccs):
        members = set(scc)
        edges = [f"{m}:{line} -> {t}" for m in scc for line, t in graph[m] if t in members]
        messages.append("import cycle among " + ", ".join(scc) + ":\n    " + "\n    ".join(edges))
    return messages


def test_every_subpackage_has_a_layer():
    """A new subpackage must be given its place in :data:`LAYERS` (or be a top-level module)."""
    subpackages = {p.name for p in (ROOT / PACKAGE).iterdir() if (p / "__init__.py").exists()}
    assert subpackages <= set(LAYERS), sorted(subpackages - set(LAYERS))


def test_no_module_imports_a_higher_layer():
    upward = upward_imports(import_graph())
    assert not upward, "imports of a higher layer:\n" + "\n".join(upward)


def test_no_import_cycle():
    cycles = import_cycles(import_graph())
    assert not cycles, "\n".join(cycles)


@pytest.mark.parametrize(
    "source, expected",
    [
        ("from ..campaign import periodic\n", "asphalt_nscd.nscd.bench:1 imports asphalt_nscd.campaign.periodic"),
        (
            "def f():\n    from asphalt_nscd.figures.cli import main\n",
            "asphalt_nscd.nscd.bench:2 imports asphalt_nscd.figures.cli",
        ),
    ],
)
def test_the_walk_sees_relative_and_function_level_imports(tmp_path, source, expected):
    """The checks themselves: an upward import inside a function or through ``from .. import``
    is reported with its module and line; two modules importing each other form a cycle."""
    pkg = tmp_path / PACKAGE
    for sub in ("nscd", "campaign", "figures"):
        (pkg / sub).mkdir(parents=True)
        (pkg / sub / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "campaign" / "periodic.py").write_text("from . import twopb\n")
    (pkg / "campaign" / "twopb.py").write_text("def f():\n    from .periodic import g\n")
    (pkg / "figures" / "cli.py").write_text("")
    (pkg / "nscd" / "bench.py").write_text(source)
    graph = import_graph(tmp_path)
    assert [m.split(" (")[0] for m in upward_imports(graph)] == [expected]
    (cycle,) = import_cycles(graph)
    assert "asphalt_nscd.campaign.periodic:1 -> asphalt_nscd.campaign.twopb" in cycle
    assert "asphalt_nscd.campaign.twopb:2 -> asphalt_nscd.campaign.periodic" in cycle
