"""dem_physical, which fits nothing on mixes, under the candidate physics of its bond laws: where the
air voids enter the mortar, whether the skeleton contacts also touch as Hertz contacts of the stones,
whether their patches keep the size the compactor pressed them to, whether the mortar bridges are
confined layers bonded to their stones, and whether the mortar's fine aggregate has a pressed skeleton
of its own, beside the mortar or as the direct contacts of a contact network.

    python reference/forecast/physics_probe.py RUN -o reference/forecast/physics_probe.csv \
        --per-mix reference/forecast/physics_probe_per_mix.csv

``RUN``: a finished run's folder (``make run``), whose ``results/forecast/`` holds the matched table, the
binder curves and the responses of the base samples (written by this version of ``forecast-response``:
the Hertz contacts read their skeleton geometry). For every variant (``air_phase`` of
``asphalt_nscd.forecast.mortar``, the last two with the air in the binder, every inclusion's fraction over
the space it shares with the air; ``contact_strain`` of ``asphalt_nscd.forecast.physical.hertz_contact``,
the test's strain amplitude, AASHTO T 342's 50-150 microstrain; ``compaction_pressure`` of the same function,
AASHTO T 312's 600 kPa; ``confinement`` of ``asphalt_nscd.forecast.physical.confined_bridge``; ``fine_skeleton_pressure``
of ``asphalt_nscd.forecast.mortar.granular_skeleton``, the pressure that pressed the contacts of the mortar's fine
aggregate, at most the compactor's 600 kPa, and a tenth and a hundredth of it: a grid laid out after a first look
at these mixes' forecasts at 600 kPa; ``fine_neighbours`` of ``asphalt_nscd.forecast.mortar.contact_network``, the
neighbours each fine particle shares a mortar bridge with, 6 of them direct contacts, at 8, 12 and 18 with the
skeleton at 600 kPa: a grid laid out after an exploratory look at these mixes' forecasts with 8 to 24 neighbours at
600 and 60 kPa) it forecasts every mix, binder through
its curve, and writes per variant and temperature (empty: all) the mean over the mixes of each mix's
mean absolute 100 ln(E_f / E_m) and phase error, with t(n - 1) 95 % intervals over the mixes, and
the mean signed errors (bias), and what the forecast misses as a complex modulus: each cell's
(E*_m - E*_f) / |E*_m| (``asphalt_nscd.forecast.validation.missing_modulus``), its storage and loss
parts (in phase with the strain and in quadrature) in percent of the measured |E*| (the mix's mean,
then the mean over the mixes with its t(n - 1) interval) and the phase angle of that mean (an elastic
part missing reads near 0 deg, a part like the binder near the binder's own phase angle, the mean
``binder_delta_deg`` over the cells beside it). Nothing is fitted, so no mix informs its own forecast; but the
variants are compared on the same 35 mixes, so choosing one by this table is a choice made on the
scored mixes. The row ``chosen in the fold`` makes that choice without the mix it scores: for each
mix left out, the variant with the least mean |E*| error over the other mixes forecasts it (its
choices counted in ``chosen``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from asphalt_nscd.diagnosis.scores import t_interval
from asphalt_nscd.forecast.models import run_forecast_inputs
from asphalt_nscd.forecast.physical import BondPhysics, PhysicalDem
from asphalt_nscd.forecast.validation import missing_modulus
from asphalt_nscd.io import InputError, write_csv

#: the gyratory compactor's vertical pressure, Pa (AASHTO T 312)
T312_PA = 6e5
#: (air_phase, contact_strain, confinement, compaction_pressure, fine_skeleton_pressure, fine_neighbours) of each
#: variant; the first is the default configuration's dem_physical
VARIANTS = (
    ("mastic", None, False, None, None, None),
    ("mortar", None, False, None, None, None),
    ("mastic", 1e-4, False, None, None, None),
    ("mortar", 5e-5, False, None, None, None),
    ("mortar", 1e-4, False, None, None, None),
    ("mortar", 1.5e-4, False, None, None, None),
    ("pockets", None, False, None, None, None),
    ("mastic", None, True, None, None, None),
    ("mortar", None, True, None, None, None),
    ("pockets", None, True, None, None, None),
    ("mortar", 1e-4, True, None, None, None),
    ("pockets", 1e-4, True, None, None, None),
    ("pockets", 1.5e-4, True, None, None, None),
    ("mastic", None, False, T312_PA, None, None),
    ("pockets", None, False, T312_PA, None, None),
    ("mortar", None, True, T312_PA, None, None),
    ("pockets", None, True, T312_PA, None, None),
    ("pockets", 1.5e-4, True, T312_PA, None, None),
    ("binder", None, False, None, None, None),
    ("binder", 1.5e-4, True, T312_PA, None, None),
    ("mastic", None, False, None, T312_PA, None),
    ("pockets", None, True, T312_PA, T312_PA, None),
    ("pockets", None, True, T312_PA, T312_PA / 10, None),
    ("pockets", None, True, T312_PA, T312_PA / 100, None),
    ("pockets", None, True, T312_PA, T312_PA, 8.0),
    ("pockets", None, True, T312_PA, T312_PA, 12.0),
    ("pockets", None, True, T312_PA, T312_PA, 18.0),
)


def choice_in_fold(score: pd.DataFrame) -> dict:
    """Per mix (``score``'s index), the column of ``score`` (one per variant: each mix's mean abs error) whose
    mean over the other mixes is least: the mix's own score never enters its choice."""
    return {m: score.drop(index=m).mean().idxmin() for m in score.index}


def probe(run: Path, cut_mm: float = 4.0) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The table of the module docstring from the run folder ``run``, and the choice inside the fold per mix:
    ``mix_id``, ``chosen`` (its variant), the mix's mean abs 100 ln(E_f / E_m) (``abs_logE_pct``) and phase
    error (``abs_phase_deg``), for pairing with the other models' per-mix errors."""
    table, responses = run_forecast_inputs(run)
    errors = {}
    for variant in VARIANTS:
        model = PhysicalDem(
            "dem_physical",
            responses,
            cut_mm,
            physics=BondPhysics(*variant),
        )
        E, P, _ = model.predict(model.fit(table), table)
        missing = missing_modulus(table["E_norm_MPa"], table["phase_deg"], E, P)
        t = table.assign(
            e=100 * np.log(E / table["E_norm_MPa"]), p=P - table["phase_deg"], mr=missing.real, mi=missing.imag
        ).dropna(subset=["e"])
        errors[variant] = t
    # the choice inside the fold: each mix forecast by the variant best on the other mixes
    keys = list(errors)  # the variants by position: a column label of None would be read back as NaN
    score = pd.DataFrame(
        {i: errors[k].groupby("mix_id")["e"].apply(lambda x: np.mean(np.abs(x))) for i, k in enumerate(keys)}
    )
    chosen = {m: keys[i] for m, i in choice_in_fold(score).items()}
    pick = pd.concat([errors[k][errors[k]["mix_id"] == m] for m, k in chosen.items()])
    names = {
        m: f"{a} {s if s is not None else 'none'}{' confined' if c else ''}{f' compacted {p / 1e3:g} kPa' if p else ''}"
        f"{f' fine skeleton {f / 1e3:g} kPa' if f else ''}{f' network of {z:g}' if z else ''}"
        for m, (a, s, c, p, f, z) in chosen.items()
    }
    counts = pd.Series(list(names.values())).value_counts()
    per_mix_chosen = (
        pick.groupby("mix_id")
        .agg(abs_logE_pct=("e", lambda x: np.mean(np.abs(x))), abs_phase_deg=("p", lambda x: np.mean(np.abs(x))))
        .reset_index()
    )
    per_mix_chosen.insert(1, "chosen", per_mix_chosen["mix_id"].map(names))
    rows = []
    for (air, strain, confined, pressure, fine, neighbours), t in [
        *errors.items(),
        (("chosen in the fold", None, None, None, None, None), pick),
    ]:
        for T in [np.nan, *sorted(t["temperature_C"].unique())]:
            sel = t if np.isnan(T) else t[t["temperature_C"] == T]
            per_mix = sel.groupby("mix_id").agg(
                ae=("e", lambda x: np.mean(np.abs(x))), ap=("p", lambda x: np.mean(np.abs(x))), be=("e", "mean")
            )
            per_mix[["bp", "mr", "mi"]] = sel.groupby("mix_id")[["p", "mr", "mi"]].mean()
            row = {"air_phase": air, "contact_strain": strain, "confinement": confined}
            row |= {"compaction_pressure_Pa": pressure, "fine_skeleton_pressure_Pa": fine}
            row |= {"fine_contact_neighbours": neighbours, "temperature_C": T}
            row["n_mixes"] = len(per_mix)
            row["chosen"] = "; ".join(f"{k}: {v}" for k, v in counts.items()) if air == "chosen in the fold" else ""
            for col, name in (
                ("ae", "abs_logE_pct"),
                ("ap", "abs_phase_deg"),
                ("be", "bias_logE_pct"),
                ("bp", "bias_phase_deg"),
                ("mr", "missing_storage_pct"),
                ("mi", "missing_loss_pct"),
            ):
                lo, hi = t_interval(per_mix[col].to_numpy())
                row |= {name: per_mix[col].mean(), f"{name}_ci_low": lo, f"{name}_ci_high": hi}
            row["missing_phase_deg"] = float(np.degrees(np.arctan2(per_mix["mi"].mean(), per_mix["mr"].mean())))
            row["binder_delta_deg"] = float(sel["binder_delta_mix_deg"].mean())
            rows.append(row)
    return pd.DataFrame(rows), per_mix_chosen


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path, help="a finished run's folder")
    ap.add_argument("--cut-mm", type=float, default=4.0, help="the run's forecast.dem.cut_mm (default 4)")
    ap.add_argument("-o", "--output", type=Path, required=True)
    ap.add_argument("--per-mix", type=Path, help="also write the choice inside the fold per mix (probe's second table)")
    args = ap.parse_args(argv)
    try:
        table, per_mix = probe(args.run, args.cut_mm)
        write_csv(table, args.output)
        if args.per_mix:
            write_csv(per_mix, args.per_mix)
    except InputError as err:  # a missing or malformed input of the run: its one-line message
        print(f"error: {err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
