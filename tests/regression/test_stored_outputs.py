"""Stored-output regression tests (in the manner of pyro2's): three tiny runs through the
package, each compared with its stored output at a stated tolerance.

* ``twopb_tiny.json`` -- a numerical 2PB job stepped in time on a 40-sphere lattice sample
  (10 Hz, 2 cycles from rest, 100 steps per cycle, the time-domain path) and the same job
  started periodic on its exact orbit: the reduced |E*|, Phi, head force and phase lag;
  relative tolerance 1e-8 (the steps are deterministic; the tolerance allows another BLAS);
* ``law_fit.json`` -- the extended law of a seeded synthetic AASHTO T 342 table (one setting,
  no artifact search): its backbone parameters and in-sample errors; relative tolerance 1e-5
  (a least-squares optimum, reproducible to the optimiser's tolerance);
* ``diagnosis.json`` -- the diagnosis of that table (artifact search, master curve, law,
  error budget): the causes named and the effects detected, the noise level, the master curve's
  parameters, the budget's in-sample errors per temperature; relative tolerance 1e-5.

Regenerate the stored files after an intended change of the numbers (and say why in the
commit): ``ASPHALT_NSCD_REGENERATE=1 .venv/bin/python -m pytest tests/regression``; the test
then writes them and fails, so that a regeneration never passes silently.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

STORED = Path(__file__).with_name("stored")
REGENERATE = os.environ.get("ASPHALT_NSCD_REGENERATE") == "1"


def _compare(name: str, got: dict, rtol: float, atol: float = 0.0) -> None:
    """``got`` against ``stored/<name>``: the same keys; numbers within rtol (atol), the rest equal."""
    path = STORED / name
    if REGENERATE:
        path.write_text(json.dumps(got, indent=1, sort_keys=True) + "\n")
        pytest.fail(f"{path} regenerated (ASPHALT_NSCD_REGENERATE=1): review and commit it, then rerun without")
    want = json.loads(path.read_text())
    assert set(got) == set(want), sorted(set(got) ^ set(want))
    for k, w in want.items():
        g = got[k]
        if isinstance(w, float) or isinstance(g, float):
            assert math.isclose(g, w, rel_tol=rtol, abs_tol=atol), f"{name}: {k} = {g!r}, stored {w!r} (rtol {rtol})"
        else:
            assert g == w, f"{name}: {k} = {g!r}, stored {w!r}"


@pytest.fixture(scope="module")
def lattice(tmp_path_factory):
    from asphalt_nscd.sample.lattice import lattice_sample
    from asphalt_nscd.sample.store import write_sample

    path = tmp_path_factory.mktemp("sample") / "s1.h5"
    write_sample(path, lattice_sample(40, seed=3, radius_range=(0.9e-3, 1.5e-3), plate_mass=(np.inf, 1e-3)))
    return path


def test_twopb_job(lattice, tmp_path):
    from asphalt_nscd.campaign import twopb
    from asphalt_nscd.rheology.laws import GeneralizedBurgers

    law = GeneralizedBurgers.burgers(Em=2.43e7, eta_m=3.71e6, Ek=4.84e7, eta_k=7.73e5)
    base = twopb.TwoPBSettings(
        dt_policy="steps_per_cycle",
        steps_per_cycle=100,
        dt_max_s=1.0,
        n_cycles=2,
        checkpoint_every=0,
        yield_stress_Pa=None,
    )
    got = {}
    for label, s in (("rest", base), ("orbit", twopb.TwoPBSettings(**{**base.__dict__, "start": "periodic"}))):
        row = twopb.reduce_test(twopb.run_test(lattice, law, 10.0, s, tmp_path / f"{label}.h5", progress=False), 1)
        assert row["path"] == ("time_domain" if label == "rest" else "orbit")
        got.update({f"{label}_{k}": float(row[k]) for k in ("E_norm_MPa", "phase_deg", "F0_N", "psi_deg")})
        got[f"{label}_n_steps"] = int(row["n_steps"])
    _compare("twopb_tiny.json", got, rtol=1e-8)


def _table():
    from asphalt_nscd.diagnosis import synthetic

    table, _ = synthetic.generate(11, schedule="aashto_t342", n_specimens=2, test_order=False)
    return table


def test_law_fit():
    from asphalt_nscd.diagnosis.crossval import Options, fit_extended
    from asphalt_nscd.rheology.extended import LawSettings
    from asphalt_nscd.rheology.metrics import cell_means

    table = _table()
    fit = fit_extended(table, Options(candidates=(LawSettings(shift="wlf", static="constant"),), artifacts=False))
    cells = cell_means(table)
    E = fit.law.complex_modulus(cells["frequency_Hz"].to_numpy(), cells["temperature_C"].to_numpy())
    got = {f"backbone_{n}": float(v) for n, v in zip(fit.law.backbone.names, fit.law.backbone.x)}
    got["mean_abs_logE_pct"] = float(100 * np.mean(np.abs(np.log(np.abs(E) / cells["E_norm_MPa"]))))
    got["mean_abs_phase_deg"] = float(np.mean(np.abs(np.degrees(np.angle(E)) - cells["phase_deg"])))
    got["settings"] = fit.settings.label()
    _compare("law_fit.json", got, rtol=1e-5, atol=1e-9)


def test_diagnosis():
    from diagnosis_chain import diagnose_table

    report, _ = diagnose_table(_table())
    got = {
        "causes": sorted(report["causes"]),
        "detected": sorted(e["name"] for e in report["effects"] if e.get("detected")),
        "noise_sigma_lnE": float(report["noise"]["sigma_lnE"]),
        "noise_sigma_phase_deg": float(report["noise"]["sigma_phase_deg"]),
    }
    got.update({f"master_curve_{k}": float(v) for k, v in report["master_curve"]["parameters"].items()})
    for T, parts in report["error_budget"].items():
        for part in ("model_form", "total"):
            for q, v in (parts.get(part) or {}).items():
                got[f"budget_{T}_{part}_{q}"] = float(v)
    _compare("diagnosis.json", got, rtol=1e-5, atol=1e-9)
