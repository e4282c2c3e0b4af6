"""Held-out validation of the extended law: folds and nested selection of its settings.

Implements the protocol of docs/validation.md: ``lofo`` (leave one frequency out; the end
frequencies are extrapolations, reported apart), ``loto`` (leave one temperature out; the end
temperatures likewise) and ``loso`` (leave one specimen out: the law of the other specimens
predicts a new specimen, scored against that specimen's own values). Inside each fold
:func:`fit_extended` refits on the training rows only: artifact search and correction
(:func:`asphalt_nscd.diagnosis.artifacts.analyse`, when >= 2 temperatures with >= 3
frequencies each, at the first-step level calibrated on the whole table,
:mod:`asphalt_nscd.diagnosis.calibration`), replicate means, the law's settings chosen by
:func:`select_settings` (inner lofo folds and inner loto folds of the interior temperatures)
and the :class:`~asphalt_nscd.rheology.extended.ThermoLaw` on all training means. Models
predicted at the held-out cells: ``burgers`` (per isotherm, Eqs. 27-29; not loto),
``extended_law``, ``card_law`` (the law a material card carries, :func:`card_law_settings`),
``nscd_sample`` (harmonic steady state of the sample whose bonds follow the
fold's law / NF_s) and, added from ``run-2pb``, ``nscd_time_domain``; ``in_sample`` rows fit
every cell. A measured cell is predicted through the fold's :class:`MeasurementModel` (its
artifact correction at the held-out rows' frequency, strain and test order). The rows carry
relative errors against the replicate means as given (the paper's MRE); the scores with their
intervals are :mod:`asphalt_nscd.diagnosis.scores`'. A fold or model that cannot be computed
is kept with ``computable = False`` and the reason.

Choices (docs/choices.md, Diagnosis: the temperature-aware extended law and held-out validation):
* score of a setting: mean over the inner folds of max(MRE|E*|/tol_E, MRE Phi/tol_Phi),
  tolerances 3 % and 5 %;
* one-standard-error rule: the fewest fitted parameters, then the coarsest Prony series, then
  the best score; standard error sd sqrt(1/n + n_test/n_train) (Nadeau & Bengio 2003);
* the inner folds share the artifact correction of their outer training table;
* the law a material card carries (``Options.card_fit``, ``Options.card_shift``): the chosen
  settings without what a Prony series with a shift function cannot carry (vertical shift,
  static trend -> constant, refinement), with the card's own WLF shift, refitted by least squares
  at every cell: a card is judged at every cell the lab measured, where the robust fit of the
  selected law lets a cell it cannot follow go.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..io import InputError
from ..rheology import extended
from ..rheology.extended import LawSettings, ThermoLaw
from ..rheology.plausibility import describe as describe_findings
from ..rheology.metrics import at_temperature, cell_means, relative_errors, same_frequency, same_temperature

if TYPE_CHECKING:
    from ..harmonic.solver import HarmonicSystem
    from ..rheology.master_curve import MasterCurveFit

SCHEMES = ("lofo", "loto", "loso")
#: shift law of the law a material card carries: the card's own (WLF) or the chosen law's
CARD_SHIFTS = ("wlf", "law")
ROW_COLUMNS = (
    "scheme",
    "fold",
    "kind",
    "model",
    "temperature_C",
    "frequency_Hz",
    "n_replicates",
    "E_norm_MPa_measured",
    "phase_deg_measured",
    "E_norm_MPa_predicted",
    "phase_deg_predicted",
    "rel_err_E_norm",
    "rel_err_phase",
    "extrapolation",
    "settings",
    "computable",
    "reason",
)
#: fit failures that make a fold or a setting "not computable" (reported, not raised)
FIT_ERRORS = (ValueError, ArithmeticError, np.linalg.LinAlgError)


def candidate_grid(
    shifts=("wlf",), statics=("constant",), verticals=(False,), refines=(None,), per_decades=(2.0,)
) -> list[LawSettings]:
    """Every combination of the given options, simplest first (see ``LawSettings.complexity``).

    Raises ValueError on an invalid option (``LawSettings``) or an empty grid.
    """
    grid = [
        LawSettings(shift=s, static=st, vertical=v, refine=r, per_decade=p)
        for s, st, v, r, p in itertools.product(shifts, statics, verticals, refines, per_decades)
    ]
    if not grid:
        raise ValueError("empty candidate grid")
    return sorted(set(grid), key=lambda c: c.complexity())


@dataclass
class Options:
    """Settings of the fitting procedure (:func:`fit_extended`).

    ``candidates``: the law settings to choose from; ``tolerances``: tol_E, tol_Phi
    (fractions) of the fit residuals and of the selection score; ``margin_decades``: see
    :mod:`asphalt_nscd.rheology.extended`; ``artifacts``: search and correct data artifacts first; ``alpha``,
    ``artifact_shift``: significance level and master-curve shift of that search;
    ``T_ref_C``: reference temperature (None: the training temperature nearest the median);
    ``one_se``: one-standard-error rule (else the best score); ``burgers_starts``: local
    runs of each Burger's fit (``rheology.calibration.fit_burgers``); ``burgers``: predict
    with the Burger's law per isotherm too (crossval); ``level``: the first-step level of
    every artifact search (a fold's included), calibrated on the whole table
    (:mod:`asphalt_nscd.diagnosis.calibration`; None: the nominal alpha / m); ``limits``:
    identifiability limits of the search; ``card_fit``: loss of the law a material card carries
    (``least_squares`` or ``robust``, :data:`asphalt_nscd.rheology.extended.LOSSES`);
    ``card_shift``: its shift law (``wlf``: the card's own; ``law``: the chosen law's).
    """

    candidates: tuple = (LawSettings(),)
    tolerances: tuple = extended.TOLERANCES
    margin_decades: float = 2.0
    artifacts: bool = True
    alpha: float = 1e-3
    artifact_shift: str = "wlf"
    T_ref_C: float | None = None
    one_se: bool = True
    burgers_starts: int = 8
    burgers: bool = True
    level: float | None = None
    limits: dict | None = None
    card_fit: str = "least_squares"
    card_shift: str = "wlf"

    def __post_init__(self):
        self.candidates = tuple(self.candidates)
        if not self.candidates:
            raise ValueError("Options: no candidate setting")
        if self.card_fit not in extended.LOSSES:
            raise ValueError(f"Options: card_fit: expected one of {list(extended.LOSSES)}, got {self.card_fit!r}")
        if self.card_shift not in CARD_SHIFTS:
            raise ValueError(f"Options: card_shift: expected one of {list(CARD_SHIFTS)}, got {self.card_shift!r}")


@dataclass
class FitResult:
    """Output of :func:`fit_extended`: the ``law`` (None if nothing could be fitted, see
    ``reason``), the chosen ``settings``, the selection ``curve`` (one row per candidate),
    the ``corrected`` table, the ``artifacts`` corrected, free-text ``notes``, the
    ``measurement`` model of those artifacts (None without artifacts) and the law a material
    card carries (``card_law``, ``card_settings``: :func:`card_law_settings` fitted with
    ``Options.card_fit``, the chosen law itself when it is that law; None when no carriable law
    could be fitted)."""

    law: ThermoLaw | None
    settings: LawSettings | None
    curve: pd.DataFrame
    corrected: pd.DataFrame
    artifacts: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    reason: str = ""
    measurement: MeasurementModel | None = None
    card_law: ThermoLaw | None = None
    card_settings: LawSettings | None = None


@dataclass
class MeasurementModel:
    """The artifacts fitted on a (training) table as a measurement model of any rows.

    ``fit``: the final master-curve fit of the artifact search (its ``terms`` are the selected
    artifacts, :mod:`asphalt_nscd.diagnosis.effects`); ``strain_ref``: the search's reference
    strain (microstrain). :meth:`correction` gives, per row, the complex factor R that the
    search multiplies a measured point by to correct it (corrected = measured x R): the ratio
    of the fitted model without and with the artifacts, times exp(b eps_ref / 100) for a strain
    nonlinearity b (the corrected table is at eps -> 0). The prediction of a measured value
    from the material law L is then L / R.
    """

    fit: MasterCurveFit
    strain_ref: float = 0.0

    def correction(self, rows: pd.DataFrame) -> np.ndarray:
        """R (complex, shape (len(rows),)) at ``rows`` (columns of a measured table, and
        ``test_step`` when self-heating was fitted). A specimen the fit has not seen takes the
        reference specimen's factors.

        Raises ValueError if the rows lack a column an artifact needs.
        """
        from ..rheology.master_curve import MasterCurveProblem, data_arrays
        from .effects import VERTICAL, artifact_ratio

        fit = self.fit
        if not any(t.name != VERTICAL for t in fit.terms):
            return np.ones(len(rows), complex)
        d = data_arrays(rows)
        d["spec"] = (
            rows["specimen"].astype(str).map({s: i for i, s in enumerate(fit.specimens)}).fillna(0).to_numpy(int)
        )
        d["specimens"], d["temperatures"] = list(fit.specimens), fit.temperatures
        prob = MasterCurveProblem(
            d,
            shift=fit.shift,
            T_ref_C=fit.T_ref_C,
            static_modulus=fit.static_modulus,
            terms=fit.terms,
            sigma_lnE=fit.sigma_lnE,
            sigma_phase_deg=fit.sigma_phase_deg,
        )
        if list(prob.names) != list(fit.names):
            raise ValueError("the rows do not match the parameter layout of the artifact fit")
        return artifact_ratio(prob, fit, self.strain_ref)


def correct_artifacts(
    table: pd.DataFrame, options: Options, given=None
) -> tuple[pd.DataFrame, list, list, MeasurementModel | None]:
    """Artifact-corrected copy of ``table`` (step 1 of the module docstring).

    ``given``: (corrected table, :class:`~asphalt_nscd.diagnosis.artifacts.ArtifactRecord`)
    of ``asphalt-nscd master-curve`` on this very table, used instead of searching again
    (then no measurement model is returned).

    Returns (corrected table, names of the corrected artifacts, notes, measurement model or
    None when no artifact was corrected).
    """
    if not options.artifacts:
        return table, [], ["artifact search off"], None
    n_f = table.groupby("temperature_C")["frequency_Hz"].nunique()
    if n_f.size < 2 or n_f.min() < 3:
        return table, [], ["artifact search skipped: needs >= 2 temperatures and >= 3 frequencies at each"], None
    if given is not None:
        corrected, rec = given
        if len(corrected) != len(table):
            raise InputError(
                f"corrected table: {len(corrected)} rows, the measured table {len(table)}: not the "
                "artifact search of this table"
            )
        return corrected, list(rec.artifacts), list(rec.notes), None
    from .artifacts import analyse

    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # trial points of the fits
            a = analyse(
                table,
                alpha=options.alpha,
                shift=options.artifact_shift,
                T_ref_C=options.T_ref_C,
                limits=options.limits,
                level=options.level,
                outliers=False,
            )
    except FIT_ERRORS as exc:
        return table, [], [f"artifact search failed ({exc}); law fitted to the table as given"], None
    names = [c.name for c in a["result"]["selected"]]
    corrected = a["corrected"].drop(columns=["test_step", "test_step_centre"], errors="ignore")
    model = MeasurementModel(a["result"]["final"], float(a["search"].strain_ref)) if names else None
    return corrected, names, [f"artifacts corrected: {', '.join(names) or 'none detected'}"], model


def exclude_rows(table: pd.DataFrame, frequencies=(), temperatures=(), where="measured table") -> pd.DataFrame:
    """``table`` without every row at the given frequencies (Hz) and temperatures (degC; the
    rule of :func:`asphalt_nscd.rheology.metrics.same_temperature`): the training rows of a
    lofo or loto fold.

    Raises InputError naming ``where`` if a value is not in the table or no row is left.
    """
    keep = np.ones(len(table), bool)
    for col, values, opt, same in (
        ("frequency_Hz", frequencies, "--exclude-frequency", same_frequency),
        ("temperature_C", temperatures, "--exclude-temperature", same_temperature),
    ):
        for v in values:
            hit = same(table[col].to_numpy(float), v)
            if not hit.any():
                raise InputError(f"{opt} {v:g}: no row of {where} has {col} = {v:g}")
            keep &= ~hit
    if not keep.any():
        raise InputError(f"{where}: no row left after --exclude-frequency/--exclude-temperature")
    return table[keep].reset_index(drop=True)


def _t_ref(cells: pd.DataFrame, options: Options) -> float:
    if options.T_ref_C is not None:
        return float(options.T_ref_C)
    temps = np.unique(cells["temperature_C"].to_numpy(float))
    return float(temps[np.argmin(np.abs(temps - np.median(temps)))])


def fit_structures(cells: pd.DataFrame, structures, T_ref_C: float, tolerances) -> dict:
    """Backbones of every structure (``LawSettings.structure``) on ``cells``.

    Simplest first: a structure starts from the fitted simpler structure of the same shift
    law with the most parameters in common (its extra parameters from 0), and the base
    structures (no trend, vertical shift or refinement) from several cold starts. Only
    ``cells`` steer the fits.

    Returns
    -------
    dict structure -> Backbone, or the error message (str) when the fit is not computable.
    """
    out: dict[tuple, extended.Backbone | str] = {}
    ordered = sorted(set(structures), key=lambda s: LawSettings(*s).complexity())  # a total order
    for st in ordered:
        settings = LawSettings(*st)
        base = not (settings.vertical or settings.refine or settings.static == "trend")
        start = None
        if not base:
            names = set(extended.backbone_names(settings, np.unique(cells["temperature_C"])))
            fitted = [
                bb for s2, bb in out.items() if not isinstance(bb, str) and s2[0] == st[0] and set(bb.names) <= names
            ]
            if fitted:
                ref = max(fitted, key=lambda bb: len(bb.names))
                start = dict(zip(ref.names, ref.x))
        try:
            out[st] = extended.fit_backbone(cells, settings, T_ref_C, tolerances, start=start)
        except FIT_ERRORS as exc:
            out[st] = f"not computable: {exc}"
    return out


def _fold_values(cells: pd.DataFrame, scheme: str) -> np.ndarray:
    key = "frequency_Hz" if scheme == "lofo" else "temperature_C"
    return np.unique(cells[key].to_numpy(float))


def fold_split(cells: pd.DataFrame, scheme: str, value: float):
    """(training mask, reason or '') of one fold on a cell (or row) table."""
    key, same = ("frequency_Hz", same_frequency) if scheme == "lofo" else ("temperature_C", same_temperature)
    train = ~same(cells[key].to_numpy(float), value)
    temps = np.unique(cells["temperature_C"].to_numpy(float)[train])
    if scheme == "loto" and temps.size < 3:
        return train, (
            f"leaves {temps.size} temperature(s): the shift law (2 constants) needs >= 3 "
            "training temperatures to carry the law to another temperature"
        )
    if temps.size < 2:
        return train, f"leaves {temps.size} temperature(s): the temperature-aware law needs >= 2"
    if not train.any():
        return train, "no training cell left"
    return train, ""


def _inner_folds(cells: pd.DataFrame) -> list:
    """(scheme, value) of the inner folds: every frequency (lofo) and every interior
    temperature (loto) whose training part is computable."""
    out = [("lofo", v) for v in _fold_values(cells, "lofo")]
    temps = _fold_values(cells, "loto")
    out += [("loto", v) for v in temps[1:-1]]
    return [(s, v) for s, v in out if not fold_split(cells, s, v)[1]]


def _fold_score(law: ThermoLaw, test: pd.DataFrame, tolerances) -> float:
    try:
        m = extended.law_metrics(law, test)
    except FIT_ERRORS:
        return np.inf
    eE, eP = m["rel_err_E_norm"].to_numpy(float), m["rel_err_phase"].to_numpy(float)
    if not (np.all(np.isfinite(eE)) and np.all(np.isfinite(eP))):
        return np.inf
    return float(max(eE.mean() / tolerances[0], eP.mean() / tolerances[1]))


def select_settings(cells: pd.DataFrame, options: Options) -> tuple[LawSettings | None, pd.DataFrame, dict]:
    """Choose the law settings by inner cross-validation on cell means (module docstring).

    Every structure is fitted on all ``cells`` first (returned, reused by :func:`fit_extended`).
    Each inner fold fits every structure on its own training cells, started as
    :func:`fit_structures` starts without parents (the simpler structure of the same fold), so
    that no inner held-out cell steers its fold's fit. The score's standard error accounts for
    the overlap of the folds' training sets (Nadeau & Bengio 2003: sd sqrt(1/n + n_test/n_train)).

    Returns
    -------
    (settings, curve, backbones)
        ``curve``: one row per candidate: ``settings`` (label), its fields, ``n_params``,
        ``cv_score`` (mean over the inner folds), ``cv_score_se``, ``n_folds``, ``chosen``,
        ``reason`` (why a candidate has no score). With one candidate, or no computable inner
        fold, the first candidate is returned without a score (``reason`` says why).
        ``backbones``: structure -> Backbone (or error text) fitted on all ``cells``.
    """
    cands = list(options.candidates)
    T_ref = _t_ref(cells, options)
    n_T = cells["temperature_C"].nunique()
    structures = [c.structure for c in cands]
    fitted = fit_structures(cells, structures, T_ref, options.tolerances)
    folds = _inner_folds(cells) if len(cands) > 1 else []
    rows: dict[LawSettings, dict[str, Any]] = {c: {"scores": [], "reason": ""} for c in cands}
    ratios = []
    for scheme, value in folds:
        train, _ = fold_split(cells, scheme, value)
        tr, te = cells[train], cells[~train]
        ratios.append(len(te) / max(len(tr), 1))
        # started from fits of the inner training cells only (no parent fitted on the inner
        # held-out cells: their values must not steer the inner fold's fit)
        bbs = fit_structures(tr, structures, T_ref, options.tolerances)
        for c in cands:
            bb = bbs[c.structure]
            if isinstance(bb, str):
                rows[c]["scores"].append(np.inf)
                rows[c]["reason"] = bb
                continue
            try:
                law = extended.fit_law(tr, c, T_ref, options.tolerances, options.margin_decades, backbone=bb)
            except FIT_ERRORS as exc:
                rows[c]["scores"].append(np.inf)
                rows[c]["reason"] = f"not computable: {exc}"
                continue
            rows[c]["scores"].append(_fold_score(law, te, options.tolerances))
    # standard error of a mean over overlapping cross-validation folds (their training sets
    # share most cells, so the fold scores are correlated): the corrected resampled variance of
    # Nadeau & Bengio (2003, Machine Learning 52, 239-281), var (1/n + n_test/n_train)
    overlap = float(np.mean(ratios)) if ratios else 0.0
    curve = []
    for c in cands:
        s = np.asarray(rows[c]["scores"], float)
        ok = s.size > 0 and np.all(np.isfinite(s))
        reason = rows[c]["reason"]
        if not folds:
            reason = (
                "single candidate: no selection"
                if len(cands) == 1
                else "no computable inner fold: first candidate kept"
            )
        elif not ok and not reason:
            reason = "a prediction was not finite"
        curve.append(
            {
                "settings": c.label(),
                **c.as_dict(),
                "n_params": c.n_params(n_T),
                "cv_score": float(s.mean()) if ok else np.nan,
                "cv_score_se": float(s.std(ddof=1) * np.sqrt(1.0 / s.size + overlap)) if ok and s.size > 1 else np.nan,
                "n_folds": int(s.size),
                "chosen": False,
                "reason": "" if ok else reason,
            }
        )
    curve = pd.DataFrame(curve)
    findings = [[] if isinstance(fitted[c.structure], str) else fitted[c.structure].findings() for c in cands]
    curve["plausible"] = [not f for f in findings]
    curve["findings"] = [describe_findings(f) for f in findings]
    curve["carriable"] = [c.carriable for c in cands]
    curve["chosen_card"] = False
    curve["note"] = ""
    scores = {i: np.asarray(rows[c]["scores"], float) for i, c in enumerate(cands)}
    chosen, note = _choose(curve, scores, overlap, options.one_se, np.ones(len(curve), bool))
    curve.loc[chosen, "chosen"] = True
    curve.loc[chosen, "note"] = note
    card, card_note = _choose(curve, scores, overlap, options.one_se, curve["carriable"].to_numpy(bool))
    if card is not None:
        curve.loc[card, "chosen_card"] = True
        if card != chosen and card_note:
            curve.loc[card, "note"] = (
                "material card (a law without vertical shift, static trend or refinement): " + card_note
            )
    return cands[chosen], curve, fitted


#: a gain over the best plausible candidate counts when it exceeds this many of its standard errors
GAIN_Z = 1.96


def _one_se_pick(curve: pd.DataFrame, sel: np.ndarray, one_se: bool) -> int:
    """The simplest candidate within one standard error of the best score among ``sel``:
    the fewest fitted parameters, then the coarsest Prony series (fewest internal variables
    per bond), then the best score (e.g. between the shift laws)."""
    best = int(curve.loc[sel, "cv_score"].idxmin())
    limit = curve.loc[best, "cv_score"]
    if one_se and np.isfinite(curve.loc[best, "cv_score_se"]):
        limit += curve.loc[best, "cv_score_se"]
    within = curve[sel & (curve["cv_score"] <= limit + 1e-12).to_numpy()]
    fewest = within[within["n_params"] == within["n_params"].min()]
    fewest = fewest[fewest["per_decade"] == fewest["per_decade"].min()]
    return int(fewest["cv_score"].idxmin())


def _choose(curve: pd.DataFrame, scores: dict, overlap: float, one_se: bool, mask: np.ndarray):
    """(index, note) of the candidate chosen among ``mask``: the one-standard-error rule
    (:func:`_one_se_pick`) among the plausible candidates, unless the best implausible one
    beats the best plausible one by a held-out gain larger than GAIN_Z of its own standard
    errors (the paired inner-fold differences, Nadeau & Bengio's correction); (None, note)
    when ``mask`` holds no candidate."""
    mask = np.asarray(mask, bool)
    if not mask.any():
        return None, "no candidate"
    scored = curve["cv_score"].notna().to_numpy() & mask
    if not scored.any():  # nothing to choose from: the simplest candidate
        return int(np.flatnonzero(mask)[0]), "no computable inner fold: the simplest candidate"
    plaus = scored & curve["plausible"].to_numpy(bool)
    pick = _one_se_pick(curve, scored, one_se)
    if curve.loc[pick, "plausible"]:
        return pick, ""
    if not plaus.any():
        return pick, "no candidate with plausible parameters: " + str(curve.loc[pick, "findings"])
    bi = int(curve.loc[scored & ~plaus, "cv_score"].idxmin())
    bp = int(curve.loc[plaus, "cv_score"].idxmin())
    d = scores[bp] - scores[bi]
    gain = float(np.mean(d))
    se = float(np.std(d, ddof=1) * np.sqrt(1.0 / d.size + overlap)) if d.size > 1 else np.inf
    text = (
        f"held-out gain of the best implausible candidate ({curve.loc[bi, 'settings']}: "
        f"{curve.loc[bi, 'findings']}) over the best plausible one ({curve.loc[bp, 'settings']}): "
        f"{gain:.3g} +- {se:.3g} in score"
    )
    if gain - GAIN_Z * se > 0:
        return pick, text + f", more than {GAIN_Z:g} standard errors: the implausible law is kept"
    return _one_se_pick(curve, plaus, one_se), text + f", within {GAIN_Z:g} standard errors: a plausible law is chosen"


def fit_extended(table: pd.DataFrame, options: Options, artifacts=None) -> FitResult:
    """The whole fitting procedure on a (training) table: steps 1-4 of the module docstring.

    ``artifacts``: the artifact search already written for this table (``given`` of
    :func:`correct_artifacts`). Never raises on a table
    :func:`asphalt_nscd.lab.measured.load_measured` accepts: a failure returns ``law = None``
    and the ``reason``.
    """
    corrected, artifacts, notes, measurement = correct_artifacts(table, options, artifacts)
    cells = cell_means(corrected)
    n_T = cells["temperature_C"].nunique()
    if n_T < 2:
        return FitResult(
            None,
            None,
            pd.DataFrame(),
            corrected,
            artifacts,
            notes,
            f"{n_T} temperature(s): the temperature-aware law needs >= 2",
            measurement,
        )
    settings, curve, backbones = select_settings(cells, options)
    T_ref = _t_ref(cells, options)
    law, chosen, last = _fit_first(
        cells, [settings] + [c for c in options.candidates if c != settings], backbones, T_ref, options, notes
    )
    if law is None:
        return FitResult(
            None, None, curve, corrected, artifacts, notes, f"no setting could be fitted ({last})", measurement
        )
    if chosen != settings:
        curve["chosen"] = curve["settings"] == chosen.label()
    law.info = {"artifacts_corrected": artifacts, "notes": list(notes)}
    card_law, card = _fit_card_law(cells, law, chosen, curve, backbones, T_ref, options, notes)
    if card_law is not None and card_law is not law:
        card_law.info = {"artifacts_corrected": artifacts, "notes": list(notes)}
    return FitResult(
        law,
        chosen,
        curve,
        corrected,
        artifacts,
        notes,
        measurement=measurement,
        card_law=card_law,
        card_settings=card if card_law is not None else None,
    )


def card_law_settings(chosen: LawSettings, options: Options) -> LawSettings:
    """The settings of the law a material card carries (module docstring): ``chosen`` without a
    vertical shift or refinement, a static trend made constant, the shift of ``options.card_shift``."""
    return LawSettings(
        shift="wlf" if options.card_shift == "wlf" else chosen.shift,
        static="constant" if chosen.static == "trend" else chosen.static,
        per_decade=chosen.per_decade,
    )


def _fit_card_law(cells, law: ThermoLaw, chosen: LawSettings, curve, backbones, T_ref, options: Options, notes):
    """(law, settings) a material card carries (:func:`card_law_settings`, fitted with
    ``options.card_fit`` from the cold starts and from the chosen law's backbone); the chosen law
    itself when it is that law; else the first carriable candidate that can be fitted (robust), or
    (None, None)."""
    settings = card_law_settings(chosen, options)
    if settings == chosen and options.card_fit == law.backbone.loss:
        return law, chosen
    try:
        start = _card_start(law, settings, cells)
        card_law = extended.fit_law(
            cells, settings, T_ref, options.tolerances, options.margin_decades, loss=options.card_fit, starts=[start]
        )
        return card_law, settings
    except FIT_ERRORS as exc:
        notes.append(
            f"material card law {settings.label()} ({options.card_fit}) not computable ({exc}); the card "
            "carries the first carriable candidate instead"
        )
    if chosen.carriable:
        return law, chosen
    picked = [c for c, on in zip(options.candidates, curve["chosen_card"]) if on] if len(curve) else []
    fallback = LawSettings(
        shift=chosen.shift,
        static="constant" if chosen.static == "trend" else chosen.static,
        per_decade=chosen.per_decade,
    )
    order = picked + [c for c in options.candidates if c.carriable and c not in picked] + [fallback]
    card_law, card, _ = _fit_first(cells, order, backbones, T_ref, options, notes)
    return card_law, card


def _card_start(law: ThermoLaw, settings: LawSettings, cells) -> dict:
    """Starting point of the card law's fit from the chosen law's backbone (its core and static
    modulus; an Arrhenius shift turned into the WLF law nearest it over the tested temperatures)."""
    bb = law.backbone
    start = {n: float(v) for n, v in zip(bb.names, bb.x) if not n.startswith("dlog10_")}
    if settings.shift == "wlf" and bb.settings.shift != "wlf":
        from ..rheology.export import card_wlf

        T = cells["temperature_C"].to_numpy(float)
        C1, C2, _, _ = card_wlf(
            {"law": "Arrhenius", "Ea_kJ_mol": bb.value("Ea_kJ_mol")}, bb.T_ref_C, float(T.min()), float(T.max())
        )
        start.update({"C1": C1, "C2_K": C2})
    return start


def _fit_first(cells, order, backbones, T_ref, options, notes):
    """(law, settings, last error) of the first settings of ``order`` that can be fitted on
    ``cells`` (backbones reused where fitted), or (None, None, last error)."""
    last = ""
    for c in order:
        try:
            bb = backbones.get(c.structure)
            if isinstance(bb, str):
                raise ValueError(bb)
            return extended.fit_law(cells, c, T_ref, options.tolerances, options.margin_decades, backbone=bb), c, ""
        except FIT_ERRORS as exc:
            last = f"{c.label()}: {exc}"
            notes.append(f"setting {c.label()} not computable on the whole table ({exc})")
    return None, None, last


def law_file_object(
    fit: FitResult, measured: pd.DataFrame, temperatures, options: Options, source: dict, card: bool = False
) -> dict:
    """The law file of ``extend-law`` (:mod:`asphalt_nscd.rheology.law_file`): the law of
    ``fit`` (``card``: the law a material card carries, ``fit.card_law``) at ``temperatures``
    (degC) with its in-sample MREs against the corrected and (``_vs_measured``) the measured
    replicate means of ``measured``, the ``selection`` (chosen settings, rule, curve, notes),
    ``card`` (the carried law's settings and whether it is the selected law) and the
    ``source`` (given keys, then the artifact search's).

    Raises ValueError with ``card`` when no carriable law could be fitted."""
    law = fit.card_law if card else fit.law
    if law is None:
        raise ValueError("no law that a Prony series with a shift function carries could be fitted")
    obj = law.to_json(temperatures, {"": cell_means(fit.corrected), "_vs_measured": cell_means(measured)})
    notes = [n for n in fit.curve.get("note", pd.Series(dtype=str)).astype(str) if n] if len(fit.curve) else []
    assert fit.settings is not None  # chosen with every fitted law
    obj["selection"] = {
        "chosen": fit.settings.as_dict(),
        "chosen_label": fit.settings.label(),
        "rule": (
            "simplest candidate within one standard error of the best inner-CV score "
            "(fewest fitted parameters, then coarsest Prony series) among the candidates "
            "with plausible parameters, unless an implausible one gains more than "
            f"{GAIN_Z:g} standard errors"
        )
        if options.one_se
        else "best inner-CV score",
        "notes": notes,
        "curve": fit.curve.to_dict(orient="records"),
    }
    card_fit = None if fit.card_law is None else fit.card_law.backbone.loss
    obj["card"] = {
        "settings": None if fit.card_settings is None else fit.card_settings.label(),
        "fit": card_fit,
        "selected_fit": fit.law.backbone.loss if fit.law is not None else None,
        "is_selected_law": fit.card_law is not None and fit.card_law is fit.law,
        "this_file": "card law" if card else "selected law",
    }
    obj["source"] = {
        **source,
        "artifact_search": {"master_curve": "2S2P1D", "shift": options.artifact_shift, "alpha": options.alpha},
        "artifacts_corrected": fit.artifacts,
        "notes": fit.notes,
        "mre_reference": "in-sample: the artifact-corrected replicate means the law was fitted on "
        "(and, _vs_measured, the measured ones); held-out errors: asphalt-nscd crossval",
    }
    return obj


@dataclass
class SampleModel:
    """The numerical sample for the ``nscd_sample`` predictions: a harmonic system, its
    EN 12697-26 geometry, the network factor NF_s (transfer JSON) and the solver options."""

    system: HarmonicSystem
    geometry_mm: dict
    network_factor: float
    name: str
    inertia: str = "full"
    amplitude_m: float = 63e-6

    @classmethod
    def load(cls, sample_path, transfer_path, inertia: str = "full") -> "SampleModel":
        """Sample file + its transfer JSON (``asphalt-nscd harmonic-transfer``): the harmonic
        system is built with the transfer JSON's kinematics and Poisson's ratio.

        Raises InputError naming the file on a bad sample or transfer JSON.
        """
        from ..harmonic.network import network_from_sample
        from ..sample.store import read_sample, specimen_geometry_mm
        from ..harmonic.solver import HarmonicSystem
        from ..harmonic.transfer import read_transfer_json

        tr = read_transfer_json(transfer_path)
        sample = read_sample(sample_path)
        network = network_from_sample(sample)
        if str(tr["sample"]) != str(network.name):
            raise InputError(
                f"{transfer_path}: key 'sample': the factor is of sample {tr['sample']!r}, "
                f"the sample file {sample_path} is {network.name!r}"
            )
        system = HarmonicSystem(
            network, nu=float(tr["nu"]), bond_kinematics=tr["bond_kinematics"], head_rotation=tr["head_rotation"]
        )
        return cls(system, specimen_geometry_mm(sample), float(tr["network_factor"]), str(network.name), inertia)

    def predict(self, law, temperature_C: float, frequencies_Hz) -> np.ndarray:
        """Sample |E*| (MPa) and Phi (deg) with bonds following ``law`` (MPa) / NF_s:
        array (n, 2)."""
        from ..harmonic.response import harmonic_rows

        bond_law = law.scaled(1e6 / self.network_factor)
        rows = harmonic_rows(
            self.system,
            bond_law,
            temperature_C,
            frequencies_Hz,
            self.geometry_mm,
            amplitude=self.amplitude_m,
            inertia=self.inertia,
        )
        return np.array([[r["E_norm_MPa"], r["phase_deg"]] for r in rows], float)


def _row(scheme, fold, kind, model, cell, pred=None, extrapolation=False, settings="", reason=""):
    E_m, P_m = float(cell["E_norm_MPa"]), float(cell["phase_deg"])
    ok = pred is not None and np.all(np.isfinite(pred))
    E_p, P_p = (float(pred[0]), float(pred[1])) if ok else (np.nan, np.nan)
    return {
        "scheme": scheme,
        "fold": fold,
        "kind": kind,
        "model": model,
        "temperature_C": float(cell["temperature_C"]),
        "frequency_Hz": float(cell["frequency_Hz"]),
        "n_replicates": int(cell["n"]),
        "E_norm_MPa_measured": E_m,
        "phase_deg_measured": P_m,
        "E_norm_MPa_predicted": E_p,
        "phase_deg_predicted": P_p,
        "rel_err_E_norm": float(relative_errors(E_p, E_m)) if ok else np.nan,
        "rel_err_phase": float(relative_errors(P_p, P_m)) if ok and P_m > 0 else np.nan,
        "extrapolation": bool(extrapolation),
        "settings": settings,
        "computable": bool(ok),
        "reason": "" if ok else (reason or "prediction not finite"),
    }


def _burgers_rows(
    scheme, fold, kind, train_rows: pd.DataFrame, test: pd.DataFrame, extrapolation, n_starts: int = 8
) -> list:
    from ..rheology.calibration import fit_burgers
    from ..rheology.laws import GeneralizedBurgers

    out = []
    for T, g in test.groupby("temperature_C"):
        tr = at_temperature(train_rows, T)
        law, reason = None, ""
        if scheme == "loto" and kind == "held_out":
            reason = "a Burger's law per isotherm has no temperature dependence (lofo only)"
        else:
            try:
                p = fit_burgers(tr["frequency_Hz"], tr["E_norm_MPa"], tr["phase_deg"], n_starts=n_starts)
                law = GeneralizedBurgers.burgers(p["Em_MPa"], p["eta_m_MPa_s"], p["Ek_MPa"], p["eta_k_MPa_s"])
            except FIT_ERRORS as exc:
                reason = f"Burger's fit at {T:g} degC: {exc}"
        for _, cell in g.iterrows():
            pred = None
            if law is not None:
                E = law.complex_modulus(2 * np.pi * cell["frequency_Hz"])
                pred = (abs(E), np.degrees(np.angle(E)))
            out.append(
                _row(scheme, fold, kind, "burgers", cell, pred, extrapolation(cell), "Burger's per isotherm", reason)
            )
    return out


def _as_measured(
    E_cells: np.ndarray | float, cells: pd.DataFrame, rows: pd.DataFrame | None, fit: FitResult | None
) -> np.ndarray:
    """Predicted replicate means (|E*| MPa, Phi deg; array (n_cells, 2)) of the measured
    table from the material's E* per cell: each held-out row's prediction is E* / R (R of the
    fold's artifact fit at that row, :class:`MeasurementModel`), averaged per cell like the
    measured replicates. Without artifacts: |E*| and Phi of E*."""
    E = np.asarray(E_cells, complex)
    if fit is None or fit.measurement is None:
        return np.column_stack([np.abs(E), np.degrees(np.angle(E))])
    assert rows is not None  # a measurement model comes with the measured rows
    R = fit.measurement.correction(rows)
    key = {(float(T), float(f)): i for i, (T, f) in enumerate(zip(cells["temperature_C"], cells["frequency_Hz"]))}
    idx = np.array([key[(float(T), float(f))] for T, f in zip(rows["temperature_C"], rows["frequency_Hz"])])
    M = E[idx] / R
    out = np.zeros((len(cells), 2))
    for i in range(len(cells)):
        sel = idx == i
        out[i] = np.abs(M[sel]).mean(), np.degrees(np.angle(M[sel])).mean()
    return out


def _law_rows(
    scheme,
    fold,
    kind,
    fit: FitResult | None,
    test: pd.DataFrame,
    sample,
    extrapolation,
    reason="",
    rows: pd.DataFrame | None = None,
) -> list:
    """Rows of the extended law, of the law a material card carries (``card_law``) and of the
    sample at the cells ``test``; ``rows``: the measured rows of those cells (with
    ``test_step``), for the fold's measurement model."""
    out = []
    models = [
        ("extended_law", None if fit is None else fit.law, None if fit is None else fit.settings),
        ("card_law", None if fit is None else fit.card_law, None if fit is None else fit.card_settings),
    ]
    for T, g in test.groupby("temperature_C"):
        f = g["frequency_Hz"].to_numpy(float)
        g_rows = None if rows is None else at_temperature(rows, T)
        preds = {}
        for name, thermo, settings in models:
            law, why = None, reason
            if not why and (fit is None or thermo is None):
                why = fit.reason if fit is not None and fit.reason else "not fitted"
            if not why:
                assert thermo is not None  # why names the reason when there is no law
                try:
                    law = thermo.law_at(float(T))
                except (InputError, *FIT_ERRORS) as exc:
                    why = f"law at {T:g} degC: {exc}"
            pred = None
            if law is not None:
                try:
                    pred = _as_measured(law.complex_modulus(2 * np.pi * f), g, g_rows, fit)
                except FIT_ERRORS as exc:
                    why = f"measurement model of the fold's artifacts at {T:g} degC: {exc}"
            preds[name] = (law, pred, why, settings.label() if settings is not None else "")
        law, pred_law, why, label = preds["extended_law"]
        pred_nscd, why_s = None, ""
        if sample is not None and pred_law is not None:
            try:
                s = sample.predict(law, float(T), f)
                pred_nscd = _as_measured(s[:, 0] * np.exp(1j * np.radians(s[:, 1])), g, g_rows, fit)
            except FIT_ERRORS as exc:
                why_s = f"harmonic solve at {T:g} degC: {exc}"
        for i, (_, cell) in enumerate(g.iterrows()):
            x = extrapolation(cell)
            for name in ("extended_law", "card_law"):
                _, pred, w, lab = preds[name]
                out.append(_row(scheme, fold, kind, name, cell, None if pred is None else pred[i], x, lab, w))
            if sample is not None:
                out.append(
                    _row(
                        scheme,
                        fold,
                        kind,
                        "nscd_sample",
                        cell,
                        None if pred_nscd is None else pred_nscd[i],
                        x,
                        label,
                        why or why_s,
                    )
                )
    return out


@dataclass
class CrossvalResult:
    """Output of :func:`crossval`: ``rows`` (module docstring, columns :data:`ROW_COLUMNS`),
    ``curves`` (the selection curve of the whole table, ``fold = all``, and of every outer
    fold), ``full`` (FitResult on the whole table) and ``fold_fits`` ({fold label: FitResult})."""

    rows: pd.DataFrame
    curves: pd.DataFrame
    full: FitResult
    fold_fits: dict


def fold_label(scheme: str, value) -> str:
    """``10`` (Hz, lofo), ``21`` (degC, loto): the held-out value, ``%g``; the specimen's
    name (loso)."""
    return str(value) if scheme == "loso" else f"{float(value):g}"


def crossval(
    table: pd.DataFrame,
    scheme: str,
    options: Options,
    sample: SampleModel | None = None,
    time_domain: pd.DataFrame | None = None,
    full: FitResult | None = None,
) -> CrossvalResult:
    """Held-out and in-sample predictions of every model for one scheme (module docstring).

    Parameters
    ----------
    table : DataFrame
        Validated measured table (``lab.measured.load_measured``).
    scheme : {"lofo", "loto", "loso"}
        loso: leave one specimen out, each fold's reference its own specimen's values.
    options : Options
    sample : SampleModel, optional
        Adds the ``nscd_sample`` model.
    time_domain : DataFrame, optional
        Reduced time-domain rows (``temperature_C, frequency_Hz, E_norm_MPa, phase_deg``) of
        the sample run with one fold's law (lofo: the fold of their frequency; loto: of
        their temperature): added as ``nscd_time_domain`` rows.
    full : FitResult, optional
        The procedure already run on the whole table (reused for the in-sample rows).

    Raises
    ------
    InputError
        on an unknown scheme or time-domain rows at a cell that is not measured.
    """
    if scheme not in SCHEMES:
        raise InputError(f"--scheme: expected one of {list(SCHEMES)}, got {scheme!r}")
    cells = cell_means(table)
    T_all = np.unique(cells["temperature_C"].to_numpy(float))
    rows, curves, fits = [], [], {}
    full = full if full is not None else fit_extended(table, options)
    if not full.curve.empty:
        curves.append(full.curve.assign(scheme=scheme, fold="all"))
    from .effects import prepare_table

    prepared = prepare_table(table)  # test_step: the test's rank in its isotherm, whole table
    nb = options.burgers_starts
    if options.burgers:
        rows += _burgers_rows(scheme, "all", "in_sample", table, cells, lambda c: False, nb)
    rows += _law_rows(scheme, "all", "in_sample", full, cells, sample, lambda c: False, rows=prepared)
    folds = sorted(prepared["specimen"].unique()) if scheme == "loso" else _fold_values(cells, scheme)
    for value in folds:
        label = fold_label(scheme, value)
        extrapolation: Callable[..., bool]
        if scheme == "loso":
            # the reference of a fold is its own specimen: the law of the others predicts a new specimen
            held = (prepared["specimen"] == value).to_numpy()
            train_rows, held_rows = prepared[~held], prepared[held]
            test = cell_means(held_rows)
            reason = (
                ""
                if train_rows["temperature_C"].nunique() >= 2
                else "the other specimens leave fewer than 2 temperatures (a single specimen: none to fit on)"
            )
            extrapolation = lambda c: False  # noqa: E731
        else:
            train_cells, reason = fold_split(cells, scheme, value)
            test = cells[~train_cells]
            # the training rows keep the test steps of the whole table (the order of the tests)
            train_mask = fold_split(prepared, scheme, value)[0]
            train_rows, held_rows = prepared[train_mask], prepared[~train_mask]
            if scheme == "loto":
                edge = bool(value <= T_all.min() or value >= T_all.max())
                extrapolation = lambda c, e=edge: e  # noqa: E731
            else:
                f_tr = train_rows["frequency_Hz"].to_numpy(float)
                extrapolation = lambda c, f=f_tr: bool(
                    f.size == 0
                    or c["frequency_Hz"] < f.min()  # noqa: E731
                    or c["frequency_Hz"] > f.max()
                )
        fit = None
        if not reason:
            fit = fit_extended(train_rows, options)
            fits[label] = fit
            if not fit.curve.empty:
                curves.append(fit.curve.assign(scheme=scheme, fold=label))
            if fit.law is None:
                reason = fit.reason
        if options.burgers:
            rows += _burgers_rows(scheme, label, "held_out", train_rows, test, extrapolation, nb)
        rows += _law_rows(scheme, label, "held_out", fit, test, sample, extrapolation, reason, rows=held_rows)
    if time_domain is not None and len(time_domain):
        rows += _time_domain_rows(scheme, cells, time_domain, fits)
    out = pd.DataFrame(rows, columns=list(ROW_COLUMNS))
    return CrossvalResult(out, pd.concat(curves, ignore_index=True) if curves else pd.DataFrame(), full, fits)


def _time_domain_rows(scheme, cells, td: pd.DataFrame, fits) -> list:
    rows = []
    for _, r in td.iterrows():
        sel = same_temperature(cells["temperature_C"], r["temperature_C"]) & same_frequency(
            cells["frequency_Hz"], r["frequency_Hz"]
        )
        if not sel.any():
            raise InputError(
                f"time-domain row at {r['temperature_C']:g} degC, {r['frequency_Hz']:g} Hz: not a measured cell"
            )
        cell = cells[sel].iloc[0]
        label = fold_label(scheme, r["frequency_Hz"] if scheme == "lofo" else r["temperature_C"])
        fit = fits.get(label)
        rows.append(
            _row(
                scheme,
                label,
                "held_out",
                "nscd_time_domain",
                cell,
                (float(r["E_norm_MPa"]), float(r["phase_deg"])),
                False,
                fit.settings.label() if fit is not None and fit.settings else "",
                "",
            )
        )
    return rows
