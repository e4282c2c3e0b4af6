"""Data artifacts: nested fits of a flexible screening model, named only where the table's
design identifies them, at a level calibrated on the table itself.

Screening model (the null): a 2S2P1D master curve with a free shift factor and a free vertical
|E*| factor exp(v_T) per isotherm (both 0 at the reference isotherm), a |E*| factor and a
phase offset per specimen (:mod:`asphalt_nscd.rheology.master_curve`, shift "free",
:func:`vertical_term`). Candidate terms, each with its physical parameter:

* ``time_lag``: Phi + 360 f dt (``time_lag_ms``);
* ``inertia_uncorrected``: E1 - gamma 1e-6 m w^2, gamma of the declared test
  (:mod:`asphalt_nscd.lab.geometry`) (``mass_factor_g``);
* ``temperature_offset``: one inner isotherm measured at T + dT (``offset_C``);
* ``strain_nonlinearity``: |E*| exp(-b (eps - eps_ref) / 100 microstrain), eps_ref the table's
  mean strain (``modulus_drop_per_100_microstrain``);
* ``self_heating`` (the n-th test of an isotherm at T + c n, |E*| exp(-a n), Phi (1 + b n)) and
  ``temperature_drift`` (along the test order, at T + d_T (n - n_c), n_c the middle of the
  isotherm's tests in the whole table): both need the table's test order (``test_order``, or
  the test sequence its sidecar declares).

Identifiability first (:meth:`ArtifactSearch.identify`): a candidate is tested only if the
design tells its signature (weighted Jacobian columns) from the screening model's freedom and
from its *rival*, the explanation that is not an artifact: an effect along the test order or
the strain against the same effect along the frequency (the covariate's least-squares shadow,
affine in log f per specimen's isotherm: a per-isotherm drift is then a change of slope, a
failure of time-temperature superposition), an offset against one more degree of the shift
law. Measured as the cosine with the null's span and the largest canonical correlation with
the rival beyond the null; limits :data:`IDENTIFIABILITY_LIMITS` (``diagnosis.identifiability``).

:class:`ArtifactSearch` selects terms forward by extra-sum-of-squares F-tests under Holm's
step-down procedure (Holm 1979, Scand. J. Statist. 6, 65-70), each also needing the physical
sign and a practical size (``PRACTICAL_MINIMUM``); the temperature offset is tested last
(:meth:`ArtifactSearch.offset_test`). The first step's level is the smaller of the nominal
alpha / m and the level calibrated on parametric-bootstrap tables of the table's own fitted
clean model (:mod:`asphalt_nscd.diagnosis.calibration`: the Westfall-Young min-P
critical value); later steps scale it as Holm does. A point is corrected by the ratio of the
model without and with the artifacts (:func:`artifact_ratio`).

Choices (docs/choices.md, Diagnosis: causes with measured error rates; Diagnosis: what a
table can identify; Diagnosis: strain nonlinearity): the flexible null, Holm, the calibrated
level, floors set by the benchmark, the centred strain and drift terms.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from ..rheology.kramers_kronig import kk_time_lag
from ..rheology.master_curve import MasterCurveFit, MasterCurveProblem, Term, data_arrays, replicate_noise
from ..rheology.metrics import same_temperature

#: 2S2P1D parameters held at the current fit while candidates are screened: the weakly
#: identified pair (E00, beta) otherwise lets a new term switch the fit to another branch
#: of their ridge, which inflates the F statistic of null effects.
SHAPE_PARAMETERS = ("log10_E00_MPa", "log10_beta")
#: Reduced chi-square above which the current model is taken as inadequate: candidates are
#: then screened with every parameter free.
INADEQUATE_CHI2 = 2.0
#: Shift-law misfit of an isotherm, degC: the smooth law through the other isotherms'
#: free shifts is taken to predict an isotherm's shift to within this standard deviation
#: on a mix without offset; it is added to the variance of the offset test. Set by the
#: benchmark (docs/choices.md, Diagnosis: on the calibration run, base seed 11, no clean
#: table of any truth family gave a false alarm with 0.6 degC).
OFFSET_MODEL_ERROR_C = 0.6
#: Reduced chi-square of the screening model (no artifact) on the clean tables of the
#: benchmark run that measured the false-alarm rates (docs/choices.md, Diagnosis; base seed
#: 6889873025987489541, 1200 clean tables): 99th percentile and largest value. A table whose
#: screening fit is worse lies outside the range where those rates were measured.
BENCH_SCREENING_CHI2 = {"q99": 1.74, "max": 2.76}
#: unit of the practical size of each artifact (``practical_size``)
SIZE_UNITS = {
    "time_lag": "deg of phase at the highest frequency",
    "inertia_uncorrected": "% of |E*| (largest E1 deficit)",
    "temperature_offset": "degC",
    "strain_nonlinearity": "% of |E*| over the tested strain range",
    "self_heating": "% of |E*| over an isotherm",
    "temperature_drift": "degC across an isotherm (largest)",
}
#: Limits of identifiability (config ``diagnosis.identifiability``): a candidate whose
#: signature has a cosine of at least ``null`` with the screening model's span (variance
#: inflation 1 / (1 - 0.995^2) = 100), or a largest canonical correlation of at least ``rival``
#: with its rival's signature once the null is projected out, is not identifiable from the
#: table (docs/choices.md, Diagnosis: what a table can identify).
IDENTIFIABILITY_LIMITS = {"null": 0.995, "rival": 0.95}
#: what each candidate's rival is (the explanation that is not that artifact)
RIVALS = {
    "time_lag": None,
    "inertia_uncorrected": None,
    "strain_nonlinearity": "the same |E*| change along the frequency (the strain's shadow on log f within "
    "each specimen's isotherm)",
    "self_heating": "the same changes along the frequency (the test step's shadow on log f within each "
    "specimen's isotherm): a frequency response of the measurement chain",
    "temperature_drift": "a change of slope of each isotherm along the frequency (the test step's shadow on "
    "log f): a failure of time-temperature superposition",
    "temperature_offset": "one more degree of the smooth shift law (a shift law that bends there)",
}
#: the row covariate of each candidate whose frequency shadow is its rival
RIVAL_COVARIATE = {
    "strain_nonlinearity": "strain_microstrain",
    "self_heating": "test_step",
    "temperature_drift": "test_step",
}
#: artifacts screened by forward selection (the temperature offset has its own test)
SCREENED = ("time_lag", "inertia_uncorrected", "strain_nonlinearity", "self_heating", "temperature_drift")
#: Practical size below which a significant artifact is not named (units SIZE_UNITS): time
#: lag, phase shift at the highest frequency (deg); inertia, largest E1 deficit relative to
#: |E*| (%); temperature offset, degC; strain nonlinearity, change of |E*| over the tested
#: strain range (%); self-heating, drop of |E*| over an isotherm (%). Part of the level set
#: by the benchmark: on truths outside the detector's model the nominal F-test is
#: anti-conservative, and the terms that absorb the misfit stay small. The time-lag (1 deg)
#: and inertia (3 %) floors are above every false alarm of the calibration run (base seed
#: 11, 80 clean tables per family: time lag 0.27-0.72 deg, inertia 0.9-2.6 %, all on
#: tables from misspecified truths); docs/choices.md, Diagnosis.
PRACTICAL_MINIMUM = {
    "time_lag": 1.0,
    "inertia_uncorrected": 3.0,
    "temperature_offset": 0.5,
    "strain_nonlinearity": 0.5,
    "self_heating": 1.0,
    "temperature_drift": 1.0,
}

#: form factor of the paper's 2PB specimen (1/mm), the scale of the inertia parameter
PAPER_GAMMA_PER_MM = 25.09577742360453
#: fitted parameter of the inertia term: the paper-2PB-equivalent mass, g (see make_term)
INERTIA_PARAMETER = "mass_2pb_equivalent_g"
#: name of the nuisance term of the screening model (vertical shift per isotherm)
VERTICAL = "vertical_shift"
ARTIFACTS = (
    "time_lag",
    "inertia_uncorrected",
    "temperature_offset",
    "strain_nonlinearity",
    "self_heating",
    "temperature_drift",
)


def prepare_table(df: pd.DataFrame) -> pd.DataFrame:
    """Add ``test_step`` (0-based rank of ``test_order`` within (specimen, temperature)) and
    ``test_step_centre`` (half the largest step of that specimen's isotherm) to a table with a
    test order. Steps already present are kept: a part of a table (a cross-validation fold's
    training or held-out rows) keeps the steps and centres of the whole table, the order the
    tests were run in, so that a row gets the same drift correction wherever it is."""
    out = df.reset_index(drop=True).copy()
    out["specimen"] = out["specimen"].astype(str)
    if "test_step" in out.columns or "test_order" not in out.columns:
        return out
    groups = ["specimen", "temperature_C"]
    out["test_step"] = out.groupby(groups)["test_order"].rank(method="dense").to_numpy(float) - 1.0
    out["test_step_centre"] = 0.5 * out.groupby(groups)["test_step"].transform("max").to_numpy(float)
    return out


def testability(df: pd.DataFrame, test=None) -> dict:
    """For each artifact: (testable, reason); ``test``: the declared test geometry
    (:class:`asphalt_nscd.lab.geometry.DeclaredTest`, default unknown)."""
    from ..lab.geometry import DeclaredTest

    test = test if test is not None else DeclaredTest()
    n_T = df["temperature_C"].nunique()
    n_f = df["frequency_Hz"].nunique()
    out = {}
    ok = n_T >= 2 and n_f >= 3
    out["time_lag"] = (ok, "" if ok else "needs >= 2 temperatures and >= 3 frequencies")
    out["inertia_uncorrected"] = out["time_lag"]
    if ok:
        out["inertia_uncorrected"] = test.inertia_testability()
    ok = n_T >= 4 and n_f >= 2
    out["temperature_offset"] = (
        ok,
        ""
        if ok
        else "needs >= 4 isotherms (an inner isotherm against the shift law, 3 "
        "parameters with its offset, of at least 3 others)",
    )
    if "strain_microstrain" not in df.columns:
        out["strain_nonlinearity"] = (False, "the table has no strain_microstrain column")
    else:
        ls = np.log(df["strain_microstrain"].to_numpy(float))
        within = ls - df.groupby("specimen")["strain_microstrain"].transform(lambda s: np.log(s).mean()).to_numpy()
        ok = float(np.std(within)) > 0.05
        out["strain_nonlinearity"] = (ok, "" if ok else "strain amplitude does not vary within specimens")
    no_order = (
        "the table gives no test order (a test_order column, or the test sequence declared in its "
        "sidecar): an effect along the tests cannot be told from one along the frequency"
    )
    if "test_step" not in df.columns:
        out["self_heating"] = (False, no_order)
        out["temperature_drift"] = (False, no_order)
    else:
        ok = float(df["test_step"].max()) >= 2
        out["self_heating"] = (ok, "" if ok else "fewer than 3 tests per isotherm and specimen")
        ok = n_T >= 3 and float(df["test_step"].max()) >= 2
        out["temperature_drift"] = (ok, "" if ok else "needs >= 3 isotherms with >= 3 tests each")
    return out


def make_term(
    name: str, strain_ref_microstrain: float = 0.0, gamma_per_mm: float | None = None, temperatures=()
) -> Term:
    """Measurement-model term of a screened artifact (see the module table; the temperature
    offset is tested on the free shifts, :meth:`ArtifactSearch.offset_test`).

    ``strain_ref_microstrain``: the strain at which the strain-nonlinearity term is 1
    (default 0: the small-strain limit); ``gamma_per_mm``: form factor of the declared test
    (inertia); ``temperatures``: the isotherms (temperature drift: one rate per isotherm).

    Terms act in the order of the measurement chain: temperature (self-heating),
    strain nonlinearity, inertia (on E1 of the specimen), then the time lag (on the phase
    read between the channels).
    """
    if name == "time_lag":
        return Term(
            name,
            ["time_lag_ms"],
            [0.0],
            [-5.0],
            [5.0],
            apply=lambda x, E, d: E * np.exp(1j * 2 * np.pi * d["f"] * x[..., 0:1] * 1e-3),
            order=3,
        )
    if name == "inertia_uncorrected":
        # parameter: the mass (g) that would give the same E1 deficit on the paper's 2PB
        # specimen, so that its scale does not depend on the test (gamma differs by 1e3
        # between a 2PB trapezoid and a uniaxial cylinder); mass = x PAPER_GAMMA / gamma
        return Term(
            name,
            [INERTIA_PARAMETER],
            [0.0],
            [-5000.0],
            [5000.0],
            apply=lambda x, E, d: E - PAPER_GAMMA_PER_MM * 1e-6 * x[..., 0:1] * (2 * np.pi * d["f"]) ** 2,
            order=2,
        )
    if name == "strain_nonlinearity":
        return Term(
            name,
            ["modulus_drop_per_100_microstrain"],
            [0.0],
            [-0.5],
            [0.5],
            apply=lambda x, E, d: E * np.exp(-x[..., 0:1] * (d["strain_microstrain"] - strain_ref_microstrain) / 100.0),
            order=1,
        )
    if name == "self_heating":

        def heat(x, E, d):
            n = d["test_step"]
            return np.abs(E) * np.exp(-x[..., 1:2] / 100 * n + 1j * np.angle(E) * (1 + x[..., 2:3] / 100 * n))

        return Term(
            name,
            ["heating_C_per_test", "extra_drop_pct_per_test", "extra_phase_pct_per_test"],
            [0.0, 0.0, 0.0],
            [-5.0, -30.0, -30.0],
            [5.0, 30.0, 30.0],
            delta_T=lambda x, d: x[..., 0:1] * d["test_step"],
            apply=heat,
            order=0,
        )
    if name == "temperature_drift":
        temps = [float(T) for T in temperatures]

        def drift(x, d):
            # the specimen's temperature moves by x_T degC per test along the test order,
            # centred on the middle of the isotherm's tests in the whole table (its mean level
            # is the free shift's); the centre travels with the rows, so that held-out rows get
            # the correction they get inside the whole table
            n = d["test_step"] - d["test_step_centre"]
            col = rows(d["T"])
            sel = col >= 0
            out = np.zeros(np.shape(x)[:-1] + np.shape(n))
            out[..., sel] = np.asarray(x)[..., col[sel]] * n[sel]
            return out

        rows = _IsothermIndex(temps)

        return Term(
            name,
            [f"drift_C_per_test_{T:g}" for T in temps],
            [0.0] * len(temps),
            [-5.0] * len(temps),
            [5.0] * len(temps),
            delta_T=drift,
            order=0,
        )
    raise ValueError(f"unknown artifact '{name}'")


@dataclass
class Candidate:
    name: str
    term: Term


def f_test(rss0: float, rss1: float, q: int, dof1: int) -> tuple[float, float]:
    """Extra-sum-of-squares F statistic and p-value of a nested model with q more parameters."""
    if dof1 <= 0 or rss1 <= 0:
        return np.nan, np.nan
    F = max(rss0 - rss1, 0.0) / q / (rss1 / dof1)
    return float(F), float(stats.f.sf(F, q, dof1))


def one_sided(name: str, estimate: float, p: float) -> float:
    """One-sided p-value for strain nonlinearity (it can only lower |E*|); two-sided otherwise."""
    if name != "strain_nonlinearity" or not np.isfinite(p):
        return p
    return p / 2 if estimate > 0 else 1 - p / 2


class _IsothermIndex:
    """Index in ``temperatures`` of the isotherm of each row (-1: none; the last match wins),
    by :func:`same_temperature`. A fit evaluates its terms on the same rows thousands of
    times, so the index of the last rows asked for is kept (compared by value)."""

    def __init__(self, temperatures):
        self.temperatures = [float(T) for T in temperatures]
        self._rows = None
        self._col = None

    def __call__(self, T) -> np.ndarray:
        T = np.asarray(T, dtype=float)
        if self._rows is None or self._rows.shape != T.shape or not np.array_equal(self._rows, T):
            col = np.full(T.shape, -1)
            for i, T_iso in enumerate(self.temperatures):
                col[same_temperature(T, T_iso)] = i
            self._rows, self._col = T.copy(), col
        return self._col


def vertical_term(data: dict, T_ref_C: float) -> Term:
    """Nuisance term of the screening model: a free |E*| factor exp(v_T) per isotherm
    (v = 0 at ``T_ref_C``), the vertical shift of a thermorheologically not quite simple mix."""
    others = [float(T) for T in data["temperatures"] if not same_temperature(T, T_ref_C)]

    rows = _IsothermIndex(others)

    def apply(x, E, d):
        # isotherm index of each row of ``d`` (any rows: the fit's or new ones, e.g. a held-out fold)
        col = rows(d["T"])
        sel = col >= 0
        v = np.zeros(E.shape)
        v[..., sel] = np.asarray(x)[..., col[sel]]
        return E * np.exp(v)

    return Term(
        VERTICAL,
        [f"ln_vertical_{T:g}" for T in others],
        [0.0] * len(others),
        [-1.0] * len(others),
        [1.0] * len(others),
        apply=apply,
        order=-1,
    )


def _shift_law(law: str):
    """(g(T, theta, T_ref), start, lower, upper) of a smooth shift law with a free offset:
    log10 aT = offset - C1 dT/(C2 + dT) (wlf) or offset + Ea/(R ln10)(1/T - 1/Tref) (arrhenius)."""
    from ..rheology.shift import arrhenius_log_shift

    if law == "arrhenius":
        return (
            lambda T, th, Tr: th[0] + arrhenius_log_shift(T, Tr, th[1] * 1e3),
            [0.0, 200.0],
            [-50.0, 10.0],
            [50.0, 1000.0],
        )
    return (
        lambda T, th, Tr: th[0] - th[1] * (T - Tr) / (th[2] + T - Tr),
        [0.0, 25.0, 170.0],
        [-50.0, 0.1, 1.0],
        [50.0, 500.0, 1e5],
    )


#: floor of the free shifts' standard deviation in the offset test, decades (keeps the
#: weights finite at the reference isotherm, whose shift is fixed at 0)
OFFSET_FLOOR_DECADES = 1e-3


def signature(problem: MasterCurveProblem, x, index, step: float = 1e-6) -> np.ndarray:
    """Weighted Jacobian columns d r / d x_j of ``problem``'s residuals at ``x`` for the
    parameters ``index`` (central differences), shape (n_residuals, len(index))."""
    x = np.asarray(x, float)
    cols = []
    for j in index:
        h = step * max(1.0, abs(x[j]))
        e = np.zeros_like(x)
        e[j] = h
        cols.append((problem.residuals(x + e) - problem.residuals(x - e)) / (2 * h))
    return np.column_stack(cols) if cols else np.zeros((2 * problem.data["f"].size, 0))


def _orthonormal(A: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """Orthonormal basis of the column span of ``A`` (SVD, rank-revealing), shape (n, rank)."""
    if A.size == 0:
        return np.zeros((A.shape[0], 0))
    U, s, _ = np.linalg.svd(A, full_matrices=False)
    return U[:, s > rtol * max(s.max(), 1e-300)]


def canonical_correlation(A: np.ndarray, B: np.ndarray) -> float:
    """Largest canonical correlation (cosine of the smallest principal angle) between the
    column spans of ``A`` and ``B`` (0 if either is empty or null)."""
    qa, qb = _orthonormal(A), _orthonormal(B)
    if qa.shape[1] == 0 or qb.shape[1] == 0:
        return 0.0
    return float(min(1.0, np.linalg.svd(qa.T @ qb, compute_uv=False).max()))


def frequency_shadow(data: dict, key: str) -> np.ndarray:
    """The part of a row covariate (``data[key]``, shape (n,)) that the frequency explains:
    within each specimen's isotherm its least-squares fit a + b log10 f (the covariate itself
    where the isotherm has fewer than 3 distinct frequencies, which a line always fits)."""
    x = np.asarray(data[key], float)
    out = x.copy()
    lf = np.log10(data["f"])
    for s in np.unique(data["spec"]):
        for T in data["temperatures"]:
            sel = (data["spec"] == s) & same_temperature(data["T"], T)
            if np.unique(lf[sel]).size < 3:
                continue
            X = np.column_stack([np.ones(sel.sum()), lf[sel]])
            coef, *_ = np.linalg.lstsq(X, x[sel], rcond=None)
            out[sel] = X @ coef
    return out


class ArtifactSearch:
    """Forward selection of artifacts on a tidy measured table (see the module docstring).

    Parameters
    ----------
    df : DataFrame
        Measured table (``specimen, temperature_C, frequency_Hz, E_norm_MPa, phase_deg``,
        optional ``strain_microstrain, test_order``).
    alpha : float
        Level of every test (the false-alarm rates it gives are measured by
        ``asphalt-nscd diagnose-bench``).
    T_ref_C : float, optional
        Unused by the screening (its reference is the tested isotherm nearest the median);
        kept for the callers' master curve.
    shift : {"wlf", "arrhenius"}
        Smooth shift law through which a temperature offset is tested.
    test : DeclaredTest, optional
        Test geometry of the table (:mod:`asphalt_nscd.lab.geometry`); default unknown
        (inertia not testable).
    """

    def __init__(
        self,
        df: pd.DataFrame,
        alpha: float = 1e-3,
        T_ref_C=None,
        shift: str = "wlf",
        test=None,
        limits: dict | None = None,
    ):
        from ..lab.geometry import DeclaredTest

        self.df = prepare_table(df)
        self.alpha = float(alpha)
        self.data = data_arrays(self.df)
        self.test = test if test is not None else DeclaredTest()
        self.gamma = self.test.form_factor_per_mm
        self.testable = testability(self.df, self.test)
        self.limits = {**IDENTIFIABILITY_LIMITS, **(limits or {})}
        strain = ("strain_microstrain",) if self.testable["strain_nonlinearity"][0] else ()
        #: reference strain of the strain-nonlinearity term (mean of the table), microstrain
        self.strain_ref = float(np.mean(self.data["strain_microstrain"])) if strain else 0.0
        sE, sP = replicate_noise(self.df, covariates=strain)
        self.noise_from_replicates = sE is not None
        #: replicate scatter as measured (None without replicates), and the floored levels that weight the fits
        self.replicate_sigma = (sE, sP)
        self.sigma = (max(sE, 2e-3), max(sP, 0.03)) if sE is not None and sP is not None else (0.02, 0.5)
        self.shift = shift
        self.T_ref_C = T_ref_C
        temps = self.data["temperatures"]
        #: reference isotherm of the screening model (free shifts: aT = 1 there)
        self.T_screen = float(temps[np.argmin(np.abs(temps - np.median(temps)))])
        self.nuisance = [vertical_term(self.data, self.T_screen)] if temps.size > 1 else []
        #: identifiability of each testable candidate (:meth:`identify`), set by :meth:`run`
        self.identified: dict = {}

    @staticmethod
    def chi2_per_dof(fit: MasterCurveFit) -> float:
        """Reduced chi-square of a screening fit (residuals weighted by the replicate noise)."""
        return float(fit.rss / max(fit.n_residuals - fit.n_params, 1))

    def problem(self, terms, data: dict | None = None) -> MasterCurveProblem:
        return MasterCurveProblem(
            self.data if data is None else data,
            shift="free",
            T_ref_C=self.T_screen,
            terms=self.nuisance + list(terms),
            sigma_lnE=self.sigma[0],
            sigma_phase_deg=self.sigma[1],
        )

    def fit(self, terms, x0=None, fixed=()) -> MasterCurveFit:
        """Screening fit with artifact ``terms`` (the nuisance terms are added in front)."""
        return self.problem(terms).fit(x0=x0, fixed=fixed)

    def all_candidates(self) -> list:
        """Every testable candidate, identifiable or not."""
        out = []
        for name in SCREENED:
            if not self.testable[name][0]:
                continue
            if name == "strain_nonlinearity":
                out.append(Candidate(name, make_term(name, strain_ref_microstrain=self.strain_ref)))
            elif name == "inertia_uncorrected":
                out.append(Candidate(name, make_term(name, gamma_per_mm=self.gamma)))
            elif name == "temperature_drift":
                out.append(Candidate(name, make_term(name, temperatures=self.data["temperatures"])))
            else:
                out.append(Candidate(name, make_term(name)))
        return out

    def candidates(self) -> list:
        """The testable candidates the table identifies (:meth:`identify`; all of them before
        it ran)."""
        return [c for c in self.all_candidates() if self.identified.get(c.name, {}).get("identifiable", True)]

    # -------------------------------------------------------------- identifiability
    def identify(self, base: MasterCurveFit) -> dict:
        """Identifiability of every testable candidate at the screening fit ``base``
        (module docstring): per name ``null_correlation`` (largest cosine of a candidate
        column with the null's span), ``rival`` (what it is), ``rival_correlation`` (largest
        canonical correlation with the rival's columns once the null is projected out; None
        without a rival), ``identifiable`` and ``reason``. The temperature offset's entry
        comes from :meth:`offset_test` (per inner isotherm). Sets :attr:`identified`."""
        out = {}
        x_base = np.asarray(base.x, float)
        J0 = None
        for c in self.all_candidates():
            prob = self.problem([c.term])
            x = np.concatenate([x_base, np.asarray(c.term.x0, float)])
            if J0 is None:
                J0 = signature(prob, x, range(x_base.size))
                Q0 = _orthonormal(J0)
            Jc = signature(prob, x, range(x_base.size, x.size))
            norms = np.linalg.norm(Jc, axis=0)
            cos_null = float(np.max(np.linalg.norm(Q0.T @ Jc, axis=0) / np.where(norms > 0, norms, 1.0)))
            entry = {"null_correlation": cos_null, "rival": RIVALS[c.name], "rival_correlation": None}
            key = RIVAL_COVARIATE.get(c.name)
            if key is not None:
                data = dict(self.data)
                data[key] = frequency_shadow(self.data, key)
                Jr = signature(self.problem([c.term], data), x, range(x_base.size, x.size))
                entry["rival_correlation"] = canonical_correlation(Jc - Q0 @ (Q0.T @ Jc), Jr - Q0 @ (Q0.T @ Jr))
            entry.update(self._verdict(entry))
            out[c.name] = entry
        self.identified = out
        return out

    def _verdict(self, entry: dict) -> dict:
        if entry["null_correlation"] >= self.limits["null"]:
            return {
                "identifiable": False,
                "reason": (
                    f"its signature lies in the screening model's own freedom (cosine "
                    f"{entry['null_correlation']:.3f} >= {self.limits['null']:g})"
                ),
            }
        rho = entry["rival_correlation"]
        if rho is not None and rho >= self.limits["rival"]:
            return {
                "identifiable": False,
                "reason": (
                    f"the table cannot tell it from {entry['rival']} (canonical correlation "
                    f"{rho:.3f} >= {self.limits['rival']:g})"
                ),
            }
        return {"identifiable": True, "reason": ""}

    def _try(self, base: MasterCurveFit, terms, cand: Candidate):
        """Fit base + cand, warm-started.

        Re-anchoring: the reduced model is refitted from the extended solution with the new
        parameter removed; if that lowers its residual the reduced fit was a local minimum,
        and the better one is returned as ``base`` and used in the F-test.
        """
        k = len(cand.term.names)
        p_full = base.x.size + k
        inadequate = base.rss / max(base.n_residuals - p_full, 1) > INADEQUATE_CHI2
        fixed = () if inadequate else SHAPE_PARAMETERS
        best = self.fit(terms + [cand.term], x0=np.concatenate([base.x, cand.term.x0]), fixed=fixed)
        again = self.fit(terms, x0=best.x[:-k], fixed=fixed)
        if again.rss < base.rss:
            base = again
        F, p = f_test(base.rss, best.rss, k, best.n_residuals - p_full)
        p = one_sided(cand.name, best.x[-1], p)
        return best, F, p, base

    def _sign_ok(self, name: str, values, fit: MasterCurveFit) -> bool:
        """Physical sign and practical size of an estimate (see PRACTICAL_MINIMUM)."""
        return self.practical_size(name, values, fit) >= PRACTICAL_MINIMUM[name]

    def practical_size(self, name: str, values, fit: MasterCurveFit) -> float:
        """Size of a screened artifact's estimate in the units of PRACTICAL_MINIMUM (the offset
        test's size is |offset_C|); 0 for the wrong sign."""
        d = self.data
        value = float(values[0])
        if name == "self_heating":
            value = self.heating_effect(fit, values)[0]
        if name in ("strain_nonlinearity", "self_heating") and value <= 0:
            return 0.0
        if name == "time_lag":
            return abs(360.0 * d["f"].max() * value * 1e-3)
        if name == "temperature_drift":
            return float(np.max(np.abs(values)) * d["test_step"].max())
        if name == "inertia_uncorrected":
            return float(
                100 * np.max(PAPER_GAMMA_PER_MM * 1e-6 * abs(value) * (2 * np.pi * d["f"]) ** 2 / np.exp(d["lnE"]))
            )
        if name == "strain_nonlinearity":
            eps = d["strain_microstrain"]
            return 100 * value * (eps.max() - eps.min()) / 100.0
        return value * d["test_step"].max()  # self_heating: mean |E*| drop over an isotherm, %

    def nominal_level(self, family_size: int) -> float:
        """Holm's first-step level alpha / m of a family of ``family_size`` tests."""
        return self.alpha / max(int(family_size), 1)

    def run(self, level: float | None = None, x0=None) -> dict:
        """Identifiability, forward selection, then the temperature-offset test.

        ``level``: the first step's critical p-value calibrated on the table
        (:mod:`asphalt_nscd.diagnosis.calibration`); the step uses the smaller of it and the
        nominal alpha / m, and step k the Holm scaling level m / (m - k). ``x0``: start of the
        screening fit (default: its several cold starts).

        Returns ``base`` and ``final`` fits (screening model), ``selected`` candidates,
        ``identified`` (:meth:`identify`, with the offset's entry), ``offset`` (the offset
        test, :meth:`offset_test`, or None), ``tests`` (per screened artifact the entry of the
        report, :func:`effect_entries`), ``family_size`` m, ``nominal_level`` alpha / m,
        ``level`` (the first step's) and ``min_p``: the procedure's statistic, the smallest
        p-value of the first step among candidates of the right sign and practical size and
        the offset test on the first step's model; the procedure names an artifact if and
        only if ``min_p < level``.
        """
        base = self.fit([], x0=x0)
        self.identify(base)
        offset_id = self.offset_identifiability(base) if self.testable["temperature_offset"][0] else None
        if offset_id is not None:
            self.identified["temperature_offset"] = offset_id
        current = base
        selected: list[Candidate] = []
        cands = self.candidates()
        offset_on = bool(offset_id is not None and offset_id["identifiable"])
        m = len(cands) + offset_on
        nominal = self.nominal_level(m)
        first = nominal if level is None else min(float(level), nominal)
        results: list[tuple] = []
        first_round: tuple[list, MasterCurveFit] | None = None
        while True:
            step_level = first * m / max(m - len(selected), 1)  # Holm's step-down over the whole family
            results = []
            for c in cands:
                if any(s.name == c.name for s in selected):
                    continue
                fit, F, p, anchor = self._try(current, [s.term for s in selected], c)
                if anchor.rss < current.rss * (1 - 1e-6):  # escaped a local minimum: start the round again
                    current = anchor
                    break
                results.append((p, F, c, fit))
            else:
                anchor = None
            if anchor is not None:
                continue
            ok = [
                (p, F, c, fit)
                for p, F, c, fit in results
                if np.isfinite(p) and self._sign_ok(c.name, fit.x[fit.x.size - len(c.term.names) :], fit)
            ]
            if first_round is None:
                first_round = ([p for p, *_ in ok], current)
            ok = [r for r in ok if r[0] < step_level]
            if not ok:
                break
            p, F, c, fit = min(ok, key=lambda r: r[0])
            # refit from the default starts too, keeping the better solution
            cold = self.fit([s.term for s in selected] + [c.term])
            current = cold if cold.rss < fit.rss else fit
            selected.append(c)
        final = current
        tests = {}
        sizes = [len(c.term.names) for c in selected]
        start0 = final.x.size - sum(sizes)
        for i, c in enumerate(selected):
            start = start0 + sum(sizes[:i])
            idx = list(range(start, start + sizes[i]))
            others = [s.term for j, s in enumerate(selected) if j != i]
            keep = np.ones(final.x.size, bool)
            keep[idx] = False
            reduced = self.fit(others, x0=final.x[keep])
            F, p = f_test(reduced.rss, final.rss, sizes[i], final.n_residuals - final.n_params)
            p = one_sided(c.name, final.x[start], p)
            tests[c.name] = {"detected": True, "p": p, "F": F, "cand": c, "fit": final, "index": idx}
        # not selected: the test of the last round (against the final model)
        for p, F, c, fit in results:
            if c.name not in tests:
                k = len(c.term.names)
                tests[c.name] = {
                    "detected": False,
                    "p": p,
                    "F": F,
                    "cand": c,
                    "fit": fit,
                    "index": list(range(fit.x.size - k, fit.x.size)),
                }
        offset = None
        p_first = list(first_round[0]) if first_round is not None else []
        if offset_on:
            assert offset_id is not None  # offset_on only with an identifiability verdict
            offset = self.offset_test(final, offset_id["isotherms"])
            offset["level"] = first * m / max(m - len(selected), 1)
            big = abs(offset["offset_C"]) >= PRACTICAL_MINIMUM["temperature_offset"]
            offset["detected"] = bool(offset["p"] < offset["level"] and big)
            at_first = offset if not selected else self.offset_test(first_round[1], offset_id["isotherms"])
            if abs(at_first["offset_C"]) >= PRACTICAL_MINIMUM["temperature_offset"]:
                p_first.append(at_first["p"])
        return {
            "base": base,
            "final": final,
            "selected": selected,
            "tests": tests,
            "offset": offset,
            "identified": dict(self.identified),
            "family_size": m,
            "nominal_level": nominal,
            "level": first,
            "min_p": float(min(p_first)) if p_first else 1.0,
        }

    # -------------------------------------------------------------- temperature offset
    def free_shifts(self, fit: MasterCurveFit) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Temperatures (n_T,), log10 aT of the screening fit (0 at the reference) and their
        covariance (n_T, n_T) from the fit's Jacobian covariance."""
        temps = self.data["temperatures"].astype(float)
        a = np.zeros(temps.size)
        cov = np.zeros((temps.size, temps.size))
        idx = {}
        for i, T in enumerate(temps):
            name = f"log10_aT_{T:g}"
            if name in fit.names:
                idx[i] = fit.names.index(name)
                a[i] = fit.x[idx[i]]
        for i, pi in idx.items():
            for j, pj in idx.items():
                cov[i, j] = fit.cov[pi, pj]
        return temps, a, cov

    def _smooth_law(self, temps, a, cov, others=None):
        """Weighted least-squares fit of the smooth shift law (with a free offset) to the free
        shifts ``a`` at ``others`` (indices; default all): (theta, law function, weights)."""
        from scipy.optimize import least_squares

        g, x0, lo, hi = _shift_law(self.shift)
        Tr = self.T_screen
        lo_ = np.array(lo, float)
        if self.shift == "wlf":
            lo_[2] = max(lo_[2], Tr - temps.min() + 1.0)
        x_start = np.clip(x0, lo_ + 1e-9, np.array(hi) - 1e-9)
        o = np.arange(temps.size) if others is None else np.asarray(others)
        w = 1.0 / np.sqrt(np.diag(cov)[o] + OFFSET_FLOOR_DECADES**2)
        res = least_squares(lambda t: (g(temps[o], t, Tr) - a[o]) * w, x_start, bounds=(lo_, hi))
        return res, g, w

    def offset_identifiability(self, fit: MasterCurveFit) -> dict:
        """Which inner isotherms' temperature offset the table identifies: the offset of
        isotherm k moves its free shift alone, which the smooth law through the isotherms
        (p constants) cannot follow; its rival is one more degree of that law, a polynomial
        term ((T - T_mid) / half range)^p. In the metric of the offset test's variances, with
        the law's Jacobian projected out, the cosine rho_k between the two directions; an
        isotherm is tested when rho_k < the rival limit. Returns ``rival``,
        ``rival_correlation`` (the smallest rho_k), ``per_isotherm`` ({T: rho_k}),
        ``isotherms`` (indices of those tested), ``identifiable``, ``reason``."""
        temps, a, cov = self.free_shifts(fit)
        res, g, w = self._smooth_law(temps, a, cov)
        th, Tr = res.x, self.T_screen
        p = th.size
        slope = (g(temps + 0.05, th, Tr) - g(temps - 0.05, th, Tr)) / 0.1
        sd = np.sqrt(np.diag(cov) + OFFSET_FLOOR_DECADES**2 + (OFFSET_MODEL_ERROR_C * slope) ** 2)
        G = res.jac / w[:, None] / sd[:, None]  # d g / d theta, whitened
        t = (temps - 0.5 * (temps.max() + temps.min())) / max(0.5 * (temps.max() - temps.min()), 1e-9)
        r = t**p / sd
        Q = _orthonormal(G)
        r_p = r - Q @ (Q.T @ r)
        per, keep = {}, []
        for k in range(1, temps.size - 1):
            e = np.zeros(temps.size)
            e[k] = 1.0 / sd[k]
            e_p = e - Q @ (Q.T @ e)
            den = np.linalg.norm(e_p) * np.linalg.norm(r_p)
            rho = (
                1.0
                if den <= 1e-12 * max(float(np.linalg.norm(e)), 1e-300) * max(float(np.linalg.norm(r)), 1e-300)
                else float(abs(e_p @ r_p) / den)
            )
            if temps.size - p < 2:
                rho = 1.0  # one residual direction at most: it is the rival's
            per[f"{temps[k]:g}"] = rho
            if rho < self.limits["rival"]:
                keep.append(k)
        entry = {
            "null_correlation": None,
            "rival": RIVALS["temperature_offset"],
            "rival_correlation": min(per.values()) if per else None,
            "per_isotherm": per,
            "isotherms": keep,
            "identifiable": bool(keep),
            "reason": "",
        }
        if not keep:
            entry["reason"] = (
                f"with {temps.size} isotherms and a {self.shift.upper()} law of {p} constants no inner "
                f"isotherm's offset can be told from {RIVALS['temperature_offset']} (cosines "
                + ", ".join(f"{T} degC {v:.3f}" for T, v in per.items())
                + f" >= {self.limits['rival']:g})"
            )
        return entry

    def offset_test(self, fit: MasterCurveFit, isotherms=None) -> dict:
        """Temperature offset of each inner isotherm against the smooth shift law of the others.

        For an inner isotherm k (not the coldest nor the hottest: at an end of the range an
        offset cannot be told from the curvature of the shift law; ``isotherms``: the indices
        tested, default every inner one), the shift law (:attr:`shift`, with a free offset) is
        fitted by weighted least squares to the free shifts of the other isotherms (weights:
        the inverse variances of the screening fit) and predicts log10 aT_k. The deviation
        d = a_k - a_k_pred has the variance of the free shifts' estimation error (delta method)
        plus (OFFSET_MODEL_ERROR_C x |d log10 aT / dT|)^2, the misfit of the smooth law at an
        isotherm without offset (set by the benchmark); z = d / sd gives a two-sided normal
        p-value, Bonferroni-corrected over the isotherms tested, and the offset
        dT = d / (d log10 aT / dT). The isotherm reported is the one whose removal leaves the
        others most consistent with the law (smallest weighted residual of the fit to the
        others): an offset isotherm among the others distorts their law and would make its
        neighbours look offset (masking); when the fits to the others have no residual degree
        of freedom, the one of largest |z|. Returns that isotherm: ``temperature_C, offset_C,
        offset_C_se, z, p, deviation_decades, n_tested`` (and ``per_isotherm``, every isotherm
        tested with its ``others_chi2``).
        """
        temps, a, cov = self.free_shifts(fit)
        Tr = self.T_screen
        inner = list(range(1, temps.size - 1)) if isotherms is None else [int(k) for k in isotherms]
        rows = []
        for k in inner:
            o = [i for i in range(temps.size) if i != k]
            res, g, w = self._smooth_law(temps, a, cov, o)
            th = res.x
            s_o = (g(temps[o] + 0.05, th, Tr) - g(temps[o] - 0.05, th, Tr)) / 0.1
            others_chi2 = float(
                np.sum(
                    (g(temps[o], th, Tr) - a[o]) ** 2
                    / (np.diag(cov)[o] + OFFSET_FLOOR_DECADES**2 + (OFFSET_MODEL_ERROR_C * s_o) ** 2)
                )
            )
            G = res.jac / w[:, None]  # d g(T_o) / d theta
            eps = 1e-6 * np.maximum(np.abs(th), 1e-3)
            gk = np.array(
                [(g(temps[k], th + e, Tr) - g(temps[k], th - e, Tr)) / (2 * e[j]) for j, e in enumerate(np.diag(eps))]
            )
            A = np.linalg.pinv((G * w[:, None] ** 2).T @ G) @ (G * w[:, None] ** 2).T  # d theta / d a_o
            c = np.zeros(temps.size)
            c[k] = 1.0
            c[o] -= gk @ A  # d = c . a
            dev = float(a[k] - g(temps[k], th, Tr))
            slope = float((g(temps[k] + 0.05, th, Tr) - g(temps[k] - 0.05, th, Tr)) / 0.1)
            var = float(c @ cov @ c) + (OFFSET_MODEL_ERROR_C * slope) ** 2
            z = dev / np.sqrt(var) if var > 0 else np.inf * np.sign(dev)
            p = float(min(1.0, 2 * stats.norm.sf(abs(z)) * len(inner)))
            off = dev / slope if slope != 0 else np.nan
            rows.append(
                {
                    "temperature_C": float(temps[k]),
                    "offset_C": float(off),
                    "offset_C_se": float(np.sqrt(max(var, 0.0)) / abs(slope)) if slope != 0 else np.nan,
                    "z": float(z),
                    "p": p,
                    "deviation_decades": dev,
                    "index": k,
                    "others_chi2": others_chi2,
                }
            )
        chi2 = [r["others_chi2"] for r in rows]
        if max(chi2) - min(chi2) < 1e-6:  # no residual degree of freedom (e.g. 4 isotherms, WLF)
            best = max(rows, key=lambda r: abs(r["z"]) if np.isfinite(r["z"]) else np.inf)
        else:
            best = min(rows, key=lambda r: r["others_chi2"])
        return {**best, "n_tested": len(inner), "per_isotherm": rows}

    def offset_corrected_fit(self, fit: MasterCurveFit, offset: dict) -> np.ndarray:
        """Parameters of ``fit`` with the shift of the offset isotherm moved onto the smooth
        law (log10 aT_k - deviation), the other isotherms unchanged."""
        x = fit.x.copy()
        T_k = offset["temperature_C"]
        dev = offset["deviation_decades"]
        name = f"log10_aT_{T_k:g}"
        if name in fit.names:
            x[fit.names.index(name)] -= dev
        else:  # the reference isotherm: move tau_ref, and every other isotherm back
            x[fit.names.index("log10_tau_ref_s")] -= dev
            for T in self.data["temperatures"]:
                n = f"log10_aT_{T:g}"
                if n in fit.names:
                    x[fit.names.index(n)] += dev
        return x

    def heating_effect(self, fit: MasterCurveFit, values) -> tuple[float, float]:
        """Mean drop of |E*| (%) and rise of Phi (%) per earlier test of the same isotherm,
        caused by the self-heating parameters ``values`` (3,) on the master curve of ``fit``,
        over the points with n > 0."""
        d = self.data
        n = d["test_step"]
        sel = n > 0
        E0 = fit.modulus(d["f"], d["T"])
        heating = make_term("self_heating").apply
        assert heating is not None  # the self-heating term acts on the modulus
        E1 = heating(np.asarray(values, float), fit.modulus(d["f"], d["T"] + values[0] * n), d)
        drop = -np.log(np.abs(E1[sel]) / np.abs(E0[sel])) / n[sel] * 100
        rise = (np.angle(E1[sel]) / np.angle(E0[sel]) - 1) / n[sel] * 100
        return float(np.mean(drop)), float(np.mean(rise))

    # -------------------------------------------------------------- report pieces
    def artifact_terms(self, fit: MasterCurveFit) -> list:
        """The artifact terms of a screening fit (its terms without the nuisance ones)."""
        return [t for t in fit.terms if t.name != VERTICAL]

    def impact(self, fit: MasterCurveFit, index) -> tuple[float, float]:
        """Mean |change| of Phi (%) and of |E*| (%) caused by parameters ``index`` of ``fit``."""
        prob = self.problem(self.artifact_terms(fit))
        E1 = prob.measured_modulus(fit.x)
        x0 = fit.x.copy()
        x0[index] = 0.0
        E0 = prob.measured_modulus(x0)
        dphi = np.abs(np.angle(E1) - np.angle(E0)) / np.abs(np.angle(E0))
        dE = np.abs(np.log(np.abs(E1) / np.abs(E0)))
        return float(100 * np.mean(dphi)), float(100 * np.mean(dE))

    def offset_impact(self, fit: MasterCurveFit, offset: dict) -> tuple[float, float]:
        """Mean |change| of Phi (%) and of |E*| (%) caused by a temperature offset."""
        prob = self.problem(self.artifact_terms(fit))
        E1 = prob.measured_modulus(fit.x)
        E0 = prob.measured_modulus(self.offset_corrected_fit(fit, offset))
        dphi = np.abs(np.angle(E1) - np.angle(E0)) / np.abs(np.angle(E0))
        dE = np.abs(np.log(np.abs(E1) / np.abs(E0)))
        return float(100 * np.mean(dphi)), float(100 * np.mean(dE))

    def corrected(self, fit: MasterCurveFit, offset: dict | None = None) -> pd.DataFrame:
        """Measured table with the fitted artifacts of ``fit`` (and a detected temperature
        ``offset``, :meth:`offset_test`) removed.

        Each point is multiplied by the complex ratio of the model without artifacts to the
        model with them (specimen factors and vertical shifts kept), which inverts every term
        exactly; the offset isotherm is moved onto the smooth shift law of the others. A
        strain nonlinearity b is corrected to the small-strain limit (the term is fitted
        about the table's mean strain eps_ref, so every point is further multiplied by
        exp(b eps_ref / 100)).
        """
        prob = self.problem(self.artifact_terms(fit))
        x_start = None if offset is None else self.offset_corrected_fit(fit, offset)
        ratio = artifact_ratio(prob, fit, self.strain_ref, x_start)
        E = self.df["E_norm_MPa"].to_numpy(float) * np.exp(1j * np.radians(self.df["phase_deg"].to_numpy(float)))
        Ec = E * ratio
        out = self.df.copy()
        out["E_norm_MPa"] = np.abs(Ec)
        out["phase_deg"] = np.degrees(np.angle(Ec))
        return out

    def consistent_correction(
        self, result: dict, shift: str | None = None, T_ref_C: float | None = None
    ) -> tuple[pd.DataFrame, MasterCurveFit]:
        """Corrected table of a :meth:`run` result and its master curve (2S2P1D, ``shift``,
        default the search's; ``T_ref_C``, default the screening isotherm), with the
        consistency check of a detected temperature offset.

        The offset is corrected by moving its isotherm onto the smooth shift law of the
        others, a correction that presumes that law. It is kept only if the corrected table
        fits the master curve better (smaller residual sum of squares) than the table
        without it; otherwise the table keeps the isotherm as measured and
        ``result["offset"]["correction_applied"]`` is False, which :func:`effect_entries`
        reports as not named (a shift-law or model-form departure, not an offset). Sets
        ``correction_applied`` and ``master_curve_rss`` on a detected offset.
        """
        from ..rheology.master_curve import fit_master_curve

        shift = shift or self.shift
        T_ref_C = self.T_screen if T_ref_C is None else T_ref_C
        corrected = self.corrected_table(result)
        master = fit_master_curve(corrected, shift=shift, T_ref_C=T_ref_C, sigma=self.sigma)
        off = result.get("offset")
        if off is not None and off.get("detected"):
            plain = self.corrected(result["final"], None)
            master_plain = fit_master_curve(plain, shift=shift, T_ref_C=T_ref_C, sigma=self.sigma)
            off["correction_applied"] = bool(master.rss < master_plain.rss)
            off["master_curve_rss"] = {"offset_corrected": float(master.rss), "not_corrected": float(master_plain.rss)}
            if not off["correction_applied"]:
                corrected, master = plain, master_plain
        return corrected, master

    def corrected_table(self, result: dict) -> pd.DataFrame:
        """:meth:`corrected` of a :meth:`run` result (with its offset if detected)."""
        off = result.get("offset")
        return self.corrected(result["final"], off if off is not None and off.get("detected") else None)


def artifact_ratio(
    prob: MasterCurveProblem, fit: MasterCurveFit, strain_ref: float, x_start: np.ndarray | None = None
) -> np.ndarray:
    """Complex factor R per row of ``prob`` that removes the artifacts of ``fit``
    (corrected = measured x R): the model with the artifact parameters set to zero over the
    model as fitted. The nuisance terms (vertical shifts, placed before the artifacts in the
    parameter vector) and the specimen factors stay in both, so they cancel. A strain
    nonlinearity b is corrected to the small-strain limit (factor exp(b eps_ref / 100), the
    term being fitted about the reference strain ``strain_ref``, microstrain).

    ``x_start``: the parameters to clear the artifacts from (default ``fit.x``; e.g. with a
    temperature offset moved onto the shift law). One rule for the training table
    (:meth:`ArtifactSearch.corrected`) and for held-out rows
    (:class:`asphalt_nscd.diagnosis.crossval.MeasurementModel`). Shape (n_rows,).
    """
    n_art = sum(len(t.names) for t in fit.terms if t.name != VERTICAL)
    x_clean = (fit.x if x_start is None else x_start).copy()
    if n_art:
        x_clean[-n_art:] = 0.0
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        ratio = prob.measured_modulus(x_clean) / prob.measured_modulus(fit.x)
    if "modulus_drop_per_100_microstrain" in fit.names:
        ratio = ratio * np.exp(fit.param("modulus_drop_per_100_microstrain") * strain_ref / 100.0)
    return ratio


def format_p(p) -> str:
    """A p-value for the report: ``n/a``, ``< 1e-6`` below 1e-6, else two significant digits."""
    if p is None or not np.isfinite(p):
        return "n/a"
    return "< 1e-6" if p < 1e-6 else f"{p:.2g}"


def p_phrase(p) -> str:
    """``p = 0.0012``, ``p < 1e-6`` or ``p = n/a``."""
    text = format_p(p)
    return f"p {text}" if text.startswith("<") else f"p = {text}"


def _evidence(name: str, est: dict, F: float, p: float, search: ArtifactSearch, fit: MasterCurveFit) -> str:
    stat = f"F = {F:.3g}, {p_phrase(p)}"
    if name == "time_lag":
        kk = kk_time_lag(search.df)
        return (
            f"phase residual of the master curve linear in f (Phi + 360 f dt): dt = "
            f"{est['time_lag_ms']:.3f} +- {est['time_lag_ms_se']:.3f} ms ({stat}); the "
            f"Kramers-Kronig (Booij-Thoone) phase residual gives dt = {kk['time_lag_ms']:.3f} "
            f"+- {kk['time_lag_se_ms']:.3f} ms"
        )
    if name == "inertia_uncorrected":
        assert search.gamma is not None  # inertia is testable only with a form factor
        f_max = float(search.df["frequency_Hz"].max())
        dE1 = search.gamma * 1e-6 * est["mass_factor_g"] * (2 * np.pi * f_max) ** 2
        return (
            f"in-phase modulus deficit proportional to w^2 (mass term gamma m w^2 of the declared "
            f"{search.test.label}, gamma = {search.gamma:.4g} 1/mm): mass "
            f"{est['mass_factor_g']:.0f} +- {est['mass_factor_g_se']:.0f} g, "
            f"i.e. E1 lowered by {dE1:.3g} MPa at {f_max:g} Hz ({stat})"
        )
    if name == "temperature_offset":
        return (
            f"the isotherm labelled {est['temperature_C']:g} degC (the inner one whose removal leaves the "
            f"others most consistent with the law) has "
            f"the shift of {est['temperature_C'] + est['offset_C']:.1f} degC on the {search.shift.upper()} "
            f"law through the other isotherms' free shifts (offset {est['offset_C']:+.2f} +- "
            f"{est['offset_C_se']:.2f} degC, z = {est['z']:.3g}, {p_phrase(p)}, Bonferroni over "
            f"{est['n_tested']} inner isotherms; the coldest and hottest are not tested)"
        )
    if name == "strain_nonlinearity":
        return (
            f"|E*| falls with strain amplitude: {100 * est['modulus_drop_per_100_microstrain']:.2f} "
            f"+- {100 * est['modulus_drop_per_100_microstrain_se']:.2f} % per 100 microstrain ({stat})"
        )
    if name == "temperature_drift":
        rates = {
            n.removeprefix("drift_C_per_test_"): (est[n], est[n + "_se"])
            for n in est
            if n.startswith("drift_C_per_test_") and not n.endswith("_se")
        }
        worst = max(rates, key=lambda T: abs(rates[T][0]))
        return (
            "along the table's test order the isotherms read as if "
            "the specimen's temperature moved by, per test: "
            + ", ".join(f"{T} degC {v:+.2f} +- {se:.2f}" for T, (v, se) in rates.items())
            + f" degC; largest at {worst} degC, {est['size']:.1f} degC across the isotherm ({stat}, "
            f"{len(rates)} degrees of freedom): a specimen not at the test temperature when the isotherm "
            "began, or a drift of the temperature control"
        )
    if name == "self_heating":
        return (
            f"|E*| changes by {-est['modulus_drop_pct_per_test']:+.2f} +- "
            f"{est['modulus_drop_pct_per_test_se']:.2f} % and Phi by "
            f"{est['phase_rise_pct_per_test']:+.2f} +- {est['phase_rise_pct_per_test_se']:.2f} % per "
            f"earlier test of the same isotherm and specimen (temperature rise "
            f"{est['heating_C_per_test']:.2f} degC per test plus direct terms; {stat}, 3 degrees of freedom)"
        )
    return stat


def adjusted_p(p, null_min_p) -> float | None:
    """Westfall-Young single-step min-P adjusted p-value of a nominal ``p``: the fraction
    (1 + #{b: m_b <= p}) / (B + 1) of the procedure's statistic m_b on B tables of the
    table's own fitted clean model (:mod:`asphalt_nscd.diagnosis.calibration`); with several
    nulls (a list of such lists, :func:`asphalt_nscd.diagnosis.calibration.null_statistics`),
    the largest over them. None without a calibration or a p-value."""
    if p is None or null_min_p is None or not np.isfinite(p):
        return None
    nulls = [np.asarray(m, float) for m in null_min_p] if np.ndim(null_min_p[0]) else [np.asarray(null_min_p, float)]
    return float(max((1 + np.sum(m <= p)) / (m.size + 1) for m in nulls))


def effect_entries(search: ArtifactSearch, result: dict, null_min_p=None) -> list:
    """Report entries (name, detected, testable, identifiable, identifiability, score,
    p_value, p_calibrated, estimate, evidence). ``null_min_p``: the procedure's statistic on
    the calibration tables (:func:`adjusted_p`), which gives ``p_calibrated``."""
    entries = []
    identified = result.get("identified", {})
    for name in ARTIFACTS:
        testable, reason = search.testable[name]
        if not testable:
            entries.append(
                {
                    "name": name,
                    "category": "data",
                    "detected": False,
                    "testable": False,
                    "identifiable": None,
                    "identifiability": {},
                    "score": 0.0,
                    "p_value": None,
                    "p_calibrated": None,
                    "estimate": {},
                    "evidence": f"not testable: {reason}",
                }
            )
            continue
        ident = {k: v for k, v in identified.get(name, {}).items() if k != "isotherms"}
        if not ident.get("identifiable", True):
            entries.append(
                {
                    "name": name,
                    "category": "data",
                    "detected": False,
                    "testable": True,
                    "identifiable": False,
                    "identifiability": ident,
                    "score": 0.0,
                    "p_value": None,
                    "p_calibrated": None,
                    "estimate": {},
                    "evidence": f"not identifiable from this table: {ident['reason']}; never named nor "
                    "used to correct the data",
                }
            )
            continue
        if name == "temperature_offset":
            off = result["offset"]
            est = {
                k: off[k] for k in ("temperature_C", "offset_C", "offset_C_se", "z", "deviation_decades", "n_tested")
            }
            est["size"] = abs(off["offset_C"])
            est["size_unit"] = SIZE_UNITS[name]
            dphi, dE = search.offset_impact(result["final"], off)
            est["phase_change_pct"] = dphi
            est["E_norm_change_pct"] = dE
            evidence = _evidence(name, est, np.nan, off["p"], search, result["final"])
            if "correction_applied" in off:  # set by diagnosis.artifacts.analyse
                rss = off["master_curve_rss"]
                est["correction_applied"] = off["correction_applied"]
                evidence += (
                    "; corrected in the table (the corrected table fits the master curve better: RSS "
                    if off["correction_applied"]
                    else "; NOT corrected in the table (moving the isotherm onto the shift law of the others "
                    "makes the whole table fit the master curve worse: RSS "
                )
                evidence += f"{rss['offset_corrected']:.4g} corrected vs {rss['not_corrected']:.4g} as measured)"
                if not off["correction_applied"]:
                    evidence += (
                        "; not named: the isotherm departs from the shift law, but no temperature offset "
                        "explains the table (a shift law or model-form departure)"
                    )
            detected = bool(off["detected"] and off.get("correction_applied", True))
            entries.append(
                {
                    "name": name,
                    "category": "data",
                    "detected": detected,
                    "testable": True,
                    "identifiable": True,
                    "identifiability": ident,
                    "score": dphi + dE,
                    "p_value": float(off["p"]),
                    "p_calibrated": adjusted_p(off["p"], null_min_p),
                    "level": off["level"],
                    "estimate": est,
                    "evidence": evidence,
                }
            )
            continue
        t = result["tests"][name]
        fit, idx = t["fit"], t["index"]
        est = {}
        for i in idx:
            est[fit.names[i]] = float(fit.x[i])
            est[f"{fit.names[i]}_se"] = float(fit.se[i])
        if name == "inertia_uncorrected":
            assert search.gamma is not None  # inertia is testable only with a form factor
            to_g = PAPER_GAMMA_PER_MM / search.gamma
            est["mass_factor_g"] = est[INERTIA_PARAMETER] * to_g
            est["mass_factor_g_se"] = est[INERTIA_PARAMETER + "_se"] * to_g
        est["size"] = search.practical_size(name, fit.x[idx], fit)
        est["size_unit"] = SIZE_UNITS[name]
        if name == "temperature_drift":  # the rate at the hottest isotherm, where it is largest
            hot = f"drift_C_per_test_{float(search.data['temperatures'].max()):g}"
            est.update(
                {
                    "drift_C_per_test": est[hot],
                    "drift_C_per_test_se": est[hot + "_se"],
                    "temperature_C": float(search.data["temperatures"].max()),
                }
            )
        if name == "self_heating":
            vals = fit.x[idx]
            g0 = np.array(search.heating_effect(fit, vals))
            J = np.zeros((2, len(idx)))
            for j in range(len(idx)):
                step = np.zeros(len(idx))
                step[j] = 1e-4 * max(1.0, abs(vals[j]))
                J[:, j] = (np.array(search.heating_effect(fit, vals + step)) - g0) / step[j]
            se = np.sqrt(np.clip(np.diag(J @ fit.cov[np.ix_(idx, idx)] @ J.T), 0, None))
            est.update(
                {
                    "modulus_drop_pct_per_test": float(g0[0]),
                    "modulus_drop_pct_per_test_se": float(se[0]),
                    "phase_rise_pct_per_test": float(g0[1]),
                    "phase_rise_pct_per_test_se": float(se[1]),
                }
            )
        dphi, dE = search.impact(fit, idx)
        est["phase_change_pct"] = dphi
        est["E_norm_change_pct"] = dE
        p = None if not np.isfinite(t["p"]) else float(t["p"])
        evidence = _evidence(name, est, t["F"], t["p"], search, fit)
        if t.get("robustness"):
            evidence += f"; {t['robustness']}"
        entries.append(
            {
                "name": name,
                "category": "data",
                "detected": bool(t["detected"]),
                "testable": True,
                "identifiable": True,
                "identifiability": ident,
                "score": dphi + dE,
                "p_value": p,
                "p_calibrated": adjusted_p(p, null_min_p),
                "level": result.get("level"),
                "estimate": est,
                "evidence": evidence,
            }
        )
    return entries
