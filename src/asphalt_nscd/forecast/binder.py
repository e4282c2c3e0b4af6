"""The binder's own data quality, and a master curve per binder (CAM with a shift law).

Input: a tidy table of one or many binders, columns ``binder, temperature_C, frequency_Hz, G_Pa``
(|G*|), ``delta_deg`` and optionally ``eta_Pa_s``; SI units, degC, Hz, degrees. :func:`check_points`
gives every point ``passed`` and ``reason`` (names ";"-joined; tolerances are module constants):

* ``bounds``: delta in (0, 90) exclusive, |G*| > 100 Pa (the floor of the source, 0.0145 psi);
* ``monotonic``: moved by more than 0.05 in ln|G*| by an isotonic regression of ln|G*| on ln f,
  the least-squares non-decreasing isotherm: every point of a falling run is moved, since
  monotonicity alone cannot tell which of them is wrong;
* ``kramers_kronig``: |delta - (pi/2) d ln|G*| / d ln w| > 20 deg on the bounded, monotone points
  (Booij & Thoone 1982, :func:`~asphalt_nscd.rheology.kramers_kronig.booij_thoone_phase`);
* ``time_temperature`` (the cold plateau): warm to cold, an isotherm must be the next warmer
  accepted one shifted to higher frequency. It implies at each frequency a shift
  log a = (ln G_c - ln G_w) / (s ln 10), s = (delta_c + delta_w) / 180 (mean Booij-Thoone slope),
  and fails if the apparent activation energy of the median shift is below 100 kJ/mol (warmest
  step) or 15 % below the warmer step's (WLF and Arrhenius keep it constant or rising on
  cooling), or if, shifted by the median, it misses the warmer isotherm by more than 0.7 in ln|G*|.
Tolerances: 300 synthetic CAM binders with 3 % |G*| and 0.5 deg noise, 5 isotherms of 6
frequencies, pass all but the floor (largest: Booij-Thoone gap 10 deg; 2S2P1D, noise-free, 7 deg;
activation-energy drop 12.6 %, ln|G*| miss 0.37; a flat ~17 MPa cold isotherm misses by > 1).

Master curve (:func:`fit_binders`), on the passing points: CAM (Marasteanu & Anderson 1999;
w = 1 is Christensen & Anderson 1992, J. AAPT 61, with v = log 2 / R), w_r = 2 pi f aT (rad/s):
    |G*| = Gg [1 + (wc / w_r)^v]^(-w/v),        delta = 90 w / [1 + (w_r / wc)^v]
with Gg = 1 GPa fixed (the usual binder value; the data stay below 0.1 Gg, so it is not
identifiable; ``glassy="fitted"`` fits it within :data:`GLASSY_BOUNDS_PA`) and 0.3 <= w <= 1; least
squares on ln|G*| and 0.05 x delta (deg). Form checked on FHWA TFHRC-ABML/Pub_TRB_RuttingBinderPTF,
scripts/Binder_FrequencySweep_Analysis.py. Read outside the temperatures of its points, a curve
extrapolates (:meth:`BinderCurve.extrapolated`).
Shift law, T_ref = 21.1 degC: ``viscosity`` (default; log aT = log10 eta(T) / eta(T_ref) on the
binder's ASTM D2493 A-VTS line, log log eta(cP) = A + VTS log T_R, no free parameter), ``wlf``
(:func:`~asphalt_nscd.rheology.shift.wlf_log_shift`, C2 in 50-400 K) or ``arrhenius``.
The default was chosen on left-out isotherms of the mixes_35.tsv binders, where it is no worse
than WLF or Arrhenius, and has no free constant to extrapolate to -10 degC; the comparison of the
shift laws and glassy moduli, per isotherm and held out by mix: reference/forecast/binder_extrapolation.py.
MEPDG Level 1 viscosity (NCHRP 1-37A): eta = |G*| / 10 (1 / sin delta)^4.8628 at 10 rad/s, |G*|
in Pa: the result is in Pa s (its Newtonian limit is eta = |G*| / w), :func:`viscosity_Pa_s`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import isotonic_regression, least_squares
from scipy.special import expit

from ..rheology.kramers_kronig import booij_thoone_phase
from ..rheology.shift import KELVIN, R_GAS, arrhenius_log_shift, wlf_log_shift

#: glassy shear modulus of every binder, Pa (fixed)
GLASSY_MODULUS_PA = 1e9
#: how a curve takes its glassy modulus: fixed at GLASSY_MODULUS_PA, or fitted within GLASSY_BOUNDS_PA
GLASSY_FORMS = ("fixed", "fitted")
#: (low, high) of a fitted glassy modulus, Pa: a factor 3 either side of the 1 GPa that Christensen & Anderson
#: (1992) found for the binders they tested (a chosen range: a fit at a bound is reported, not hidden)
GLASSY_BOUNDS_PA = (0.3e9, 3e9)
#: temperatures closer than this to the span of a curve's points are inside it, degC
SPAN_TOL_C = 0.05
#: |G*| at or below this is the source's floor, not a measurement, Pa
G_FLOOR_PA = 100.0
#: largest move of ln|G*| by the isotonic regression of an isotherm
MONOTONIC_TOL_LN = 0.05
#: largest |delta - delta_Booij-Thoone|, degrees
KK_TOL_DEG = 20.0
#: least apparent activation energy of a binder's warmest step, J/mol
EA_MIN_J_MOL = 100e3
#: largest fall of the apparent activation energy from one step to the next colder, fraction
TTS_EA_TOL = 0.15
#: largest miss of a shifted isotherm on the warmer one, ln|G*|
TTS_OVERLAY_LN = 0.7
#: reference temperature of the master curves, degC (70 degF, the third test temperature)
T_REF_C = 21.1
SHIFT_FORMS = ("viscosity", "wlf", "arrhenius")
DEFAULT_SHIFT = "viscosity"
#: (low, high) bounds of the fitted shift constants
SHIFT_BOUNDS = {"C1": (1.0, 100.0), "C2_K": (50.0, 400.0), "Ea_J_mol": (30e3, 400e3)}
#: weight of one degree of phase against ln|G*| in the fit
PHASE_WEIGHT_PER_DEG = 0.05
#: exponent of the MEPDG Level 1 viscosity, evaluated at 10 rad/s
MEPDG_EXPONENT = 4.8628
MEPDG_OMEGA_RAD_S = 10.0
REASONS = ("bounds", "monotonic", "kramers_kronig", "time_temperature")
_COLUMNS = ("binder", "temperature_C", "frequency_Hz", "G_Pa", "delta_deg")
_SHIFT_NAMES = {"viscosity": (), "wlf": ("C1", "C2_K"), "arrhenius": ("Ea_J_mol",)}


def binder_ids(frame_of_mixes: pd.DataFrame) -> pd.Series:
    """A binder id per mix, from the mixes' binder columns.

    Rule: two mixes share a binder when their binder values (|G*|, delta and, where given, eta)
    are equal to 10 significant digits at every (temperature, frequency); the binders are
    numbered ``B01``, ``B02``, ... in the order of their first mix, mix ids sorted as text.

    Parameters
    ----------
    frame_of_mixes : DataFrame, one row per (mix, temperature, frequency)
        Columns ``mix_id, temperature_C, frequency_Hz, binder_delta_deg``, the modulus as
        ``binder_G_Pa`` (or ``binder_G_MPa``, the matched table's) and optionally
        ``binder_eta_Pa_s`` (NaN allowed).

    Returns
    -------
    Series of str, index ``mix_id`` (sorted as text), name ``binder``.

    Raises
    ------
    ValueError
        if a column is missing.
    """
    G = next((c for c in ("binder_G_Pa", "binder_G_MPa") if c in frame_of_mixes), "binder_G_Pa")
    needed = ("mix_id", "temperature_C", "frequency_Hz", G, "binder_delta_deg")
    missing = [c for c in needed if c not in frame_of_mixes]
    if missing:
        raise ValueError(f"binder ids: missing column(s) {missing}")
    cols = list(needed[1:]) + (["binder_eta_Pa_s"] if "binder_eta_Pa_s" in frame_of_mixes else [])
    keys = {}
    for mix, g in frame_of_mixes.groupby(frame_of_mixes["mix_id"].astype(str)):
        values = g.sort_values(["temperature_C", "frequency_Hz"])[cols].to_numpy(float).ravel()
        keys[mix] = ";".join(f"{v:.10g}" for v in values)
    width = max(2, len(str(len(set(keys.values())))))
    names: dict = {}
    ids = {mix: names.setdefault(keys[mix], f"B{len(names) + 1:0{width}d}") for mix in sorted(keys)}
    return pd.Series(ids, name="binder", dtype=object).rename_axis("mix_id")


def _validated(frame: pd.DataFrame) -> pd.DataFrame:
    """A copy of a binder table with numeric, finite columns (ValueError naming the problem)."""
    missing = [c for c in _COLUMNS if c not in frame]
    if missing:
        raise ValueError(f"binder table: missing column(s) {missing}")
    df = frame.reset_index(drop=True).copy()
    df["binder"] = df["binder"].astype(str)
    for c in _COLUMNS[1:]:
        x = pd.to_numeric(df[c], errors="coerce").to_numpy(float)
        bad = ~np.isfinite(x) | ((x <= 0) if c in ("frequency_Hz", "G_Pa") else False)
        if bad.any():
            which = sorted(set(df.loc[bad, "binder"]))
            raise ValueError(f"binder table: column {c} not a finite (positive) number for binder(s) {which}")
        df[c] = x
    dup = df.duplicated(["binder", "temperature_C", "frequency_Hz"])
    if dup.any():
        which = sorted(set(df.loc[dup, "binder"]))
        raise ValueError(f"binder table: repeated (binder, temperature, frequency) for binder(s) {which}")
    return df


def _implied_shift(cold: pd.DataFrame, warm: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """log10 aT from a warmer to a colder isotherm implied at each cold frequency within the
    warm isotherm's range, and the mean slope s = (delta_c + delta_w) / 180 used."""
    x, xw = np.log(cold["frequency_Hz"].to_numpy()), np.log(warm["frequency_Hz"].to_numpy())
    o = np.argsort(xw)
    inside = (x >= xw[o[0]]) & (x <= xw[o[-1]])
    lnGw = np.interp(x[inside], xw[o], np.log(warm["G_Pa"].to_numpy()[o]))
    s = (cold["delta_deg"].to_numpy()[inside] + np.interp(x[inside], xw[o], warm["delta_deg"].to_numpy()[o])) / 180.0
    return (np.log(cold["G_Pa"].to_numpy()[inside]) - lnGw) / (s * np.log(10.0)), s


def _failed_isotherms(ok: pd.DataFrame, ea_tol: float, overlay_tol: float) -> list:
    """Temperatures of one binder's isotherms that fail ``time_temperature``, judged warm to
    cold on the points ``ok`` (not empty; module docstring)."""
    iso = dict(tuple(ok.groupby("temperature_C")))
    temps = sorted(iso, reverse=True)
    failed: list = []
    ref, ea_floor = temps[0], EA_MIN_J_MOL
    for T in temps[1:]:
        la, s = _implied_shift(iso[T], iso[ref])
        if not la.size:
            continue
        med = float(np.median(la))
        ea = med * R_GAS * np.log(10.0) / (1.0 / (T + KELVIN) - 1.0 / (ref + KELVIN))
        if ea < ea_floor or np.max(np.abs(la - med) * s) * np.log(10.0) > overlay_tol:
            failed.append(T)
        else:
            ref, ea_floor = T, (1.0 - ea_tol) * ea
    return failed


def check_points(
    frame: pd.DataFrame,
    *,
    G_floor_Pa: float = G_FLOOR_PA,
    monotonic_tol: float = MONOTONIC_TOL_LN,
    kk_tol_deg: float = KK_TOL_DEG,
    tts_ea_tol: float = TTS_EA_TOL,
    tts_overlay_ln: float = TTS_OVERLAY_LN,
) -> pd.DataFrame:
    """Quality checks of every point of one or many binders (module docstring).

    Parameters
    ----------
    frame : DataFrame, n rows
        Columns ``binder, temperature_C`` (degC), ``frequency_Hz`` (Hz), ``G_Pa`` (|G*|, Pa),
        ``delta_deg`` (degrees); others (``eta_Pa_s``) are kept.
    G_floor_Pa, monotonic_tol, kk_tol_deg, tts_ea_tol, tts_overlay_ln : float
        Tolerances (:data:`G_FLOOR_PA`, :data:`MONOTONIC_TOL_LN`, :data:`KK_TOL_DEG`,
        :data:`TTS_EA_TOL`, :data:`TTS_OVERLAY_LN`).

    Returns
    -------
    DataFrame, n rows: ``frame`` (index reset) with ``passed`` (bool) and ``reason`` ("" or the
    failed checks of :data:`REASONS`, ";"-joined). ``kramers_kronig`` is judged on the points
    that pass ``bounds`` and ``monotonic`` (3 frequencies or more), ``time_temperature`` on
    those and fails whole isotherms.

    Raises
    ------
    ValueError
        on a missing column, a value that is not finite, a frequency or |G*| <= 0, or a
        repeated (binder, temperature, frequency).

    Sources: Booij & Thoone 1982 (Rheol. Acta 21); the rules and their evidence: module docstring.
    """
    df = _validated(frame)
    f, G, d = (df[c].to_numpy() for c in ("frequency_Hz", "G_Pa", "delta_deg"))
    flag = {r: np.zeros(len(df), bool) for r in REASONS}
    flag["bounds"] = (d <= 0.0) | (d >= 90.0) | (G <= G_floor_Pa)
    for idx in df.groupby(["binder", "temperature_C"]).indices.values():
        idx = idx[np.argsort(f[idx])]
        lnG = np.log(G[idx])
        flag["monotonic"][idx] = np.abs(lnG - isotonic_regression(lnG).x) > monotonic_tol
        clean = idx[~flag["bounds"][idx] & ~flag["monotonic"][idx]]
        if np.unique(f[clean]).size >= 3:
            flag["kramers_kronig"][clean] = np.abs(d[clean] - booij_thoone_phase(f[clean], G[clean])) > kk_tol_deg
    ok = df[~flag["bounds"] & ~flag["monotonic"]]
    for b, g in ok.groupby("binder"):
        for T in _failed_isotherms(g, tts_ea_tol, tts_overlay_ln):
            flag["time_temperature"] |= (df["binder"] == b).to_numpy() & (df["temperature_C"] == T).to_numpy()
    reason = [";".join(r for r in REASONS if flag[r][i]) for i in range(len(df))]
    return df.assign(passed=[r == "" for r in reason], reason=reason)


def _rankine(temperature_C) -> np.ndarray:
    return np.asarray(temperature_C, float) * 1.8 + 491.67


def a_vts(rows: pd.DataFrame) -> dict:
    """ASTM D2493 viscosity-temperature line of one binder: log10 log10 eta(cP) = A + VTS log10 T_R.

    Parameters
    ----------
    rows : DataFrame of one binder with ``temperature_C`` (degC) and ``eta_Pa_s`` (Pa s, one
        value per temperature; NaN ignored).

    Returns
    -------
    dict ``A``, ``VTS`` (least squares over the temperatures, T_R in degrees Rankine).

    Raises
    ------
    ValueError
        if fewer than 2 temperatures carry a viscosity above 1 cP.

    Source: ASTM D2493 (viscosity-temperature chart of asphalt), as NCHRP 1-37A uses it.
    """
    binder = rows["binder"].iloc[0] if "binder" in rows and len(rows) else "?"
    eta = rows.groupby("temperature_C")["eta_Pa_s"].first() if "eta_Pa_s" in rows else pd.Series(dtype=float)
    eta = eta[np.isfinite(eta) & (eta > 1e-3)]
    if eta.size < 2:
        raise ValueError(
            f"binder {binder}: the viscosity shift needs eta_Pa_s (> 1 cP) at 2 temperatures or more, got {eta.size}"
        )
    VTS, A = np.polyfit(np.log10(_rankine(eta.index)), np.log10(np.log10(eta.to_numpy() * 1e3)), 1)
    return {"A": float(A), "VTS": float(VTS)}


@dataclass
class BinderCurve:
    """CAM master curve of one binder with its shift law (module docstring).

    ``log10_wc_rad_s`` is log10 of the crossover frequency (rad/s) at ``T_ref_C``;
    ``shift_params`` holds the shift law's constants (viscosity: A, VTS; wlf: C1, C2_K;
    arrhenius: Ea_J_mol). Fit statistics on the points used: ``rmse_lnG``, ``rmse_delta_deg``,
    ``n_used``, and ``n_left_out`` (the binder's points that failed a check).
    """

    binder: str
    log10_wc_rad_s: float
    v: float
    w: float
    shift: str
    shift_params: dict
    T_ref_C: float = T_REF_C
    Gg_Pa: float = GLASSY_MODULUS_PA
    rmse_lnG: float = 0.0
    rmse_delta_deg: float = 0.0
    n_used: int = 0
    n_left_out: int = 0
    temperatures_used_C: list = field(default_factory=list)

    def extrapolated(self, temperature_C) -> np.ndarray:
        """True where the curve is read outside the temperatures of the points it was fitted on
        (below the coldest or above the warmest of ``temperatures_used_C``, by more than
        :data:`SPAN_TOL_C`): there the curve is its shift law's extrapolation, not data. Bool
        array of the shape of ``temperature_C`` (degC); ValueError for a curve that does not
        record its temperatures."""
        if not self.temperatures_used_C:
            raise ValueError(f"binder {self.binder}: its curve does not record the temperatures it was fitted on")
        T = np.asarray(temperature_C, float)
        lo, hi = min(self.temperatures_used_C), max(self.temperatures_used_C)
        return (T < lo - SPAN_TOL_C) | (T > hi + SPAN_TOL_C)

    def log_shift(self, temperature_C) -> np.ndarray:
        """log10 aT (> 0 below ``T_ref_C``) at ``temperature_C`` (degC, any shape); ValueError
        outside the WLF domain or for an unknown shift law."""
        T, p = np.asarray(temperature_C, float), self.shift_params
        if self.shift == "viscosity":
            return 10.0 ** (p["A"] + p["VTS"] * np.log10(_rankine(T))) - 10.0 ** (
                p["A"] + p["VTS"] * np.log10(_rankine(self.T_ref_C))
            )
        if self.shift == "wlf":
            return wlf_log_shift(T, self.T_ref_C, p["C1"], p["C2_K"])
        if self.shift == "arrhenius":
            return arrhenius_log_shift(T, self.T_ref_C, p["Ea_J_mol"])
        raise ValueError(f"binder {self.binder}: shift law {self.shift!r}, expected one of {SHIFT_FORMS}")

    def _z(self, temperature_C, frequency_Hz) -> np.ndarray:
        """v ln(wc / w_r), broadcast over temperatures and frequencies."""
        T, f = np.broadcast_arrays(np.asarray(temperature_C, float), np.asarray(frequency_Hz, float))
        return self.v * np.log(10.0) * (self.log10_wc_rad_s - np.log10(2.0 * np.pi * f) - self.log_shift(T))

    def G_Pa(self, temperature_C, frequency_Hz) -> np.ndarray:
        """|G*| (Pa) at temperatures (degC) and frequencies (Hz) broadcast together."""
        return self.Gg_Pa * np.exp(-self.w / self.v * np.logaddexp(0.0, self._z(temperature_C, frequency_Hz)))

    def delta_deg(self, temperature_C, frequency_Hz) -> np.ndarray:
        """Phase angle (degrees) at temperatures (degC) and frequencies (Hz) broadcast together."""
        return 90.0 * self.w * expit(self._z(temperature_C, frequency_Hz))

    def as_dict(self) -> dict:
        """A JSON-safe dict (plain floats, ints, strings); :meth:`from_dict` reads it back."""
        d = asdict(self)
        d["shift_params"] = {k: float(v) for k, v in self.shift_params.items()}
        d["temperatures_used_C"] = [float(t) for t in self.temperatures_used_C]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> BinderCurve:
        """The curve of :meth:`as_dict` (ValueError on an unknown shift law)."""
        if d.get("shift") not in SHIFT_FORMS:
            raise ValueError(f"binder {d.get('binder')}: shift law {d.get('shift')!r}, expected one of {SHIFT_FORMS}")
        return cls(
            **{
                **d,
                "shift_params": dict(d["shift_params"]),
                "temperatures_used_C": list(d.get("temperatures_used_C", [])),
            }
        )


def fit_curve(
    points: pd.DataFrame, *, shift: str = DEFAULT_SHIFT, T_ref_C: float = T_REF_C, glassy: str = "fixed"
) -> BinderCurve:
    """CAM master curve of one binder, fitted on its points that passed the checks.

    Least squares (SciPy ``least_squares``, trf, from crossover frequencies 1, 1e3 and 1e6
    rad/s; the best kept) on ln|G*| and ``PHASE_WEIGHT_PER_DEG`` x delta (deg); bounds
    -8 <= log10 wc <= 12, 0.02 <= v <= 1.5, 0.3 <= w <= 1, :data:`SHIFT_BOUNDS` and, for a
    fitted glassy modulus, :data:`GLASSY_BOUNDS_PA` (from 1 GPa).

    Parameters
    ----------
    points : DataFrame of one binder, as :func:`check_points` returns it (``passed`` column;
        without one every row is used). The viscosity shift reads ``eta_Pa_s`` of every row.
    shift : one of :data:`SHIFT_FORMS`.
    T_ref_C : reference temperature, degC.
    glassy : one of :data:`GLASSY_FORMS`: Gg fixed at :data:`GLASSY_MODULUS_PA` or fitted.

    Returns
    -------
    BinderCurve

    Raises
    ------
    ValueError
        naming the binder: several binders, an unknown shift law or glassy form, fewer passing
        points than twice the parameters (viscosity 6, Arrhenius 8, WLF 10; 2 more with Gg
        fitted) or at fewer than 2 temperatures, WLF with data below T_ref - C2_min, or no
        viscosity for the viscosity shift.
    """
    if shift not in SHIFT_FORMS:
        raise ValueError(f"shift law {shift!r}: expected one of {SHIFT_FORMS}")
    if glassy not in GLASSY_FORMS:
        raise ValueError(f"glassy modulus {glassy!r}: expected one of {GLASSY_FORMS}")
    binders = points["binder"].astype(str).unique()
    if binders.size != 1:
        raise ValueError(f"fit_curve: one binder expected, got {list(binders)}")
    binder = str(binders[0])
    used = points[points["passed"]] if "passed" in points else points
    T, f, G, d = (used[c].to_numpy(float) for c in ("temperature_C", "frequency_Hz", "G_Pa", "delta_deg"))
    names = _SHIFT_NAMES[shift]
    fit_gg = glassy == "fitted"
    n_par, n_T = 3 + len(names) + fit_gg, np.unique(T).size
    if T.size < 2 * n_par or n_T < 2:
        raise ValueError(
            f"binder {binder}: {T.size} passing point(s) at {n_T} temperature(s); the {shift} master curve needs "
            f"{2 * n_par} points at 2 temperatures or more "
            f"({len(points) - T.size} point(s) failed a check)"
        )
    if shift == "wlf" and np.any(T - T_ref_C <= -SHIFT_BOUNDS["C2_K"][0]):
        raise ValueError(f"binder {binder}: WLF with C2 >= {SHIFT_BOUNDS['C2_K'][0]} K is undefined at {T.min()} degC")
    fixed = a_vts(points) if shift == "viscosity" else {}

    def curve(x) -> BinderCurve:
        params = {**fixed, **{n: float(v) for n, v in zip(names, x[3 : 3 + len(names)])}}
        Gg = 10.0 ** float(x[-1]) if fit_gg else GLASSY_MODULUS_PA
        return BinderCurve(binder, float(x[0]), float(x[1]), float(x[2]), shift, params, T_ref_C, Gg)

    def resid(x) -> np.ndarray:
        c = curve(x)
        return np.concatenate([np.log(c.G_Pa(T, f) / G), PHASE_WEIGHT_PER_DEG * (c.delta_deg(T, f) - d)])

    gg = [np.log10(GLASSY_BOUNDS_PA[0]), np.log10(GLASSY_BOUNDS_PA[1]), np.log10(GLASSY_MODULUS_PA)] if fit_gg else []
    lower = [-8.0, 0.02, 0.3] + [SHIFT_BOUNDS[n][0] for n in names] + gg[:1]
    upper = [12.0, 1.5, 1.0] + [SHIFT_BOUNDS[n][1] for n in names] + gg[1:2]
    tail = {"viscosity": [], "wlf": [15.0, 120.0], "arrhenius": [200e3]}[shift] + gg[2:]
    fits = [
        least_squares(resid, [lw, 0.2, 0.95, *tail], bounds=(lower, upper), x_scale="jac") for lw in (0.0, 3.0, 6.0)
    ]
    c = curve(min(fits, key=lambda r: r.cost).x)
    c.rmse_lnG = float(np.sqrt(np.mean(np.log(c.G_Pa(T, f) / G) ** 2)))
    c.rmse_delta_deg = float(np.sqrt(np.mean((c.delta_deg(T, f) - d) ** 2)))
    c.n_used, c.n_left_out = int(T.size), int(len(points) - T.size)
    c.temperatures_used_C = [float(t) for t in np.unique(T)]
    return c


def fit_binders(
    frame: pd.DataFrame, *, shift: str = DEFAULT_SHIFT, T_ref_C: float = T_REF_C, **tolerances
) -> tuple[dict, pd.DataFrame]:
    """Checks and a master curve for every binder of a table.

    Parameters
    ----------
    frame : DataFrame, n rows (:func:`check_points`).
    shift, T_ref_C : the curves' shift law and reference temperature (:func:`fit_curve`).
    **tolerances : keyword tolerances of :func:`check_points`.

    Returns
    -------
    curves : dict, binder id -> :class:`BinderCurve`
    points : DataFrame, n rows, with ``passed`` and ``reason`` (:func:`check_points`).

    Raises
    ------
    ValueError
        from :func:`check_points`, or from :func:`fit_curve` for a binder whose passing points
        cannot carry a curve (no fallback: the message names the binder and what is missing).
    """
    points = check_points(frame, **tolerances)
    curves = {b: fit_curve(g, shift=shift, T_ref_C=T_ref_C) for b, g in points.groupby("binder")}
    return curves, points


#: what a binder's curve is fitted on, in order, when the points before cannot carry it: the points that pass
#: every check; those within bounds and monotonic; those within bounds (each with the viscosity shift when the
#: binder has viscosities at 2 temperatures, else Arrhenius, whose one constant the data always fix)
FIT_LADDER = (("passed", ()), ("bounds_monotonic", ("bounds", "monotonic")), ("bounds", ("bounds",)))


def fit_binder_ladder(
    points: pd.DataFrame, *, T_ref_C: float = T_REF_C, shift: str | None = None, glassy: str = "fixed"
) -> tuple[BinderCurve, str, str]:
    """The curve of one binder from :func:`check_points`'s rows: on the first rung of
    :data:`FIT_LADDER` whose points carry it, with the default shift law, or Arrhenius when the
    binder has no viscosity (``shift`` None), or with ``shift`` on every rung; ``glassy`` as in
    :func:`fit_curve`. Returns (curve, rung, shift law).

    Raises ValueError naming the binder when no rung carries a curve."""
    if shift is None:
        eta = points.get("eta_Pa_s")
        has_eta = eta is not None and points.loc[np.isfinite(eta.to_numpy(float)), "temperature_C"].nunique() >= 2
        shift = DEFAULT_SHIFT if has_eta else "arrhenius"
    errors = []
    for rung, reasons in FIT_LADDER:
        if rung == "passed":
            use = points
        else:
            bad = points["reason"].str.split(";").apply(lambda r: any(x in reasons for x in r if x))
            use = points.assign(passed=~bad.to_numpy(bool))
        try:
            return fit_curve(use, shift=shift, T_ref_C=T_ref_C, glassy=glassy), rung, shift
        except ValueError as exc:
            errors.append(f"{rung}: {exc}")
    raise ValueError(f"binder {points['binder'].iloc[0]}: no master curve ({'; '.join(errors)})")


def viscosity_Pa_s(curve: BinderCurve, temperature_C) -> np.ndarray:
    """MEPDG Level 1 binder viscosity from the master curve at 10 rad/s (NCHRP 1-37A):
    eta = |G*| / 10 (1 / sin delta)^4.8628, |G*| in Pa, eta in Pa s (module docstring), for
    the viscosity-based Witczak 1-37A equation.

    Parameters
    ----------
    curve : BinderCurve
    temperature_C : float or array, any shape (degC)

    Returns
    -------
    ndarray, same shape, Pa s.
    """
    f = MEPDG_OMEGA_RAD_S / (2.0 * np.pi)
    return mepdg_viscosity_Pa_s(curve.G_Pa(temperature_C, f), curve.delta_deg(temperature_C, f))


def mepdg_viscosity_Pa_s(G_Pa, delta_deg) -> np.ndarray:
    """MEPDG Level 1 binder viscosity (NCHRP 1-37A) of a binder's |G*| (Pa) and phase angle
    delta (degrees) at 10 rad/s: eta = |G*| / 10 (1 / sin delta)^4.8628, Pa s; arrays of one
    shape (or broadcasting), returned in that shape."""
    return G_Pa / MEPDG_OMEGA_RAD_S * (1.0 / np.sin(np.radians(delta_deg))) ** MEPDG_EXPONENT
