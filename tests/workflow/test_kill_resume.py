"""Kill and resume: a running ``asphalt-nscd run-2pb`` stopped by SIGTERM (what Snakemake and
SLURM send), then by SIGKILL, and rerun, gives the uninterrupted run to 1e-12 relative, and
leaves no half-written output behind."""

from __future__ import annotations

from cli_options import set_options

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.campaign import twopb
from asphalt_nscd.sample.lattice import lattice_sample
from asphalt_nscd.sample.store import write_sample

REPO = Path(__file__).resolve().parents[2]
SETTINGS = {
    "n_cycles": 40,
    "dt_policy": "steps_per_cycle",
    "steps_per_cycle": 400,
    "dt_max_s": 0.02,
    "checkpoint_every": 400,
    "profile_instants": 4,
}


@pytest.fixture(scope="module")
def sample(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("sample") / "s1.h5"
    write_sample(path, lattice_sample(60, seed=5, radius_range=(0.9e-3, 1.5e-3), plate_mass=(np.inf, 1e-3)))
    return path


def command(sample: Path, out: Path) -> list[str]:
    cli = Path(sys.executable).parent / "asphalt-nscd"
    return [
        str(cli),
        "run-2pb",
        "--sample",
        str(sample),
        "--parameters",
        str(REPO / "data/paper/table3_burgers.csv"),
        "--table3-units",
        "Pa",
        "--temperature",
        "15",
        "--frequency",
        "10",
        "--no-progress",
        *set_options(json.dumps(SETTINGS)),
        "-o",
        str(out),
        "--row",
        str(out.with_suffix(".csv")),
    ]


def checkpoint_step(out: Path) -> int:
    """Steps a rerun would resume from: the solver checkpoint's step (``<out>.ckpt.h5``), bounded
    by the steps the partial arrays beside it cover (``<out>.partial.npz``, written first); 0
    while either is missing or being renamed into place."""
    partial, ckpt = out.with_name(out.name + ".partial.npz"), out.with_name(out.name + ".ckpt.h5")
    if not (partial.exists() and ckpt.exists()):
        return 0
    try:
        with np.load(partial) as z:
            covered = int(np.count_nonzero(z["t"]))
        with h5py.File(ckpt, "r") as f:
            return min(covered, int(f.attrs["step_index"]))
    except (OSError, ValueError, KeyError):  # being renamed into place
        return 0


def interrupt(cmd: list[str], out: Path, sig: int, after_step: int) -> None:
    """Start the job, wait until its checkpoint covers ``after_step`` steps, send ``sig``."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 600
    while checkpoint_step(out) < after_step:
        assert proc.poll() is None, f"the job ended before step {after_step}: {proc.communicate()}"
        assert time.monotonic() < deadline
        time.sleep(0.05)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode != 0, "the job was not interrupted: it finished first"
    assert not out.exists() and not out.with_suffix(".csv").exists(), "an interrupted job left an output"
    if sig == signal.SIGTERM:
        assert proc.returncode == 128 + signal.SIGTERM, err
        assert not list(out.parent.glob(".*.tmp")), "SIGTERM left a temporary file"


def test_sigterm_then_sigkill_then_rerun_gives_the_uninterrupted_result(sample, tmp_path):
    ref = tmp_path / "ref" / "15C_10Hz.h5"
    subprocess.run(command(sample, ref), check=True, capture_output=True)
    out = tmp_path / "killed" / "15C_10Hz.h5"
    cmd = command(sample, out)
    n_steps = 40 * 400
    interrupt(cmd, out, signal.SIGTERM, after_step=4000)
    first = checkpoint_step(out)
    interrupt(cmd, out, signal.SIGKILL, after_step=first + 4000)
    assert checkpoint_step(out) > first, "the second run did not resume past the first checkpoint"
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    assert "resuming from" in proc.stderr
    a, b = twopb.read_record(ref), twopb.read_record(out)
    assert a["force_N"].shape == (n_steps,)
    np.testing.assert_allclose(b["force_N"], a["force_N"], rtol=1e-12, atol=0)
    np.testing.assert_allclose(b["displacement_m"], a["displacement_m"], rtol=1e-12, atol=0)
    ra, rb = pd.read_csv(ref.with_suffix(".csv")), pd.read_csv(out.with_suffix(".csv"))
    for col in ("E_norm_MPa", "phase_deg", "F0_N", "z0_m"):
        np.testing.assert_allclose(rb[col], ra[col], rtol=1e-12, atol=0, err_msg=col)
    left = [p.name for p in out.parent.iterdir() if p.suffix not in (".h5", ".csv") or ".ckpt" in p.name]
    assert not left, f"files left next to the finished record: {left}"
