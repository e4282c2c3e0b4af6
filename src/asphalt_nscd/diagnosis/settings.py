"""The diagnosis commands' options from the workflow configuration's ``diagnosis`` section.

A command of this step given ``--config`` (calibrate-search, master-curve, extend-law,
crossval, diagnose) takes its option values from the merged, checked configuration
(:func:`option_values`); an option also given on the command line wins. The workflow passes
the run's configuration file and keeps the values of each rule's groups as the rule's
``settings`` parameter (:func:`asphalt_nscd.plan.diagnosis_settings`), so a change of them, and
only of them, reruns the rule.
"""

from __future__ import annotations

from collections.abc import Mapping

#: option groups: the artifact search (every command of the step), the extended law's candidates
#: and the law a material card carries (extend-law, crossval), the search's calibration
#: (calibrate-search), the cause tolerances and the campaign's Moreau-Jean theta (diagnose), the detection
#: benchmark (diagnose-bench)
GROUPS = ("search", "law", "calibration", "causes", "bench")


def option_values(cfg: Mapping, *groups: str) -> dict:
    """Argument name (argparse ``dest``) -> value of the options of ``groups`` (default: all of
    :data:`GROUPS`), from the ``diagnosis`` section of a merged, checked workflow config, in the
    types the command line gives (floats, ``on``/``off`` for the vertical shift, ``off`` for
    no refinement).

    Raises
    ------
    KeyError
        when the section lacks a key (a config that did not pass the schemas).
    ValueError
        for a group not in :data:`GROUPS`.
    """
    unknown = sorted(set(groups) - set(GROUPS))
    if unknown:
        raise ValueError(f"unknown option group(s) {unknown}; expected some of {GROUPS}")
    groups = groups or GROUPS
    diag = cfg["diagnosis"]
    out: dict = {}
    if "search" in groups:
        ident = diag["identifiability"]
        out |= {
            "alpha": float(diag["alpha"]),
            "shift": diag["shift"],
            "t_ref": None if diag.get("T_ref_C") is None else float(diag["T_ref_C"]),
            "identifiability_null": float(ident["null"]),
            "identifiability_rival": float(ident["rival"]),
        }
    if "law" in groups:
        law, card = diag["law"], diag["material_card"]
        out |= {
            "law_shifts": list(law["shifts"]),
            "law_statics": list(law["statics"]),
            "law_verticals": ["on" if v else "off" for v in law["verticals"]],
            "law_refines": ["off" if r is None else str(float(r)) for r in law["refines"]],
            "law_per_decades": [float(v) for v in law["per_decades"]],
            "margin_decades": float(law["margin_decades"]),
            "tolerances_pct": [float(v) for v in law["tolerances_pct"]],
            "no_one_se": not law.get("one_se", True),
            "no_artifacts": not law.get("artifacts", True),
            "card_fit": card["fit"],
            "card_shift": card["shift"],
        }
    if "calibration" in groups:
        cal = diag["calibration"]
        out |= {
            "tables": int(cal["tables"]),
            "seed": int(cal["seed"]),
            "familywise_rate": float(cal["familywise_rate"]),
        }
    if "causes" in groups:
        tol = diag.get("cause_tolerances") or {}
        out |= {
            "tolerance_network_factor": float(tol.get("network_factor", 0.01)),
            "tolerance_phase_deg": float(tol.get("time_integration_deg", 0.1)),
            # the rows of a time-integration table at the campaign's own Moreau-Jean theta
            "theta": float(cfg["campaign"]["test"]["theta"]),
        }
    if "bench" in groups:
        bench = diag["bench"]
        out |= {
            "clean": int(bench["clean"]),
            "planted": int(bench["planted"]),
            "base_seed": int(bench["base_seed"]),
            "families": ",".join(bench["families"]),
            "alpha": float(diag["alpha"]),
            "configuration": bench["configuration"],
            "power": int(bench["power"]),
        }
    return out
