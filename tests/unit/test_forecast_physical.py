"""The physical discrete forecast: its uniform series terms against the per-bond direct solve, a
planted mix recovered by the ladder's fit, air voids softening it, nothing fitted by
``dem_physical``, constants held inside their ranges, and the choice inside the fold without leak."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.forecast import dem, physical
from asphalt_nscd.forecast.formulation import film_thickness_m, phase_volumes
from asphalt_nscd.forecast.nested import Selected, selection_log
from asphalt_nscd.forecast.validation import cross_validate, mix_folds, with_binder_route
from asphalt_nscd.lab.matched import read_matched
from asphalt_nscd.sample.lattice import lattice_sample

TABLE = Path(__file__).resolve().parents[2] / "data" / "binder_mix" / "mixes_35.tsv"
MIXES = ["193", "204", "209", "211", "218", "236"]


def _sample(seed: int, n: int = 40, shrink: float = 0.95):
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


def _per_bond_modulus(sample, constants, Em, Gm, film):
    """E* of the sample with every bond's own series law (no uniform approximation), by the sparse
    direct solve of the uniaxial test at each condition."""
    from asphalt_nscd.forecast.mortar import Constituents
    from asphalt_nscd.harmonic.network import network_from_sample
    from asphalt_nscd.harmonic.solver import HarmonicSystem

    system = HarmonicSystem(network_from_sample(sample), head_rotation="clamped")
    g, skel = dem.bond_geometry(sample)
    R = dem.contact_radius(sample)
    Es = constants["E_stone_Pa"] / (1 - Constituents().nu_stone ** 2)
    h = constants["film_factor"] * film
    out = []
    for em, gm in zip(Em, Gm):
        k_bridge = 1.0 / (1.0 / (g * em) + 1.0 / (sample.bonds["r_min"] * Es))
        k_film = 6 * np.pi * gm * R**2 / h
        k_stone = np.sqrt(2 * R * h) * Es
        k = k_bridge + skel / (1.0 / k_film + 1.0 / k_stone)
        sol = system.solve(k, k * system.t_ratio, 1e-12, amplitude=1.0, inertia="none", axis=2)
        out.append(sol.force[2] / float(sample.attrs["h_m"]))
    return np.array(out)


def test_the_uniform_series_terms_approximate_the_per_bond_laws(table):
    """The response with the stones' series terms taken uniform over a class (the eigen-decomposition's
    requirement) against every bond's own law solved directly, at every condition of a real binder from
    glassy to fluid: the error of the approximation, which is largest where the skeleton's contacts
    turn from stone-limited to film-limited (this lattice: 29 % and 6.2 deg, its sphere-plate contacts
    having twice the sphere-sphere radius; real samples: reference/forecast/uniform_series.csv);
    exact (1e-9) where the series terms vanish (stones rigid)."""
    s = _sample(2, n=60)
    r = dem.sample_response(s)
    rows = table[table["mix_id"] == "211"]
    v = phase_volumes(rows.iloc[0], 4.0)
    mm = physical.MixMortar(rows["binder_G_mix_MPa"].to_numpy() * 1e6, rows["binder_delta_mix_deg"].to_numpy(), v)
    c = {k: v.default for k, v in physical.CONSTANTS.items()}
    Em, Gm = mm.moduli(c["fine_packing"], c["E_stone_Pa"])
    film = film_thickness_m(rows.iloc[0])
    e1, zeta = physical.bond_moduli(c, Em, Gm, film, r)
    approx = e1 * r.factor(zeta, skeleton="film")
    exact = _per_bond_modulus(s, c, Em, Gm, film)
    assert np.max(np.abs(np.log(np.abs(approx / exact)))) < 0.33
    assert np.max(np.abs(np.degrees(np.angle(approx / exact)))) < 7.0
    stiff = {**c, "E_stone_Pa": 1e30}
    e1, zeta = physical.bond_moduli(stiff, Em, Gm, film, r)
    assert e1 * r.factor(zeta, skeleton="film") == pytest.approx(_per_bond_modulus(s, stiff, Em, Gm, film), rel=1e-9)


def test_a_planted_mix_is_recovered(responses, table):
    """Measured values made by dem_c2 with known constants (inside their ranges) on the same samples:
    the ladder step recovers them in every leave-one-mix-out fold and forecasts the held-out mix to
    1e-4; dem_c4 fitted on the same planted data does not move the held-out forecast beyond 1 %."""
    truth = physical.PhysicalDem("dem_c2", responses, 4.0)
    state = {**truth.constants((0.78, 0.35)), "at_bound": []}
    E, P, _ = truth.predict(state, table)
    planted = table.assign(E_norm_MPa=E, phase_deg=P)
    rows, states = cross_validate(planted, [truth], pd.Series({m: m for m in MIXES}), mix_folds(MIXES), "raw")
    assert np.allclose(rows["E_pred_MPa"], rows["E_meas_MPa"], rtol=1e-4)
    for st in states:
        assert st["state"]["fine_packing"] == pytest.approx(0.78, abs=1e-3)
        assert st["state"]["skeleton_exponent"] == pytest.approx(0.35, abs=1e-3)


@pytest.mark.parametrize(
    "step, physics",
    [
        ("dem_c4", physical.BondPhysics()),
        ("dem_p3", physical.BondPhysics()),
        ("dem_c3", physical.BondPhysics("pockets", None, True, None)),
    ],
)
def test_the_fits_jacobian_is_the_models_derivative(responses, table, step, physics):
    """The fits' Jacobian (the Schur sum's exact slope, the bond moduli differenced) against central
    differences of the whole model (ln|E*| and the phase, every row, every free constant), away from
    the bounds and at an upper bound (where its step turns inward): agreement to 1e-4 of the column's
    largest entry (measured: 1e-5 at worst, with confined bridges near the fine aggregate's packing limit);
    without the slope's term, or with a wrong step sign, it is off by the whole entry."""
    model = physical.PhysicalDem(step, responses, 4.0, physics=physics)
    cells = model._cells(table)
    lo = np.array([physical.CONSTANTS[k].low for k in model.free])
    hi = np.array([physical.CONSTANTS[k].high for k in model.free])
    for x in (lo + 0.37 * (hi - lo), np.where(np.arange(lo.size) == 0, hi, lo + 0.6 * (hi - lo))):
        J = model._log_modulus_jacobian(cells, len(table), x)
        assert J.shape == (len(table), lo.size) and np.all(np.isfinite(J))
        for j in range(lo.size):
            h = 1e-5 * (hi[j] - lo[j])

            def at(d, j=j, x=x):
                z = x.copy()
                z[j] += d
                return model._log_modulus(cells, len(table), model.constants(z))

            if x[j] + h <= hi[j]:  # central differences, else the second-order one-sided ones at the bound
                fd = (at(h) - at(-h)) / (2 * h)
            else:
                fd = (3 * at(0.0) - 4 * at(-h) + at(-2 * h)) / (2 * h)
            scale = np.max(np.abs(fd))
            assert scale > 0
            assert np.max(np.abs(J[:, j] - fd)) < 1e-4 * scale, (step, model.free[j])


@pytest.mark.parametrize(
    "air_phase, strain, confined, pressure, fine",
    [
        ("mastic", None, False, None, None),
        ("mortar", None, False, None, None),
        ("mortar", 1e-4, False, None, None),
        ("pockets", None, True, None, None),
        ("pockets", None, True, 6e5, None),
        ("binder", None, False, None, None),
        ("binder", 1.5e-4, True, 6e5, None),
        ("mastic", None, False, None, 6e5),
        ("pockets", None, True, 6e5, 6e5),
        ("pockets", None, True, 6e5, (6e5, 12.0)),
    ],
)
def test_more_air_voids_make_the_forecast_softer(responses, table, air_phase, strain, confined, pressure, fine):
    """At the same sample, binder and effective binder, more air voids (a larger VMA) soften every
    condition's forecast (the mortar's voids or the bridges' section, and a thicker film), wherever the
    voids enter, with the Hertz contacts, with confined bridges, with the compaction's patches and with
    the fine aggregate's own skeleton too, beside the mortar or as its contact network."""
    model = physical.PhysicalDem(
        "dem_physical",
        responses,
        4.0,
        physics=physical.BondPhysics(air_phase, strain, confined, pressure, *np.atleast_1d(fine)),
    )
    state = model.fit(table)
    rows = table[table["mix_id"] == "209"]
    E = [model.predict(state, rows.assign(Va_pct=va))[0] for va in (3.0, 5.0, 8.0)]
    assert np.all(E[0] > E[1]) and np.all(E[1] > E[2])


def test_dem_physical_fits_nothing_and_the_ladder_stays_in_range(responses, table):
    """dem_physical's constants are the defaults whatever the measured values; every fitted constant
    lies inside its documented range, and one pushed against its range is reported at its bound."""
    model = physical.PhysicalDem("dem_physical", responses, 4.0)
    a = model.fit(table)
    b = model.fit(table.assign(E_norm_MPa=table["E_norm_MPa"] * 50.0))
    for k, c in physical.CONSTANTS.items():
        assert a[k] == b[k] == c.default
    c4 = physical.PhysicalDem("dem_c4", responses, 4.0)
    st = c4.fit(table.assign(E_norm_MPa=table["E_norm_MPa"] * 30.0))
    for k in c4.free:
        assert physical.CONSTANTS[k].low <= st[k] <= physical.CONSTANTS[k].high
    assert st["at_bound"], "a forecast 30 times too stiff must push some constant to its bound"


def test_the_choice_is_made_inside_the_fold(responses, table):
    """dem_selected chooses among the ladder on the training mixes only: multiplying a held-out mix's
    measured values by 20 moves neither the choice nor the forecast of that mix; the log lists every
    candidate's inner score in every fold."""
    cands = [physical.PhysicalDem(n, responses, 4.0) for n in ("dem_physical", "dem_c1")]
    model = Selected("dem_selected", cands, inner_folds=3, seed=1)
    binder = pd.Series({m: m for m in MIXES})
    folds = mix_folds(MIXES)
    rows, states = cross_validate(table, [model], binder, folds, "raw")
    held = MIXES[2]
    bumped = table.copy()
    sel = bumped["mix_id"] == held
    bumped.loc[sel, ["E_norm_MPa"]] *= 20.0
    rows2, states2 = cross_validate(bumped, [model], binder, folds, "raw")
    k = folds.index([held])
    assert states[k]["state"]["chosen"] == states2[k]["state"]["chosen"]
    a, b = rows[rows["mix_id"] == held], rows2[rows2["mix_id"] == held]
    assert np.allclose(a["E_pred_MPa"], b["E_pred_MPa"], rtol=1e-12)
    log = selection_log(states)
    assert len(log) == len(folds) * 2 and log.groupby("fold")["chosen"].sum().eq(1).all()


@pytest.mark.parametrize("rule", ["best", "one_se"])
def test_the_sample_variant_is_chosen_inside_the_fold(responses, table, rule):
    """Measured values planted by dem_c2 on a variant's samples (other packings of twice the spheres, another
    bond geometry): dem_selected, offered the ladder on the base samples and on the variant's, chooses
    a step on the variant in every fold and forecasts the held-out mix to 1e-3; the log labels the
    variant's candidates ``<step>@<variant>``."""
    from asphalt_nscd.forecast.models import model_set

    variant = {}
    for k, m in enumerate(MIXES):
        r = dem.sample_response(_sample(k + 10, n=80), m, 1)
        r.variant = "cut4_x2"
        variant[m] = [r]
    truth = physical.PhysicalDem("dem_c2", variant, 4.0, variant="cut4_x2")
    E, P, _ = truth.predict({**truth.constants((0.78, 0.35)), "at_bound": []}, table)
    planted = table.assign(E_norm_MPa=E, phase_deg=P)
    cfg = {
        "baselines": [],
        "dem": {
            "models": [],
            "physical": ["dem_physical", "dem_c2"],
            "selected": True,
            "inner_folds": 3,
            "selection_rule": rule,
            "cut_mm": 4.0,
            "size_dmax": 2.5,
            "variants": [{"cut_mm": 4.0, "size_dmax": 2.0}],
        },
    }
    both = {m: responses[m] + variant[m] for m in MIXES}
    selected = [m for m in model_set(cfg, both) if isinstance(m, Selected)]
    assert len(selected) == 1 and len(selected[0].candidates) == 4 and selected[0].rule == rule
    rows, states = cross_validate(planted, selected, pd.Series({m: m for m in MIXES}), mix_folds(MIXES), "raw")
    assert all(st["state"]["chosen"] == "dem_c2@cut4_x2" for st in states)
    assert np.allclose(rows["E_pred_MPa"], rows["E_meas_MPa"], rtol=1e-3)
    log = selection_log(states)
    assert set(log["candidate"]) == {"dem_physical", "dem_c2", "dem_physical@cut4_x2", "dem_c2@cut4_x2"}
    assert (log["rule"] == rule).all()


def _per_mix(mean: float, spread: float, n: int = 30, seed: int = 0) -> pd.Series:
    """Per-mix inner scores of mean ``mean`` exactly, around it by +-``spread`` (a seeded draw)."""
    x = np.random.default_rng(seed).normal(0.0, 1.0, n)
    x = (x - x.mean()) / x.std(ddof=1)
    return pd.Series(mean + spread * x, index=[f"m{i}" for i in range(n)])


def test_one_standard_error_rule_takes_the_simplest_candidate_within_one_se():
    """The rule's arithmetic on constructed per-mix scores: the paired excess of each candidate over
    the best, its standard error SD/sqrt(n); the simplest qualifying candidate is taken, the best
    when nothing simpler is within one standard error."""
    from asphalt_nscd.forecast.nested import complexity, one_se_choice

    n = 30
    best = _per_mix(40.0, 5.0, n, seed=1)
    # a simpler candidate 0.5 worse on average, its per-mix excess spread 10 (SE = 10/sqrt(30) = 1.83): within
    near = best + _per_mix(0.5, 10.0, n, seed=2)
    # a simpler candidate 3 worse, excess spread 2 (SE 0.37): clearly worse
    far = best + _per_mix(3.0, 2.0, n, seed=3)
    scores = {"c4": 40.0, "c1": float(near.mean()), "physical": float(far.mean())}
    per_mix = {"c4": best, "c1": near, "physical": far}
    order = {"c4": (4, 0), "c1": (1, 0), "physical": (0, 0)}
    chosen, se = one_se_choice(scores, per_mix, order)
    assert chosen == "c1"
    assert (
        se["c4"] == 0.0
        and se["c1"] == pytest.approx(10.0 / np.sqrt(n))
        and se["physical"] == pytest.approx(2.0 / np.sqrt(n))
    )
    # the same near candidate made 3 worse at the same spread falls outside the band: the best is kept
    scores["c1"], per_mix["c1"] = 43.0 + 0.0, best + _per_mix(3.0, 10.0, n, seed=2)
    assert one_se_choice(scores, per_mix, order)[0] == "c4"
    # equal complexity: the base sample before the variant, then the least score
    pm = {"p2@cut4_x2": best, "p2": best + _per_mix(0.1, 5.0, n, seed=4)}
    tie = {k: float(v.mean()) for k, v in pm.items()}
    assert one_se_choice(tie, pm, {"p2": (2, 0), "p2@cut4_x2": (2, 1)})[0] == "p2"
    m = physical.PhysicalDem("dem_p2", {}, 4.0, variant="cut4_x2")
    assert complexity(m) == (len(m.free), 1) and complexity(physical.PhysicalDem("dem_physical", {}, 4.0)) == (0, 0)


def test_an_unknown_selection_rule_is_refused():
    from asphalt_nscd.io import InputError

    with pytest.raises(InputError, match="rule 'lowest'; expected one of"):
        Selected("dem_selected", [physical.PhysicalDem("dem_c2", {}, 4.0)], rule="lowest")


def test_an_unconfigured_sample_variant_is_refused(responses):
    """Responses of a variant the config does not list are refused, naming it; a variant that repeats
    the base sample is refused; a choice whose variant's responses are not given is refused at
    forecast time, naming it."""
    from asphalt_nscd.forecast.formulation import sample_variants
    from asphalt_nscd.forecast.models import model_set
    from asphalt_nscd.io import InputError

    r = dem.sample_response(_sample(0), "193", 1)
    r.variant = "cut8_x3"
    cfg = {"baselines": [], "dem": {"models": ["dem"], "physical": [], "cut_mm": 4.0, "size_dmax": 2.5}}
    with pytest.raises(InputError, match="cut8_x3"):
        model_set(cfg, {"193": responses["193"] + [r]})
    with pytest.raises(InputError, match="repeats the base"):
        sample_variants({"cut_mm": 4.0, "size_dmax": 2.5, "variants": [{"cut_mm": 4, "size_dmax": 2.5}]})
    assert sample_variants({"cut_mm": 4.0, "size_dmax": 2.5, "variants": [{"cut_mm": 6.3, "size_dmax": 2}]}) == {
        "cut6.3_x2": (6.3, 2.0)
    }
    base_only = Selected("dem_selected", [physical.PhysicalDem("dem_c2", responses, 4.0)])
    with pytest.raises(InputError, match="dem_c2@cut4_x2"):
        base_only.predict({"chosen": "dem_c2@cut4_x2", "state": {}}, pd.DataFrame())


@pytest.mark.parametrize("air_phase", ["mortar", "binder"])
def test_the_tabulated_porous_mortar_is_the_direct_one(table, air_phase):
    """MixMortar with the air in the mortar (added after the fine stage at every query) or in the binder
    (every inclusion's fraction over the space it shares with the air) at a packing limit and stone
    modulus on its grids gives the direct mortar_moduli, and its voids soften it against the dense mortar."""
    from asphalt_nscd.forecast.mortar import Constituents, mortar_moduli, young

    rows = table[table["mix_id"] == "211"]
    v = phase_volumes(rows.iloc[0], 4.0)
    G, d = rows["binder_G_mix_MPa"].to_numpy() * 1e6, rows["binder_delta_mix_deg"].to_numpy()
    mm = physical.MixMortar(G, d, v, air_phase=air_phase)
    E_stone = float(physical.E_STONE_GRID[2])
    Em, Gm = mm.moduli(0.8, E_stone)
    direct = mortar_moduli(G, d, v, Constituents(E_stone_Pa=E_stone, fine_packing=0.8), air_phase)
    np.testing.assert_allclose(Em, young(*direct["mortar"]), rtol=2e-3)
    np.testing.assert_allclose(Gm, direct["mastic"][1], rtol=1e-9)
    dense = physical.MixMortar(G, d, {**v, "air": 0.0}, air_phase=air_phase).moduli(0.8, E_stone)[0]
    assert np.all(np.abs(Em) < np.abs(dense))


def test_hertz_contacts_follow_hertz_and_stiffen_the_warm_forecast(responses, table):
    """The Hertz term is (6 E*^2 R N)^(1/3) per contact (computed here from a force N and radius R
    directly), grows as the strain^(1/3); in the forecast the fixed point holds (E = e_1 F(zeta + e_H(|E|)
    / e_1)), the Hertz contacts stiffen every condition and lower the warm phase angle (an elastic
    path beside the films); a response without their geometry is refused; a strain outside (0, 0.01) too."""
    from asphalt_nscd.forecast.mortar import Constituents

    r = responses["211"][0]
    assert np.isfinite(r.skeleton_v_over_l) and np.isfinite(r.skeleton_r53) and r.n_skeleton > 0
    Es = 55e9 / (1 - Constituents().nu_stone ** 2)
    E = np.array([1e8, 1e10])
    k = physical.hertz_contact(E, 1e-4, r, Es)
    N = E * 1e-4 * r.skeleton_v_over_l
    R = r.skeleton_r53**0.6  # the radius whose R^(5/3) is the mean
    np.testing.assert_allclose(k * R**2, (6 * (Es / 2) ** 2 * R * N) ** (1 / 3), rtol=1e-12)
    np.testing.assert_allclose(physical.hertz_contact(E, 8e-4, r, Es), 2 * k, rtol=1e-12)
    plain = physical.PhysicalDem("dem_physical", responses, 4.0)
    hertz = physical.PhysicalDem("dem_physical", responses, 4.0, physics=physical.BondPhysics(contact_strain=1e-4))
    rows = table[table["mix_id"] == "211"]
    E0, P0, _ = plain.predict(plain.fit(table), rows)
    E1, P1, _ = hertz.predict(hertz.fit(table), rows)
    assert np.all(E1 > E0)
    warm = rows["temperature_C"].to_numpy() > 50
    assert np.all(P1[warm] < P0[warm])
    c = hertz.constants(())
    mm, film = hertz._cells(rows)[0][1:3]
    Em, Gm = mm.moduli(c["fine_packing"], c["E_stone_Pa"])
    e1, zeta = physical.bond_moduli(c, Em, Gm, film, r)
    E = E1 * 1e6 * np.exp(1j * np.radians(P1))
    again = e1 * r.factor(zeta + physical.hertz_contact(np.abs(E), 1e-4, r, Es) / e1, skeleton="film")
    np.testing.assert_allclose(again, E, rtol=1e-6)
    import dataclasses

    from asphalt_nscd.io import InputError

    old = {"211": [dataclasses.replace(r, skeleton_v_over_l=np.nan)]}
    with pytest.raises(InputError, match="rerun forecast-response"):
        physical.PhysicalDem("dem_physical", old, 4.0, physics=physical.BondPhysics(contact_strain=1e-4)).predict(
            plain.fit(table), rows
        )
    with pytest.raises(InputError, match="contact strain"):
        physical.BondPhysics(contact_strain=0.05)


def test_bond_physics_reads_its_config_keys_and_refuses_what_is_outside_its_ranges():
    """forecast.dem's physics keys reach the options under their names (absent keys off), every fit
    records them, and an option outside its range is refused naming it."""
    from asphalt_nscd.io import InputError

    assert physical.BondPhysics.from_config({}) == physical.BondPhysics("mastic", None, False, None)
    options = physical.BondPhysics.from_config(
        {
            "air_phase": "pockets",
            "contact_strain": 1e-4,
            "bridge_confinement": True,
            "compaction_pressure_Pa": 6e5,
            "fine_skeleton_pressure_Pa": 6e4,
            "fine_contact_neighbours": 12,
        }
    )
    assert options == physical.BondPhysics("pockets", 1e-4, True, 6e5, 6e4, 12.0) and options.touching
    assert physical.BondPhysics(compaction_pressure=6e5).touching and not physical.BondPhysics().touching
    model = physical.PhysicalDem("dem_physical", {}, 4.0, physics=options)
    assert model.physics() == {
        "air_phase": "pockets",
        "contact_strain": 1e-4,
        "confinement": True,
        "compaction_pressure": 6e5,
        "fine_skeleton_pressure": 6e4,
        "fine_neighbours": 12.0,
    }
    for bad, key in (
        ({"air_phase": "asphalt"}, "air phase"),
        ({"contact_strain": 0.0}, "contact strain"),
        ({"compaction_pressure_Pa": "high"}, "compaction pressure 'high'; expected a number"),
        ({"fine_skeleton_pressure_Pa": 0.0}, "fine skeleton pressure 0.0 Pa; expected in"),
        ({"fine_skeleton_pressure_Pa": 2e8}, "fine skeleton pressure"),
        ({"fine_contact_neighbours": 12}, "fine neighbours need a fine skeleton pressure"),
        ({"fine_skeleton_pressure_Pa": 6e5, "fine_contact_neighbours": 6}, "fine neighbours 6.0; expected in"),
        ({"fine_skeleton_pressure_Pa": 6e5, "fine_contact_neighbours": 50}, "fine neighbours 50.0; expected in"),
        ({"fine_skeleton_pressure_Pa": 6e5, "fine_contact_neighbours": "many"}, "fine neighbours 'many'; expected a"),
    ):
        with pytest.raises(InputError, match=key):
            physical.BondPhysics.from_config(bad)
    # a number written as text in a config is read once, as the number
    assert physical.BondPhysics.from_config({"contact_strain": "1.5e-4"}).contact_strain == 1.5e-4


def test_compaction_patches_are_flat_punches_that_stiffen_the_warm_forecast(responses, table):
    """A contact pressed by the compactor keeps the patch of that load: its stiffness is the flat
    punch's 2 a E* with a the Hertz radius under the compaction's mean contact force (Love-Weber), the
    same whatever the sample's modulus while the test's stress stays below the pressure, the test's
    own Hertz contact above it; it grows as the pressure's cube root; the forecast gains most warm,
    where the binder carries least, and its warm phase falls (an elastic skeleton); refused out of range."""
    from asphalt_nscd.forecast.mortar import Constituents
    from asphalt_nscd.io import InputError

    r = responses["211"][0]
    Es = 55e9 / (1 - Constituents().nu_stone ** 2)
    Estar, p = Es / 2, 6e5
    N = p * r.skeleton_v_over_l
    R = r.skeleton_r53**0.6  # the radius whose R^(5/3) is the mean
    a = (3 * N * R / (4 * Estar)) ** (1 / 3)  # Hertz: the patch's radius under N
    soft, stiff = np.array([1e7, 1e8]), np.array([2e10, 3e10])
    k = physical.hertz_contact(soft, 1e-4, r, Es, pressure=p)
    np.testing.assert_allclose(k * R**2, 2 * a * Estar, rtol=1e-12)  # the flat punch, one value for both moduli
    np.testing.assert_allclose(physical.hertz_contact(soft, 0.0, r, Es, pressure=8 * p), 2 * k, rtol=1e-12)
    np.testing.assert_allclose(  # a test stress above the pressure: the test's own Hertz contact
        physical.hertz_contact(stiff, 1e-4, r, Es, pressure=p), physical.hertz_contact(stiff, 1e-4, r, Es), rtol=1e-12
    )
    rows = table[table["mix_id"] == "211"]
    T = rows["temperature_C"].to_numpy()
    plain = physical.PhysicalDem(
        "dem_physical", responses, 4.0, physics=physical.BondPhysics(air_phase="pockets", confinement=True)
    )
    pressed = physical.PhysicalDem(
        "dem_physical", responses, 4.0, physics=physical.BondPhysics("pockets", None, True, p)
    )
    E0, P0, _ = plain.predict(plain.fit(table), rows)
    state = pressed.fit(table)
    assert state["compaction_pressure"] == p
    E1, P1, _ = pressed.predict(state, rows)
    gain = np.log(E1 / E0)
    assert np.all(gain > 0) and gain[T > 50].mean() > 3 * gain[T < 0].mean()
    assert np.all(P1[T > 50] < P0[T > 50])
    harder = physical.PhysicalDem(
        "dem_physical", responses, 4.0, physics=physical.BondPhysics("pockets", None, True, 4 * p)
    )
    assert np.all(harder.predict(harder.fit(table), rows)[0] > E1)
    for bad in (0.0, -1.0, 2e8):
        with pytest.raises(InputError, match="compaction pressure"):
            physical.BondPhysics(compaction_pressure=bad)


def test_the_fine_skeleton_adds_to_the_mortar_and_stiffens_the_warm_forecast_elastically(responses, table):
    """With the fine aggregate's skeleton (mortar.granular_skeleton at the mix's fine fraction of its mortar)
    the mortar's K and G are the suspension's plus the skeleton's, exactly, where that sum is below the
    Hashin-Shtrikman upper bound, and the bound (the sum's phase kept) where it is not: never above it; the
    forecast stiffens at every cell, most where the binder is softest, and its warm phase falls (an elastic
    skeleton); a higher pressure stiffens further; the fits' Jacobian still matches finite differences."""
    from asphalt_nscd.forecast.mortar import Constituents, granular_skeleton, young

    rows = table[table["mix_id"] == "211"].reset_index(drop=True)
    T = rows["temperature_C"].to_numpy()
    plain = physical.PhysicalDem("dem_physical", responses, 4.0)
    grains = physical.PhysicalDem(
        "dem_physical", responses, 4.0, physics=physical.BondPhysics(fine_skeleton_pressure=6e5)
    )
    c = plain.constants(())
    cells = plain._cells(rows)
    mortar = cells[0][1]
    (K, G), _ = mortar.bulk_shear(c["fine_packing"], c["E_stone_Pa"])
    Kg, Gg = granular_skeleton(c["E_stone_Pa"], Constituents().nu_stone, mortar.phi_fine, 6e5)
    assert Kg > 0 and 0.6 * Kg == Gg
    w = physical._stone_weights(float(np.log(c["E_stone_Pa"])))
    cK, cG = np.exp(np.tensordot(w, mortar._cap_nodes, axes=1))  # the mortar's Hashin-Shtrikman upper bounds
    (Kc, Gc), _ = mortar.bulk_shear(c["fine_packing"], c["E_stone_Pa"], (Kg, Gg))
    for got, plain_sum, cap in ((Kc, K + Kg, cK), (Gc, G + Gg, cG)):
        np.testing.assert_allclose(
            got, np.where(np.abs(plain_sum) > cap, plain_sum * cap / np.abs(plain_sum), plain_sum)
        )
        assert np.all(np.abs(got) <= cap * (1 + 1e-12))
    # a skeleton that would push the mortar past the bound (a packing of 60 contacts a grain at 100 MPa) meets the cap
    strong = granular_skeleton(c["E_stone_Pa"], 0.2, 0.7, 1e8, coordination=60.0)
    (Kh, _), _ = mortar.bulk_shear(c["fine_packing"], c["E_stone_Pa"], strong)
    assert np.all(np.abs(Kh) <= cK * (1 + 1e-12)) and np.any(np.isclose(np.abs(Kh), cK, rtol=1e-12))
    ((_, e1_plain, _),) = plain._bond_parts(cells, c)[0]
    ((_, e1_grains, _),) = grains._bond_parts(grains._cells(rows), c)[0]
    Es = physical.plane_strain_stone(c)
    chi = responses["211"][0].chi_bridge
    np.testing.assert_allclose(1 / e1_grains - chi / Es, 1 / young(Kc, Gc), rtol=1e-10)
    np.testing.assert_allclose(1 / e1_plain - chi / Es, 1 / young(K, G), rtol=1e-10)
    E0, P0, _ = plain.predict(plain.fit(table), rows)
    E1, P1, _ = grains.predict(grains.fit(table), rows)
    gain = np.log(E1 / E0)
    assert np.all(gain > 0) and gain[T > 50].mean() > 3 * gain[T < 0].mean()
    assert np.all(P1[T > 50] < P0[T > 50])
    harder = physical.PhysicalDem(
        "dem_physical", responses, 4.0, physics=physical.BondPhysics(fine_skeleton_pressure=6e6)
    )
    assert np.all(harder.predict(harder.fit(table), rows)[0] > E1)
    _stone_jacobian_matches_differences(responses, physical.BondPhysics(fine_skeleton_pressure=6e5), cells, len(rows))


def _stone_jacobian_matches_differences(responses, physics, cells, n: int) -> None:
    """The fits' Jacobian in the stone's modulus (``dem_c1`` under ``physics``, at 60 GPa) against central
    differences of the model's ln E*, on ``cells`` of ``n`` rows."""
    step = physical.PhysicalDem("dem_c1", responses, 4.0, physics=physics, free=("E_stone_Pa",))
    x = np.array([60e9])
    J = step._log_modulus_jacobian(cells, n, x)[:, 0]
    h = 1e3
    fd = (step._log_modulus(cells, n, step.constants(x + h)) - step._log_modulus(cells, n, step.constants(x - h))) / (
        2 * h
    )
    np.testing.assert_allclose(J, fd, rtol=1e-4, atol=1e-18)


def test_the_fine_contact_network_lies_between_the_films_and_the_sum_and_keeps_a_viscous_warm_part(responses, table):
    """With fine_neighbours the mortar's K and G are the contact network of the skeleton beside the films (direct)
    and the films alone (mortar.contact_network), then capped: between the mortar without a skeleton and the
    Voigt sum, at every cell; the forecast with it is stiffer than without a skeleton everywhere, and warm its
    phase is above the summed skeleton's (half the films' phase is kept, not an elastic floor); more
    neighbours (more films per direct contact) soften it; the fits' Jacobian matches finite differences."""
    from asphalt_nscd.forecast.mortar import Constituents, contact_network, granular_skeleton

    rows = table[table["mix_id"] == "211"].reset_index(drop=True)
    T = rows["temperature_C"].to_numpy()
    options = {"air_phase": "pockets", "confinement": True, "compaction_pressure": 6e5}
    plain = physical.PhysicalDem("dem_physical", responses, 4.0, physics=physical.BondPhysics(**options))
    summed, network, wider = (
        physical.PhysicalDem("dem_physical", responses, 4.0, physics=physical.BondPhysics(**options, **extra))
        for extra in (
            {"fine_skeleton_pressure": 6e5},
            {"fine_skeleton_pressure": 6e5, "fine_neighbours": 9},
            {"fine_skeleton_pressure": 6e5, "fine_neighbours": 18},
        )
    )
    c = plain.constants(())
    cells = plain._cells(rows)
    mortar = cells[0][1]
    skeleton = granular_skeleton(c["E_stone_Pa"], Constituents().nu_stone, mortar.phi_fine, 6e5)
    (K, G), _ = mortar.bulk_shear(c["fine_packing"], c["E_stone_Pa"])
    (Ks, Gs), _ = mortar.bulk_shear(c["fine_packing"], c["E_stone_Pa"], skeleton)
    (Kn, Gn), _ = mortar.bulk_shear(c["fine_packing"], c["E_stone_Pa"], skeleton, 9.0)
    w = physical._stone_weights(float(np.log(c["E_stone_Pa"])))
    cK, cG = np.exp(np.tensordot(w, mortar._cap_nodes, axes=1))
    for got, films, direct, cap, summed_modulus in ((Kn, K, skeleton[0], cK, Ks), (Gn, G, skeleton[1], cG, Gs)):
        free = contact_network(films + direct, films, 9.0)
        np.testing.assert_allclose(got, np.where(np.abs(free) > cap, free * cap / np.abs(free), free), rtol=1e-10)
        assert np.all(np.abs(films) < np.abs(got)) and np.all(np.abs(got) <= np.abs(summed_modulus) * (1 + 1e-12))
    E0, P0, _ = plain.predict(plain.fit(table), rows)
    Es_, Ps, _ = summed.predict(summed.fit(table), rows)
    state = network.fit(table)
    assert state["fine_neighbours"] == 9.0
    En, Pn, _ = network.predict(state, rows)
    assert np.all(En > E0) and np.all(En <= Es_ * (1 + 1e-9))
    assert np.all(Pn[T > 50] > Ps[T > 50] + 1.0)
    assert np.all(wider.predict(wider.fit(table), rows)[0] < En)
    physics = physical.BondPhysics(fine_skeleton_pressure=6e5, fine_neighbours=9)
    _stone_jacobian_matches_differences(responses, physics, cells, len(rows))


def test_confined_bridges_are_the_bonds_mean_and_stiffen_the_warm_forecast(responses, table):
    """The sample's bond shape factors are r_min / (2 h) of each bond (h its bond_geometry length); the
    condensed nodes keep their g_b-weighted mean; the confined bridge is the g_b-weighted mean of each
    bond's confined modulus (computed here bond by bond); it stiffens every condition; with dense
    bridges (the air in pockets) the warm, nearly incompressible mortar stiffens most; more air voids
    still soften the forecast; a response without shape factors is refused."""
    import dataclasses

    from asphalt_nscd.forecast.mortar import confined_modulus, young
    from asphalt_nscd.io import InputError

    r = responses["211"][0]
    s = _sample(MIXES.index("211"))
    g, _ = dem.bond_geometry(s)
    np.testing.assert_allclose(r.bridge_shape, s.bonds["r_min"] / (2 * np.pi * s.bonds["r_min"] ** 2 / g))
    nodes, w = physical.shape_nodes(r)
    assert w.sum() == pytest.approx(1.0) and np.sum(w * nodes) == pytest.approx(np.average(r.bridge_shape, weights=g))
    K, G = np.array([3e9 + 0j, 3e9]), np.array([1e9 + 1e8j, 2e4 + 5e4j])
    direct = (g[:, None] * confined_modulus(K[None], G[None], r.bridge_shape[:, None])).sum(0) / g.sum()
    np.testing.assert_allclose(physical.confined_bridge(K, G, physical.shape_nodes(r)), direct, rtol=1e-3)
    rows = table[table["mix_id"] == "211"]
    T = rows["temperature_C"].to_numpy()
    for air in ("mastic", "pockets"):
        free = physical.PhysicalDem("dem_physical", responses, 4.0, physics=physical.BondPhysics(air_phase=air))
        confined = physical.PhysicalDem(
            "dem_physical", responses, 4.0, physics=physical.BondPhysics(air_phase=air, confinement=True)
        )
        gain = np.log(confined.predict(confined.fit(table), rows)[0] / free.predict(free.fit(table), rows)[0])
        assert np.all(gain > 0)
    # the dense mortar's bridges: 1 + 2 S^2 warm (nu -> 1/2) against a modest gain cold
    mm = confined._cells(rows)[0][1]
    (K, G), _ = mm.bulk_shear(0.8, 55e9)
    ratio = np.abs(physical.confined_bridge(K, G, physical.shape_nodes(r)) / young(K, G))
    assert ratio[T > 50].mean() > 2 * ratio[T < 0].mean()
    state = confined.fit(table)
    E = [confined.predict(state, rows.assign(Va_pct=va))[0] for va in (3.0, 5.0, 8.0)]
    assert np.all(E[0] > E[1]) and np.all(E[1] > E[2])
    old = {"211": [dataclasses.replace(r, bridge_shape=np.zeros(0), bridge_weight=np.zeros(0))]}
    with pytest.raises(InputError, match="rerun forecast-response"):
        physical.PhysicalDem("dem_physical", old, 4.0, physics=physical.BondPhysics(confinement=True)).predict(
            state, rows
        )


def test_the_page_states_the_physics_the_ladder_ran_with(responses, table):
    """Every fit records its bond laws' options, and the page's ladder section says which ran."""
    from asphalt_nscd.forecast.page_dem import physics_line

    model = physical.PhysicalDem(
        "dem_physical", responses, 4.0, physics=physical.BondPhysics(air_phase="pockets", confinement=True)
    )
    state = model.fit(table)
    assert (state["air_phase"], state["contact_strain"], state["confinement"]) == ("pockets", None, True)
    line = " ".join(physics_line({"fits": [{"model": "dem_physical", "binder_route": "curve", "state": state}]}))
    assert "air voids in the pockets" in line and "confined" in line and "films only" in line
    hertz = physical.PhysicalDem("dem_physical", responses, 4.0, physics=physical.BondPhysics(contact_strain=1e-4)).fit(
        table
    )
    line = " ".join(physics_line({"fits": [{"model": "dem_physical", "binder_route": "curve", "state": hertz}]}))
    assert "air voids in the mastic" in line and "Hertz contacts at strain 0.0001" in line and "bridges free" in line
    pressed = physical.PhysicalDem(
        "dem_physical", responses, 4.0, physics=physical.BondPhysics(compaction_pressure=6e5)
    ).fit(table)
    line = " ".join(physics_line({"fits": [{"model": "dem_physical", "binder_route": "curve", "state": pressed}]}))
    assert "stone contacts whose patches pressed by the compaction at 600 kPa" in line and "films only" not in line
    assert "fine aggregate without a skeleton of its own" in line
    grains = physical.PhysicalDem(
        "dem_physical", responses, 4.0, physics=physical.BondPhysics(fine_skeleton_pressure=6e4)
    ).fit(table)
    line = " ".join(physics_line({"fits": [{"model": "dem_physical", "binder_route": "curve", "state": grains}]}))
    assert (
        "fine aggregate a skeleton of its own pressed at 60 kPa (`fine_skeleton_pressure_Pa`) beside the mortar."
        in line
    )
    network = physical.PhysicalDem(
        "dem_physical", responses, 4.0, physics=physical.BondPhysics(fine_skeleton_pressure=6e5, fine_neighbours=12)
    ).fit(table)
    line = " ".join(physics_line({"fits": [{"model": "dem_physical", "binder_route": "curve", "state": network}]}))
    assert "pressed at 600 kPa (`fine_skeleton_pressure_Pa`), the direct contacts of a network of 12 neighbours" in line
    assert physics_line({"fits": [{"model": "dem_physical", "binder_route": "curve", "state": {}}]}) == []


def test_binder_in_place_of_air_is_each_models_exact_derivative(responses, table):
    """reference/forecast/volumetric_sensitivity.py: moving volume from air to binder at a fixed VMA gives,
    for Witczak 1-37A (log-linear in Va and Vbeff / VMA), its analytic derivative 100 ln(10) (-a_Va +
    a_Vr / VMA) per 1 %; for dem_physical the central difference of the model itself (each mix's ln|E*|
    at +-0.5 %, nothing refitted, the sample unchanged); every mix and temperature present."""
    import reference_scripts

    from asphalt_nscd.forecast.baselines import PUBLISHED

    module = reference_scripts.load("reference/forecast/volumetric_sensitivity.py")
    rows = table.dropna(subset=["E_norm_MPa", "phase_deg"]).reset_index(drop=True)
    variant = (("dem_physical", ("mastic", None, False, None)),)
    got = module.sensitivity(rows, responses, 4.0, dem_variants=variant)
    assert set(got["model"]) == {"dem_physical", *module.FORMULAS}
    assert len(got) == len(got["model"].unique()) * (1 + rows["temperature_C"].nunique())
    c = PUBLISHED["witczak_1_37a"]
    per_mix = rows.groupby("mix_id").first()
    exact = 100.0 * np.log(10.0) * (-c["a_Va"] + c["a_Vr"] / (per_mix["Va_pct"] + per_mix["Vbeff_pct"]))
    w = got[(got["model"] == "witczak_1_37a") & got["temperature_C"].isna()]
    np.testing.assert_allclose(w["dlnE_pct_per_pct"].item(), exact.mean(), rtol=1e-8)
    model = physical.PhysicalDem("dem_physical", responses, 4.0, physics=physical.BondPhysics())
    state = model.fit(rows)
    ln = [
        np.log(model.predict(state, rows.assign(Vbeff_pct=rows["Vbeff_pct"] + d, Va_pct=rows["Va_pct"] - d))[0])
        for d in (0.5, -0.5)
    ]
    one = rows.assign(s=100.0 * (ln[0] - ln[1])).groupby("mix_id")["s"].mean().mean()
    d = got[(got["model"] == "dem_physical") & got["temperature_C"].isna()]
    np.testing.assert_allclose(d["dlnE_pct_per_pct"].item(), one, rtol=1e-10)
    assert np.isfinite(got["dlnE_pct_per_pct"]).all()

    # with the air in the binder the aggregate's packing does not move: binder in place of air stiffens every cell
    binder = physical.PhysicalDem("dem_physical", responses, 4.0, physics=physical.BondPhysics("binder"))
    state = binder.fit(rows)
    E = [
        binder.predict(state, rows.assign(Vbeff_pct=rows["Vbeff_pct"] + d, Va_pct=rows["Va_pct"] - d))[0]
        for d in (0.5, -0.5)
    ]
    assert np.all(E[0] > E[1])


def test_the_physics_probe_chooses_each_mix_variant_on_the_other_mixes_only(responses, table, monkeypatch):
    """reference/forecast/physics_probe.py on three variants: each variant's rows are dem_physical's own forecasts
    under its options; the choice inside the fold forecasts each mix by the variant whose mean abs |E*| error over
    the other mixes is least (recomputed here from the variants' per-mix errors), never by its own score; its
    per-mix table and its row agree; the contact network's neighbours are a column of the table."""
    import reference_scripts

    module = reference_scripts.load("reference/forecast/physics_probe.py")
    rows = table.dropna(subset=["E_norm_MPa", "phase_deg"]).reset_index(drop=True)
    monkeypatch.setattr(module, "run_forecast_inputs", lambda run: (rows, responses))
    variants = (
        ("mastic", None, False, None, None, None),
        ("pockets", None, True, 6e5, None, None),
        ("pockets", None, True, 6e5, 6e5, 12.0),
    )
    monkeypatch.setattr(module, "VARIANTS", variants)
    got, per_mix = module.probe(Path("unused"))
    overall = got[got["temperature_C"].isna()]
    assert len(overall) == len(variants) + 1 and overall["fine_contact_neighbours"].iloc[-2] == 12.0
    errors = []
    for v in variants:
        model = physical.PhysicalDem("dem_physical", responses, 4.0, physics=physical.BondPhysics(*v))
        E, _, _ = model.predict(model.fit(rows), rows)
        e = rows.assign(e=np.abs(100 * np.log(E / rows["E_norm_MPa"]))).groupby("mix_id")["e"].mean()
        errors.append(e)
    score = pd.concat(errors, axis=1, keys=range(len(variants)))
    for i, v in enumerate(variants):
        assert overall["abs_logE_pct"].iloc[i] == pytest.approx(score[i].mean(), rel=1e-12)
    expected = {m: int(np.argmin([score.drop(index=m)[i].mean() for i in range(len(variants))])) for m in score.index}
    got_mix = per_mix.set_index("mix_id")
    for m, i in expected.items():
        assert got_mix.loc[m, "abs_logE_pct"] == pytest.approx(score.loc[m, i], rel=1e-12)
    assert overall["abs_logE_pct"].iloc[-1] == pytest.approx(got_mix["abs_logE_pct"].mean(), rel=1e-12)
    assert overall["air_phase"].iloc[-1] == "chosen in the fold" and set(got_mix.index) == set(score.index)
    # a mix whose own score would flip the choice: the least mean over all mixes is variant 1, over the others
    # of mix "c" variant 0
    planted = pd.DataFrame({0: [10.0, 10.0, 100.0], 1: [30.0, 30.0, 20.0]}, index=["a", "b", "c"])
    assert module.choice_in_fold(planted) == {"a": 1, "b": 1, "c": 0}
