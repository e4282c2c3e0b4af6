"""Time-domain check of the harmonic solver: the same sample, law and head motion run
through the NSCD core (:mod:`asphalt_nscd.nscd`), reduced by the same Eqs. 1-5.

Set-up: the 2PB rig of the campaign's jobs (:func:`asphalt_nscd.sample.rig.setup`, the
spheres the bond network holds, :func:`.solver.held_spheres`), identical to the harmonic
model with the same ``bond_kinematics`` and ``head_rotation`` (``NSCDParameters.bond_kinematics``
and, for a free head, the rig's head inertia): no gravity, bottom plate fixed, top plate driven
with x(t) = A sin(w t) (mass = the sample file's top-plate mass, which enters the driver force),
bonds with the macro law scaled per bond (Eqs. 30-33, 8-11), Moreau-Jean theta-method with
step ``dt``.

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
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io import InputError
from ..nscd.state import HEAD_AMPLITUDE_M, HEAD_ROTATIONS
from ..rheology.laws import POISSON_RATIO


@dataclass
class HeadSignals:
    """What :func:`head_signals` records of a run, one value per step (n,).

    time_s : mid-step times, s. reaction_N : the head bonds' reaction on the head along the
    driven axis, N (minus ``StepStats.plate_force[1, axis]``). driver_N : the driver's force
    along that axis, N (``StepStats.driver_force[1, axis]``). n_nonlinear : steps not solved on
    the linear fast path (an active contact or a broken bond). wall_s, cpu_s : time of the steps, s.
    """

    time_s: np.ndarray
    reaction_N: np.ndarray
    driver_N: np.ndarray
    n_nonlinear: int
    wall_s: float
    cpu_s: float


def head_signals(sim, n_steps: int, axis: int) -> HeadSignals:
    """Step the 2PB or uniaxial simulation ``sim`` (:class:`asphalt_nscd.nscd.Simulation`, head =
    plate 1) ``n_steps`` times by the Moreau-Jean scheme and record its head signals along
    ``axis`` (0: x, the 2PB's driven axis; 2: z, the uniaxial test's), forces read at mid-step."""
    time_s, reaction, driver = np.empty(n_steps), np.empty(n_steps), np.empty(n_steps)
    n_nonlinear = 0
    wall0, cpu0 = time.perf_counter(), time.process_time()
    dt = float(sim.params.dt)
    for k in range(n_steps):
        st = sim.step()
        time_s[k] = st.time - 0.5 * dt
        reaction[k] = -st.plate_force[1, axis]
        driver[k] = st.driver_force[1, axis]
        n_nonlinear += st.solver != "linear"
    return HeadSignals(
        time_s, reaction, driver, int(n_nonlinear), time.perf_counter() - wall0, time.process_time() - cpu0
    )


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
    sim = simulation(sample, law, lambda t: (amplitude * np.sin(omega * t), 0.0, 0.0), params, head_rotation, nu)
    spheres = sim.spheres
    period = 1.0 / frequency_Hz
    duration = max(n_cycles * period, settle_factor * relaxation_bound_s(law))
    duration = np.ceil(duration / period - 1e-9) * period
    n_steps = int(round(duration / dt))
    if n_steps > max_steps:
        raise InputError(
            f"time-domain run of {n_steps} steps (f={frequency_Hz} Hz, dt={dt} s) exceeds max_steps={max_steps}"
        )
    steps = head_signals(sim, n_steps, axis=0)
    t, force, driver, wall = steps.time_s, steps.reaction_N, steps.driver_N, steps.wall_s
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
            "n_nlgs_steps": steps.n_nonlinear,
        }
    )
    return row


def simulation(sample, law, displacement, params, head_rotation: str = "clamped", nu: float = POISSON_RATIO):
    """The 2PB rig of ``sample`` (:func:`asphalt_nscd.sample.rig.setup`) holding the spheres the
    bond network holds under ``params.bond_kinematics`` (:func:`.solver.held_spheres`),
    unbreakable bonds: the time-domain twin of the harmonic model."""
    from ..sample import rig
    from . import solver

    held = solver.held_spheres(sample, params.bond_kinematics, head_rotation, nu)
    return rig.setup(sample, law, displacement, params, head_rotation, nu, held=held)


def maxwell_equivalent(k, omega: float) -> tuple[np.ndarray, np.ndarray]:
    """(K, C): the Maxwell element (spring K, N/m, in series with a dashpot C, N s/m) whose
    complex stiffness at ``omega`` (rad/s) is ``k`` (array, N/m): 1/k = 1/K + 1/(i omega C), so
    K = |k|^2 / Re k and C = |k|^2 / (omega Im k). Any linear viscoelastic bond at one frequency.

    Raises ValueError unless every Re k > 0 and Im k > 0 (a dissipative solid)."""
    k = np.asarray(k, complex)
    if not (np.all(k.real > 0) and np.all(k.imag > 0)):
        raise ValueError("maxwell_equivalent: every stiffness needs Re k > 0 and Im k > 0")
    a2 = np.abs(k) ** 2
    return a2 / k.real, a2 / (omega * k.imag)


def uniaxial_time_domain_row(
    sample,
    kn,
    kt,
    frequency_Hz: float,
    amplitude: float = 1e-7,
    steps_per_cycle: int = 400,
    settle_factor: float = 5.0,
    n_cycles: int = 4,
    theta: float = 0.5,
    tolerance: float = 1e-10,
    max_steps: int = 2_000_000,
) -> dict:
    """The uniaxial test of a cube stepped in time by the NSCD core: bottom plate fixed, head
    clamped and driven along the height (z) with A sin(w t), no gravity, each bond the Maxwell
    element of its complex stiffness at f (:func:`maxwell_equivalent`; normal ``kn``, tangential
    ``kt``, (B,) complex N/m, in the order of ``sample.bonds``), unbreakable. The time-domain twin
    of :meth:`.solver.HarmonicSystem.solve` with ``axis=2, inertia="full"`` (its ``reaction``) at
    that one frequency, for the spheres the bond network holds (:func:`.solver.held_spheres`).

    Duration: max(n_cycles periods, settle_factor x the longest bond time constant C/K), whole
    cycles; the head's bond reaction (forces read at mid-step, as :func:`time_domain_row`) is fitted
    over the last cycle by a sinusoid, an offset and a drift, which absorbs what is left of the
    start's offset decaying with those time constants (on a 294-sphere forecast sample at a bond
    time constant of 51 / w, 1, 2 and 4 time constants gave the same |E*| within 3e-6 %).

    Returns
    -------
    dict
        ``stiffness`` (complex, N/m: the reaction's amplitude over A, phase lead positive),
        ``dt_s``, ``n_steps``, ``duration_s``, ``n_nonlinear_steps`` (steps on which a contact was
        active: 0 certifies the linear model), ``cpu_s``.

    Raises
    ------
    InputError
        if the run would exceed ``max_steps`` steps.
    ValueError
        if ``kn``/``kt`` do not have one value per bond, or a stiffness is not dissipative.
    """
    from ..nscd import NSCDParameters
    from ..rheology.laws import GeneralizedBurgers
    from ..sample import rig
    from . import solver

    kn, kt = np.asarray(kn, complex), np.asarray(kt, complex)
    n_bonds = int(np.asarray(sample.bonds["i"]).size)
    if kn.shape != (n_bonds,) or kt.shape != (n_bonds,):
        raise ValueError(f"kn, kt: expected ({n_bonds},) complex, got {kn.shape} and {kt.shape}")
    omega = 2.0 * np.pi * frequency_Hz
    held = solver.held_spheres(sample, "contact", "clamped")
    i, j = np.asarray(sample.bonds["i"]), np.asarray(sample.bonds["j"])
    kept = held[i] & ((j < 0) | held[np.maximum(j, 0)])  # the bonds store.subsample keeps, in order
    Kn, Cn = maxwell_equivalent(kn[kept], omega)
    Kt, Ct = maxwell_equivalent(kt[kept], omega)
    period, dt = 1.0 / frequency_Hz, 1.0 / (frequency_Hz * steps_per_cycle)
    params = NSCDParameters(dt=dt, theta=theta, gravity=(0.0, 0.0, 0.0), tolerance=tolerance)
    sim = rig.setup(
        sample,
        GeneralizedBurgers(Em=1.0, eta_m=1.0),  # replaced bond by bond below
        lambda t: (0.0, 0.0, amplitude * np.sin(omega * t)),
        params,
        "clamped",
        yield_stress=np.inf,
        held=held,
    )
    sim.bonds.Km[:] = np.column_stack([Kn, Kt])
    sim.bonds.Cm[:] = np.column_stack([Cn, Ct])
    sim.bonds.Kinf[:] = 0.0
    tau = float(max((Cn / Kn).max(), (Ct / Kt).max()))
    n_periods = np.ceil(max(n_cycles * period, settle_factor * tau) / period - 1e-9)
    n_steps = int(round(n_periods * steps_per_cycle))
    if n_steps > max_steps:
        raise InputError(
            f"uniaxial time-domain run of {n_steps} steps (f={frequency_Hz} Hz) exceeds max_steps={max_steps}"
        )
    steps = head_signals(sim, n_steps, axis=2)
    t, force = steps.time_s, steps.reaction_N
    last = t >= t[-1] - period + 0.5 * dt
    basis = np.column_stack([np.sin(omega * t[last]), np.cos(omega * t[last]), np.ones(last.sum()), t[last] - t[-1]])
    a, b, _, _ = np.linalg.lstsq(basis, force[last], rcond=None)[0]
    return {
        "stiffness": complex(a + 1j * b) / amplitude,
        "dt_s": dt,
        "n_steps": n_steps,
        "duration_s": float(n_periods * period),
        "n_nonlinear_steps": steps.n_nonlinear,
        "cpu_s": steps.cpu_s,
    }
