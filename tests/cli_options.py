"""Command-line options the tests build from Python values."""

from __future__ import annotations

import json


def set_options(settings: dict | str) -> list[str]:
    """``--set KEY=VALUE`` options of run-2pb, campaign-dt-policy and periodic-check for the
    test settings ``settings`` (a dict of TwoPBSettings keys, or its JSON); each VALUE is
    written as JSON, which the command reads as YAML."""
    if isinstance(settings, str):
        settings = json.loads(settings)
    return [opt for key, value in settings.items() for opt in ("--set", f"{key}={json.dumps(value)}")]
