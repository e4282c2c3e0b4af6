"""Where the CPU of one paper-scale 2PB job goes: run one job of the paper configuration under
cProfile with the process's CPU clock and write the CPU of its phases.

Usage, from a checkout with a paper-scale sample (``make run CONFIG=config/paper.yaml`` made
``results/samples/s1.h5``):

    .venv/bin/python reference/paper_scale/profile_job.py SAMPLE.h5 OUT.csv [--rig-state RIG.h5] [--temperature 20 --frequency 10]

``--rig-state``: the sample's rig state (``results/campaign/rig/s1.h5``, rule ``rig_state``), as the
workflow's jobs read it; without it the job computes the held spheres and the gravity solution itself.

Rows (phase, cpu_s, calls): the job's process CPU without the profiler (a separate run,
``resource.getrusage`` of the child), the profiled total, and the cumulative CPU of the
functions a job on its periodic orbit spends it in (profiled: the profiler adds its own
overhead, so read the phases as shares of the profiled total); Phases nest where said (the held-sphere search and the periodic state both
build harmonic systems and factorise them).
"""

from __future__ import annotations

import argparse
import cProfile
import csv
import os
import pstats
import resource
import subprocess
import sys
import tempfile
import time

#: phase label -> (end of the function's file path, function name) as cProfile names it
PHASES = {
    "held-sphere search (harmonic.solver.held_spheres)": ("harmonic/solver.py", "held_spheres"),
    "periodic state (harmonic.periodic.periodic_state)": ("harmonic/periodic.py", "periodic_state"),
    "gravity state, inside the periodic state (harmonic.periodic.gravity_state)": (
        "harmonic/periodic.py",
        "gravity_state",
    ),
    "harmonic system set-up, in both (HarmonicSystem.__init__)": ("harmonic/solver.py", "__init__"),
    "sparse LU factorisations, in both (SuperLU gstrf)": (
        "~",
        "<built-in method scipy.sparse.linalg._dsolve._superlu.gstrf>",
    ),
    "rig state read (campaign.twopb.read_rig_state)": ("campaign/twopb.py", "read_rig_state"),
    "rig set-up (sample.rig.setup)": ("sample/rig.py", "setup"),
    "record written (campaign.twopb.write_record)": ("campaign/twopb.py", "write_record"),
}


def _child_cpu(cmd) -> float:
    """User + system CPU, s, of a child process running ``cmd`` (raises on a non-zero exit)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("sample")
    p.add_argument("output")
    p.add_argument("--temperature", default="20")
    p.add_argument("--frequency", default="10")
    p.add_argument("--rig-state", default=None, help="the sample's rig-state file (run-2pb --rig-state)")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        cmd = ["run-2pb", "--sample", args.sample, "--mode", "paper", "--parameters", "data/paper/table3_burgers.csv"]
        cmd += ["--temperature", args.temperature, "--frequency", args.frequency]
        if args.rig_state:
            cmd += ["--rig-state", args.rig_state]
        cmd += ["--config", "config/config.yaml", "config/paper.yaml"]
        cmd += ["-o", os.path.join(tmp, "r.h5"), "--row", os.path.join(tmp, "r.csv")]
        startup = _child_cpu([sys.executable, "-m", "asphalt_nscd", "run-2pb", "--help"])
        process = _child_cpu(
            [sys.executable, "-m", "asphalt_nscd", *cmd[:-4], "-o", os.path.join(tmp, "a.h5")]
            + ["--row", os.path.join(tmp, "a.csv")]
        )
        profile = cProfile.Profile(time.process_time)
        t0 = time.process_time()
        from asphalt_nscd.cli import main as cli_main

        status = profile.runcall(cli_main, cmd)
        total = time.process_time() - t0
        if status:
            return status
    stats = pstats.Stats(profile).stats
    rows = [
        ("job process, not profiled", process, 1),
        ("command start-up: interpreter and imports (run-2pb --help), not profiled", startup, 1),
        ("profiled total", total, 1),
    ]
    for label, (where, func) in PHASES.items():
        cpu, calls = 0.0, 0
        for (path, _, name), (_, ncalls, _, cum, _) in stats.items():
            if path.endswith(where) and name == func:
                cpu += cum
                calls += ncalls
        rows.append((label, cpu, calls))
    with open(args.output, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["phase", "cpu_s", "calls"])
        w.writerows((label, f"{cpu:.3f}", calls) for label, cpu, calls in rows)
    for label, cpu, calls in rows:
        print(f"{label:55s} {cpu:7.2f} s  ({calls})", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
