"""The scripts under reference/ that remake the committed tables name only what the package
has: every ``module.attribute`` they use on a module of ``asphalt_nscd`` they import exists, and
every name they import from the package exists (a package change that moves a function fails
here, not on the day a table is remade)."""

import ast
import importlib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SCRIPTS = sorted((REPO / "reference").rglob("*.py"))


def _package_names(tree: ast.AST) -> tuple[dict[str, str], list[tuple[str, str]]]:
    """(local name -> package module it is bound to, [(module, name) imported from the package])."""
    modules: dict[str, str] = {}
    imported: list[tuple[str, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("asphalt_nscd") and a.asname:
                    modules[a.asname] = a.name
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("asphalt_nscd"):
            for a in node.names:
                full = f"{node.module}.{a.name}"
                try:
                    importlib.import_module(full)
                    modules[a.asname or a.name] = full  # a submodule
                except ImportError:
                    imported.append((node.module, a.name))
    return modules, imported


@pytest.mark.parametrize("script", SCRIPTS, ids=[str(s.relative_to(REPO)) for s in SCRIPTS])
def test_a_reference_script_names_only_what_the_package_has(script):
    tree = ast.parse(script.read_text())
    modules, imported = _package_names(tree)
    missing = [f"from {m} import {n}" for m, n in imported if not hasattr(importlib.import_module(m), n)]
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in modules:
            module = importlib.import_module(modules[node.value.id])
            if not hasattr(module, node.attr):
                missing.append(f"{node.value.id}.{node.attr} (line {node.lineno})")
    where = script.relative_to(REPO) if script.is_relative_to(REPO) else script
    assert not missing, f"{where}: " + ", ".join(missing)


def test_the_check_finds_a_name_the_package_lacks(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("from asphalt_nscd.campaign import twopb\n\ntwopb.no_such_function()\n")
    with pytest.raises(AssertionError, match="twopb.no_such_function"):
        test_a_reference_script_names_only_what_the_package_has(bad)
