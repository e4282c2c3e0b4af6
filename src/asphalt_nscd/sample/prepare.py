"""Preparation of one numerical sample (paper Section 3.2.1).

:func:`prepare_sample` runs the stages, :func:`write_outputs` writes the sample file:

1. spheres: class counts from the PSD cut at ``psd.cut_mm`` (:mod:`.psd`) for the layer of
   the (scaled) box, density 2600 kg/m^3 (:func:`sphere_population`);
2. random placement on the cubic lattice of the box (:func:`.geometry.lattice_positions`);
3. deposition under gravity in the six-plate box, friction 0.2, until the largest speed is
   below ``deposition.settle_velocity_m_s`` or ``deposition.duration_s`` has elapsed;
4. vibration of the top wall (A = 6 mm, f = 30 Hz, 1 s; ``vibration.form``), then settling;
5. cut: spheres whose barycentre lies outside the trapezoid (length h, thickness e) centred
   on the layer mid-height (``layer_height.measure``, :func:`.geometry.layer_height`) are
   removed; flip to the specimen frame (z up along h, x the bending direction);
6. plates: bottom plate at z = 0 (fixed), head at z = h (free, 0.235 kg x scale^3); gravity -z;
7. shrink every sphere by 10 % of its volume, then set the density so that the sample mass is
   0.6 kg x scale^3 (paper: 3415 kg/m^3);
8. bonds for every sphere-sphere and sphere-plate gap below d_min (the smallest class
   diameter, or ``bond_gap_mm``), reference state the shrunk one (docs/design.md);
9. stabilisation: ``stabilisation.steps`` steps (paper: 1000) under gravity, friction 0.7, a
   Burger's law (default Table 3 at 15 degC read in Pa); the file stores these positions.

The sample file is temperature independent: the campaign creates the bond laws of each
temperature from ``delta0, l0, r_min``. Choices (docs/choices.md, Samples): ``vibration.form``
``tap`` or ``sine``, ``layer_height.measure`` ``surface`` or ``max``, ``nscd.bonded_contact``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

import logging

from ..io import InputError
from . import geometry, psd, settings
from .store import SampleData, write_bonds_vtu, write_sample, write_vtu

if TYPE_CHECKING:
    import pandas

#: A contact, for the coordination number, is a surface gap below this fraction of d_min.
CONTACT_TOLERANCE = 0.01

log = logging.getLogger(__name__)


class _PhaseClock:
    """Wall-clock and process CPU time of the preparation phases (s), lap by lap."""

    def __init__(self):
        self._wall = [time.perf_counter()]
        self._cpu = [time.process_time()]
        self.names = []

    def lap(self, name: str) -> None:
        self.names.append(name)
        self._wall.append(time.perf_counter())
        self._cpu.append(time.process_time())

    def _table(self, t) -> dict:
        out = {f"{n}_s": t[k + 1] - t[k] for k, n in enumerate(self.names)}
        out["total_s"] = t[-1] - t[0]
        return out

    def wall(self) -> dict:
        return self._table(self._wall)

    def cpu(self) -> dict:
        return self._table(self._cpu)


@dataclass
class PreparedSample:
    """Result of :func:`prepare_sample`: the sample, the stage snapshots and the summary."""

    sample: SampleData
    stages: list  # dicts: title, frame, position (N, 3), radius (N,)
    summary: dict
    trapezoid: geometry.Trapezoid


def sphere_population(cfg: dict, passing: dict | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Class diameters (m), counts in the layer, and the solid volume (m^3) for a config.

    ``passing``: sieve opening (mm) -> % passing of the aggregate to sample (a mix's own
    gradation, :mod:`asphalt_nscd.forecast.formulation`); None: the paper's Table 1.

    Raises
    ------
    InputError
        if the PSD keys are inconsistent.
    """
    geo = settings.scaled_geometry(cfg)
    p = cfg["psd"]
    try:
        d, frac = psd.class_fractions(passing, cut_mm=p["cut_mm"], class_diameter=p["class_diameter"])
        volume = p["solid_fraction"] * geo["box"][0] * geo["box"][1] * geo["layer_height"]
        counts = psd.sphere_counts(volume, d, frac)
    except ValueError as exc:
        raise InputError(f"sample.psd: {exc}") from exc
    return d, counts, volume


def counts_table(cfg: dict, summaries=()) -> pandas.DataFrame:
    """Counts per diameter: paper (Table 2), our rule at full scale (scale 1, cut 2 mm),
    this configuration's layer, and the mean inside the prepared samples.

    Columns ``diameter_mm, n_paper, n_rule_full_scale, rel_diff_pct, n_config_layer,
    n_sample_mean``.
    """
    import json

    full = settings.merge(settings.DEFAULTS, {"psd": {**cfg["psd"], "cut_mm": 2.0}, "scale": 1.0})
    d_full, n_full, _ = sphere_population(full)
    table = psd.table2_comparison(d_full, n_full).rename(columns={"n_ours": "n_rule_full_scale"})
    d_cfg, n_cfg, _ = sphere_population(cfg)
    layer = {round(float(d) * 1e3, 3): int(n) for d, n in zip(d_cfg, n_cfg)}
    table["n_config_layer"] = [layer.get(d, 0) for d in table["diameter_mm"]]
    per_sample = []
    for path in summaries:
        try:
            data = json.loads(Path(path).read_text())
            per_sample.append({float(k): v for k, v in data["counts_sample"].items()})
        except (OSError, ValueError, KeyError) as exc:
            raise InputError(f"{path}: not a sample summary with 'counts_sample' ({exc})") from exc
    if per_sample:
        table["n_sample_mean"] = [np.mean([c.get(d, 0) for c in per_sample]) for d in table["diameter_mm"]]
    first = ["diameter_mm", "n_paper", "n_rule_full_scale", "rel_diff_pct"]
    return table[first + [c for c in table.columns if c not in first]]


@dataclass
class Packing:
    """The vibrated layer of stages 1-4 (:func:`pack`), before the cut: what a preparation
    spends its time on, and all that depends on the seed.

    ``position`` (N, 3) m and ``radius`` (N,) m in the deposition frame; ``d_class`` (K,) m and
    ``counts`` (K,) the sphere classes; ``summary`` the layer's entries of the sample summary.
    """

    position: np.ndarray
    radius: np.ndarray
    d_class: np.ndarray
    counts: np.ndarray
    stages: list
    summary: dict
    clock: _PhaseClock


def prepare_sample(
    cfg: dict,
    seed: int,
    bonded_contact: str | None = None,
    passing: dict | None = None,
    solid_fraction: float | None = None,
) -> PreparedSample:
    """Run stages 1-9 for one seed (see module docstring): :func:`pack`, then :func:`finish`.

    Parameters
    ----------
    cfg
        sample section merged over :data:`.settings.DEFAULTS`.
    seed
        seed of the lattice placement (the only random step).
    bonded_contact
        contact of the bonded pairs during the stabilisation (config ``nscd.bonded_contact``,
        NSCDParameters); None: the core's default.
    passing
        % passing per sieve (mm) of the aggregate; None: the paper's Table 1 (:func:`sphere_population`).
    solid_fraction
        sphere volume / specimen volume after the shrink (stage 7); None: the paper's shrink by
        ``shrink_volume_fraction`` of each sphere's volume (:func:`finish`).

    Returns
    -------
    PreparedSample

    Raises
    ------
    InputError
        if the box cannot hold the spheres, or the cut leaves no sphere.
    """
    return finish(pack(cfg, seed, passing), cfg, seed, bonded_contact, solid_fraction)


def pack(cfg: dict, seed: int, passing: dict | None = None) -> Packing:
    """Stages 1-4 for one seed: sphere classes, lattice, deposition, vibration (module docstring).

    Raises
    ------
    InputError
        if the box cannot hold the spheres or the layer height cannot be measured.
    """
    from . import dynamics

    clock = _PhaseClock()
    geo = settings.scaled_geometry(cfg)
    rng = np.random.default_rng(seed)
    d_class, counts, _ = sphere_population(cfg, passing)
    radius = np.repeat(0.5 * d_class, counts)
    try:
        position = geometry.lattice_positions(radius, geo["box"], geo["lattice"], rng)
    except ValueError as exc:
        raise InputError(f"sample (box_height_mm / lattice_mm / scale): {exc}") from exc
    stages = []
    clock.lap("lattice")
    log.info(
        "sample s%d: %d spheres on the lattice of a %.0f x %.0f x %.0f mm box",
        seed,
        radius.size,
        *(1e3 * np.asarray(geo["box"])),
    )

    position, dep_info = dynamics.deposit(position, radius, cfg, geo)
    clock.lap("deposition")
    stages.append(
        {
            "title": "deposit by gravity",
            "frame": "deposition",
            "position": position,
            "radius": radius,
            "length": geo["box"][0],
        }
    )
    footprint = geo["box"][:2]
    lh = cfg["layer_height"]
    try:
        h_deposit = geometry.layer_height(position, radius, footprint, lh["measure"], lh["cell_mm"] * 1e-3)
    except ValueError as exc:
        raise InputError(f"sample.layer_height: {exc}") from exc
    top_deposit = geometry.layer_top(position, radius)

    position, vib_info = dynamics.vibrate(position, radius, cfg, geo)
    clock.lap("vibration")  # shaking and settling: vibration.{shaking,settling}.cpu_s split it
    h_layer = geometry.layer_height(position, radius, footprint, lh["measure"], lh["cell_mm"] * 1e-3)
    h_surface = geometry.layer_height(position, radius, footprint, "surface", lh["cell_mm"] * 1e-3)
    log.info(
        "layer after deposition %.1f mm, after vibration %.1f mm (%s)", h_deposit * 1e3, h_layer * 1e3, lh["measure"]
    )
    z_mid, phi_slices = geometry.solid_fraction_profile(position, radius, h_surface, footprint)
    bulk = (z_mid > 0.2 * h_surface) & (z_mid < 0.8 * h_surface)
    stages.append(
        {
            "title": "after vibration of the top wall",
            "frame": "deposition",
            "position": position,
            "radius": radius,
            "length": geo["box"][0],
        }
    )
    summary = {
        "seed": int(seed),
        "n_spheres_layer": int(radius.size),
        "layer_height_measure": lh["measure"],
        "layer_height_after_deposition_mm": h_deposit * 1e3,
        "layer_height_after_vibration_mm": h_layer * 1e3,
        "layer_top_after_deposition_mm": top_deposit * 1e3,
        "layer_top_after_vibration_mm": geometry.layer_top(position, radius) * 1e3,
        "layer_surface_after_vibration_mm": h_surface * 1e3,
        "solid_fraction_layer": float(geometry.sphere_volume(radius).sum() / (footprint[0] * footprint[1] * h_surface)),
        "solid_fraction_bulk": float(np.mean(phi_slices[bulk])) if bulk.any() else float("nan"),
        "max_overlap_after_vibration_mm": geometry.max_overlap(position, radius) * 1e3,
        "deposition": dep_info,
        "vibration": vib_info,
    }
    return Packing(position, radius, d_class, counts, stages, summary, clock)


def save_packing(path, packing: Packing) -> None:
    """Write a :class:`Packing` (its arrays and summary; not its stage snapshots) to an ``.npz``
    file, atomically: a preparation's costly part, kept so that :func:`finish` can be rerun."""
    import json

    from ..io import atomic_path

    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(
                fh,
                position=packing.position,
                radius=packing.radius,
                d_class=packing.d_class,
                counts=packing.counts,
                summary=np.array(json.dumps(packing.summary)),
            )


def load_packing(path) -> Packing:
    """Read a packing written by :func:`save_packing` (stage snapshots: the vibrated layer only).

    Raises InputError naming the file when it is missing or not a packing."""
    import json

    try:
        with np.load(path) as data:
            arrays = {k: data[k] for k in ("position", "radius", "d_class", "counts")}
            summary = json.loads(str(data["summary"]))
    except (OSError, KeyError, ValueError) as exc:
        raise InputError(f"{path}: not a packing file of 'forecast-pack' ({exc})") from None
    n = arrays["radius"].shape[0]
    if arrays["position"].shape != (n, 3) or arrays["d_class"].shape != arrays["counts"].shape:
        raise InputError(f"{path}: inconsistent packing arrays (positions {arrays['position'].shape}, {n} radii)")
    stage = {"title": "after vibration of the top wall", "frame": "deposition", **arrays}
    clock = _PhaseClock()
    return Packing(arrays["position"], arrays["radius"], arrays["d_class"], arrays["counts"], [stage], summary, clock)


def finish(
    packing: Packing,
    cfg: dict,
    seed: int,
    bonded_contact: str | None = None,
    solid_fraction: float | None = None,
) -> PreparedSample:
    """Stages 5-9 on a :func:`pack` layer: cut, flip, plates, shrink, bonds, stabilisation.

    ``solid_fraction``: shrink every sphere by one factor so that the spheres fill this fraction
    of the specimen (a mix's own coarse-aggregate volume, :mod:`asphalt_nscd.forecast.formulation`),
    but at least by the paper's ``shrink_volume_fraction`` of their volume (a target above what
    that leaves takes the paper's shrink); None: the paper's shrink.

    Raises
    ------
    InputError
        if the cut leaves no sphere, or ``solid_fraction`` is not in (0, 1).
    """
    from . import dynamics

    clock, stages = packing.clock, list(packing.stages)
    position, radius, d_class, counts = packing.position, packing.radius, packing.d_class, packing.counts
    geo = settings.scaled_geometry(cfg)
    trap = geometry.Trapezoid(B=geo["B"], b=geo["b"], e=geo["e"], h=geo["h"])
    d_min = cfg["bond_gap_mm"] * 1e-3 if cfg["bond_gap_mm"] is not None else float(d_class.min())
    h_layer = packing.summary["layer_height_after_vibration_mm"] * 1e-3

    # Stage 5: cut by barycentre, flip.
    zc = 0.5 * max(h_layer, trap.B)
    spec = geometry.to_specimen_frame(position, zc, geo["box"][1])
    inside = trap.contains(spec)
    if not inside.any():
        raise InputError("sample: no sphere left inside the trapezoid after the cut")
    spec, r_cut = spec[inside], radius[inside]
    log.info("cut to the trapezoid: %d spheres", int(inside.sum()))
    coordination = geometry.coordination_number(spec, r_cut, CONTACT_TOLERANCE * d_min)
    porosity_cut = 1.0 - geometry.sphere_volume(r_cut).sum() / trap.volume
    clock.lap("cut_flip")

    # Stages 6-8: plates, shrink, density, bonds.
    if solid_fraction is None:
        r_final = geometry.shrink_radii(r_cut, cfg["shrink_volume_fraction"])
    else:
        if not 0.0 < solid_fraction < 1.0:
            raise InputError(f"sample: solid fraction after the shrink {solid_fraction!r}; expected a number in (0, 1)")
        paper = (1.0 - cfg["shrink_volume_fraction"]) ** (1.0 / 3.0)
        r_final = r_cut * min(paper, (solid_fraction / (1.0 - porosity_cut)) ** (1.0 / 3.0))
    density = geometry.density_for_mass(r_final, geo["sample_mass"])
    mass = density * geometry.sphere_volume(r_final)
    plate_point = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, trap.h]])
    plate_normal = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    plate_mass = np.array([np.inf, geo["top_plate_mass"]])
    clock.lap("plates_shrink")
    bonds = geometry.make_bonds(spec, r_final, plate_point, plate_normal, d_min)
    clock.lap("bonds")

    # Stage 9: stabilisation.
    stab_position, stab_info = dynamics.stabilise(
        spec, r_final, mass, plate_point, plate_normal, plate_mass, bonds, cfg, bonded_contact=bonded_contact
    )
    clock.lap("stabilisation")
    stages.append(
        {
            "title": "sample after cut, flip, shrink and stabilisation",
            "frame": "specimen",
            "position": stab_position,
            "radius": r_final,
        }
    )

    attrs = {
        "seed": int(seed),
        "scale": float(cfg["scale"]),
        "density_kg_m3": density,
        "friction": float(cfg["friction_bonded"]),
        "d_min_m": d_min,
        "config": {k: v for k, v in cfg.items() if k != "seeds"},
        "stage": "final",
        "B_m": trap.B,
        "b_m": trap.b,
        "e_m": trap.e,
        "h_m": trap.h,
        "n_spheres": int(r_final.size),
    }
    sample = SampleData(
        position=stab_position,
        radius=r_final,
        mass=mass,
        plate_point=plate_point,
        plate_normal=plate_normal,
        plate_mass=plate_mass,
        bonds=bonds,
        attrs=attrs,
    )
    n = r_final.size
    n_ss = int(np.sum(bonds["j"] >= 0))
    d_cut_mm = np.round(2e3 * r_cut, 3)
    summary = {
        "seed": int(seed),
        "scale": float(cfg["scale"]),
        "psd_cut_mm": float(cfg["psd"]["cut_mm"]),
        "counts_layer": {f"{d * 1e3:g}": int(c) for d, c in zip(d_class, counts)},
        "counts_sample": {f"{d * 1e3:g}": int(np.sum(d_cut_mm == round(d * 1e3, 3))) for d in d_class},
        "n_spheres_layer": packing.summary["n_spheres_layer"],
        "n_spheres": int(n),
        "trapezoid_mm": {"B": trap.B * 1e3, "b": trap.b * 1e3, "e": trap.e * 1e3, "h": trap.h * 1e3},
        **{k: packing.summary[k] for k in _LAYER_KEYS},
        "trapezoid_centre_height_mm": zc * 1e3,
        "porosity_before_shrink": porosity_cut,
        "porosity": 1.0 - geometry.sphere_volume(r_final).sum() / trap.volume,
        "coordination_number": coordination,
        "contact_tolerance_mm": CONTACT_TOLERANCE * d_min * 1e3,
        "max_overlap_after_vibration_mm": packing.summary["max_overlap_after_vibration_mm"],
        "n_bonds": int(bonds["i"].size),
        "n_bonds_sphere_sphere": n_ss,
        "n_bonds_bottom_plate": int(np.sum(bonds["j"] == -1)),
        "n_bonds_top_plate": int(np.sum(bonds["j"] == -2)),
        "bonds_per_sphere": 2.0 * n_ss / n,
        "d_min_mm": d_min * 1e3,
        "density_deposition_kg_m3": float(cfg["density_deposition_kg_m3"]),
        "density_kg_m3": density,
        "sample_mass_kg": float(mass.sum()),
        "top_plate_mass_kg": float(geo["top_plate_mass"]),
        "deposition": packing.summary["deposition"],
        "vibration": packing.summary["vibration"],
        "stabilisation": stab_info,
        "timings_s": clock.wall(),
        "cpu_s": clock.cpu(),
    }
    if solid_fraction is not None:  # the shrink to a target: its radius factor, for the contacts of the packing
        factor = float(np.max(r_final / r_cut))
        summary["shrink_radius_factor"] = sample.attrs["shrink_radius_factor"] = factor
    return PreparedSample(sample=sample, stages=stages, summary=summary, trapezoid=trap)


#: entries of the sample summary that describe the layer (:func:`pack`), in the summary's order
_LAYER_KEYS = (
    "layer_height_measure",
    "layer_height_after_deposition_mm",
    "layer_height_after_vibration_mm",
    "layer_top_after_deposition_mm",
    "layer_top_after_vibration_mm",
    "layer_surface_after_vibration_mm",
    "solid_fraction_layer",
    "solid_fraction_bulk",
)


def write_outputs(result: PreparedSample, path, vtk_dir=None) -> None:
    """Write the sample file and, if ``vtk_dir`` is given, one VTU per stage plus the bonds."""
    write_sample(path, result.sample)
    if vtk_dir is not None:
        vtk_dir = Path(vtk_dir)
        vtk_dir.mkdir(parents=True, exist_ok=True)
        names = ["stage_a_deposit", "stage_b_vibrated", "stage_c_sample"]
        for name, stage in zip(names, result.stages):
            write_vtu(vtk_dir / f"{name}.vtu", stage["position"], stage["radius"])
        write_bonds_vtu(vtk_dir / "bonds.vtu", result.sample)
