"""Benchmark of the artifact detection over many synthetic tables.

Seed s draws (from ``numpy.random.default_rng([base_seed, s])``) how many effects to plant
(0, 1 or 2, equally likely) and which ones; :func:`synthetic.generate` builds the table with
seed ``base_seed * 100003 + s``. Per effect the benchmark reports:

* detection rate: fraction of the tables where it was planted and named;
* estimate rate: fraction of those where the estimate is within ``tolerance`` (relative)
  of the truth (temperature offset: on the right isotherm too);
* false-alarm rate: fraction of the tables where it was *not* planted but named;

and the fraction of clean tables (no effect) with any data-artifact alarm.
"""

from __future__ import annotations

import time

import numpy as np

from . import synthetic
from .effects import ArtifactSearch, effect_entries

#: estimate key of each effect in the report and the truth
ESTIMATE_KEYS = {
    "time_lag": "time_lag_ms",
    "inertia_uncorrected": "mass_factor_g",
    "temperature_offset": "offset_C",
    "strain_nonlinearity": "modulus_drop_per_100_microstrain",
    "self_heating": "modulus_drop_pct_per_test",
}


def scenario(seed: int, base_seed: int = 0) -> list:
    """Effects planted for benchmark seed ``seed`` (0, 1 or 2 distinct names)."""
    rng = np.random.default_rng([base_seed, seed])
    k = int(rng.integers(0, 3))
    return [str(e) for e in rng.choice(synthetic.EFFECTS, size=k, replace=False)]


def estimate_ok(name: str, entry: dict, truth: dict, tolerance: float) -> bool:
    """Whether the estimate of a detected effect is within ``tolerance`` of the truth."""
    key = ESTIMATE_KEYS[name]
    true = truth["effects"][name][key]
    est = entry["estimate"].get(key)
    if est is None:
        return False
    if name == "temperature_offset" and entry["estimate"].get("temperature_C") != truth["effects"][name]["temperature_C"]:
        return False
    return abs(est - true) <= tolerance * abs(true)


def run_one(seed: int, effects, alpha: float = 1e-3, tolerance: float = 0.25) -> dict:
    """Generate one table, diagnose its artifacts; the outcome per effect."""
    table, truth = synthetic.generate(seed, effects)
    search = ArtifactSearch(table, alpha=alpha)
    entries = {e["name"]: e for e in effect_entries(search, search.run())}
    out = {"seed": seed, "planted": list(effects), "schedule": truth["schedule"],
           "n_specimens": truth["n_specimens"], "detected": [], "estimate_ok": {}}
    for name in synthetic.EFFECTS:
        e = entries[name]
        if e["detected"]:
            out["detected"].append(name)
        if name in effects:
            out["estimate_ok"][name] = bool(e["detected"] and estimate_ok(name, e, truth, tolerance))
    return out


def run_bench(n_seeds: int, base_seed: int = 0, alpha: float = 1e-3, tolerance: float = 0.25) -> dict:
    """Run :func:`run_one` over ``n_seeds`` scenarios and summarise the rates per effect."""
    runs = []
    t0 = time.perf_counter()
    for s in range(n_seeds):
        runs.append(run_one(base_seed * 100003 + s, scenario(s, base_seed), alpha, tolerance))
    elapsed = time.perf_counter() - t0
    per_effect = {}
    for name in synthetic.EFFECTS:
        planted = [r for r in runs if name in r["planted"]]
        absent = [r for r in runs if name not in r["planted"]]
        per_effect[name] = {
            "n_planted": len(planted),
            "detection_rate": float(np.mean([name in r["detected"] for r in planted])) if planted else None,
            "estimate_within_tolerance_rate": (float(np.mean([r["estimate_ok"][name] for r in planted]))
                                               if planted else None),
            "n_absent": len(absent),
            "false_alarm_rate": float(np.mean([name in r["detected"] for r in absent])) if absent else None,
        }
    clean = [r for r in runs if not r["planted"]]
    return {"n_seeds": n_seeds, "base_seed": base_seed, "alpha": alpha, "tolerance": tolerance,
            "goals": {"detection_rate": 0.95, "false_alarm_rate": 0.05},
            "per_effect": per_effect,
            "clean_tables": len(clean),
            "clean_any_alarm_rate": float(np.mean([bool(r["detected"]) for r in clean])) if clean else None,
            "seconds_per_table": elapsed / max(n_seeds, 1),
            "runs": runs}
