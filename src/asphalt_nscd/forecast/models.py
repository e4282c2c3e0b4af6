"""The forecast's inputs read once and its models assembled: binders, curves, DEM responses, model set.

One place for what every forecast command reads: the matched table's binders as points
(:func:`binder_points`), the binder master curves (JSON of ``forecast-binders``), the DEM
responses of the mixes' samples (``forecast-response``), and the set of models a run scores
(:func:`model_set`): each published formula with its published and recalibrated coefficients
(:class:`.validation.Baseline`), then the discrete models (:class:`.dem.DemModel`) when their
responses are given, then the learned yardstick (:class:`.learned.GradientBoosting`). Model labels
(:func:`label`): ``hirsch_published``, ``hirsch_recalibrated``, ..., ``dem``, ``dem_extended``,
``gradient_boosting_learned``.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..io import InputError


def label(model) -> str:
    """The model's name in tables: ``<formula>_<coefficients>`` or the DEM model's name."""
    from .validation import model_label

    return model_label(model)


def binder_points(matched: pd.DataFrame, binder_of_mix: pd.Series) -> pd.DataFrame:
    """One row per (binder, temperature, frequency): columns ``binder, temperature_C,
    frequency_Hz, G_Pa, delta_deg, eta_Pa_s`` and ``mixes`` (the mixes that use the binder),
    from the first mix of each binder (mixes of one binder carry identical columns); the
    frequency is the one the binder was tested at (``binder_frequency_Hz``)."""
    b = matched["mix_id"].map(binder_of_mix)
    first = matched.groupby(b, sort=True)["mix_id"].first()
    rows = matched[matched["mix_id"].isin(first.to_numpy())]
    mixes = matched.groupby(b)["mix_id"].unique().map(lambda m: " ".join(sorted(map(str, m))))
    out = pd.DataFrame(
        {
            "binder": rows["mix_id"].map(binder_of_mix).to_numpy(),
            "temperature_C": rows["temperature_C"].to_numpy(float),
            "frequency_Hz": rows["binder_frequency_Hz"].to_numpy(float),
            "G_Pa": rows["binder_G_MPa"].to_numpy(float) * 1e6,
            "delta_deg": rows["binder_delta_deg"].to_numpy(float),
            "eta_Pa_s": rows["binder_eta_Pa_s"].to_numpy(float),
        }
    )
    out["mixes"] = out["binder"].map(mixes)
    return out.sort_values(["binder", "temperature_C", "frequency_Hz"]).reset_index(drop=True)


def read_curves(path) -> dict:
    """binder id -> :class:`.binder.BinderCurve` from the JSON of ``forecast-binders``.

    Raises InputError naming the file when it is not such a file."""
    from ..io import read_json
    from .binder import BinderCurve

    data = read_json(path, what="binder master curves JSON")
    try:
        fields = set(BinderCurve.__dataclass_fields__)
        return {
            b: BinderCurve.from_dict({k: v for k, v in c.items() if k in fields}) for b, c in data["curves"].items()
        }
    except (KeyError, TypeError, AttributeError) as exc:
        raise InputError(f"{path}: not a binder-curve file of 'forecast-binders' ({exc})") from None


def read_responses(paths) -> dict:
    """mix_id -> list of :class:`.dem.Response` (one per seed and sample variant) from response files."""
    from .dem import Response

    out: dict[str, list] = {}
    for p in paths:
        r = Response.load(Path(p))
        out.setdefault(r.mix_id, []).append(r)
    return out


def by_variant(responses: dict) -> dict:
    """variant -> (mix_id -> responses of that sample variant): "" the base sample, else
    :func:`.formulation.variant_name` (:attr:`.dem.Response.variant`)."""
    out: dict = {}
    for mix, rs in responses.items():
        for r in rs:
            out.setdefault(r.variant, {}).setdefault(mix, []).append(r)
    return out


def model_set(forecast_cfg: dict, responses: dict | None) -> list:
    """The models a run scores: every baseline of ``forecast.baselines`` with published and
    recalibrated coefficients, then ``forecast.dem.models`` when ``responses`` are given, then
    the learned models of ``forecast.learned`` (:mod:`.learned`).

    The discrete models read the base sample's responses; ``dem_selected`` chooses among the
    ladder on the base sample and on every sample variant of ``forecast.dem.variants``
    (:func:`.formulation.sample_variants`) whose responses are given, labelled
    ``<step>@<variant>``. Raises InputError when a response's variant is not configured."""
    from .dem import DemModel
    from .validation import COEFFICIENTS, Baseline

    from .nested import Selected
    from .physical import BondPhysics, PhysicalDem

    models: list = [Baseline(m, c) for m in forecast_cfg.get("baselines", []) for c in COEFFICIENTS]
    if responses:
        from .formulation import sample_variants

        dem = forecast_cfg.get("dem") or {}
        split = by_variant(responses)
        configured = sample_variants(dem)
        unknown = sorted(set(split) - set(configured) - {""})
        if unknown:
            raise InputError(
                f"DEM responses of sample variants {unknown} not in forecast.dem.variants {list(configured)}"
            )
        base = split.get("", {})
        legacy = [DemModel(name, base, dem["cut_mm"]) for name in dem.get("models", [])]
        physics = BondPhysics.from_config(dem)
        ladder = [PhysicalDem(name, base, dem["cut_mm"], physics=physics) for name in dem.get("physical", [])]
        models += legacy + ladder
        if dem.get("selected") and ladder:
            # inside the choice every candidate is fitted from the middle of its ranges (one start: its cost),
            # on the base sample and on every variant prepared
            inner = [PhysicalDem(m.model, base, dem["cut_mm"], starts=1, physics=physics) for m in ladder]
            for name, (cut, _) in configured.items():
                if name in split:
                    inner += [
                        PhysicalDem(m.model, split[name], cut, starts=1, variant=name, physics=physics) for m in ladder
                    ]
            # the legacy models (constants outside their physical ranges) are scored beside, not chosen from
            rule = dem.get("selection_rule", "best")
            models.append(Selected("dem_selected", inner, dem.get("inner_folds", 5), forecast_cfg.get("seed", 1), rule))
    # the learned yardstick (forecast.learned): gradient-boosted trees on the formulas' inputs (:mod:`.learned`)
    if forecast_cfg.get("learned"):
        from .learned import MODELS as LEARNED

        models += [LEARNED[name](grid=forecast_cfg.get("learned_grid")) for name in forecast_cfg["learned"]]
    return models


def headline_only(model) -> bool:
    """Whether a model is scored on the headline binder route only (the physical ladder and the
    choice inside the fold: their nested fits are the run's largest cost)."""
    from .nested import Selected
    from .physical import PhysicalDem

    return isinstance(model, (PhysicalDem, Selected))


def routed_tables(matched: pd.DataFrame, curves: dict, binder_of_mix: pd.Series, routes) -> dict:
    """route -> the matched table with its binder columns as that route reads them
    (:func:`.validation.with_binder_route`)."""
    from .validation import with_binder_route

    return {route: with_binder_route(matched, curves, binder_of_mix, route) for route in routes}


def run_forecast_inputs(run) -> tuple[pd.DataFrame, dict]:
    """A finished run's forecast inputs: its matched table with the binder through its master curve (rows
    with a measured |E*| and phase angle) and its samples' responses (mix_id -> list of
    :class:`.dem.Response`), from ``<run>/results/forecast/`` (``matched.csv``, ``binder_curves.json``,
    ``responses/*.npz``). Raises InputError naming a file that is missing or malformed."""
    from pathlib import Path

    from ..lab.matched import read_matched
    from .validation import binder_ids

    f = Path(run) / "results" / "forecast"
    matched = read_matched(f / "matched.csv")
    table = routed_tables(matched, read_curves(f / "binder_curves.json"), binder_ids(matched), ["curve"])["curve"]
    table = table.dropna(subset=["E_norm_MPa", "phase_deg"]).reset_index(drop=True)
    return table, read_responses(sorted((f / "responses").glob("*.npz")))
