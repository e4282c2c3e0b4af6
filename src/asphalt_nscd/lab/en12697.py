"""EN 12697-26 (Annex A) two-point bending on trapezoids: reduction of a force/displacement
record to the complex modulus (paper Section 2, Eqs. 1-5).

Chain
-----
1. ``fit_sinusoid`` — least-squares fit of ``offset + drift t + A sin(w t + phi)`` to the
   head displacement and to the force over a window (the paper reads F0, z0 and Psi over the
   last 10 s of a lab test; a simulation is read over its last cycle).
2. ``reduce_record`` — F0, z0 and Psi = phi_force - phi_displacement, then
3. ``complex_modulus`` — Eqs. 1-5::

       E1 = gamma (F0/z0 cos Psi + 1e-6 mu w^2)      (Eq. 1)
       E2 = gamma  F0/z0 sin Psi                      (Eq. 2)
       gamma = 12 h^3 / (e (B-b)^3) [(2 - b/(2B)) b/B - 3/2 - ln(b/B)]   (Eq. 3, 1/mm)
       mu = 0.135 M + m                               (mass factor, g)
       |E*| = sqrt(E1^2 + E2^2),  Phi = arctan(E2/E1) (Eqs. 4, 5)

Units: inputs and outputs of the functions are SI at the edges named by their suffix
(``F0_N``, ``z0_m``, ``psi_deg``); Eqs. 1-3 are evaluated as the standard writes them,
with z0 in mm, gamma in 1/mm and mu in g, which gives E1, E2 in MPa (the factor 1e-6 turns
g s^-2 into N/mm).

Sign convention: Psi is the phase lead of the force over the head displacement, so a
viscoelastic specimen has Psi in (0, 90 deg). The inertia term ``+ 1e-6 mu w^2`` adds back
the force spent accelerating the moving mass (head + 0.135 of the specimen), which lowers
the measured in-phase force.

Choices (the standard leaves them open)
---------------------------------------
* The sinusoid fit carries an offset and a linear drift, so a slow creep of the mean force
  or a not-yet-centred displacement does not bias the amplitudes.
* The window is the last ``window_s`` seconds or the last ``window_cycles`` cycles of the
  record (configurable: ``lab.window_s``, ``lab.window_cycles``); with neither, the whole
  record is used.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

from ..io import InputError, read_csv, require_columns

#: Keys of the JSON sidecar of a lab record (specimen geometry and test conditions).
RECORD_META_KEYS = ("b_mm", "B_mm", "e_mm", "h_mm", "M_kg", "m_kg", "temperature_C", "frequency_Hz")
#: Columns of a record CSV.
RECORD_COLUMNS = ("time_s", "displacement_m", "force_N")


@dataclass(frozen=True)
class Specimen2PB:
    """Trapezoidal 2PB specimen of EN 12697-26 and the moving mass at its head.

    Parameters
    ----------
    b_mm, B_mm : float
        Head (top) and base widths, mm (paper: 25, 56).
    e_mm : float
        Thickness, mm (paper: 25).
    h_mm : float
        Height, mm (paper: 250).
    M_kg : float
        Specimen mass, kg (paper: about 0.6).
    m_kg : float
        Moving mass at the head (loading head + sensor), kg (paper: 0.235).

    Raises
    ------
    ValueError
        if a dimension or mass is not positive and finite, or b >= B.
    """

    b_mm: float = 25.0
    B_mm: float = 56.0
    e_mm: float = 25.0
    h_mm: float = 250.0
    M_kg: float = 0.6
    m_kg: float = 0.235

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{f.name} must be a positive number, got {value!r}")
        if self.b_mm >= self.B_mm:
            raise ValueError(f"head width b_mm={self.b_mm} must be smaller than base width B_mm={self.B_mm}")

    @property
    def gamma_per_mm(self) -> float:
        """Form factor gamma (1/mm), EN 12697-26 Annex A, paper Eq. 3."""
        b, B, e, h = self.b_mm, self.B_mm, self.e_mm, self.h_mm
        r = b / B
        bracket = (2.0 - b / (2.0 * B)) * r - 1.5 - math.log(r)
        return 12.0 * h**3 / (e * (B - b) ** 3) * bracket

    @property
    def mu_g(self) -> float:
        """Mass factor mu = 0.135 M + m (g), EN 12697-26 Annex A (paper Section 2)."""
        return (0.135 * self.M_kg + self.m_kg) * 1e3

    @classmethod
    def from_json(cls, path) -> "Specimen2PB":
        """Read the geometry keys ``b_mm, B_mm, e_mm, h_mm, M_kg, m_kg`` of a JSON file.

        Other keys (e.g. ``temperature_C``, ``frequency_Hz`` of a record sidecar) are ignored.

        Raises
        ------
        InputError
            naming the file and the key if the file is unreadable, not a JSON object, a key
            is missing, or a value is not a positive number (or b_mm >= B_mm).
        """
        data = _read_json_object(path)
        values = {}
        for f in fields(cls):
            values[f.name] = _positive_number(data, f.name, path)
        try:
            return cls(**values)
        except ValueError as exc:
            raise InputError(f"{path}: {exc}") from None

    def as_dict(self) -> dict:
        return asdict(self)


def _read_json_object(path) -> dict:
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a readable JSON file ({exc})") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: expected a JSON object with keys {', '.join(RECORD_META_KEYS)}")
    return data


def _positive_number(data: dict, key: str, path) -> float:
    if key not in data:
        raise InputError(f"{path}: missing key '{key}' (expected keys: {', '.join(RECORD_META_KEYS)})")
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise InputError(f"{path}: key '{key}' must be a positive number, got {value!r}")
    return float(value)


def complex_modulus(F0_N, z0_m, psi_deg, frequency_Hz, specimen: Specimen2PB | None = None) -> dict:
    """Complex modulus of a 2PB trapezoid from force and displacement amplitudes (Eqs. 1-5).

    Parameters
    ----------
    F0_N : float or array
        Force amplitude at the head, N.
    z0_m : float or array
        Head displacement amplitude, m (converted to mm inside, as the standard writes Eq. 1).
    psi_deg : float or array
        Phase lead of the force over the displacement, degrees.
    frequency_Hz : float or array
        Loading frequency, Hz.
    specimen : Specimen2PB, optional
        Geometry and masses (default: the paper's specimen).

    Returns
    -------
    dict
        ``gamma_per_mm`` (1/mm), ``mu_g`` (g), ``E1_MPa``, ``E2_MPa``, ``E_norm_MPa`` (MPa),
        ``phase_deg`` (degrees, ``arctan2(E2, E1)``); arrays broadcast over the inputs.

    Raises
    ------
    ValueError
        if z0 or the frequency is not positive.
    """
    spec = specimen or Specimen2PB()
    F0 = np.asarray(F0_N, dtype=float)
    z0_mm = np.asarray(z0_m, dtype=float) * 1e3
    f = np.asarray(frequency_Hz, dtype=float)
    if np.any(z0_mm <= 0) or np.any(f <= 0):
        raise ValueError("z0 and the frequency must be positive")
    psi = np.radians(np.asarray(psi_deg, dtype=float))
    omega = 2.0 * np.pi * f
    gamma = spec.gamma_per_mm
    mu = spec.mu_g
    E1 = gamma * (F0 / z0_mm * np.cos(psi) + 1e-6 * mu * omega**2)  # Eq. 1
    E2 = gamma * (F0 / z0_mm * np.sin(psi))  # Eq. 2
    out = {
        "gamma_per_mm": gamma,
        "mu_g": mu,
        "E1_MPa": E1,
        "E2_MPa": E2,
        "E_norm_MPa": np.hypot(E1, E2),  # Eq. 4
        "phase_deg": np.degrees(np.arctan2(E2, E1)),  # Eq. 5
    }
    return {k: (float(v) if np.ndim(v) == 0 else v) for k, v in out.items()}


def fit_sinusoid(time_s, signal, frequency_Hz) -> dict:
    """Least-squares fit of ``offset + drift t + amplitude sin(2 pi f t + phase)``.

    Linear least squares on the basis (1, t, sin, cos) with t centred on the window for
    conditioning; the returned offset and phase refer to the original time origin.

    Parameters
    ----------
    time_s : array, shape (n,)
        Sample times, s (n >= 5, spanning at least half a period is advisable).
    signal : array, shape (n,)
        Sampled signal (any unit U).
    frequency_Hz : float
        Known frequency of the sinusoid, Hz.

    Returns
    -------
    dict
        ``amplitude`` (U, >= 0), ``phase_rad`` (rad, in (-pi, pi]), ``offset`` (U),
        ``drift`` (U/s), ``rms_residual`` (U).

    Raises
    ------
    ValueError
        if the arrays differ in shape, hold fewer than 5 samples or non-finite values, or
        the frequency is not positive.
    """
    t = np.asarray(time_s, dtype=float)
    y = np.asarray(signal, dtype=float)
    if t.shape != y.shape or t.ndim != 1:
        raise ValueError(f"time and signal must be 1-D arrays of equal length, got {t.shape} and {y.shape}")
    if t.size < 5:
        raise ValueError(f"need at least 5 samples to fit a sinusoid with offset and drift, got {t.size}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        raise ValueError("time and signal must be finite")
    if not (np.isfinite(frequency_Hz) and frequency_Hz > 0):
        raise ValueError(f"frequency must be positive, got {frequency_Hz}")
    omega = 2.0 * np.pi * float(frequency_Hz)
    tc = 0.5 * (t[0] + t[-1])
    tau = t - tc
    basis = np.column_stack([np.ones_like(tau), tau, np.sin(omega * tau), np.cos(omega * tau)])
    coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
    c0, c1, a_sin, a_cos = coef
    # a_sin sin(w tau) + a_cos cos(w tau) = A sin(w tau + phi_c);  w tau = w t - w tc
    amplitude = float(np.hypot(a_sin, a_cos))
    phase = math.atan2(a_cos, a_sin) - omega * tc
    phase = math.atan2(math.sin(phase), math.cos(phase))
    residual = y - basis @ coef
    return {
        "amplitude": amplitude,
        "phase_rad": phase,
        "offset": float(c0 - c1 * tc),
        "drift": float(c1),
        "rms_residual": float(np.sqrt(np.mean(residual**2))),
    }


def select_window(time_s, frequency_Hz, window_s=None, window_cycles=None) -> np.ndarray:
    """Boolean mask of the samples in the last ``window_s`` s or last ``window_cycles`` cycles.

    Parameters
    ----------
    time_s : array, shape (n,)
        Increasing sample times, s.
    frequency_Hz : float
        Loading frequency, Hz (for ``window_cycles``).
    window_s, window_cycles : float, optional
        At most one of them; None for both selects the whole record.

    Raises
    ------
    ValueError
        if both are given, a window is not positive or longer than the record.
    """
    t = np.asarray(time_s, dtype=float)
    if window_s is not None and window_cycles is not None:
        raise ValueError("give window_s or window_cycles, not both")
    length = None
    if window_s is not None:
        length = float(window_s)
    elif window_cycles is not None:
        length = float(window_cycles) / float(frequency_Hz)
    if length is None:
        return np.ones(t.shape, dtype=bool)
    if not length > 0:
        raise ValueError(f"window must be positive, got {length} s")
    duration = t[-1] - t[0]
    # tolerance of one sample interval: a record of exactly N cycles holds N cycles
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    if length > duration + dt * 1.0001:
        raise ValueError(f"window of {length:g} s is longer than the record ({duration:g} s)")
    return t >= t[-1] - length - 1e-9 * max(1.0, abs(t[-1]))


def reduce_record(
    time_s,
    displacement_m,
    force_N,
    specimen: Specimen2PB | None,
    frequency_Hz: float,
    window_s: float | None = None,
    window_cycles: float | None = None,
) -> dict:
    """Reduce a 2PB record (head displacement and force vs time) to one complex-modulus row.

    Parameters
    ----------
    time_s, displacement_m, force_N : arrays, shape (n,)
        Increasing times (s), head displacement (m) and force at the head (N).
    specimen : Specimen2PB or None
        Geometry and masses (None: the paper's specimen).
    frequency_Hz : float
        Loading frequency, Hz.
    window_s, window_cycles : float, optional
        Analyse the last ``window_s`` seconds (lab: 10 s) or last ``window_cycles`` cycles
        (simulation: 1); neither: the whole record.

    Returns
    -------
    dict
        ``frequency_Hz, F0_N, z0_m, psi_deg`` (Psi = phase of force - phase of displacement,
        wrapped to (-180, 180]), every key of :func:`complex_modulus`, ``n_samples``,
        ``window_start_s`` and the relative rms residuals ``force_residual`` and
        ``displacement_residual`` (rms residual / amplitude).

    Raises
    ------
    ValueError
        on arrays of different length, non-increasing time, a bad window, or a zero
        displacement amplitude.
    """
    t = np.asarray(time_s, dtype=float)
    z = np.asarray(displacement_m, dtype=float)
    F = np.asarray(force_N, dtype=float)
    if not (t.shape == z.shape == F.shape) or t.ndim != 1:
        raise ValueError(
            f"time, displacement and force must be 1-D of equal length, got {t.shape}, {z.shape}, {F.shape}"
        )
    if t.size < 5 or np.any(np.diff(t) <= 0):
        raise ValueError("time must be strictly increasing with at least 5 samples")
    mask = select_window(t, frequency_Hz, window_s=window_s, window_cycles=window_cycles)
    fz = fit_sinusoid(t[mask], z[mask], frequency_Hz)
    fF = fit_sinusoid(t[mask], F[mask], frequency_Hz)
    if fz["amplitude"] <= 0:
        raise ValueError("displacement amplitude is zero")
    psi = math.degrees(fF["phase_rad"] - fz["phase_rad"])
    psi = (psi + 180.0) % 360.0 - 180.0
    if psi == -180.0:
        psi = 180.0
    row = {
        "frequency_Hz": float(frequency_Hz),
        "F0_N": fF["amplitude"],
        "z0_m": fz["amplitude"],
        "psi_deg": psi,
    }
    row.update(complex_modulus(row["F0_N"], row["z0_m"], psi, frequency_Hz, specimen))
    row.update(
        {
            "n_samples": int(mask.sum()),
            "window_start_s": float(t[mask][0]),
            "force_residual": fF["rms_residual"] / fF["amplitude"] if fF["amplitude"] > 0 else math.nan,
            "displacement_residual": fz["rms_residual"] / fz["amplitude"],
        }
    )
    return row


def read_record(csv_path, meta_path) -> tuple[dict, Specimen2PB, dict]:
    """Read a lab record: CSV ``time_s, displacement_m, force_N`` and its JSON sidecar.

    Returns
    -------
    columns : dict of arrays, shape (n,)
        ``time_s`` (s), ``displacement_m`` (m), ``force_N`` (N).
    specimen : Specimen2PB
    conditions : dict
        ``temperature_C`` (degC), ``frequency_Hz`` (Hz).

    Raises
    ------
    InputError
        naming the file and the key/column/row for a missing or non-positive sidecar key,
        a missing column, a non-numeric or non-finite value, or non-increasing time.
    """
    import pandas as pd

    specimen = Specimen2PB.from_json(meta_path)
    data = _read_json_object(meta_path)
    if "temperature_C" not in data:
        raise InputError(f"{meta_path}: missing key 'temperature_C' (expected keys: {', '.join(RECORD_META_KEYS)})")
    T = data["temperature_C"]
    if isinstance(T, bool) or not isinstance(T, (int, float)) or not math.isfinite(T):
        raise InputError(f"{meta_path}: key 'temperature_C' must be a number, got {T!r}")
    conditions = {"temperature_C": float(T), "frequency_Hz": _positive_number(data, "frequency_Hz", meta_path)}

    csv_path = Path(csv_path)
    frame = read_csv(csv_path)
    require_columns(frame, RECORD_COLUMNS, csv_path)
    columns = {}
    for c in RECORD_COLUMNS:
        values = pd.to_numeric(frame[c], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise InputError(
                f"{csv_path}: row {bad[0] + 2} (file line), column '{c}': expected a finite number, "
                f"got {frame[c].iloc[bad[0]]!r}"
            )
        columns[c] = values
    steps = np.flatnonzero(np.diff(columns["time_s"]) <= 0)
    if steps.size:
        raise InputError(f"{csv_path}: row {steps[0] + 3} (file line), column 'time_s': time must increase")
    if len(frame) < 5:
        raise InputError(f"{csv_path}: {len(frame)} rows; need at least 5 samples")
    return columns, specimen, conditions
