"""The numerical two-point bending complex modulus test (paper Section 3.2.2).

:func:`run_test` loads a prepared sample (``results/samples/<sample>.h5``, docs/design.md),
fixes the bottom plate and drives the top plate (mass ``plates/mass[1]``, 0.235 kg in the
paper) along x (the paper's "z") by u(t) = A sin(w t), A = 63e-6 m. The bonds follow the macro
Burger's law of the temperature (Eqs. 30-33, 8-11), at rest in the stored (stabilised)
configuration, and the Moreau-Jean theta-method runs the loading cycles. Every step is recorded
(HDF5) at its mid-step time t - dt/2: the imposed displacement, two readings of the head force
(``force_bonds_N``: the sample's reaction plus the exact inertia of the imposed head motion;
``force_driver_N``: the core's driver force), solver statistics (``stats``) and velocity
profiles of the last cycle (``profile``, Fig. 8). The last ``window_cycles`` cycles are reduced
by :func:`asphalt_nscd.lab.en12697.reduce_record` (Eqs. 1-5) with the sample's geometry and
mu = 0.135 M + m. Every ``checkpoint_every`` steps the arrays and then the core state are
written atomically (``<output>.partial.npz``, ``<output>.ckpt.h5``); a rerun with the same run
key (sample, law, f, dt, steps) resumes from them.

Choices (docs/choices.md, Campaign):
* ``dt_policy``: ``fixed`` (the paper's 5e-5 s) or ``steps_per_cycle`` (default, 500 per cycle);
* ``force_reading``: ``bonds`` (default, second order in dt) or ``driver`` (first order);
* ``yield_stress_Pa``: the paper's 2.7 MPa, or None for unbreakable bonds;
* ``gravity``: off at reduced scale, on in ``config/paper.yaml``;
* ``bond_kinematics`` ``contact`` and ``head_rotation`` ``free`` (docs/choices.md, Bond kinematics);
* ``start``: ``rest`` (``n_cycles`` cycles) or ``periodic``
  (:mod:`asphalt_nscd.harmonic.periodic`, ``periodic_cycles``).
"""

from __future__ import annotations

import json
import logging
import math
import sys
import time
import zipfile
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..io import InputError, atomic_path, check_termination, remove_stale_temporaries
from ..nscd.state import BOND_KINEMATICS, HEAD_AMPLITUDE_M, HEAD_ROTATIONS, YIELD_STRESS
from ..rheology.laws import POISSON_RATIO
from ..harmonic import periodic

#: how a test starts: at rest, or in the periodic steady state (:mod:`asphalt_nscd.harmonic.periodic`)
START_MODES = ("rest", "periodic")
#: how a job is computed (module docstring)
METHODS = ("auto", "time_domain", "orbit")
DT_POLICIES = ("fixed", "steps_per_cycle")
FORCE_READINGS = ("bonds", "driver")
#: per-step statistics stored under ``stats/``
STAT_KEYS = (
    "iterations",
    "residual_quad",
    "residual_max",
    "converged",
    "n_contacts",
    "n_active_contacts",
    "n_bonds",
    "n_broken_total",
    "dissipated",
    "linear",
)


@dataclass
class TwoPBSettings:
    """Settings of the numerical 2PB test (config section ``campaign.test``).

    amplitude_m : head displacement amplitude A, m (paper 63e-6).
    n_cycles : loading cycles simulated (paper 5).
    window_cycles : last cycles reduced (config ``lab.simulation_window_cycles``).
    dt_policy : 'fixed' | 'steps_per_cycle' (docs/choices.md, Campaign); dt_s : s; steps_per_cycle : N;
    dt_max_s : cap of the steps_per_cycle policy, s.
    theta : Moreau-Jean theta; tolerance, max_iterations : NLGS; friction : Coulomb (0.7).
    gravity : bool. nu : Poisson's ratio of Eqs. 8-11.
    yield_stress_Pa : bond strength sigma_y, R_crit = sigma_y pi r_min^2 (paper 2.7e6 Pa);
        None = unbreakable bonds (a linear test).
    force_reading : 'bonds' | 'driver'. checkpoint_every : steps (0 = never).
    profile_bins, profile_instants : height bins and instants of the velocity profile.
    bond_kinematics : 'contact' | 'barycentre' (config ``nscd.bond_kinematics``);
    head_rotation : 'free' | 'clamped' (docs/choices.md, Bond kinematics).
    start : 'rest' (``n_cycles`` from rest, the paper) | 'periodic' (``periodic_cycles`` from
        the periodic steady state, :mod:`asphalt_nscd.harmonic.periodic`).
    linear_solver : the core's linear fast-path solver, 'cg' | 'cg_ssor' | 'direct'
        (config ``nscd.linear_solver``, per mode ``campaign.paper|measured.linear_solver``;
        :mod:`asphalt_nscd.nscd.linear`).
    linear_tolerance : relative residual at which the conjugate gradient of the fast path
        stops (config ``nscd.linear_tolerance``; the core's default 1e-10 without it).
    periodic_cycles : cycles simulated after a periodic start (the last ``window_cycles``
        are reduced).
    fast_path_contacts : most contacts a fast-path step solves on their condensed Delassus
        operator (:class:`asphalt_nscd.nscd.NSCDParameters`, :mod:`asphalt_nscd.nscd.condensed`;
        0 = every closing contact sends the step to NLGS, the former behaviour).
    method : 'auto' | 'time_domain' | 'orbit' (module docstring).
    time_domain_steps_per_cycle : steps per cycle of a job that steps in time (its certificate
        fails, or a verification job): dt = 1 / (f N) instead of the dt policy's, which the orbit
        keeps; None: the dt policy's for both (:func:`time_domain_step`).
    mechanisms : 'supported' | 'free' -- how the weakly held spheres' zero modes meet gravity
        (:data:`asphalt_nscd.harmonic.periodic.MECHANISMS`); with 'supported' and gravity, every
        job (time domain and orbit, any start) applies the support force to them.
    """

    amplitude_m: float = HEAD_AMPLITUDE_M
    n_cycles: float = 5.0
    window_cycles: float = 1.0
    dt_policy: str = "steps_per_cycle"
    dt_s: float = 5e-5
    steps_per_cycle: int = 500
    dt_max_s: float = 0.02
    theta: float = 0.5
    tolerance: float = 1e-6
    max_iterations: int = 500
    friction: float = 0.7
    gravity: bool = False
    nu: float = POISSON_RATIO
    yield_stress_Pa: float | None = YIELD_STRESS
    force_reading: str = "bonds"
    checkpoint_every: int = 5000
    profile_bins: int = 10
    profile_instants: int = 8
    bond_kinematics: str = "contact"
    head_rotation: str = "free"
    start: str = "rest"
    periodic_cycles: float = 1.0
    linear_solver: str = "cg"
    linear_tolerance: float = 1e-10
    fast_path_contacts: int = 16
    method: str = "auto"
    mechanisms: str = "supported"
    time_domain_steps_per_cycle: int | None = None

    def __post_init__(self):
        if self.time_domain_steps_per_cycle is not None and not self.time_domain_steps_per_cycle >= 8:
            raise ValueError(
                f"time_domain_steps_per_cycle must be >= 8 or None, got {self.time_domain_steps_per_cycle!r}"
            )
        if self.mechanisms not in periodic.MECHANISMS:
            raise ValueError(f"mechanisms must be one of {periodic.MECHANISMS}, got {self.mechanisms!r}")
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {self.method!r}")
        if self.start not in START_MODES:
            raise ValueError(f"start must be one of {START_MODES}, got {self.start!r}")
        if self.start == "periodic" and not (0 < self.window_cycles <= self.periodic_cycles):
            raise ValueError(
                f"window_cycles must lie in (0, periodic_cycles={self.periodic_cycles}] "
                f"with start 'periodic', got {self.window_cycles}"
            )
        if self.head_rotation not in HEAD_ROTATIONS:
            raise ValueError(f"head_rotation must be one of {HEAD_ROTATIONS}, got {self.head_rotation!r}")
        if self.bond_kinematics not in BOND_KINEMATICS:
            raise ValueError(f"bond_kinematics must be one of {BOND_KINEMATICS}, got {self.bond_kinematics!r}")
        if self.dt_policy not in DT_POLICIES:
            raise ValueError(f"dt_policy must be one of {DT_POLICIES}, got {self.dt_policy!r}")
        if self.force_reading not in FORCE_READINGS:
            raise ValueError(f"force_reading must be one of {FORCE_READINGS}, got {self.force_reading!r}")
        if not (self.amplitude_m > 0 and self.dt_s > 0 and self.dt_max_s > 0 and self.steps_per_cycle >= 8):
            raise ValueError("amplitude_m, dt_s, dt_max_s > 0 and steps_per_cycle >= 8 required")
        if not (0 < self.window_cycles <= self.n_cycles):
            raise ValueError(f"window_cycles must lie in (0, n_cycles={self.n_cycles}], got {self.window_cycles}")


#: keys of a schedule section (campaign.paper, campaign.measured) that override campaign.test
MODE_OVERRIDES = ("dt_policy", "yield_stress_Pa", "start", "linear_solver", "time_domain_steps_per_cycle")


def mode_settings(
    campaign: dict,
    mode: str,
    bond_kinematics: str = "contact",
    linear_solver: str = "cg",
    linear_tolerance: float | None = None,
) -> dict:
    """The test settings (keys of :class:`TwoPBSettings`, JSON-serialisable) of the jobs of
    one mode of a ``campaign`` config section, as workflow/rules/campaign.smk runs them.

    ``campaign.test`` with the overrides (:data:`MODE_OVERRIDES`) of the mode's schedule:
    ``campaign.measured`` for the measured and extended modes, ``campaign.paper`` for the
    paper modes and the studies (dt_study, sensitivity, units_*). A reading mode
    ``paper_<unit>`` (Table 3 read in <unit> beside the paper mode) then takes every override
    of its own section ``campaign.paper_<unit>`` (e.g. its bond strength). The start may
    further be set per study or mode section (``campaign.extended.start``,
    ``campaign.dt_study.start``, ``campaign.sensitivity.start``,
    ``campaign.units_question.start`` for units_*). Modes ending in ``_nobreak`` get
    unbreakable bonds; ``bond_kinematics``, ``linear_solver`` and ``linear_tolerance`` are the
    core's (config ``nscd.bond_kinematics``, ``nscd.linear_solver``, ``nscd.linear_tolerance``;
    None: the core's default); a schedule's own ``linear_solver`` wins (e.g. ``direct`` for
    mix-like bonds, docs/choices.md).
    """
    sched = campaign["measured"] if mode in ("measured", "extended") else campaign["paper"]
    cfg = {**campaign["test"], "linear_solver": linear_solver, **{k: sched[k] for k in MODE_OVERRIDES if k in sched}}
    own = "units_question" if mode.startswith("units_") else mode
    if own.startswith("paper_"):
        cfg.update({k: v for k, v in (campaign.get(own) or {}).items() if k in MODE_OVERRIDES})
    elif own not in ("paper", "measured") and "start" in (campaign.get(own) or {}):
        cfg["start"] = campaign[own]["start"]
    if mode.endswith("_nobreak"):
        cfg["yield_stress_Pa"] = None
    cfg["bond_kinematics"] = bond_kinematics
    if linear_tolerance is not None:
        cfg["linear_tolerance"] = float(linear_tolerance)
    return cfg


def job_settings(cfg: dict, mode: str) -> dict:
    """The test settings of a job of ``mode`` from a whole workflow config ``cfg`` (merged and
    checked, :func:`asphalt_nscd.config.checked`): :func:`mode_settings` of its ``campaign``
    section with the core's ``nscd.bond_kinematics``, ``nscd.linear_solver`` and
    ``nscd.linear_tolerance``, and ``window_cycles`` from ``lab.simulation_window_cycles``.
    What ``run-2pb --config`` runs and what the workflow tracks per job (a change reruns it)."""
    nscd = cfg.get("nscd") or {}
    out = mode_settings(
        cfg["campaign"],
        mode,
        nscd.get("bond_kinematics", "contact"),
        nscd.get("linear_solver", "cg"),
        nscd.get("linear_tolerance"),
    )
    window = (cfg.get("lab") or {}).get("simulation_window_cycles")
    if window is not None:
        out["window_cycles"] = window
    return out


def settings_from(cfg: dict, where: str = "--set") -> TwoPBSettings:
    """:class:`TwoPBSettings` from a dict of its fields (e.g. :func:`mode_settings` updated by
    the command line's ``--set KEY=VALUE``).

    Raises
    ------
    InputError
        naming ``where``: an unknown key (with the known ones), or a value the settings reject.
    """
    names = set(TwoPBSettings.__dataclass_fields__)
    unknown = sorted(set(cfg) - names)
    if unknown:
        raise InputError(f"{where}: unknown key(s) {unknown}; expected some of {sorted(names)}")
    try:
        return TwoPBSettings(**cfg)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{where}: {exc}") from exc


def read_config(paths) -> dict:
    """The workflow config of the files ``paths`` (one path, or several merged in order), with
    ``config/config.yaml`` of the working directory merged under them as Snakemake merges
    ``--configfile`` and checked against the workflow's schemas
    (:func:`asphalt_nscd.config.checked`); it must hold a ``campaign`` section.

    Raises
    ------
    InputError
        naming the file: unreadable, not YAML, not a mapping, a key the schemas refuse; or no
        ``campaign`` section.
    """
    from .. import config

    cfg = config.checked(paths)
    if "campaign" not in cfg:
        names = " ".join(str(p) for p in ([paths] if isinstance(paths, (str, Path)) else paths))
        raise InputError(f"{names}: no 'campaign' section")
    return cfg


def time_step(frequency_Hz: float, settings: TwoPBSettings) -> float:
    """Time step (s) of a test at ``frequency_Hz`` under the settings' dt policy."""
    if settings.dt_policy == "fixed":
        return float(settings.dt_s)
    return float(min(1.0 / (frequency_Hz * settings.steps_per_cycle), settings.dt_max_s))


def cycles_of(settings: TwoPBSettings, start: str | None = None) -> float:
    """Loading cycles simulated with ``start`` (default ``settings.start``): ``n_cycles``
    from rest, ``periodic_cycles`` from the periodic steady state."""
    start = settings.start if start is None else start
    return float(settings.periodic_cycles if start == "periodic" else settings.n_cycles)


def n_steps_of(frequency_Hz: float, dt: float, settings: TwoPBSettings, start: str | None = None) -> int:
    """Number of steps covering the cycles of ``start`` (:func:`cycles_of`) at step ``dt``."""
    return int(math.ceil(cycles_of(settings, start) / (frequency_Hz * dt) - 1e-9))


class HeadMotion:
    """Imposed head displacement u(t) = (A sin(w t), 0, 0), m (picklable callable)."""

    def __init__(self, amplitude_m: float, frequency_Hz: float):
        self.amplitude = float(amplitude_m)
        self.omega = 2.0 * math.pi * float(frequency_Hz)

    def __call__(self, t: float) -> np.ndarray:
        return np.array([self.amplitude * math.sin(self.omega * t), 0.0, 0.0])

    def x(self, t):
        return self.amplitude * np.sin(self.omega * np.asarray(t, float))


def _file_sha256(path) -> str:
    import hashlib

    with open(path, "rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


#: the settings a rig-state file is computed for (:func:`write_rig_state`), checked by its reader
RIG_STATE_SETTINGS = ("bond_kinematics", "head_rotation", "nu", "gravity", "mechanisms")

#: datasets of a rig state's ``gravity`` group, the fields of :class:`asphalt_nscd.harmonic.periodic.GravityUnit`
_UNIT_ARRAYS = ("displacement", "rotation", "head_rotation", "support_force", "mechanism_acceleration")


def write_rig_state(sample_path, settings: TwoPBSettings, output) -> dict:
    """Compute once what every 2PB job of a sample needs and no law changes, and write it
    atomically to ``output`` (HDF5): the spheres the rig holds
    (:func:`asphalt_nscd.harmonic.solver.held_spheres`; dataset ``held`` (N,) bool) and, with
    gravity, the law-free gravity solution U_1 (:func:`asphalt_nscd.harmonic.periodic.gravity_unit`;
    group ``gravity``: ``displacement``, ``rotation`` (N_held, 3), ``head_rotation`` (3,),
    ``support_force`` (N_held, 3) N, ``mechanism_acceleration`` (N_held, 3) m/s^2; attributes
    ``residual``, ``n_mechanisms``, ``failed``), and the reference stiffness G of the sample's
    harmonic system with its fill-reducing ordering (group ``harmonic_reference``,
    :meth:`asphalt_nscd.harmonic.solver.HarmonicSystem.reference_state`: a job takes them
    instead of assembling G from its bonds' 6x6 blocks and ordering it, the same to the last
    bit). Root attributes: the sample file's SHA-256, its sphere and bond counts and
    :data:`RIG_STATE_SETTINGS` of ``settings``. All depend on the sample and these settings
    only, not on the law, T, f or dt. Returns the root attributes.

    Raises
    ------
    InputError if the sample file is missing or malformed.
    """
    import h5py

    from ..harmonic import periodic, solver
    from ..rheology.laws import GeneralizedBurgers
    from ..sample.store import read_sample

    sample = read_sample(sample_path)
    held = solver.held_spheres(sample, settings.bond_kinematics, settings.head_rotation, settings.nu)
    # the rig as a job builds it; the law only scales the bonds, which U_1 does not see
    sim, _ = build_simulation(sample, GeneralizedBurgers(Em=1.0, eta_m=1.0), 1.0, 1.0e-4, settings, held=held)
    system = periodic.harmonic_system(sim, settings.head_rotation, settings.nu)
    unit = periodic.gravity_unit(
        sim, settings.head_rotation, settings.nu, system=system, mechanisms=settings.mechanisms
    )
    reference = system.reference_state()
    attrs = {
        "sample_sha256": _file_sha256(sample_path),
        "n_spheres": int(sample.radius.size),
        "n_bonds": int(len(sample.bonds["i"])),
        **{k: getattr(settings, k) for k in RIG_STATE_SETTINGS},
    }
    with atomic_path(output) as tmp:
        with h5py.File(tmp, "w") as f:
            f["held"] = held
            grp = f.create_group("gravity")
            for k in _UNIT_ARRAYS:
                grp[k] = np.asarray(getattr(unit, k), float)
            grp.attrs.update(residual=unit.residual, n_mechanisms=unit.n_mechanisms, failed=unit.failed)
            _write_reference(f.create_group("harmonic_reference"), reference)
            f.attrs.update(attrs)
    return attrs


def _write_reference(grp, reference: dict) -> None:
    """A :meth:`asphalt_nscd.harmonic.solver.HarmonicSystem.reference_state` into the HDF5 group
    ``grp``: per block of G a subgroup (``data``, ``indices``, ``indptr``; attribute ``shape``),
    ``permutation`` when there is one, attributes ``network_sha256`` and ``options``."""
    for name, block in reference["G"].items():
        sub = grp.create_group(f"G/{name}")
        sub["data"], sub["indices"], sub["indptr"] = block.data, block.indices, block.indptr
        sub.attrs["shape"] = block.shape
    if reference["permutation"] is not None:
        grp["permutation"] = reference["permutation"]
    grp.attrs.update(network_sha256=reference["network_sha256"], options=reference["options"])


def _read_reference(grp) -> dict:
    """The reference state :func:`_write_reference` wrote to ``grp``."""
    import scipy.sparse as sp

    blocks = {
        name: sp.csc_matrix(
            (np.asarray(sub["data"]), np.asarray(sub["indices"]), np.asarray(sub["indptr"])),
            shape=tuple(int(k) for k in sub.attrs["shape"]),
        )
        for name, sub in grp["G"].items()
    }
    return {
        "G": blocks,
        "permutation": np.asarray(grp["permutation"]) if "permutation" in grp else None,
        "network_sha256": str(grp.attrs["network_sha256"]),
        "options": str(grp.attrs["options"]),
    }


def read_rig_state(path, sample_path, settings: TwoPBSettings):
    """The rig state of :func:`write_rig_state` in ``path``, checked against the job's sample
    file and settings: (held (N,) bool, :class:`asphalt_nscd.harmonic.periodic.GravityUnit`,
    the harmonic system's reference state or None for a file without one:
    :meth:`asphalt_nscd.harmonic.solver.HarmonicSystem.reference_state`).

    Raises
    ------
    InputError
        naming ``path`` and the key when the file is missing or not a rig state, or was
        computed from another sample file (SHA-256) or other settings than the job's.
    """
    import h5py

    from ..harmonic.periodic import GravityUnit

    want = {"sample_sha256": _file_sha256(sample_path), **{k: getattr(settings, k) for k in RIG_STATE_SETTINGS}}
    try:
        with h5py.File(path, "r") as f:
            attrs = {k: f.attrs[k] for k in f.attrs}
            held = np.asarray(f["held"], bool)
            grp = f["gravity"]
            arrays = {k: np.asarray(grp[k], float) for k in _UNIT_ARRAYS}
            gattrs = {k: grp.attrs[k] for k in ("residual", "n_mechanisms", "failed")}
            reference = _read_reference(f["harmonic_reference"]) if "harmonic_reference" in f else None
    except (OSError, KeyError) as exc:
        raise InputError(f"{path}: not a rig-state file of asphalt-nscd rig-state ({exc})") from None
    for key, value in want.items():
        if key not in attrs:
            raise InputError(f"{path}: attribute {key!r} missing (expected the output of asphalt-nscd rig-state)")
        stored = attrs[key].item() if hasattr(attrs[key], "item") else attrs[key]
        if stored != value:
            what = f"sample file {sample_path}" if key == "sample_sha256" else "the job's settings"
            raise InputError(f"{path}: {key} is {stored!r}, but {what} give {value!r}: recompute it for this job")
    n_held = int(held.sum())
    if held.shape != (int(attrs.get("n_spheres", -1)),) or any(
        arrays[k].shape != (n_held, 3) for k in _UNIT_ARRAYS if k != "head_rotation"
    ):
        raise InputError(
            f"{path}: held has {held.shape} entries and gravity {arrays['displacement'].shape}: expected "
            f"n_spheres entries and one row per held sphere"
        )
    unit = GravityUnit(
        residual=float(gattrs["residual"]),
        n_mechanisms=int(gattrs["n_mechanisms"]),
        failed=str(gattrs["failed"]),
        **arrays,
    )
    return held, unit, reference


def build_simulation(sample, law, frequency_Hz: float, dt: float, settings: TwoPBSettings, held=None):
    """The NSCD simulation of the test: spheres of ``sample`` (SampleData), bottom plate
    fixed, top plate driven by :class:`HeadMotion` (and free to rotate when
    ``settings.head_rotation == 'free'``, inertia of the harmonic model's steel cuboid), bonds
    with the macro ``law`` (GeneralizedBurgers, Pa, Pa s) and ``settings.bond_kinematics``:
    the 2PB rig (:func:`asphalt_nscd.sample.rig.setup`) holding the spheres the bond network
    holds: ``held`` (N,) bool when given (:func:`read_rig_state`), else
    :func:`asphalt_nscd.harmonic.solver.held_spheres` under ``settings``. Returns (Simulation, HeadMotion).

    Raises
    ------
    InputError if the head is free to rotate but has no positive finite inertia.
    """
    from ..harmonic import solver

    if held is None:
        held = solver.held_spheres(sample, settings.bond_kinematics, settings.head_rotation, settings.nu)
    return _held_simulation(sample, held, law, frequency_Hz, dt, settings)


def _held_simulation(sample, held: np.ndarray, law, frequency_Hz: float, dt: float, settings: TwoPBSettings):
    """:func:`build_simulation` of ``sample`` holding the spheres of ``held`` (N,) bool.

    Raises
    ------
    InputError if the head is free to rotate but has no positive finite inertia.
    """
    from ..nscd import NSCDParameters
    from ..sample import rig

    motion = HeadMotion(settings.amplitude_m, frequency_Hz)
    strength = np.inf if settings.yield_stress_Pa is None else float(settings.yield_stress_Pa)
    gravity = (0.0, 0.0, -9.81) if settings.gravity else (0.0, 0.0, 0.0)
    params = NSCDParameters(
        dt=dt,
        theta=settings.theta,
        gravity=gravity,
        friction=settings.friction,
        tolerance=settings.tolerance,
        max_iterations=settings.max_iterations,
        bond_kinematics=settings.bond_kinematics,
        linear_solver=settings.linear_solver,
        linear_tolerance=settings.linear_tolerance,
        fast_path_contacts=settings.fast_path_contacts,
    )
    sim = rig.setup(sample, law, motion, params, settings.head_rotation, settings.nu, strength, held=held)
    return sim, motion


def start_test(sim, law, frequency_Hz: float, settings: TwoPBSettings, continuous: bool = False) -> dict:
    """Put a freshly built simulation in its initial state: at rest, or, with ``settings.start
    == 'periodic'``, in the periodic steady state (:mod:`asphalt_nscd.harmonic.periodic`) unless that state would
    break a bond (then at rest, with a message on stderr). The ``info`` of :func:`periodic_start`."""
    return periodic_start(sim, law, frequency_Hz, settings, continuous)[0]


def periodic_start(
    sim,
    law,
    frequency_Hz: float,
    settings: TwoPBSettings,
    continuous: bool = False,
    gravity=None,
    reference: dict | None = None,
    system=None,
) -> tuple[dict, "periodic.PeriodicState | None"]:
    """:func:`start_test` with the periodic state it computed: (info, state; None without a
    periodic request).

    With gravity and ``settings.mechanisms == 'supported'`` the simulation's external force is set
    to the weakly held spheres' support force (:func:`asphalt_nscd.harmonic.periodic.support_force`;
    ``gravity``'s when given), whatever the start.

    ``info``: start ('rest' | 'periodic', the start used), requested, and for a
    periodic request (``continuous``: the continuous steady state s = i w instead of the
    theta-method's, :func:`asphalt_nscd.harmonic.periodic.periodic_state`, for ``periodic-check``) solve_s and solve_cpu_s (wall and CPU time of the solve, counted in the
    record's times), force_ratio (steady bond force / strength), gravity (with gravity on: the
    steady state under gravity superposed, :meth:`asphalt_nscd.harmonic.periodic.GravityState.info`), gmres_iterations,
    laplace_imag (the theta-method's effective angular frequency, rad/s) and fallback
    (reason, when it starts from rest). ``gravity``: the law-free gravity solution of ``sim``
    (:func:`asphalt_nscd.harmonic.periodic.gravity_unit`, e.g. from :func:`read_rig_state`), or
    None to compute it. ``reference``: the harmonic system's reference state (G and its ordering,
    from :func:`read_rig_state`), or None to assemble them. ``system``: the
    :func:`asphalt_nscd.harmonic.periodic.harmonic_system` of ``sim``, built before (then
    ``reference`` is not read), or None to build it.

    Raises
    ------
    InputError for a ``reference`` computed on another network or with other options.
    """
    info: dict[str, Any] = {"start": "rest", "requested": settings.start}
    if system is None and reference is not None:
        system = _system_of(sim, settings, reference)
    if settings.start != "periodic":
        if settings.gravity and settings.mechanisms == "supported":
            sim.external_force = periodic.support_force(
                sim, settings.head_rotation, settings.nu, system=system, unit=gravity
            )
        return info, None
    cpu = time.process_time()
    state = periodic.periodic_state(
        sim,
        law,
        frequency_Hz,
        settings.amplitude_m,
        head_rotation=settings.head_rotation,
        nu=settings.nu,
        continuous=continuous,
        system=system,
        mechanisms=settings.mechanisms,
        gravity=gravity,
    )
    info.update(_solve_info(state, time.process_time() - cpu))
    if state.gravity is not None:
        info["gravity"] = state.gravity.info()
        if settings.mechanisms == "supported":
            assert state.gravity.support_force is not None  # computed for supported mechanisms
            sim.external_force = state.gravity.support_force.copy()
    if state.breaks:
        info["fallback"] = (
            f"the steady state would break bonds (force / strength up to "
            f"{state.force_ratio:.3g}): the test is not linear, started from rest"
        )
        print(f"periodic start: {info['fallback']}", file=sys.stderr, flush=True)
        return info, state
    periodic.apply_periodic_state(sim, state)
    info["start"] = "periodic"
    if continuous:
        info["continuous"] = True
    return info, state


def _solve_info(state: "periodic.PeriodicState", cpu_s: float) -> dict:
    """The start info of a periodic ``state`` solved in ``cpu_s`` s of CPU time: solve_s (wall),
    solve_cpu_s, force_ratio, gmres_iterations, laplace_real and laplace_imag (1/s)."""
    return {
        "solve_s": state.solve_s,
        "solve_cpu_s": cpu_s,
        "force_ratio": state.force_ratio,
        "gmres_iterations": state.gmres_iterations,
        "laplace_real": state.laplace.real,
        "laplace_imag": state.laplace.imag,
    }


def time_domain_step(frequency_Hz: float, settings: TwoPBSettings) -> float | None:
    """Time step (s) of a job that steps in time under ``settings.time_domain_steps_per_cycle``
    (1 / (f N)), or None when the dt policy's applies (:func:`time_step`)."""
    n = settings.time_domain_steps_per_cycle
    return None if n is None else 1.0 / (frequency_Hz * n)


@dataclass(frozen=True)
class JobInputs:
    """What a 2PB job is asked, as :func:`run_test` takes it (its parameters there).

    sample_path : sample file. law : GeneralizedBurgers (Pa, Pa s). frequency_Hz : f, Hz.
    settings : :class:`TwoPBSettings`. meta : extra record attributes, or None.
    continuous_start : start from the continuous steady state. verify : a verification job.
    """

    sample_path: Any
    law: Any
    frequency_Hz: float
    settings: TwoPBSettings
    meta: dict | None = None
    continuous_start: bool = False
    verify: bool = False


@dataclass
class Rig:
    """What a job reads from its sample once and every later step shares.

    sample : SampleData of the sample file (the only read of it in a job).
    specimen : EN 12697-26 specimen of the sample (:func:`asphalt_nscd.sample.store.specimen_of`).
    edges : (profile_bins + 1,) m, the height bins of the velocity profile between the plates.
    counts : (profile_bins,) int, spheres per height bin at rest (the profile's divisor).
    held : (N,) bool, the spheres the rig holds (:func:`hold`), None until held.
    unit : the law-free gravity solution (:class:`asphalt_nscd.harmonic.periodic.GravityUnit`)
        or None (not needed, or not yet computed).
    reference : the harmonic system's reference state from a rig-state file, or None.
    system : the :class:`asphalt_nscd.harmonic.solver.HarmonicSystem` of the job, built on its
        first simulation and kept for a second one (None: none built, or none needed).
    """

    sample: Any
    specimen: Any
    edges: np.ndarray
    counts: np.ndarray
    held: np.ndarray | None = None
    unit: Any = None
    reference: dict | None = None
    system: Any = None


def read_rig(sample_path, settings: TwoPBSettings) -> Rig:
    """The :class:`Rig` of a job: its sample read once, its specimen and profile bins.

    Raises
    ------
    InputError if the sample file is missing or malformed.
    """
    from ..sample.store import read_sample, specimen_of

    sample = read_sample(sample_path)
    specimen = specimen_of(sample)
    z_bot, z_top = float(sample.plate_point[0, 2]), float(sample.plate_point[1, 2])
    edges = np.linspace(min(z_bot, z_top), max(z_bot, z_top), settings.profile_bins + 1)
    zbin = np.clip(np.digitize(sample.position[:, 2], edges) - 1, 0, settings.profile_bins - 1)
    counts = np.bincount(zbin, minlength=settings.profile_bins)
    return Rig(sample=sample, specimen=specimen, edges=edges, counts=counts)


def hold(rig: Rig, sample_path, settings: TwoPBSettings, rig_state=None) -> Rig:
    """``rig`` with the spheres it holds: read from the ``rig_state`` file with its gravity
    solution and reference state (:func:`read_rig_state`), or computed
    (:func:`asphalt_nscd.harmonic.solver.held_spheres`; the gravity solution then follows on
    the first simulation, :func:`_with_system`).

    Raises
    ------
    InputError for a rig-state file that is missing or computed for another sample or settings.
    """
    from ..harmonic import solver

    if rig_state is not None:
        held, unit, reference = read_rig_state(rig_state, sample_path, settings)
        return replace(rig, held=held, unit=unit, reference=reference)
    held = solver.held_spheres(rig.sample, settings.bond_kinematics, settings.head_rotation, settings.nu)
    return replace(rig, held=held)


def _system_of(sim, settings: TwoPBSettings, reference: dict | None):
    """:func:`asphalt_nscd.harmonic.periodic.harmonic_system` of ``sim`` under ``settings``.

    Raises
    ------
    InputError for a ``reference`` computed on another network or with other options.
    """
    try:
        return periodic.harmonic_system(sim, settings.head_rotation, settings.nu, reference)
    except ValueError as exc:
        if reference is None:
            raise
        raise InputError(f"rig state: {exc}; recompute it (asphalt-nscd rig-state) for this job") from None


def _with_system(rig: Rig, sim, settings: TwoPBSettings) -> Rig:
    """``rig`` with the harmonic system of ``sim`` and, for a periodic start under gravity, the
    law-free gravity solution (:func:`asphalt_nscd.harmonic.periodic.gravity_unit`): built on a
    job's first simulation; a later simulation of the job (another dt, the same network) keeps
    both and only drops the system's shifted factors. No system when the start needs none
    (a rest start without supported mechanisms under gravity, and no reference state).

    Raises
    ------
    InputError for a reference state of another network or other options.
    """
    if rig.system is not None:
        rig.system.drop_shifted_factors()
        return rig
    supported = settings.gravity and settings.mechanisms == "supported"
    if rig.reference is None and settings.start != "periodic" and not supported:
        return rig
    system = _system_of(sim, settings, rig.reference)
    unit = rig.unit
    if unit is None and settings.gravity and settings.start == "periodic":
        unit = periodic.gravity_unit(
            sim, settings.head_rotation, settings.nu, system=system, mechanisms=settings.mechanisms
        )
    return replace(rig, system=system, unit=unit)


@dataclass
class JobStart:
    """A job's simulation at its time step in its initial state, with its certificate.

    rig : the job's :class:`Rig` (with its harmonic system once one is built).
    sim, motion : the Simulation and its :class:`HeadMotion` (:func:`build_simulation`).
    dt : time step, s. rest_z : (N,) m, the spheres' heights at rest.
    info : the start info (:func:`periodic_start`; with ``certificate``, ``path``, ...).
    state : the periodic state (:class:`asphalt_nscd.harmonic.periodic.PeriodicState`) or None.
    n_steps : steps of the start's cycles (:func:`n_steps_of`).
    certificate : :class:`asphalt_nscd.harmonic.orbit.Certificate` or None.
    path : 'orbit' | 'time_domain' (:func:`choose_path`; '' until chosen).
    """

    rig: Rig
    sim: Any
    motion: HeadMotion
    dt: float
    rest_z: np.ndarray
    info: dict
    state: Any
    n_steps: int
    certificate: Any
    path: str = ""


def set_up(rig: Rig, inputs: JobInputs, dt: float) -> JobStart:
    """The simulation of a job at step ``dt`` in its initial state (:func:`periodic_start`), with
    its linearity certificate (:func:`asphalt_nscd.harmonic.orbit.certify`, for a periodic start
    on the theta-method's state). ``rig``: held (:func:`hold`).

    Raises
    ------
    InputError for a reference state of another network or other options.
    ValueError for a rig that is not held.
    """
    if rig.held is None:
        raise ValueError("set_up: the rig holds no spheres yet (hold it first)")
    law, frequency_Hz, settings, continuous = inputs.law, inputs.frequency_Hz, inputs.settings, inputs.continuous_start
    sim, motion = _held_simulation(rig.sample, rig.held, law, frequency_Hz, dt, settings)
    rest_z = sim.spheres.position[:, 2].copy()
    rig = _with_system(rig, sim, settings)
    info, state = periodic_start(
        sim, law, frequency_Hz, settings, continuous=continuous, gravity=rig.unit, system=rig.system
    )
    n_steps = n_steps_of(frequency_Hz, dt, settings, info["start"])
    cert = None
    if state is not None and state.phasors is not None and not continuous:
        from ..harmonic.orbit import certify

        cpu = time.process_time()
        cert = certify(sim, state, n_steps * dt)
        info["certificate"] = cert.row()
        info["solve_cpu_s"] = info.get("solve_cpu_s", 0.0) + time.process_time() - cpu
    return JobStart(rig, sim, motion, dt, rest_z, info, state, n_steps, cert)


def start_job(rig: Rig, inputs: JobInputs) -> JobStart:
    """Set a job up at its dt policy's step (:func:`time_step`), choose its path from the
    certificate and settings (:func:`choose_path`), and set it up again at
    ``time_domain_steps_per_cycle``'s step when it steps in time at another dt (both set-ups'
    solve times counted; the first certificate kept as ``certificate_at_policy_dt``). The
    info gets ``path`` and ``path_reason``.

    Raises
    ------
    InputError for ``method: orbit`` on a job not certified linear, or a reference state of
    another network.
    """
    frequency_Hz, settings = inputs.frequency_Hz, inputs.settings
    job = set_up(rig, inputs, time_step(frequency_Hz, settings))
    path, why = choose_path(settings, job.info, job.certificate, inputs.verify)
    dt_td = time_domain_step(frequency_Hz, settings)
    if path == "time_domain" and dt_td is not None and dt_td != job.dt:  # stepped at its own converged dt
        first = job.info
        job = set_up(job.rig, inputs, dt_td)
        job.info["solve_s"] = job.info.get("solve_s", 0.0) + first.get("solve_s", 0.0)  # both set-ups count
        job.info["solve_cpu_s"] = job.info.get("solve_cpu_s", 0.0) + first.get("solve_cpu_s", 0.0)
        if first.get("certificate") is not None:
            job.info["certificate_at_policy_dt"] = first["certificate"]
        why += (
            f"; stepped at {settings.time_domain_steps_per_cycle} steps per cycle (dt = {dt_td:.4g} s, "
            "time_domain_steps_per_cycle)"
        )
    job.info.update({"path": path, "path_reason": why})
    job.path = path
    return job


def choose_path(settings: TwoPBSettings, start_info: dict, certificate, verify: bool) -> tuple[str, str]:
    """(path, why) of a job (module docstring, ``method``): ``orbit`` or ``time_domain``.

    Raises InputError for ``method: orbit`` on a job whose certificate fails or that does not
    start periodic."""
    if verify:
        return "time_domain", "verification job: steps in time, its orbit's result recorded beside"
    if settings.method == "time_domain":
        return "time_domain", "method time_domain"
    started = start_info["start"] == "periodic" and certificate is not None
    if settings.method == "orbit":
        if not started or not certificate.holds:
            why = certificate.reason if started else f"the job starts {start_info['start']}, not periodic"
            raise InputError(
                f"method orbit: the job is not certified linear ({why}); run it with method auto or time_domain"
            )
        return "orbit", "method orbit, certificate holds"
    if not started:
        return "time_domain", (
            f"starts {start_info['start']}" + (f" ({start_info['fallback']})" if start_info.get("fallback") else "")
        )
    if not certificate.holds:
        return "time_domain", f"certificate fails: {certificate.reason}"
    return "orbit", "certificate holds: the exact periodic orbit, no time steps"


def _orbit_arrays(sim, state, rest_z: np.ndarray, n_steps: int, prof_steps, edges, counts) -> dict:
    """The arrays of :func:`run_test` on the orbit (:func:`asphalt_nscd.harmonic.orbit.orbit_record`):
    the head forces, the velocity profile at ``prof_steps`` (binned as the time-stepping loop bins
    it: by the current heights ``edges``, divided by the ``counts`` at rest), and the statistics of
    linear steps (no NLGS, no contact; ``n_contacts`` and ``dissipated`` not computed: NaN).
    ``rest_z``: the spheres' heights at rest (the state's reference)."""
    from ..harmonic.orbit import orbit_record

    sig = orbit_record(sim, state, n_steps)
    ph = state.phasors
    g = ph["gravity_state"]
    dt = sim.params.dt
    z = np.exp(1j * 2.0 * math.pi * ph["frequency_Hz"] * dt)
    vhat = state.laplace * ph["displacement"]
    bins = len(edges) - 1
    out = {
        "t": sig["time_s"],
        "plate_fx": sig["plate_fx"],
        "driver_fx": sig["driver_fx"],
        "profile_vx": np.zeros((len(prof_steps), bins)),
    }
    for n, k in enumerate(prof_steps):  # the state after step k: y_{k+1}
        zk = z ** (k + 1)
        vx = np.real(vhat[:, 0] * zk) + (g.velocity[:, 0] if g is not None else 0.0)
        hz = rest_z + np.real(ph["displacement"][:, 2] * zk)
        if g is not None:
            hz = hz + g.displacement[:, 2] + g.velocity[:, 2] * (k + 1) * dt
        pos = np.clip(np.digitize(hz, edges) - 1, 0, bins - 1)
        out["profile_vx"][n] = np.bincount(pos, weights=vx, minlength=bins) / np.maximum(counts, 1)
    stats = {
        "iterations": 0.0,
        "residual_quad": 0.0,
        "residual_max": 0.0,
        "converged": 1.0,
        "n_contacts": np.nan,
        "n_active_contacts": 0.0,
        "n_bonds": float(sim.bonds.n),
        "n_broken_total": 0.0,
        "dissipated": np.nan,
        "linear": 1.0,
    }
    for k in STAT_KEYS:
        out[k] = np.full(n_steps, stats[k])
    return out


def _profile_steps(n_steps: int, steps_per_period: float, k: int) -> np.ndarray:
    """Indices (0-based) of ``k`` steps evenly spread over the last period."""
    start = n_steps - steps_per_period
    return np.unique(
        np.clip(np.round(start + (np.arange(k) + 1) * steps_per_period / k).astype(int) - 1, 0, n_steps - 1)
    )


def orbit_result(job: JobStart, inputs: JobInputs):
    """The record of a job on the orbit path, sampled on its periodic orbit (:func:`_orbit_arrays`),
    or None for a job that steps in time. A verification job that starts periodic with a
    certificate gets the orbit's reduced result (Eqs. 1-5, :func:`reduce_test`) in its info
    (``orbit``: E_norm_MPa, phase_deg, certified). The sampling's CPU time is counted in the
    info's ``solve_cpu_s``; the record's wall time is the solve's and the certificate's."""
    info, frequency_Hz, settings, verify = job.info, inputs.frequency_Hz, inputs.settings, inputs.verify
    if not (job.path == "orbit" or (verify and job.certificate is not None and info["start"] == "periodic")):
        return None
    cpu = time.process_time()
    prof = _profile_steps(job.n_steps, 1.0 / (frequency_Hz * job.dt), settings.profile_instants)
    arrays = _orbit_arrays(job.sim, job.state, job.rest_z, job.n_steps, prof, job.rig.edges, job.rig.counts)
    info["solve_cpu_s"] = info.get("solve_cpu_s", 0.0) + time.process_time() - cpu
    if verify:
        record = _record(inputs, job.rig, job.sim, job.motion, arrays, {**info, "path": "orbit"}, (0.0, 0.0))
        red = reduce_test(record, settings.window_cycles)
        info["orbit"] = {
            "E_norm_MPa": red["E_norm_MPa"],
            "phase_deg": red["phase_deg"],
            "certified": bool(job.certificate.holds),
        }
    if job.path != "orbit":
        return None
    wall = info.get("solve_s", 0.0) + (job.certificate.seconds if job.certificate else 0.0)
    return _record(inputs, job.rig, job.sim, job.motion, arrays, info, (wall, info.get("solve_cpu_s", 0.0)))


@dataclass
class TimeDomainRun:
    """A job that steps in time: its simulation, the per-step arrays it fills and its start info.

    sim, motion : the Simulation (at its step index) and its :class:`HeadMotion`.
    arrays : ``t``, ``plate_fx``, ``driver_fx`` and :data:`STAT_KEYS` (n_steps,), ``profile_vx``
        (instants, bins), ``wall`` and ``cpu`` (1,) s spent before the steps left, and
        ``start_info`` (the info as JSON): what a checkpoint stores.
    info : the start info.
    """

    sim: Any
    motion: HeadMotion
    arrays: dict
    info: dict


@dataclass
class JobFiles:
    """Where a job writes: its record and, beside it, its checkpoint (``.ckpt.h5``) and arrays
    (``.partial.npz``), with the run key a resumed run must match (sample, law, f, dt, settings)."""

    output: Path
    ckpt: Path
    partial: Path
    key: str


def _fresh_run(job: JobStart, frequency_Hz: float, settings: TwoPBSettings) -> TimeDomainRun:
    """The :class:`TimeDomainRun` of a job set up to step in time, its arrays zero."""
    n_steps = job.n_steps
    n_prof = len(_profile_steps(n_steps, 1.0 / (frequency_Hz * job.dt), settings.profile_instants))
    arrays = {
        "t": np.zeros(n_steps),
        "plate_fx": np.zeros(n_steps),
        "driver_fx": np.zeros(n_steps),
        "profile_vx": np.zeros((n_prof, settings.profile_bins)),
        "wall": np.array([job.info.get("solve_s", 0.0)]),
        "cpu": np.array([job.info.get("solve_cpu_s", 0.0)]),
        "start_info": np.array(json.dumps(job.info)),
    }
    for name in STAT_KEYS:
        arrays[name] = np.zeros(n_steps)
    return TimeDomainRun(job.sim, job.motion, arrays, job.info)


def _resume(files: JobFiles, settings: TwoPBSettings, frequency_Hz: float) -> TimeDomainRun | None:
    """The run of a checkpoint of the same run key, or None (no checkpoint, another key, or an
    unreadable one: then set aside as ``*.unreadable`` with a warning, the job restarts)."""
    from ..nscd import read_checkpoint

    ckpt, partial = files.ckpt, files.partial
    if not (ckpt.exists() and partial.exists()):
        return None
    try:
        with np.load(partial, allow_pickle=False) as z:
            arrays = {k: z[k].copy() for k in z.files}
        if str(arrays.pop("key")) != files.key:
            return None
        motion = HeadMotion(settings.amplitude_m, frequency_Hz)
        sim = read_checkpoint(ckpt, drivers=[None, motion])
        info = json.loads(str(arrays["start_info"]))
        print(f"resuming from {ckpt} at step {sim.step_index} of {len(arrays['t'])}", flush=True, file=sys.stderr)
        return TimeDomainRun(sim, motion, arrays, info)
    except (InputError, OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError) as exc:
        for unreadable in (ckpt, partial):
            if unreadable.exists():
                unreadable.replace(unreadable.with_name(unreadable.name + ".unreadable"))
        logging.getLogger("asphalt_nscd").warning(
            "%s: the checkpoint cannot be read (%s); moved aside as *.unreadable, the job restarts from its beginning",
            ckpt,
            str(exc).splitlines()[0] if str(exc) else type(exc).__name__,
        )
        return None


def step_in_time(
    run: TimeDomainRun,
    rig: Rig,
    settings: TwoPBSettings,
    frequency_Hz: float,
    files: JobFiles,
    progress: bool = True,
    stop_after: int | None = None,
) -> tuple[float, float] | None:
    """Step ``run`` to its last step, filling its arrays (the velocity profile binned by the
    current heights over ``rig``'s bins, divided by its counts at rest) and checkpointing every
    ``settings.checkpoint_every`` steps. Returns the run's (wall, CPU) time in s, or None once
    ``stop_after`` steps are done in total (after a checkpoint)."""
    from tqdm import tqdm

    from ..nscd import write_checkpoint

    sim, arrays = run.sim, run.arrays
    n_steps = len(arrays["t"])
    dt = float(sim.params.dt)  # the policy's, or time_domain_steps_per_cycle's (also on a resumed run)
    prof_steps = _profile_steps(n_steps, 1.0 / (frequency_Hz * dt), settings.profile_instants)
    prof_index = {int(s): n for n, s in enumerate(prof_steps)}
    bar = tqdm(
        total=n_steps,
        initial=sim.step_index,
        disable=not progress,
        mininterval=5.0,
        desc=f"2PB f={frequency_Hz:g} Hz dt={dt:.3g} s",
        unit="step",
    )
    tic, cpu_tic = time.perf_counter(), time.process_time()
    wall0, cpu0 = float(arrays["wall"][0]), float(arrays["cpu"][0])
    for k in range(sim.step_index, n_steps):
        check_termination()
        st = sim.step()
        arrays["t"][k] = st.time - 0.5 * dt
        arrays["plate_fx"][k] = st.plate_force[1, 0]
        arrays["driver_fx"][k] = st.driver_force[1, 0]
        for name in STAT_KEYS:
            arrays[name][k] = (st.solver == "linear") if name == "linear" else getattr(st, name)
        if k in prof_index:
            pos = np.clip(np.digitize(sim.spheres.position[:, 2], rig.edges) - 1, 0, settings.profile_bins - 1)
            vx = np.bincount(pos, weights=sim.spheres.velocity[:, 0], minlength=settings.profile_bins)
            arrays["profile_vx"][prof_index[k]] = vx / np.maximum(rig.counts, 1)
        bar.update(1)
        done = k + 1
        every = bool(settings.checkpoint_every) and done % settings.checkpoint_every == 0 and done < n_steps
        if every or (stop_after is not None and done == stop_after):
            arrays["wall"][0] = wall0 + time.perf_counter() - tic
            arrays["cpu"][0] = cpu0 + time.process_time() - cpu_tic
            with atomic_path(files.partial) as tmp:
                with open(tmp, "wb") as fh:
                    np.savez(fh, key=np.array(files.key), **arrays)
            write_checkpoint(sim, files.ckpt)
            if stop_after is not None and done == stop_after:
                bar.close()
                return None
    bar.close()
    return wall0 + time.perf_counter() - tic, cpu0 + time.process_time() - cpu_tic


def run_test(
    sample_path,
    law,
    frequency_Hz: float,
    settings: TwoPBSettings,
    output,
    meta: dict | None = None,
    progress: bool = True,
    stop_after: int | None = None,
    continuous_start: bool = False,
    verify: bool = False,
    rig_state=None,
):
    """Run (or resume) the numerical 2PB test and write its record (HDF5) atomically.

    The steps: the rig is read once (:func:`read_rig`); a checkpoint of the same run key is
    resumed (:func:`_resume`); otherwise the rig holds its spheres (:func:`hold`), the job is
    set up and its path chosen (:func:`start_job`), and the orbit's record is sampled
    (:func:`orbit_result`) or the job steps in time from its start (:func:`step_in_time`).

    Parameters
    ----------
    sample_path : sample file (docs/design.md).
    law : GeneralizedBurgers, macro law (Pa, Pa s) of the temperature.
    frequency_Hz : loading frequency f, Hz.
    settings : TwoPBSettings.
    output : record path (.h5); checkpoints live next to it.
    meta : extra root attributes (temperature_C, sample, mode, ...), JSON-serialisable.
    progress : tqdm progress bar on stderr.
    stop_after : stop (after checkpointing) once this many steps are done in total;
        used to test the resume path. None: run to the end.
    continuous_start : with ``settings.start == 'periodic'``, start from the continuous
        steady state (s = i w) instead of the theta-method's (``periodic-check`` measures
        the difference).
    verify : step in time whatever ``settings.method`` says, and record the orbit's reduced
        result (``start_info['orbit']``) beside (a verification job).
    rig_state : the sample's rig-state file (:func:`write_rig_state`, checked against
        ``sample_path`` and ``settings`` by :func:`read_rig_state`): the held spheres and the
        law-free gravity solution, read instead of computed; None: the job computes both (the
        same numbers).

    Returns
    -------
    dict of the record (see :func:`read_record`), or None when stopped by ``stop_after``.

    Raises
    ------
    InputError if the sample file is missing or malformed.
    """
    inputs = JobInputs(sample_path, law, frequency_Hz, settings, meta, continuous_start, verify)
    rig = read_rig(sample_path, settings)
    files = _job_files(output, inputs)
    run = _resume(files, settings, frequency_Hz)
    if run is None:
        job = start_job(hold(rig, sample_path, settings, rig_state), inputs)
        record = orbit_result(job, inputs)
        if record is not None:
            write_record(record, files.output)
            return record
        run = _fresh_run(job, frequency_Hz, settings)
    times = step_in_time(run, rig, settings, frequency_Hz, files, progress, stop_after)
    if times is None:
        return None
    record = _record(inputs, rig, run.sim, run.motion, run.arrays, run.info, times)
    write_record(record, files.output)
    files.ckpt.unlink(missing_ok=True)
    files.partial.unlink(missing_ok=True)
    return record


def _job_files(output, inputs: JobInputs) -> JobFiles:
    """The :class:`JobFiles` of a job writing ``output``, the temporaries a killed writer left
    beside them removed; the run key holds the dt policy's step (:func:`time_step`)."""
    output = Path(output)
    ckpt = output.with_name(output.name + ".ckpt.h5")
    partial = output.with_name(output.name + ".partial.npz")
    for stale in (output, ckpt, partial):  # left by a writer killed outright
        remove_stale_temporaries(stale)
    key = json.dumps(
        {
            "sample": str(inputs.sample_path),
            "law": inputs.law.as_dict(),
            "f": inputs.frequency_Hz,
            "dt": time_step(inputs.frequency_Hz, inputs.settings),
            "settings": asdict(inputs.settings),
            "continuous_start": bool(inputs.continuous_start),
            "verify": bool(inputs.verify),
        },
        sort_keys=True,
    )
    return JobFiles(output, ckpt, partial, key)


def _record(
    inputs: JobInputs, rig: Rig, sim, motion: HeadMotion, arrays: dict, start_info: dict, times: tuple[float, float]
) -> dict:
    """The record of :func:`run_test` from its per-step ``arrays`` (``t, plate_fx, driver_fx,
    profile_vx`` and :data:`STAT_KEYS`, (n_steps,)), stepped in time or sampled on the orbit by
    ``sim`` at its step, on ``rig``'s sample, specimen and profile bins; ``times``: the job's
    (wall, CPU) time, s."""
    settings, law, frequency_Hz = inputs.settings, inputs.law, inputs.frequency_Hz
    dt, n_steps = float(sim.params.dt), len(arrays["t"])
    wall, cpu = times
    t = arrays["t"]
    x = motion.x(t)
    sample, edges, counts = rig.sample, rig.edges, rig.counts
    m_head = float(sample.plate_mass[1])
    force_bonds = -arrays["plate_fx"] - m_head * motion.omega**2 * x
    prof_steps = _profile_steps(n_steps, 1.0 / (frequency_Hz * dt), settings.profile_instants)
    record = {
        "time_s": t,
        "displacement_m": x,
        "force_bonds_N": force_bonds,
        "force_driver_N": np.asarray(arrays["driver_fx"]).copy(),
        "stats": {k: arrays[k] for k in STAT_KEYS},
        "profile": {
            "time_s": t[prof_steps],
            "z_m": 0.5 * (edges[1:] + edges[:-1]),
            "vx_m_s": arrays["profile_vx"],
            "count": counts,
        },
        "attrs": {
            **(inputs.meta or {}),
            "frequency_Hz": float(frequency_Hz),
            "dt_s": dt,
            "n_steps": n_steps,
            "n_spheres": int(sim.spheres.n),
            "n_bonds": int(len(sim.bonds.i)),
            "n_mechanisms_dropped": int(sample.radius.size - sim.spheres.n),
            "wall_time_s": wall,
            "cpu_time_s": cpu,
            "cpu_per_sphere_step_s": cpu / (n_steps * sim.spheres.n),
            "law": json.dumps(law.as_dict()),
            "settings": json.dumps(asdict(settings)),
            "specimen": json.dumps(rig.specimen.as_dict()),
            "sample_file": str(inputs.sample_path),
            "head_mass_kg": m_head,
            "amplitude_m": settings.amplitude_m,
            "start": start_info["start"],
            "start_requested": settings.start,
            "n_cycles_simulated": cycles_of(settings, start_info["start"]),
            "path": start_info.get("path", "time_domain"),
            "path_reason": start_info.get("path_reason", ""),
            "start_info": json.dumps(start_info),
        },
    }
    record["force_N"] = record[f"force_{settings.force_reading}_N"]
    return record


def write_record(record: dict, path) -> None:
    """Write a test record to HDF5 atomically (datasets of :func:`run_test`, SI units)."""
    import h5py

    with atomic_path(path) as tmp:
        with h5py.File(tmp, "w") as f:
            for k in ("time_s", "displacement_m", "force_N", "force_bonds_N", "force_driver_N"):
                f[k] = record[k]
            for grp in ("stats", "profile"):
                for k, v in record[grp].items():
                    f[f"{grp}/{k}"] = np.asarray(v)
            for k, v in record["attrs"].items():
                f.attrs[k] = v


def read_record(path) -> dict:
    """Read a record written by :func:`write_record`.

    Returns dict with ``time_s, displacement_m, force_N, force_bonds_N, force_driver_N``
    (n,), ``stats`` and ``profile`` dicts of arrays and ``attrs``.

    Raises InputError if the file is missing or is not a 2PB record.
    """
    import h5py

    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: record file not found")
    with h5py.File(path, "r") as f:
        if "force_N" not in f or "time_s" not in f:
            raise InputError(f"{path}: not a 2PB record (datasets time_s, force_N expected)")
        rec = {k: f[k][()] for k in ("time_s", "displacement_m", "force_N", "force_bonds_N", "force_driver_N")}
        rec["stats"] = {k: f[f"stats/{k}"][()] for k in f["stats"]}
        rec["profile"] = {k: f[f"profile/{k}"][()] for k in f["profile"]}
        rec["attrs"] = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in f.attrs.items()}
    return rec


def truncate_record(record: dict, end_cycle: float) -> dict:
    """The record up to the end of cycle ``end_cycle`` (steps whose end time is at most
    end_cycle / f): what a run of ``end_cycle`` cycles from the same start would have
    recorded, since the imposed motion does not depend on the run's length.

    Raises ValueError if the record is shorter than ``end_cycle`` cycles.
    """
    a = record["attrs"]
    n = int(math.ceil(end_cycle / (float(a["frequency_Hz"]) * float(a["dt_s"])) - 1e-9))
    if n > len(record["time_s"]):
        raise ValueError(f"record of {len(record['time_s'])} steps is shorter than {end_cycle} cycles ({n} steps)")
    out: dict[str, Any] = {
        k: np.asarray(record[k])[:n] for k in ("time_s", "displacement_m", "force_N", "force_bonds_N", "force_driver_N")
    }
    out["stats"] = {k: np.asarray(v)[:n] for k, v in record["stats"].items()}
    out["profile"] = record["profile"]
    out["attrs"] = {**a, "n_steps": n}
    return out


def reduce_test(record: dict, window_cycles: float, force_reading: str | None = None) -> dict:
    """Reduce a record by EN 12697-26 (Eqs. 1-5) over its last ``window_cycles`` cycles.

    Returns the row of :func:`asphalt_nscd.lab.en12697.reduce_record` plus the record's
    meta attributes, the other force reading's ``E_norm_MPa_other_reading,
    phase_deg_other_reading`` and run statistics (``dt_s, n_steps, wall_time_s,
    cpu_per_sphere_step_s, n_nlgs_steps, n_contact_steps`` (steps with an active contact),
    ``n_not_converged, max_iterations_used, n_broken_total``), the ``path`` the job took and why (``path_reason``), its linearity
    certificate (``cert_*``, :class:`asphalt_nscd.harmonic.orbit.Certificate`) and, for a
    verification job (``verification``), the orbit's ``E_norm_MPa_orbit, phase_deg_orbit`` and
    their differences to the time domain (``orbit_vs_time_domain_E_pct``, ``_phase_deg``).
    """
    from ..lab.en12697 import Specimen2PB, reduce_record

    a = record["attrs"]
    settings = json.loads(a["settings"])
    reading = force_reading or settings["force_reading"]
    other = "driver" if reading == "bonds" else "bonds"
    spec = Specimen2PB(**json.loads(a["specimen"]))
    f = float(a["frequency_Hz"])
    args: dict[str, Any] = dict(specimen=spec, frequency_Hz=f, window_cycles=window_cycles)
    row = {
        k: a[k] for k in ("mode", "sample", "temperature_C", "variant", "parameter", "factor", "table3_units") if k in a
    }
    row.update(reduce_record(record["time_s"], record["displacement_m"], record[f"force_{reading}_N"], **args))
    alt = reduce_record(record["time_s"], record["displacement_m"], record[f"force_{other}_N"], **args)
    s = record["stats"]
    row.update(
        {
            "start": a.get("start", "rest"),
            "n_cycles_simulated": float(a.get("n_cycles_simulated", settings["n_cycles"])),
            "iterations_mean": float(np.mean(record["stats"]["iterations"])),
            "force_reading": reading,
            "E_norm_MPa_other_reading": alt["E_norm_MPa"],
            "phase_deg_other_reading": alt["phase_deg"],
            "dt_s": float(a["dt_s"]),
            "n_steps": int(a["n_steps"]),
            "n_spheres": int(a["n_spheres"]),
            "n_bonds": int(a["n_bonds"]),
            "wall_time_s": float(a["wall_time_s"]),
            "cpu_time_s": float(a["cpu_time_s"]),
            "cpu_per_sphere_step_s": float(a["cpu_per_sphere_step_s"]),
            "n_nlgs_steps": int((s["linear"] == 0).sum()),
            "n_contact_steps": int((np.nan_to_num(s["n_active_contacts"]) > 0).sum()),
            "n_not_converged": int((s["converged"] == 0).sum()),
            "max_iterations_used": int(s["iterations"].max()),
            "n_broken_total": int(s["n_broken_total"][-1]),
        }
    )
    info = json.loads(a.get("start_info", "{}") or "{}")
    row.update({"path": a.get("path", "time_domain"), "path_reason": a.get("path_reason", "")})
    row.update(info.get("certificate") or {})
    orbit = info.get("orbit")
    row["verification"] = orbit is not None
    if orbit is not None:
        row.update(
            {
                "E_norm_MPa_orbit": orbit["E_norm_MPa"],
                "phase_deg_orbit": orbit["phase_deg"],
                "orbit_vs_time_domain_E_pct": 100.0 * (orbit["E_norm_MPa"] / row["E_norm_MPa"] - 1.0),
                "orbit_vs_time_domain_phase_deg": orbit["phase_deg"] - row["phase_deg"],
            }
        )
    return row
