"""The SLURM profile (profiles/slurm) builds the DAG in a dry run, without sbatch."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
PROFILE = REPO / "profiles" / "slurm"


def test_profile_uses_slurm_executor_with_per_rule_resources():
    """(Every rule's entries in both profiles: tests/unit/test_workflow_lint.py.)"""
    cfg = yaml.safe_load((PROFILE / "config.yaml").read_text())
    assert cfg["executor"] == "slurm"
    assert {"mem_mb", "runtime"} <= set(cfg["default-resources"])
    for rule, res in cfg["set-resources"].items():
        assert {"mem_mb", "runtime"} <= set(res), rule
        assert rule in cfg["set-threads"], rule


@pytest.mark.parametrize("config", ["config/smoke.yaml", "config/config.yaml"])
def test_dry_run_with_slurm_profile_builds_dag(tmp_path, config):
    for name in ("data", "config"):
        (tmp_path / name).symlink_to(REPO / name)
    env = dict(os.environ)
    # PATH: the venv's bin and a few basic tools, no SLURM command (the dry run must not need sbatch)
    tools = tmp_path / "bin"
    tools.mkdir()
    for name in ("bash", "sh", "which", "uname", "cat", "ls"):
        found = shutil.which(name)
        if found and "slurm" not in found:
            (tools / name).symlink_to(found)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), str(tools)])
    assert shutil.which("sbatch", path=env["PATH"]) is None
    cmd = [
        sys.executable,
        "-m",
        "snakemake",
        "-s",
        str(REPO / "Snakefile"),
        "--directory",
        str(tmp_path),
        "-n",
        "--workflow-profile",
        str(PROFILE),
        "--configfile",
        config,
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-6000:]
    for rule in ("measured_table", "fit_burgers", "rheology_figures", "report_index"):
        assert rule in out
    # the profile's per-rule resources reach the jobs
    block = out[out.index("rule fit_burgers:") :]
    block = block[: block.index("\n\n")] if "\n\n" in block else block
    assert "runtime=20" in block and "mem_mb=2000" in block
    # the SLURM workflow profile replaces profiles/default; a 2PB job's limit is the paper-scale
    # expression 240 * attempt, evaluated at the first attempt
    assert f"workflow specific profile {PROFILE}" in out and "profiles/default" not in out
    block = out[out.index("rule run_2pb:") :]
    block = block[: block.index("\n\n")] if "\n\n" in block else block
    assert "runtime=240" in block and "mem_mb=2000" in block
