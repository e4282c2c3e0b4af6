"""The ``sample`` configuration section: paper defaults, loading, and the ``scale`` rule.

Scaling (``scale`` = s, a linear factor; paper: 1)
--------------------------------------------------
A sample of the paper has ~14 000 spheres; the default and smoke runs need a few hundred.
With the PSD kept, the number of spheres is fixed by the ratio thickness / largest
diameter alone (N ~ 14 000 (e / 2.5 d_max)^3), so a few hundred spheres cannot keep the
full PSD in a trapezoid at least one large sphere thick. Two keys therefore act together:

* ``scale`` multiplies every length of the *specimen and layer*: B, b, e, h, the box
  footprint (h x e) and the layer height; the sample mass and the top-plate mass are
  multiplied by s^3 (same density). Sphere diameters, the lattice cell, the box height, the
  vibration amplitude and gravity are *not* scaled. Downstream steps must read the specimen
  dimensions and the plate mass from the sample file (root attributes ``B_m, b_m, e_m, h_m``
  and ``plates/mass``), not from the paper.
* ``psd.cut_mm`` raises the PSD cut (paper: 2 mm): more of the fines go to the mastic, the
  kept classes are renormalised, and ``d_min`` (bond gap threshold) becomes the new smallest
  diameter.

Counts in the deposited layer are ~ 14 200 s^3 at cut 2 mm, ~ 1 280 s^3 at 6.3 mm and
~ 790 s^3 at 8 mm; the trapezoid keeps about 2/3 of them.
"""

from __future__ import annotations

import copy
from pathlib import Path

from ..io import InputError

#: The paper's full-scale sample (Section 3.2.1) for every key: the ``sample`` section of
#: config/config.yaml with the paper's values of ``scale`` (1), ``psd.cut_mm`` (2 mm),
#: ``vibration.duration_s`` (1 s) and ``solver.tolerance`` (1e-4, as config/paper.yaml);
#: tests/unit/test_config.py checks that relation. The values of prepare-sample without a
#: config and of a bare sample section; a workflow config's section is merged over them.
DEFAULTS: dict = {
    "seeds": [1, 2, 3, 4],
    "scale": 1.0,
    "specimen": {"B_mm": 56.0, "b_mm": 25.0, "e_mm": 25.0, "h_mm": 250.0},
    "psd": {"cut_mm": 2.0, "class_diameter": "lower", "solid_fraction": 0.70, "layer_height_mm": 60.0},
    "layer_height": {"measure": "surface", "cell_mm": 5.0},
    "box_height_mm": 1600.0,
    "lattice_mm": 10.0,
    "density_deposition_kg_m3": 2600.0,
    "gravity_m_s2": 9.81,
    "friction_deposition": 0.2,
    "deposition": {"time_step_s": 2.0e-4, "duration_s": 1.0, "settle_velocity_m_s": 0.01, "rest_measure": "max"},
    "vibration": {
        "form": "tap",
        "amplitude_mm": 6.0,
        "frequency_Hz": 30.0,
        "duration_s": 1.0,
        "time_step_s": 2.0e-4,
        "settle_duration_s": 0.1,
    },
    "shrink_volume_fraction": 0.10,
    "sample_mass_kg": 0.6,
    "top_plate_mass_kg": 0.235,
    "bond_gap_mm": None,
    "friction_bonded": 0.7,
    "stabilisation": {
        "steps": 1000,
        "time_step_s": 5.0e-5,
        "Em_Pa": 2.43e7,
        "eta_m_Pa_s": 3.71e6,
        "Ek_Pa": 4.84e7,
        "eta_k_Pa_s": 7.73e5,
    },
    "solver": {"tolerance": 1.0e-4, "max_iterations": 200},
}


def merge(defaults: dict, given: dict, where: str = "sample") -> dict:
    """Deep-merge ``given`` over ``defaults``; unknown keys raise InputError naming the key."""
    out = copy.deepcopy(defaults)
    for key, value in given.items():
        if key not in defaults:
            raise InputError(f"{where}: unknown key {key!r}; expected one of {sorted(defaults)}")
        if isinstance(defaults[key], dict):
            if not isinstance(value, dict):
                raise InputError(f"{where}.{key}: expected a mapping, got {value!r}")
            out[key] = merge(defaults[key], value, f"{where}.{key}")
        else:
            out[key] = value
    return out


def level_name(scale: float, cut_mm: float) -> str:
    """Name of a resolution level (config ``harmonic.resolution.levels``): ``x{scale}_cut{cut}``
    (``:g``), e.g. x0.7_cut6.3."""
    return f"x{float(scale):g}_cut{float(cut_mm):g}"


def workflow_config(paths) -> dict | None:
    """The whole workflow configuration of the files ``paths`` (merged over config/config.yaml
    of the working directory and checked against the workflow's schemas,
    :func:`asphalt_nscd.config.checked`), or None when ``paths`` is a single file holding a
    bare sample section (no top-level key among :data:`asphalt_nscd.config.SECTIONS`).

    Raises
    ------
    InputError
        naming the file (missing, unreadable, not a mapping) or the key the schemas refuse.
    """
    from .. import config

    paths = [paths] if isinstance(paths, (str, Path)) else list(paths)
    if len(paths) == 1 and not set(config.read(paths[0])) & set(config.SECTIONS):
        return None
    return config.checked(paths)


def load(paths, level: str | None = None) -> dict:
    """The ``sample`` section of the config files ``paths`` (one path or several, in order),
    merged over :data:`DEFAULTS`; with ``level``, the section of that resolution level (its
    ``scale`` and ``psd.cut_mm`` from ``harmonic.resolution.levels``, named by
    :func:`level_name`).

    Files holding a workflow config (a top-level key among
    :data:`asphalt_nscd.config.SECTIONS`) are merged as Snakemake merges ``--configfile``:
    config/config.yaml of the working directory first, then each file in order, and checked
    against the workflow's schemas (:func:`workflow_config`); the ``sample`` section of the
    result is taken. A single file holding the sample section alone (YAML, or JSON if named
    ``*.json``) is merged over :data:`DEFAULTS` directly.

    Raises
    ------
    InputError
        naming the file: missing, unreadable, not valid YAML/JSON, not a mapping, refused by a
        schema; or naming the key: an unknown key of the sample section, a ``level`` the
        config does not list (or given with a bare sample section).
    """
    from .. import config

    paths = [paths] if isinstance(paths, (str, Path)) else list(paths)
    names = " ".join(str(p) for p in paths)
    whole = workflow_config(paths)
    if whole is None:
        if level is not None:
            raise InputError(f"{names}: a resolution level needs a workflow config (harmonic.resolution.levels)")
        return merge(DEFAULTS, config.read(paths[0]), f"{names}: sample")
    section = whole.get("sample") or {}
    if not isinstance(section, dict):
        raise InputError(f"{names}: sample: expected a mapping of sample settings, got {section!r}")
    out = merge(DEFAULTS, section, f"{names}: sample")
    if level is not None:
        levels = {
            level_name(lv["scale"], lv["cut_mm"]): lv
            for lv in ((whole.get("harmonic") or {}).get("resolution") or {}).get("levels") or []
        }
        if level not in levels:
            raise InputError(
                f"{names}: harmonic.resolution.levels: no level {level!r}; expected one of {sorted(levels)}"
            )
        out["scale"] = float(levels[level]["scale"])
        out["psd"]["cut_mm"] = float(levels[level]["cut_mm"])
    return out


def scaled_geometry(cfg: dict) -> dict:
    """SI lengths and masses after applying ``scale`` (see module docstring).

    Returns a dict with ``B, b, e, h, layer_height`` (m), ``box`` (L, W, H in m),
    ``lattice`` (m), ``sample_mass, top_plate_mass`` (kg).
    """
    s = float(cfg["scale"])
    if not s > 0:
        raise InputError(f"sample.scale: expected > 0, got {s}")
    spec = cfg["specimen"]
    B, b, e, h = (s * spec[k] * 1e-3 for k in ("B_mm", "b_mm", "e_mm", "h_mm"))
    return {
        "B": B,
        "b": b,
        "e": e,
        "h": h,
        "layer_height": s * cfg["psd"]["layer_height_mm"] * 1e-3,
        "box": (h, e, cfg["box_height_mm"] * 1e-3),
        "lattice": cfg["lattice_mm"] * 1e-3,
        "sample_mass": s**3 * cfg["sample_mass_kg"],
        "top_plate_mass": s**3 * cfg["top_plate_mass_kg"],
    }
