"""Harmonic |E*| and Phi of a sample: solve, reduce by EN 12697-26 (Eqs. 1-5), compare.

Each (T, f) gives one reduced complex-modulus row (docs/design.md "Reduced complex-modulus
rows") computed by :func:`asphalt_nscd.lab.en12697.complex_modulus` from the head force
phasor, plus the macro law at the same (T, f) and the *network factor*:

    network_factor = |E*|_sample / |E*|_macro,   phase_difference_deg = Phi_sample - Phi_macro

The macro law is the Burger's model of the parameter row (Eqs. 27-29); Eqs. 30-33 assume
the sample behaves like one bond of section pi r_min^2 and length l0, and the network
factor measures how far the discrete sample is from that assumption. It depends strongly on
the bond kinematics of :mod:`.solver` (about 1.1-1.4 with ``contact`` + free head, about 80
with ``barycentre`` on the default samples; :func:`.analysis.kinematics_study`).

Specimen geometry for gamma (Eq. 3): :func:`asphalt_nscd.sample.store.specimen_geometry_mm`
(the sample file's scaled dimensions, else the EN 12697-26 trapezoid of a test sample).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..io import InputError
from ..nscd.state import HEAD_AMPLITUDE_M
from ..rheology.metrics import same_temperature
from .solver import HarmonicSystem

#: Paper frequencies of the campaign, Hz.
PAPER_FREQUENCIES_HZ = (3.0, 6.0, 10.0, 25.0, 40.0)
#: Burger's parameter columns (MPa, MPa s), as in asphalt_nscd.rheology.calibration.
PARAM_COLUMNS = ("Em_MPa", "eta_m_MPa_s", "Ek_MPa", "eta_k_MPa_s")


def specimen_for(system: HarmonicSystem, geometry_mm: dict):
    """EN 12697-26 specimen (gamma, mu) of a sample: geometry + M = sphere mass, m = top plate."""
    from ..lab.en12697 import Specimen2PB

    return Specimen2PB(M_kg=system.network.sample_mass, m_kg=float(system.network.plate_mass[1]), **geometry_mm)


def harmonic_rows(
    system: HarmonicSystem,
    law,
    temperature_C: float,
    frequencies_Hz,
    geometry_mm: dict,
    amplitude: float = HEAD_AMPLITUDE_M,
    inertia: str = "full",
    solver: str = "reuse",
    rtol: float = 1e-12,
) -> list[dict]:
    """Reduced complex-modulus rows of the sample at one temperature.

    Parameters
    ----------
    system : HarmonicSystem
        The prepared sample.
    law : object with ``complex_modulus(omega)`` (Pa), e.g. GeneralizedBurgers
        Macro law at ``temperature_C`` (bonds: Eqs. 30-33, 8-11).
    temperature_C : float
        Label of the rows, degC.
    frequencies_Hz : sequence of float
        Test frequencies, Hz.
    geometry_mm : dict
        ``b_mm, B_mm, e_mm, h_mm`` for gamma (Eq. 3).
    amplitude, inertia, solver, rtol
        See :meth:`HarmonicSystem.solve_law`.

    Returns
    -------
    list of dict
        One row per frequency: the reduced row (``temperature_C, frequency_Hz, F0_N, z0_m,
        psi_deg, gamma_per_mm, mu_g, E1_MPa, E2_MPa, E_norm_MPa, phase_deg``), the macro
        ``macro_E_norm_MPa, macro_phase_deg``, ``network_factor, phase_difference_deg``,
        the reaction components ``Fx_re_N, Fx_im_N, Fy_abs_N, Fz_abs_N`` and the solver's
        ``inertia, solver, n_free_dof, n_load_free, residual, solve_time_s``.
    """
    from ..lab.en12697 import complex_modulus

    specimen = specimen_for(system, geometry_mm)
    rows = []
    for f in np.atleast_1d(np.asarray(frequencies_Hz, float)):
        sol = system.solve_law(law, f, amplitude=amplitude, inertia=inertia, solver=solver, rtol=rtol)
        reduced = complex_modulus(sol.F0_N, amplitude, sol.psi_deg, f, specimen)
        macro_norm, macro_phase = law.norm_and_phase(2 * np.pi * f)
        row = {
            "temperature_C": float(temperature_C),
            "frequency_Hz": float(f),
            "F0_N": sol.F0_N,
            "z0_m": amplitude,
            "psi_deg": sol.psi_deg,
            **reduced,
            "macro_E_norm_MPa": float(macro_norm) * 1e-6,
            "macro_phase_deg": float(macro_phase),
        }
        row["network_factor"] = row["E_norm_MPa"] / row["macro_E_norm_MPa"]
        row["phase_difference_deg"] = row["phase_deg"] - row["macro_phase_deg"]
        row.update(
            {
                "Fx_re_N": float(sol.force[0].real),
                "Fx_im_N": float(sol.force[0].imag),
                "Fy_abs_N": float(abs(sol.force[1])),
                "Fz_abs_N": float(abs(sol.force[2])),
                "inertia": inertia,
                "solver": sol.solver,
                "n_free_dof": sol.n_free_dof,
                "n_load_free": sol.n_load_free,
                "residual": sol.residual,
                "solve_time_s": sol.solve_time_s,
            }
        )
        rows.append(row)
    return rows


#: Columns of the rows of :func:`harmonic_rows` that the readers of ``asphalt-nscd harmonic``
#: outputs need (:func:`read_harmonic_rows`).
ROW_COLUMNS = (
    "temperature_C",
    "frequency_Hz",
    "E_norm_MPa",
    "phase_deg",
    "macro_E_norm_MPa",
    "macro_phase_deg",
    "network_factor",
    "phase_difference_deg",
    "inertia",
)


def read_harmonic_rows(path, extra=("sample", "mode")) -> pd.DataFrame:
    """Read an output table of ``asphalt-nscd harmonic`` (rows of :func:`harmonic_rows` with
    the ``sample`` and ``mode`` columns the command adds).

    Raises
    ------
    InputError
        naming the file: missing or not a CSV table, or a column of :data:`ROW_COLUMNS` or
        ``extra`` missing.
    """
    from ..io import read_csv, require_columns

    frame = read_csv(path)
    require_columns(frame, (*extra, *ROW_COLUMNS), path, "an output of 'asphalt-nscd harmonic'")
    return frame


def select_temperatures(params: pd.DataFrame, temperatures, path="parameters") -> pd.DataFrame:
    """Rows of ``params`` at the requested temperatures (all when ``temperatures`` is empty).

    Raises
    ------
    InputError
        if a requested temperature has no row (within 1e-6 degC).
    """
    if not temperatures:
        return params
    keep = []
    for t in temperatures:
        hit = np.flatnonzero(same_temperature(params["temperature_C"].to_numpy(float), t))
        if hit.size == 0:
            raise InputError(
                f"{path}: no row with temperature_C = {t} (have {sorted(params['temperature_C'].tolist())})"
            )
        keep.append(hit[0])
    return params.iloc[keep]


def frequency_plan(
    params: pd.DataFrame, frequencies=None, frequencies_from=None, sweep=None
) -> list[tuple[pd.Series, np.ndarray]]:
    """(parameter row, frequencies in Hz) per temperature.

    Exactly one source: ``frequencies`` (the same list at every temperature), ``sweep``
    (fmin_Hz, fmax_Hz, n: log-spaced), or ``frequencies_from`` (a table with
    ``temperature_C, frequency_Hz``, e.g. the measured summary: its frequencies at each of
    its temperatures that the parameter table has).

    Raises
    ------
    InputError
        if no source or more than one is given, or the table lacks the columns.
    """
    given = [
        x is not None and (len(x) if not isinstance(x, (str, Path)) else 1)
        for x in (frequencies, frequencies_from, sweep)
    ]
    if sum(bool(g) for g in given) != 1:
        raise InputError("give exactly one of --frequency, --frequencies-from, --sweep")
    plan = []
    if frequencies_from is not None:
        table = pd.read_csv(frequencies_from)
        for col in ("temperature_C", "frequency_Hz"):
            if col not in table.columns:
                raise InputError(f"{frequencies_from}: missing column '{col}'")
        for _, row in params.iterrows():
            sel = same_temperature(table["temperature_C"].to_numpy(float), row["temperature_C"])
            f = np.unique(table.loc[sel, "frequency_Hz"].to_numpy(float))
            if f.size:
                plan.append((row, f))
        if not plan:
            raise InputError(f"{frequencies_from}: no temperature in common with the parameters")
        return plan
    if sweep is not None:
        fmin, fmax, n = float(sweep[0]), float(sweep[1]), int(sweep[2])
        if not (0 < fmin < fmax and n >= 2):
            raise InputError(f"--sweep: expected 0 < fmin < fmax and n >= 2, got {sweep}")
        f = np.geomspace(fmin, fmax, n)
    else:
        f = np.asarray(frequencies, float)
        if np.any(f <= 0):
            raise InputError(f"--frequency: frequencies must be positive, got {list(f)}")
    return [(row, f) for _, row in params.iterrows()]
