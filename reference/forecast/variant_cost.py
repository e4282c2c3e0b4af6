"""The cost of a mix's sample at each cut and cube size: packing, sample and response, measured.

    python reference/forecast/variant_cost.py --mix 193 --variant 4:2.5 --variant 6.3:2.5 \
        --variant 4:2 --variant 2:2 -o reference/forecast/variant_cost.csv

Runs ``asphalt-nscd forecast-pack``, ``forecast-sample`` and ``forecast-response`` on the mix of the
shipped table (``data/binder_mix/mixes_35.tsv`` through ``asphalt-nscd matched``) at each
``cut_mm:size_dmax`` in a scratch folder, one process at a time, and writes per variant and step the
CPU (user + system of the child, getrusage), the wall time, the child's peak resident memory and the
sample's sphere count. The default sample variants are chosen from this table: a finer cut costs
the dense generalized eigen-decomposition of the response, O(n^3) in the spheres.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

from asphalt_nscd.forecast.formulation import variant_name
from asphalt_nscd.io import write_csv

ROOT = Path(__file__).resolve().parents[2]
TABLE = ROOT / "data" / "binder_mix" / "mixes_35.tsv"
CLI = [sys.executable, "-m", "asphalt_nscd"]


def _run(argv: list[str], log: Path) -> dict:
    """Run one command (stderr to ``log``); its CPU (s), wall (s) and peak RSS (MB) from the child's
    rusage. Raises SystemExit with the log's tail when the command fails."""
    t0 = time.perf_counter()
    with open(log, "w") as err:
        p = subprocess.Popen(CLI + argv, cwd=ROOT, stderr=err)
        _, status, usage = os.wait4(p.pid, 0)
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode:
        raise SystemExit(f"{' '.join(argv[:1])} failed ({p.returncode}): {log.read_text()[-2000:]}")
    return {
        "cpu_s": usage.ru_utime + usage.ru_stime,
        "wall_s": time.perf_counter() - t0,
        "max_rss_mb": usage.ru_maxrss / 1024,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mix", default="193", help="mix_id of the shipped table")
    ap.add_argument("--variant", action="append", required=True, help="cut_mm:size_dmax, e.g. 6.3:2.5")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("-o", "--output", required=True)
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        matched = work / "matched.csv"
        subprocess.run(CLI + ["matched", str(TABLE), "-o", str(matched)], cwd=ROOT, check=True)
        for v in args.variant:
            cut, size = (float(x) for x in v.split(":"))
            name = variant_name(cut, size)
            base = work / name
            common = ["--table", str(matched), "--mix", args.mix, "--cut-mm", f"{cut:g}", "--size-dmax", f"{size:g}"]
            steps = {
                "forecast-pack": ["forecast-pack", *common, "--seed", str(args.seed), "-o", f"{base}.npz"],
                "forecast-sample": [
                    "forecast-sample",
                    *common,
                    "--packing",
                    f"{base}.npz",
                    "-o",
                    f"{base}.h5",
                    "--summary",
                    f"{base}_summary.json",
                ],
                "forecast-response": [
                    "forecast-response",
                    f"{base}.h5",
                    "--mix",
                    args.mix,
                    "--seed",
                    str(args.seed),
                    "--variant",
                    name,
                    "-o",
                    f"{base}_response.npz",
                ],
            }
            for step, cmd in steps.items():
                r = _run(cmd, work / f"{name}_{step}.log")
                print(
                    f"{name} {step}: {r['cpu_s']:.1f} s CPU, {r['wall_s']:.1f} s wall, {r['max_rss_mb']:.0f} MB",
                    flush=True,
                )
                n = (
                    json.loads(Path(f"{base}_summary.json").read_text()).get("n_spheres")
                    if step != "forecast-pack"
                    else None
                )
                rows.append(
                    {
                        "variant": name,
                        "cut_mm": cut,
                        "size_dmax": size,
                        "mix_id": args.mix,
                        "step": step,
                        "n_spheres": n,
                        "cpu_s": round(r["cpu_s"], 2),
                        "wall_s": round(r["wall_s"], 2),
                        "max_rss_mb": round(r["max_rss_mb"], 1),
                    }
                )
    write_csv(pd.DataFrame(rows), args.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
