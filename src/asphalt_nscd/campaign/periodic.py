"""``asphalt-nscd periodic-check``: the periodic start of the 2PB test against the from-rest protocol.

:func:`check_case` runs one (sample, law, f) from rest for many cycles (the reference), from
the periodic steady state of :mod:`asphalt_nscd.harmonic.periodic` and, on request, from the
continuous steady state, and compares their |E*| and Phi cycle by cycle: the table of
docs/choices.md.
"""

from __future__ import annotations

import json
import math

import numpy as np

from . import twopb

#: Equality tolerances of the periodic start against the converged from-rest result: |E*| relative, Phi absolute.
TOLERANCE_E_REL = 1e-3
TOLERANCE_PHASE_DEG = 0.05


def _close(e, phase, e_ref, phase_ref) -> bool:
    return bool(abs(e / e_ref - 1.0) <= TOLERANCE_E_REL and abs(phase - phase_ref) <= TOLERANCE_PHASE_DEG)


def check_case(
    sample_path,
    law,
    frequency_Hz: float,
    settings,
    long_cycles: int = 20,
    rest_cycles: float | None = None,
    continuous: bool = False,
    workdir=None,
    meta: dict | None = None,
) -> tuple[dict, list[dict]]:
    """Compare the periodic start with the from-rest protocol on one (sample, law, f).

    Runs (records in ``workdir``, a temporary directory by default): from rest for
    ``long_cycles`` cycles (the reference; its first ``rest_cycles`` cycles, default
    ``settings.n_cycles``, are the paper's protocol, since the imposed motion does not depend
    on the run's length); from the periodic start for ``settings.periodic_cycles`` cycles;
    with ``continuous`` also from the continuous steady state (s = i w). Every run is
    reduced over its last ``settings.window_cycles`` cycles with ``settings.force_reading``.

    Returns
    -------
    (row, cycles)
        row: ``meta`` + temperature/frequency, dt_s, steps_per_period, the starts' |E*| (MPa)
        and Phi (deg): ``E_rest_MPa, phase_rest_deg`` (after rest_cycles),
        ``E_long_MPa, phase_long_deg`` (after long_cycles), ``E_periodic_MPa,
        phase_periodic_deg`` (and ``*_continuous``), differences to the long reference
        ``dE_rest_pct, dphase_rest_deg, dE_periodic_pct, dphase_periodic_deg`` (and
        continuous), ``dE_long_pct, dphase_long_deg`` = the long run's last-cycle change
        over its last 5 cycles (its own convergence), ``rest_converged`` and
        ``periodic_equal`` (within :data:`TOLERANCE_E_REL`, :data:`TOLERANCE_PHASE_DEG`),
        ``first_cycle_to_periodic`` (first from-rest cycle within the tolerances of the
        periodic start, -1 if none), steps per job (``steps_rest, steps_periodic``), mean
        solver iterations per step (``iterations_rest_first_cycle, iterations_rest_cycle_N,
        iterations_rest_last_cycle, iterations_periodic``), NLGS steps, the periodic solve
        time and steady bond force / strength, and the start the periodic run used.
        cycles: one dict per from-rest cycle k (1..long_cycles) with its |E*|, Phi and the
        differences to the periodic start.
    """
    import dataclasses
    import tempfile
    from pathlib import Path

    rest_cycles = float(settings.n_cycles if rest_cycles is None else rest_cycles)
    if long_cycles < rest_cycles:
        raise ValueError(f"long_cycles ({long_cycles}) must be >= rest_cycles ({rest_cycles})")
    base = dataclasses.replace(settings, checkpoint_every=0, method="time_domain")  # a check of the time stepping
    w = base.window_cycles
    meta = dict(meta or {})
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        tmp = Path(tmp)
        long_set = dataclasses.replace(base, start="rest", n_cycles=float(long_cycles))
        rec = twopb.run_test(sample_path, law, frequency_Hz, long_set, tmp / "rest.h5", meta=meta, progress=False)
        per_set = dataclasses.replace(base, start="periodic")
        runs = {
            "periodic": twopb.run_test(
                sample_path, law, frequency_Hz, per_set, tmp / "periodic.h5", meta=meta, progress=False
            )
        }
        if continuous:
            runs["continuous"] = twopb.run_test(
                sample_path,
                law,
                frequency_Hz,
                per_set,
                tmp / "cont.h5",
                meta=meta,
                progress=False,
                continuous_start=True,
            )
    dt = float(rec["attrs"]["dt_s"])
    per_period = 1.0 / (frequency_Hz * dt)
    red = {k: twopb.reduce_test(r, w) for k, r in runs.items()}
    long_row = twopb.reduce_test(rec, w)
    rest_row = twopb.reduce_test(twopb.truncate_record(rec, rest_cycles), w)
    prev = twopb.reduce_test(twopb.truncate_record(rec, long_cycles - 5), w) if long_cycles - 5 >= w else long_row
    e_per, ph_per = red["periodic"]["E_norm_MPa"], red["periodic"]["phase_deg"]
    it = np.asarray(rec["stats"]["iterations"], float)

    def cycle_mean(k):  # mean iterations over cycle k (1-based)
        a, b = int(round((k - 1) * per_period)), int(round(k * per_period))
        return float(it[a:b].mean())

    cycles = []
    first = -1
    for k in range(int(math.ceil(w)), long_cycles + 1):
        r = twopb.reduce_test(twopb.truncate_record(rec, k), w)
        ok = _close(r["E_norm_MPa"], r["phase_deg"], e_per, ph_per)
        if ok and first < 0:
            first = k
        elif not ok:
            first = -1
        cycles.append(
            {
                **meta,
                "temperature_C": meta.get("temperature_C"),
                "frequency_Hz": frequency_Hz,
                "cycle": k,
                "E_norm_MPa": r["E_norm_MPa"],
                "phase_deg": r["phase_deg"],
                "dE_to_periodic_pct": 100.0 * (r["E_norm_MPa"] / e_per - 1.0),
                "dphase_to_periodic_deg": r["phase_deg"] - ph_per,
                "iterations_mean": cycle_mean(k),
            }
        )
    e_l, ph_l = long_row["E_norm_MPa"], long_row["phase_deg"]
    info = json.loads(runs["periodic"]["attrs"]["start_info"])
    row = {
        **meta,
        "frequency_Hz": frequency_Hz,
        "dt_s": dt,
        "steps_per_period": per_period,
        "rest_cycles": rest_cycles,
        "long_cycles": long_cycles,
        "periodic_cycles": base.periodic_cycles,
        "window_cycles": w,
        "E_rest_MPa": rest_row["E_norm_MPa"],
        "phase_rest_deg": rest_row["phase_deg"],
        "E_long_MPa": e_l,
        "phase_long_deg": ph_l,
        "E_periodic_MPa": e_per,
        "phase_periodic_deg": ph_per,
        "dE_rest_pct": 100.0 * (rest_row["E_norm_MPa"] / e_l - 1.0),
        "dphase_rest_deg": rest_row["phase_deg"] - ph_l,
        "dE_periodic_pct": 100.0 * (e_per / e_l - 1.0),
        "dphase_periodic_deg": ph_per - ph_l,
        "dE_long_pct": 100.0 * (e_l / prev["E_norm_MPa"] - 1.0),
        "dphase_long_deg": ph_l - prev["phase_deg"],
        "dE_rest_to_periodic_pct": 100.0 * (rest_row["E_norm_MPa"] / e_per - 1.0),
        "dphase_rest_to_periodic_deg": rest_row["phase_deg"] - ph_per,
        "rest_converged": _close(rest_row["E_norm_MPa"], rest_row["phase_deg"], e_l, ph_l),
        "periodic_equal": _close(e_per, ph_per, e_l, ph_l),
        "rest_equal_periodic": _close(rest_row["E_norm_MPa"], rest_row["phase_deg"], e_per, ph_per),
        "first_cycle_to_periodic": first,
        "steps_rest": twopb.n_steps_of(frequency_Hz, dt, dataclasses.replace(base, n_cycles=rest_cycles), "rest"),
        "steps_periodic": int(runs["periodic"]["attrs"]["n_steps"]),
        "iterations_rest_first_cycle": cycle_mean(1),
        f"iterations_rest_cycle_{int(rest_cycles)}": cycle_mean(int(rest_cycles)),
        "iterations_rest_last_cycle": cycle_mean(long_cycles),
        "iterations_periodic": float(np.mean(runs["periodic"]["stats"]["iterations"])),
        "n_nlgs_steps_rest": int(long_row["n_nlgs_steps"]),
        "n_nlgs_steps_periodic": int(red["periodic"]["n_nlgs_steps"]),
        "n_broken_rest": int(long_row["n_broken_total"]),
        "start_periodic_run": runs["periodic"]["attrs"]["start"],
        "periodic_solve_s": info.get("solve_s", float("nan")),
        "periodic_force_ratio": info.get("force_ratio", float("nan")),
        "cpu_rest_s_per_cycle": float(rec["attrs"]["cpu_time_s"]) / long_cycles,
        "cpu_periodic_s": float(runs["periodic"]["attrs"]["cpu_time_s"]),
    }
    if continuous:
        c = red["continuous"]
        row.update(
            {
                "E_continuous_MPa": c["E_norm_MPa"],
                "phase_continuous_deg": c["phase_deg"],
                "dE_continuous_pct": 100.0 * (c["E_norm_MPa"] / e_l - 1.0),
                "dphase_continuous_deg": c["phase_deg"] - ph_l,
                "dE_continuous_to_periodic_pct": 100.0 * (c["E_norm_MPa"] / e_per - 1.0),
                "dphase_continuous_to_periodic_deg": c["phase_deg"] - ph_per,
            }
        )
    return row, cycles
