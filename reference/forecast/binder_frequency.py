"""The evidence for the matched table's binder frequency, and its binders, as a committed table.

The MEPDG relation eta = |G*| / 10 (1 / sin delta)^4.8628 (|G*| in Pa, at 10 rad/s) returns a
binder's viscosity from its |G*| and delta. Read at the rows whose mix frequency value is 10,
it gives the table's own eta if those binder columns are at 10 rad/s; read in Hz, those rows
sit at 63 rad/s. Per temperature above 20 degC, the median over the mixes of
log10(eta_MEPDG / eta_table).

    python reference/forecast/binder_frequency.py -o reference/forecast/binder_frequency.csv

Reads ``data/binder_mix/mixes_35.tsv`` with its sidecar (``asphalt_nscd.lab.matched``); writes
one row per temperature (``temperature_C``, ``n_mixes``, ``median_log10_ratio``, and the
angular frequency of the rows read in Hz, ``omega_if_hz_rad_s``) and the table's counts of
mixes, temperatures, frequencies and binders (``asphalt_nscd.forecast.binder.binder_ids``) in every row.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd

from asphalt_nscd.forecast.binder import binder_ids, mepdg_viscosity_Pa_s
from asphalt_nscd.lab.matched import read_matched

ROOT = Path(__file__).resolve().parents[2]
TABLE = ROOT / "data" / "binder_mix" / "mixes_35.tsv"
#: the mix frequency value whose binder columns are checked
AT = 10.0


def evidence(table: pd.DataFrame) -> pd.DataFrame:
    """The median log10 ratio of the MEPDG viscosity to the table's, per temperature above
    20 degC, at the rows whose frequency value is ``AT`` (module docstring)."""
    r = table[np.isclose(table["frequency_Hz"], AT) & (table["temperature_C"] > 20.0)]
    eta = mepdg_viscosity_Pa_s(r["binder_G_MPa"] * 1e6, np.minimum(r["binder_delta_deg"], 89.99))
    ratio = np.log10(eta / r["binder_eta_Pa_s"])
    out = ratio.groupby(r["temperature_C"]).agg(["median", "size"]).reset_index()
    out.columns = ["temperature_C", "median_log10_ratio", "n_mixes"]
    out["omega_if_hz_rad_s"] = 2.0 * math.pi * AT
    out["mixes"] = table["mix_id"].nunique()
    out["temperatures"] = table["temperature_C"].nunique()
    out["frequencies"] = table["frequency_Hz"].nunique()
    out["binders"] = binder_ids(table).nunique()
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--output", type=Path, required=True)
    args = ap.parse_args(argv)
    evidence(read_matched(TABLE)).to_csv(args.output, index=False, float_format="%.6g")


if __name__ == "__main__":
    main()
