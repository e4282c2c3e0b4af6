"""Shared test setup: the tests directory on sys.path (for :mod:`strategies`, the reusable
hypothesis strategies) and the hypothesis profile of the suite.

Profile ``ci`` (default): derandomized (the same examples every run), no deadline (fits
take a variable time), 25 examples unless a test asks for fewer. Select another with
``HYPOTHESIS_PROFILE=<name>``; ``dev`` draws 200 random examples.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from hypothesis import HealthCheck, settings

sys.path.insert(0, str(Path(__file__).resolve().parent))

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
