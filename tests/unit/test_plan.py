"""The workflow's plan (asphalt_nscd.plan) on the repository's three configurations.

The configs are loaded as the Snakefile loads them: config/config.yaml extended by the chosen
config file, validated (defaults filled) by the workflow's schemas. Expected counts and command
options are those of `snakemake -n -p -F --configfile CONFIG` before the logic moved out of the
rule files (smoke: 16 run_2pb jobs, default: 184, paper: 576)."""

from __future__ import annotations

import copy
import os
import inspect
from collections import Counter
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml

from asphalt_nscd import plan
from asphalt_nscd.campaign import modes
from asphalt_nscd.io import InputError

REPO = Path(__file__).resolve().parents[2]
SCHEMAS = REPO / "workflow" / "schemas"


def load_config(name: str) -> dict:
    """config/config.yaml extended by config/{name}.yaml, validated with defaults (as the Snakefile)."""
    from snakemake.utils import update_config, validate

    cfg = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    if name != "config":
        update_config(cfg, yaml.safe_load((REPO / "config" / f"{name}.yaml").read_text()))
    validate(cfg, str(SCHEMAS / "config.schema.yaml"))
    for section, schema in plan.section_schemas(cfg, SCHEMAS).items():
        validate(cfg[section], schema)
    return cfg


@pytest.fixture(autouse=True)
def _in_repo(monkeypatch):
    """Config paths (data/...) are relative to the repository, the workflow's working directory."""
    monkeypatch.chdir(REPO)


@pytest.fixture(scope="module", params=["smoke", "config", "paper"])
def named_config(request):
    return request.param, load_config(request.param)


def job_rows(cfg: dict) -> set:
    """Every run_2pb row the rules consume: isotherms of each main mode and the extended mode,
    dt study, sensitivity and its baseline, units question, last cycle and diagnosis inputs."""
    rows = set()
    for mode in [*cfg["campaign"]["modes"], "extended"]:
        rows |= set(plan.mode_rows(cfg, mode))
    if "paper" in cfg["campaign"]["modes"]:
        rows |= set(plan.dt_study_files(cfg, "csv"))
        rows |= set(plan.sensitivity_rows(cfg)) | set(plan.sensitivity_baseline(cfg))
        rows |= set(plan.units_rows(cfg, "Pa")) | set(plan.units_rows(cfg, "kPa"))
        rows |= set(plan.units_rows(cfg, "kPa", nobreak=True))
        rows.add(plan.last_cycle_record(cfg).replace(".h5", ".csv"))
    rows |= {p for p in plan.diagnosis_input_files(cfg) if p.startswith("results/sim/")}
    return rows


JOBS_PER_MODE = {
    "smoke": {
        "dt_study": 2,
        "extended": 1,
        "measured": 1,
        "paper": 2,
        "sensitivity": 8,
        "units_kPa": 1,
        "units_kPa_nobreak": 1,
    },
    "config": {
        "dt_study": 4,
        "extended": 30,
        "measured": 60,
        "paper": 60,
        "sensitivity": 24,
        "units_kPa": 3,
        "units_kPa_nobreak": 3,
    },
    "paper": {
        "dt_study": 16,
        "extended": 120,
        "measured": 120,
        "paper": 120,
        "paper_kPa": 120,
        "sensitivity": 160,
        "units_kPa": 20,
        "units_kPa_nobreak": 20,
    },
}


def test_jobs_per_mode(named_config):
    name, cfg = named_config
    rows = job_rows(cfg)
    assert Counter(r.split("/")[2] for r in rows) == JOBS_PER_MODE[name]
    # every row is a case name the CLI options can be built from
    for r in rows:
        _, _, mode, sample, case = r[: -len(".csv")].split("/")
        assert plan.case_options(cfg, mode, sample, case).startswith("--temperature ")


def test_case_names_round_trip():
    assert plan.case_name(-10, 0.1) == "-10C_0.1Hz"
    assert plan.case_name(15.0, 40, "_dt" + plan.number(2e-4)) == "15C_40Hz_dt0.0002"
    assert plan.parse_case("15C_40Hz_dt5e-05") == {"T": "15", "f": "40", "dt": "5e-05", "p": None, "x": None}
    assert plan.parse_case("20C_10Hz_eta_mx0.5") == {"T": "20", "f": "10", "dt": None, "p": "eta_m", "x": "0.5"}
    for bad in ("15C_40Hz_nux2", "40Hz", "15C_40Hz_dt"):
        with pytest.raises(InputError, match="bad campaign case name"):
            plan.parse_case(bad)


def test_case_options_of_known_cases():
    cfg = load_config("smoke")
    # the case name gives temperature, frequency and a dt or factor; the run's config the rest
    assert plan.case_options(cfg, "extended", "s1", "21C_10Hz") == "--temperature 21 --frequency 10"
    assert plan.case_options(cfg, "sensitivity", "s1", "20C_40Hz_eta_kx0.5") == (
        "--temperature 20 --frequency 40 --factor eta_k=0.5"
    )
    assert (
        plan.case_options(cfg, "dt_study", "s1", "15C_40Hz_dt0.0002") == "--temperature 15 --frequency 40 --dt 0.0002"
    )
    # the smoke schedule's one cell is its coldest and warmest, lowest and highest: a verification job
    assert plan.job_values(cfg, "extended", "s1", "21C_10Hz") == {"verify": True}
    assert plan.job_values(cfg, "measured", "s1", "21C_10Hz") == {"table3_units": None, "verify": True}
    off = copy.deepcopy(cfg)
    off["campaign"]["verification"] = None
    assert plan.job_values(off, "measured", "s1", "21C_10Hz") == {"table3_units": None, "verify": False}
    paper = load_config("paper")
    ends = [
        (T, f)
        for T in paper["campaign"]["paper"]["temperatures_C"]
        for f in paper["campaign"]["paper"]["frequencies_Hz"]
        if modes.is_verification(paper, "paper_kPa", T, f)
    ]
    assert ends == [(-10, 3), (-10, 40), (30, 3), (30, 40)]
    assert not modes.is_verification(paper, "sensitivity", -10, 3)
    # a study job (factor, dt) never verifies; its Table 3 reading is the paper mode's or its own
    assert plan.job_values(paper, "sensitivity", "s1", "-10C_3Hz_eta_kx0.5") == {"table3_units": "Pa"}
    assert plan.job_values(paper, "dt_study", "s1", "15C_3Hz_dt0.0002") == {"table3_units": "Pa"}
    assert plan.job_values(paper, "units_kPa_nobreak", "s1", "20C_40Hz") == {"table3_units": "kPa", "verify": False}
    assert plan.job_values(paper, "paper_kPa", "s1", "-10C_40Hz") == {"table3_units": "kPa", "verify": True}
    assert plan.job_transfer(off, "extended", "s1") == ["results/harmonic/transfer/s1.json"]
    off["campaign"]["extended"]["transfer_correction"] = False
    assert plan.job_transfer(off, "extended", "s1") == []
    assert plan.job_transfer(cfg, "extended", "s2") == ["results/harmonic/transfer/s2.json"]
    assert plan.job_transfer(cfg, "measured", "s1") == []
    # the same through the rule's params function of the wildcards
    fn = plan.from_wildcards(plan.case_options, cfg)
    assert fn(SimpleNamespace(mode="dt_study", sample="s1", case="15C_40Hz_dt0.0002")) == (
        "--temperature 15 --frequency 40 --dt 0.0002"
    )
    # an input given as an option only when the job has it, shell-quoted
    opt = plan.input_options(transfer="--network-factor-json", test="--test")
    assert opt(None, SimpleNamespace(transfer=["t/s1.json"], test=[])) == "--network-factor-json t/s1.json"
    assert (
        opt(None, SimpleNamespace(transfer="a b.json", test=["x.json"]))
        == "--network-factor-json 'a b.json' --test x.json"
    )
    assert opt(None, SimpleNamespace()) == ""


def test_mode_laws_and_options():
    cfg = load_config("config")
    assert plan.mode_parameters(cfg, "measured") == "results/calibration/burgers_parameters.csv"
    assert plan.mode_parameters(cfg, "extended") == plan.LAW_JSON
    assert plan.mode_parameters(cfg, "units_kPa") == cfg["calibration"]["table3"] == "data/paper/table3_burgers.csv"
    assert plan.law_option(cfg, "extended") == "--law-json" and plan.law_option(cfg, "paper") == "--parameters"
    assert plan.mode_summary(cfg, "extended") == [plan.MEASURED_SUMMARY] and plan.mode_summary(cfg, "paper") == []
    assert (
        plan.mode_paper_table4(cfg, "paper_kPa") == [plan.PAPER_TABLE4]
        and plan.mode_paper_table4(cfg, "measured") == []
    )
    assert Path(plan.PAPER_TABLE4).is_file()
    title = "NSCD vs Table 3 Burger's read in Pa (paper mode)"
    assert plan.isotherm_settings(cfg, "paper") == {"table3_units": "Pa", "title": title}
    assert plan.isotherm_settings(cfg, "paper_kPa") == {
        "table3_units": "kPa",
        "title": "NSCD vs Table 3 Burger's read in kPa (paper_kPa mode)",
    }
    assert plan.isotherm_settings(cfg, "extended") == {"title": "NSCD vs measured (extended mode)"}
    assert plan.isotherm_settings(cfg, "measured") == {
        "table3_units": None,
        "title": "NSCD vs measured (measured mode)",
    }
    # the reading modes: the paper schedule, their own reading and overrides
    assert plan.job_values(cfg, "paper_kPa", "s1", "15C_40Hz") == {"table3_units": "kPa", "verify": False}
    assert modes.schedule(cfg, "paper_kPa") == modes.schedule(cfg, "paper")
    both = copy.deepcopy(cfg)
    both["campaign"]["paper_kPa"] = {"yield_stress_Pa": None, "linear_solver": "direct"}
    kpa = plan.mode_settings(both, "paper_kPa")
    pa = plan.mode_settings(both, "paper")
    assert kpa["yield_stress_Pa"] is None and kpa["linear_solver"] == "direct"
    assert {k: v for k, v in kpa.items() if k not in ("yield_stress_Pa", "linear_solver")} == {
        k: v for k, v in pa.items() if k not in ("yield_stress_Pa", "linear_solver")
    }
    # dt-policy check: the reading, upper median temperature and the schedule's frequencies
    assert plan.policy_settings(cfg, "paper") == {
        "table3_units": "Pa",
        "temperature": 15.0,
        "frequencies": [3.0, 6.0, 10.0, 25.0, 40.0],
    }
    assert plan.policy_settings(cfg, "measured") == {
        "table3_units": None,
        "temperature": 21.0,
        "frequencies": [0.1, 0.5, 1.0, 5.0, 10.0, 25.0],
    }
    assert plan.policy_settings(cfg, "paper_Pa")["table3_units"] == "Pa"
    settings = plan.mode_settings(cfg, "extended")
    assert settings["bond_kinematics"] == cfg["nscd"]["bond_kinematics"] and settings["start"] in ("rest", "periodic")
    wc = SimpleNamespace(mode="paper")
    assert plan.from_wildcards(plan.mode_rows, cfg)(wc) == plan.mode_rows(cfg, "paper")
    assert plan.from_wildcards(plan.mode_settings, cfg)(wc) == plan.mode_settings(cfg, "paper")
    assert plan.from_wildcards(plan.policy_settings, cfg)(wc)["temperature"] == 15
    assert plan.from_wildcards(plan.mode_parameters, cfg)(wc) == "data/paper/table3_burgers.csv"


def test_mode_rows_and_samples():
    cfg = load_config("config")
    assert plan.sample_names(cfg) == ["s1", "s2", "s3", "s4"]
    assert plan.mode_samples(cfg, "paper") == ["s1", "s2"] and plan.mode_samples(cfg, "extended") == ["s1"]
    rows = plan.mode_rows(cfg, "extended")
    assert rows[0] == "results/sim/extended/s1/-10C_0.1Hz.csv" and len(rows) == 30
    # the extended mode runs the measured schedule
    assert [r.replace("extended", "measured") for r in rows] == plan.mode_rows(cfg, "measured", ["s1"])
    assert plan.last_cycle_record(cfg).startswith("results/sim/paper/s1/")
    assert plan.sensitivity_figures()[0] == "results/campaign/paper/figures/fig11_sensitivity_Em.png"
    paper = load_config("paper")
    assert plan.campaign_samples(paper, None) == ["s1", "s2", "s3", "s4"]
    assert plan.campaign_samples(paper, 2) == ["s1", "s2"]


def test_diagnosis_inputs_with_auto_settings():
    cfg = load_config("smoke")
    assert plan.diagnosis_inputs(cfg) == {
        "simulated": ["results/sim/measured/s1/21C_10Hz.csv"],
        "harmonic": ["results/harmonic/jobs/s1_measured.csv"],
        "time_integration": ["results/campaign/measured/dt_policy_phase_error.csv"],
        "simulated_extended": ["results/sim/extended/s1/21C_10Hz.csv"],
        "transfer": ["results/harmonic/transfer/s1.json"],
    }
    opts = plan.input_options(**plan.DIAGNOSIS_INPUT_OPTIONS)(None, SimpleNamespace(**plan.diagnosis_inputs(cfg)))
    assert plan.diagnosis_input_function(cfg)(None) == plan.diagnosis_inputs(cfg)
    search = {
        "alpha": 0.001,
        "shift": "wlf",
        "t_ref": None,
        "identifiability_null": 0.995,
        "identifiability_rival": 0.95,
    }
    assert plan.diagnosis_settings(cfg, "search") == search
    law = plan.diagnosis_settings(cfg, "search", "law")
    assert {k: law[k] for k in search} == search
    assert law["law_shifts"] == ["wlf"] and law["law_statics"] == ["constant", "trend"]
    assert opts == (
        "--simulated results/sim/measured/s1/21C_10Hz.csv --harmonic results/harmonic/jobs/s1_measured.csv"
        " --time-integration results/campaign/measured/dt_policy_phase_error.csv"
        " --simulated-extended results/sim/extended/s1/21C_10Hz.csv --transfer results/harmonic/transfer/s1.json"
    )
    assert plan.diagnosis_settings(cfg, "causes") == {
        "tolerance_network_factor": 0.01,
        "tolerance_phase_deg": 0.1,
        "theta": 0.5,
    }
    # null leaves an input out, a path is used as is
    other = copy.deepcopy(cfg)
    other["diagnosis"]["harmonic"] = None
    other["diagnosis"]["time_integration"] = None
    other["diagnosis"]["simulated"] = "data/my_rows.csv"
    inputs = plan.diagnosis_inputs(other)
    assert "harmonic" not in inputs and inputs["simulated"] == ["data/my_rows.csv"]
    assert plan.diagnosis_input_files(other)[0] == "data/my_rows.csv"
    with pytest.raises(InputError, match="unknown simulation input"):
        plan.diagnosis_auto_input(cfg, "nope")
    # the default config: the extended mode's sample (n_samples 1) before and after
    full = load_config("config")
    assert len(plan.diagnosis_inputs(full)["simulated"]) == 30
    assert plan.diagnosis_inputs(full)["transfer"] == ["results/harmonic/transfer/s1.json"]
    fit = plan.diagnosis_settings(full, "law")
    assert fit["law_verticals"] == ["off", "on"] and fit["law_refines"] == ["off", "1.0"]
    assert fit["law_per_decades"] == [2.0, 4.0] and fit["card_fit"] == "least_squares"


def test_crossval_time_domain_cell(tmp_path):
    cfg = load_config("smoke")
    # auto: median tested temperature (lower middle) and its frequency nearest 10 Hz
    assert plan.crossval_time_domain_cell(cfg) == {"temperature_C": 21.0, "frequency_Hz": 10.0}
    assert plan.crossval_time_domain_case(cfg) == "21C_10Hz"
    assert plan.crossval_time_domain_row(cfg) == "results/diagnosis/crossval/time_domain_21C_10Hz.csv"
    assert plan.crossval_time_domain_input(cfg, "lofo") == [plan.crossval_time_domain_row(cfg)]
    assert plan.crossval_time_domain_input(cfg, "loto") == []
    assert plan.from_wildcards(plan.crossval_time_domain_input, cfg)(SimpleNamespace(scheme="loto")) == []
    assert plan.crossval_sample(cfg) == "s1"
    table = tmp_path / "t.csv"
    table.write_text(
        "specimen,temperature_C,frequency_Hz,E_norm_MPa,phase_deg\n"
        + "".join(
            f"S1,{T},{f},1000,20\n" for T, f in ((-5, 1), (-5, 30), (10, 3), (10, 20), (30, 8), (30, 15), (40, 1))
        )
    )
    other = copy.deepcopy(cfg)
    other["measured"]["table"] = str(table)
    assert plan.crossval_time_domain_cell(other) == {"temperature_C": 10.0, "frequency_Hz": 20.0}
    other["diagnosis"]["crossval"]["time_domain"] = {"temperature_C": 30, "frequency_Hz": 8}
    assert plan.crossval_time_domain_case(other) == "30C_8Hz"
    other["diagnosis"]["crossval"]["time_domain"] = {"temperature_C": 30, "frequency_Hz": 9}
    with pytest.raises(InputError, match="is not a measured cell of"):
        plan.crossval_time_domain_cell(other)
    other["diagnosis"]["crossval"]["time_domain"] = None
    assert plan.crossval_time_domain_cell(other) is None and plan.crossval_time_domain_case(other) is None
    assert plan.crossval_time_domain_input(other, "lofo") == []
    other["diagnosis"]["crossval"]["time_domain"] = "auto"
    other["measured"]["table"] = str(tmp_path / "missing.csv")
    with pytest.raises(InputError, match="missing.csv"):
        plan.crossval_time_domain_cell(other)


def workflow_report_files(name: str) -> list:
    """plan.report_files of the workflow's own rules under config/{name}.yaml: a dry run of a
    Snakefile that includes the project's and writes the list once every rule file is read."""
    import json
    import subprocess
    import sys
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "report_files.json"
        snakefile = Path(tmp) / "Snakefile"
        snakefile.write_text(
            f'include: "{REPO / "Snakefile"}"\n'
            "import json as _json\n"
            f'_json.dump(plan.report_files(workflow.rules, config), open("{out}", "w"))\n'
        )
        proc = subprocess.run(
            [sys.executable, "-m", "snakemake", "-s", str(snakefile), "-d", str(REPO), "-n", "--quiet", "all"]
            + ["--configfile", str(REPO / "config" / f"{name}.yaml"), "--nolock"],
            capture_output=True,
            text=True,
            cwd=REPO,
        )
        assert proc.returncode == 0 and out.exists(), proc.stderr[-2000:]
        return json.loads(out.read_text())


@pytest.fixture(scope="module", params=["smoke", "config", "paper"])
def named_report_files(request):
    return request.param, load_config(request.param), workflow_report_files(request.param)


def test_the_report_is_every_output_the_rules_flag(named_report_files):
    name, cfg, files = named_report_files
    # one sample in the smoke run, four in the others; paper adds the paper_kPa mode's four
    assert len(files) == len(set(files)) == {"smoke": 103, "config": 109, "paper": 113}[name]
    assert all(f.startswith("results/") and "{" not in f for f in files)
    # in the order of the rule files: the lab data first, the figures' rule file last
    assert files[:2] == ["results/lab/measured.csv", "results/lab/measured_summary.csv"]
    assert files[-1] == plan.MATERIAL_CARD_FIGURES["terms_curve"]
    for expected in (
        "results/campaign/paper/figures/fig14_sensitivity_eta_k.png",
        "results/campaign/extended/table4_extended.csv",
        plan.DIAGNOSIS_PAGE,
        *(f"results/bench/prepare_{s}.json" for s in plan.sample_names(cfg)),
        *plan.MATERIAL_CARDS.values(),
        *plan.crossval_files(cfg, "_summary.csv"),
        *(f"results/samples/{s}_stages.png" for s in plan.sample_names(cfg)),
        *(f"results/campaign/{m}/dt_policy_phase_error.csv" for m in cfg["campaign"]["modes"]),
    ):
        assert expected in files, expected


class _Out(str):
    """An output of a fake rule: a path with Snakemake's flags."""

    def __new__(cls, path, report=False):
        out = super().__new__(cls, path)
        out.flags = {"report": True} if report else {}
        return out


def _rule(name, *outputs):
    return SimpleNamespace(name=name, output=list(outputs))


def test_report_files_expand_the_flagged_outputs_with_the_rules_wildcards():
    cfg = load_config("config")
    rules = [
        _rule("measured_table", _Out("results/lab/measured.csv", report=True), _Out("results/lab/x.json")),
        _rule("crossval", _Out("results/diagnosis/crossval/{scheme,lofo|loto|loso}.png", report=True)),
        _rule("campaign_sensitivity", _Out("results/campaign/paper/sensitivity.csv", report=True)),
    ]
    files = plan.report_files(rules, cfg)
    schemes = cfg["diagnosis"]["crossval"]["schemes"]
    assert files == ["results/lab/measured.csv", *(f"results/diagnosis/crossval/{s}.png" for s in schemes)] + [
        "results/campaign/paper/sensitivity.csv"
    ]
    # the paper mode's studies report nothing when the campaign has no paper mode
    no_paper = copy.deepcopy(cfg)
    no_paper["campaign"]["modes"] = ["measured"]
    assert "results/campaign/paper/sensitivity.csv" not in plan.report_files(rules, no_paper)
    # a flagged output whose wildcards have no values is refused, naming the rule
    with pytest.raises(InputError, match="rule new_rule: report output"):
        plan.report_files([_rule("new_rule", _Out("results/{thing}.csv", report=True))], cfg)


def test_lab_inputs(tmp_path):
    cfg = load_config("smoke")
    table = cfg["measured"]["table"]
    assert plan.measured_test(cfg) == str(Path(table).with_name(Path(table).stem + ".test.json"))
    assert plan.measured_test_input(cfg) == (
        [plan.measured_test(cfg)] if Path(plan.measured_test(cfg)).is_file() else []
    )
    other = copy.deepcopy(cfg)
    other["measured"]["table"] = str(tmp_path / "m.csv")
    other["measured"]["test"] = None
    assert plan.measured_test(other) == str(tmp_path / "m.test.json") and plan.measured_test_input(other) == []
    other["measured"]["test"] = "given.json"
    assert plan.measured_test_input(other) == ["given.json"]
    other["lab"]["records"] = ["data/lab/r1.csv", "data/lab/r2.csv"]
    assert plan.lab_records(other) == {"r1": "data/lab/r1.csv", "r2": "data/lab/r2.csv"}
    assert plan.from_wildcards(plan.record_meta, other)(SimpleNamespace(record="r2")) == "data/lab/r2.json"
    assert plan.from_wildcards(plan.record_file, other)(SimpleNamespace(record="r1")) == "data/lab/r1.csv"
    with pytest.raises(InputError, match="r3"):
        plan.record_file(other, "r3")


def test_settings_and_options_of_other_rules():
    cfg = load_config("smoke")
    settings = plan.sample_settings(cfg)
    assert "seeds" not in settings["sample"] and settings["sample"]["scale"] == cfg["sample"]["scale"]
    assert settings["bonded_contact"] == cfg["nscd"]["bonded_contact"]
    assert plan.sample_file("s3") == "results/samples/s3.h5"
    assert plan.rig_state_file("s2") == "results/campaign/rig/s2.h5"
    assert plan.rig_state_settings(cfg) == {
        "bond_kinematics": cfg["nscd"]["bond_kinematics"],
        "head_rotation": cfg["campaign"]["test"]["head_rotation"],
        "nu": cfg["campaign"]["test"]["nu"],
        "gravity": cfg["campaign"]["test"]["gravity"],
        "mechanisms": cfg["campaign"]["test"]["mechanisms"],
    }
    assert plan.command_settings(cfg, "fit") == {
        "model": "burgers",
        "weight_log_modulus": cfg["calibration"]["weight_log_modulus"],
        "weight_phase": cfg["calibration"]["weight_phase"],
        "n_starts": cfg["calibration"]["n_starts"],
    }
    bench = cfg["nscd"]["bench"]
    assert plan.nscd_bench_files(cfg) == [f"results/bench/nscd_bonded_n{n}.json" for n in bench["bonded_n"]] + [
        f"results/bench/nscd_granular_n{n}.json" for n in bench["granular_n"]
    ]
    granular = plan.from_wildcards(plan.bench_settings, cfg)(SimpleNamespace(case="granular"))
    assert granular["tolerance"] == bench["granular_tolerance"] and granular["steps"] == bench["steps"]
    assert plan.bench_settings(cfg, "bonded")["tolerance"] == bench["tolerance"]
    assert plan.bench_settings(cfg, "bonded")["bonded_contact"] == plan.bonded_contact(cfg)
    assert plan.number(40.0) == "40" and plan.number("1e-05") == "1e-05"
    # harmonic solver: the paper's frequencies or the lab summary's
    fn = plan.harmonic_frequency_option
    assert fn(SimpleNamespace(mode="paper"), None) == "--grid paper"
    assert fn(SimpleNamespace(mode="measured"), SimpleNamespace(summary="s.csv")) == "--frequencies-from s.csv"
    harm = cfg["harmonic"]
    jobs = plan.harmonic_job_settings(cfg, "paper")
    assert jobs["frequency"] == [3.0, 6.0, 10.0, 25.0, 40.0] and jobs["inertia"] == harm["inertia"]
    assert "frequency" not in plan.harmonic_job_settings(cfg, "measured")
    sweep = plan.command_settings(cfg, "harmonic", grid="sweep")["sweep"]
    assert sweep == [harm["sweep"]["fmin_Hz"], harm["sweep"]["fmax_Hz"], harm["sweep"]["points"]]
    assert (
        plan.from_wildcards(plan.harmonic_parameters, cfg)(SimpleNamespace(mode="measured"))
        == plan.HARMONIC_PARAMETERS["measured"]
    )
    # the commands that check or correct the time-domain test take its kinematics
    transfer = plan.command_settings(cfg, "harmonic-transfer")
    assert transfer == {
        "bond_kinematics": cfg["nscd"]["bond_kinematics"],
        "head_rotation": cfg["campaign"]["test"]["head_rotation"],
        "nu": cfg["campaign"]["test"]["nu"],
    }
    levels = plan.command_settings(cfg, "harmonic-resolution")["levels"]
    assert levels == [level for level, _ in plan.resolution_samples(cfg)]


def test_environment_and_schemas(tmp_path):
    env = plan.job_environment("/opt/venv/bin/python", str(tmp_path), "/usr/bin", str(tmp_path / "run"))
    assert env["PATH"].split(":") == ["/opt/venv/bin", "/usr/bin"]
    assert env["ASPHALT_NSCD_SOURCE"] == str(tmp_path.resolve())
    assert env["ASPHALT_NSCD_CPU_LOG"] == str(tmp_path.resolve() / "run" / "benchmarks" / "process_cpu.jsonl")
    cfg = load_config("smoke")
    schemas = plan.section_schemas(cfg, SCHEMAS)
    assert {"campaign", "diagnosis", "harmonic", "sample"} <= set(schemas)
    assert all(Path(p).is_file() for p in schemas.values())


def test_jobs_get_one_library_thread_unless_the_user_sets_a_count():
    assert plan.thread_environment({}) == {v: "1" for v in plan.LIBRARY_THREAD_VARIABLES}
    assert set(plan.LIBRARY_THREAD_VARIABLES) == {"OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"}
    # a count the user set is kept; an empty value counts as unset
    assert plan.thread_environment({"OMP_NUM_THREADS": "4", "MKL_NUM_THREADS": ""}) == {
        "OPENBLAS_NUM_THREADS": "1",
        "MKL_NUM_THREADS": "1",
    }
    # the Snakefile sets them in the environment its jobs inherit, before any job starts
    text = (Path(__file__).resolve().parents[2] / "Snakefile").read_text()
    assert "os.environ.update(plan.thread_environment(os.environ))" in text
    assert text.index("thread_environment") < text.index("include:")


def test_byte_compile_writes_the_byte_code_once(tmp_path):
    import importlib.util

    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "a.py").write_text("X = 1\n")
    (pkg / "sub" / "b.py").write_text("Y = 2\n")
    assert plan.byte_compile(pkg)
    for src in (pkg / "a.py", pkg / "sub" / "b.py"):
        assert Path(importlib.util.cache_from_source(str(src))).is_file()
    first = Path(importlib.util.cache_from_source(str(pkg / "a.py"))).stat().st_mtime_ns
    assert plan.byte_compile(pkg)  # up to date: nothing rewritten
    assert Path(importlib.util.cache_from_source(str(pkg / "a.py"))).stat().st_mtime_ns == first
    pkg.chmod(0o500)
    try:
        writable = os.access(pkg, os.W_OK)  # root writes anyway
        assert plan.byte_compile(pkg) is writable
    finally:
        pkg.chmod(0o700)


def test_every_public_function_is_documented():
    functions = [
        f
        for name, f in inspect.getmembers(plan, inspect.isfunction)
        if not name.startswith("_") and f.__module__ == plan.__name__
    ]
    assert len(functions) > 50
    undocumented = [f.__name__ for f in functions if not inspect.getdoc(f)]
    assert not undocumented


def test_each_mode_runs_its_configured_linear_solver(named_config):
    """The 2PB jobs get the core's linear solver (nscd.linear_solver) unless their schedule sets
    its own: the measured and extended modes run the direct solver in every shipped config."""
    _, cfg = named_config
    settings = {m: plan.mode_settings(cfg, m) for m in ("paper", "measured", "extended", "dt_study")}
    assert settings["measured"]["linear_solver"] == settings["extended"]["linear_solver"] == "direct"
    expected = cfg["campaign"]["paper"].get("linear_solver", cfg["nscd"]["linear_solver"])
    assert settings["paper"]["linear_solver"] == settings["dt_study"]["linear_solver"] == expected


def test_former_resource_keys_are_rejected_with_their_new_place(named_config):
    _, cfg = named_config
    plan.reject_resource_keys(cfg)  # the repository's configs hold no resource
    for key, value in (("campaign.job_runtime_min", 30), ("harmonic.compare.runtime_min", 30), ("nscd.threads", 1)):
        old = copy.deepcopy(cfg)
        node = old
        *parents, leaf = key.split(".")
        for part in parents:
            node = node[part]
        node[leaf] = value
        with pytest.raises(InputError, match=rf"{key}.*profiles/default/config.yaml"):
            plan.reject_resource_keys(old)


@pytest.mark.parametrize("overlay", sorted(p.stem for p in (REPO / "config").glob("*.yaml") if p.stem != "config"))
def test_every_shipped_overlay_passes_the_schemas_and_the_value_checks(overlay):
    """Each overlay of config/ (merged on config/config.yaml as Snakemake merges it) is accepted."""
    plan.check_values(load_config(overlay))


def test_config_values_no_schema_expresses_are_checked(named_config):
    _, cfg = named_config
    plan.check_values(cfg)  # the repository's configs pass
    dem = cfg["forecast"].get("dem") or {}
    bad = copy.deepcopy(cfg)
    bad["forecast"]["dem"] = {**dem, "variants": [{"cut_mm": 6.3, "size_dmax": 2.0}, {"cut_mm": 6.3, "size_dmax": 2.0}]}
    with pytest.raises(InputError, match=r"forecast\.dem\.variants\[1\]: cut6\.3_x2 repeats"):
        plan.check_values(bad)
    bad["forecast"]["dem"]["variants"] = [{"cut_mm": 6.3}]
    with pytest.raises(InputError, match=r"forecast\.dem\.variants\[0\]: expected"):
        plan.check_values(bad)
    bad["forecast"]["dem"]["variants"] = [{"cut_mm": dem.get("cut_mm", 4.0), "size_dmax": dem.get("size_dmax", 2.5)}]
    bad["forecast"]["dem"].setdefault("cut_mm", 4.0)
    bad["forecast"]["dem"].setdefault("size_dmax", 2.5)
    with pytest.raises(InputError, match=r"repeats the base sample"):
        plan.check_values(bad)


def test_bench_family_schema_lists_every_truth_family():
    """The config schema accepts exactly the truth families the detection benchmark knows."""
    import yaml

    from asphalt_nscd.diagnosis import synthetic

    schema = yaml.safe_load((SCHEMAS / "diagnosis.schema.yaml").read_text())
    enum = schema["properties"]["bench"]["properties"]["families"]["items"]["enum"]
    assert sorted(enum) == sorted(synthetic.FAMILIES)


def test_from_wildcards_takes_the_parameters_without_default():
    """One helper makes every input or params function of the rules: the parameters of the
    plain function after ``config`` that have no default are the job's wildcards."""
    cfg = load_config("config")
    rows = plan.from_wildcards(plan.mode_rows, cfg)  # mode_rows(config, mode, samples=None)
    assert rows(SimpleNamespace(mode="measured", samples=["s9"])) == plan.mode_rows(cfg, "measured")
    assert inspect.getdoc(rows) == "mode_rows(config, mode) of a job's wildcards"
    transfer = plan.from_wildcards(plan.job_transfer, cfg)
    assert transfer(SimpleNamespace(sample="s2", mode="extended")) == [plan.transfer_file("s2")]


def test_shared_result_files_are_named_once():
    cfg = load_config("config")
    assert plan.CALIBRATION_TABLE.format(table="paper_table3") == plan.PAPER_TABLE3 == plan.HARMONIC_PARAMETERS["paper"]
    assert plan.mode_parameters(cfg, "measured") == plan.BURGERS_PARAMETERS == plan.HARMONIC_PARAMETERS["measured"]
    assert plan.diagnosis_auto_input(cfg, "harmonic")[0] == plan.harmonic_job_file("s1", "measured")
    assert plan.crossval_files(cfg, "_summary.csv") == [
        plan.crossval_file(s, "_summary.csv") for s in cfg["diagnosis"]["crossval"]["schemes"]
    ]


def test_own_table_folder_is_named_by_the_tables_folder_and_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg = {"measured": {"table": "data/measured/uiuc_fdmix1_utm/complex_modulus.csv"}}
    assert plan.own_table_dir(cfg) == "results/tables/uiuc_fdmix1_utm-complex_modulus"
    assert (
        plan.own_table_dir({"measured": {"table": "my lab \u00ef/m\u00efx (ksi).csv"}})
        == "results/tables/my lab \u00ef-m\u00efx (ksi)"
    )
    assert plan.own_table_dir({"measured": {"table": "mix.csv"}}) == "results/tables/mix"


def test_console_messages_of_this_run_once_each_and_both_kinds_printed_on_error(tmp_path):
    """The project's errors and warnings of the rule logs written since the run started, each
    once; older logs are not repeated. The Snakefile prints warnings on failure too (a warning,
    e.g. phases that look like radians, is often the cause of the failure)."""
    import os
    import re
    import time

    old = tmp_path / "lab" / "old.log"
    old.parent.mkdir()
    old.write_text("error: from an earlier run\n")
    os.utime(old, (time.time() - 100, time.time() - 100))
    new = tmp_path / "diagnosis" / "extend_law.log"
    new.parent.mkdir()
    new.write_text(
        "2026 asphalt_nscd WARNING: the phases look like radians\n"
        "2026 asphalt_nscd WARNING: the phases look like radians\n"
        "error: t.csv: line 3, column 'phase_deg': value nan\nTraceback ignored\n"
    )
    start = time.time() - 10
    assert plan.console_messages(start, "warning", str(tmp_path)) == [f"{new}: the phases look like radians"]
    assert plan.console_messages(start, "error", str(tmp_path)) == [
        f"{new}: error: t.csv: line 3, column 'phase_deg': value nan"
    ]
    snakefile = (Path(__file__).resolve().parents[2] / "Snakefile").read_text()
    onerror = re.search(r"^onerror:\n((?:    .*\n)+)", snakefile, re.M).group(1)
    assert '"warning"' in onerror and '"error"' in onerror and "crash_messages" in onerror


def test_a_command_that_failed_unexpectedly_is_named_with_its_exception_line(tmp_path):
    """A rule log that ends in a Python traceback (the last of chained ones) gives its exception
    line on the console; a log with the project's one-line error, or an older one, gives none."""
    import os
    import time

    old = tmp_path / "old.log"
    old.write_text("Traceback (most recent call last):\n  File x\nKeyError: 'old'\n")
    os.utime(old, (time.time() - 100, time.time() - 100))
    (tmp_path / "forecast").mkdir()
    crashed = tmp_path / "forecast" / "mix.log"
    crashed.write_text(
        "mix 1: packing its sample\n"
        'Traceback (most recent call last):\n  File "a.py", line 1, in <module>\n    f()\nValueError: first\n\n'
        "During handling of the above exception, another exception occurred:\n\n"
        'Traceback (most recent call last):\n  File "b.py", line 216, in extrapolation\n'
        "    if np.isfinite(first[c]):\n"
        "TypeError: ufunc 'isfinite' not supported for the input types\n"
    )
    (tmp_path / "refused.log").write_text("error: mix.yaml: key 'volumetrics.Va': expected a number\n")
    start = time.time() - 10
    assert plan.crash_messages(start, str(tmp_path)) == [
        f"{crashed}: failed unexpectedly: TypeError: ufunc 'isfinite' not supported for the input types "
        "(the traceback is in the log)"
    ]
    assert plan.crash_messages(start, str(tmp_path / "absent")) == []


def test_a_forecast_sample_folder_names_its_variant_and_its_settings(tmp_path):
    """The base folder is the configured sample, a variants/<name> folder the listed variant; an
    unlisted one is refused; the responses cover every mix on every sample; the params functions
    read the job's folder."""
    import re

    from asphalt_nscd.io import InputError

    dem = {"models": ["dem"], "cut_mm": 4.0, "size_dmax": 2.5, "layer_over_side": 1.3}
    config = {"forecast": {"dem": {**dem, "variants": [{"cut_mm": 6.3, "size_dmax": 2.5}]}}, "sample": {"seeds": [1]}}
    variant = f"{plan.FORECAST}/variants/cut6.3_x2.5"
    assert plan.forecast_variant(config, plan.FORECAST) == {"name": "", "cut_mm": 4.0, "size_dmax": 2.5}
    assert plan.forecast_variant(config, variant) == {"name": "cut6.3_x2.5", "cut_mm": 6.3, "size_dmax": 2.5}
    with pytest.raises(InputError, match="cut2_x2"):
        plan.forecast_variant(config, f"{plan.FORECAST}/variants/cut2_x2")
    for where in (plan.FORECAST, variant):
        assert re.fullmatch(plan.forecast_where(config), where)
    assert not re.fullmatch(plan.forecast_where(config), "results/other")
    assert plan.forecast_sample_param(config)(SimpleNamespace(where=variant))["dem"]["cut_mm"] == 6.3
    assert plan.forecast_variant_param(config)(SimpleNamespace(where=plan.FORECAST)) == ""
    matched = tmp_path / "matched.csv"
    matched.write_text("mix_id,x\n193,1\n193,2\n211,1\n")
    assert plan.forecast_responses(config, matched) == [
        f"{plan.FORECAST}/responses/193_s1.npz",
        f"{plan.FORECAST}/responses/211_s1.npz",
        f"{variant}/responses/193_s1.npz",
        f"{variant}/responses/211_s1.npz",
    ]


def test_a_tables_forecast_works_in_its_own_folder(tmp_path):
    """make forecast TABLE=... (the overlay of forecast-config) moves the whole chain, its matched table,
    samples of every variant and responses, into <the table's published folder>.work/forecast: make run's
    results/forecast (and the models a mix file is forecast with) stay as they are; the chain's settings
    param does not change with the folder (no rerun of make run's chain); an unset folder is make run's."""
    import re

    import yaml

    from asphalt_nscd.cli import main

    table = tmp_path / "lab dép" / "mixes.tsv"
    table.parent.mkdir()
    table.write_text("mix_id\n")
    overlay = tmp_path / "overlay.yaml"
    assert main(["forecast-config", "--table", str(table), "-o", str(overlay)]) == 0
    section = yaml.safe_load(overlay.read_text())["forecast"]
    root = "results/forecasts/lab dép-mixes.work/forecast"
    assert section == {"table": str(table), "work_dir": root}
    assert plan.forecast_dir({"forecast": section}) == "results/forecasts/lab dép-mixes"
    dem = {"models": ["dem"], "cut_mm": 4.0, "size_dmax": 2.5, "variants": [{"cut_mm": 6.3, "size_dmax": 2.5}]}
    config = {"forecast": {**section, "dem": dem}, "sample": {"seeds": [1]}}
    assert plan.forecast_root(config) == root and plan.forecast_matched(config) == f"{root}/matched.csv"
    assert re.fullmatch(plan.forecast_where(config), f"{root}/variants/cut6.3_x2.5")
    assert not re.fullmatch(plan.forecast_where(config), plan.FORECAST)
    assert plan.forecast_variant(config, root)["name"] == ""
    matched = tmp_path / "matched.csv"
    matched.write_text("mix_id,x\n193,1\n")
    assert plan.forecast_responses(config, matched) == [
        f"{root}/responses/193_s1.npz",
        f"{root}/variants/cut6.3_x2.5/responses/193_s1.npz",
    ]
    files = SimpleNamespace(files=[f"{root}/matched.csv", f"{root}/crossval.csv"])
    assert plan.forecast_publish_root(None, files) == "results/forecasts/lab dép-mixes.work"
    assert plan.forecast_publish_root(None, SimpleNamespace(files=[f"{plan.FORECAST}/matched.csv"])) == "results"
    default = {"forecast": {"table": str(table), "work_dir": None, "dem": dem}, "sample": {"seeds": [1]}}
    assert plan.forecast_root(default) == plan.FORECAST
    assert plan.forecast_settings(config) == plan.forecast_settings(default)
