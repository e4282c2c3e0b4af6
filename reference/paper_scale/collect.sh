#!/usr/bin/env bash
# Collect the paper-scale reference run (reference/paper_scale/README.md) from the run's
# working directory RUN (default: the current directory) into this folder:
#   jobs.csv          one row per finished 2PB job (the rows of results/sim/paper/s1/*.csv)
#   table4_paper_scale_s1.csv  Table 4 analogue of the finished jobs (campaign-isotherms;
#                     n_frequencies says how many of the 5 frequencies each temperature has)
#   s1_summary.json   the sample's summary (counts, porosity, density, bonds, CPU times)
# Usage: bash reference/paper_scale/collect.sh /path/to/run
set -euo pipefail
RUN=${1:-.}
HERE=$(cd "$(dirname "$0")" && pwd)
ASPHALT=${ASPHALT:-asphalt-nscd}
python3 - "$RUN" "$HERE/jobs.csv" <<'PY'
import csv, glob, sys
run, out = sys.argv[1], sys.argv[2]
keep = ["temperature_C", "frequency_Hz", "start", "n_cycles_simulated", "dt_s", "n_steps", "n_spheres", "n_bonds",
        "E_norm_MPa", "phase_deg", "E1_MPa", "E2_MPa", "n_nlgs_steps", "iterations_mean", "cpu_time_s",
        "wall_time_s", "cpu_per_sphere_step_s", "n_broken_total"]
rows = [next(csv.DictReader(open(f))) for f in glob.glob(f"{run}/results/sim/paper/s1/*.csv")]
rows.sort(key=lambda r: (float(r["temperature_C"]), float(r["frequency_Hz"])))
with open(out, "w", newline="") as fh:
    w = csv.DictWriter(fh, keep, extrasaction="ignore")
    w.writeheader()
    w.writerows(rows)
print(f"{len(rows)} jobs -> {out}")
PY
tmp=$(mktemp -d)
"$ASPHALT" campaign-isotherms --rows "$RUN"/results/sim/paper/s1/*.csv --parameters "$RUN/data/paper/table3_burgers.csv" \
    --table3-units Pa --paper-table4 "$RUN/data/paper/table4_mre.csv" --isotherms "$tmp/iso.csv" \
    --table4 "$HERE/table4_paper_scale_s1.csv" --figure-modulus "$tmp/m.png" --figure-phase "$tmp/p.png"
cp "$RUN/results/samples/s1_summary.json" "$HERE/s1_summary.json"
rm -rf "$tmp"
