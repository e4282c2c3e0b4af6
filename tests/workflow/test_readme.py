"""The README's first command as a newcomer runs it, and what its run must give.

A fresh copy of the repository (the files a clone holds: tracked and not-ignored ones, no
`.venv`, no `results/`) runs the README's first command on the smoke configuration,
``make run CONFIG=config/smoke.yaml``, from a plain shell: no virtual environment activated
and no `.venv/bin` on the PATH. On that run:

* the report index and every file it links exist, nothing is half-written;
* ``make report`` builds the HTML report with no docutils warning, and headless Chromium
  shows it: it loads, lists every report category, no caption shows an error box, and a
  figure renders (its screenshot is not blank);
* a second run of the same command from scratch gives identical result tables, except the
  measured compute times listed in ``NOT_IDENTICAL`` (see the README, "Determinism").

Marked ``slow``: it installs the pinned environment in the copy (about a minute) and runs the
smoke workflow twice.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.io import InputError, content_sha256

REPO = Path(__file__).resolve().parents[2]
SMOKE = "config/smoke.yaml"

#: Outputs that legitimately differ between two runs of the same configuration, and why.
#: Files (glob under results/) are skipped whole; columns/keys are dropped before comparing.
NOT_IDENTICAL = {
    "files": {
        "bench/*": "NSCD core benchmark: measured times (bench command)",
        "report/bench/*": "copy of the benchmark table",
        "harmonic/bench.json": "harmonic solver benchmark: measured times",
        "forecasts/*/manifest.json": "the time stamp of a published forecast (its files' SHA-256 are compared through them)",
        "report/harmonic/bench.json": "copy of the harmonic solver benchmark",
    },
    "columns": {
        "wall_time_s": "measured wall time of a simulation job",
        "cpu_time_s": "measured CPU time of a simulation job",
        "cpu_per_sphere_step_s": "measured CPU time per sphere and step",
        "solve_time_s": "measured time of a harmonic solve",
        "wall_clock_s": "measured wall time of a sample preparation phase",
        "timings_s": "measured wall times of the sample preparation phases",
        "cpu_s": "measured CPU time of a sample preparation phase",
        "seconds_per_table": "measured time per table of the detection benchmark",
        "seconds_per_table_wall": "measured wall time per table of the detection benchmark",
        "cpu_seconds_main_process": "measured CPU time of the detection benchmark",
        "cpu_seconds": "measured CPU time of the artifact search's calibration and of a benchmark table",
        "cert_seconds": "measured wall time of a job's linearity certificate",
    },
}


def readme_commands() -> list[str]:
    """The commands of the README's first code block (comments stripped)."""
    text = (REPO / "README.md").read_text()
    block = re.search(r"```(?:bash|sh)?\n(.*?)```", text, re.S)
    assert block, "README has no code block"
    return [line.split("#")[0].strip() for line in block.group(1).splitlines() if line.split("#")[0].strip()]


def newcomer_env() -> dict:
    """The environment of a plain shell: no virtual environment, no .venv/bin on the PATH."""
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH", "CONDA_PREFIX", "PYTHONHOME")}
    ours = str(Path(sys.executable).parent)
    env["PATH"] = os.pathsep.join(
        p
        for p in env.get("PATH", "").split(os.pathsep)
        if p and p != ours and ".venv" not in Path(p).parts and "venv" not in Path(p).name
    )
    return env


def make_args(env: dict) -> list[str]:
    """``PYTHON=...`` only where the plain shell has no python3.11 (the Makefile's default)."""
    if shutil.which("python3.11", path=env["PATH"]):
        return []
    base = Path(getattr(sys, "_base_executable", sys.executable))
    return [f"PYTHON={base}"]


def run(cmd: list[str], cwd: Path, env: dict, timeout: float = 3600) -> subprocess.CompletedProcess:
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        logs = (
            "\n".join(
                f"--- {p}\n{p.read_text()[-2000:]}"
                for p in sorted((cwd / "logs").rglob("*.log"))
                if "rror" in p.read_text()
            )
            if (cwd / "logs").exists()
            else ""
        )
        pytest.fail(
            f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-5000:]}\n{logs}"
        )
    return proc


def fresh_copy(dest: Path) -> Path:
    """Copy the files a clone of the working tree holds (tracked and not-ignored ones) to ``dest``."""
    files = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split("\0")
    for name in filter(None, files):
        src = REPO / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)
    return dest


@pytest.fixture(scope="module")
def clone(tmp_path_factory) -> Path:
    """A fresh copy of the repository: the files a clone of the working tree holds."""
    return fresh_copy(tmp_path_factory.mktemp("clone") / "asphalt-nscd")


@pytest.fixture(scope="module")
def smoke_run(clone) -> Path:
    """``make run CONFIG=config/smoke.yaml`` in the fresh copy, from a plain shell."""
    env = newcomer_env()
    assert shutil.which("asphalt-nscd", path=env["PATH"]) is None, "the plain shell already sees asphalt-nscd"
    run(["make", "run", f"CONFIG={SMOKE}", *make_args(env)], clone, env)
    return clone


def test_readme_first_screen_gives_the_two_commands():
    assert readme_commands() == ["make run", "make test"]
    assert "make test" in (REPO / ".ci" / "run").read_text()


@pytest.mark.slow
def test_make_run_from_a_plain_shell_builds_the_report_index(smoke_run):
    index = smoke_run / "results" / "report" / "index.md"
    assert index.is_file()
    links = [line.split("(")[-1].rstrip(")") for line in index.read_text().splitlines() if line.endswith(")")]
    assert len(links) > 20, "report index lists too few figures and tables"
    for link in links:
        path = smoke_run / "results" / "report" / link
        assert path.is_file() and path.stat().st_size > 0, link
    assert not list((smoke_run / "results").rglob("*.tmp"))
    assert not list((smoke_run / "results").rglob("*.ckpt.h5")), "a finished run left a checkpoint"
    # the measured and extended modes start from the periodic steady state (1 cycle), the paper
    # mode from rest (campaign.*.start of config/smoke.yaml)
    starts = {
        mode: pd.read_csv(next((smoke_run / "results" / "sim" / mode).rglob("*.csv"))).iloc[0]
        for mode in ("paper", "measured", "extended")
    }
    assert starts["paper"]["start"] == "rest" and starts["paper"]["n_cycles_simulated"] == 2
    for mode in ("measured", "extended"):
        assert starts[mode]["start"] == "periodic" and starts[mode]["n_cycles_simulated"] == 1


def report_categories() -> set[str]:
    """Every report category the rules declare (``category=`` or a *_CATEGORY constant)."""
    cats = set()
    for smk in (REPO / "workflow" / "rules").glob("*.smk"):
        text = smk.read_text()
        cats |= set(re.findall(r'\bcategory="([^"]+)"', text))
        cats |= set(re.findall(r'^\w+_CATEGORY = "([^"]+)"', text, re.M))
    return cats


@pytest.mark.slow
def test_html_report_renders_in_headless_chromium(smoke_run):
    proc = run(["make", "report", f"CONFIG={SMOKE}", *make_args(newcomer_env())], smoke_run, newcomer_env())
    messages = re.findall(r"\((?:INFO/1|WARNING/2|ERROR/3|SEVERE/4)\).*", proc.stdout + proc.stderr)
    assert not messages, "docutils messages while building the report:\n" + "\n".join(messages[:20])
    report = smoke_run / "results" / "report.html"
    assert report.stat().st_size > 10_000

    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.skip(
            "Chromium is not installed (Debian: apt-get install chromium; .ci/run installs it "
            "where it can): the HTML report was built without docutils messages but not opened"
        )
    check_report_in_browser(report, chromium, smoke_run / "results" / "report_screens")


def check_report_in_browser(report: Path, chromium: str, screens: Path) -> None:
    """Open the HTML report in headless Chromium: it loads, its menu lists every report
    category, no caption shows a docutils error box, and a figure renders (not blank)."""
    from PIL import Image
    from playwright.sync_api import sync_playwright

    args = [
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-sync",
        "--disable-background-networking",
        "--disable-component-update",
    ]
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=chromium, args=args)
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        errors: list[str] = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.goto(report.as_uri())
        page.wait_for_selector("text=RESULTS")
        assert page.title() == "Snakemake Report"
        menu = page.locator("div.p-3 ul li a span").all_inner_texts()
        missing = sorted(c for c in report_categories() if c not in menu)
        assert not missing, f"categories missing from the report menu {menu}: {missing}"

        shown = {"captions": 0, "figure": None}
        for category in sorted(report_categories()):
            _open(page, [category])
            if page.locator("tr:has([role=group])").count():
                _check_items(page, [category], shown, screens)
                continue
            for sub in page.locator("div.p-3 ul li a span").all_inner_texts():
                _open(page, [category, sub])
                _check_items(page, [category, sub], shown, screens)
        assert shown["captions"] > 20, shown
        assert shown["figure"] is not None, "no figure was shown"
        assert not errors, errors
        browser.close()
    pixels = np.asarray(Image.open(shown["figure"]).convert("L"), float)
    assert pixels.std() > 10.0, f"the figure screenshot {shown['figure']} is blank"


def _open(page, path: list[str]) -> None:
    """Go home (breadcrumb) and open a category, then a subcategory, by their menu entries."""
    page.locator("nav ol li a").first.click()
    for name in path:
        page.locator("div.p-3 ul li a span").filter(has_text=re.compile(rf"^{re.escape(name)}$")).click()


def _check_items(page, path: list[str], shown: dict, screens: Path) -> None:
    """Every file of an open (sub)category: its caption (info view) shows no docutils error
    box; the first PNG is shown in the content panel and screenshotted."""
    rows = page.locator("tr:has([role=group])")
    names = [rows.nth(k).locator("td").first.inner_text().strip() for k in range(rows.count())]
    assert names, f"no files under {path}"
    for name in names:
        page.locator("tr:has([role=group])").filter(has_text=name).first.locator(
            "[iconname=information-circle]"
        ).click()
        page.wait_for_selector("text=DESCRIPTION")
        body = page.inner_text("body")
        assert page.locator(".system-message").count() == 0 and "System Message" not in body, (
            f"error box under the caption of {name}"
        )
        shown["captions"] += 1
        _open(page, path)
        if shown["figure"] is None and name.endswith(".png"):
            page.locator("tr:has([role=group])").filter(has_text=name).first.locator("[iconname=eye]").click()
            img = page.locator("img[src^='data:image/png']").last
            img.wait_for(state="visible")
            screens.mkdir(parents=True, exist_ok=True)
            shot = screens / (Path(name).stem + ".png")
            img.screenshot(path=str(shot))
            shown["figure"] = shot
            _open(page, path)


def _tables(results: Path) -> dict[str, Path]:
    from fnmatch import fnmatch

    out = {}
    for p in sorted(results.rglob("*")):
        rel = p.relative_to(results).as_posix()
        if p.suffix in (".csv", ".json", ".md") and not any(fnmatch(rel, g) for g in NOT_IDENTICAL["files"]):
            out[rel] = p
    return out


def _drop_times(obj):
    if isinstance(obj, dict):
        return {k: _drop_times(v) for k, v in obj.items() if k not in NOT_IDENTICAL["columns"]}
    if isinstance(obj, list):
        return [_drop_times(v) for v in obj]
    return obj


def differing_tables(a: dict[str, Path], b: dict[str, Path]) -> list[str]:
    """The tables of ``a`` (``_tables`` of one results/ folder) whose content differs from the same
    table of ``b``, the columns and keys of ``NOT_IDENTICAL`` left out."""
    differ = []
    for rel, pa in a.items():
        pb = b[rel]
        if pa.suffix == ".csv":
            da, db = pd.read_csv(pa), pd.read_csv(pb)
            cols = [c for c in da.columns if c not in NOT_IDENTICAL["columns"]]
            same = list(da.columns) == list(db.columns) and da[cols].equals(db[cols])
        elif pa.suffix == ".json":
            same = _drop_times(json.loads(pa.read_text())) == _drop_times(json.loads(pb.read_text()))
        else:
            same = pa.read_text() == pb.read_text()
        if not same:
            differ.append(rel)
    return differ


@pytest.mark.slow
def test_two_runs_of_the_same_config_give_identical_tables(smoke_run):
    first = smoke_run / "results_first_run"
    shutil.copytree(smoke_run / "results", first)
    shutil.rmtree(smoke_run / "results")
    run(["make", "run", f"CONFIG={SMOKE}", *make_args(newcomer_env())], smoke_run, newcomer_env())
    a, b = _tables(first), _tables(smoke_run / "results")
    assert set(a) == set(b)
    assert len(a) > 30
    differ = differing_tables(a, b)
    assert not differ, f"tables that differ between two runs of {SMOKE}: {differ}"
    # the prepared samples are bit-identical
    import h5py

    for pa in sorted((first / "samples").glob("*.h5")):
        with h5py.File(pa) as fa, h5py.File(smoke_run / "results" / "samples" / pa.name) as fb:
            names: list[str] = []
            fa.visit(lambda n: names.append(n) if isinstance(fa[n], h5py.Dataset) else None)
            assert names
            for n in names:
                np.testing.assert_array_equal(fa[n][()], fb[n][()], err_msg=f"{pa.name}:{n}")


@pytest.mark.slow
def test_faults_in_the_workflows_own_files_end_in_the_reference_results(smoke_run):
    """Three faults at once in the smoke run's own files: a key table deleted, a 2PB job's output
    gone with an unreadable checkpoint beside it, another job's row cut to its header. ``make
    run`` rebuilds the key table, restarts the job from its beginning (the checkpoint moved aside,
    said on the console) and stops on the header-only row with the project's one-line error on
    the console, naming the file and what to do; done as told, the next ``make run`` ends in the
    reference results (identical tables)."""
    results = smoke_run / "results"
    reference = smoke_run / "results_reference"
    shutil.copytree(results, reference)
    env = newcomer_env()
    make = ["make", "run", f"CONFIG={SMOKE}", *make_args(env)]
    key = sorted(results.glob("campaign/*/table4_*.csv"))[0]
    key.unlink()
    rows = sorted(results.glob("sim/*/s1/*.csv"))
    assert len(rows) >= 2, rows
    restarted, cut = rows[0], rows[1]
    record = restarted.with_suffix(".h5")
    record.unlink()
    restarted.unlink()
    rng = np.random.default_rng(7)
    for suffix in (".ckpt.h5", ".partial.npz"):
        record.with_name(record.name + suffix).write_bytes(rng.bytes(4096))
    cut.write_text(cut.read_text().splitlines()[0] + "\n")
    proc = subprocess.run(make, cwd=smoke_run, env=env, capture_output=True, text=True, timeout=3600)
    assert proc.returncode != 0, proc.stdout[-3000:]
    rel = cut.relative_to(smoke_run).as_posix()
    assert f"{rel}: no data rows after the header" in proc.stderr and "delete it and rerun" in proc.stderr, proc.stderr[
        -5000:
    ]
    assert "the checkpoint cannot be read" in proc.stderr and "Traceback" not in proc.stderr, proc.stderr[-5000:]
    assert record.with_name(record.name + ".ckpt.h5.unreadable").exists() and restarted.exists()
    cut.unlink()  # as the error says
    run(make, smoke_run, env)
    a, b = _tables(reference), _tables(results)
    assert set(a) == set(b)
    differ = differing_tables(a, b)
    assert not differ, f"tables that differ from the reference after the faults: {differ}"
    shutil.rmtree(reference)


def _sha_or_none(path: Path) -> str | None:
    """SHA-256 of ``path``, None while it does not exist."""
    try:
        return content_sha256(path)
    except InputError:
        if path.exists():
            raise
        return None


def readme_own_table_command() -> str:
    """The command of the README's section "Your own table" (its first code block)."""
    text = (REPO / "README.md").read_text()
    section = text.split("## Your own table", 1)[1]
    block = re.search(r"```(?:bash|sh)?\n(.*?)```", section, re.S)
    assert block, "README: no code block under 'Your own table'"
    lines = [ln.split("#")[0].strip() for ln in block.group(1).splitlines() if ln.split("#")[0].strip()]
    assert len(lines) == 1 and "TABLE=" in lines[0], lines
    return lines[0]


@pytest.mark.slow
def test_own_table_in_ksi_and_degF_through_the_readme_command(smoke_run):
    """A lab's AASHTO-style table in ksi and degF (its own column names, declared in its
    sidecar) through the README's own-table command, literally, from a plain shell: the law
    JSON at the table's temperatures in degC, the material cards (checked exact against the
    law they carry, their loss stated), the master-curve figures and the diagnosis page, in the
    lab's units with degC beside."""
    from asphalt_nscd.diagnosis import synthetic
    from asphalt_nscd.lab.table_format import MODULUS_UNITS

    table, _ = synthetic.generate(21, schedule="aashto_t342", n_specimens=3)
    lab = pd.DataFrame(
        {
            "Specimen ID": table["specimen"],
            "Temp (F)": table["temperature_C"] * 1.8 + 32,
            "Frequency (Hz)": table["frequency_Hz"],
            "|E*| (ksi)": table["E_norm_MPa"] / MODULUS_UNITS["ksi"],
            "Phase Angle (deg)": table["phase_deg"],
        }
    )
    # a path with a space, a quote and non-ASCII characters, as labs name folders
    folder = smoke_run / "my lab's d\u00e9p\u00f4t"
    folder.mkdir(exist_ok=True)
    lab.to_csv(folder / "m\u00efx.csv", index=False)
    (folder / "m\u00efx.test.json").write_text(
        json.dumps(
            {
                "test": "uniaxial_cylinder",
                "diameter_mm": 100,
                "height_mm": 150,
                "table": {"modulus_unit": "ksi", "temperature_unit": "F", "modulus_form": "norm_phase"},
            }
        )
    )
    # the README's command with its placeholder path replaced by this table's
    table_arg = f"TABLE={folder.name}/m\u00efx.csv"
    command = [table_arg if c.startswith("TABLE=") else c for c in readme_own_table_command().split()]
    assert command.count(table_arg) == 1, readme_own_table_command()
    env = newcomer_env()
    run(command + make_args(env), smoke_run, env)
    results = smoke_run / "results"
    law = json.loads((results / "diagnosis" / "generalized_burgers.json").read_text())
    assert sorted(float(T) for T in law["temperatures"]) == [-10.0, 4.0, 21.0, 37.0, 54.0]
    card = json.loads((results / "diagnosis" / "material_cards" / "prony.json").read_text())
    assert card["check"]["n_cells"] == 30 and card["exact"] and len(card["loss"]) == 6
    assert "*VISCOELASTIC, TIME=PRONY" in (results / "diagnosis" / "material_cards" / "abaqus.inp").read_text()
    assert "*MAT_GENERAL_VISCOELASTIC" in (results / "diagnosis" / "material_cards" / "lsdyna.k").read_text()
    assert (results / "diagnosis" / "figures" / "master_curve.png").stat().st_size > 20_000
    page = (results / "diagnosis" / "what_the_simulation_gets_wrong.md").read_text()
    assert "## Held-out errors" in page and "## Material card" in page and "T (degF (degC))" in page
    assert "no simulation ran" in page and page.count("Targets:") == 1
    measured = pd.read_csv(results / "lab" / "measured.csv")
    np.testing.assert_allclose(np.sort(measured["E_norm_MPa"]), np.sort(table["E_norm_MPa"]), rtol=1e-9)
    # the complete run, copied with its manifest; a second table under the same name, stopped once
    # its lab step has replaced results/lab, leaves that copy whole
    published = results / "tables" / f"{folder.name}-m\u00efx"
    manifest = json.loads((published / "manifest.json").read_text())
    assert manifest["table_sha256"] == content_sha256(folder / "m\u00efx.csv")
    assert {
        "lab/measured.csv",
        "diagnosis/generalized_burgers.json",
        "diagnosis/material_cards/abaqus.inp",
        "diagnosis/what_the_simulation_gets_wrong.md",
        "diagnosis/figures/master_curve.png",
    } <= set(manifest["files"])
    assert {rel: content_sha256(published / rel) for rel in manifest["files"]} == manifest["files"]
    first = {p.relative_to(published): p.read_bytes() for p in published.rglob("*") if p.is_file()}
    lab.assign(**{"|E*| (ksi)": lab["|E*| (ksi)"] * 1.25}).to_csv(folder / "m\u00efx.csv", index=False)
    lab_step = content_sha256(results / "lab" / "measured.csv")
    proc = subprocess.Popen(
        command + make_args(env),
        cwd=smoke_run,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + 600
        while _sha_or_none(results / "lab" / "measured.csv") in (lab_step, None):  # Snakemake removes it first
            assert proc.poll() is None and time.monotonic() < deadline, "the second run did not reach its lab step"
            time.sleep(0.5)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert {p.relative_to(published): p.read_bytes() for p in published.rglob("*") if p.is_file()} == first
    assert sorted(p.name for p in published.parent.iterdir()) == [published.name]


def readme_forecast_command() -> str:
    """The command of the README's section "A forecast from the binder"."""
    text = (REPO / "README.md").read_text()
    section = text.split("## A forecast from the binder", 1)[1]
    block = re.search(r"```(?:bash|sh)?\n(.*?)```", section, re.S)
    assert block, "README: no code block under 'A forecast from the binder'"
    lines = [ln.split("#")[0].strip() for ln in block.group(1).splitlines() if ln.split("#")[0].strip()]
    assert len(lines) == 1 and "TABLE=" in lines[0], lines
    return lines[0]


@pytest.mark.slow
def test_forecast_of_emptied_mixes_through_the_readme_command(smoke_run):
    """The shipped matched table as published (psi, radians, its sidecar), two mixes' |E*| and phase
    emptied, in a folder whose name has a space and non-ASCII characters, through the README's
    forecast command on the smoke configuration (six mixes): every model forecasts the two mixes at
    their 30 conditions, the held-out table and the page are written, the Level 1 tables are there,
    and the complete run is published with its manifest."""
    from asphalt_nscd.lab.matched import read_matched

    shipped = REPO / "data" / "binder_mix"
    folder = smoke_run / "binder d\u00e9p\u00f4t"
    folder.mkdir(exist_ok=True)
    lines = (shipped / "mixes_35.tsv").read_text(encoding="utf-8").split("\n")
    emptied = ("204", "236")

    def empty(line: str) -> str:
        cells = line.split("\t")
        return "\t".join("" if k in (1, 2) else c for k, c in enumerate(cells)) if cells[0] in emptied else line

    (folder / "mixes.tsv").write_text("\n".join([lines[0], *map(empty, lines[1:])]), encoding="utf-8")
    shutil.copy(shipped / "mixes_35.test.json", folder / "mixes.test.json")
    table_arg = f"TABLE={folder.name}/mixes.tsv"
    command = [table_arg if c.startswith("TABLE=") else c for c in readme_forecast_command().split()]
    env = newcomer_env()
    results = smoke_run / "results"
    own = sorted(p for p in (results / "forecast").rglob("*") if p.is_file())
    before = {p: content_sha256(p) for p in own}
    run(command + [f"CONFIG={SMOKE}", *make_args(env)], smoke_run, env)
    # the table's chain ran in its own folder: make run's (and the trained models of a mix file) left as they were
    assert (results / "forecasts" / f"{folder.name}-mixes.work" / "forecast" / "matched.csv").is_file()
    assert sorted(p for p in (results / "forecast").rglob("*") if p.is_file()) == own
    assert {p: content_sha256(p) for p in own} == before
    published = results / "forecasts" / f"{folder.name}-mixes"
    manifest = json.loads((published / "manifest.json").read_text())
    assert manifest["table_sha256"] == content_sha256(folder / "mixes.tsv")
    assert {rel: content_sha256(published / rel) for rel in manifest["files"]} == manifest["files"]
    forecast = pd.read_csv(published / "forecast" / "forecast.csv", dtype={"mix_id": str})
    assert set(forecast["mix_id"]) == set(emptied)
    models = set(forecast["model"])
    assert {"hirsch_published", "hirsch_recalibrated", "witczak_1_40d_recalibrated", "dem", "dem_extended"} <= models
    assert forecast.groupby(["mix_id", "model"]).size().eq(30).all()
    assert np.isfinite(forecast[["E_norm_MPa", "phase_deg"]].to_numpy()).all()
    truth = read_matched(shipped / "mixes_35.tsv")
    best = forecast[forecast["model"] == "hirsch_recalibrated"].merge(
        truth[["mix_id", "temperature_C", "frequency_Hz", "E_norm_MPa"]], on=["mix_id", "temperature_C", "frequency_Hz"]
    )
    assert len(best) == 60 and np.all(np.abs(np.log(best["E_norm_MPa_x"] / best["E_norm_MPa_y"])) < np.log(4))
    scores = pd.read_csv(published / "forecast" / "crossval.csv")
    assert set(scores["binder_route"]) == {"curve", "raw"} and scores["abs_logE_ci_low"].notna().any()
    level1 = pd.read_csv(published / "forecast" / "level1_tables.csv", dtype={"mix_id": str})
    assert set(level1["mix_id"]) == set(emptied) and set(level1["unit"]) == {"psi", "MPa"}
    assert len(level1) == 2 * 2 * 5 and {"0.1 Hz", "25 Hz"} <= set(level1.columns)
    page = (published / "forecast" / "forecast.md").read_text()
    assert "## Which model forecasts best" in page and "204, 236" in page


def readme_mix_command() -> str:
    """The command of the README's section "Your mix, forecast"."""
    text = (REPO / "README.md").read_text()
    section = text.split("## Your mix, forecast", 1)[1]
    block = re.search(r"```(?:bash|sh)?\n(.*?)```", section, re.S)
    assert block, "README: no code block under 'Your mix, forecast'"
    lines = [ln.split("#")[0].strip() for ln in block.group(1).splitlines() if ln.split("#")[0].strip()]
    assert len(lines) == 1 and "MIX=" in lines[0], lines
    return lines[0]


@pytest.mark.slow
def test_a_mix_file_through_the_readme_command(smoke_run):
    """The README's one-mix command on the smoke configuration's trained state: the example mix (a
    shipped mix written as DSR sweeps in kPa and rad/s, a sieve analysis in US sieve names, Pb, Gmm
    and Gmb) is forecast by every trained model, as the trained state forecasts the same mix read from
    the matched table with the same sample (within 0.5 % and 0.05 deg), with its intervals, Level 1
    tables, binder inputs and summary page, published with its manifest."""
    from asphalt_nscd.forecast import product
    from asphalt_nscd.forecast.models import read_curves, read_responses
    from asphalt_nscd.forecast.validation import binder_ids, with_binder_route
    from asphalt_nscd.lab.matched import read_matched

    command = readme_mix_command().split()
    env = newcomer_env()
    run(command + [f"CONFIG={SMOKE}", *make_args(env)], smoke_run, env)
    mix = Path(next(c for c in command if c.startswith("MIX=")).split("=", 1)[1])
    published = smoke_run / "results" / "mixes" / f"{mix.parent.name}-{mix.stem}"
    manifest = json.loads((published / "manifest.json").read_text())
    assert {rel: content_sha256(published / rel) for rel in manifest["files"]} == manifest["files"]
    lab = pd.read_csv(published / "forecast.csv", dtype={"mix_id": str})
    results = smoke_run / "results" / "forecast"
    state, training = product.read_state(results / "trained")
    table = read_matched(results / "matched.csv")
    routed = with_binder_route(
        table[table["mix_id"] == "211"].assign(E_norm_MPa=np.nan, phase_deg=np.nan),
        read_curves(results / "binder_curves.json"),
        binder_ids(table),
        "curve",
    )
    # the base sample's response and every sample variant's (results/forecast/variants/<name>/responses/)
    responses = read_responses(sorted(results.glob("**/responses/211_s*.npz")))
    ref = product.forecast_mixes(state, training, routed, responses)
    m = lab.merge(ref, on=["mix_id", "temperature_C", "frequency_Hz", "model"], suffixes=("_lab", "_table"))
    assert len(m) == len(ref) and {"dem_selected", "hirsch_recalibrated", "gradient_boosting_learned"} <= set(
        m["model"]
    )
    assert np.max(np.abs(np.log(m["E_norm_MPa_lab"] / m["E_norm_MPa_table"]))) < 0.005
    assert np.max(np.abs(m["phase_deg_lab"] - m["phase_deg_table"])) < 0.05
    level1 = pd.read_csv(published / "level1_tables.csv", dtype={"mix_id": str})
    assert {"psi", "MPa"} == set(level1["unit"]) and "25 Hz high" in level1
    assert "Level 1" in (published / "211.md").read_text()
