"""The workflow passes `snakemake --lint` (no lint on config/smoke.yaml) and is formatted by
snakefmt (line length of pyproject.toml [tool.snakefmt]); the Python sources pass ruff. The tools are the virtual
environment's, pinned in requirements.lock."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


def test_snakemake_lint_reports_nothing():
    proc = subprocess.run(
        [str(BIN / "snakemake"), "--lint", "--configfile", "config/smoke.yaml"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )
    out = proc.stdout + proc.stderr
    # snakemake 9 exits 1 when it finds lints; older versions exit 0, so the text is checked too:
    # every lint is printed under a "Lints for snakefile ..." or "Lints for rule ..." heading
    lints = [line for line in out.splitlines() if line.startswith("Lints for")]
    assert not lints, "snakemake --lint:\n" + out[-6000:]
    assert proc.returncode == 0, out[-6000:]
    assert "Congratulations, your workflow is in a good condition!" in out


def test_rule_files_are_snakefmt_formatted():
    proc = subprocess.run(
        [str(BIN / "snakefmt"), "--check", "workflow/", "Snakefile"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, f"snakefmt --check workflow/ Snakefile (run snakefmt to fix):\n{proc.stderr[-4000:]}"


def test_rule_files_hold_no_python_logic():
    """The logic lives in asphalt_nscd.plan (tested): no def, lambda or regex in the
    rule files."""
    for smk in [REPO / "Snakefile", *(REPO / "workflow" / "rules").glob("*.smk")]:
        code = "\n".join(line.split("#")[0] for line in smk.read_text().splitlines())
        for word in ("def ", "lambda", "import re", "re.compile", "re.match"):
            assert word not in code, f"{smk.relative_to(REPO)}: {word.strip()!r} belongs in asphalt_nscd.plan"


def _rules() -> dict:
    """Rule name -> its rule file, for every rule (and checkpoint) of workflow/rules/*.smk."""
    import re

    rules = {}
    for smk in sorted((REPO / "workflow" / "rules").glob("*.smk")):
        for name in re.findall(r"^\s*(?:rule|checkpoint) (\w+):", smk.read_text(), flags=re.M):
            rules[name] = smk.name
    return rules


def test_threads_and_resources_live_in_the_profiles():
    """Every rule has its threads, mem_mb and runtime in both workflow profiles (profiles/default,
    profiles/slurm) and none in its rule file; the profiles name no rule that does not exist."""
    import yaml

    rules = _rules()
    assert len(rules) > 30
    for smk in (REPO / "workflow" / "rules").glob("*.smk"):
        code = "\n".join(line.split("#")[0] for line in smk.read_text().splitlines())
        for word in ("threads:", "resources:"):
            assert word not in code, f"{smk.name}: {word} belongs in profiles/default and profiles/slurm"
    for profile in ("default", "slurm"):
        cfg = yaml.safe_load((REPO / "profiles" / profile / "config.yaml").read_text())
        assert set(cfg["set-threads"]) == set(rules), profile
        assert set(cfg["set-resources"]) == set(rules), profile
        for rule, res in cfg["set-resources"].items():
            assert set(res) == {"mem_mb", "runtime"}, (profile, rule)
    assert "default-resources" not in yaml.safe_load((REPO / "profiles" / "default" / "config.yaml").read_text())


def _dry_run(tmp_path: Path, config: str) -> subprocess.CompletedProcess:
    """`snakemake -n -p -F` of the repository's Snakefile in a fresh working directory."""
    import os

    for name in ("data", "config"):
        (tmp_path / name).symlink_to(REPO / name)
    env = dict(os.environ)
    env["PATH"] = f"{BIN}{os.pathsep}{env.get('PATH', '')}"
    return subprocess.run(
        [
            str(BIN / "snakemake"),
            "-s",
            str(REPO / "Snakefile"),
            "--directory",
            str(tmp_path),
            "-n",
            "-p",
            "-F",
            "--configfile",
            config,
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )


def test_default_profile_reaches_the_jobs_from_any_directory(tmp_path):
    """Started from another directory with -s, Snakemake still loads profiles/default beside the
    Snakefile: its per-rule resources reach the jobs and nscd_bench's threads reach the command."""
    proc = _dry_run(tmp_path, "config/smoke.yaml")
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-6000:]
    assert f"workflow specific profile {REPO / 'profiles' / 'default'}" in out
    block = out[out.index("rule nscd_bench:") :]
    block = block[: block.index("\n\n")]
    assert "runtime=60" in block and "mem_mb=3000" in block
    assert "NUMBA_NUM_THREADS=1 asphalt-nscd bench" in block and " --threads 1 " in block


def test_config_with_a_former_resource_key_is_rejected_with_its_new_place(tmp_path):
    import yaml

    cfg = yaml.safe_load((REPO / "config" / "smoke.yaml").read_text())
    cfg["campaign"]["job_runtime_min"] = 10
    (tmp_path / "old.yaml").write_text(yaml.safe_dump(cfg))
    proc = _dry_run(tmp_path, str(tmp_path / "old.yaml"))
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "campaign.job_runtime_min" in out and "profiles/default/config.yaml" in out


def test_python_sources_pass_ruff():
    """Unused imports and variables, undefined names and syntax errors in the package and its
    tests (rules of pyproject.toml [tool.ruff.lint])."""
    proc = subprocess.run(
        [str(BIN / "ruff"), "check", "--no-cache", "src", "tests"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, f"ruff check src tests (ruff check --fix to repair):\n{proc.stdout[-4000:]}"


def test_python_sources_are_formatted():
    """The package, its tests and the reference scripts in ruff's format (pyproject.toml
    [tool.ruff]: 120 columns); ``ruff format src tests reference`` repairs."""
    proc = subprocess.run(
        [str(BIN / "ruff"), "format", "--check", "--no-cache", "src", "tests", "reference"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, (
        f"ruff format --check (ruff format src tests reference repairs):\n{proc.stdout[-4000:]}"
    )
