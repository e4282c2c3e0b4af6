"""Every module of ``asphalt_nscd`` says what it is in a module docstring of at most 40 lines.

Measurements, variants tried and the reasons of a choice belong in docs/choices.md, to which
a module docstring points; the docstring itself stays a description of the module.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "src" / "asphalt_nscd"
MAX_LINES = 40


def _modules() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def _docstring_lines(path: Path) -> int | None:
    """Lines of the module docstring of ``path`` (``ast.get_docstring``), None without one."""
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"), filename=str(path)))
    return None if doc is None else len(doc.splitlines())


def test_package_found():
    assert len(_modules()) > 10, f"no modules under {PACKAGE}"


def test_every_module_has_a_short_docstring():
    missing, too_long = [], []
    for path in _modules():
        name = path.relative_to(PACKAGE.parent).as_posix()
        n = _docstring_lines(path)
        if n is None:
            missing.append(name)
        elif n > MAX_LINES:
            too_long.append(f"{name}: {n} lines")
    problems = []
    if missing:
        problems.append("no module docstring: " + ", ".join(missing))
    if too_long:
        problems.append(f"module docstring over {MAX_LINES} lines: " + "; ".join(too_long))
    if problems:
        pytest.fail("\n".join(problems))
