"""Artifact search and master curve of a measured table: the first diagnosis step, written once.

:func:`analyse` runs the artifact search of :mod:`asphalt_nscd.diagnosis.effects` (forward
selection of data artifacts on nested master-curve fits, noise levels from replicate
scatter), corrects the table and fits the 2S2P1D master curve of the corrected table
(:func:`asphalt_nscd.rheology.master_curve.fit_master_curve`). ``asphalt-nscd master-curve``
writes what the later steps need (:func:`to_json`; workflow:
``results/diagnosis/master_curve.json`` and the corrected table
``results/diagnosis/corrected_measured.csv``); ``extend-law`` fits the extended law on the
corrected table and ``diagnose`` reads both (:func:`read`, :func:`read_corrected`) instead of
searching again.

The JSON holds: the search settings (``alpha``, ``shift``, ``T_ref_C``), ``noise`` (sigma of
ln|E*| and of Phi in deg, from replicates or not), ``artifact_screening`` (reduced
chi-square of the screening model against the detection benchmark's clean tables),
``artifacts_corrected`` (names), ``notes``, ``effects`` (report entries of the data
artifacts, :func:`asphalt_nscd.diagnosis.effects.effect_entries`) and ``master_curve``
(every field of the :class:`~asphalt_nscd.rheology.master_curve.MasterCurveFit`, MPa,
plus the 2S2P1D constants and log10 aT per tested temperature for the reader). Floats are
written with Python's shortest round-trip representation, so :func:`read` gives the very
numbers :func:`analyse` computed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..io import InputError, checked, json_safe, read_csv, read_json
from ..rheology.master_curve import MasterCurveFit
from . import effects

#: columns of a corrected table (those of a measured table; the optional ones when present)
CORRECTED_COLUMNS = ("specimen", "temperature_C", "frequency_Hz", "E_norm_MPa", "phase_deg")


def analyse(
    measured: pd.DataFrame,
    alpha: float = 1e-3,
    shift: str = "wlf",
    T_ref_C: float | None = None,
    test=None,
    calibration: dict | None = None,
    limits: dict | None = None,
    level: float | None = None,
    outliers: bool = True,
) -> dict:
    """Artifact search and master curve of a measured table.

    ``test``: the declared test geometry (:mod:`asphalt_nscd.lab.geometry`); default the
    one :func:`asphalt_nscd.lab.measured.load_measured` attached to ``measured.attrs``.
    ``calibration``: the table's calibration (:func:`asphalt_nscd.diagnosis.calibration.calibrate`
    with the same ``alpha``, ``shift`` and ``limits``), whose level the first step uses
    (default: the nominal alpha / m). ``limits``: identifiability limits
    (:data:`asphalt_nscd.diagnosis.effects.IDENTIFIABILITY_LIMITS`). ``level``: a first-step
    level given directly (a cross-validation fold: the whole table's calibrated level),
    without a calibration. ``outliers``: look for outlying cells
    (:func:`asphalt_nscd.diagnosis.quality.cell_outliers`) and name an artifact only if the
    search without them names it too (its evidence must not rest on one or two cells); off in
    the cross-validation folds (cost).

    Returns
    -------
    dict with ``search`` (effects.ArtifactSearch), ``result`` (its ``run()``), ``corrected``
    (artifact-corrected table, same rows as ``measured``, with ``test_step`` when the table
    has ``test_order``), ``master`` (2S2P1D MasterCurveFit of the corrected table, MPa) and
    ``calibration`` (as given).

    Raises
    ------
    InputError
        if the measured table has fewer than 2 temperatures (no master curve), or the
        calibration was computed with other settings.
    """
    check_design(measured)
    test = test if test is not None else measured.attrs.get("test")
    search = effects.ArtifactSearch(measured, alpha=alpha, T_ref_C=T_ref_C, shift=shift, test=test, limits=limits)
    if calibration is not None:
        check_calibration(calibration, search)
        level = calibration["artifacts"]["level"]
    result = search.run(level=level)
    from ..lab.checks import quality_report
    from ..lab.table_format import DisplayUnits
    from .quality import cell_outliers

    found = cell_outliers(search, result["final"]) if outliers else []
    if found and result["selected"]:
        _drop_artifacts_resting_on_outliers(search, result, found, level, measured, alpha, shift, T_ref_C, test, limits)
    T_mc = T_ref_C if T_ref_C is not None else search.T_screen
    corrected, master = search.consistent_correction(result, shift=shift, T_ref_C=T_mc)
    quality = {"indicators": quality_report(measured, getattr(test, "quality_limits", None)), "outliers": found}
    return {
        "search": search,
        "result": result,
        "corrected": corrected,
        "master": master,
        "calibration": calibration,
        "units": DisplayUnits.of(test).as_dict(),
        "quality": quality,
    }


def _drop_artifacts_resting_on_outliers(
    search, result: dict, found: list, level, measured, alpha, shift, T_ref_C, test, limits
) -> None:
    """Rerun the search without the outlying cells ``found``; an artifact it does not name
    too is unnamed in ``result`` (its test entry says why) and the final fit is refitted
    without it, in place."""
    cells = {(round(o["temperature_C"], 6), float(o["frequency_Hz"])) for o in found}
    keep = [
        (round(float(T), 6), float(f)) not in cells for T, f in zip(measured["temperature_C"], measured["frequency_Hz"])
    ]
    rest = measured[np.asarray(keep)]
    try:
        again = effects.ArtifactSearch(rest, alpha=alpha, T_ref_C=T_ref_C, shift=shift, test=test, limits=limits).run(
            level=level
        )
    except ValueError:
        return
    named = {c.name for c in again["selected"]}
    kept = [c for c in result["selected"] if c.name in named]
    dropped = [c for c in result["selected"] if c.name not in named]
    if not dropped:
        return
    final = search.fit([c.term for c in kept]) if kept else result["base"]
    sizes = [len(c.term.names) for c in kept]
    start0 = final.x.size - sum(sizes)
    for i, c in enumerate(kept):
        t = result["tests"][c.name]
        start = start0 + sum(sizes[:i])
        t.update({"fit": final, "index": list(range(start, start + sizes[i]))})
    where = ", ".join(f"{T:g} degC / {f:g} Hz" for T, f in sorted(cells))
    for c in dropped:
        t = result["tests"][c.name]
        t["detected"] = False
        t["robustness"] = (
            f"not named: the search without the outlying cells ({where}) does not name it, so its "
            "evidence rests on those cells"
        )
    result["selected"], result["final"] = kept, final


def check_design(measured: pd.DataFrame, where: str = "measured table") -> None:
    """Raise InputError unless the table can carry a master curve: >= 2 isotherms with >= 3
    tested frequencies each (the isotherms must overlap in reduced frequency for their shifts
    to be determined), saying what the table has."""
    n_f = measured.groupby("temperature_C")["frequency_Hz"].nunique()
    good = n_f[n_f >= 3]
    if good.size < 2:
        have = ", ".join(f"{T:g} degC: {n}" for T, n in n_f.items())
        raise InputError(
            f"{where}: a master curve (and the temperature-aware law) needs >= 2 isotherms with >= 3 "
            f"tested frequencies each; the table has {n_f.size} isotherm(s) with frequencies {have}"
        )


def check_calibration(calibration: dict, search: effects.ArtifactSearch, where: str = "calibration JSON") -> None:
    """Raise InputError if ``calibration`` was computed with other search settings (alpha,
    shift, identifiability limits) than ``search``'s."""
    mine = {"alpha": search.alpha, "shift": search.shift, "limits": dict(search.limits)}
    theirs = {"alpha": calibration.get("alpha"), "shift": calibration.get("shift"), "limits": calibration.get("limits")}
    if theirs != mine:
        raise InputError(
            f"{where}: computed with {theirs}, the search uses {mine}; rerun 'asphalt-nscd "
            "calibrate-search' with the search's settings"
        )


def screening_summary(search: effects.ArtifactSearch, result: dict) -> dict:
    """Reduced chi-square of the artifact screening model against the benchmark's clean
    tables (:data:`effects.BENCH_SCREENING_CHI2`): ``within_bench_range`` when it is at most
    their 99th percentile (beyond it the measured false-alarm rates do not describe the table
    and its p-values are nominal)."""
    chi2 = search.chi2_per_dof(result["base"])
    bench = effects.BENCH_SCREENING_CHI2
    return {
        "model": "2S2P1D, free shift and vertical factor per isotherm, specimen factors",
        "chi2_per_dof": chi2,
        "bench_clean_chi2_per_dof_q99": bench["q99"],
        "bench_clean_chi2_per_dof_max": bench["max"],
        "within_bench_range": bool(chi2 <= bench["q99"]),
    }


@dataclass
class ArtifactRecord:
    """What the later steps use of an :func:`analyse` result (the content of the JSON).

    ``alpha``, ``shift``, ``T_ref_C`` (requested, None: the default): search settings;
    ``sigma``: noise of ln|E*| and of Phi (deg); ``noise_from_replicates``; ``screening``
    (:func:`screening_summary`); ``effects``: report entries of the data artifacts;
    ``artifacts``: names of the corrected ones; ``master``: the master curve of the corrected
    table; ``selection``: the procedure's family size, nominal and used level, statistic
    ``min_p`` and its calibrated p-value; ``calibration``: the table's calibration (None:
    nominal levels only); ``findings``: the master curve's parameters outside their plausible
    range or at a bound of the fit (:mod:`asphalt_nscd.rheology.plausibility`); ``notes``: free
    text; ``units``: the units the lab wrote the table in ({modulus, temperature}, for the
    figures and pages); ``free_shifts``: {T: log10 aT} of the screening fit; ``quality``: the
    lab's data-quality indicators and flagged rows (:func:`asphalt_nscd.lab.checks.quality_report`)
    and the outlying cells (:func:`asphalt_nscd.diagnosis.quality.cell_outliers`).
    """

    alpha: float
    shift: str
    T_ref_C: float | None
    sigma: tuple
    noise_from_replicates: bool
    screening: dict
    effects: list
    artifacts: list
    master: MasterCurveFit
    selection: dict = field(default_factory=dict)
    calibration: dict | None = None
    findings: list = field(default_factory=list)
    units: dict = field(default_factory=dict)
    free_shifts: dict = field(default_factory=dict)
    quality: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)


def record(analysis: dict, alpha: float, shift: str, T_ref_C: float | None) -> ArtifactRecord:
    """The :class:`ArtifactRecord` of an :func:`analyse` result run with these settings."""
    search, result = analysis["search"], analysis["result"]
    cal = analysis.get("calibration")
    from .calibration import null_statistics

    null = null_statistics(cal)
    names = [c.name for c in result["selected"]]
    selection = {
        "family_size": int(result["family_size"]),
        "nominal_level": float(result["nominal_level"]),
        "level": float(result["level"]),
        "min_p": float(result["min_p"]),
        "min_p_calibrated": effects.adjusted_p(result["min_p"], null),
        "level_source": "nominal alpha / m"
        if cal is None
        else f"min(calibrated, nominal): {cal['artifacts']['binding']}",
    }
    return ArtifactRecord(
        alpha=float(alpha),
        shift=shift,
        T_ref_C=T_ref_C,
        sigma=tuple(search.sigma),
        noise_from_replicates=bool(search.noise_from_replicates),
        screening=screening_summary(search, result),
        effects=json_safe(effects.effect_entries(search, result, null)),
        artifacts=names,
        master=analysis["master"],
        selection=selection,
        calibration=cal,
        findings=json_safe(analysis["master"].findings()),
        units=dict(analysis.get("units") or {}),
        quality=json_safe(analysis.get("quality") or {}),
        free_shifts={f"{T:g}": float(v) for T, v in zip(*search.free_shifts(result["final"])[:2])},
        notes=[f"artifacts corrected: {', '.join(names) or 'none detected'}"],
    )


def _fit_json(fit: MasterCurveFit, temperatures) -> dict:
    if fit.terms:
        raise ValueError("master curve with measurement-model terms: not a master curve of a corrected table")
    return {
        "model": "2S2P1D",
        "shift": fit.shift,
        "T_ref_C": float(fit.T_ref_C),
        "static_modulus": bool(fit.static_modulus),
        "parameters": {k: float(v) for k, v in fit.core().items()},
        "log10_aT": {f"{float(T):g}": float(fit.log_shift(T)) for T in temperatures},
        "names": list(fit.names),
        "x": [float(v) for v in fit.x],
        "se": [float(v) for v in fit.se],
        "cov": np.asarray(fit.cov, float).tolist(),
        "rss": float(fit.rss),
        "n_residuals": int(fit.n_residuals),
        "n_free": None if fit.n_free is None else int(fit.n_free),
        "temperatures_C": [float(T) for T in fit.temperatures],
        "specimens": [str(s) for s in fit.specimens],
        "sigma_lnE": float(fit.sigma_lnE),
        "sigma_phase_deg": float(fit.sigma_phase_deg),
        "specimen_mean": [float(v) for v in fit.specimen_mean],
    }


def to_json(rec: ArtifactRecord, source: dict | None = None) -> dict:
    """The JSON object of ``rec`` (module docstring); ``source``: free description of the
    input (e.g. the measured table's path)."""
    temps = rec.master.temperatures
    return {
        "source": source or {},
        "alpha": rec.alpha,
        "shift": rec.shift,
        "T_ref_C": rec.T_ref_C,
        "noise": {
            "sigma_lnE": float(rec.sigma[0]),
            "sigma_phase_deg": float(rec.sigma[1]),
            "from_replicates": rec.noise_from_replicates,
        },
        "artifact_screening": json_safe(rec.screening),
        "artifacts_corrected": list(rec.artifacts),
        "selection": json_safe(rec.selection),
        "calibration": json_safe(rec.calibration),
        "findings": json_safe(rec.findings),
        "units": dict(rec.units),
        "free_shifts": dict(rec.free_shifts),
        "quality": json_safe(rec.quality),
        "notes": list(rec.notes),
        "effects": json_safe(rec.effects),
        "master_curve": _fit_json(rec.master, temps),
    }


def read(path) -> ArtifactRecord:
    """The :class:`ArtifactRecord` of a JSON written by ``asphalt-nscd master-curve``.

    Raises InputError naming the file and the missing or malformed key.
    """
    return record_from(read_json(path, "master-curve JSON"), path)


def record_from(obj, path) -> ArtifactRecord:
    """The :class:`ArtifactRecord` of the object ``obj`` of a master-curve JSON read from
    ``path`` (:func:`asphalt_nscd.io.read_json`; the path names the file in errors).

    Raises InputError naming the file and the missing or malformed key.
    """
    try:
        m = obj["master_curve"]
        n = len(m["names"])
        x, se = np.array(m["x"], float), np.array(m["se"], float)
        cov = np.array(m["cov"], float)
        if x.shape != (n,) or se.shape != (n,) or cov.shape != (n, n):
            raise ValueError(f"master_curve: names, x, se and cov of inconsistent sizes ({n} names)")
        master = MasterCurveFit(
            names=list(m["names"]),
            x=x,
            se=se,
            cov=cov,
            rss=float(m["rss"]),
            n_residuals=int(m["n_residuals"]),
            shift=str(m["shift"]),
            T_ref_C=float(m["T_ref_C"]),
            static_modulus=bool(m["static_modulus"]),
            temperatures=np.array(m["temperatures_C"], float),
            specimens=[str(s) for s in m["specimens"]],
            sigma_lnE=float(m["sigma_lnE"]),
            sigma_phase_deg=float(m["sigma_phase_deg"]),
            specimen_mean=tuple(float(v) for v in m["specimen_mean"]),
            n_free=None if m["n_free"] is None else int(m["n_free"]),
        )
        noise = obj["noise"]
        entries = obj["effects"]
        if not isinstance(entries, list) or not all(isinstance(e, dict) and "name" in e for e in entries):
            raise ValueError("effects: expected a list of objects with a name")
        return ArtifactRecord(
            alpha=float(obj["alpha"]),
            shift=str(obj["shift"]),
            T_ref_C=None if obj["T_ref_C"] is None else float(obj["T_ref_C"]),
            sigma=(float(noise["sigma_lnE"]), float(noise["sigma_phase_deg"])),
            noise_from_replicates=bool(noise["from_replicates"]),
            screening=dict(obj["artifact_screening"]),
            effects=entries,
            artifacts=[str(a) for a in obj["artifacts_corrected"]],
            master=master,
            selection=dict(obj["selection"]),
            calibration=obj["calibration"],
            findings=list(obj["findings"]),
            units=dict(obj["units"]),
            quality=dict(obj["quality"]),
            free_shifts={k: float(v) for k, v in obj["free_shifts"].items()},
            notes=[str(t) for t in obj.get("notes", [])],
        )
    except KeyError as exc:
        raise InputError(
            f"{path}: key {exc.args[0]!r}: missing; expected the output of 'asphalt-nscd master-curve'"
        ) from None
    except (TypeError, ValueError) as exc:
        raise InputError(f"{path}: not a master-curve JSON of 'asphalt-nscd master-curve' ({exc})") from None


def read_corrected(path) -> pd.DataFrame:
    """An artifact-corrected table written by ``asphalt-nscd master-curve`` (floats read back
    exactly; ``specimen`` as text).

    Raises InputError naming the file and the missing column or the row of a bad value.
    """
    table = read_csv(path, dtype={"specimen": str})  # pandas >= 3 parses floats round-trip exactly
    if "specimen" not in table.columns:
        raise InputError(f"{path}: line 1 (header): missing column(s) ['specimen']")
    return checked(table, path, CORRECTED_COLUMNS[1:], positive=("frequency_Hz", "E_norm_MPa"))
