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
    # one run: every collected 'kernels' test passed (the summary line counts nothing else)
    run = _pytest("-q", "-x", "-rA", env=env)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    summary = run.stdout.strip().splitlines()[-1]
    m = re.fullmatch(r"=* ?(\d+) passed, \d+ deselected(, \d+ warnings?)? in .*", summary)
    assert m, f"not only passes: {summary}"
    n = int(m.group(1))
    assert n >= 20, f"only {n} tests carry the 'kernels' marker"
    # -rA lists each passed test by its node id: as many as the summary counts
    passed = {line.split()[1] for line in run.stdout.splitlines() if line.startswith("PASSED ")}
    assert len(passed) == n, f"{len(passed)} PASSED lines for {n} passes"
