"""Benchmark of the artifact detection: false-alarm and detection rates with confidence intervals.

The level of a test is only known where it was measured. ``asphalt-nscd diagnose-bench``
measures the artifact detection of :mod:`asphalt_nscd.diagnosis.effects` on synthetic tables
(:mod:`asphalt_nscd.diagnosis.synthetic`) of several *truth families*, most of them outside
the detector's own model, with specimen scatter of 2-5 % and each schedule's declared geometry.

Per family: ``n_clean`` clean tables give the **false-alarm rate** of each artifact and the
family-wise one (any artifact named), judged on the 95 % Clopper-Pearson upper bound;
``n_planted`` tables per artifact planted at its **stated effect size** (:data:`EFFECT_SIZES`
x ``effect_scale``) give the **detection rate** and the cross-talk of the others. Inertia is
planted in 2PB designs only (a moving mass of a few kg changes E1 of a uniaxial test at
<= 25 Hz by well under 1 %), an offset on a random inner isotherm of >= 4.

Configurations (:data:`CONFIGURATIONS`): ``random`` draws the schedule and 2-4 specimens and
keeps a random test order; ``shipped`` is the shipped UIUC table's design (AASHTO T 342,
3 specimens, no test order, no strain column, a uniaxial test without its dimensions);
``paper`` the paper's (2PB 6 x 5, 4 specimens, the standard order with a repeat of each
isotherm's first frequency at its end, strains, the 2PB geometry). Only what a configuration
can test is planted in it.

Power curves (``power`` tables per size): the offset, the time lag and the uncorrected mass
planted at a grid of sizes (:data:`POWER_SIZES`) on the families in turn; the detection rate
per size with its one-sided 95 % lower bound, the smallest size whose lower bound reaches 95 %
(the power the tables show) and the smallest whose observed rate does (a point estimate).

The level: the procedure runs at its nominal level alpha / m (the ceiling of the level
calibrated on a table, :mod:`asphalt_nscd.diagnosis.calibration`, which can only be stricter);
each clean table records the statistic ``min_p``, so the largest level whose family-wise
false-alarm upper bound is <= 5 % in every family is computed too (``level_for_goal``). The
complete procedure, its level calibrated on each table, is measured by calibrating the clean
tables with a nominal alarm (``calibration_tables``, :func:`calibrate_alarms`): the others
cannot raise one.

Seeds: table seeds come from ``numpy.random.SeedSequence([base_seed, family, kind, i])``; the
base seed (default: fresh from the operating system) is recorded, so ``--base-seed`` reruns a
run exactly.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from ..io import read_json_lines
from . import synthetic
from .calibration import LEVEL_RULE
from .effects import ARTIFACTS, ArtifactSearch, effect_entries
from .scores import binomial_ci

#: estimate key of each effect in the report and the truth
ESTIMATE_KEYS = {
    "time_lag": "time_lag_ms",
    "inertia_uncorrected": "mass_factor_g",
    "temperature_offset": "offset_C",
    "strain_nonlinearity": "modulus_drop_per_100_microstrain",
    "self_heating": "modulus_drop_pct_per_test",
    "temperature_drift": "drift_C_per_test",
}
#: Stated effect sizes at which detection is measured (keys of the truth JSON). Time lag
#: 0.3 ms (360 f dt: 4.3 deg of phase at 40 Hz, 2.7 deg at 25 Hz); inertia: an uncorrected
#: moving mass on the paper's 2PB specimen that lowers E1 by 5 % of |E*| at the most
#: affected point (the hottest isotherm's highest frequency; 40-400 g on the truths drawn);
#: temperature offset: 3 degC on one inner isotherm (sign random); strain nonlinearity: 4 %
#: of |E*| per 100 microstrain; self-heating: |E*| -1 % and Phi +1 % per earlier test of the
#: isotherm; temperature drift: 1 degC per test at the hottest isotherm along the assumed
#: order (about 5 degC across it), falling linearly to 0 at the coldest.
EFFECT_SIZES = {
    "time_lag": {"time_lag_ms": 0.3},
    "inertia_uncorrected": {"E_deficit_pct": 5.0},
    "temperature_offset": {"offset_C": 3.0},
    "strain_nonlinearity": {"modulus_drop_per_100_microstrain": 0.04},
    "self_heating": {"modulus_drop_pct_per_test": 1.0, "phase_rise_pct_per_test": 1.0},
    "temperature_drift": {"drift_C_per_test": 1.0},
}
#: schedules on which an artifact is planted (default: every schedule)
PLANTED_SCHEDULES = {
    "inertia_uncorrected": ("paper_2pb",),
    "temperature_offset": ("paper_2pb", "aashto_t342"),
    "temperature_drift": ("paper_2pb", "aashto_t342"),
}
GOALS = {"detection_rate": 0.95, "false_alarm_rate": 0.05}
KINDS = ("clean",) + ARTIFACTS
#: designs of the benchmark tables (module docstring); None: drawn per table
CONFIGURATIONS: dict[str, dict[str, Any] | None] = {
    "random": None,
    "shipped": {
        "schedule": "aashto_t342",
        "n_specimens": 3,
        "test_order": False,
        "order": "standard",
        "strain": False,
        "test": {"test": "uniaxial_cylinder", "diameter_mm": None, "height_mm": None},
    },
    "paper": {
        "schedule": "paper_2pb",
        "n_specimens": 4,
        "test_order": True,
        "order": "repeat",
        "strain": True,
        "test": None,
    },
}
#: sizes of the power curves (key of the planted magnitude: values)
POWER_SIZES: dict[str, tuple[str, tuple[float, ...]]] = {
    "temperature_offset": ("offset_C", (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)),
    "time_lag": ("time_lag_ms", (0.05, 0.1, 0.2, 0.3, 0.5)),
    "inertia_uncorrected": ("E_deficit_pct", (1.0, 2.0, 3.0, 5.0, 8.0)),
}


def plantable(kind: str, configuration: dict | None) -> bool:
    """Whether an artifact can be planted (and tested) in a configuration's design."""
    if configuration is None:
        return True
    if kind in ("self_heating", "temperature_drift") and not configuration["test_order"]:
        return False
    if kind == "strain_nonlinearity" and not configuration["strain"]:
        return False
    if kind == "inertia_uncorrected" and (
        configuration["test"] is not None or configuration["schedule"] != "paper_2pb"
    ):
        return False
    if kind == "temperature_offset" and len(synthetic.SCHEDULES[configuration["schedule"]][0]) < 4:
        return False
    return True


def case_seed(base_seed: int, family: str, kind: str, i: int) -> int:
    """Seed of table ``i`` of ``kind`` (clean or an artifact) in ``family``."""
    ss = np.random.SeedSequence([int(base_seed), synthetic.FAMILIES.index(family), KINDS.index(kind), int(i)])
    return int(ss.generate_state(1, dtype=np.uint32)[0])


def planted_magnitude(kind: str, rng: np.random.Generator, schedule: str, scale: float = 1.0) -> dict:
    """Magnitudes of a planted artifact at its stated size (times ``scale``)."""
    out = {k: v * scale for k, v in EFFECT_SIZES[kind].items()}
    if kind == "temperature_offset":
        temps = synthetic.SCHEDULES[schedule][0]
        out["temperature_C"] = float(rng.choice(temps[1:-1]))
        out["offset_C"] *= float(rng.choice([-1.0, 1.0]))
    if kind == "temperature_drift":
        out["temperature_C"] = float(max(synthetic.SCHEDULES[schedule][0]))
    return out


def plan(
    base_seed: int,
    families,
    n_clean: int,
    n_planted: int,
    scale: float = 1.0,
    configuration: str = "random",
    power: int = 0,
) -> list:
    """Cases of a benchmark run: dicts ``family, kind, index, seed, schedule, effects,
    magnitudes, test_order, configuration`` (and ``power_size`` for a power-curve case, kind
    ``power:<artifact>``).

    Raises ValueError on an unknown configuration."""
    if configuration not in CONFIGURATIONS:
        raise ValueError(f"unknown configuration '{configuration}'; expected one of {list(CONFIGURATIONS)}")
    conf = CONFIGURATIONS[configuration]
    cases = []

    def case(fam, kind, i, seed, rng, effects, mags):
        schedule = (
            conf["schedule"]
            if conf
            else str(
                rng.choice(
                    PLANTED_SCHEDULES.get(effects[0] if effects else "clean", tuple(sorted(synthetic.SCHEDULES)))
                )
            )
        )
        mags = {k: (v(schedule) if callable(v) else v) for k, v in mags.items()}
        return {
            "family": fam,
            "kind": kind,
            "index": i,
            "seed": seed,
            "schedule": schedule,
            "effects": effects,
            "magnitudes": mags,
            "test_order": conf["test_order"] if conf else True,
            "configuration": configuration,
        }

    for fam in families:
        for kind in KINDS:
            if kind != "clean" and not plantable(kind, conf):
                continue
            n = n_clean if kind == "clean" else n_planted
            for i in range(n):
                seed = case_seed(base_seed, fam, kind, i)
                rng = np.random.default_rng([seed, 2])
                effects = [] if kind == "clean" else [kind]
                mags = (
                    {} if kind == "clean" else {kind: (lambda sch, k=kind, r=rng: planted_magnitude(k, r, sch, scale))}
                )
                cases.append(case(fam, kind, i, seed, rng, effects, mags))
    for name, (key, sizes) in POWER_SIZES.items():
        if power <= 0 or not plantable(name, conf) or (conf is None and name == "inertia_uncorrected"):
            continue
        for j, size in enumerate(sizes):
            for i in range(power):
                fam = families[i % len(families)]
                ss = np.random.SeedSequence([int(base_seed), 97, list(POWER_SIZES).index(name), j, i])
                seed = int(ss.generate_state(1, dtype=np.uint32)[0])
                rng = np.random.default_rng([seed, 2])

                def mag(sch, name=name, key=key, size=size, rng=rng):
                    out = planted_magnitude(name, rng, sch, 1.0)
                    out[key] = size * (np.sign(out[key]) if key == "offset_C" else 1.0)
                    return out

                c = case(fam, f"power:{name}", i, seed, rng, [name], {name: mag})
                c["power_size"] = float(size)
                cases.append(c)
    return cases


def estimate_ok(name: str, entry: dict, truth: dict, tolerance: float, n_se: float = 0.0) -> bool:
    """Whether the estimate of a detected effect is within ``tolerance`` (relative) of the
    truth, or within ``n_se`` of its own standard errors (``<key>_se`` of the estimate; 0: the
    relative tolerance only, as the benchmark counts). A temperature offset must also sit on
    the planted isotherm."""
    key = ESTIMATE_KEYS[name]
    true = truth["effects"][name][key]
    est = entry["estimate"].get(key)
    if est is None:
        return False
    if (
        name == "temperature_offset"
        and entry["estimate"].get("temperature_C") != truth["effects"][name]["temperature_C"]
    ):
        return False
    se = entry["estimate"].get(key + "_se") or 0.0
    return abs(est - true) <= max(tolerance * abs(true), n_se * se)


def case_table(case: dict) -> tuple:
    """The table of a case (a dict of :func:`plan`) as its configuration shows it: the
    table, the truth (:func:`asphalt_nscd.diagnosis.synthetic.generate`) and the declared test
    (:class:`~asphalt_nscd.lab.geometry.TestGeometry`)."""
    from ..lab.geometry import from_dict

    conf = CONFIGURATIONS.get(case.get("configuration", "random"))
    table, truth = synthetic.generate(
        case["seed"],
        case["effects"],
        schedule=case["schedule"],
        magnitudes=case["magnitudes"],
        family=case["family"],
        test_order=case.get("test_order", True),
        n_specimens=None if conf is None else conf["n_specimens"],
        order="random" if conf is None else conf["order"],
    )
    if conf is not None and not conf["strain"]:
        table = table.drop(columns="strain_microstrain")
    test = truth["test"] if conf is None or conf["test"] is None else conf["test"]
    return table, truth, from_dict(test, "synthetic")


def run_case(case: dict, alpha: float = 1e-3, tolerance: float = 0.25, level: float | None = None) -> dict:
    """Generate one table of a case and diagnose its artifacts; the outcome. ``level``: the
    first step's level calibrated on the table (default the nominal alpha / m)."""
    table, truth, test = case_table(case)
    t0 = time.process_time()
    search = ArtifactSearch(table, alpha=alpha, test=test)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        result = search.run(level=level)
    if result["offset"] is not None and result["offset"].get("detected"):
        search.consistent_correction(result)  # the report's consistency check of an offset
    entries = {e["name"]: e for e in effect_entries(search, result)}
    out = {k: case[k] for k in ("family", "kind", "index", "seed", "schedule")}
    out.update(
        {
            "configuration": case.get("configuration", "random"),
            "power_size": case.get("power_size"),
            "min_p": float(result["min_p"]),
            "level": float(result["level"]),
            "not_identifiable": [n for n, v in result["identified"].items() if not v.get("identifiable", True)],
        }
    )
    out.update(
        {
            "n_specimens": truth["n_specimens"],
            "planted": list(case["effects"]),
            "detected": [n for n in ARTIFACTS if entries[n]["detected"]],
            "testable": [n for n in ARTIFACTS if entries[n]["testable"] and entries[n]["identifiable"]],
            "cpu_seconds": time.process_time() - t0,
            "p_values": {n: entries[n]["p_value"] for n in ARTIFACTS},
            "sizes": {n: entries[n]["estimate"].get("size") for n in ARTIFACTS},
            "screening_chi2_per_dof": search.chi2_per_dof(result["base"]),
            "estimate_ok": {},
        }
    )
    for name in case["effects"]:
        e = entries[name]
        out["estimate_ok"][name] = bool(e["detected"] and estimate_ok(name, e, truth, tolerance))
        out["truth"] = truth["effects"]
    return out


def _rate(k: int, n: int) -> dict:
    """A count k of n: its rate, exact 95 % interval and one-sided 95 % bounds."""
    lo, hi = binomial_ci(k, n)
    return {
        "k": int(k),
        "n": int(n),
        "rate": (k / n) if n else None,
        "ci95": [lo, hi],
        "lower_95": lower_bound(k, n),
        "upper_95": upper_bound(k, n),
    }


def family_wise(runs: list, families) -> dict:
    """Per family (and pooled, ``all``): the family-wise false-alarm rate, the fraction of
    clean tables on which the selection names any artifact (all candidates, all rounds, the
    offset test), judged on its 95 % upper bound (``ok``: <= 5 %), and the screening reduced
    chi-square of the clean tables (median, 99th percentile, maximum)."""
    out = {}
    for fam in list(families) + ["all"]:
        clean = [r for r in runs if r["kind"] == "clean" and (fam == "all" or r["family"] == fam)]
        chi = np.array([r["screening_chi2_per_dof"] for r in clean], float)
        rate = _rate(sum(bool(r["detected"]) for r in clean), len(clean))
        rate["ok"] = rate["ci95"][1] is not None and rate["ci95"][1] <= GOALS["false_alarm_rate"]
        out[fam] = {"false_alarm_any": rate}
        if clean and all("detected_calibrated" in r for r in clean):
            cal = _rate(sum(bool(r["detected_calibrated"]) for r in clean), len(clean))
            cal["ok"] = cal["ci95"][1] <= GOALS["false_alarm_rate"]
            out[fam]["false_alarm_any_calibrated"] = cal
        out[fam].update(
            {
                "screening_chi2_per_dof": {
                    "median": float(np.median(chi)) if chi.size else None,
                    "p99": float(np.percentile(chi, 99)) if chi.size else None,
                    "max": float(chi.max()) if chi.size else None,
                }
            }
        )
    return out


def _calibrated_level(args) -> dict:
    from .calibration import calibrate

    case, alpha, n_tables, decide = args
    table, _, test = case_table(case)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        # the decision needs the artifact procedure's level only, not the static-modulus test's;
        # curtailed at the table's own statistic: the same decision as all n_tables tables
        cal = calibrate(
            table, alpha=alpha, test=test, n_tables=n_tables, seed=case["seed"], static=False, decide=decide
        )
    a = cal["artifacts"]
    nulls = a["nulls"]
    return {
        "level": a["level"],
        "calibrated_level": a["calibrated_level"],
        "binding_null": a["binding_null"],
        "observed_min_p": a["observed_min_p"],
        "null_levels": {k: v["calibrated_level"] for k, v in nulls.items()},
        "null_below": {k: int(np.sum(np.asarray(v["null_min_p"]) <= a["observed_min_p"])) for k, v in nulls.items()},
        "n_run": {k: v["n_run"] for k, v in nulls.items()},
        "null_models": {k: v["model"] for k, v in nulls.items()},
        "level_bound": a["calibrated_level_bound"],
        "cpu_seconds": cal["cpu_seconds"],
    }


def calibrate_alarms(
    result: dict,
    n_tables: int = 200,
    jobs: int = 1,
    checkpoint: Path | None = None,
    planted: int = 0,
    artifacts=ARTIFACTS,
) -> dict:
    """The complete procedure's false alarms on the clean tables of a benchmark result, and its
    detections on planted ones: each table on which the nominal procedure names an artifact is
    calibrated on itself (:func:`asphalt_nscd.diagnosis.calibration.calibrate`, ``n_tables``
    bootstrap tables of each null seeded by the table's seed, run in turn until the decision is
    known: curtailed once more than the calibration's share of one null's reach the table's
    ``min_p``). The calibrated level is never above the nominal one, so a table without a
    nominal alarm has none after calibration: the counts are exact without calibrating those.

    Clean tables: an alarm stays only if its ``min_p`` is below the calibrated level
    (``detected_calibrated``, bool). Planted tables at the stated size (``planted``: the first
    ``planted`` of each family and artifact; 0: none): a curtailed calibration names nothing;
    otherwise the search is run again at the calibrated level and ``detected_calibrated`` lists
    what it names (Holm's later steps and the offset test at their levels); ``artifacts``: the
    planted artifacts recounted (default all). Adds
    ``calibrated_level`` where it was computed, ``calibration_tables`` and ``planted_calibrated``
    to the result; recomputes ``family_wise`` and adds ``detection_calibrated``
    (:func:`detection_calibrated`). Returns ``result`` (changed in place).

    ``checkpoint``: a JSON-lines file; each table's calibration is appended to it as it ends and
    a table already there (same family, kind, index, seed, ``n_tables``, nulls and ``min_p``)
    is read back instead of rerun, so a stopped calibration resumes where it stopped.

    Raises ValueError when a run's table cannot be regenerated from the result's plan."""
    runs = result["runs"]
    n_planted = int(result.get("n_planted_per_family_and_artifact", 0)) if planted else 0
    cases = {
        (c["family"], c["kind"], c["index"]): c
        for c in plan(
            result["base_seed"],
            result["families"],
            result["n_clean_per_family"],
            n_planted,
            result["effect_scale"],
            result["configuration"],
            0,
        )
    }
    todo = []
    for r in runs:
        if r["kind"] == "clean":
            r["detected_calibrated"] = False
        elif r["kind"] in artifacts and r["index"] < planted:
            r["detected_calibrated"] = []
        else:
            continue
        if r["detected"]:
            case = cases.get((r["family"], r["kind"], r["index"]))
            if case is None or case["seed"] != r["seed"]:
                raise ValueError(
                    f"{r['kind']} table {r['family']} #{r['index']}: not in the result's plan (base seed "
                    f"{result['base_seed']}); was the result produced by another version?"
                )
            todo.append((r, case))
    done = _read_checkpoint(checkpoint, int(n_tables))
    rest = [(r, c) for r, c in todo if _checkpoint_key(r) not in done]
    tasks = [(c, result["alpha"], int(n_tables), r["min_p"]) for r, c in rest]
    for (r, c), out in zip(rest, _map_cases(_calibrated_level, tasks, jobs, lazy=True)):
        if r["kind"] != "clean":
            out["detected"] = _named_at(c, result["alpha"], out)
        done[_checkpoint_key(r)] = out
        if checkpoint is not None:
            rec = {k: r[k] for k in CHECKPOINT_KEY}
            with open(checkpoint, "a") as fh:
                line = {**rec, **checkpoint_tag(n_tables), "out": out}
                fh.write(json.dumps(line) + "\n")
    for r, _ in todo:
        out = done[_checkpoint_key(r)]
        r["calibrated_level"] = out["level"]
        r["calibration_cpu_seconds"] = out["cpu_seconds"]
        r["calibration_min_p"] = out["observed_min_p"]  # the table's statistic, recomputed with its calibration
        r["calibration_null_below"] = out["null_below"]  # per null: bootstrap tables whose statistic is <= it
        r["calibration_tables_run"] = out["n_run"]  # per null; fewer than n_tables: stopped once decided
        r["calibration_null_levels"] = out["null_levels"]
        r["calibration_binding_null"] = out["binding_null"]
        r["calibrated_level_is_bound"] = out["level_bound"]
        if r["kind"] == "clean":
            r["detected_calibrated"] = bool(r["min_p"] < out["level"])
        else:
            r["detected_calibrated"] = list(out["detected"])
    result["calibration_tables"] = int(n_tables)
    result["planted_calibrated"] = int(planted)
    result["family_wise"] = family_wise(runs, result["families"])
    result["detection_calibrated"] = detection_calibrated(runs, result["families"])
    return result


def _named_at(case: dict, alpha: float, out: dict) -> list:
    """What the search names on a case's table at the level of a calibration ``out`` (none when
    the calibration stopped early: its level is then at most the table's statistic)."""
    if out["level_bound"]:
        return []
    return run_case(case, alpha, level=out["level"])["detected"]


def detection_calibrated(runs: list, families) -> dict:
    """Per artifact, family and pooled (``all``): the planted tables whose detection was
    recounted with the calibrated level (:func:`calibrate_alarms`), named at the nominal level
    and after calibration, with the one-sided 95 % lower bound of the calibrated rate."""
    out: dict[str, dict] = {}
    for name in ARTIFACTS:
        rs = [r for r in runs if r["kind"] == name and "detected_calibrated" in r]
        if not rs:
            continue
        out[name] = {}
        for fam in list(families) + ["all"]:
            g = [r for r in rs if fam == "all" or r["family"] == fam]
            if not g:
                continue
            k = sum(name in r["detected_calibrated"] for r in g)
            out[name][fam] = {
                "nominal": _rate(sum(name in r["detected"] for r in g), len(g)),
                "calibrated": _rate(k, len(g)),
                "calibrated_lower_95": lower_bound(k, len(g)),
            }
    return out


#: the fields that name a table in a :func:`calibrate_alarms` checkpoint
CHECKPOINT_KEY = ("family", "kind", "index", "seed", "min_p")


def _checkpoint_key(rec: dict) -> tuple:
    """A table's key in a :func:`calibrate_alarms` checkpoint (:data:`CHECKPOINT_KEY`)."""
    family, kind, index, seed, min_p = (rec[k] for k in CHECKPOINT_KEY)
    return (family, kind, int(index), int(seed), float(min_p))


def _nulls_tag() -> list:
    """The calibration's nulls, recorded with each checkpoint line (a line of other nulls is
    not read back)."""
    from .calibration import NULLS

    return list(NULLS)


def checkpoint_tag(n_tables: int) -> dict:
    """What a calibration checkpoint line records of how it was calibrated: the number of tables
    per null, the nulls and the level rule (:data:`asphalt_nscd.diagnosis.calibration.LEVEL_RULE`);
    a line read back must carry the same (:func:`is_current`)."""
    return {"n_tables": int(n_tables), "nulls": _nulls_tag(), "level_rule": LEVEL_RULE}


def is_current(rec: dict, n_tables: int) -> bool:
    """Whether a checkpoint line was calibrated as a run of ``n_tables`` tables is now
    (:func:`checkpoint_tag`)."""
    return all(rec.get(k) == v for k, v in checkpoint_tag(n_tables).items())


def _read_checkpoint(path: Path | None, n_tables: int) -> dict:
    """Calibrations already written to a :func:`calibrate_alarms` checkpoint with the same
    number of tables, nulls and level rule (:data:`asphalt_nscd.diagnosis.calibration.LEVEL_RULE`),
    keyed by table (:func:`asphalt_nscd.io.read_json_lines`: a last line cut short by a killed run is removed,
    that table calibrated again; any other line that is not a record raises InputError)."""
    if path is None:
        return {}
    want = (*CHECKPOINT_KEY, "n_tables", "out")
    return {
        _checkpoint_key(rec): rec["out"]
        for rec in read_json_lines(path, "calibration record", want)
        if is_current(rec, n_tables)
    }


def _map_cases(fn, tasks: list, jobs: int, lazy: bool = False):
    """``fn`` over ``tasks``, in ``jobs`` processes; ``lazy``: yield each result as it ends (in
    order) rather than return the list."""
    if jobs > 1 and len(tasks) > 1:
        from concurrent.futures import ProcessPoolExecutor

        def run():
            with ProcessPoolExecutor(max_workers=jobs) as pool:
                yield from pool.map(fn, tasks)

        return run() if lazy else list(run())
    return (fn(t) for t in tasks) if lazy else [fn(t) for t in tasks]


def level_for_goal(runs: list, families, goal: float = GOALS["false_alarm_rate"]) -> float | None:
    """The largest first-step level c whose family-wise false-alarm count #{min_p < c} on the
    clean tables has a 95 % Clopper-Pearson upper bound <= ``goal`` in every family (None
    without clean tables)."""
    per = [np.sort([r["min_p"] for r in runs if r["kind"] == "clean" and r["family"] == f]) for f in families]
    per = [m for m in per if m.size]
    if not per:
        return None

    def upper(m: np.ndarray, c: float) -> float:
        hi = binomial_ci(int(np.sum(m < c)), m.size)[1]
        assert hi is not None  # m is not empty
        return hi

    best = 0.0
    for c in np.unique(np.concatenate(per + [np.array([1.0])])):
        if all(upper(m, c) <= goal for m in per):
            best = float(c)
        else:
            break
    return best


def lower_bound(k: int, n: int, level: float = 0.95) -> float | None:
    """One-sided exact (Clopper-Pearson) lower confidence bound of a proportion k/n at ``level``
    (0 for k = 0; None for n = 0): the power a detection count shows at least."""
    if n <= 0:
        return None
    if k <= 0:
        return 0.0
    return float(stats.beta.ppf(1.0 - level, k, n - k + 1))


def upper_bound(k: int, n: int, level: float = 0.95) -> float | None:
    """One-sided exact (Clopper-Pearson) upper confidence bound of a proportion k/n at ``level``
    (1 for k = n; None for n = 0): the false-alarm rate a count bounds at most."""
    if n <= 0:
        return None
    if k >= n:
        return 1.0
    return float(stats.beta.ppf(level, k + 1, n - k))


def power_sizes(rows: list) -> dict:
    """The smallest sizes of a power curve (rows of :func:`power_curves`) that reach the goal:
    ``size_95``, whose one-sided 95 % lower bound of the detection rate is >= 95 % (the power
    the tables show), and ``size_95_point``, whose observed rate is >= 95 % (a point estimate:
    48 of 50 has a lower bound of 88 %); None where no size does."""
    goal = GOALS["detection_rate"]
    shown = [r["size"] for r in rows if (lower_bound(r["detection"]["k"], r["detection"]["n"]) or 0.0) >= goal]
    point = [r["size"] for r in rows if r["detection"]["rate"] is not None and r["detection"]["rate"] >= goal]
    return {"size_95": min(shown) if shown else None, "size_95_point": min(point) if point else None}


def power_curves(runs: list) -> dict:
    """Per artifact of the power cases: one row per planted size (``size``, detection and
    estimate rates with 95 % intervals and the one-sided 95 % lower bound of the detection
    rate, ``detection_lower_95``) and the sizes of :func:`power_sizes`."""
    out = {}
    for name, (key, sizes) in POWER_SIZES.items():
        rs = [r for r in runs if r["kind"] == f"power:{name}"]
        if not rs:
            continue
        rows: list[dict[str, Any]] = []
        for size in sizes:
            at = [r for r in rs if r["power_size"] == size]
            k = sum(name in r["detected"] for r in at)
            rows.append(
                {
                    "size": size,
                    "size_key": key,
                    "detection": _rate(k, len(at)),
                    "detection_lower_95": lower_bound(k, len(at)),
                    "estimate_within_tolerance": _rate(sum(r["estimate_ok"].get(name, False) for r in at), len(at)),
                }
            )
        out[name] = {"size_key": key, "curve": rows, **power_sizes(rows)}
    return out


def summarize(runs: list, families) -> dict:
    """Per artifact and family (and pooled, ``all``): false alarms on clean tables, cross-talk
    on tables planted with another artifact, detection and estimate rates at the stated size
    (the power-curve tables are summarised apart, :func:`power_curves`)."""
    runs = [r for r in runs if not r["kind"].startswith("power:")]
    out: dict[str, dict] = {}
    for name in ARTIFACTS:
        out[name] = {}
        for fam in list(families) + ["all"]:
            rs = [r for r in runs if fam == "all" or r["family"] == fam]
            clean = [r for r in rs if r["kind"] == "clean" and name in r["testable"]]
            other = [r for r in rs if r["kind"] not in ("clean", name) and name in r["testable"]]
            planted = [r for r in rs if r["kind"] == name]
            out[name][fam] = {
                "false_alarm": _rate(sum(name in r["detected"] for r in clean), len(clean)),
                "cross_talk": _rate(sum(name in r["detected"] for r in other), len(other)),
                "detection": _rate(sum(name in r["detected"] for r in planted), len(planted)),
                "estimate_within_tolerance": _rate(
                    sum(r["estimate_ok"].get(name, False) for r in planted), len(planted)
                ),
            }
    return out


def goals_met(summary: dict) -> dict:
    """Per artifact: pooled detection >= 95 %, and false alarms with a 95 % upper bound
    <= 5 % in every family."""
    out = {}
    for name, per in summary.items():
        fams = [f for f in per if f != "all"]
        fa = [per[f]["false_alarm"]["rate"] for f in fams if per[f]["false_alarm"]["n"]]
        hi = [per[f]["false_alarm"]["ci95"][1] for f in fams if per[f]["false_alarm"]["n"]]
        det = per["all"]["detection"]["rate"]
        out[name] = {
            "false_alarm_max_over_families": max(fa) if fa else None,
            "false_alarm_upper_max_over_families": max(hi) if hi else None,
            "false_alarm_ok": bool(hi) and max(hi) <= GOALS["false_alarm_rate"],
            "detection_pooled": det,
            "detection_ok": det is not None and det >= GOALS["detection_rate"],
        }
    return out


def run_bench(
    n_clean: int,
    n_planted: int,
    base_seed: int | None = None,
    families=synthetic.FAMILIES,
    alpha: float = 1e-3,
    effect_scale: float = 1.0,
    tolerance: float = 0.25,
    jobs: int = 1,
    configuration: str = "random",
    power: int = 0,
    calibration_tables: int = 0,
) -> dict:
    """Run the benchmark (module docstring) and return its JSON-ready summary.

    Parameters
    ----------
    n_clean, n_planted : int
        Clean tables per family, planted tables per family and artifact.
    base_seed : int, optional
        Base seed; default a fresh one from the operating system (recorded in the result).
    families : sequence of str
        Truth families (:data:`synthetic.FAMILIES`).
    alpha : float
        Level of the detector's tests.
    effect_scale : float
        Factor on every stated effect size (e.g. 0.5 for a point of the power curve).
    tolerance : float
        Relative tolerance of a correct estimate.
    jobs : int
        Worker processes.
    configuration : str
        Design of the tables (:data:`CONFIGURATIONS`).
    power : int
        Tables per size of the power curves (0: none).
    calibration_tables : int
        Bootstrap tables of the calibration of each clean table with a nominal alarm
        (:func:`calibrate_alarms`; 0: none, the family-wise rate at the nominal level only).

    Raises
    ------
    ValueError
        on an unknown family or configuration, or non-positive counts.
    """
    families = list(families)
    unknown = [f for f in families if f not in synthetic.FAMILIES]
    if unknown:
        raise ValueError(f"unknown truth famil(y/ies) {unknown}; expected some of {list(synthetic.FAMILIES)}")
    if n_clean < 0 or n_planted < 0 or power < 0 or n_clean + n_planted + power == 0:
        raise ValueError(f"need n_clean, n_planted, power >= 0 and not all 0, got {n_clean}, {n_planted}, {power}")
    if base_seed is None:
        entropy = np.random.SeedSequence().entropy
        assert isinstance(entropy, int)  # fresh entropy drawn from the system: an int
        base_seed = int(entropy % (2**63))
    cases = plan(base_seed, families, n_clean, n_planted, effect_scale, configuration, power)
    t0, c0 = time.perf_counter(), time.process_time()
    if jobs > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(max_workers=jobs) as pool:
            runs = list(pool.map(run_case, cases, [alpha] * len(cases), [tolerance] * len(cases), chunksize=2))
    else:
        runs = [run_case(c, alpha, tolerance) for c in cases]
    summary = summarize(runs, families)
    fw = family_wise(runs, families)
    result = {
        "base_seed": base_seed,
        "configuration": configuration,
        "design": CONFIGURATIONS[configuration],
        "family_wise": fw,
        "family_wise_ok": {f: bool(v["false_alarm_any"]["ok"]) for f, v in fw.items()},
        "level_for_goal": level_for_goal(runs, families),
        "power_curves": power_curves(runs),
        "power_tables_per_size": power,
        "families": families,
        "n_clean_per_family": n_clean,
        "n_planted_per_family_and_artifact": n_planted,
        "alpha": alpha,
        "effect_sizes": {k: {kk: vv * effect_scale for kk, vv in v.items()} for k, v in EFFECT_SIZES.items()},
        "effect_scale": effect_scale,
        "planted_schedules": PLANTED_SCHEDULES,
        "schedules": sorted(synthetic.SCHEDULES),
        "tolerance": tolerance,
        "goals": GOALS,
        "summary": summary,
        "goals_met": goals_met(summary),
        "seconds_per_table_wall": (time.perf_counter() - t0) / len(cases),
        "cpu_seconds_main_process": time.process_time() - c0,
        "n_tables": len(cases),
        "runs": runs,
    }
    if calibration_tables:
        calibrate_alarms(result, calibration_tables, jobs)
    return result


def _false_alarm_columns(fa: dict) -> dict:
    """The false-alarm columns of a bench row from a count record ``{n, k, rate, ci95}``: tables,
    alarms, rate, its 95 % interval and its one-sided 95 % upper bound (:func:`upper_bound`)."""
    return {
        "n_clean": fa["n"],
        "false_alarms": fa["k"],
        "false_alarm_rate": fa["rate"],
        "false_alarm_ci_low": fa["ci95"][0],
        "false_alarm_ci_high": fa["ci95"][1],
        "false_alarm_upper_95": upper_bound(fa["k"], fa["n"]),
    }


def _detection_columns(d: dict, lower_95: float | None) -> dict:
    """The detection columns of a bench row from a count record ``{n, k, rate, ci95}`` and its
    one-sided 95 % lower bound."""
    return {
        "n_planted": d["n"],
        "detected": d["k"],
        "detection_rate": d["rate"],
        "detection_ci_low": d["ci95"][0],
        "detection_ci_high": d["ci95"][1],
        "detection_lower_95": lower_95,
    }


def bench_table(result: dict) -> pd.DataFrame:
    """One row per artifact and family (and ``all``): configuration, effect size, detection
    and false-alarm counts, rates, 95 % intervals and one-sided 95 % bounds (a detection rate's
    lower, a false-alarm rate's upper); the family-wise false alarms as artifact ``any`` (at the
    nominal level) and ``any, calibrated on the table`` (the complete procedure,
    :func:`calibrate_alarms`, where it was run), and the detections recounted with the
    calibrated level as ``<artifact>, calibrated on the table`` (with ``detected_nominal``:
    those tables' detections at the nominal level)."""
    rows = []
    conf = result.get("configuration", "random")
    for fam, v in result["family_wise"].items():
        fa = v["false_alarm_any"]
        rows.append(
            {
                "configuration": conf,
                "artifact": "any",
                "family": fam,
                "effect_size": "",
                **_false_alarm_columns(fa),
            }
        )
        if "false_alarm_any_calibrated" in v:
            fa = v["false_alarm_any_calibrated"]
            rows.append(
                {
                    "configuration": conf,
                    "artifact": "any, calibrated on the table",
                    "family": fam,
                    "effect_size": "",
                    **_false_alarm_columns(fa),
                }
            )
    for name, per in result.get("detection_calibrated", {}).items():
        size = "; ".join(f"{k} = {v:g}" for k, v in result["effect_sizes"][name].items())
        for fam, r in per.items():
            d = r["calibrated"]
            rows.append(
                {
                    "configuration": conf,
                    "artifact": f"{name}, calibrated on the table",
                    "family": fam,
                    "effect_size": size,
                    **_detection_columns(d, r["calibrated_lower_95"]),
                    "detected_nominal": r["nominal"]["k"],
                }
            )
    for name, per in result["summary"].items():
        size = "; ".join(f"{k} = {v:g}" for k, v in result["effect_sizes"][name].items())
        for fam, r in per.items():
            d, fa, x = r["detection"], r["false_alarm"], r["cross_talk"]
            if d["n"] == 0 and fa["n"] == 0:
                continue  # not testable in this configuration
            rows.append(
                {
                    "configuration": conf,
                    "artifact": name,
                    "family": fam,
                    "effect_size": size,
                    **_detection_columns(d, lower_bound(d["k"], d["n"])),
                    **_false_alarm_columns(fa),
                    "n_other_planted": x["n"],
                    "cross_talk": x["k"],
                    "cross_talk_rate": x["rate"],
                }
            )
    return pd.DataFrame(rows)


def power_table(result: dict) -> pd.DataFrame:
    """One row per artifact and planted size of the power curves: configuration, size and its
    key, tables, detected, rate and its 95 % interval, estimates within tolerance."""
    rows = []
    for name, pc in result.get("power_curves", {}).items():
        for r in pc["curve"]:
            d, e = r["detection"], r["estimate_within_tolerance"]
            rows.append(
                {
                    "configuration": result.get("configuration", "random"),
                    "artifact": name,
                    "size_key": r["size_key"],
                    "size": r["size"],
                    "n": d["n"],
                    "detected": d["k"],
                    "detection_rate": d["rate"],
                    "detection_ci_low": d["ci95"][0],
                    "detection_ci_high": d["ci95"][1],
                    "detection_lower_95": r.get("detection_lower_95", lower_bound(d["k"], d["n"])),
                    "estimate_ok": e["k"],
                    "size_95": pc["size_95"],
                    "size_95_point": pc.get("size_95_point"),
                }
            )
    return pd.DataFrame(rows)
