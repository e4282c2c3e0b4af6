"""The mix file of a forecast: one or more mixes in the forms a lab reports them.

A YAML file (schema ``mix.schema.yaml`` beside this module, JSON schema draft 2020-12, checked as the
workflow's configs are; numbers read as YAML 1.2 reads them, so ``4.4e9`` is a number)::

    mixes:
      - id: "211"                         # letters, digits, . _ + -
        binder:
          file: binder_211_dsr.csv        # DSR frequency sweep, relative to this file (lab.dsr)
          id: B1                          # optional: the binder in a file of several binders
          sidecar: other.test.json        # optional: default <sweep stem>.test.json beside it
          pg_grade: PG 76-22              # optional
          viscosity: {unit: Pa s, temperature_unit: F, values: {14: 1.1e10, 40: 2.0e8}}  # optional
        gradation: sieve_211.csv          # a sieve file (lab.sieve), or {file: ..., sidecar: ...},
                                          # or inline {"3/4 in": 100, "3/8 in": 74, "No. 4": 30, ...},
                                          # or {form: cumulative_retained, sieves: {...}}
        volumetrics: {Pb: 6.735, Gmm: 2.520, Gmb: 2.322, Gb: 1.03, Gsb: 2.65}   # lab.volumetrics

The PG grade and the viscosity may come from the sweep's sidecar instead (``binder`` or
``binders.<id>``, :mod:`.dsr`), not from both. The viscosity is placed on the sweep's points of the
same temperature (``eta_Pa_s``, within 0.5 degC) and kept whole in :attr:`MixInput.viscosity`.

:func:`read_mix_file` returns one :class:`MixInput` per mix; every error is an
:class:`asphalt_nscd.io.InputError` naming the mix file, the mix id and the key (an error inside a
sweep or sieve file keeps that file's line and column after them).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..io import InputError
from .dsr import BinderInfo, read_dsr, with_viscosity
from .sieve import FORMS, SieveAnalysis, from_values, read_sieve_analysis, validate
from .volumetrics import Volumetrics, convert

SCHEMA_PATH = Path(__file__).with_name("mix.schema.yaml")
_FLOAT_1_2 = re.compile(r"^[-+]?(?:\d[\d_]*(?:\.\d*)?|\.\d+)[eE][-+]?\d+$")


@dataclass(frozen=True)
class MixInput:
    """One mix of a mix file, read and checked.

    Attributes
    ----------
    mix_id : str
    binder_points : DataFrame, one row per (temperature, frequency) of the mix's binder
        :data:`asphalt_nscd.lab.dsr.COLUMNS`: ``binder, temperature_C, frequency_Hz, G_Pa,
        delta_deg, eta_Pa_s, n_specimens`` (degC, Hz, Pa, degrees, Pa s; replicates averaged).
    passing : (openings_mm, passing_pct), shape (n,) each: every sieve of the analysis, openings
        increasing, % passing by mass of aggregate.
    witczak : dict ``rho34_pct, rho38_pct, rho4_pct, rho200_pct`` (:meth:`.sieve.SieveAnalysis.witczak`).
    volumetrics : dict ``Va_pct, Vbeff_pct, Pb_pct, VMA_pct, VFA_pct`` (%; Pb None when the report
        does not give it).
    pg_high_C, pg_low_C : float or None (degC).
    sources : dict ``mix_file, binder_file, binder_sidecar, binder_id, gradation`` (a path or
        ``"inline"``).
    viscosity : DataFrame ``temperature_C, eta_Pa_s``, every viscosity given (empty if none).
    gradation : :class:`asphalt_nscd.lab.sieve.SieveAnalysis` (``passing_at`` any opening).
    report : :class:`asphalt_nscd.lab.volumetrics.Volumetrics` (Gse, Pba, ... where derivable).
    warnings : list of str (the sweep's plausibility warnings).
    """

    mix_id: str
    binder_points: pd.DataFrame
    passing: tuple
    witczak: dict
    volumetrics: dict
    pg_high_C: float | None
    pg_low_C: float | None
    sources: dict
    viscosity: pd.DataFrame
    gradation: SieveAnalysis
    report: Volumetrics
    warnings: list = field(default_factory=list)

    def passing_at(self, openings_mm) -> np.ndarray:
        """% passing at ``openings_mm`` (mm, any shape) on the mix's passing curve."""
        return self.gradation.passing_at(openings_mm)

    def formulation(self) -> dict:
        """The per-mix columns of a matched table (:data:`asphalt_nscd.lab.matched.FORMULATION`, and
        ``pg_high_C, pg_low_C`` when known): ``rho34_pct ... Vbeff_pct``, floats; a value the report
        does not give (Pb from Va with Vbeff, or VMA with VFA) is NaN, as an empty cell of a matched table."""
        vol = {k: self.volumetrics[k] for k in ("Pb_pct", "Va_pct", "Vbeff_pct")}
        out = {**self.witczak, **{k: float("nan") if v is None else float(v) for k, v in vol.items()}}
        if self.pg_high_C is not None:
            out.update(pg_high_C=self.pg_high_C, pg_low_C=self.pg_low_C)
        return out


def load_yaml(path: Path):
    """The YAML document at ``path``, floats as YAML 1.2 writes them (``1e-3``, ``4.4e9``).

    Raises InputError naming the file: missing, unreadable or not YAML."""
    import yaml

    base = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

    class Loader(base):  # type: ignore[misc, valid-type]
        pass

    Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_1_2, list("-+0123456789."))
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the mix file ({exc})") from None
    try:
        return yaml.load(text, Loader=Loader)
    except yaml.YAMLError as exc:
        raise InputError(f"{path}: not valid YAML ({' '.join(str(exc).split())})") from None


def read_mix_file(path) -> list[MixInput]:
    """Read and check a mix file (module docstring).

    Parameters
    ----------
    path : str or Path
        The YAML mix file; the files it names are relative to it.

    Returns
    -------
    list of :class:`MixInput`, in file order.

    Raises
    ------
    InputError
        ``"<mix file>: mix '<id>': key '<key>': ..."``: a key the schema refuses, a repeated mix id, a
        binder the sweep file lacks, PG grade or viscosity given twice, and every error of
        :func:`asphalt_nscd.lab.dsr.read_dsr`, :func:`asphalt_nscd.lab.sieve.read_sieve_analysis`,
        :func:`asphalt_nscd.lab.sieve.from_values` and :func:`asphalt_nscd.lab.volumetrics.convert`.
    """
    from ..config import yaml_load

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: file not found (a mix file)")
    doc = load_yaml(path)
    schema = yaml_load(SCHEMA_PATH.read_text(encoding="utf-8"))
    _validate(doc, schema, path)
    mixes: list[MixInput] = []
    seen: set[str] = set()
    cache: dict[tuple, pd.DataFrame] = {}
    for mix in doc["mixes"]:
        mix_id = str(mix["id"])
        where = f"{path}: mix {mix_id!r}"
        if mix_id in seen:
            raise InputError(f"{where}: key 'id': mix {mix_id!r} is given twice")
        seen.add(mix_id)
        mixes.append(_read_mix(path, mix, mix_id, where, cache))
    return mixes


def _validate(doc, schema: dict, path: Path) -> None:
    """The schema's check, its message naming the mix by id."""
    if not isinstance(doc, dict):
        raise InputError(f"{path}: expected a mapping with key 'mixes' at the top, got {type(doc).__name__}")
    try:
        validate(doc, schema, str(path))
    except InputError as exc:
        text = str(exc)
        m = re.match(rf"^{re.escape(str(path))}: key 'mixes\.(\d+)\.?([^']*)': (.*)$", text)
        if m is None:
            raise
        k = int(m.group(1))
        item = doc["mixes"][k] if k < len(doc.get("mixes", [])) else {}
        mix_id = item.get("id", f"#{k + 1}") if isinstance(item, dict) else f"#{k + 1}"
        raise InputError(f"{path}: mix {str(mix_id)!r}: key '{m.group(2) or '(the mix)'}': {m.group(3)}") from None


def _wrapped(where: str, key: str, fn, *args, **kwargs):
    """``fn(*args, **kwargs)``; an InputError from it re-raised naming the mix file, mix and key."""
    try:
        return fn(*args, **kwargs)
    except InputError as exc:
        raise InputError(f"{where}: key '{key}': {exc}") from None


def _read_mix(path: Path, mix: dict, mix_id: str, where: str, cache: dict) -> MixInput:
    root = path.parent
    b = mix["binder"]
    sweep = root / b["file"]
    side = None if b.get("sidecar") is None else root / b["sidecar"]
    key = (str(sweep.resolve()), None if side is None else str(side.resolve()))
    if key not in cache:
        cache[key] = _wrapped(where, "binder.file", read_dsr, sweep, side)
    points = cache[key]
    binders = list(dict.fromkeys(points["binder"]))
    if b.get("id") is not None:
        binder = str(b["id"])
        if binder not in binders:
            raise InputError(f"{where}: key 'binder.id': no binder {binder!r} in {sweep} (its binders: {binders})")
    elif len(binders) == 1:
        binder = binders[0]
    else:
        raise InputError(f"{where}: key 'binder.id': {sweep} holds binders {binders}; name the mix's binder")
    info: BinderInfo = points.attrs["binders"][binder]
    own = _binder_block(binder, b, f"{where}: key 'binder'")
    for name, mine, theirs in (
        ("pg_grade", own.pg_high_C, info.pg_high_C),
        ("viscosity", len(own.viscosity) or None, len(info.viscosity) or None),
    ):
        if mine is not None and theirs is not None:
            raise InputError(f"{where}: key 'binder.{name}': also given in {info.where}; give it once")
    pg_high = own.pg_high_C if own.pg_high_C is not None else info.pg_high_C
    pg_low = own.pg_low_C if own.pg_low_C is not None else info.pg_low_C
    viscosity = own.viscosity if len(own.viscosity) else info.viscosity
    mine = points[points["binder"] == binder].reset_index(drop=True)
    mine = with_viscosity(mine, viscosity)
    mine.attrs = {}
    gradation, grad_source = _gradation(root, mix["gradation"], where)
    witczak = _wrapped(where, "gradation", gradation.witczak)
    report = convert(mix["volumetrics"], f"{where}: key 'volumetrics'")
    warnings = [w for w in points.attrs["warnings"] if f"binder {binder!r}" in w]
    return MixInput(
        mix_id=mix_id,
        binder_points=mine,
        passing=(gradation.openings_mm.copy(), gradation.passing_pct.copy()),
        witczak=witczak,
        volumetrics=report.as_dict(),
        pg_high_C=pg_high,
        pg_low_C=pg_low,
        sources={
            "mix_file": str(path),
            "binder_file": str(sweep),
            "binder_sidecar": points.attrs["source"]["declaration"],
            "binder_id": binder,
            "gradation": grad_source,
        },
        viscosity=viscosity.reset_index(drop=True),
        gradation=gradation,
        report=report,
        warnings=warnings,
    )


def _binder_block(binder: str, b: dict, where: str) -> BinderInfo:
    from .dsr import binder_info

    block = {k: b[k] for k in ("pg_grade", "viscosity") if b.get(k) is not None}
    return binder_info(binder, block, where)


def _gradation(root: Path, g, where: str) -> tuple[SieveAnalysis, str]:
    """The mix's sieve analysis from any of the gradation forms (module docstring)."""
    if isinstance(g, str):
        return _wrapped(where, "gradation", read_sieve_analysis, root / g), str(root / g)
    if "file" in g:
        extra = sorted(set(g) - {"file", "sidecar"})
        if extra:
            raise InputError(f"{where}: key 'gradation.{extra[0]}': unknown key beside 'file'; allowed: file, sidecar")
        side = None if g.get("sidecar") is None else root / str(g["sidecar"])
        return _wrapped(where, "gradation.file", read_sieve_analysis, root / str(g["file"]), side), str(
            root / g["file"]
        )
    place = f"{where}: key 'gradation'"
    if "form" in g or "sieves" in g:
        extra = sorted(set(g) - {"form", "sieves"})
        if extra or not isinstance(g.get("sieves"), dict) or g.get("form", "passing") not in FORMS:
            raise InputError(
                f"{place}: expected {{form: {' | '.join(FORMS)}, sieves: {{sieve: value}}}}"
                + (f"; unknown key {extra[0]!r}" if extra else "")
            )
        return from_values(g["sieves"], f"{place}.sieves", g.get("form", "passing")), "inline"
    return from_values(g, place, "passing"), "inline"
