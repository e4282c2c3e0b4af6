"""The package passes the type checker: mypy, run as pyproject.toml [tool.mypy] configures it
(the sources under src/asphalt_nscd, Python 3.11, libraries without type information taken
as Any, unused ``type: ignore`` comments reported), finds no error. mypy is the virtual
environment's, pinned in requirements.lock."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def test_mypy_finds_no_error():
    """``python -m mypy`` from the repository root (its files and options from pyproject.toml)
    exits 0: no type error in the package."""
    if importlib.util.find_spec("mypy") is None:
        pytest.skip("mypy is not installed in this environment (pinned in requirements.lock)")
    proc = subprocess.run([sys.executable, "-m", "mypy"], cwd=REPO, capture_output=True, text=True, timeout=900)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"mypy (configured in pyproject.toml [tool.mypy]) exited {proc.returncode}:\n{out}"
