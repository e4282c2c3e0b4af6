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


def test_a_test_process_runs_one_blas_and_openmp_thread_unless_told_otherwise():
    import numpy  # noqa: F401  (loads OpenBLAS)
    from threadpoolctl import threadpool_info

    assert all(os.environ.get(name) for name in THREADS)
    if all(os.environ[name] == "1" for name in THREADS):
        pools = [p for p in threadpool_info() if p["user_api"] in ("blas", "openmp")]
        assert pools, "no BLAS pool loaded"
        assert {p["num_threads"] for p in pools} == {1}, pools


def test_a_count_set_by_the_user_is_kept(tmp_path):
    """conftest.py sets the counts only where the environment leaves them unset."""
    probe = tmp_path / "test_probe.py"
    probe.write_text(
        "import os\n\ndef test_counts():\n"
        "    assert os.environ['OMP_NUM_THREADS'] == '3'\n"
        "    assert os.environ['OPENBLAS_NUM_THREADS'] == '1'\n"
    )
    for name in ("conftest.py", "suite_order.py"):
        (tmp_path / name).write_text((REPO / "tests" / name).read_text())
    env = {k: v for k, v in os.environ.items() if k not in THREADS}
    env["OMP_NUM_THREADS"] = "3"
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist", str(probe)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )
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
