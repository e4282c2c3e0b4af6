"""Before/after benchmark of where people wait: one invocation runs the same work with the code of two
commits, one after the other on this machine, and writes the CPU and wall time of each and their ratios
(JSON). Speed on a shared machine depends on the hour; a ratio measured in one run does much less.

    .venv/bin/python reference/timings/ab_bench.py tests --before BASE -o results/bench/ab_tests.json
    .venv/bin/python reference/timings/ab_bench.py run --before BASE -o results/bench/ab_run.json
    .venv/bin/python reference/timings/ab_bench.py prepare --before BASE -o results/bench/ab_prepare.json
    .venv/bin/python reference/timings/ab_bench.py crossval --before BASE --run-dir . -o results/bench/ab_crossval.json
    .venv/bin/python reference/timings/ab_bench.py response --before BASE --run-dir . -o results/bench/ab_response.json
    .venv/bin/python reference/timings/ab_bench.py diagnose --before BASE -o results/bench/ab_diagnose.json

Cases (``make bench`` runs them on small selections; the options name larger ones):

* ``tests``: the test modules ``--tests`` (default :data:`TESTS`) as each commit's ``make test`` runs
  them: ``python -m pytest`` with the options of its Makefile's ``PYTEST_ARGS`` (none before they
  existed), in a checkout of the commit.
* ``run``: ``snakemake --cores 2`` on ``--configfile`` (default the smoke configuration) and the targets
  ``--targets`` (default :data:`RUN_TARGETS`: the 2PB rows of one sample's measured and extended modes
  and what they need) in a fresh working directory per commit.
* ``crossval``: ``asphalt-nscd forecast-crossval --jobs 1`` (the forecast's nested leave-mix-out) on the
  inputs of a finished ``make run`` (``--run-dir``: its run configuration, matched table, binder curves
  and sample responses); the record holds the largest difference between the two sides' scores.
* ``response``: ``asphalt-nscd forecast-response`` (the sample's generalized eigen-decompositions), one
  process per sample as ``make run`` runs it, on the forecast samples of a finished ``make run``
  (``--run-dir``; ``--samples``: how many, the smallest, median and largest first, default all); the record
  holds each side's CPU per sample and the largest relative difference between the two sides' factors F(zeta)
  (both skeleton weightings, at :data:`ZETAS`).
* ``diagnose``: ``asphalt-nscd diagnose-bench --jobs 1`` (the detection bench's master-curve fits) on
  ``--configfile`` (default config/config.yaml) and a selection of its tables (``--bench-tables``: clean and
  planted tables per family, default 2 and 1; ``--families``, default :data:`DIAGNOSE_FAMILIES`; the
  configuration's base seed); the record holds the largest difference between the two sides' rate tables.
* ``prepare``: ``asphalt-nscd prepare-bench`` of one seed on ``--configfile`` (default
  config/paper.yaml) with each commit's code; the record holds each sample's statistics (spheres,
  porosity, coordination number, bonds) beside the times.

Each commit is checked out with ``git worktree add --detach`` into a temporary directory (removed at the
end) and runs on this interpreter's environment with its own sources first (``PYTHONPATH``). CPU is the
user + system time of the command and of every process it waited for (``getrusage``). ``--after`` is a
commit or ``worktree`` (the working tree as it is, uncommitted changes included; the default).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
#: test modules of the ``tests`` case by default: a few seconds to a minute each, from the parts the
#: speed-ups touch (library threads, byte code, the sample preparation, the campaign)
TESTS = [
    "tests/unit/test_chain_robustness.py",
    "tests/unit/test_sample_prepare.py",
    "tests/unit/test_campaign_twopb.py",
    "tests/unit/test_harmonic_solver.py",
]
#: zetas at which the ``response`` case compares the two sides' factors: the plane's corners and middle
ZETAS = [1e-6, 1e-3 - 1e-3j, 0.05 + 0.02j, 0.3 - 0.2j, 1.0, 20.0 - 5.0j, 1e3 - 1e2j, 1e6]
#: truth families of the ``diagnose`` case by default: the detector's own model and one outside it
DIAGNOSE_FAMILIES = ["wlf", "gmaxwell"]
#: targets of the ``run`` case by default (config/smoke.yaml): the sample, the law, the measured and
#: extended 2PB rows of one sample and their isotherm tables
RUN_TARGETS = [
    "results/campaign/measured/table4_measured.csv",
    "results/campaign/extended/table4_extended.csv",
]


def cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def timed(cmd: list[str], cwd: Path, env: dict, log: Path) -> dict:
    """Run ``cmd``; its wall time, CPU (its processes and those they waited for), exit status."""
    c0, t0 = cpu_children(), time.perf_counter()
    with open(log, "w") as fh:
        proc = subprocess.run(cmd, cwd=cwd, env=env, stdout=fh, stderr=subprocess.STDOUT)
    return {
        "command": " ".join(cmd),
        "returncode": proc.returncode,
        "wall_s": round(time.perf_counter() - t0, 2),
        "cpu_s": round(cpu_children() - c0, 2),
        "load_average_1min_end": round(os.getloadavg()[0], 2),
    }


@contextlib.contextmanager
def checkout(rev: str, root: Path):
    """The source tree of ``rev`` (a commit; 'worktree': this working tree as it is)."""
    if rev == "worktree":
        yield REPO
        return
    path = root / f"tree-{rev[:12]}"
    subprocess.run(["git", "worktree", "add", "--detach", "-q", str(path), rev], cwd=REPO, check=True)
    try:
        yield path
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", str(path)], cwd=REPO, check=False)


def environment(tree: Path) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(tree / "src"), env.get("PYTHONPATH", "")]))
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    return env


def pytest_args(tree: Path) -> list[str]:
    """The pytest options of ``make test`` in ``tree``: its Makefile's ``PYTEST_ARGS`` (none if unset)."""
    m = re.search(r"^PYTEST_ARGS\s*\?=\s*(.*)$", (tree / "Makefile").read_text(), flags=re.M)
    return m.group(1).split() if m else []


def run_case(case: str, tree: Path, work: Path, log: Path, args) -> dict:
    """Run ``case`` with the code of ``tree`` in the fresh directory ``work``; its output to ``log``."""
    env = environment(tree)
    work.mkdir(parents=True, exist_ok=True)
    if case == "tests":
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *pytest_args(tree), *args.tests]
        return timed(cmd, tree, env, log)
    if case == "run":
        for name in ("data", "config"):
            (work / name).symlink_to(tree / name)
        cmd = [sys.executable, "-m", "snakemake", "-s", str(tree / "Snakefile"), "--directory", str(work)]
        cmd += ["--cores", "2", "--configfile", *args.configfile, *args.targets]
        rec = timed(cmd, work, env, log)
        cpu_log = work / "benchmarks" / "process_cpu.jsonl"
        if cpu_log.exists():
            jobs = [json.loads(line) for line in cpu_log.read_text().splitlines() if line.strip()]
            rec["jobs"] = len(jobs)
            rec["jobs_cpu_s"] = round(sum(j["user_s"] + j["system_s"] for j in jobs), 2)
        return rec
    if case == "prepare":
        for name in ("data", "config"):
            (work / name).symlink_to(tree / name)
        out = work / "prepare.json"
        cmd = [str(Path(sys.executable).parent / "asphalt-nscd"), "prepare-bench", "--config", *args.configfile]
        cmd += ["--seed", str(args.seed), "-o", str(out), "--summary", str(work / "summary.json")]
        rec = timed(cmd, work, env, log)
        if out.exists():
            bench = json.loads(out.read_text())
            rec["phases_cpu_s"] = {k: round(v["cpu_s"], 2) for k, v in bench["phases"].items()}
            rec["sample"] = bench["sample"]
        return rec
    if case == "crossval":
        run = Path(args.run_dir).resolve()
        forecast = run / "results" / "forecast"
        configs = sorted((run / "results" / "config").glob("*.yaml"))
        responses = sorted((forecast / "responses").glob("*.npz"))
        if len(configs) != 1 or not responses or not (forecast / "matched.csv").exists():
            raise SystemExit(f"{run}: expected a finished make run (one results/config/*.yaml, the forecast's inputs)")
        cmd = [str(Path(sys.executable).parent / "asphalt-nscd"), "forecast-crossval", "--config", str(configs[0])]
        cmd += ["--matched", str(forecast / "matched.csv"), "--curves", str(forecast / "binder_curves.json")]
        cmd += ["--responses", *map(str, responses), "-o", str(work / "rows.csv"), "--scores", str(work / "scores.csv")]
        for option, name in (("constants", "c.json"), ("split", "split.csv"), ("selection", "selection.csv")):
            cmd += [f"--{option}", str(work / name)]
        cmd += ["--learned-rows", str(work / "learned_rows.csv"), "--jobs", "1"]
        rec = timed(cmd, run, env, log)
        if (work / "scores.csv").exists():
            rec["_scores"] = (work / "scores.csv").read_text()  # compared, then dropped
        return rec
    if case == "diagnose":
        for name in ("data", "config"):
            (work / name).symlink_to(tree / name)
        clean, planted = args.bench_tables
        cmd = [str(Path(sys.executable).parent / "asphalt-nscd"), "diagnose-bench", "--config", *args.configfile]
        cmd += ["--clean", str(clean), "--planted", str(planted), "--families", ",".join(args.families)]
        cmd += ["--jobs", "1", "-o", str(work / "bench.json"), "--table", str(work / "bench.csv")]
        rec = timed(cmd, work, env, log)
        if (work / "bench.csv").exists():
            rec["_scores"] = (work / "bench.csv").read_text()  # compared, then dropped
        return rec
    if case == "response":
        samples = response_samples(Path(args.run_dir).resolve(), args.samples)
        recs, per = [], {}
        for h5 in samples:
            mix, seed = h5.stem.rsplit("_s", 1)
            out = work / f"{h5.stem}.npz"
            cmd = [str(Path(sys.executable).parent / "asphalt-nscd"), "forecast-response", str(h5), "--mix", mix]
            cmd += ["--seed", seed, "--variant", "", "-o", str(out)]
            with open(log, "a") as fh:
                fh.write(f"$ {' '.join(cmd)}\n")
            recs.append(timed(cmd, work, env, log.with_suffix(f".{h5.stem}.log")))
            per[h5.stem] = recs[-1]["cpu_s"]
            if recs[-1]["returncode"]:
                break
        rec = {
            "command": f"asphalt-nscd forecast-response, one process per sample, {len(samples)} samples",
            "returncode": max(r["returncode"] for r in recs),
            "wall_s": round(sum(r["wall_s"] for r in recs), 2),
            "cpu_s": round(sum(r["cpu_s"] for r in recs), 2),
            "cpu_s_per_sample": per,
            "_responses": str(work),
        }
        return rec
    raise SystemExit(f"unknown case {case!r}")


def response_samples(run: Path, count: int | None) -> list[Path]:
    """The forecast samples of the finished run ``run``, ordered smallest, median, largest, then the rest
    (by file size); the first ``count`` (all if None). Raises SystemExit if it has none."""
    samples = sorted(
        (run / "results" / "forecast" / "samples").glob("*_s*.h5"), key=lambda p: (p.stat().st_size, p.name)
    )
    if not samples:
        raise SystemExit(f"{run}: expected a finished make run (results/forecast/samples/*_s*.h5)")
    first = list(dict.fromkeys([samples[0], samples[len(samples) // 2], samples[-1]]))
    ordered = first + [p for p in samples if p not in first]
    return ordered if count is None else ordered[:count]


def factor_difference(before: Path, after: Path) -> float:
    """The largest relative difference between the factors F(zeta) of the responses of the same names in two
    directories (both skeleton weightings, at :data:`ZETAS`); inf where a response is missing or not usable on
    one side only."""
    import numpy as np

    sys.path.insert(0, str(REPO / "src"))
    from asphalt_nscd.forecast.dem import Response

    zeta = np.array(ZETAS, complex)
    names = sorted({p.name for p in before.glob("*.npz")} | {p.name for p in after.glob("*.npz")})
    worst = 0.0
    for name in names:
        if not ((before / name).exists() and (after / name).exists()):
            return float("inf")
        b, a = Response.load(before / name), Response.load(after / name)
        if b.usable != a.usable:
            return float("inf")
        if not b.usable:
            continue
        for skeleton in ("mortar", "film"):
            fb, fa = b.factor(zeta, skeleton), a.factor(zeta, skeleton)
            worst = max(worst, float(np.max(np.abs(fa - fb) / np.abs(fb))))
    return worst


def score_difference(before: str, after: str) -> float:
    """The largest absolute difference between two ``forecast-crossval`` score tables' numbers (their
    text columns and missing scores must agree); inf where their shapes, columns, text or missing scores differ."""
    import io

    import numpy as np
    import pandas as pd

    b, a = (pd.read_csv(io.StringIO(t)) for t in (before, after))
    if b.shape != a.shape or list(b.columns) != list(a.columns):
        return float("inf")
    num = [c for c in b.columns if pd.api.types.is_numeric_dtype(b[c])]
    if not b.drop(columns=num).astype(str).equals(a.drop(columns=num).astype(str)):
        return float("inf")
    x, y = b[num].to_numpy(float), a[num].to_numpy(float)
    if not np.array_equal(np.isnan(x), np.isnan(y)):  # a score missing on one side only
        return float("inf")
    return float(np.max(np.where(np.isnan(x), 0.0, np.abs(x - y)), initial=0.0))


def portable(text: str, work: Path) -> str:
    """``text`` with this machine's folders replaced: the bench's temporary folder by ``$WORK``, this
    interpreter's scripts folder and the repository by nothing (a committed record names no outside path)."""
    for folder, name in ((work, "$WORK"), (Path(sys.executable).parent, ""), (REPO, "")):
        text = text.replace(f"{folder}/", f"{name}/" if name else "").replace(str(folder), name or ".")
    return text


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("case", choices=["tests", "run", "prepare", "crossval", "response", "diagnose"])
    ap.add_argument("--before", required=True, help="commit of the 'before' code")
    ap.add_argument("--after", default="worktree", help="commit of the 'after' code, or worktree (default)")
    ap.add_argument("--tests", nargs="+", default=TESTS, help="tests case: test files or node ids")
    ap.add_argument("--configfile", nargs="+", help="run and prepare cases: configuration files")
    ap.add_argument("--targets", nargs="+", default=RUN_TARGETS, help="run case: Snakemake targets")
    ap.add_argument("--seed", type=int, default=1, help="prepare case: the seed")
    ap.add_argument("--run-dir", default=".", help="crossval and response cases: the directory of a finished make run")
    ap.add_argument("--bench-tables", type=int, nargs=2, default=[2, 1], metavar=("CLEAN", "PLANTED"))
    ap.add_argument("--families", nargs="+", default=DIAGNOSE_FAMILIES, help="diagnose case: truth families")
    ap.add_argument("--samples", type=int, default=None, help="response case: how many samples (default all)")
    ap.add_argument("--order", choices=["before-first", "after-first"], default="before-first")
    ap.add_argument("-o", "--output", required=True, help="JSON record")
    args = ap.parse_args(argv)
    if args.configfile is None:
        args.configfile = {"run": ["config/smoke.yaml"], "diagnose": ["config/config.yaml"]}.get(
            args.case, ["config/paper.yaml"]
        )
    revs = {"before": args.before, "after": args.after}
    order = ["before", "after"] if args.order == "before-first" else ["after", "before"]
    root = Path(tempfile.mkdtemp(prefix="ab_bench_"))
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    record: dict = {"case": args.case, "date": time.strftime("%Y-%m-%d %H:%M:%S"), "machine": platform.node()}
    record["cores"] = os.cpu_count()
    record["load_average_1min_start"] = round(os.getloadavg()[0], 2)
    try:
        for side in order:
            with checkout(revs[side], root) as tree:
                head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=tree, capture_output=True, text=True)
                log = Path(args.output).with_suffix(f".{side}.log")
                rec = run_case(args.case, tree, root / side, log, args)
                rec["log"] = str(log)
                rec["commit"] = head.stdout.strip() + (" + working tree" if revs[side] == "worktree" else "")
                record[side] = rec
                print(f"{side}: {json.dumps({k: v for k, v in rec.items() if not k.startswith('_')})}", file=sys.stderr)
        b, a = record["before"], record["after"]
        if "_scores" in b and "_scores" in a:
            record["max_abs_difference_scores"] = score_difference(b.pop("_scores"), a.pop("_scores"))
        if "_responses" in b and "_responses" in a:
            record["max_rel_difference_factor"] = factor_difference(
                Path(b.pop("_responses")), Path(a.pop("_responses"))
            )
    finally:
        shutil.rmtree(root, ignore_errors=True)
    record["cpu_ratio_before_over_after"] = round(b["cpu_s"] / a["cpu_s"], 3) if a["cpu_s"] else None
    record["wall_ratio_before_over_after"] = round(b["wall_s"] / a["wall_s"], 3) if a["wall_s"] else None
    Path(args.output).write_text(portable(json.dumps(record, indent=2), root) + "\n")
    if b["returncode"] or a["returncode"]:
        raise SystemExit(
            f"a side failed (exit {b['returncode']} before, {a['returncode']} after): {b['log']}, {a['log']}"
        )


if __name__ == "__main__":
    main()
