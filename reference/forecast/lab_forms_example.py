"""One mix of the shipped matched table written in the forms a lab reports it: data/forecast_example/.

    python reference/forecast/lab_forms_example.py -o data/forecast_example

Reads ``data/binder_mix/mixes_35.tsv`` with its sidecar (``asphalt_nscd.lab.matched``) and writes,
for mix 211: its binder's points as a DSR frequency sweep in kPa, rad/s and degF
(``binder_211_dsr.csv``, headers carrying the units, and its sidecar), its four sieve figures as a
sieve analysis in US sieve names (``sieve_211.csv``), and the mix file ``mix_211.yaml`` with the
binder's PG grade and viscosity and the volumetrics as Pb, Gmm, Gmb, Gb, Gsb; then ``SOURCE.md``.
Reading the mix file (``asphalt_nscd.lab.mix_input.read_mix_file``) returns the table's figures.

The matched table declares its binder columns at f rad/s for a mix row at f Hz
(``binder_frequency_Hz`` = f / 2 pi): the sweep's angular frequency is f. Temperatures go back to
the table's degF (rounded to 1e-6: 14, 40, 70, 100, 130). Gb = 1.03 and Gsb = 2.65 are chosen (the
table gives neither: 1.03 is the usual binder value, MS-2's examples; 2.65 a usual aggregate bulk
specific gravity); Gmb and Gmm follow from the table's Va and Vbeff through VMA = Va + Vbeff (an
identity of the MS-2 relations): Gmb = (100 - VMA) Gsb / (100 - Pb), Gmm = Gmb / (1 - Va/100),
written with every digit so that they give Va and Vbeff back to 1e-12.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
from pathlib import Path

from asphalt_nscd.io import write_text
from asphalt_nscd.lab.matched import read_matched
from asphalt_nscd.lab.volumetrics import convert

ROOT = Path(__file__).resolve().parents[2]
TABLE = ROOT / "data" / "binder_mix" / "mixes_35.tsv"
MIX = "211"
GB = 1.03
GSB = 2.65


def _csv(rows: list[list]) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    return buf.getvalue()


def _F(temperature_C: float) -> float:
    return round(temperature_C * 1.8 + 32.0, 6)


def _volumetrics(Pb: float, Va: float, Vbeff: float, Gb: float, Gsb: float):
    """The MS-2 volumetrics of Pb, Gb, Gsb and the Gmb, Gmm that return Va and Vbeff (module docstring)."""
    Gmb = (100.0 - (Va + Vbeff)) * Gsb / (100.0 - Pb)
    return convert({"Pb": Pb, "Gmm": Gmb / (1.0 - Va / 100.0), "Gmb": Gmb, "Gb": Gb, "Gsb": Gsb}, "example")


def example_files(table, mix_id: str = MIX, Gb: float = GB, Gsb: float = GSB) -> dict[str, str]:
    """File name -> text of the example of mix ``mix_id`` of a matched table (module docstring)."""
    mix = table[table["mix_id"] == mix_id].sort_values(["temperature_C", "frequency_Hz"], ascending=[True, False])
    if mix.empty:
        raise SystemExit(f"no mix {mix_id!r} in the table")
    first = mix.iloc[0]
    stem = f"binder_{mix_id}_dsr"
    sweep = [["Temperature (°F)", "Angular Frequency (rad/s)", "Complex Modulus |G*| (kPa)", "Phase Angle (°)"]]
    for _, r in mix.iterrows():
        omega = round(2.0 * math.pi * r["binder_frequency_Hz"], 9)
        sweep.append(
            [repr(_F(r["temperature_C"])), repr(omega), repr(r["binder_G_MPa"] * 1e3), repr(r["binder_delta_deg"])]
        )
    sidecar = {
        "test": "dsr_frequency_sweep",
        "description": f"binder of mix {mix_id} of data/binder_mix/mixes_35.tsv written as a DSR frequency sweep",
        "source": "reference/forecast/lab_forms_example.py from the matched table's binder columns (SOURCE.md)",
    }
    sieves = ([["1 in", 100.0]] if first["rho34_pct"] > 0 else []) + [
        ["3/4 in", 100.0 - first["rho34_pct"]],
        ["3/8 in", 100.0 - first["rho38_pct"]],
        ["No. 4", 100.0 - first["rho4_pct"]],
        ["No. 200", first["rho200_pct"]],
    ]
    grading = _csv([["Sieve", "% Passing"]] + [[name, repr(float(v))] for name, v in sieves])
    Pb, Va, Vbeff = (float(first[c]) for c in ("Pb_pct", "Va_pct", "Vbeff_pct"))
    check = _volumetrics(Pb, Va, Vbeff, Gb, Gsb)
    Gmb, Gmm = check.Gmb, check.Gmm
    eta = mix.groupby("temperature_C")["binder_eta_Pa_s"].first()
    visc = ", ".join(f"{_F(T):g}: {float(e)!r}" for T, e in eta.items())
    grade = f"PG {first['pg_high_C']:g}{first['pg_low_C']:g}"
    mix_file = (
        f"# Mix {mix_id} of data/binder_mix/mixes_35.tsv in the forms a lab reports it (SOURCE.md).\n"
        "mixes:\n"
        f'  - id: "{mix_id}"\n'
        "    binder:\n"
        f"      file: {stem}.csv\n"
        f'      pg_grade: "{grade}"\n'
        f"      viscosity: {{unit: Pa s, temperature_unit: F, values: {{{visc}}}}}\n"
        f"    gradation: sieve_{mix_id}.csv\n"
        "    volumetrics:\n"
        f"      Pb: {Pb!r}\n"
        f"      Gmm: {Gmm!r}\n"
        f"      Gmb: {Gmb!r}\n"
        f"      Gb: {Gb!r}\n"
        f"      Gsb: {Gsb!r}\n"
    )
    span = [_volumetrics(Pb, Va, Vbeff, Gb, g).Pba_pct for g in (2.4, 2.9)]
    source = f"""# A mix given in lab forms: mix {mix_id} of data/binder_mix/mixes_35.tsv

The input of `make forecast MIX=data/forecast_example/mix_{mix_id}.yaml`: one mix of the shipped matched
table (`data/binder_mix/`, SOURCE.md there) written as a lab reports a mix. Made by

    python reference/forecast/lab_forms_example.py -o data/forecast_example

which reads the table with `asphalt_nscd.lab.matched.read_matched` and writes every file here (this
one included); `tests/unit/test_lab_mix_input.py` checks that the files are what the command writes
and that reading `mix_{mix_id}.yaml` gives back the table's figures. Licence: that of the table (MIT,
"Copyright (c) 2025 Robin0111", `data/binder_mix/LICENSE.source`).

| file | what | from the table |
|---|---|---|
| `{stem}.csv` (+ `{stem}.test.json`) | the binder's DSR frequency sweep, one row per point: `Temperature (°F)`, `Angular Frequency (rad/s)`, `Complex Modulus \\|G*\\| (kPa)`, `Phase Angle (°)` | `binder_G_MPa` x 1000, `binder_delta_deg`, temperature back to the table's °F (rounded to 1e-6), angular frequency 2π `binder_frequency_Hz` (rounded to 1e-9): the table declares its binder columns at f rad/s for the mix row at f Hz |
| `sieve_{mix_id}.csv` | a sieve analysis, % passing by US sieve name ({", ".join(n for n, _ in sieves)}) | 100 − rho34, 100 − rho38, 100 − rho4, rho200; the top size at 100 % (1 in if rho34 > 0, else 3/4 in) |
| `mix_{mix_id}.yaml` | the mix file: the sweep, the PG grade ({grade}), the viscosity per temperature (Pa s at °F), the sieve file, and the volumetrics as Pb, Gmm, Gmb, Gb, Gsb | `pg_high_C`, `pg_low_C`, `binder_eta_Pa_s` per temperature, `Pb_pct`; Gmm, Gmb below |

Volumetrics: the table gives Pb {Pb:g} %, Va {Va:g} %, Vbeff {Vbeff:.10g} % and no specific gravity. Chosen:
Gb = {Gb:g} (the usual binder value, MS-2's examples) and Gsb = {Gsb:g} (a usual aggregate bulk specific
gravity). Computed so that the MS-2 / AASHTO R 35 relations (`asphalt_nscd.lab.volumetrics`) return the
table's Va and Vbeff: VMA = Va + Vbeff, Gmb = (100 − VMA) Gsb / (100 − Pb) = {Gmb:.6f}, Gmm = Gmb /
(1 − Va/100) = {Gmm:.6f} (written with every digit; a lab reports three decimals). They imply Gse =
{check.Gse:.4f} and an absorbed binder Pba = {check.Pba_pct:.2f} % of the aggregate mass: high (the
table's Vbeff is {Vbeff / Pb:.3g} Pb), the case of absorptive aggregates; any Gsb from 2.4 to 2.9
gives Pba {span[0]:.2f}-{span[1]:.2f} %.
"""
    return {
        f"{stem}.csv": _csv(sweep),
        f"{stem}.test.json": json.dumps(sidecar, indent=2, ensure_ascii=False) + "\n",
        f"sieve_{mix_id}.csv": grading,
        f"mix_{mix_id}.yaml": mix_file,
        "SOURCE.md": source,
    }


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--output", type=Path, required=True, help="the folder (data/forecast_example)")
    args = ap.parse_args(argv)
    for name, text in example_files(read_matched(TABLE)).items():
        write_text(text, args.output / name)


if __name__ == "__main__":
    main()
