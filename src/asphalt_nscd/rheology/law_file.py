"""The law file: generalized Burger's laws per temperature as JSON (write, read, validate,
evaluate at (T, f)).

Written by ``asphalt-nscd extend-law`` (the extended law of
:mod:`asphalt_nscd.rheology.extended`), read by the campaign (``run-2pb --law-json``,
``campaign-isotherms --law-json``), the cross-validation's time-domain check and
``asphalt-nscd diagnose``. Format::

    {"units": {"Em": "Pa", "eta_m": "Pa s", "Ek": "Pa", "eta_k": "Pa s", "E_inf": "Pa"},
     "law": "GeneralizedBurgers: ...",
     "temperatures": {"<T degC, %g>": {"Em": Pa, "eta_m": Pa s or null (no Maxwell dashpot),
                                        "Ek": [Pa, ...], "eta_k": [Pa s, ...], "E_inf": Pa,
                                        ...optional fields...}},
     ...optional objects (model, selection, source)...}

E*(w) = E_inf + [1/Em + 1/(i w eta_m) + sum_i 1/(Ek_i + i w eta_k,i)]^-1
(:class:`asphalt_nscd.rheology.laws.GeneralizedBurgers`). The file is in SI (Pa, Pa s); the
diagnosis works in MPa (:func:`read_mpa`). Temperatures are matched with the rule of
:mod:`asphalt_nscd.rheology.metrics`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..io import InputError, read_json, write_json
from .laws import GeneralizedBurgers
from .metrics import temperature_key

#: units of the fields of one temperature
UNITS = {"Em": "Pa", "eta_m": "Pa s", "Ek": "Pa", "eta_k": "Pa s", "E_inf": "Pa"}
#: fields of one temperature of a law file
LAW_FIELDS = ("Em", "eta_m", "Ek", "eta_k", "E_inf")
#: description of the law in the file
LAW_TEXT = (
    "GeneralizedBurgers: Maxwell (Em, eta_m) in series with Kelvin-Voigt units "
    "(Ek[i], eta_k[i]), in parallel with E_inf"
)


def to_json(laws: dict, mre_E: dict | None = None, mre_phase: dict | None = None) -> dict:
    """The law-file object of ``laws`` {T degC: GeneralizedBurgers in MPa, MPa s}, written in
    Pa and Pa s, keyed by temperature (``"%g"``).

    Fields per temperature: ``Em, eta_m, Ek (list), eta_k (list), E_inf`` (``eta_m`` null means
    no Maxwell dashpot) and, if given, the in-sample MREs (%) ``in_sample_mre_E_norm_pct,
    in_sample_mre_phase_pct`` ({T: value}).
    """
    out: dict[str, Any] = {"units": dict(UNITS), "law": LAW_TEXT, "temperatures": {}}
    for T, law in sorted(laws.items()):
        d = law.scaled(1e6).as_dict()
        if not np.isfinite(d["eta_m"]):
            d["eta_m"] = None
        if mre_E is not None:
            assert mre_phase is not None  # the MREs are given together
            d["in_sample_mre_E_norm_pct"] = mre_E.get(T)
            d["in_sample_mre_phase_pct"] = mre_phase.get(T)
        out["temperatures"][f"{T:g}"] = d
    return out


def write(obj: dict, path) -> None:
    """Write a law-file object (:func:`to_json`, possibly with more objects) atomically after
    checking that it reads back (:func:`validate`). Raises InputError naming ``path`` and the
    key if it does not."""
    validate(obj, path)
    write_json(obj, path)


def validate(obj, path) -> dict:
    """The laws {T degC (float): GeneralizedBurgers in Pa, Pa s} of a law-file object.

    Raises
    ------
    InputError
        naming ``path`` and the key: no ``temperatures`` object or an empty one, a temperature
        key that is not a finite number or is given twice, a missing field, a field that is
        not a (list of) positive finite number(s) (``E_inf`` >= 0, ``eta_m`` may be null),
        ``Ek``/``eta_k`` of different lengths, or ``units`` other than Pa and Pa s.
    """
    if not isinstance(obj, dict) or not isinstance(obj.get("temperatures"), dict) or not obj["temperatures"]:
        raise InputError(f"{path}: key 'temperatures': expected a non-empty object keyed by temperature (degC)")
    units = obj.get("units")
    if units is not None:
        bad = [k for k, u in UNITS.items() if isinstance(units, dict) and k in units and units[k] != u]
        if not isinstance(units, dict) or bad:
            raise InputError(f"{path}: key 'units': expected {UNITS}, got {units}")

    def number(value, key, allow_zero=False):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) and np.isfinite(value)
        if not ok or value < 0 or (value == 0 and not allow_zero):
            raise InputError(
                f"{path}: key {key}: expected a {'non-negative' if allow_zero else 'positive'} "
                f"finite number, got {value!r}"
            )
        return float(value)

    laws: dict[float, GeneralizedBurgers] = {}
    for key, d in obj["temperatures"].items():
        where = f"'temperatures.{key}'"
        try:
            T = float(key)
        except ValueError:
            raise InputError(f"{path}: key {where}: expected a temperature in degC") from None
        if not np.isfinite(T):
            raise InputError(f"{path}: key {where}: expected a finite temperature in degC")
        if not isinstance(d, dict):
            raise InputError(f"{path}: key {where}: expected an object with {list(LAW_FIELDS)}")
        missing = [k for k in LAW_FIELDS if k not in d]
        if missing:
            raise InputError(f"{path}: key {where}: missing field(s) {missing}")
        Em = number(d["Em"], f"'temperatures.{key}.Em'")
        eta_m = np.inf if d["eta_m"] is None else number(d["eta_m"], f"'temperatures.{key}.eta_m'")
        units_lists = []
        for k in ("Ek", "eta_k"):
            if not isinstance(d[k], list):
                raise InputError(f"{path}: key 'temperatures.{key}.{k}': expected a list of positive numbers")
            units_lists.append([number(v, f"'temperatures.{key}.{k}[{i}]'") for i, v in enumerate(d[k])])
        if len(units_lists[0]) != len(units_lists[1]):
            raise InputError(
                f"{path}: key 'temperatures.{key}': Ek has {len(units_lists[0])} units but "
                f"eta_k has {len(units_lists[1])}"
            )
        E_inf = number(d["E_inf"], f"'temperatures.{key}.E_inf'", allow_zero=True)
        if temperature_key(laws, T) is not None:
            raise InputError(f"{path}: key {where}: temperature {T:g} degC given twice")
        laws[T] = GeneralizedBurgers(
            Em=Em, eta_m=eta_m, Ek=tuple(units_lists[0]), eta_k=tuple(units_lists[1]), E_inf=E_inf
        )
    return laws


def read(path) -> dict:
    """Laws per temperature of a law file: {T degC (float): GeneralizedBurgers in Pa, Pa s}.

    Raises InputError naming the file (unreadable, not JSON) and the key (:func:`validate`).
    """
    return validate(read_json(path, "law JSON"), path)


def read_mpa(path, temperatures=None) -> dict:
    """:func:`read` in MPa and MPa s (the diagnosis' units); with ``temperatures`` (degC), the
    laws at exactly those temperatures, keyed by them.

    Raises InputError naming the file and the temperatures without a law.
    """
    return laws_mpa(read(path), temperatures, path)


def laws_mpa(laws: dict, temperatures=None, path="") -> dict:
    """Laws per temperature ``laws`` ({T degC: GeneralizedBurgers in Pa, Pa s}, :func:`validate`)
    in MPa and MPa s; with ``temperatures`` (degC), the laws at exactly those temperatures,
    keyed by them.

    Raises InputError naming ``path`` and the temperatures without a law.
    """
    laws = {T: law.scaled(1e-6) for T, law in laws.items()}
    if temperatures is None:
        return laws
    missing = [float(T) for T in temperatures if temperature_key(laws, T) is None]
    if missing:
        raise InputError(
            f"{path}: key 'temperatures': no law at {missing} degC (measured temperatures); given: {sorted(laws)}"
        )
    return {float(T): laws[temperature_key(laws, T)] for T in temperatures}


def read_info(path) -> dict:
    """``selection``, ``model`` and ``card`` objects of a law file (None where absent)."""
    return info_of(read_json(path, "law JSON"))


def info_of(obj) -> dict:
    """``selection``, ``model`` and ``card`` objects of a law file's JSON object ``obj`` (None
    where absent)."""
    return {k: obj.get(k) if isinstance(obj, dict) else None for k in ("selection", "model", "card")}


def law_at(laws: dict, temperature_C: float, where="") -> GeneralizedBurgers:
    """The law of ``laws`` ({T: law}) at ``temperature_C`` (same isotherm,
    :func:`asphalt_nscd.rheology.metrics.same_temperature`).

    Raises InputError naming ``where`` and the available temperatures if it is missing.
    """
    key = temperature_key(laws, temperature_C)
    if key is None:
        raise InputError(
            f"{where}: key 'temperatures': no law at {float(temperature_C):g} degC; available: {sorted(laws)}"
        )
    return laws[key]


def complex_modulus(laws: dict, temperature_C, frequency_Hz, where="") -> np.ndarray:
    """E* of the laws at each (T degC, f Hz) pair (1-d arrays broadcast together), in the
    laws' units (Pa for :func:`read`, MPa for :func:`read_mpa`), complex, shape (n,).

    Raises InputError (naming ``where``) if a temperature has no law.
    """
    T, f = np.broadcast_arrays(
        np.atleast_1d(np.asarray(temperature_C, float)), np.atleast_1d(np.asarray(frequency_Hz, float))
    )
    return np.array([complex(law_at(laws, t, where).complex_modulus(2 * np.pi * x)) for t, x in zip(T, f)], complex)
