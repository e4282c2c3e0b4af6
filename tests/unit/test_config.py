"""One complete configuration (config/config.yaml) and overlays merged over it.

The package's merge (asphalt_nscd.config) equals Snakemake's (snakemake.utils.update_config) on
the repository's overlays and on random nested configs; the overlays hold only the keys they
change; every merged configuration passes the workflow's schemas; and the defaults written in
the code (sample settings, options of the extended law, schema defaults) agree with
config/config.yaml."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from asphalt_nscd import config
from asphalt_nscd.io import InputError

REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / "config"
SCHEMAS = REPO / "workflow" / "schemas"
OVERLAYS = ("paper", "smoke", "table")


def raw(name: str) -> dict:
    return yaml.safe_load((CONFIG / f"{name}.yaml").read_text())


def snakemake_config(*names: str) -> dict:
    """The config Snakemake builds from ``--configfile config/{names}.yaml`` (the Snakefile's
    configfile config/config.yaml first)."""
    from snakemake.utils import update_config

    cfg = raw("config")
    for name in names:
        update_config(cfg, raw(name))
    return cfg


def leaves(d: dict, prefix: str = "") -> dict:
    """Dotted key -> value of every non-mapping value of a nested mapping."""
    out = {}
    for key, value in d.items():
        if isinstance(value, dict):
            out.update(leaves(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


@pytest.fixture
def in_repo(monkeypatch):
    """Run in the repository root, where config/config.yaml is the default config."""
    monkeypatch.chdir(REPO)


# ---------------------------------------------------------------------------------------------
# the merge


@pytest.mark.parametrize("name", OVERLAYS)
def test_load_equals_snakemake_merge(name, in_repo):
    expected = snakemake_config(name)
    assert config.load([f"config/{name}.yaml"]) == expected
    assert config.load(f"config/{name}.yaml") == expected
    # naming the default first, as `snakemake --configfile config/config.yaml config/table.yaml`
    assert config.load(["config/config.yaml", f"config/{name}.yaml"]) == expected
    # from elsewhere: the default given explicitly
    assert config.load([CONFIG / f"{name}.yaml"], default=CONFIG / "config.yaml") == expected


def test_load_of_several_overlays_in_order(in_repo):
    assert config.load(["config/paper.yaml", "config/table.yaml"]) == snakemake_config("paper", "table")
    assert config.load(["config/smoke.yaml", "config/paper.yaml"]) == snakemake_config("smoke", "paper")


def test_load_without_a_default(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no config/config.yaml here
    assert config.load([CONFIG / "table.yaml"]) == raw("table")
    assert config.load([CONFIG / "table.yaml"], default=None) == raw("table")


_scalars = st.one_of(
    st.none(), st.booleans(), st.integers(-3, 3), st.sampled_from(["a", "b"]), st.lists(st.integers(0, 3), max_size=3)
)
_keys = st.sampled_from(["a", "b", "c", "d"])
_configs = st.recursive(_scalars, lambda children: st.dictionaries(_keys, children, max_size=4), max_leaves=12)


@given(st.dictionaries(_keys, _configs, max_size=4), st.dictionaries(_keys, _configs, max_size=4))
def test_merge_equals_update_config(base, overlay):
    """Any nested configs: mappings merged key by key, lists and values replaced, a mapping over
    a value replaces it; neither argument is modified."""
    from snakemake.utils import update_config

    base0, overlay0 = copy.deepcopy(base), copy.deepcopy(overlay)
    expected = copy.deepcopy(base)
    update_config(expected, copy.deepcopy(overlay))
    assert config.merge(base, overlay) == expected
    assert base == base0 and overlay == overlay0


def test_merge_shares_nothing_with_its_arguments():
    base, overlay = {"a": {"x": [1, 2]}}, {"b": {"y": [3]}}
    out = config.merge(base, overlay)
    out["a"]["x"].append(9)
    out["b"]["y"].append(9)
    assert base == {"a": {"x": [1, 2]}} and overlay == {"b": {"y": [3]}}


@pytest.mark.parametrize(
    "name, text, message",
    [
        ("bad.yaml", "sample: [1, 2\n", "bad.yaml: not valid YAML"),
        ("bad.json", '{"sample": }', "bad.json: not valid JSON"),
        ("list.yaml", "- 1\n- 2\n", "list.yaml: expected a mapping of config sections"),
    ],
)
def test_bad_file_named(tmp_path, name, text, message):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(InputError, match=message):
        config.load([path], default=None)
    with pytest.raises(InputError, match=message):  # the default read first, then the bad file
        config.load([path], default=CONFIG / "config.yaml")


def test_missing_file_named(tmp_path):
    with pytest.raises(InputError, match=r"nope\.yaml: cannot read the config file"):
        config.load([tmp_path / "nope.yaml"])


def test_empty_file_is_an_empty_overlay(tmp_path, in_repo):
    (tmp_path / "empty.yaml").write_text("# nothing changed\n")
    assert config.load([tmp_path / "empty.yaml"]) == raw("config")


@pytest.mark.parametrize("name", OVERLAYS)
def test_workflow_order_is_the_default_configs(name, in_repo):
    """Snakemake starts from the --configfile files, merges the Snakefile's configfile and then
    them again over it, so an overlay's keys come first; restore_default_order (the Snakefile)
    puts them back in config/config.yaml's order, the order of load's result."""
    from snakemake.utils import update_config

    workflow = copy.deepcopy(raw(name))
    update_config(workflow, raw("config"))
    update_config(workflow, raw(name))
    config.restore_default_order(workflow)
    assert json.dumps(workflow) == json.dumps(config.load([f"config/{name}.yaml"]))
    default = raw("config")
    for section in default:
        assert list(workflow[section])[: len(default[section])] == list(default[section])


def test_ordered_like_keeps_values_and_extra_keys():
    out = config.ordered_like(
        {"b": 1, "x": {"q": 1, "p": [2]}, "a": {"d": 1, "c": 2}}, {"a": {"c": 0, "d": 0}, "b": 0, "x": 5}
    )
    assert json.dumps(out) == json.dumps({"a": {"c": 2, "d": 1}, "b": 1, "x": {"q": 1, "p": [2]}})


# ---------------------------------------------------------------------------------------------
# the files


def test_sections_are_the_schema_and_the_default_config():
    schema = yaml.safe_load((SCHEMAS / "config.schema.yaml").read_text())
    assert set(config.SECTIONS) == set(schema["properties"]) == set(raw("config"))


@pytest.mark.parametrize("name", OVERLAYS)
def test_overlays_hold_only_changed_keys(name):
    """Every value of an overlay differs from config/config.yaml's (or is a key it lacks);
    config/table.yaml restates the held-out schemes it runs."""
    default = leaves(raw("config"))
    assert set(raw(name)) <= set(config.SECTIONS)
    same = [k for k, v in leaves(raw(name)).items() if k in default and default[k] == v]
    assert same == (["diagnosis.crossval.schemes"] if name == "table" else [])


@pytest.mark.parametrize("names", [(), ("paper",), ("smoke",), ("table",)])
def test_merged_configs_pass_the_schemas(names, in_repo):
    """As workflow/rules/common.smk: the top-level schema, then each section's schema."""
    from snakemake.utils import validate

    cfg = config.load([f"config/{n}.yaml" for n in names])
    validate(copy.deepcopy(cfg), str(SCHEMAS / "config.schema.yaml"))
    for section in config.SECTIONS:
        sub = copy.deepcopy(cfg[section])
        validate(sub, str(SCHEMAS / f"{section}.schema.yaml"))
        assert sub == cfg[section], f"a schema default filled a key config/config.yaml lacks in {section}"


def _schema_defaults(schema: dict, prefix: str = "") -> dict:
    out = {}
    for key, sub in (schema.get("properties") or {}).items():
        if "default" in sub:
            out[f"{prefix}{key}"] = sub["default"]
        out.update(_schema_defaults(sub, f"{prefix}{key}."))
    return out


def test_schema_defaults_are_the_default_config():
    default = leaves(raw("config"))
    found = {}
    for section in config.SECTIONS:
        schema = yaml.safe_load((SCHEMAS / f"{section}.schema.yaml").read_text())
        found.update(_schema_defaults(schema, f"{section}."))
    assert found, "no schema default found"
    for key, value in found.items():
        assert key in default and default[key] == value, (key, value, default.get(key))


# ---------------------------------------------------------------------------------------------
# the readers of the package


@pytest.mark.parametrize("name", OVERLAYS)
def test_campaign_read_config_merges(name, in_repo):
    from asphalt_nscd.campaign import twopb

    expected = snakemake_config(name)
    assert twopb.read_config(f"config/{name}.yaml") == expected
    assert twopb.read_config(["config/config.yaml", f"config/{name}.yaml"]) == expected


def test_campaign_read_config_needs_a_campaign(tmp_path, monkeypatch):
    from asphalt_nscd.campaign import twopb

    monkeypatch.chdir(tmp_path)
    (tmp_path / "lab.yaml").write_text("lab: {window_s: 10.0}\n")
    with pytest.raises(InputError, match=r"lab\.yaml: no 'campaign' section"):
        twopb.read_config(tmp_path / "lab.yaml")


@pytest.mark.parametrize("name", ("config",) + OVERLAYS)
def test_sample_settings_load_merges(name, in_repo):
    from asphalt_nscd.sample import settings

    expected = settings.merge(settings.DEFAULTS, snakemake_config(*([name] if name != "config" else []))["sample"])
    assert settings.load(f"config/{name}.yaml") == expected
    assert settings.load(["config/config.yaml", f"config/{name}.yaml"]) == expected


def test_sample_settings_of_a_bare_section(tmp_path, in_repo):
    """A file holding the sample section alone is merged over the paper's values, not over
    config/config.yaml; an unknown key is named."""
    from asphalt_nscd.sample import settings

    (tmp_path / "s.json").write_text(json.dumps({"scale": 0.4, "psd": {"cut_mm": 8.0}}))
    bare = {"scale": 0.4, "psd": {"cut_mm": 8.0}}
    assert settings.load(tmp_path / "s.json") == settings.merge(settings.DEFAULTS, bare)
    (tmp_path / "typo.yaml").write_text("scal: 0.5\n")
    with pytest.raises(InputError, match=r"typo\.yaml: sample: unknown key 'scal'"):
        settings.load(tmp_path / "typo.yaml")
    (tmp_path / "typo2.yaml").write_text("sample:\n  scal: 0.5\n")
    with pytest.raises(InputError, match=r"typo2\.yaml: sample: .*'scal'"):  # the schema refuses it
        settings.load(tmp_path / "typo2.yaml")


def test_sample_table_command_merges_the_overlay(tmp_path, in_repo):
    """`sample-table --config config/smoke.yaml` = `--config config/config.yaml config/smoke.yaml`
    = the merged smoke sample section given alone (merged over the paper's values)."""
    import pandas as pd
    import yaml

    from asphalt_nscd.cli import main

    bare = tmp_path / "bare_sample.yaml"
    bare.write_text(yaml.safe_dump(snakemake_config("smoke")["sample"]))
    outs = []
    for k, opts in enumerate(
        (
            ["--config", "config/smoke.yaml"],
            ["--config", "config/config.yaml", "config/smoke.yaml"],
            ["--config", str(bare)],
        )
    ):
        out = tmp_path / f"t{k}.csv"
        assert main(["sample-table", *opts, "-o", str(out)]) == 0
        outs.append(pd.read_csv(out))
    for other in outs[1:]:
        pd.testing.assert_frame_equal(outs[0], other)


def _subparser(name: str):
    from asphalt_nscd.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if hasattr(a, "choices") and isinstance(a.choices, dict))
    return sub.choices[name]


# ---------------------------------------------------------------------------------------------
# defaults in the code


def test_sample_defaults_are_the_default_config_at_paper_scale():
    """sample.settings.DEFAULTS = config/config.yaml's sample section with the paper's
    full-scale values (Section 3.2.1) where the reduced-size default differs."""
    from asphalt_nscd.sample import settings

    paper_values = {
        "scale": 1.0,
        "psd": {"cut_mm": 2.0},
        "vibration": {"duration_s": 1.0},
        "solver": {"tolerance": 1.0e-4},
    }
    assert settings.DEFAULTS == config.merge(raw("config")["sample"], paper_values)
    # the paper's values also stand in config/paper.yaml
    paper = snakemake_config("paper")["sample"]
    assert all(leaves(paper)[k] == v for k, v in leaves(paper_values).items())


def test_extended_law_defaults_are_the_default_config():
    """diagnosis.cli.LAW_DEFAULTS and the other defaults of the extended law's options
    (extend-law, crossval) and of the artifact search (master-curve) = config/config.yaml's
    diagnosis section."""
    from asphalt_nscd.diagnosis.cli import LAW_DEFAULTS

    diag = raw("config")["diagnosis"]
    law = diag["law"]
    assert list(LAW_DEFAULTS["shifts"]) == law["shifts"]
    assert list(LAW_DEFAULTS["statics"]) == law["statics"]
    assert [v == "on" for v in LAW_DEFAULTS["verticals"]] == law["verticals"]
    assert [None if r == "off" else float(r) for r in LAW_DEFAULTS["refines"]] == law["refines"]
    assert [float(v) for v in LAW_DEFAULTS["per_decades"]] == [float(v) for v in law["per_decades"]]
    for command in ("extend-law", "crossval"):
        d = _subparser(command)
        assert d.get_default("law_shifts") == law["shifts"]
        assert d.get_default("law_statics") == law["statics"]
        assert [v == "on" for v in d.get_default("law_verticals")] == law["verticals"]
        refines = [None if r == "off" else float(r) for r in d.get_default("law_refines")]
        assert refines == law["refines"]
        assert d.get_default("law_per_decades") == [float(v) for v in law["per_decades"]]
        assert d.get_default("margin_decades") == law["margin_decades"]
        assert list(d.get_default("tolerances_pct")) == law["tolerances_pct"]
        assert d.get_default("no_one_se") is (not law["one_se"])
        assert d.get_default("no_artifacts") is (not law["artifacts"])
    for command in ("master-curve", "extend-law", "crossval"):
        d = _subparser(command)
        assert d.get_default("alpha") == diag["alpha"]
        assert d.get_default("shift") == diag["shift"]
        assert d.get_default("t_ref") == diag["T_ref_C"]


def test_calibration_defaults_are_the_default_config():
    """The Burger's fit options of the fit command = config/config.yaml's calibration."""
    cal = raw("config")["calibration"]
    d = _subparser("fit")
    assert d.get_default("n_starts") == cal["n_starts"]
    assert d.get_default("weight_log_modulus") == cal["weight_log_modulus"]
    assert d.get_default("weight_phase") == cal["weight_phase"]


def test_material_card_tolerance_default_is_the_default_config():
    """export-law's default tolerance (rheology.export.CARD_TOLERANCE, used when --tolerance is
    not given) = config/config.yaml's diagnosis.material_card.tolerance."""
    from asphalt_nscd.rheology import export

    assert list(export.CARD_TOLERANCE) == raw("config")["diagnosis"]["material_card"]["tolerance"]
    assert _subparser("export-law").get_default("tolerance") is None


def test_card_law_defaults_are_the_default_config():
    """The card law's fit and shift (extend-law, crossval options; diagnosis.crossval.Options)
    = config/config.yaml's diagnosis.material_card.fit and shift."""
    from asphalt_nscd.diagnosis.cli import LAW_DEFAULTS
    from asphalt_nscd.diagnosis.crossval import Options

    card = raw("config")["diagnosis"]["material_card"]
    assert (LAW_DEFAULTS["card_fit"], LAW_DEFAULTS["card_shift"]) == (card["fit"], card["shift"])
    assert (Options().card_fit, Options().card_shift) == (card["fit"], card["shift"])
    for command in ("extend-law", "crossval"):
        d = _subparser(command)
        assert (d.get_default("card_fit"), d.get_default("card_shift")) == (card["fit"], card["shift"])


def test_2pb_settings_defaults_are_the_default_config():
    """campaign.twopb.TwoPBSettings has no default of its own: each field that
    config/config.yaml's campaign.test sets equals it (the time-step policy, its cap, the
    fast-path contacts among them)."""
    import dataclasses

    from asphalt_nscd.campaign.twopb import TwoPBSettings

    test = raw("config")["campaign"]["test"]
    fields = {f.name: f.default for f in dataclasses.fields(TwoPBSettings)}
    assert set(test) <= set(fields)
    assert {k: fields[k] for k in test} == test
    assert fields["window_cycles"] == raw("config")["lab"]["simulation_window_cycles"]
    assert fields["bond_kinematics"] == raw("config")["nscd"]["bond_kinematics"]


@pytest.mark.parametrize("name", ["smoke", "paper", "table"])
def test_jobs_read_from_the_run_config_what_the_rules_track(name, tmp_path, in_repo):
    """The Snakefile writes the merged config (config.write_run_config) and the jobs read it
    (--config): the test settings of every mode and the sample section of every resolution level
    a job builds from that file equal the rules' `settings` params (plan.mode_settings,
    plan.resolution_sample_settings) from which Snakemake decides reruns."""
    from asphalt_nscd import plan
    from asphalt_nscd.campaign import twopb
    from asphalt_nscd.sample import settings

    cfg = snakemake_config(name)
    config.restore_default_order(cfg)
    path = config.write_run_config(cfg, tmp_path / "run")
    assert config.write_run_config(cfg, tmp_path / "run") == path  # same content, same file
    read = config.checked(path)
    for mode in ("paper", "paper_kPa", "measured", "extended", "dt_study", "sensitivity", "units_Pa"):
        assert twopb.job_settings(read, mode) == plan.mode_settings(cfg, mode)
    for level in plan.resolution_levels(cfg):
        expected = settings.merge(settings.DEFAULTS, plan.resolution_sample_settings(cfg, level)["sample"])
        got = settings.load(path, level=level)
        assert {k: v for k, v in got.items() if k != "seeds"} == {k: v for k, v in expected.items() if k != "seeds"}
    with pytest.raises(InputError, match="no level 'x9_cut9'"):
        settings.load(path, level="x9_cut9")
    changed = config.merge(cfg, {"harmonic": {"sweep": {"n_points": 7}}})
    assert config.write_run_config(changed, tmp_path / "run") != path  # a new file, the old one kept
    assert Path(path).is_file()


def test_commands_check_the_schemas(tmp_path, in_repo):
    """A command given --config refuses what the workflow's schemas refuse, naming the file and key."""
    from asphalt_nscd.cli import main

    bad = tmp_path / "bad.yaml"
    bad.write_text("campaign:\n  test:\n    method: fastest\n")
    with pytest.raises(InputError, match=r"bad\.yaml: campaign\.test\.method: 'fastest' is not one of"):
        config.checked(bad)
    assert main(["sample-table", "--config", str(bad), "-o", str(tmp_path / "t.csv")]) == 2
    assert not (tmp_path / "t.csv").exists()


@pytest.mark.parametrize("name", ["config", "smoke", "table"])
def test_diagnosis_commands_take_their_options_from_the_config(name, tmp_path, in_repo):
    """`--config` gives a diagnosis command the options of its config's diagnosis section
    (diagnosis.settings.option_values): the parsed arguments equal those of the same options
    spelled out, an option given on the command line wins, and a bad config is refused."""
    from asphalt_nscd.cli import build_parser, main, with_config_values
    from asphalt_nscd.diagnosis.settings import option_values

    cfg = snakemake_config(name)
    path = config.write_run_config(cfg, tmp_path)
    values = option_values(cfg, "search", "law")

    def spelled(v) -> list[str]:
        return [str(x) for x in v] if isinstance(v, list) else [str(v)]

    flags = []
    for dest, v in values.items():
        if isinstance(v, bool):
            flags += [f"--{dest.replace('_', '-')}"] if v else []
        elif v is not None:
            flags += [f"--{dest.replace('_', '-')}", *spelled(v)]
    base = ["crossval", "--measured", "m.csv", "--scheme", "lofo", "-o", "o.csv"]

    def parsed(argv):
        parser = build_parser()
        return vars(with_config_values(parser, parser.parse_args(argv), argv))

    by_config, by_flags = parsed(base + ["--config", path]), parsed(base + flags)
    for dest in values:
        assert by_config[dest] == by_flags[dest], dest
    assert parsed(base + ["--config", path, "--alpha", "0.02"])["alpha"] == 0.02
    bad = tmp_path / "bad.yaml"
    bad.write_text("diagnosis:\n  alpha: high\n")
    assert main(base + ["--config", str(bad)]) == 2


@pytest.mark.parametrize("name", ["config", "smoke", "paper"])
def test_commands_take_from_the_run_config_what_the_rules_track(name, tmp_path, in_repo):
    """A command given the run's config file parses to the values the rule keeps as its
    settings (plan.command_settings and the mode-aware plan.job_values, isotherm_settings,
    policy_settings), and those are the config's own values: the Burger's fits, the harmonic
    solver and its studies, the 2PB job's Table 3 reading and verification, the dt-policy check."""
    from asphalt_nscd import plan
    from asphalt_nscd.cli import build_parser, with_config_values

    cfg = snakemake_config(name)
    path = config.write_run_config(cfg, tmp_path)

    def parsed(*argv: str) -> dict:
        parser = build_parser()
        args = [*argv, "--config", path]
        return vars(with_config_values(parser, parser.parse_args(args), args))

    def agrees(got: dict, settings: dict) -> None:
        assert settings, "the rule tracks nothing"
        for dest, value in settings.items():
            assert got[dest] == value, dest

    cal, harm = cfg["calibration"], cfg["harmonic"]
    fit = parsed("fit", "--measured", "m.csv", "-o", "o.csv")
    agrees(fit, plan.command_settings(cfg, "fit"))
    assert (fit["weight_phase"], fit["n_starts"]) == (cal["weight_phase"], cal["n_starts"])
    micro = parsed("micro", "--parameters", "p.csv", "-o", "o.csv")
    agrees(micro, plan.command_settings(cfg, "micro"))
    assert micro["r_min_mm"] == cal["micro"]["r_min_mm"] and micro["nu"] == cal["micro"]["poisson_ratio"]
    assert parsed("table3", "t.csv", "-o", "o.csv")["units"] == cal["table3_units"]
    refit = parsed("refit-check", "--parameters", "p.csv", "-o", "o.csv")
    assert refit["frequencies"] == cal["refit_frequencies_Hz"]
    jobs = parsed("harmonic", "--sample", "s.h5", "--parameters", "p.csv", "--grid", "paper", "-o", "o.csv")
    agrees(jobs, plan.harmonic_job_settings(cfg, "paper"))
    assert jobs["frequency"] == harm["paper_frequencies_Hz"] and jobs["sweep"] is None
    sweep = parsed("harmonic", "--sample", "s.h5", "--parameters", "p.csv", "--grid", "sweep", "-o", "o.csv")
    assert sweep["sweep"] == [harm["sweep"]["fmin_Hz"], harm["sweep"]["fmax_Hz"], harm["sweep"]["points"]]
    assert sweep["frequency"] is None
    measured = parsed("harmonic", "--sample", "s.h5", "--parameters", "p.csv", "--frequencies-from", "m.csv", "-o", "o")
    assert measured["frequency"] is None and measured["rtol"] == harm["rtol"]
    compare = parsed("harmonic-compare", "--sample", "s.h5", "--parameters", "p.csv", "-o", "o.csv")
    agrees(compare, plan.command_settings(cfg, "harmonic-compare"))
    assert (
        compare["dt"] == harm["compare"]["dt_s"]
        and compare["head_rotation"] == cfg["campaign"]["test"]["head_rotation"]
    )
    for command in ("harmonic-sensitivity", "harmonic-kinematics"):
        agrees(
            parsed(command, "--sample", "s.h5", "--parameters", "p.csv", "-o", "o.csv"),
            plan.command_settings(cfg, command),
        )
    agrees(
        parsed("harmonic-transfer", "--sample", "s.h5", "-o", "o.json"), plan.command_settings(cfg, "harmonic-transfer")
    )
    resolution = parsed(
        "harmonic-resolution", "--samples", "a.h5", "-o", "o", "--summary", "s", "--fits", "f", "--figure", "g"
    )
    assert resolution["levels"] == [level for level, _ in plan.resolution_samples(cfg)]
    agrees(parsed("harmonic-bench", "-o", "b.json"), plan.command_settings(cfg, "harmonic-bench"))
    # the 2PB jobs of every main mode at their schedule's corners, and the studies' jobs
    for mode in ("paper", "paper_kPa", "measured", "extended"):
        sched = cfg["campaign"]["measured" if mode in ("measured", "extended") else "paper"]
        source = ["--law-json", "law.json"] if mode == "extended" else ["--parameters", "p.csv"]
        for T in (min(sched["temperatures_C"]), max(sched["temperatures_C"])):
            for f in sched["frequencies_Hz"]:
                case = plan.case_name(T, f)
                argv = ["run-2pb", "--sample", "s.h5", "--mode", mode, *source, "-o", "r.h5", "--row", "r.csv"]
                got = parsed(*argv, *plan.case_options(cfg, mode, "s1", case).split())
                agrees(got, plan.job_values(cfg, mode, "s1", case))
        isotherms = ["campaign-isotherms", "--rows", "r.csv", *source, "--mode", mode, "--isotherms", "i"]
        got = parsed(*isotherms, "--table4", "t", "--figure-modulus", "m", "--figure-phase", "p")
        agrees(got, plan.isotherm_settings(cfg, mode))
        if mode != "extended":
            got = parsed("campaign-dt-policy", "--parameters", "p.csv", "--settings-mode", mode, "-o", "o.csv")
            agrees(got, plan.policy_settings(cfg, mode))
            assert got["frequencies"] == [float(f) for f in sched["frequencies_Hz"]]
    # the studies beside the campaign, the core's checks and the diagnosis benchmark
    sens = parsed(
        "campaign-sensitivity",
        "--rows",
        "r",
        "--baseline",
        "b",
        "--parameters",
        "p",
        "--table",
        "t",
        "--figures",
        *"abcd",
    )
    assert (
        sens["temperature"] == cfg["campaign"]["sensitivity"]["temperature_C"]
        and sens["table3_units"] == cal["table3_units"]
    )
    units = parsed("campaign-units", "--table3", "t", "--rows-pa", "a", "--rows-kpa", "b", "--sample", "s", "-o", "o")
    agrees(units, plan.command_settings(cfg, "campaign-units"))
    assert (units["r_min_mm"], units["l0_mm"]) == (cal["micro"]["r_min_mm"][0], cal["micro"]["l0_mm"][0])
    verify = parsed("verify", "-o", "v.json")
    assert [float(x) for x in verify["phase_dts"].split(",")] == cfg["nscd"]["verify"]["phase_dts_s"]
    for case in ("bonded", "granular"):
        agrees(parsed("bench", "--case", case, "--n", "10", "-o", "b.json"), plan.bench_settings(cfg, case))
    bench = parsed("diagnose-bench", "-o", "b.json")
    agrees(bench, plan.diagnosis_settings(cfg, "bench"))
    assert bench["families"].split(",") == cfg["diagnosis"]["bench"]["families"]
    card = parsed("export-law", "--law-json", "l", "--measured", "m", "-o", "d")
    assert card["tolerance"] == cfg["diagnosis"]["material_card"]["tolerance"] and card["nu"] is None
    assert parsed("reduce", "r.csv", "--meta", "m.json", "-o", "o")["window_s"] == cfg["lab"]["window_s"]
    assert parsed("reduce", "r.csv", "--meta", "m.json", "--window-cycles", "1", "-o", "o")["window_s"] is None
    for case in ("20C_3Hz_Emx1.5", "15C_3Hz_dt5e-05"):
        argv = [
            "run-2pb",
            "--sample",
            "s.h5",
            "--mode",
            "sensitivity",
            "--parameters",
            "p.csv",
            "-o",
            "r",
            "--row",
            "r",
        ]
        got = parsed(*argv, *plan.case_options(cfg, "sensitivity", "s1", case).split())
        assert got["verify"] is False and got["table3_units"] == cal["table3_units"]


def _same_value(a, b) -> bool:
    """Equal as option values: numbers by value, comma-separated numbers by their numbers,
    'off' and number strings of the refinement weights by meaning."""

    def norm(v):
        if isinstance(v, str) and "," in v:
            return [norm(x) for x in v.split(",")]
        if isinstance(v, (list, tuple)):
            return [norm(x) for x in v]
        if isinstance(v, bool) or v is None:
            return v
        try:
            return float(v)
        except (TypeError, ValueError):
            return v

    return norm(a) == norm(b)


def test_command_defaults_are_the_default_config(in_repo):
    """Every option a command takes from --config has, run without one, the default config's
    value (config/config.yaml) or no value of its own (None or empty: required without a
    config, or worked out from the job's mode): the defaults are written once."""
    from asphalt_nscd.cli import _commands, config_values

    cfg = config.checked([])
    probes = {"run-2pb": {"temperature": 15.0, "frequency": 3.0}, "bench": {"case": "bonded"}}
    checked = 0
    for name, sub in _commands().items():
        if sub.get_default("config_values") is None:
            continue
        defaults = {a.dest: a.default for a in sub._actions}
        for dest, value in config_values(name, cfg, **probes.get(name, {})).items():
            own = defaults[dest]
            if own is None or own == [] or own == "":
                continue
            checked += 1
            assert _same_value(own, value), f"asphalt-nscd {name} --{dest.replace('_', '-')}: {own!r} != {value!r}"
    assert checked > 40
