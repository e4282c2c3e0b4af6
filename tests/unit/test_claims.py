"""Every number a reader sees is computed from a committed table: the claims file
(reference/claims/, checked by reference/claims.py) holds on the committed tables, covers
every number of the pages it lists, dates every claim with the command that made its tables,
and fails when a table it cites changes."""

import reference_scripts
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

REPO = Path(__file__).resolve().parents[2]


def _claims_module():
    return reference_scripts.load("reference/claims.py")


claims = _claims_module()
DATA = claims.load()


def _tables() -> list[str]:
    return sorted({rel for c in DATA["claims"] for rel in (c.get("tables") or {}).values()})


def test_every_claim_holds_on_the_committed_tables():
    failed = [r.message for r in claims.check_claims(DATA) if not r.ok]
    assert not failed, "\n".join(failed)


def test_every_number_of_the_covered_pages_is_claimed_or_said_to_state_no_result():
    missing = claims.uncovered(DATA)
    assert not missing, "numbers neither claimed nor listed in not_results:\n" + "\n".join(missing[:60])


def test_every_claim_has_its_run_date_and_command_and_every_listed_entry_is_on_its_page():
    runs = DATA["runs"]
    for key, run in runs.items():
        assert str(run.get("date", "")).count("-") == 2 and run.get("command"), key
    for entry in DATA["records"]:
        assert entry.get("run") in runs and entry.get("why"), entry
    for entry in DATA["not_results"] + DATA["records"]:
        assert entry.get("why"), entry
        raw = (REPO / entry["file"]).read_text()
        if "pattern" in entry:
            assert re.search(entry["pattern"], raw), f"{entry['file']}: pattern matches nothing: {entry['pattern']!r}"
            continue
        assert claims.collapse(entry["text"]) in claims.collapse(raw), f"{entry['file']}: not found: {entry['text']!r}"
    for name in DATA["covered"]:
        assert (REPO / name).is_file(), name


def _perturbed_copy(value):
    """Every number changed (x -> 1.1 x + 1: ratios, counts and ranges all move)."""
    if isinstance(value, bool) or value is None:
        return value
    if isinstance(value, (int, float)):
        return 1.1 * value + 1.0
    if isinstance(value, list):
        return [_perturbed_copy(v) for v in value]
    if isinstance(value, dict):
        return {k: _perturbed_copy(v) for k, v in value.items()}
    return value


@pytest.fixture
def copied_tables(tmp_path):
    """A copy of every cited table under tmp_path, at its path relative to the repository."""
    for rel in _tables():
        dest = tmp_path / rel
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / rel, dest)
    return tmp_path


@pytest.mark.parametrize("rel", _tables())
def test_a_changed_table_fails_the_claims_that_cite_it(copied_tables, rel):
    """A temporary edit of one cited table (a perturbed copy; the committed file is untouched)
    fails at least one claim that cites it and no claim that does not."""
    root = copied_tables
    assert not [r.message for r in claims.check_claims(DATA, root=root) if not r.ok]  # the copy holds
    path = root / rel
    if path.suffix == ".json":
        path.write_text(json.dumps(_perturbed_copy(json.loads(path.read_text()))))
    elif path.suffix == ".jsonl":
        lines = [json.dumps(_perturbed_copy(json.loads(x))) for x in path.read_text().splitlines() if x.strip()]
        path.write_text("\n".join(lines) + "\n")
    else:
        frame = pd.read_csv(path)
        for col in frame.columns:
            if pd.api.types.is_numeric_dtype(frame[col]) and not pd.api.types.is_bool_dtype(frame[col]):
                frame[col] = 1.1 * frame[col] + 1.0
            elif (
                pd.api.types.is_string_dtype(frame[col]) or frame[col].dtype == object
            ):  # a count of named rows (what a table's alarms name) changes too
                frame[col] = frame[col].where(frame[col].isna(), frame[col].astype(str) + "~")
        frame.to_csv(path, index=False)
    results = claims.check_claims(DATA, root=root)
    citing = [r for r in results if rel in (r.claim.get("tables") or {}).values()]
    others = [r for r in results if rel not in (r.claim.get("tables") or {}).values()]
    assert citing and any(not r.ok for r in citing), f"no claim citing {rel} noticed the change"
    assert all(r.ok for r in others), [r.message for r in others if not r.ok]


def test_the_number_parser_reads_numbers_as_written():
    got = claims.numbers_in("9,695 s (2.69 h), 1.5e-4 %, −10 °C, 1.05-1.32, [3.22, 19.45], 2026-11-24, s1, 2S2P1D")
    assert got == ["9,695", "2.69", "1.5e-4", "−10", "1.05", "1.32", "3.22", "19.45"]
    assert [claims.parse(x) for x in ("9,695", "−10", "1.5e-4")] == [9695.0, -10.0, 1.5e-4]
    assert claims.half_unit("4.91") == pytest.approx(0.005) and claims.half_unit("9,695") == 0.5
    assert claims.half_unit("1.5e-4") == pytest.approx(5e-6)
    claim = {"file": "README.md", "text": "x", "expr": "1"}
    assert not claims.evaluate(claim).ok  # a text that is not on its page fails


def test_the_changelog_says_its_entries_are_history():
    head = (REPO / "CHANGELOG.md").read_text().split("\n## ", 1)[0]
    assert "history" in head and "reference/claims/" in head


def test_pandas_and_numpy_are_what_the_expressions_see():
    assert claims.HELPERS["np"] is np and claims.HELPERS["pd"] is pd


def _forecast_readme_module():
    return reference_scripts.load("reference/forecast/readme.py", "forecast_readme")


def test_the_forecast_page_is_what_its_tables_give_and_follows_a_changed_table(tmp_path, monkeypatch):
    """reference/forecast/README.md is rendered from its folder's tables (readme.py): the
    committed page equals the rendering, and a changed table changes the rendering."""
    readme = _forecast_readme_module()
    assert readme.main(["--check"]) == 0, "reference/forecast/README.md: rerun python reference/forecast/readme.py"
    folder = tmp_path / "forecast"
    shutil.copytree(REPO / "reference" / "forecast", folder)
    monkeypatch.setattr(readme, "HERE", folder)
    assert readme.render() == (REPO / "reference" / "forecast" / "README.md").read_text()
    frame = pd.read_csv(folder / "default_crossval.csv")
    frame["abs_logE_pct"] = 1.1 * frame["abs_logE_pct"] + 1.0
    frame.to_csv(folder / "default_crossval.csv", index=False)
    assert readme.main(["--check"]) == 1


def test_the_binder_frequency_evidence_is_what_the_shipped_table_gives():
    """reference/forecast/binder_frequency.csv (the evidence docs/forecast.md cites for the
    binder columns' rad/s) is recomputed from data/binder_mix/ by its script: a changed table or
    reader changes it. At 10 rad/s the MEPDG relation returns the table's own viscosity within
    a factor 2 at every temperature above 20 degC."""
    module = reference_scripts.load("reference/forecast/binder_frequency.py")
    got = module.evidence(module.read_matched(module.TABLE))
    committed = pd.read_csv(REPO / "reference" / "forecast" / "binder_frequency.csv")
    assert list(got.columns) == list(committed.columns)
    np.testing.assert_allclose(got.to_numpy(float), committed.to_numpy(float), rtol=1e-5)
    assert (got["median_log10_ratio"].abs() < np.log10(2.0)).all()


def test_the_probes_choice_is_paired_with_each_model_over_the_mixes_both_forecast():
    """readme.paired_choice_section: per model, the mean over the shared mixes of the choice's minus the model's
    mean abs errors with its t(n - 1) interval; a mix one side lacks is left out; a model with fewer than two
    shared mixes gets no row."""
    from asphalt_nscd.diagnosis.scores import t_interval

    readme = _forecast_readme_module()
    choice = pd.DataFrame(
        {"mix_id": ["1", "2", "3", "4"], "chosen": "v", "abs_logE_pct": [30.0, 40.0, 20.0, 50.0], "abs_phase_deg": 5.0}
    )
    rows = []
    for label, e in (("witczak_1_40d_published", [35.0, 30.0, 28.0]), ("hirsch_recalibrated", [10.0])):
        for mix, v in zip(["1", "2", "3"], e):
            rows.append(
                {"label": label, "binder_route": "curve", "mix_id": mix, "e": v, "p": 4.0, "temperature_C": None}
            )
    per_mix = pd.DataFrame(rows)
    lines = readme.paired_choice_section(choice, per_mix)
    d = np.array([30.0 - 35.0, 40.0 - 30.0, 20.0 - 28.0])
    lo, hi = t_interval(d)
    assert f"| witczak_1_40d_published | 3 | {d.mean():.1f} [{lo:.1f}, {hi:.1f}] | 1.0 [1.0, 1.0] |" in lines
    assert not any("hirsch_recalibrated" in line for line in lines)
    assert readme.paired_choice_section(None, per_mix) == []
