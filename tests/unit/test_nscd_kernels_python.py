"""The unit tests of the NSCD core's kernels (marker ``kernels``) run again with numba's JIT
disabled (``NUMBA_DISABLE_JIT=1``): the kernels then execute as plain Python, so they can be
stepped through in a debugger and measured by coverage, and this test checks that they give
the same results (the same assertions pass) in both modes.

By hand: ``NUMBA_DISABLE_JIT=1 .venv/bin/python -m pytest -m kernels``.
"""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _pytest(*args, env):
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-p",
            "no:cacheprovider",
            "-m",
            "kernels",
            *args,
            str(REPO / "tests" / "unit"),
        ],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,
    )


@pytest.mark.slow
def test_kernel_tests_pass_as_python():
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    collected = _pytest("--collect-only", "-q", env=env)
    assert collected.returncode == 0, collected.stdout[-2000:] + collected.stderr[-2000:]
    n = len([line for line in collected.stdout.splitlines() if "::" in line])
    assert n >= 20, f"only {n} tests carry the 'kernels' marker"
    run = _pytest("-q", "-x", env=env)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    assert re.search(rf"\b{n} passed\b", run.stdout), run.stdout[-2000:]
