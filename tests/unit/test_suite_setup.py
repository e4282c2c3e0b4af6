"""The test suite's own setup (tests/conftest.py, the Makefile's ``test`` target): one BLAS and OpenMP
thread per test process, the suite on one worker per core, the slow modules handed out first."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
from suite_order import slow_modules_first

REPO = Path(__file__).resolve().parents[2]
THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def _run_probe(tmp_path, body: str, env: dict) -> subprocess.CompletedProcess:
    """Run ``body`` as a test module in a fresh pytest process under the suite's conftest.py."""
    probe = tmp_path / "test_probe.py"
    probe.write_text(body)
    for name in ("conftest.py", "suite_order.py"):
        (tmp_path / name).write_text((REPO / "tests" / name).read_text())
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist", str(probe)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )


def test_a_test_process_runs_one_blas_and_openmp_thread_unless_told_otherwise(tmp_path):
    """In a fresh test process whose environment sets no count, conftest.py sets each to 1 and the
    BLAS and OpenMP pools numpy loads run one thread. (A fresh process: in the suite's own workers a
    threaded NSCD test may have set numba's OpenMP pool to its own count before, as it should.)"""
    body = (
        "import os\n\ndef test_counts():\n"
        "    import numpy\n"
        "    from threadpoolctl import threadpool_info\n"
        f"    assert all(os.environ[name] == '1' for name in {THREADS!r})\n"
        "    pools = [p for p in threadpool_info() if p['user_api'] in ('blas', 'openmp')]\n"
        "    assert pools, 'no BLAS pool loaded'\n"
        "    assert {p['num_threads'] for p in pools} == {1}, pools\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in THREADS}
    proc = _run_probe(tmp_path, body, env)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]


def test_a_count_set_by_the_user_is_kept(tmp_path):
    """conftest.py sets the counts only where the environment leaves them unset."""
    body = (
        "import os\n\ndef test_counts():\n"
        "    assert os.environ['OMP_NUM_THREADS'] == '3'\n"
        "    assert os.environ['OPENBLAS_NUM_THREADS'] == '1'\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in THREADS}
    env["OMP_NUM_THREADS"] = "3"
    proc = _run_probe(tmp_path, body, env)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]


def _item(nodeid: str, slow: bool = False):
    return SimpleNamespace(nodeid=nodeid, get_closest_marker=lambda name: object() if slow and name == "slow" else None)


def test_slow_modules_are_handed_out_first_the_workflow_runs_before_them():
    items = [
        _item("tests/unit/test_a.py::test_1"),
        _item("tests/unit/test_b.py::test_1"),
        _item("tests/unit/test_b.py::test_2", slow=True),
        _item("tests/workflow/test_c.py::test_1"),
        _item("tests/workflow/test_d.py::test_1", slow=True),
        _item("tests/workflow/test_d.py::test_2"),
        _item("tests/unit/test_e.py::test_1"),
    ]
    order = [i.nodeid for i in slow_modules_first(items)]
    assert order == [
        "tests/workflow/test_d.py::test_1",
        "tests/workflow/test_d.py::test_2",
        "tests/unit/test_b.py::test_1",
        "tests/unit/test_b.py::test_2",
        "tests/unit/test_a.py::test_1",
        "tests/workflow/test_c.py::test_1",
        "tests/unit/test_e.py::test_1",
    ]
    assert sorted(order) == sorted(i.nodeid for i in items)  # nothing dropped


def test_make_test_runs_one_worker_per_core_with_whole_modules():
    makefile = (REPO / "Makefile").read_text()
    args = re.search(r"^PYTEST_ARGS \?= (.*)$", makefile, re.M)
    assert args, "Makefile: no PYTEST_ARGS"
    assert args.group(1).split() == [
        "-n",
        "$(CORES)",
        "--dist",
        "loadscope",
        "--no-loadscope-reorder",
        "--durations=20",
    ]
    assert re.search(r"^test: setup\n\t\$\(BIN\)/python -m pytest \$\(PYTEST_ARGS\)$", makefile, re.M)
    locked = (REPO / "requirements.lock").read_text().splitlines()
    assert any(line.startswith("pytest-xdist==") for line in locked)
    pytest.importorskip("xdist")
