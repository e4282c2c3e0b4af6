"""Campaign tables: macro laws per job, numerical isotherms, Table 4 analogue, sensitivity,
the Table 3 units question and the phase error of the time-step policy.

Modes (config ``campaign.modes``)
---------------------------------
* ``paper``: the paper's Table 3 (read under ``calibration.table3_units``) at the paper's
  temperatures and frequencies. The paper's lab data are not available, so the
  "experimental" reference of the Table 4 analogue is the Burger's isotherm of Table 3 at the
  same (T, f) (the paper's Table 4 compares with measurements the Burger's model fits within
  a few per cent).
* ``measured``: the Burger's parameters calibrated on the measured mix
  (``results/calibration/burgers_parameters.csv``) at the measured temperatures and
  frequencies; reference = the measured means (``results/lab/measured_summary.csv``).
* ``extended``: the measured mode's schedule with the extended bond law of the diagnosis, a
  generalized Burger's law per temperature (``results/diagnosis/generalized_burgers.json``,
  read by :func:`asphalt_nscd.rheology.law_file.read`); reference = the measured means. With
  ``campaign.extended.transfer_correction`` (default) the bonds are calibrated with
  E*(w) / NF_s, NF_s the sample's network factor (``run-2pb --network-factor-json``,
  :mod:`asphalt_nscd.harmonic.transfer`); the measured mode keeps Eqs. 30-33 as printed.

Mean relative error (Table 4 analogue), per temperature, over the frequencies f of the
campaign, of the sample-mean numerical value x_num against the reference x_ref:
MRE = mean_f |x_num - x_ref| / |x_ref| x 100 %, for |E*| and Phi.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from ..io import InputError
from ..rheology import law_file
from ..rheology.calibration import burgers_model
from ..rheology.metrics import at_temperature, mre_pct

#: Burger's parameters that the sensitivity study varies, with their table columns.
SENSITIVITY_PARAMETERS = {"Em": "Em_MPa", "eta_m": "eta_m_MPa_s", "Ek": "Ek_MPa", "eta_k": "eta_k_MPa_s"}


def parameter_table(path, table3_units: str | None = None) -> pd.DataFrame:
    """Burger's parameters (MPa, MPa s) per temperature: the paper's Table 3 as printed read
    under ``table3_units`` ('Pa' | 'kPa'), or a calibrated table in MPa when None."""
    from ..rheology.calibration import load_table3, read_parameters

    return load_table3(path, units=table3_units) if table3_units else read_parameters(path)


def parameters_at(table: pd.DataFrame, temperature_C: float, factors: dict | None = None, where="") -> dict:
    """Row of ``table`` at ``temperature_C`` (MPa, MPa s), each parameter of ``factors``
    ({'Em': 1.5, ...}) multiplied by its factor.

    Raises InputError if the temperature is not in the table or a factor name is unknown.
    """
    hit = at_temperature(table, temperature_C)
    if hit.empty:
        raise InputError(
            f"{where}: no Burger's parameters at {temperature_C} degC; "
            f"available: {sorted(table['temperature_C'].astype(float))}"
        )
    row = {c: float(hit.iloc[0][c]) for c in SENSITIVITY_PARAMETERS.values()}
    for name, factor in (factors or {}).items():
        if name not in SENSITIVITY_PARAMETERS:
            raise InputError(f"factor {name!r}: expected one of {list(SENSITIVITY_PARAMETERS)}")
        row[SENSITIVITY_PARAMETERS[name]] *= float(factor)
    return row


def law_summary(law) -> dict:
    """Scalar description of a generalized Burger's law (Pa, Pa s) for a reduced row, in MPa:
    ``n_kelvin, Em_MPa, eta_m_MPa_s`` (inf: no dashpot), ``E_inf_MPa``."""
    return {
        "n_kelvin": int(law.n_kelvin),
        "Em_MPa": law.Em * 1e-6,
        "eta_m_MPa_s": law.eta_m * 1e-6,
        "E_inf_MPa": law.E_inf * 1e-6,
    }


def law_curves(laws: dict, temperatures_C, frequency_Hz, where="law JSON") -> pd.DataFrame:
    """Model isotherms of the laws (Pa) at the given temperatures, in the format of
    ``rheology.calibration.burgers_curves``: ``temperature_C, frequency_Hz, E_norm_MPa,
    phase_deg, E1_MPa, E2_MPa``, shape (n_temperatures * k, 6).

    Raises InputError (naming ``where``) if a temperature has no law.
    """
    f = np.asarray(frequency_Hz, dtype=float).ravel()
    frames = []
    for T in sorted({float(t) for t in np.atleast_1d(temperatures_C)}):
        e = law_file.law_at(laws, T, where).complex_modulus(2.0 * np.pi * f) * 1e-6
        frames.append(
            pd.DataFrame(
                {
                    "temperature_C": T,
                    "frequency_Hz": f,
                    "E_norm_MPa": np.abs(e),
                    "phase_deg": np.degrees(np.angle(e)),
                    "E1_MPa": e.real,
                    "E2_MPa": e.imag,
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def law_reference(laws: dict, temperature_C, frequency_Hz, where="law JSON") -> pd.DataFrame:
    """|E*| (MPa) and Phi (deg) of the laws (Pa) at each (T, f) pair, as :func:`burgers_reference`."""
    rows = []
    for T, f in zip(np.atleast_1d(temperature_C), np.atleast_1d(frequency_Hz)):
        e = complex(law_file.law_at(laws, T, where).complex_modulus(2.0 * np.pi * float(f))) * 1e-6
        rows.append(
            {
                "temperature_C": float(T),
                "frequency_Hz": float(f),
                "E_norm_MPa_ref": abs(e),
                "phase_deg_ref": float(np.degrees(np.angle(e))),
            }
        )
    return pd.DataFrame(rows)


class JobLaws:
    """The macro law of a job of any mode, from the law files the workflow passes to run-2pb
    (workflow/rules/campaign.smk): the paper's Table 3 read under ``table3_units`` (paper
    mode and the studies; paper_Pa / paper_kPa and units_Pa / units_kPa under their own reading), the calibrated
    Burger's table (measured mode), the generalized law JSON (extended mode), divided by the
    sample's network factor read from ``network_factor_json`` when given (transfer
    correction). Files are read when first needed.

    Raises
    ------
    InputError
        naming the missing option when a mode's file was not given, or from the readers.
    """

    def __init__(
        self,
        table3=None,
        table3_units: str = "Pa",
        parameters=None,
        law_json=None,
        network_factor_json=None,
        sample_name: str | None = None,
    ):
        self.table3, self.table3_units = table3, table3_units
        self.parameters, self.law_json = parameters, law_json
        self.network_factor_json, self.sample_name = network_factor_json, sample_name
        self._cache: dict[Any, Any] = {}

    def _read(self, key, fn):
        if key not in self._cache:
            self._cache[key] = fn()
        return self._cache[key]

    def law(self, mode: str, temperature_C: float, factors: dict | None = None):
        """GeneralizedBurgers (Pa, Pa s) of a job of ``mode`` at ``temperature_C`` (degC),
        Burger's parameters multiplied by ``factors`` ({'Em': 1.5, ...}; not for extended)."""
        if mode == "extended":
            if not self.law_json:
                raise InputError("an extended-mode job needs the law JSON (--law-json)")
            law = law_file.law_at(
                self._read("json", lambda: law_file.read(self.law_json)), temperature_C, where=self.law_json
            )
            if self.network_factor_json:
                from ..harmonic.transfer import corrected_law

                law, _ = corrected_law(law, self.network_factor_json, sample=self.sample_name)
            return law
        if mode == "measured":
            if not self.parameters:
                raise InputError("a measured-mode job needs the calibrated Burger's table (--parameters)")
            table = self._read("measured", lambda: parameter_table(self.parameters))
            return burgers_model(parameters_at(table, temperature_C, factors, where=self.parameters))
        if not self.table3:
            raise InputError(f"a {mode}-mode job needs the paper's Table 3 (--table3)")
        units = mode.split("_")[1] if mode.startswith(("units_", "paper_")) else self.table3_units
        table = self._read(f"table3_{units}", lambda: parameter_table(self.table3, units))
        return burgers_model(parameters_at(table, temperature_C, factors, where=self.table3))


def burgers_reference(table: pd.DataFrame, temperature_C, frequency_Hz) -> pd.DataFrame:
    """Burger's |E*| (MPa) and Phi (deg) of ``table`` at each (T, f) pair (Eqs. 27-29)."""
    from ..rheology.calibration import burgers_isotherm

    rows = []
    for T, f in zip(np.atleast_1d(temperature_C), np.atleast_1d(frequency_Hz)):
        e, p = burgers_isotherm(parameters_at(table, T, where="reference"), float(f))
        rows.append(
            {"temperature_C": float(T), "frequency_Hz": float(f), "E_norm_MPa_ref": float(e), "phase_deg_ref": float(p)}
        )
    return pd.DataFrame(rows)


def measured_reference(summary: pd.DataFrame) -> pd.DataFrame:
    """Reference columns from results/lab/measured_summary.csv (means of the replicates)."""
    need = ("temperature_C", "frequency_Hz", "E_norm_MPa_mean", "phase_deg_mean")
    from ..io import require_columns

    require_columns(summary, need, "measured summary")
    return summary.rename(columns={"E_norm_MPa_mean": "E_norm_MPa_ref", "phase_deg_mean": "phase_deg_ref"})[
        ["temperature_C", "frequency_Hz", "E_norm_MPa_ref", "phase_deg_ref"]
    ]


def numerical_isotherms(rows: pd.DataFrame, reference: pd.DataFrame) -> pd.DataFrame:
    """Sample mean and standard deviation of the reduced rows per (T, f), beside the reference.

    Parameters
    ----------
    rows : reduced rows (one per sample and (T, f)): temperature_C, frequency_Hz, sample,
        E_norm_MPa, phase_deg, E1_MPa, E2_MPa.
    reference : temperature_C, frequency_Hz, E_norm_MPa_ref, phase_deg_ref.

    Returns
    -------
    DataFrame: temperature_C, frequency_Hz, n_samples, E_norm_MPa_mean, E_norm_MPa_std,
    phase_deg_mean, phase_deg_std, E1_MPa, E2_MPa (means), max_broken_bond_fraction (over
    samples; NaN without n_broken_total, n_bonds), E_norm_MPa_ref, phase_deg_ref,
    rel_error_E_norm_pct, rel_error_phase_pct (of the sample means).

    Raises InputError if a (T, f) of the rows has no reference.
    """
    rows = rows.copy()
    if {"n_broken_total", "n_bonds"} <= set(rows.columns):
        rows["broken_fraction"] = rows["n_broken_total"] / rows["n_bonds"]
    else:
        rows["broken_fraction"] = np.nan
    g = rows.groupby(["temperature_C", "frequency_Hz"])
    out = g.agg(
        max_broken_bond_fraction=("broken_fraction", "max"),
        n_samples=("E_norm_MPa", "size"),
        E_norm_MPa_mean=("E_norm_MPa", "mean"),
        E_norm_MPa_std=("E_norm_MPa", "std"),
        phase_deg_mean=("phase_deg", "mean"),
        phase_deg_std=("phase_deg", "std"),
        E1_MPa=("E1_MPa", "mean"),
        E2_MPa=("E2_MPa", "mean"),
    ).reset_index()
    out[["E_norm_MPa_std", "phase_deg_std"]] = out[["E_norm_MPa_std", "phase_deg_std"]].fillna(0.0)
    ref = reference.copy()
    for c in ("temperature_C", "frequency_Hz"):
        ref[c] = ref[c].astype(float).round(6)
        out[c] = out[c].astype(float).round(6)
    out = out.merge(ref, on=["temperature_C", "frequency_Hz"], how="left")
    miss = out[out["E_norm_MPa_ref"].isna()]
    if not miss.empty:
        raise InputError(f"no reference value at (T, f) = {list(zip(miss.temperature_C, miss.frequency_Hz))}")
    out["rel_error_E_norm_pct"] = 100 * (out["E_norm_MPa_mean"] - out["E_norm_MPa_ref"]) / out["E_norm_MPa_ref"]
    out["rel_error_phase_pct"] = 100 * (out["phase_deg_mean"] - out["phase_deg_ref"]) / out["phase_deg_ref"]
    return out


def table4(isotherms: pd.DataFrame, paper_table4: pd.DataFrame | None = None) -> pd.DataFrame:
    """Mean relative error per temperature (Table 4 analogue), %, from :func:`numerical_isotherms`;
    with the paper's Table 4 (``mre_E_norm_pct, mre_phase_pct``) beside when given."""
    out = (
        isotherms.assign(a=isotherms["rel_error_E_norm_pct"].abs(), b=isotherms["rel_error_phase_pct"].abs())
        .groupby("temperature_C")
        .agg(
            n_frequencies=("a", "size"),
            mre_E_norm_pct=("a", "mean"),
            mre_phase_pct=("b", "mean"),
            max_broken_bond_fraction=("max_broken_bond_fraction", "max"),
        )
        .reset_index()
    )
    ratio = (isotherms["E_norm_MPa_mean"] / isotherms["E_norm_MPa_ref"]).groupby(isotherms["temperature_C"]).mean()
    out["mean_ratio_E_norm"] = out["temperature_C"].map(ratio)
    dphi = (isotherms["phase_deg_mean"] - isotherms["phase_deg_ref"]).groupby(isotherms["temperature_C"]).mean()
    out["mean_phase_difference_deg"] = out["temperature_C"].map(dphi)
    if paper_table4 is not None:
        p = paper_table4.rename(
            columns={"mre_E_norm_pct": "paper_mre_E_norm_pct", "mre_phase_pct": "paper_mre_phase_pct"}
        )
        p["temperature_C"] = p["temperature_C"].astype(float)
        out = out.merge(p, on="temperature_C", how="left")
    return out


def sensitivity_table(rows: pd.DataFrame, baseline: pd.DataFrame) -> pd.DataFrame:
    """Sample means of the sensitivity runs (columns parameter, factor) and of the baseline
    (factor 1, one row set shared by every parameter), per (parameter, factor, f), with the
    change relative to the baseline (%, degrees)."""
    base = baseline.groupby("frequency_Hz").agg(E0=("E_norm_MPa", "mean"), P0=("phase_deg", "mean")).reset_index()
    parts = [rows]
    for p in SENSITIVITY_PARAMETERS:
        parts.append(baseline.assign(parameter=p, factor=1.0))
    allr = pd.concat(parts, ignore_index=True)
    out = (
        allr.groupby(["parameter", "factor", "frequency_Hz"])
        .agg(
            n_samples=("E_norm_MPa", "size"),
            E_norm_MPa_mean=("E_norm_MPa", "mean"),
            E_norm_MPa_std=("E_norm_MPa", "std"),
            phase_deg_mean=("phase_deg", "mean"),
            phase_deg_std=("phase_deg", "std"),
        )
        .reset_index()
        .fillna({"E_norm_MPa_std": 0.0, "phase_deg_std": 0.0})
    )
    out = out.merge(base, on="frequency_Hz", how="left")
    out["change_E_norm_pct"] = 100 * (out["E_norm_MPa_mean"] / out["E0"] - 1)
    out["change_phase_deg"] = out["phase_deg_mean"] - out["P0"]
    return out.drop(columns=["E0", "P0"])


def first_resonance_Hz(stiffness_N_m: float, specimen) -> float:
    """First bending resonance of sample + head, Hz: a cantilever with the EN 12697-26
    lumped moving mass mu = 0.135 M + m (kg) on the head stiffness k (N/m):
    f1 = sqrt(k / mu) / (2 pi)."""
    return math.sqrt(stiffness_N_m / (specimen.mu_g * 1e-3)) / (2 * math.pi)


def units_question(
    table3_path, rows_by_reading: dict, sample, temperature_C: float, micro: dict, reference_frequency_Hz: float = 10.0
) -> pd.DataFrame:
    """One row per Table 3 reading ('Pa', 'kPa'): stiffness, time scales, resonance, agreement.

    Parameters
    ----------
    table3_path : the paper's Table 3 as printed.
    rows_by_reading : {'Pa': DataFrame, 'kPa': DataFrame, ...} of reduced rows of the
        units-question runs (same sample(s), temperature, frequencies) under each reading;
        the reading is the first word of the key (e.g. 'kPa (unbreakable bonds)').
    sample : SampleData of the first sample (bonds, masses, geometry).
    temperature_C : temperature of the comparison, degC.
    micro : ``grain_mass_kg, r_min_mm, l0_mm`` (config calibration.micro; first r_min/l0
        used) for the paper-style dt_e.
    reference_frequency_Hz : frequency of the Burger's |E*| quoted.

    Returns
    -------
    DataFrame with, per reading: Em_MPa, Burgers_E_norm_MPa (at the reference frequency),
    head_stiffness_Em_N_m = Em / gamma (glassy, static 2PB form factor),
    head_stiffness_sim_N_m = F0/z0 of the run at the lowest frequency, dt_e_paper_s
    (sqrt(m_g / Km), Km of the config's representative bond), dt_e_sample_s (median sphere
    mass over the median normal Km of the sample's bonds), first_resonance_Em_Hz and
    first_resonance_sim_Hz (:func:`first_resonance_Hz`), dt_s of the runs, mre_E_norm_pct,
    mre_phase_pct (runs vs Burger's at the same (T, f)), frequencies_Hz, and
    max_broken_bond_fraction (bonds broken at R_crit = 2.7 MPa pi r_min^2 by the end of a run).
    """
    from ..rheology.calibration import burgers_isotherm
    from ..rheology.laws import bond_scale
    from ..sample.store import specimen_of

    spec = specimen_of(sample)
    gamma = spec.gamma_per_mm
    out = []
    for label, rows in rows_by_reading.items():
        reading = label.split()[0]
        table = parameter_table(table3_path, reading)
        p = parameters_at(table, temperature_C, where=str(table3_path))
        Em = p["Em_MPa"] * 1e6
        e_ref, _ = burgers_isotherm(p, reference_frequency_Hz)
        k_em = p["Em_MPa"] / gamma * 1e3  # MPa / (1/mm) = N/mm -> N/m
        km_paper = float(bond_scale(micro["r_min_mm"][0] * 1e-3, micro["l0_mm"][0] * 1e-3)) * Em
        km_sample = float(np.median(bond_scale(sample.bonds["r_min"], sample.bonds["l0"]))) * Em
        m_med = float(np.median(sample.mass))
        r = rows.sort_values("frequency_Hz")
        k_sim = float(r.iloc[0]["F0_N"] / r.iloc[0]["z0_m"]) if len(r) else math.nan
        ref = burgers_reference(table, r["temperature_C"], r["frequency_Hz"])
        rel_e = (r["E_norm_MPa"].to_numpy() - ref["E_norm_MPa_ref"].to_numpy()) / ref["E_norm_MPa_ref"].to_numpy()
        out.append(
            {
                "table3_units": label,
                "temperature_C": temperature_C,
                "Em_MPa": p["Em_MPa"],
                "Burgers_E_norm_MPa": float(e_ref),
                "reference_frequency_Hz": reference_frequency_Hz,
                "gamma_per_mm": gamma,
                "mu_g": spec.mu_g,
                "head_stiffness_Em_N_m": k_em,
                "head_stiffness_sim_N_m": k_sim,
                "dt_e_paper_s": math.sqrt(micro["grain_mass_kg"] / km_paper),
                "dt_e_sample_s": math.sqrt(m_med / km_sample),
                "first_resonance_Em_Hz": first_resonance_Hz(k_em, spec),
                "first_resonance_sim_Hz": first_resonance_Hz(k_sim, spec) if k_sim > 0 else math.nan,
                "dt_s": ";".join(f"{v:.3g}" for v in sorted(set(r["dt_s"]))),
                "frequencies_Hz": ";".join(f"{v:g}" for v in r["frequency_Hz"]),
                "n_runs": len(r),
                "mre_E_norm_pct": mre_pct(r["E_norm_MPa"], ref["E_norm_MPa_ref"]),
                "mre_phase_pct": mre_pct(r["phase_deg"], ref["phase_deg_ref"]),
                "mean_ratio_E_norm": float(np.mean(1 + rel_e)) if len(r) else math.nan,
                "max_broken_bond_fraction": float((r["n_broken_total"] / r["n_bonds"]).max())
                if {"n_broken_total", "n_bonds"} <= set(r.columns) and len(r)
                else math.nan,
            }
        )
    return pd.DataFrame(out)


#: the paper's internal evidence on the units of Table 3 (Sections 2, 3.2): the values it states
PAPER_EVIDENCE: dict[str, Any] = {
    "dt_e_s": 2e-5,
    "dt_g_s": 2e-3,
    "p_Pa": 2.79e3,
    "d_g_m": 2.52e-3,
    "m_g_kg": 2.86e-5,
    "density_kg_m3": 3415.0,
    "yield_stress_Pa": 2.7e6,
    "amplitude_m": 63e-6,
    "strain_max": 50e-6,
    "band_Hz": (3.0, 40.0),
}


def max_bending_strain(amplitude_m: float, specimen) -> float:
    """Largest bending strain of the EN 12697-26 trapezoid (a cantilever clamped at its base,
    width B -> b) for a head displacement ``amplitude_m`` (m), elastic beam theory.

    With F/E = z0 / gamma (Eq. 3: E = gamma F / z0) and the section modulus e w(z)^2 / 6 the
    surface strain at height z is eps(z) = 6 z0 (h - z) / (gamma e w(z)^2), w(z) = B - (B - b)
    z / h, lengths in mm (gamma in 1/mm); its maximum over z in [0, h] (dimensionless).
    """
    z = np.linspace(0.0, specimen.h_mm, 2001)
    w = specimen.B_mm - (specimen.B_mm - specimen.b_mm) * z / specimen.h_mm
    eps = 6.0 * amplitude_m * 1e3 * (specimen.h_mm - z) / (specimen.gamma_per_mm * specimen.e_mm * w**2)
    return float(eps.max())


def reading_evidence(units: pd.DataFrame, mix_E_MPa: float | None = None, specimen=None) -> pd.DataFrame:
    """The paper's internal evidence on the unit of Table 3, computed under each reading.

    Parameters
    ----------
    units : :func:`units_question` table (rows 'Pa', 'kPa', optionally 'kPa (unbreakable
        bonds)'), at the paper's 15 degC.
    mix_E_MPa : |E*| (MPa) of a real asphalt mix at the table's temperature and reference
        frequency (e.g. the measured mix interpolated, :func:`mix_modulus_at`); None: the row
        compares with the 5-30 GPa of dense asphalt mixes at 15 degC, 10 Hz.
    specimen : Specimen2PB (default the paper's EN 12697-26 trapezoid).

    Returns
    -------
    DataFrame, one row per piece of evidence: ``evidence``, ``paper`` (what the paper states),
    ``Pa``, ``kPa`` (the value under each reading; the same where Table 3 does not enter),
    ``supports`` (Pa | kPa | both | neither) and ``rule`` (how it is judged).

    Raises
    ------
    InputError if the Pa or kPa row is missing.
    """
    from ..lab.en12697 import Specimen2PB

    spec = specimen or Specimen2PB()
    ev = PAPER_EVIDENCE
    rows = {r["table3_units"]: r for r in units.to_dict("records")}
    if not {"Pa", "kPa"} <= set(rows):
        raise InputError(f"units table: rows 'Pa' and 'kPa' needed, got {sorted(rows)}")
    pa, kpa = rows["Pa"], rows["kPa"]
    out = []

    def add(evidence, paper, v_pa, v_kpa, ok_pa, ok_kpa, rule):
        supports = "both" if ok_pa and ok_kpa else "Pa" if ok_pa else "kPa" if ok_kpa else "neither"
        out.append({"evidence": evidence, "paper": paper, "Pa": v_pa, "kPa": v_kpa, "supports": supports, "rule": rule})

    def near(x, y, factor):
        return bool(np.isfinite(x) and x > 0 and abs(math.log(x / y)) <= math.log(factor))

    add(
        "time scale dt_e = sqrt(m_g / K_m) at 15 degC, s",
        ev["dt_e_s"],
        pa["dt_e_paper_s"],
        kpa["dt_e_paper_s"],
        near(pa["dt_e_paper_s"], ev["dt_e_s"], 2),
        near(kpa["dt_e_paper_s"], ev["dt_e_s"], 2),
        "within a factor 2 of the paper's value",
    )
    dt_g = math.sqrt(ev["m_g_kg"] / (ev["p_Pa"] * ev["d_g_m"]))
    add(
        "time scale dt_g = sqrt(m_g / (p d_g)), s (Table 3 does not enter)",
        ev["dt_g_s"],
        dt_g,
        dt_g,
        near(dt_g, ev["dt_g_s"], 2),
        near(dt_g, ev["dt_g_s"], 2),
        "within a factor 2 of the paper's value",
    )
    m_g = 4.0 / 3.0 * math.pi * (ev["d_g_m"] / 2) ** 3 * ev["density_kg_m3"]
    add(
        "grain mass m_g of a d_g sphere at 3415 kg/m^3, kg (Table 3 does not enter)",
        ev["m_g_kg"],
        m_g,
        m_g,
        near(m_g, ev["m_g_kg"], 1.1),
        near(m_g, ev["m_g_kg"], 1.1),
        "within 10 % of the paper's value",
    )
    b_pa, b_kpa = pa["max_broken_bond_fraction"], kpa["max_broken_bond_fraction"]
    add(
        "bonds intact at the paper's yield stress 2.7e6 Pa in the 63 um test (broken fraction)",
        0.0,
        b_pa,
        b_kpa,
        b_pa == 0,
        b_kpa == 0,
        "no bond breaks (the paper: no damage at small amplitude)",
    )
    eps = max_bending_strain(ev["amplitude_m"], spec)
    add(
        "largest bending strain at A = 63 um (Table 3 does not enter)",
        ev["strain_max"],
        eps,
        eps,
        eps < ev["strain_max"],
        eps < ev["strain_max"],
        "below the paper's 50e-6",
    )
    ref = mix_E_MPa if mix_E_MPa is not None else math.sqrt(5e3 * 30e3)
    factor = 3.0 if mix_E_MPa is not None else math.sqrt(30e3 / 5e3)
    what = f"the measured mix: {mix_E_MPa:.4g} MPa" if mix_E_MPa is not None else "dense mixes: 5-30 GPa"
    add(
        f"|E*| at {pa['temperature_C']:g} degC, {pa['reference_frequency_Hz']:g} Hz of the Burger's model, MPa "
        f"(a mix: {what})",
        ref,
        pa["Burgers_E_norm_MPa"],
        kpa["Burgers_E_norm_MPa"],
        near(pa["Burgers_E_norm_MPa"], ref, factor),
        near(kpa["Burgers_E_norm_MPa"], ref, factor),
        f"within a factor {factor:.3g} of the mix's",
    )
    lo, hi = ev["band_Hz"]
    r_pa, r_kpa = pa["first_resonance_sim_Hz"], kpa["first_resonance_sim_Hz"]
    add(
        "first resonance of sample + head (simulated head stiffness), Hz",
        f"none in {lo:g}-{hi:g} Hz",
        r_pa,
        r_kpa,
        bool(r_pa > 2 * hi),
        bool(r_kpa > 2 * hi),
        f"above twice the band's top ({2 * hi:g} Hz)",
    )
    return pd.DataFrame(out)


def mix_modulus_at(summary: pd.DataFrame, temperature_C: float, frequency_Hz: float) -> float:
    """|E*| (MPa) of a measured summary (``lab.measured.summarize``: column ``E_norm_MPa_mean``)
    at (T, f): log|E*| interpolated linearly in log f along
    each isotherm and then in T between the two isotherms that bracket ``temperature_C``.

    Raises
    ------
    InputError if no two isotherms bracket the temperature or an isotherm does not bracket the
    frequency.
    """
    temps = np.sort(summary["temperature_C"].unique())
    below, above = temps[temps <= temperature_C], temps[temps >= temperature_C]
    if not len(below) or not len(above):
        raise InputError(f"measured summary: no isotherms bracket {temperature_C:g} degC (tested {list(temps)})")
    values = []
    for T in (below.max(), above.min()):
        iso = at_temperature(summary, T).sort_values("frequency_Hz")
        f = iso["frequency_Hz"].to_numpy(float)
        if not f.min() <= frequency_Hz <= f.max():
            raise InputError(f"measured summary: the {T:g} degC isotherm does not bracket {frequency_Hz:g} Hz")
        values.append(np.interp(np.log(frequency_Hz), np.log(f), np.log(iso["E_norm_MPa_mean"].to_numpy(float))))
    T0, T1 = below.max(), above.min()
    w = 0.0 if T1 == T0 else (temperature_C - T0) / (T1 - T0)
    return float(np.exp((1 - w) * values[0] + w * values[1]))


def dt_policy_phase_table(
    table: pd.DataFrame, temperature_C: float, frequencies_Hz, settings, theta: float | None = None
) -> pd.DataFrame:
    """Phase and amplitude error of the time-discrete bond law at the policy's dt for each
    frequency (:func:`asphalt_nscd.nscd.verify.phase_error_table`), beside the paper's fixed
    5e-5 s where that costs under 2e5 steps."""
    from ..nscd.verify import phase_error_table
    from .twopb import time_step

    law = burgers_model(parameters_at(table, temperature_C, where="dt policy"))
    th = settings.theta if theta is None else theta
    frames = []
    for f in frequencies_Hz:
        dts = {time_step(f, settings)}
        if 2.0 / (f * 5e-5) < 2e5:
            dts.add(5e-5)
        t = phase_error_table(law, omegas=(2 * np.pi * f,), dts=tuple(sorted(dts)), thetas=(th,))
        t["policy"] = [settings.dt_policy if d == time_step(f, settings) else "fixed 5e-5 s" for d in t["dt_s"]]
        frames.append(t)
    out = pd.concat(frames, ignore_index=True)
    out.insert(0, "temperature_C", float(temperature_C))
    return out
