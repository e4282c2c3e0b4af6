"""Hidden-effect tests: effects planted in synthetic tables must be named and estimated.

Seeds are drawn afresh on every run: each case is checked on 5 seed bases from the operating
system's entropy (printed on failure; ``ASPHALT_NSCD_SEED_BASES=b1,b2,...`` reruns given
ones), so that no lucky seed passes it. The planted sizes lie inside the generator's own
ranges (:func:`asphalt_nscd.diagnosis.synthetic.random_effect`), in their upper part where
the benchmark's detection rate is 1 (docs/choices.md, Diagnosis); the uncorrected mass is the
missing one (positive, the generator's commoner sign), and a temperature offset sits on an
inner isotherm other than the screening's reference, whose offset the master curve's
reference time absorbs (both limits measured by the benchmark, not hidden here). A second
check plants each artifact at the smallest size the committed benchmark
(reference/detection_bench) detects with 95 % power, on fresh seeds in that benchmark's
designs (the shipped table's, the paper's): realistic sizes, not the top of a range. The checks
are calibrated to the benchmark's stated rates (false alarms at most 5 % per table,
detection at least 95 %): per case at most 2 of 5 seeds may miss, or name an effect that was
not planted, and over all cases the counts stay within the binomial 99.9 % bounds of those
rates, so a detector exactly at those rates fails a run with probability 0.03 (less for a better
one) and a broken one fails.
Cases on the detector's own truth family (2S2P1D + WLF) and on the mildly misspecified
``mixed`` family must name no unplanted effect (temperature offset on the right isotherm), every estimate within
25 % of the truth on the detector's own family and within 50 % elsewhere, or within 3 of its
own standard errors (70 estimates per run: a fixed relative tolerance alone fails an honest
estimator now and then, as a 2.6-s.e. self-heating estimate did on a fresh seed) (misspecification
biases the estimates: the free vertical factor of the hottest isotherm takes up to a third of
an uncorrected mass on ``mixed``); cases on the truth families outside 2S2P1D (Huet-Sayegh,
generalized Maxwell, MEPDG sigmoid, with temperature-dependent specimen factors and cell
misfit) must name the planted effect and estimate it within 50 % (their family-wise
false-alarm and estimate rates are measured by the benchmark). Two limits found on fresh seeds
(docs/choices.md, Diagnosis): an uncorrected mass together with self-heating on the
2PB schedule (self-heating lowers an isotherm's late, low-frequency tests, the mass its early,
high-frequency ones: the isotherm's free shift takes up the change of slope) went unnamed on 2 of 5
seeds, and an offset at 4 degC on the quadratic-shift ``mixed`` family was once attributed to
the 21 degC isotherm.
"""

import functools
import os

import numpy as np
import pandas as pd
import pytest
from scipy.stats import binom

from asphalt_nscd.diagnosis import synthetic
from asphalt_nscd.diagnosis.bench import ESTIMATE_KEYS, estimate_ok, run_case
from asphalt_nscd.diagnosis import effects as fx
from asphalt_nscd.diagnosis.effects import ArtifactSearch, effect_entries, make_term
from asphalt_nscd.lab.geometry import from_dict


def _seed_bases() -> list:
    given = os.environ.get("ASPHALT_NSCD_SEED_BASES")
    if given:
        return [int(v) for v in given.split(",")]
    return [int(np.random.SeedSequence().entropy % (2**31)) for _ in range(5)]


SEED_BASES = _seed_bases()
#: planted sizes in the upper part of the generator's ranges
SIZES = {
    "time_lag": {"time_lag_ms": 1.0},
    "inertia_uncorrected": {"mass_factor_g": 350.0},
    "strain_nonlinearity": {"modulus_drop_per_100_microstrain": 0.05},
    "self_heating": {"modulus_drop_pct_per_test": 1.5, "phase_rise_pct_per_test": 1.5},
    "temperature_drift": {"drift_C_per_test": 1.2},
}
#: an estimate passes within its relative tolerance or within N_SE of its own standard errors
#: (a 1-in-370 chance of a miss for an unbiased estimate with a correct s.e.), its s.e. at
#: most half the planted size
N_SE = 3.0
#: (effects, family, exact): exact = the named set must equal the planted one
CASES = [
    ((), "wlf", True),
    ((), "mixed", True),
    (("time_lag",), "wlf", True),
    (("time_lag",), "gmaxwell", False),
    (("inertia_uncorrected",), "mixed", True),
    (("temperature_offset",), "wlf", True),
    (("temperature_offset",), "glassy_drift", True),
    (("strain_nonlinearity",), "mixed", True),
    (("time_lag",), "sigmoidal", False),
    (("self_heating",), "wlf", True),
    (("temperature_drift",), "wlf", True),
    (("temperature_drift",), "huet_sayegh", False),
    (("time_lag", "temperature_offset"), "wlf", True),
    (("time_lag", "strain_nonlinearity"), "wlf", True),
]


def _diagnose(seed, effects, family):
    rng = np.random.default_rng([seed, 7])
    schedule = ("paper_2pb", "aashto_t342")[int(rng.integers(2))]
    if "inertia_uncorrected" in effects:
        schedule = "paper_2pb"  # inertia matters in a 2PB test
    mags = {e: dict(SIZES[e]) for e in effects if e in SIZES}
    if "temperature_offset" in effects:
        # an inner isotherm other than the screening's reference (the tested one nearest the
        # median), whose offset the reference time of the master curve absorbs
        temps = synthetic.SCHEDULES[schedule][0]
        ref = temps[int(np.argmin(np.abs(np.asarray(temps) - np.median(temps))))]
        inner = [T for T in temps[1:-1] if T != ref]
        mags["temperature_offset"] = {
            "temperature_C": float(rng.choice(inner)),
            "offset_C": float(rng.choice([-5.0, 5.0])),
        }
    table, truth = synthetic.generate(seed, effects, schedule=schedule, magnitudes=mags, family=family)
    search = ArtifactSearch(table, test=from_dict(truth["test"], "synthetic"))
    entries = {e["name"]: e for e in effect_entries(search, search.run())}
    return entries, truth


#: the benchmark's stated rates (docs/choices.md, Diagnosis): family-wise false alarms at most
#: 5 % per table, detection with a correct estimate at least 95 % per planted table
FALSE_ALARM_RATE, POWER = 0.05, 0.95
#: largest chance that a detector exactly at those rates fails a check: per case (5 tables:
#: at most 2 misses or 2 false alarms, exceeded with probability 0.0012) and over all cases
CASE_LEVEL, ALL_LEVEL = 1e-2, 1e-3


@functools.lru_cache(maxsize=None)
def _outcomes(index: int) -> tuple:
    """One outcome per seed base of case ``index``: (seed, named effects, planted ok, extra)."""
    effects, family, exact = CASES[index]
    out = []
    for base in SEED_BASES:
        seed = base + 1000 * index
        entries, truth = _diagnose(seed, effects, family)
        detected = {n for n, e in entries.items() if e["detected"]}
        ok = set(effects) <= detected
        for name in effects:
            e = entries[name]
            # a planted effect the diagnosis gave no estimate (declared not identifiable from the table, or not
            # testable) is a miss of that seed, counted against the case's allowance and the rates below
            se = e["estimate"].get(ESTIMATE_KEYS[name] + "_se", np.nan)
            true = truth["effects"][name][ESTIMATE_KEYS[name]]
            # outside its own model the detector's estimates are biased by the misfit: 50 %
            ok = (
                ok
                and e["testable"]
                and 0 < se <= 0.5 * abs(true)
                and estimate_ok(name, e, truth, 0.25 if family == "wlf" else 0.5, n_se=N_SE)
            )
        extra = sorted(detected - set(effects)) if exact else []
        out.append(
            (
                seed,
                sorted(detected),
                ok,
                extra,
                {n: entries[n]["estimate"].get(ESTIMATE_KEYS[n], entries[n]["evidence"]) for n in effects},
            )
        )
    return tuple(out)


def _rerun_hint() -> str:
    return f"rerun: ASPHALT_NSCD_SEED_BASES={','.join(map(str, SEED_BASES))}"


def _allowed_failures(n: int, rate: float, level: float) -> int:
    """Largest count of failures in n tables that a detector failing at ``rate`` exceeds with
    probability at most ``level`` (binomial upper quantile)."""
    return int(binom.isf(level, n, rate))


@pytest.mark.parametrize("index,case", list(enumerate(CASES)))
def test_planted_effects_are_named_and_estimated_on_fresh_seeds(index, case):
    """Per case, 5 fresh seeds: the planted effects named with a correct estimate, and no
    effect named on a clean table beyond the benchmark's false-alarm rate. A detector with a
    95 % power misses now and then: a case fails when it misses (or names an unplanted
    effect) on more than 2 of its 5 seeds, which such a detector does with probability 0.0012."""
    effects, family, exact = case
    outcomes = _outcomes(index)
    n = len(outcomes)
    if effects:
        missed = [o for o in outcomes if not o[2]]
        assert len(missed) <= _allowed_failures(n, 1 - POWER, CASE_LEVEL), (
            f"{family} {effects}: planted effects missed or misestimated on {len(missed)} of {n} seeds "
            f"(seed, named, ok, extra, estimates): {missed}; {_rerun_hint()}"
        )
    alarms = [o for o in outcomes if o[3]]
    assert len(alarms) <= _allowed_failures(n, FALSE_ALARM_RATE, CASE_LEVEL), (
        f"{family} {effects}: effects named that were not planted on {len(alarms)} of {n} seeds: {alarms}; "
        f"{_rerun_hint()}"
    )


def test_fresh_seed_rates_over_all_cases():
    """All cases together (60 planted tables, 55 in the exact cases): planted effects named and estimated at least as often,
    and unplanted effects named at most as often, as the benchmark's rates allow (binomial,
    each check failing a detector exactly at those rates with probability 1e-3)."""
    rows = [(i, o) for i in range(len(CASES)) for o in _outcomes(i)]
    planted = [(i, o) for i, o in rows if CASES[i][0]]
    missed = [(CASES[i][:2], o) for i, o in planted if not o[2]]
    exact = [(i, o) for i, o in rows if CASES[i][2]]
    alarms = [(CASES[i][:2], o) for i, o in exact if o[3]]
    print(
        f"fresh seeds {SEED_BASES}: {len(planted) - len(missed)} of {len(planted)} planted tables named and "
        f"estimated; unplanted effects named on {len(alarms)} of {len(exact)} tables"
    )
    assert len(missed) <= _allowed_failures(len(planted), 1 - POWER, ALL_LEVEL), (missed, _rerun_hint())
    assert len(alarms) <= _allowed_failures(len(exact), FALSE_ALARM_RATE, ALL_LEVEL), (alarms, _rerun_hint())


def test_generator_is_seeded_and_physical():
    a, ta = synthetic.generate(3, ["time_lag"], schedule="paper_2pb", n_specimens=2)
    b, tb = synthetic.generate(3, ["time_lag"], schedule="paper_2pb", n_specimens=2)
    assert a.equals(b) and ta == tb
    assert set(a.columns) >= {
        "specimen",
        "temperature_C",
        "frequency_Hz",
        "E_norm_MPa",
        "phase_deg",
        "strain_microstrain",
        "test_order",
    }
    assert len(a) == 2 * 6 * 5
    assert a["phase_deg"].between(0, 90).all() and (a["E_norm_MPa"] > 0).all()
    with pytest.raises(ValueError, match="unknown effect"):
        synthetic.generate(0, ["bogus"])


def test_time_lag_adds_360_f_dt_and_keeps_modulus():
    mags = {"time_lag": {"time_lag_ms": 1.0}}
    clean, _ = synthetic.generate(5, [], schedule="paper_2pb", n_specimens=1)
    lag, truth = synthetic.generate(5, ["time_lag"], schedule="paper_2pb", n_specimens=1, magnitudes=mags)
    # same random stream apart from the effect draw: compare through the truth model instead
    f = lag["frequency_Hz"].to_numpy()
    E = synthetic.truth_modulus(truth["parameters"], f, lag["temperature_C"].to_numpy())
    excess = lag["phase_deg"].to_numpy() - np.degrees(np.angle(E))
    slope = np.polyfit(f, excess, 1)[0]
    assert slope == pytest.approx(0.36, abs=0.03)  # deg/Hz = 360 * 1 ms
    assert clean.shape == lag.shape


def test_inertia_term_matches_eq1():
    from asphalt_nscd.lab.en12697 import Specimen2PB

    spec = Specimen2PB()
    E = np.array([1000.0 + 100j])
    d = {"f": np.array([40.0])}
    # on the paper's 2PB specimen the parameter is the mass itself (paper Eq. 1)
    term = make_term("inertia_uncorrected", gamma_per_mm=spec.gamma_per_mm)
    out = term.apply(np.array([spec.mu_g]), E, d)
    assert out.imag[0] == pytest.approx(100.0)
    assert 1000.0 - out.real[0] == pytest.approx(spec.gamma_per_mm * 1e-6 * spec.mu_g * (2 * np.pi * 40) ** 2)


def test_inertia_uses_the_declared_form_factor():
    """Uniaxial cylinder: E1 deficit gamma m w^2 with gamma = h/A; the estimate is in grams of
    that test's moving mass, not of a 2PB head."""
    cyl = from_dict({"test": "uniaxial_cylinder", "diameter_mm": 100.0, "height_mm": 150.0}, "x")
    mags = {"inertia_uncorrected": {"mass_factor_g": 40000.0}}
    table, truth = synthetic.generate(
        31, ["inertia_uncorrected"], schedule="aashto_t342", n_specimens=3, magnitudes=mags
    )
    m = truth["effects"]["inertia_uncorrected"]["mass_factor_g"]
    assert truth["test"]["test"] == "uniaxial_cylinder"
    search = ArtifactSearch(table, test=cyl)
    assert search.gamma == pytest.approx(150.0 / (np.pi * 2500.0))
    e = {x["name"]: x for x in effect_entries(search, search.run())}["inertia_uncorrected"]
    assert e["testable"]
    assert e["estimate"]["mass_factor_g"] == pytest.approx(m, rel=0.3)
    # without a declared test: not testable, and the search goes on
    bare = ArtifactSearch(table)
    e = {x["name"]: x for x in effect_entries(bare, bare.run())}["inertia_uncorrected"]
    assert not e["testable"] and "unknown" in e["evidence"]


def test_testability_without_optional_columns():
    table, _ = synthetic.generate(1, [], schedule="aashto_t342", n_specimens=2)
    from asphalt_nscd.diagnosis.effects import prepare_table

    t = fx.testability(prepare_table(table.drop(columns=["strain_microstrain", "test_order"])))
    assert t["strain_nonlinearity"][0] is False and "strain_microstrain" in t["strain_nonlinearity"][1]
    assert t["self_heating"][0] is False and "test_order" in t["self_heating"][1]
    assert t["temperature_drift"][0] is False and "test order" in t["temperature_drift"][1]
    assert t["time_lag"][0] and t["temperature_offset"][0]


def test_bench_case_outcome():
    case = {
        "family": "wlf",
        "kind": "time_lag",
        "index": 0,
        "seed": 7003,
        "schedule": "aashto_t342",
        "effects": ["time_lag"],
        "magnitudes": {"time_lag": {"time_lag_ms": 0.5}},
    }
    r = run_case(case)
    assert r["planted"] == ["time_lag"] and "time_lag" in r["detected"] and r["estimate_ok"]["time_lag"]


def test_replicate_noise_regresses_out_the_strain_effect():
    from asphalt_nscd.rheology.master_curve import replicate_noise

    mags = {"strain_nonlinearity": {"modulus_drop_per_100_microstrain": 0.06}}
    table, truth = synthetic.generate(21, ["strain_nonlinearity"], schedule="paper_2pb", n_specimens=4, magnitudes=mags)
    true_sigma = truth["noise"]["point_lnE_sigma"]
    plain, _ = replicate_noise(table)
    adjusted, sP = replicate_noise(table, covariates=("strain_microstrain",))
    # the strain effect (sd 0.06 x 0.35 = 2 %) inflates the plain estimate, not the adjusted one
    assert plain > np.hypot(true_sigma, 0.5 * 0.06 * 0.35)
    assert adjusted == pytest.approx(true_sigma, rel=0.25)
    # without covariates the two-way least squares equals the plain estimate (balanced table)
    clean, _ = synthetic.generate(22, [], schedule="paper_2pb", n_specimens=3)
    a, _ = replicate_noise(clean)
    b, _ = replicate_noise(clean.assign(zero=0.0), covariates=("zero",))
    assert b == pytest.approx(a, rel=1e-9)


def test_strain_term_is_centred_and_correction_goes_to_small_strain():
    # an AASHTO T 342 table with 2 replicates: the uncentred term, screened with E00 held
    # fixed, took the mean |E*| drop for a master-curve change and was missed
    table, truth = synthetic.generate(54, ["strain_nonlinearity"], schedule="aashto_t342", n_specimens=2)
    search = ArtifactSearch(table)
    assert search.strain_ref == pytest.approx(table["strain_microstrain"].mean())
    result = search.run()
    entries = {e["name"]: e for e in effect_entries(search, result)}
    e = entries["strain_nonlinearity"]
    assert e["detected"] and estimate_ok("strain_nonlinearity", e, truth, 0.25)
    b = result["final"].param("modulus_drop_per_100_microstrain")
    corrected = search.corrected(result["final"])
    ratio = np.log(corrected["E_norm_MPa"].to_numpy() / search.df["E_norm_MPa"].to_numpy())
    # every point is brought to eps -> 0: ln ratio = b eps / 100
    assert np.allclose(ratio, b * search.df["strain_microstrain"].to_numpy() / 100.0, atol=1e-9)


def test_temperature_offset_is_found_on_its_inner_isotherm_and_corrected():
    mags = {"temperature_offset": {"temperature_C": 10.0, "offset_C": -3.0}}
    table, truth = synthetic.generate(41, ["temperature_offset"], schedule="paper_2pb", n_specimens=3, magnitudes=mags)
    search = ArtifactSearch(table)
    result = search.run()
    off = result["offset"]
    assert off["detected"] and off["temperature_C"] == 10.0
    assert off["offset_C"] == pytest.approx(-3.0, abs=0.75)
    # only the inner isotherms are tested (an end offset is a shift-law curvature)
    assert [r["temperature_C"] for r in off["per_isotherm"]] == [0.0, 10.0, 15.0, 20.0]
    # the corrected isotherm sits on the smooth law: a second search finds no offset there
    again = ArtifactSearch(search.corrected_table(result)).run()["offset"]
    assert not again["detected"]
    assert abs(next(r for r in again["per_isotherm"] if r["temperature_C"] == 10.0)["offset_C"]) < 0.5
    # a planted offset passes the consistency check: the corrected table fits the master curve better
    corrected, _ = search.consistent_correction(result)
    assert (
        off["correction_applied"]
        and off["master_curve_rss"]["offset_corrected"] < off["master_curve_rss"]["not_corrected"]
    )
    assert np.allclose(corrected["E_norm_MPa"], search.corrected_table(result)["E_norm_MPa"])
    entry = next(e for e in fx.effect_entries(search, result) if e["name"] == "temperature_offset")
    assert entry["detected"] and "corrected in the table" in entry["evidence"]


def test_format_of_small_p_values():
    assert fx.format_p(3e-67) == "< 1e-6" and fx.p_phrase(3e-67) == "p < 1e-6"
    assert fx.p_phrase(0.0123) == "p = 0.012" and fx.format_p(None) == "n/a"


DRIFT = {"temperature_drift": {"drift_C_per_test": 1.2}}


@pytest.mark.parametrize("schedule", ["aashto_t342", "paper_2pb"])
def test_a_drift_along_a_frequency_sweep_is_not_identifiable_and_never_named(schedule):
    """A drift planted along the standard order (every isotherm swept monotonically in frequency)
    reads exactly as a change of slope per isotherm, a failure of time-temperature superposition:
    its signature and its rival's have a canonical correlation >= 0.95, so it is reported not
    identifiable and never named; the same drift along a random order, or with the first
    frequency repeated at the end of each isotherm, is identifiable and named; without an order,
    not testable."""
    for order, expected in (("standard", False), ("random", True), ("repeat", True)):
        table, truth = synthetic.generate(
            17, ["temperature_drift"], schedule=schedule, n_specimens=3, magnitudes=DRIFT, order=order
        )
        search = ArtifactSearch(table, test=from_dict(truth["test"], "x"))
        result = search.run()
        e = {x["name"]: x for x in effect_entries(search, result)}["temperature_drift"]
        assert e["testable"] and e["identifiable"] is expected, (order, e["identifiability"])
        rho = e["identifiability"]["rival_correlation"]
        assert (rho >= fx.IDENTIFIABILITY_LIMITS["rival"]) is (not expected)
        assert e["detected"] is expected
        if not expected:
            assert "time-temperature superposition" in e["evidence"] and "temperature_drift" not in [
                c.name for c in result["selected"]
            ]
    no_order, truth = synthetic.generate(
        17, ["temperature_drift"], schedule=schedule, n_specimens=3, magnitudes=DRIFT, test_order=False
    )
    search = ArtifactSearch(no_order, test=from_dict(truth["test"], "x"))
    e = {x["name"]: x for x in effect_entries(search, search.run())}["temperature_drift"]
    assert not e["testable"] and not e["detected"]


def test_the_shipped_table_names_no_artifact_it_cannot_identify():
    """The shipped UIUC table gives no test order: drift and self-heating are not testable; the
    time lag and the offset are tested, each identifiable (cosines and correlations reported)."""
    from pathlib import Path

    from asphalt_nscd.lab.measured import load_measured

    table = load_measured(Path(__file__).resolve().parents[2] / "data/measured/uiuc_fdmix1_utm/complex_modulus.csv")
    search = ArtifactSearch(table, test=table.attrs["test"])
    result = search.run()
    e = {x["name"]: x for x in effect_entries(search, result)}
    assert not e["temperature_drift"]["testable"] and not e["temperature_drift"]["detected"]
    assert e["time_lag"]["identifiable"] and 0 < e["time_lag"]["identifiability"]["null_correlation"] < 0.995
    assert e["temperature_offset"]["identifiable"] and result["family_size"] == 2
    assert set(e["temperature_offset"]["identifiability"]["per_isotherm"]) == {"4", "21", "37"}


def test_offset_with_four_isotherms_cannot_be_told_from_a_bend_of_the_shift_law():
    table, truth = synthetic.generate(5, [], schedule="paper_2pb", n_specimens=3)
    four = table[table["temperature_C"].isin([0.0, 10.0, 20.0, 30.0])]
    search = ArtifactSearch(four, test=from_dict(truth["test"], "x"))
    result = search.run()
    e = {x["name"]: x for x in effect_entries(search, result)}["temperature_offset"]
    assert e["testable"] and e["identifiable"] is False and "bends" in e["evidence"]
    assert result["offset"] is None


def test_calibration_levels_are_seeded_and_control_the_rate_on_the_tables_own_null():
    """The calibration reruns the whole procedure on tables of the table's fitted clean model:
    the same seed gives the same numbers; its level is the k-th smallest statistic, k =
    floor(rate (B + 1)) (none with fewer than 1 / rate - 1 tables), which names exactly the
    statistics whose calibrated p-value (1 + #{m_b <= p}) / (B + 1) is at most the rate;
    calibrated p-values count the tables at least as extreme."""
    from asphalt_nscd.diagnosis import calibration as cal

    table, truth = synthetic.generate(9, [], schedule="aashto_t342", n_specimens=3, family="sigmoidal")
    test = from_dict(truth["test"], "x")
    # a family-wise rate of 0.2 (0.1 per group): 24 tables give a level, the k = 2nd smallest
    a = cal.calibrate(table, test=test, n_tables=24, seed=4, rate=0.2)
    # the same seed again, curtailed at a statistic every table reaches (k = 2 of each null run): the
    # same first tables of each null and the same static null (every table of a full calibration is
    # compared between two runs of the whole workflow, tests/workflow/test_readme.py)
    b = cal.calibrate(table, test=test, n_tables=24, seed=4, rate=0.2, decide=1.0)
    assert b["artifacts"]["calibrated_level_bound"] and b["static"] == a["static"]
    assert b["clean_model"] == a["clean_model"]
    for name, null in a["artifacts"]["nulls"].items():
        assert b["artifacts"]["nulls"][name]["n_run"] == 2
        assert b["artifacts"]["nulls"][name]["null_min_p"] == null["null_min_p"][:2]
    m = np.sort(a["artifacts"]["null_min_p"])
    c = a["artifacts"]["calibrated_level"]
    assert c == m[1] and np.sum(m < c) == 1
    assert a["artifacts"]["level"] == min(c, a["artifacts"]["nominal_level"])
    assert a["artifacts"]["exact_rate"] == pytest.approx(2 / 25)
    assert a["artifacts"]["rate"]["half_tables"] == 12 and a["artifacts"]["rate"]["rate"] is not None
    # at the default rate 0.05, 24 tables could name nothing (floor(0.025 x 25) = 0): refused
    assert cal.min_tables() == 39
    # the fewest tables with level_rank >= 1, at each rate just above and at the boundary
    for rate in (0.025, 0.1, 0.01, 0.3):
        b = cal.fewest_tables(rate)
        assert cal.level_rank(rate, b) >= 1 and cal.level_rank(rate, b - 1) == 0
    with pytest.raises(ValueError, match="n_tables must be >= 39"):
        cal.calibrate(table, test=test, n_tables=38, seed=4)
    assert cal.critical_level([0.3, 0.1, 0.2, 0.4], 0.25) == 0.1 and cal.critical_level([0.5], 0.99) == 0.5
    assert cal.critical_level([0.3, 0.1, 0.2], 0.2) == 0.0 and cal.level_rank(0.025, 200) == 5
    assert fx.adjusted_p(0.15, [0.1, 0.2, 0.3]) == pytest.approx(2 / 4) and fx.adjusted_p(None, [0.1]) is None
    assert cal.static_p(10.0, {"static": {"null_F": [1.0, 20.0, 3.0]}}) == pytest.approx(2 / 4)
    cm = a["clean_model"]
    assert cm["sigma_point_lnE"] > 0 and cm["sigma_cell_lnE"] >= 0
    with pytest.raises(ValueError, match="n_tables"):
        cal.calibrate(table, n_tables=5)
    # the search refuses a calibration of other settings
    from asphalt_nscd.diagnosis import artifacts
    from asphalt_nscd.io import InputError

    with pytest.raises(InputError, match="calibrate-search"):
        artifacts.analyse(table, alpha=1e-2, test=test, calibration=a)


@pytest.mark.parametrize("B, rate", [(200, 0.025), (199, 0.025), (39, 0.025), (100, 0.05), (57, 0.1)])
def test_calibrated_level_is_an_exact_monte_carlo_test(B, rate):
    """Exchangeability: of B + 1 tables of a null, each judged against the other B, exactly
    k = floor(rate (B + 1)) are named, a rate k / (B + 1) <= rate (the earlier rule, the
    (floor(rate B) + 1)-th smallest, named one more: 6 of 201 at 0.025); a statistic is named
    exactly when its calibrated p-value (1 + #{m_b <= p}) / (B + 1) is at most the rate."""
    from asphalt_nscd.diagnosis import calibration as cal

    for seed in range(3):
        x = np.random.default_rng(seed).uniform(size=B + 1)
        named = [x[i] < cal.critical_level(np.delete(x, i), rate) for i in range(B + 1)]
        assert sum(named) == int(np.floor(rate * (B + 1) + 1e-9)) and sum(named) <= rate * (B + 1)
        for i in range(0, B + 1, 7):
            null = np.delete(x, i)
            assert named[i] == (fx.adjusted_p(x[i], null) <= rate + 1e-12)


def test_cross_fitted_rate_is_reported_only_where_a_half_can_set_a_level():
    """Each half's level judged on the other half; with halves too few to set a level of their
    own (20 tables per half at 0.025) the rate would be a vacuous 0 and is not reported, and the
    page says why."""
    from asphalt_nscd.diagnosis import calibration as cal
    from asphalt_nscd.diagnosis.render import _calibration_rate_sentence

    rng = np.random.default_rng(5)
    stat = {"2s2p1d": rng.uniform(size=200), "maxwell": rng.uniform(size=200)}
    r = cal.cross_fitted_rate(stat, 0.025, nominal=1.0)
    assert r["half_tables"] == 100 and cal.level_rank(0.025, 100) == 2
    # by hand: each half's level is the smaller of the nulls' 2nd smallest; count the other half below it
    halves = {n: (v[:100], v[100:]) for n, v in stat.items()}
    lev = [min(np.sort(h[i])[1] for h in halves.values()) for i in (0, 1)]
    for n, (a, b) in halves.items():
        k = int(np.sum(b < lev[0]) + np.sum(a < lev[1]))
        assert r["per_null"][n]["k"] == k and r["per_null"][n]["rate"] == k / 200
        lo, hi = r["per_null"][n]["ci95"]
        assert lo <= k / 200 <= hi
    assert r["rate"] == max(v["rate"] for v in r["per_null"].values())
    # a nominal level below every statistic names nothing out of sample
    assert cal.cross_fitted_rate(stat, 0.025, nominal=0.0)["k"] == 0
    small = cal.cross_fitted_rate({n: v[:40] for n, v in stat.items()}, 0.025, nominal=1.0)
    assert small["half_tables"] == 20 and small["rate"] is None and small["k"] is None
    assert small["half_min_tables"] == 39 and cal.cross_fitted_rate(stat, 0.1, 1.0)["half_min_tables"] == 9
    assert cal.level_rank(0.025, 39) == 1 and cal.level_rank(0.025, 38) == 0
    art = {"rate": small, "exact_rate": 1 / 41}
    text = _calibration_rate_sentence(art, {"n_tables": 40})
    assert "No out-of-sample rate: halves of 20 tables" in text and "at least 39 each" in text
    assert "at most 2.44 %" in text
    art = {"rate": r, "exact_rate": 5 / 201}
    text = _calibration_rate_sentence(art, {"n_tables": 200})
    assert f"named an artifact on {r['k']} of 200 clean tables" in text and "at most 2.49 %" in text


def test_cell_misfit_is_the_cell_means_scatter_beyond_the_point_noise():
    from asphalt_nscd.diagnosis.calibration import cell_misfit

    rng = np.random.default_rng(2)
    rows = pd.DataFrame({"temperature_C": np.repeat(np.arange(40.0), 4), "frequency_Hz": 10.0})
    cells = np.repeat(rng.normal(0, 0.03, 40), 4)
    e = cells + rng.normal(0, 0.02, 160)
    sE, sP = cell_misfit(rows, e, e, (0.02, 0.02), n_params=0)
    assert sE == pytest.approx(0.03, rel=0.3) and sP == sE
    assert cell_misfit(rows, rng.normal(0, 0.02, 160), np.zeros(160), (0.02, 0.02), 0)[0] < 0.012


#: tables per artifact of the check of the committed power claims (per configuration)
POWER_CHECK_TABLES = {"shipped": 10, "paper": 6}


def _committed_power_claims() -> list:
    """(configuration, artifact, size key, size, lower 95 % bound of its detection rate) of
    the smallest size whose detection rate in the committed benchmark (reference/detection_bench)
    reaches 95 % (``size_95_point``, a point estimate; its lower bound is what is checked)."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[2] / "reference" / "detection_bench"
    out = []
    for conf in POWER_CHECK_TABLES:
        path = root / f"{conf}_power.csv"
        if not path.exists():
            continue
        table = pd.read_csv(path)
        for artifact, rows in table.groupby("artifact"):
            size = rows["size_95_point"].iloc[0] if "size_95_point" in rows else rows["size_95"].iloc[0]
            if pd.isna(size):
                continue
            row = rows[rows["size"] == size].iloc[0]
            out.append((conf, artifact, row["size_key"], float(size), float(row["detection_ci_low"])))
    return out


@pytest.mark.parametrize("claim", _committed_power_claims(), ids=lambda c: f"{c[0]}-{c[1]}-{c[3]:g}")
def test_committed_power_claim_holds_on_fresh_seeds(claim):
    """The smallest size the committed benchmark detects with 95 % power, planted on fresh
    seeds in the same design across the truth families in turn: the detections are
    consistent with the benchmark's lower 95 % bound of that rate (binomial, a detector at
    that bound fails with probability 1e-3), so the claim is checked at a realistic size and
    not only at the top of the generator's range."""
    from asphalt_nscd.diagnosis import bench

    conf, artifact, key, size, low = claim
    n = POWER_CHECK_TABLES[conf]
    base = SEED_BASES[0]
    cases = [
        c
        for c in bench.plan(base, list(synthetic.FAMILIES), 0, 0, configuration=conf, power=n)
        if c["kind"] == f"power:{artifact}" and c["power_size"] == size
    ]
    assert len(cases) == n
    runs = [run_case(c) for c in cases]
    missed = [(r["family"], r["seed"], r["detected"]) for r in runs if artifact not in r["detected"]]
    assert len(missed) <= _allowed_failures(n, 1.0 - low, ALL_LEVEL), (
        f"{conf}: {artifact} at {key} = {size:g} missed on {len(missed)} of {n} tables {missed}; "
        f"the committed benchmark's rate is >= {low:.3f}; {_rerun_hint()}"
    )


@pytest.mark.parametrize("seed,schedule", [(3, "paper_2pb"), (4, "aashto_t342")])
def test_residuals_of_many_parameter_vectors_are_each_vectors_residuals_to_the_bit(seed, schedule):
    """The fits' finite-difference Jacobian evaluates its points as rows of one array
    (MasterCurveProblem.fit's ``workers`` map): each row must be, to the bit, what the
    vector alone gives, with every artifact term and each shift law, so that the fits do not
    depend on how the points are grouped."""
    from asphalt_nscd.rheology.master_curve import MasterCurveProblem

    table, truth = synthetic.generate(seed, ["time_lag"], schedule=schedule, family="mixed")
    search = ArtifactSearch(table, test=from_dict(truth["test"], "synthetic"))
    terms = [c.term for c in search.all_candidates()]
    assert {"time_lag", "self_heating", "temperature_drift"} <= {t.name for t in terms}
    problems = [search.problem(terms)] + [
        MasterCurveProblem(search.data, shift=shift, terms=search.nuisance + terms) for shift in ("wlf", "arrhenius")
    ]
    for k, prob in enumerate(problems):
        lo, hi = prob.bounds()
        X = lo + (hi - lo) * np.random.default_rng([seed, k]).random((6, lo.size))
        X[0] = prob.starts()[0]
        rows = prob.residuals(X)
        assert rows.shape == (6, 2 * len(table))
        for x, row in zip(X, rows):
            assert np.array_equal(row, prob.residuals(x)), prob.shift


def _prony_table(seed: int) -> tuple:
    """A table of the AASHTO T 342 design (3 specimens) whose truth is a generalized Maxwell
    series drawn afresh (a positive spectrum over 12 decades, WLF shifts), with specimen factors
    and point noise: (table, declared test)."""
    rng = np.random.default_rng(seed)
    temps, freqs = synthetic.SCHEDULES["aashto_t342"]
    rho = 10.0 ** np.linspace(-7.0, 5.0, 25)
    w = np.exp(-0.5 * ((np.log10(rho) + 1.0) / 2.5) ** 2 + rng.normal(0.0, 0.3, rho.size))
    E0, E00 = rng.uniform(25e3, 40e3), rng.uniform(50.0, 200.0)
    C1, C2 = rng.uniform(20.0, 30.0), rng.uniform(140.0, 200.0)
    rows = []
    for s in range(3):
        c, p0 = rng.normal(0.0, 0.03), rng.normal(0.0, 0.1)
        for T in temps:
            aT = 10.0 ** (-C1 * (T - 21.0) / (C2 + T - 21.0))
            for f in freqs:
                iwr = 1j * 2 * np.pi * f * aT * rho
                E = (E00 + (E0 - E00) * np.sum(w / w.sum() * iwr / (1 + iwr))) * np.exp(c + 1j * np.radians(p0))
                rows.append(
                    {
                        "specimen": f"S{s + 1}",
                        "temperature_C": T,
                        "frequency_Hz": f,
                        "E_norm_MPa": abs(E) * np.exp(rng.normal(0.0, 0.01)),
                        "phase_deg": np.degrees(np.angle(E)) + rng.normal(0.0, 0.2),
                    }
                )
    test = from_dict({"test": "uniaxial_cylinder", "diameter_mm": None, "height_mm": None}, "x")
    return pd.DataFrame(rows), test


@pytest.mark.parametrize("seed", [101, 202, 303])
def test_the_relaxation_spectrum_null_follows_a_linear_viscoelastic_table_and_not_a_time_lag(seed):
    """The relaxation-spectrum null (a generalized Maxwell master curve with a smooth shift law,
    fitted to the table) describes a clean table of any positive spectrum to its noise (reduced
    chi-square near 1, where the 2S2P1D screening model need not), and a table with a planted
    time lag it does not: a phase growing with the test frequency at a fixed |E*| is no linear
    viscoelastic material's, so on a table the screening model follows its mean carries far
    less of the lag than the table does."""
    from asphalt_nscd.diagnosis import calibration as cal

    table, test = _prony_table(seed)
    search = ArtifactSearch(table, test=test)
    with np.errstate(all="ignore"):
        base = search.fit([])
        clean = cal.clean_model(search, base)
        null = cal.maxwell_model(search, base, clean)
    assert null.info["chi2_per_dof"] < 1.6
    assert null.info["terms_per_decade"] in cal.MAXWELL_DENSITIES and null.info["positive_terms"] >= 3
    err = np.log(np.abs(null.E)) - np.log(table["E_norm_MPa"].to_numpy())
    assert np.sqrt(np.mean(err**2)) < 0.02
    lagged, _ = synthetic.generate(
        seed,
        ["time_lag"],
        schedule="aashto_t342",
        n_specimens=3,
        magnitudes={"time_lag": {"time_lag_ms": 0.3}},
        test_order=False,
    )
    search = ArtifactSearch(lagged, test=test)
    with np.errstate(all="ignore"):
        observed = search.run()
        null = cal.maxwell_model(search, observed["base"], cal.clean_model(search, observed["base"]))
        mean = null.rows.assign(E_norm_MPa=np.abs(null.E), phase_deg=np.degrees(np.angle(null.E)))
        p_mean = ArtifactSearch(mean, test=test).run()["tests"]["time_lag"]["p"]
    assert observed["min_p"] < 1e-20 and p_mean > 1e6 * observed["min_p"]


def test_the_relaxation_spectrum_columns_and_weights_are_a_maxwell_series():
    """A Maxwell element of relaxation time rho has E*(w) = E iw rho / (1 + iw rho): at w rho = 1
    its modulus is E / sqrt(2) and its phase 45 deg, at w rho >> 1 it tends to E with a phase
    1 / (w rho) rad; the static column is 1. The non-negative weights fitted to a series drawn on
    the grid give it back, and the grid spans the reduced band widened by the margin at each end
    at the stated density."""
    from asphalt_nscd.diagnosis import calibration as cal

    C = cal.maxwell_columns(np.array([1.0, 1e4]), np.array([1.0]))
    assert C.shape == (2, 2) and np.all(C[:, 0] == 1.0)
    assert abs(C[0, 1]) == pytest.approx(1 / np.sqrt(2)) and np.degrees(np.angle(C[0, 1])) == pytest.approx(45.0)
    assert abs(C[1, 1]) == pytest.approx(1.0, abs=1e-8) and np.angle(C[1, 1]) == pytest.approx(1e-4, rel=1e-6)
    omega = 2 * np.pi * np.logspace(-4.0, 3.0, 40)
    rho = cal.relaxation_grid(omega, 1.5)
    assert rho[0] == pytest.approx(10**-2 / omega.max()) and rho[-1] == pytest.approx(10**2 / omega.min())
    assert (rho.size - 1) / np.log10(rho[-1] / rho[0]) == pytest.approx(1.5, rel=0.05)
    rng = np.random.default_rng(3)
    x = np.where(rng.random(rho.size + 1) < 0.6, rng.uniform(50.0, 3000.0, rho.size + 1), 0.0)
    Cg = cal.maxwell_columns(omega, rho)
    w = cal.maxwell_weights(Cg, Cg @ x, (0.01, 0.2))
    assert np.all(w >= 0.0)
    np.testing.assert_allclose(Cg @ w, Cg @ x, rtol=1e-6)


def test_calibrated_p_values_of_several_nulls_take_the_largest():
    """With two nulls the calibrated p-value of a statistic is the larger of the two nulls'
    (1 + #{m_b <= p}) / (B + 1); a calibration written with one null reads as one list."""
    from asphalt_nscd.diagnosis import calibration as cal

    a, b = [0.1, 0.2, 0.3], [0.01, 0.02, 0.5]
    assert fx.adjusted_p(0.15, [a, b]) == pytest.approx(3 / 4) and fx.adjusted_p(0.15, a) == pytest.approx(2 / 4)
    two = {"artifacts": {"null_min_p": a, "nulls": {"2s2p1d": {"null_min_p": a}, "maxwell": {"null_min_p": b}}}}
    assert cal.null_statistics(two) == [a, b]
    assert cal.null_statistics({"artifacts": {"null_min_p": a}}) == [a] and cal.null_statistics(None) is None
