"""How each forecast answers binder in place of air voids at the same VMA.

    python reference/forecast/volumetric_sensitivity.py RUN -o reference/forecast/volumetric_sensitivity.csv

``RUN``: a finished run's folder (``make run``), as for ``physics_probe.py``. At a fixed VMA the
aggregate, its gradation and so the discrete model's sample (its coarse fraction is
(1 - VMA)(1 - P_cut)) stay the same: only the split of the voids in the mineral aggregate between
effective binder and air changes. So 100 d ln|E*| / dV_be at fixed VMA (percent per 1 % of the mix's
volume moved from air to binder; central difference of +-0.5 %) is an exact property of every model,
with no new sample. It is computed per cell for ``dem_physical`` (nothing fitted) in the default
configuration and under the physics variant the probe chooses in the fold (air in pockets, Hertz
contacts at 150 microstrain, confined bridges, the compactor's 600 kPa patches:
``config/forecast_physics.yaml`` with ``forecast.dem.contact_strain``) and with the same physics but the
air in the binder (``air_phase: binder``: every inclusion's fraction over the space it shares with the
air, so the aggregate's packing does not move), and for the published Witczak
1-37A, 1-40D and Hirsch formulas (binder through its master curve for all; read as in the crossval), and
written per model and temperature (empty: all) as the mean over the mixes of each mix's mean, with its
t(n - 1) 95 % interval, and the share of mixes whose mean is negative (binder in place of air softening
the forecast). The formulas, fitted on many mixes, stiffen with binder in place of air; a model that
softens answers the volumetrics with the opposite sign.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from asphalt_nscd.diagnosis.scores import t_interval
from asphalt_nscd.forecast import baselines
from asphalt_nscd.forecast.models import run_forecast_inputs
from asphalt_nscd.forecast.physical import BondPhysics, PhysicalDem
from asphalt_nscd.io import InputError, write_csv

#: the half step of the central difference, % of the mix's volume
STEP_PCT = 0.5
#: dem_physical's variants: (label, BondPhysics arguments)
DEM_VARIANTS = (
    ("dem_physical (default configuration)", ("mastic", None, False, None)),
    ("dem_physical (air in pockets, Hertz 150 microstrain, confined, 600 kPa)", ("pockets", 1.5e-4, True, 6e5)),
    ("dem_physical (air in the binder, Hertz 150 microstrain, confined, 600 kPa)", ("binder", 1.5e-4, True, 6e5)),
)
#: the published formulas (their own coefficients)
FORMULAS = ("witczak_1_37a", "witczak_1_40d", "hirsch")


def ln_moduli(table: pd.DataFrame, responses: dict, cut_mm: float, dem_variants=DEM_VARIANTS) -> pd.DataFrame:
    """ln|E*| (|E*| in MPa) of every row of ``table`` (columns: the models)."""
    out = {}
    for label, args in dem_variants:
        model = PhysicalDem("dem_physical", responses, cut_mm, physics=BondPhysics(*args))
        out[label] = np.log(model.predict(model.fit(table), table)[0])
    mix = baselines.Mix(
        table["rho34_pct"],
        table["rho38_pct"],
        table["rho4_pct"],
        table["rho200_pct"],
        table["Va_pct"],
        table["Vbeff_pct"],
    )
    G, delta = table["binder_G_mix_MPa"] * 1e6, table["binder_delta_mix_deg"]
    for name in FORMULAS:
        out[name] = np.log(baselines.predict(name, mix, table["frequency_Hz"], G, delta, table["binder_eta_Pa_s"])[0])
    return pd.DataFrame(out, index=table.index)


def sensitivity(table: pd.DataFrame, responses: dict, cut_mm: float = 4.0, dem_variants=DEM_VARIANTS) -> pd.DataFrame:
    """The table of the module docstring from the crossval's rows ``table`` (binder through its curve);
    ``dem_variants``: (label, :class:`BondPhysics` arguments) of the ``dem_physical`` variants."""

    def moved(d):
        return table.assign(Vbeff_pct=table["Vbeff_pct"] + d, Va_pct=table["Va_pct"] - d)

    up, down = (ln_moduli(moved(d), responses, cut_mm, dem_variants) for d in (STEP_PCT, -STEP_PCT))
    s = 100.0 * (up - down)
    s = s / (2.0 * STEP_PCT)
    s[["mix_id", "temperature_C"]] = table[["mix_id", "temperature_C"]]
    rows = []
    for model in [c for c in s.columns if c not in ("mix_id", "temperature_C")]:
        for T in [np.nan, *sorted(s["temperature_C"].unique())]:
            sel = s if np.isnan(T) else s[s["temperature_C"] == T]
            per_mix = sel.dropna(subset=[model]).groupby("mix_id")[model].mean().to_numpy()
            lo, hi = t_interval(per_mix)
            rows.append(
                {
                    "model": model,
                    "temperature_C": T,
                    "n_mixes": per_mix.size,
                    "dlnE_pct_per_pct": per_mix.mean(),
                    "dlnE_pct_per_pct_ci_low": lo,
                    "dlnE_pct_per_pct_ci_high": hi,
                    "share_softening": float(np.mean(per_mix < 0)),
                }
            )
    return pd.DataFrame(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path, help="a finished run's folder")
    ap.add_argument("--cut-mm", type=float, default=4.0, help="the run's forecast.dem.cut_mm (default 4)")
    ap.add_argument("-o", "--output", type=Path, required=True)
    args = ap.parse_args(argv)
    try:
        write_csv(sensitivity(*run_forecast_inputs(args.run), args.cut_mm), args.output)
    except InputError as err:  # a missing or malformed input of the run: its one-line message
        print(f"error: {err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
