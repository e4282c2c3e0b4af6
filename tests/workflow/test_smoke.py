"""Reduced-size run of the whole Snakemake workflow (config/smoke.yaml), its report, and
dry runs of the default and paper configurations."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _workdir(tmp_path: Path) -> Path:
    """A fresh working directory seeing the repository's data and configs (read-only use)."""
    for name in ("data", "config"):
        (tmp_path / name).symlink_to(REPO / name)
    return tmp_path


def _snakemake(workdir: Path, *args: str, timeout: float = 1800) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    cmd = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "--directory", str(workdir), *args]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout)
    if proc.returncode != 0:
        logs = "\n".join(
            f"--- {p}\n{p.read_text()[-3000:]}" for p in sorted((workdir / "logs").rglob("*.log"))
        ) if (workdir / "logs").exists() else ""
        pytest.fail(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-6000:]}\n{logs}")
    return proc


@pytest.mark.parametrize("config", ["config/config.yaml", "config/smoke.yaml", "config/paper.yaml"])
def test_dry_run_builds_dag(tmp_path, config):
    proc = _snakemake(_workdir(tmp_path), "-n", "--configfile", config, "--quiet", "rules")
    assert "report_index" in proc.stdout + proc.stderr


@pytest.mark.slow
def test_smoke_workflow_runs_end_to_end(tmp_path):
    workdir = _workdir(tmp_path)
    _snakemake(workdir, "--configfile", "config/smoke.yaml", "--cores", "2")
    index = workdir / "results" / "report" / "index.md"
    assert index.is_file()
    text = index.read_text()
    # every figure/table the index links exists in the report directory and is not empty
    links = [line.split("(")[-1].rstrip(")") for line in text.splitlines() if line.endswith(")")]
    assert links, "report index lists no figures or tables"
    for link in links:
        path = workdir / "results" / "report" / link
        assert path.is_file() and path.stat().st_size > 0, link
    # nothing left half-written
    assert not list((workdir / "results").rglob("*.tmp"))
    # the measured and extended modes start from the periodic steady state (1 cycle), the paper
    # mode from rest (campaign.*.start of config/smoke.yaml)
    import pandas as pd

    starts = {mode: pd.read_csv(next((workdir / "results" / "sim" / mode).rglob("*.csv"))).iloc[0]
              for mode in ("paper", "measured", "extended")}
    assert starts["paper"]["start"] == "rest" and starts["paper"]["n_cycles_simulated"] == 2
    for mode in ("measured", "extended"):
        assert starts[mode]["start"] == "periodic" and starts[mode]["n_cycles_simulated"] == 1
    # the HTML report builds from the same run
    _snakemake(workdir, "--configfile", "config/smoke.yaml", "--report", str(workdir / "report.html"))
    assert (workdir / "report.html").stat().st_size > 10_000


def test_invalid_config_is_rejected_with_the_key_named(tmp_path):
    import yaml

    workdir = _workdir(tmp_path)
    cfg = yaml.safe_load((REPO / "config" / "smoke.yaml").read_text())
    cfg["sample"]["scale"] = -1.0
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(cfg))
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    proc = subprocess.run(
        [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "--directory", str(workdir),
         "-n", "--configfile", str(bad)],
        capture_output=True, text=True, env=env, timeout=300,
    )
    assert proc.returncode != 0
    assert "scale" in proc.stderr + proc.stdout
