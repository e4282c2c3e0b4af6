"""Shared test setup: one BLAS and OpenMP thread per test process, the tests directory on
sys.path (for :mod:`strategies`, the reusable hypothesis strategies) and the hypothesis profile of
the suite.

Threads: ``make test`` runs the suite in one worker process per core (pytest-xdist), and the
workflow runs one job per core; OpenBLAS's and OpenMP's own threads would contend for the same
cores (a 2,600 x 2,600 ``eigh`` took 47 s of CPU with OpenBLAS's default threads and 8.5 s with one,
on this project's 2-core machine beside other jobs). Like the workflow (``plan.thread_environment``),
the suite sets ``OPENBLAS_NUM_THREADS``, ``OMP_NUM_THREADS`` and ``MKL_NUM_THREADS`` to 1 unless the
environment sets them, before numpy is imported, and its subprocesses (CLI commands, Snakemake runs)
inherit them. Numba's threads are set by the tests of threaded kernels themselves.

Hypothesis profile ``ci`` (default): derandomized (the same examples every run), no deadline (fits
take a variable time), 25 examples unless a test asks for fewer. Select another with
``HYPOTHESIS_PROFILE=<name>``; ``dev`` draws 200 random examples.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    if not os.environ.get(_name):
        os.environ[_name] = "1"
if "numpy" in sys.modules:  # loaded by a plugin before this file: limit the pools already started
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)

from hypothesis import HealthCheck, settings  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

from suite_order import slow_modules_first  # noqa: E402  (tests/suite_order.py, on the path above)

settings.register_profile(
    "ci",
    max_examples=25,
    deadline=None,
    derandomize=True,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.register_profile(
    "dev", max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large]
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


def pytest_collection_modifyitems(session, config, items):
    items[:] = slow_modules_first(items)
