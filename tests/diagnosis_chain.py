"""The diagnosis chain as the workflow runs it, for the tests: ``master-curve`` (artifact
search and master curve, written once), ``extend-law`` (the law from the corrected table),
``diagnose`` (reads both). In memory (:func:`diagnose_table`) or through the CLI
(:func:`cli_chain`)."""

from __future__ import annotations

from pathlib import Path

from asphalt_nscd.cli import main
from asphalt_nscd.diagnosis import artifacts
from asphalt_nscd.diagnosis.budget import diagnose
from asphalt_nscd.diagnosis.crossval import Options, fit_extended


def diagnose_table(measured, alpha: float = 1e-3, shift: str = "wlf", T_ref_C=None, options=None, **kwargs):
    """(report, extra) of :func:`asphalt_nscd.diagnosis.budget.diagnose` after the upstream
    steps on ``measured``; a law that cannot be fitted leaves ``laws = None`` with its reason,
    as ``extend-law`` would stop with it. ``kwargs`` go to ``diagnose``."""
    a = artifacts.analyse(measured, alpha=alpha, shift=shift, T_ref_C=T_ref_C)
    rec = artifacts.record(a, alpha=alpha, shift=shift, T_ref_C=T_ref_C)
    corrected = a["corrected"].drop(columns=["test_step"], errors="ignore")
    options = options if options is not None else Options(alpha=alpha, artifact_shift=shift, T_ref_C=T_ref_C)
    laws, info, failure = None, None, None
    try:
        fit = fit_extended(measured, options, artifacts=(corrected, rec))
        failure = None if fit.law is not None else fit.reason
    except ValueError as exc:  # e.g. a Prony fit with no glassy compliance on an odd table
        failure = str(exc)
    if failure is None:
        laws = fit.law.laws(sorted(measured["temperature_C"].unique()))
        info = {
            "selection": {
                "chosen": fit.settings.as_dict(),
                "chosen_label": fit.settings.label(),
                "curve": fit.curve.to_dict(orient="records"),
            },
            "model": fit.law.description(),
        }
    return diagnose(measured, rec, corrected, laws, law_info=info, law_failure=failure, **kwargs)


def cli_chain(measured: Path, out: Path, fit_options=(), test=None) -> dict:
    """Run ``master-curve`` and ``extend-law`` on ``measured`` into directory ``out``; returns
    the paths and the ``diagnose`` arguments that read them (``--measured ... --law-json ...``)."""
    out.mkdir(parents=True, exist_ok=True)
    paths = {"search": out / "master_curve.json", "corrected": out / "corrected.csv", "law": out / "law.json"}
    search = [a for a in fit_options if a]  # only the artifact-search options apply to master-curve
    keep = []
    for i, a in enumerate(search):
        if a in ("--alpha", "--shift", "--t-ref"):
            keep += [a, search[i + 1]]
    testopt = ["--test", str(test)] if test is not None else []
    assert (
        main(
            [
                "master-curve",
                "--measured",
                str(measured),
                *keep,
                *testopt,
                "-o",
                str(paths["search"]),
                "--corrected",
                str(paths["corrected"]),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "extend-law",
                "--measured",
                str(measured),
                *fit_options,
                "--master-curve",
                str(paths["search"]),
                "--corrected-table",
                str(paths["corrected"]),
                "-o",
                str(paths["law"]),
            ]
        )
        == 0
    )
    paths["args"] = [
        "--measured",
        str(measured),
        *testopt,
        "--master-curve",
        str(paths["search"]),
        "--corrected-table",
        str(paths["corrected"]),
        "--law-json",
        str(paths["law"]),
    ]
    return paths
