"""The campaign's job modes read from a workflow config: which schedule a mode runs, how it
reads the paper's Table 3, which of its jobs verify the exact periodic orbit in the time
domain, and the option values the campaign commands take from ``--config``
(:func:`config_values`).

Modes: ``paper`` (Table 3 under ``calibration.table3_units``), ``paper_Pa`` and ``paper_kPa``
(Table 3 under an explicit reading, the paper's schedule), ``measured`` (the calibrated
Burger's table, the measured schedule), ``extended`` (the diagnosis' generalized law, the
measured schedule) and the studies run beside them (``dt_study``, ``sensitivity``,
``units_<unit>[_nobreak]``).
"""

from __future__ import annotations

from collections.abc import Mapping

#: main campaign modes with numerical isotherms and a Table 4 analogue (a wildcard constraint)
ISOTHERM_MODES = ("paper", "paper_Pa", "paper_kPa", "measured", "extended")
#: modes whose law is not the paper's Table 3
OWN_LAW_MODES = ("measured", "extended")


def schedule(cfg: Mapping, mode: str) -> dict:
    """The schedule section of a main mode: ``campaign.measured`` (measured, extended) or
    ``campaign.paper`` (paper and the reading modes paper_Pa, paper_kPa):
    ``temperatures_C``, ``frequencies_Hz``."""
    return cfg["campaign"]["measured" if mode in OWN_LAW_MODES else "paper"]


def table3_reading(cfg: Mapping, mode: str) -> str | None:
    """The unit reading (``Pa`` or ``kPa``) of Table 3 in a paper-parameter mode:
    ``calibration.table3_units`` for ``paper`` and the studies run beside it (dt_study,
    sensitivity), the mode's own for ``paper_<unit>`` and ``units_<unit>[_nobreak]``; None for
    the modes with their own law (measured, extended)."""
    if mode in OWN_LAW_MODES:
        return None
    if mode.startswith(("paper_", "units_")):
        return mode.split("_")[1]
    return cfg["calibration"]["table3_units"]


def is_verification(cfg: Mapping, mode: str, T: float, f: float) -> bool:
    """Whether the main-campaign job of ``mode`` at (T degC, f Hz) is a verification job
    (``campaign.verification``: ``ends`` = the coldest and warmest temperature at the lowest
    and highest frequency of the mode's schedule; null = none): it steps in time and records
    its orbit's result beside (:func:`asphalt_nscd.campaign.twopb.run_test`)."""
    if cfg["campaign"].get("verification") != "ends" or mode not in ISOTHERM_MODES:
        return False
    sched = schedule(cfg, mode)
    temps, freqs = [float(t) for t in sched["temperatures_C"]], [float(x) for x in sched["frequencies_Hz"]]
    return float(T) in (min(temps), max(temps)) and float(f) in (min(freqs), max(freqs))


def policy_temperature(cfg: Mapping, mode: str) -> float:
    """Temperature of a mode's dt-policy phase error, degC: the upper median of its schedule."""
    temps = sorted(float(t) for t in schedule(cfg, mode)["temperatures_C"])
    return temps[len(temps) // 2]


def isotherms_title(cfg: Mapping, mode: str) -> str:
    """Title of a mode's isotherm figures (Figs. 9-10 analogues)."""
    if mode in OWN_LAW_MODES:
        return f"NSCD vs measured ({mode} mode)"
    return f"NSCD vs Table 3 Burger's read in {table3_reading(cfg, mode)} ({mode} mode)"


def config_values(cfg: Mapping, args) -> dict:
    """Option values of the campaign commands from a merged, checked workflow config
    (``--config``; an option given on the command line wins), for the job mode the command
    line names (``--mode``; ``campaign-dt-policy``: ``--settings-mode``):

    * ``run-2pb``: the Table 3 reading and, for a main-campaign job (no ``--dt``, no
      ``--factor``), whether it is a verification job (:func:`is_verification`);
    * ``campaign-isotherms``: the Table 3 reading and the figures' title;
    * ``campaign-dt-policy``: the Table 3 reading, :func:`policy_temperature` and the
      schedule's frequencies;
    * ``campaign-dt-study``, ``campaign-sensitivity``: the paper mode's Table 3 reading (and
      ``campaign.sensitivity.temperature_C``);
    * ``campaign-units``: ``campaign.units_question.temperature_C`` and the first
      representative bond of ``calibration.micro`` (grain mass, r_min, l0).

    The test settings themselves come from :func:`asphalt_nscd.campaign.twopb.job_settings`.
    """
    command = args.command
    mode = getattr(args, "settings_mode", None) if command == "campaign-dt-policy" else None
    mode = mode or getattr(args, "mode", None) or "paper"
    out: dict = {}
    if getattr(args, "law_json", None) is None:
        out["table3_units"] = table3_reading(cfg, mode)
    if command == "run-2pb" and args.dt is None and not args.factor:
        out["verify"] = is_verification(cfg, mode, args.temperature, args.frequency)
    elif command == "campaign-isotherms":
        out["title"] = isotherms_title(cfg, mode)
    elif command == "campaign-dt-policy":
        out["temperature"] = policy_temperature(cfg, mode)
        out["frequencies"] = [float(f) for f in schedule(cfg, mode)["frequencies_Hz"]]
    elif command == "campaign-sensitivity":
        out["temperature"] = float(cfg["campaign"]["sensitivity"]["temperature_C"])
    elif command == "campaign-units":
        micro = cfg["calibration"]["micro"]
        out |= {
            "temperature": float(cfg["campaign"]["units_question"]["temperature_C"]),
            "grain_mass_kg": float(micro["grain_mass_kg"]),
            "r_min_mm": float(micro["r_min_mm"][0]),
            "l0_mm": float(micro["l0_mm"][0]),
        }
    return out
