"""Dry runs of the three configurations and config validation. The reduced-size run of the
whole workflow, started as the README starts it, is tests/workflow/test_readme.py."""

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
        logs = (
            "\n".join(f"--- {p}\n{p.read_text()[-3000:]}" for p in sorted((workdir / "logs").rglob("*.log")))
            if (workdir / "logs").exists()
            else ""
        )
        pytest.fail(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-6000:]}\n{logs}")
    return proc


@pytest.mark.parametrize("config", ["config/config.yaml", "config/smoke.yaml", "config/paper.yaml"])
def test_dry_run_builds_dag(tmp_path, config):
    proc = _snakemake(_workdir(tmp_path), "-n", "--configfile", config, "--quiet", "rules")
    assert "report_index" in proc.stdout + proc.stderr


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
        [
            sys.executable,
            "-m",
            "snakemake",
            "-s",
            str(REPO / "Snakefile"),
            "--directory",
            str(workdir),
            "-n",
            "--configfile",
            str(bad),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert proc.returncode != 0
    assert "scale" in proc.stderr + proc.stdout


def test_a_sample_variant_repeating_the_base_is_refused_at_load(tmp_path):
    """A forecast sample variant equal to the base sample (a check no schema expresses) stops
    the workflow when it loads, naming the key, before any job is planned."""
    import yaml

    workdir = _workdir(tmp_path)
    dem = yaml.safe_load((REPO / "config" / "config.yaml").read_text())["forecast"]["dem"]
    bad = tmp_path / "bad.yaml"
    repeat = {"cut_mm": dem["cut_mm"], "size_dmax": dem["size_dmax"]}
    bad.write_text(yaml.safe_dump({"forecast": {"dem": {"variants": [repeat]}}}))
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    cmd = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "--directory", str(workdir), "-n"]
    proc = subprocess.run([*cmd, "--configfile", str(bad)], capture_output=True, text=True, env=env, timeout=300)
    out = proc.stderr + proc.stdout
    assert proc.returncode != 0
    assert "forecast.dem.variants[0]" in out and "repeats the base sample" in out, out[-3000:]
    assert "Job stats" not in out and "Traceback (most recent call last)" not in out, out[-3000:]
