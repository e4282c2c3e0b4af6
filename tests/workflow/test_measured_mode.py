"""The workflow in measured mode on a second mix: the smoke configuration with
``measured.table`` pointed at the AMPT-like regression table (3 specimens x 3 temperatures x
6 frequencies, strain column, uniaxial sidecar; tests/data) runs the lab step, the Burger's
fit, the measured- and extended-mode NSCD jobs, the extended law and the diagnosis."""

from __future__ import annotations

import json

import pytest
import yaml

from asphalt_nscd.config import load as load_config

from test_smoke import REPO, _snakemake, _workdir

AMPT = REPO / "tests" / "data" / "ampt_like_3x3x6.csv"


@pytest.mark.slow
def test_measured_mode_on_the_ampt_like_table(tmp_path):
    workdir = _workdir(tmp_path)
    # the smoke overlay merged over config/config.yaml, as Snakemake merges it
    cfg = load_config([REPO / "config" / "smoke.yaml"], default=REPO / "config" / "config.yaml")
    cfg["measured"]["table"] = str(AMPT)
    cfg["measured"]["test"] = None
    config = tmp_path / "ampt.yaml"
    config.write_text(yaml.safe_dump(cfg))
    _snakemake(
        workdir,
        "--configfile",
        str(config),
        "--cores",
        "2",
        "results/diagnosis/report.json",
        "results/campaign/measured/table4_measured.csv",
    )
    report = json.loads((workdir / "results" / "diagnosis" / "report.json").read_text())
    assert report["measured"]["temperatures_C"] == [4.0, 21.0, 37.0]
    assert report["measured"]["test"]["test"] == "uniaxial_cylinder"
    by = {e["name"]: e for e in report["effects"]}
    assert not by["temperature_offset"]["testable"]  # 3 isotherms: no inner isotherm with a law to test
    assert by["inertia_uncorrected"]["testable"]  # the sidecar gives the cylinder's form factor
    assert by["broad_spectrum"]["testable"] and by["network_factor"]["testable"]
    assert json.loads((workdir / "results" / "lab" / "measured.test.json").read_text())["diameter_mm"] == 100.0
    assert (workdir / "results" / "campaign" / "measured" / "table4_measured.csv").stat().st_size > 0
