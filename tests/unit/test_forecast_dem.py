"""The discrete forecast: its sample response against the direct harmonic solve (exact), its two bond
laws in their limits, a planted mix recovered through the leave-mixes-out calibration, and no leak
of a held-out mix into its fold."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.forecast import dem
from asphalt_nscd.forecast.mortar import hs_lower_mortar_modulus as mortar_modulus, rigid_inclusion_factor
from asphalt_nscd.forecast.validation import Baseline, cross_validate, mix_folds, with_binder_route
from asphalt_nscd.lab.matched import read_matched
from asphalt_nscd.sample.lattice import lattice_sample

TABLE = Path(__file__).resolve().parents[2] / "data" / "binder_mix" / "mixes_35.tsv"
MIXES = ["193", "204", "209", "211", "218", "236"]


def _sample(seed: int, n: int = 40, shrink: float = 0.95):
    """A jittered-lattice cube standing in for a prepared sample: spheres shrunk by ``shrink`` from
    touching-neighbour radii, so that the face neighbours were in contact before the shrink."""
    s = lattice_sample(n, seed=seed, aspect=(1.0, 1.0, 1.0), radius_range=(1.9e-3, 2.0e-3), jitter=0.0)
    side = float(s.plate_point[1, 2])
    s.attrs.update(B_m=side, e_m=side, h_m=side, shrink_radius_factor=shrink)
    return s


@pytest.fixture(scope="module")
def responses():
    return {m: [dem.sample_response(_sample(k), m, 1)] for k, m in enumerate(MIXES)}


@pytest.fixture(scope="module")
def table():
    t = read_matched(TABLE)
    t = t[t["mix_id"].isin(MIXES)].reset_index(drop=True)
    return with_binder_route(t, {}, pd.Series(dtype=str), "raw")


def test_the_response_is_the_direct_harmonic_solve():
    """F(zeta) of the eigen-decomposition equals the sparse complex solve of the uniaxial test with
    the bond stiffnesses g (1 + zeta s), for zeta across the plane (rel 1e-9); its compiled slope
    dF/dzeta is F's central difference (rel 1e-6)."""
    from asphalt_nscd.harmonic.network import network_from_sample
    from asphalt_nscd.harmonic.solver import HarmonicSystem
    from asphalt_nscd.sample.prepare import CONTACT_TOLERANCE

    s = _sample(3, n=60)
    r = dem.sample_response(s)
    assert 0 < r.n_skeleton < r.n_bonds
    system = HarmonicSystem(network_from_sample(s), head_rotation="clamped")
    film = np.maximum(s.bonds["delta0"], CONTACT_TOLERANCE * s.attrs["d_min_m"]) + dem.mortar_thickness(s)
    g = np.pi * s.bonds["r_min"] ** 2 / film
    skel = dem.skeleton_bonds(s)
    for zeta in (0.0, 0.3 - 0.2j, 50.0 - 30.0j, 1e4 - 1e3j, 1e-6 - 1e-5j):
        k = g * (1.0 + zeta * skel)
        sol = system.solve(k, k * system.t_ratio, 1e-12, amplitude=1.0, inertia="none", axis=2)
        assert r.factor(zeta) == pytest.approx(sol.force[2] / r.side_m, rel=1e-9)
        # the compiled slope dF/dzeta (the fits' Jacobian): the factor itself, and a central difference
        f, slope = r.factor_and_slope(np.array([zeta, zeta]))
        np.testing.assert_allclose(f, r.factor(zeta), rtol=1e-13)
        h = 1e-5 * max(abs(zeta), 1.0)
        assert slope[0] == pytest.approx((r.factor(zeta + h) - r.factor(zeta - h)) / (2 * h), rel=1e-6)
    # the slopes of an array of zetas keep its shape
    zs = np.array([[0.3 - 0.2j, 2.0], [1e3 - 1e2j, 1e-3j]])
    f, slope = r.factor_and_slope(zs)
    assert f.shape == slope.shape == zs.shape
    np.testing.assert_allclose(f, r.factor(zs), rtol=1e-13)


def test_pencil_projections_are_those_of_the_full_eigendecomposition():
    """Eigenvalues and projections V^T x of the reduction without back transformation equal SciPy's full
    generalized ``eigh`` (eigenvalues rel 1e-12, projections up to each eigenvector's sign, 1e-10), and the
    projections are complete: sum_k alpha_k beta_k = a.A^-1.b and sum_k lam_k alpha_k^2 = a.A^-1 M A^-1.a
    (rel 1e-10), on a semidefinite M of half rank as the skeleton's."""
    import scipy.linalg as sl

    rng = np.random.default_rng(11)
    n = 90
    x = rng.standard_normal((n, n))
    A = x @ x.T / n + 0.5 * np.eye(n)
    y = rng.standard_normal((n, n // 2))
    M = y @ y.T / n
    a, b = rng.standard_normal(n), rng.standard_normal(n)
    lam, (alpha, beta) = dem.pencil_projections(sl.cholesky(A, lower=True), M, [a, b])
    ref_lam, V = sl.eigh(M, A)
    np.testing.assert_allclose(lam, ref_lam, rtol=1e-12, atol=1e-12 * ref_lam.max())
    sign = np.sign(V.T @ a) * np.sign(alpha)
    big = np.abs(lam) > 1e-8 * lam.max()  # the null space's eigenvectors are any basis of it
    np.testing.assert_allclose(alpha[big] * sign[big], (V.T @ a)[big], atol=1e-10 * np.abs(alpha).max())
    np.testing.assert_allclose(beta[big] * sign[big], (V.T @ b)[big], atol=1e-10 * np.abs(beta).max())
    ainv_a, ainv_b = np.linalg.solve(A, a), np.linalg.solve(A, b)
    assert alpha @ beta == pytest.approx(a @ ainv_b, rel=1e-10)
    assert np.sum(lam * alpha**2) == pytest.approx(ainv_a @ M @ ainv_a, rel=1e-10)
    assert np.count_nonzero(~big) == n - n // 2


def test_the_forecast_modulus_holds_in_the_time_domain():
    """The bonds of a forecast (mortar and skeleton, complex) stepped in time by the NSCD core as
    Maxwell elements: within 0.05 % and 0.01 deg of the harmonic solve with inertia at 200 steps per
    cycle, the difference falling as dt^2 (second order), no contact active; the quasi-static
    response the forecast reads differs from the harmonic solve by the spheres' inertia alone."""
    s = _sample(3, n=40)
    e1, zeta = 3e8 * np.exp(1j * np.radians(30.0)), 5.0 * np.exp(-1j * np.radians(15.0))
    coarse, fine = (dem.time_domain_check(s, e1, zeta, 10.0, steps_per_cycle=n) for n in (100, 200))
    assert abs(fine["td_vs_harmonic_E_pct"]) < 0.05 and abs(fine["td_vs_harmonic_phase_deg"]) < 0.01
    assert 3.5 < coarse["td_vs_harmonic_E_pct"] / fine["td_vs_harmonic_E_pct"] < 4.5
    assert coarse["n_nonlinear_steps"] == fine["n_nonlinear_steps"] == 0
    assert abs(fine["inertia_E_pct"]) < 1e-3 and fine["E_harmonic_MPa"] > 100.0


def test_a_bond_at_one_frequency_is_its_maxwell_element():
    from asphalt_nscd.harmonic.timedomain import maxwell_equivalent

    k = np.array([2e6 + 1e6j, 5e5 + 4e6j])
    K, C = maxwell_equivalent(k, 20.0)
    np.testing.assert_allclose(1.0 / (1.0 / K + 1.0 / (1j * 20.0 * C)), k, rtol=1e-12)
    with pytest.raises(ValueError, match="Im k > 0"):
        maxwell_equivalent(np.array([1e6 - 1e3j]), 20.0)


def test_the_response_file_reads_back(tmp_path, responses):
    r = responses["193"][0]
    r.save(tmp_path / "r.npz")
    again = dem.Response.load(tmp_path / "r.npz")
    assert again.mix_id == "193" and again.factor(0.7 - 0.1j) == r.factor(0.7 - 0.1j)


def test_the_mortar_keeps_the_binder_phase_and_stiffens_by_its_inclusions():
    assert rigid_inclusion_factor(0.0) == 1.0
    assert rigid_inclusion_factor(0.01) == pytest.approx(1.025, rel=1e-3)  # Einstein's dilute limit
    e = mortar_modulus([1e6, 1e3], [40.0, 80.0], 0.3, 0.6)
    assert np.degrees(np.angle(e)) == pytest.approx([40.0, 80.0])
    assert abs(e[0]) == pytest.approx(3e6 * rigid_inclusion_factor(0.3) * rigid_inclusion_factor(0.6))


def test_dem_follows_the_mortar_and_the_extension_adds_the_glassy_and_skeleton_limits(table, responses):
    """dem: |E*| proportional to the mortar's, phase = the binder's; dem_extended: bounded by the
    stones at a glassy binder, held up by the skeleton at a soft one."""
    rows = table[table["mix_id"] == "193"]
    E, P, _ = dem.DemModel("dem", responses, 4.0).predict({"C_m": 2.0}, rows)
    np.testing.assert_allclose(P, rows["binder_delta_mix_deg"], atol=1e-9)
    ratio = E / rows["binder_G_mix_MPa"]
    np.testing.assert_allclose(ratio, ratio.iloc[0], rtol=1e-9)
    ext = dem.DemModel("dem_extended", responses, 4.0)
    glassy = rows.assign(binder_G_mix_MPa=1e6, binder_delta_mix_deg=1.0)  # a binder far stiffer than stone
    soft = rows.assign(binder_G_mix_MPa=1e-9, binder_delta_mix_deg=89.0)  # a fluid binder
    state = {"C_m": 1.0, "C_a": 0.5, "C_s": 0.01, "n_s": 0.0}
    Eg, Pg, _ = ext.predict(state, glassy)
    Es, Ps, _ = ext.predict(state, soft)
    Es2, _, _ = ext.predict(state, soft.assign(binder_G_mix_MPa=1e-11))
    r = responses["193"][0]
    stone = 0.5 * dem.E_AGGREGATE_PA
    np.testing.assert_allclose(Eg * 1e6, stone * np.real(r.factor(0.02)), rtol=2e-3)
    np.testing.assert_allclose(Es2, Es, rtol=1e-3)  # the skeleton's modulus, whatever the binder
    assert np.all(Pg < 1.0) and np.all(Ps < 1.0) and np.all(Es > 0)
    # a parabolic skeleton (n_s = 0.4): at a soft binder its phase is 0.4 times the binder's
    _, Pp, _ = ext.predict({**state, "n_s": 0.4}, soft)
    np.testing.assert_allclose(Pp, 0.4 * 89.0, atol=0.5)


def _planted(table, responses, state, noise: float, seed: int) -> pd.DataFrame:
    E, P, _ = dem.DemModel("dem_extended", responses, 4.0).predict(state, table)
    rng = np.random.default_rng(seed)
    return table.assign(
        E_norm_MPa=E * np.exp(noise * rng.standard_normal(len(E))),
        phase_deg=P + np.degrees(noise) * rng.standard_normal(len(E)),
    )


@pytest.mark.parametrize("seed", [1, 2])
def test_a_planted_mix_is_recovered_within_fold_noise(table, responses, seed):
    """Measured values made by dem_extended with known constants (3 % log noise): every fold
    recovers the constants, and every held-out forecast is within the noise of the planted value."""
    state = {"C_m": 20.0, "C_a": 0.3, "C_s": 0.5, "n_s": 0.3}
    planted = _planted(table, responses, state, 0.03, seed)
    truth = _planted(table, responses, state, 0.0, seed)
    model = dem.DemModel("dem_extended", responses, 4.0)
    ids = pd.Series({m: m for m in MIXES})
    rows, states = cross_validate(planted, [model], ids, mix_folds(MIXES), "raw")
    for s in states:
        for k, v in state.items():
            assert s["state"][k] == pytest.approx(v, rel=0.15, abs=0.05), (k, s["state"])
    merged = rows.merge(truth[["mix_id", "temperature_C", "frequency_Hz", "E_norm_MPa", "phase_deg"]])
    err = np.log(merged["E_pred_MPa"] / merged["E_norm_MPa"])
    assert np.sqrt(np.mean(err**2)) < 0.03 and np.abs(merged["phase_pred_deg"] - merged["phase_deg"]).max() < 1.0


def test_a_held_skeleton_exponent_stays_and_costs_fit_on_a_parabolic_mix(table, responses):
    """n_s held at 0 (the elastic skeleton) on data planted with n_s = 0.3: every fold keeps n_s = 0
    and fits the phase worse than the fitted exponent does."""
    planted = _planted(table, responses, {"C_m": 20.0, "C_a": 0.3, "C_s": 0.5, "n_s": 0.3}, 0.0, 1)
    ids = pd.Series({m: m for m in MIXES})
    out = {}
    for held in (0.0, None):
        model = dem.DemModel("dem_extended", responses, 4.0, skeleton_exponent=held)
        rows, states = cross_validate(planted, [model], ids, mix_folds(MIXES), "raw")
        if held is not None:
            assert all(s["state"]["n_s"] == pytest.approx(0.0, abs=1e-9) for s in states)
        merged = rows.merge(planted[["mix_id", "temperature_C", "frequency_Hz", "phase_deg"]])
        out[held] = np.abs(merged["phase_pred_deg"] - merged["phase_deg"]).mean()
    assert out[None] < 0.1 < out[0.0]


def test_a_held_out_mix_never_reaches_its_fold(table, responses):
    """Three times the held-out mix's |E*| (and 10 degrees more phase): its forecast by every model
    does not move; the forecasts of the other folds do."""
    t = _planted(table, responses, {"C_m": 20.0, "C_a": 0.3, "C_s": 0.5, "n_s": 0.3}, 0.05, 3)
    models = [
        dem.DemModel("dem", responses, 4.0),
        dem.DemModel("dem_extended", responses, 4.0),
        Baseline("hirsch", "recalibrated"),
        Baseline("witczak_1_40d", "recalibrated"),
    ]
    ids = pd.Series({m: m for m in MIXES})
    folds = mix_folds(MIXES)
    base, _ = cross_validate(t, models, ids, folds, "raw")
    held = t["mix_id"] == "204"
    moved = t.assign(
        E_norm_MPa=np.where(held, 3 * t["E_norm_MPa"], t["E_norm_MPa"]),
        phase_deg=np.where(held, t["phase_deg"] + 10, t["phase_deg"]),
    )
    again, _ = cross_validate(moved, models, ids, folds, "raw")
    own = base["mix_id"] == "204"
    np.testing.assert_array_equal(again.loc[own, "E_pred_MPa"], base.loc[own, "E_pred_MPa"])
    np.testing.assert_array_equal(again.loc[own, "phase_pred_deg"], base.loc[own, "phase_pred_deg"])
    assert np.all(again.loc[~own, "E_pred_MPa"].to_numpy() != base.loc[~own, "E_pred_MPa"].to_numpy())


@pytest.mark.slow
def test_a_coarser_gradation_stiffens_the_forecast_as_the_size_study_shows(table):
    """The same mix with more aggregate retained on 4.75 mm (rho4 33 -> 60 %): its sample, prepared by
    Section 3.2.1 at the smallest size of the size study, holds more coarse aggregate, and its
    sample factor -- mortar alone and with the skeleton -- is larger, as at every size of
    reference/forecast/size_study_summary.csv (the coarse mixes' factors above the fine ones')."""
    from asphalt_nscd.forecast import formulation
    from asphalt_nscd.sample import settings
    from asphalt_nscd.sample.prepare import finish, pack

    base = settings.merge(settings.DEFAULTS, {"deposition": {"duration_s": 0.6}, "vibration": {"duration_s": 0.1}})
    base["stabilisation"]["steps"] = 100
    mix = table[table["mix_id"] == "193"].iloc[0]
    coarse = mix.copy()
    coarse["rho4_pct"] = 60.0
    factors = []
    for m in (mix, coarse):
        cfg, passing, fraction = formulation.sample_settings(base, m, 4.0, 2.0, 1.3)
        result = finish(pack(cfg, 1, passing), cfg, 1, solid_fraction=fraction)
        r = dem.sample_response(result.sample)
        factors.append((fraction, r.factor(0.0).real, r.factor(1.0).real))
    (f0, a0, b0), (f1, a1, b1) = factors
    assert f1 > f0 + 0.1 and a1 > a0 and b1 > b0


def test_a_mix_without_a_usable_sample_is_forecast_as_missing(table, responses):
    """A sample that carries no load (its response empty): the discrete models forecast its mix as
    missing values and fit on the others; the scores count its cells as not computed."""
    from asphalt_nscd.forecast.validation import score

    t = _planted(table, responses, {"C_m": 20.0, "C_a": 0.3, "C_s": 0.5, "n_s": 0.3}, 0.03, 5)
    gone = dict(responses, **{"209": [dem.Response.empty("209", 1, _sample(9))]})
    model = dem.DemModel("dem_extended", gone, 4.0)
    ids = pd.Series({m: m for m in MIXES})
    rows, states = cross_validate(t, [model], ids, mix_folds(MIXES), "raw")
    own = rows["mix_id"] == "209"
    assert rows.loc[own, "E_pred_MPa"].isna().all() and rows.loc[~own, "E_pred_MPa"].notna().all()
    assert all(s["state"]["n_rows"] == 30 * 4 for s in states if s["fold"] != MIXES.index("209"))
    s = score(rows)
    assert s[(s["group"] == "all") & s["temperature_C"].isna()].iloc[0]["n_mixes"] == 5


def test_a_failed_eigenproblem_is_the_samples_input_error(monkeypatch):
    """LAPACK's failure in the reduction ends in the project's InputError naming the sample (the command then
    writes the mix's empty response with a warning), not a traceback."""
    from asphalt_nscd.io import InputError

    def failing(*args, **kwargs):
        raise np.linalg.LinAlgError("dstevd: info 3")

    monkeypatch.setattr(dem, "pencil_projections", failing)
    with pytest.raises(InputError, match="generalized eigenproblem of its network failed.*dstevd: info 3"):
        dem.sample_response(_sample(3, n=60))


def test_the_missing_modulus_names_the_kind_of_stiffness_missing():
    """missing_modulus: zero for an exact forecast; a forecast lacking an elastic part misses it at
    0 deg, one lacking a part like the binder at the binder's phase angle; a forecast too stiff misses a
    negative storage part; magnitudes in percent of the measured |E*|."""
    from asphalt_nscd.forecast.validation import missing_modulus

    rng = np.random.default_rng(3)
    E = rng.uniform(100.0, 3e4, 8)
    phi = rng.uniform(5.0, 40.0, 8)
    measured = E * np.exp(1j * np.radians(phi))
    np.testing.assert_allclose(missing_modulus(E, phi, E, phi), 0.0, atol=1e-12)
    for part_phase in (0.0, 60.0):  # the forecast lacks a part of 30 % of |E*_m| at part_phase
        part = 0.3 * E * np.exp(1j * np.radians(part_phase))
        forecast = measured - part
        m = missing_modulus(E, phi, np.abs(forecast), np.degrees(np.angle(forecast)))
        np.testing.assert_allclose(np.abs(m), 30.0, rtol=1e-12)
        np.testing.assert_allclose(np.degrees(np.angle(m)), part_phase, atol=1e-9)
    m = missing_modulus(E, phi, 2.0 * E, phi)  # twice as stiff at the same phase angle: all of E*_m too much
    np.testing.assert_allclose(m, -100.0 * np.exp(1j * np.radians(phi)), atol=1e-9)
    assert np.all(m.real < 0)
