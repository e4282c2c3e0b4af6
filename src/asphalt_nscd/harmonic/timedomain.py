"""Time-domain check of the harmonic solver: the same sample, law and head motion run
through the NSCD core (:mod:`asphalt_nscd.nscd`), reduced by the same Eqs. 1-5.

Set-up (identical to the harmonic model with the same ``bond_kinematics`` and
``head_rotation``, passed to the NSCD core: ``NSCDParameters.bond_kinematics`` and, for a
free head, a top plate with ``rotation=True`` and the harmonic model's head inertia
(:func:`.network.head_inertia`, about ``plates/point[1]``)): no gravity, bottom plate fixed,
top plate driven with x(t) = A sin(w t) (mass = the sample file's top-plate mass, which
enters the driver force), bonds created from the sample configuration with the macro law scaled per bond
(``Bonds.create``: Eqs. 30-33, 8-11), Moreau-Jean theta-method with step ``dt``.

Reading: the forces of a step are means over the step, so they are sampled at the mid-step
time t - dt/2 together with the imposed displacement at that time (sampling them at the end
of the step would add a phase lag w dt / 2: 0.36 deg at 40 Hz and dt = 5e-5 s). The head
force is read as F = m a(t - dt/2) - plate_force_x, the bond reaction plus the exact inertia of
the imposed head motion (``force_reading="bonds"``, default). ``"driver"`` reads the core's
``StepStats.driver_force`` instead, whose plate-inertia term is evaluated from step
velocities; on samples where the head inertia dominates the force (small samples, high f)
it converges only to first order in dt (measured: 1.4 % on |E*| at 40 Hz, dt = 5e-5 s, on a
60-sphere sample, against 2e-5 with the "bonds" reading). Both readings are returned.
The record is reduced over its last ``window_cycles`` cycles by
:func:`asphalt_nscd.lab.en12697.reduce_record` (sinusoid + offset + drift fit), with the same
specimen (gamma, mu = 0.135 M + m) as the harmonic rows.

Duration: the transient of a Burger's network under imposed displacement decays with time
constants below max(eta_m/Em, eta_k/Ek); the run lasts
max(n_cycles periods, settle_factor x that bound), rounded up to whole cycles.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from ..io import InputError
from ..nscd.state import HEAD_AMPLITUDE_M, HEAD_ROTATIONS, YIELD_STRESS
from ..rheology.laws import POISSON_RATIO


def relaxation_bound_s(law) -> float:
    """Upper bound of the transient time constants, max(eta_m/Em, eta_k[i]/Ek[i]), s."""
    taus = [law.eta_m / law.Em] if np.isfinite(law.eta_m) else []
    taus += [c / e for e, c in zip(law.Ek, law.eta_k)]
    return float(max(taus)) if taus else 0.0


def time_domain_row(
    sample_path: str | Path,
    law,
    frequency_Hz: float,
    geometry_mm: dict,
    dt: float,
    amplitude: float = HEAD_AMPLITUDE_M,
    n_cycles: int = 5,
    settle_factor: float = 6.0,
    window_cycles: int = 1,
    theta: float = 0.5,
    tolerance: float = 1e-8,
    nu: float = POISSON_RATIO,
    max_steps: int = 2_000_000,
    force_reading: str = "bonds",
    bond_kinematics: str = "contact",
    head_rotation: str = "free",
) -> dict:
    """Run the time-domain 2PB test of a sample at one (law, f, dt) and reduce it.

    Parameters
    ----------
    sample_path : path of the sample file (docs/design.md).
    law : GeneralizedBurgers (Pa, Pa s), the macro law.
    frequency_Hz : f, Hz.  geometry_mm : ``b_mm, B_mm, e_mm, h_mm`` for gamma (Eq. 3).
    dt : time step, s.  amplitude : A, m.
    n_cycles, settle_factor, window_cycles : duration and analysis window (module docstring).
    theta, tolerance : Moreau-Jean theta and NLGS tolerance (fast path is exact).
    force_reading : {"bonds", "driver"}, see the module docstring.
    bond_kinematics : {"contact", "barycentre"}; head_rotation : {"free", "clamped"} — the
        model (:mod:`.solver`), passed to the NSCD core (module docstring).

    Returns
    -------
    dict
        The reduced row of ``reduce_record`` plus ``force_reading``, the other reading's
        ``F0_N_other_reading, psi_deg_other_reading, E_norm_MPa_other_reading,
        phase_deg_other_reading``, and ``dt_s, n_steps, duration_s, wall_time_s,
        cpu_per_sphere_step_s, n_nlgs_steps``.

    Raises
    ------
    InputError
        if the run would exceed ``max_steps`` steps.
    ValueError
        on an unknown ``force_reading``.
    """
    if force_reading not in ("bonds", "driver"):
        raise ValueError(f"force_reading must be 'bonds' or 'driver', got {force_reading!r}")
    if head_rotation not in HEAD_ROTATIONS:
        raise ValueError(f"head_rotation must be one of {HEAD_ROTATIONS}, got {head_rotation!r}")
    from ..lab.en12697 import Specimen2PB, reduce_record
    from ..nscd import NSCDParameters
    from ..sample.store import read_sample

    sample = read_sample(sample_path)
    plate_mass = sample.plate_mass
    omega = 2.0 * np.pi * frequency_Hz
    params = NSCDParameters(
        dt=dt, theta=theta, gravity=(0.0, 0.0, 0.0), tolerance=tolerance, bond_kinematics=bond_kinematics
    )
    sim = build_simulation(
        sample, law, lambda t: (amplitude * np.sin(omega * t), 0.0, 0.0), params, head_rotation=head_rotation, nu=nu
    )
    spheres = sim.spheres
    period = 1.0 / frequency_Hz
    duration = max(n_cycles * period, settle_factor * relaxation_bound_s(law))
    duration = np.ceil(duration / period - 1e-9) * period
    n_steps = int(round(duration / dt))
    if n_steps > max_steps:
        raise InputError(
            f"time-domain run of {n_steps} steps (f={frequency_Hz} Hz, dt={dt} s) exceeds max_steps={max_steps}"
        )
    t = np.empty(n_steps)
    force = np.empty(n_steps)
    driver = np.empty(n_steps)
    n_nlgs = 0
    t0 = time.perf_counter()
    for k in range(n_steps):
        st = sim.step()
        t[k] = st.time - 0.5 * dt
        force[k] = -st.plate_force[1, 0]
        driver[k] = st.driver_force[1, 0]
        n_nlgs += st.solver != "linear"
    wall = time.perf_counter() - t0
    specimen = Specimen2PB(M_kg=float(spheres.mass.sum()), m_kg=float(plate_mass[1]), **geometry_mm)
    x = amplitude * np.sin(omega * t)
    force = force - float(plate_mass[1]) * omega**2 * x  # + m a, a = -w^2 x exactly
    raw = reduce_record(t, x, driver, specimen, frequency_Hz, window_cycles=window_cycles)
    row = reduce_record(t, x, force, specimen, frequency_Hz, window_cycles=window_cycles)
    if force_reading == "driver":
        row, raw = raw, row
    row["force_reading"] = force_reading
    row.update({f"{k}_other_reading": raw[k] for k in ("F0_N", "psi_deg", "E_norm_MPa", "phase_deg")})
    row.update(
        {
            "dt_s": dt,
            "n_steps": n_steps,
            "duration_s": float(duration),
            "wall_time_s": wall,
            "cpu_per_sphere_step_s": wall / (n_steps * spheres.n),
            "n_nlgs_steps": int(n_nlgs),
        }
    )
    return row


def held_spheres(
    sample, bond_kinematics: str = "contact", head_rotation: str = "free", nu: float = POISSON_RATIO
) -> np.ndarray:
    """Mask (N,) of the spheres the bond network holds: every sphere but (1) the spheres no
    chain of bonds ties to a plate (a sphere or a cluster floating inside the sample: it carries
    no load in the test and, under gravity, falls through the sample -- 3 mm in the 25 ms of a
    40 Hz cycle -- into spheres it then pushes) and (2) the dangling mechanisms of the
    ``contact`` kinematics, the clusters of weakly held spheres
    (:meth:`asphalt_nscd.harmonic.solver.HarmonicSystem.mechanism_modes`) that hang by a
    single bond from the rest of the sample (a sphere held by one bond, a pair held by one),
    found again after each removal until none is left. Such a cluster carries no load in the
    linear test (nothing passes through it), and under gravity its linearised bond lets it
    turn without limit about the bond's contact point (a pendulum without a restoring force:
    about 400 rad in 0.35 s for a 2 mm sphere), through its neighbours. A weakly held sphere
    on a load path (two bonds, a chain link) stays: its only zero mode is a spin about the
    line through its bonds (``campaign.test.mechanisms`` says how its weight meets it). The
    ``barycentre`` kinematics has no mechanisms; its floating spheres are dropped too."""
    from ..sample.store import subsample
    from .network import network_from_sample
    from .solver import HarmonicSystem

    keep = np.ones(sample.radius.size, bool)
    while True:
        sub = subsample(sample, keep)
        system = HarmonicSystem(
            network_from_sample(sub),
            nu=nu,
            bond_kinematics=bond_kinematics,
            head_rotation=head_rotation,
            regularisation=0.0,
        )
        i, j = sub.bonds["i"], sub.bonds["j"]
        dropped = [np.flatnonzero(~system.active)]  # no chain of bonds to a plate
        if bond_kinematics != "contact":
            modes = []
        else:
            modes = system.mechanism_modes()
        for _, _, _, spheres in modes:
            inside = np.zeros(sub.radius.size, bool)
            inside[spheres] = True
            external = inside[i] != ((j >= 0) & inside[np.maximum(j, 0)])  # one end in the cluster
            if int(external.sum()) <= 1:
                dropped.append(spheres)
        if not sum(len(d) for d in dropped):
            return keep
        keep[np.flatnonzero(keep)[np.concatenate(dropped)]] = False


def build_simulation(
    sample,
    law,
    displacement,
    params,
    head_rotation: str = "clamped",
    nu: float = POISSON_RATIO,
    yield_stress: float = YIELD_STRESS,
):
    """The NSCD simulation of the 2PB test on ``sample`` (SampleData): its spheres (a copy of
    the positions: the run moves them), the bottom plate fixed, the top plate (the head, its
    mass from the sample) driven by ``displacement(t) -> (x, y, z)`` (m) and, when
    ``head_rotation == 'free'``, free to rotate with the steel cuboid's inertia
    (:func:`asphalt_nscd.harmonic.network.network_from_sample`); bonds of the sample with the
    macro ``law`` (GeneralizedBurgers, Pa, Pa s), Poisson ratio ``nu`` and ``yield_stress``
    (Pa; inf: unbreakable); ``params`` (NSCDParameters) of the run. The one builder of the
    campaign's jobs (:func:`asphalt_nscd.campaign.twopb.build_simulation`), the time-domain
    check of the harmonic solution and its benchmark. The spheres the bond network does not
    hold under ``params.bond_kinematics`` (:func:`held_spheres`) are left out of the test; the
    simulation's ``n_mechanisms_dropped`` says how many.

    Raises
    ------
    InputError if the head is free to rotate but has no positive finite inertia.
    ValueError on an unknown ``head_rotation``.
    """
    from ..nscd import Bonds, Plate, Plates, Simulation, Spheres
    from ..sample.store import subsample
    from .network import network_from_sample

    if head_rotation not in HEAD_ROTATIONS:
        raise ValueError(f"head_rotation must be one of {HEAD_ROTATIONS}, got {head_rotation!r}")
    keep = held_spheres(sample, params.bond_kinematics, head_rotation, nu)
    n_dropped = int((~keep).sum())
    if n_dropped:
        sample = subsample(sample, keep)
    spheres = Spheres(
        position=np.array(sample.position, dtype=float), radius=sample.radius, mass=sample.mass, inertia=sample.inertia
    )
    head: dict[str, Any] = {}
    if head_rotation == "free":
        inertia = network_from_sample(sample).plate_inertia
        assert inertia is not None  # the network of a sample has its head's inertia
        if not np.all((inertia > 0) & np.isfinite(inertia)):
            raise InputError(
                f"head_rotation 'free': the head has no positive finite rotational "
                f"inertia (top-plate mass {sample.plate_mass[1]} kg, moments "
                f"{inertia} kg m²)"
            )
        head = {"rotation": True, "inertia": inertia}
    plates = Plates(
        [
            Plate(sample.plate_point[0], sample.plate_normal[0], mode="fixed"),
            Plate(
                sample.plate_point[1],
                sample.plate_normal[1],
                mode="driven",
                mass=float(sample.plate_mass[1]),
                displacement=displacement,
                **head,
            ),
        ]
    )
    bonds = Bonds.create(spheres, plates, sample.bonds["i"], sample.bonds["j"], law, nu=nu, yield_stress=yield_stress)
    sim = Simulation(spheres, plates, bonds, params)
    sim.n_mechanisms_dropped = n_dropped
    return sim
