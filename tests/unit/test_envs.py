"""The rules' software environment (workflow/envs/asphalt-nscd.yaml, conda-forge names) pins
the same versions as requirements.lock, and covers every runtime dependency of the package."""

import re
import tomllib
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[2]
ENV = REPO / "workflow" / "envs" / "asphalt-nscd.yaml"
#: conda-forge name -> PyPI name where they differ
CONDA_TO_PYPI = {"matplotlib-base": "matplotlib"}
#: runtime dependencies of pyproject.toml that the jobs do not need (they drive the workflow)
WORKFLOW_ONLY = {"snakemake", "snakemake-executor-plugin-slurm"}
#: build tools of the post-deploy install, unpinned in both files
UNPINNED = {"python", "pip", "setuptools", "wheel"}


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def lock() -> dict:
    pins = {}
    for line in (REPO / "requirements.lock").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, version = line.split("==")
            pins[_norm(name)] = version.strip()
    return pins


def env_pins() -> dict:
    deps = yaml.safe_load(ENV.read_text())["dependencies"]
    pins = {}
    for dep in deps:
        assert isinstance(dep, str), f"{ENV.name}: unexpected entry {dep!r}"
        name, _, version = (part.strip() for part in dep.partition("="))
        pins[_norm(CONDA_TO_PYPI.get(name, name))] = version
    return pins


def test_env_versions_equal_the_lock_file():
    pins, locked = env_pins(), lock()
    for name, version in pins.items():
        if name in UNPINNED:
            continue
        assert name in locked, f"{ENV.name}: {name} is not in requirements.lock"
        assert version == locked[name], f"{ENV.name}: {name} ={version}, requirements.lock {locked[name]}"


def test_env_covers_the_runtime_dependencies():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    needed = {_norm(re.split(r"[<>=!~ \[;]", d)[0]) for d in project["dependencies"]} - WORKFLOW_ONLY
    missing = needed - set(env_pins())
    assert not missing, f"{ENV.name} lacks runtime dependencies {sorted(missing)}"
    assert env_pins()["python"].startswith("3.11")


def test_every_rule_uses_the_env():
    """Every rule of workflow/rules/*.smk that runs something (also those under an ``if``,
    indented) declares the environment; snakefmt puts directives in its own order, so the block is searched."""
    n_rules = 0
    for smk in (REPO / "workflow" / "rules").glob("*.smk"):
        text = smk.read_text()
        rules = re.findall(r"^\s*rule (\w+):", text, re.M)
        blocks = re.split(r"^\s*rule \w+:", text, flags=re.M)[1:]
        n_rules += len(rules)
        for name, block in zip(rules, blocks):
            if not re.search(r"^\s+(shell|run|script|notebook|wrapper):", block, re.M):
                continue  # a target-only rule (inputs only) runs nothing
            assert re.search(r'^\s+conda:\s*\n\s+"\.\./envs/asphalt-nscd\.yaml"', block, re.M), (
                f"{smk.name}: rule {name} has no conda env"
            )
    assert n_rules >= 38, f"only {n_rules} rules found in workflow/rules/*.smk"
