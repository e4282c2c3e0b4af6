"""Dynamic stages of the preparation, run with the NSCD core (:mod:`asphalt_nscd.nscd`):
deposition under gravity, vibration of the top wall, bonded stabilisation.

Every stage returns the new positions (N, 3) m and a JSON-ready dict of run statistics
(steps, simulated time, unconverged steps, largest speed at the end, wall-clock time).

Choices
-------
* Deposition ends when the sphere speed falls below ``deposition.settle_velocity_m_s``
  after at least the free-fall time of the highest sphere, or after
  ``deposition.duration_s`` (the paper does not give the duration). The speed is measured
  by ``deposition.rest_measure``: ``max`` (the largest sphere speed) or ``rms`` (the
  root-mean-square speed of the layer). ``rms`` is the better-posed test for a large
  layer: a few rattlers (or the residual velocities of steps whose NLGS stopped at
  ``solver.max_iterations``) keep the largest speed above a small threshold long after the
  layer as a whole is at rest, and the vibration stage follows anyway.
* Vibration (see :mod:`.prepare`): ``vibration.form`` ``tap`` (default) is
  ``u_z = A (1 - cos 2 pi f t)`` from the layer top (the wall never goes below the initial
  top of the layer); ``sine`` is ``u_z = -A sin 2 pi f t`` (the wall pushes A into the
  layer every cycle).
* Stabilisation: bonds from :func:`.geometry.make_bonds` with the Burger's law
  ``stabilisation.*``; sphere-plate bonds get an infinite critical force (paper: "a large
  value of yield stress to avoid any bond breakage"), sphere-sphere bonds the paper's
  2.7 MPa yield stress. Bottom plate fixed, top plate free (its mass), gravity -z,
  friction ``friction_bonded``.
"""

from __future__ import annotations

import logging
import time
from typing import Any

import numpy as np

#: Steps between two checks of the rest criterion during deposition.
CHECK_EVERY = 25
#: When True, :func:`_run` shows a progress bar on stderr (tqdm; the CLI's --progress).
PROGRESS = False
#: shortest interval between two progress updates, s (keeps a job log short)
PROGRESS_INTERVAL_S = 10.0

log = logging.getLogger(__name__)


def _params(cfg: dict, dt: float, friction: float, **extra):
    from ..nscd import NSCDParameters

    return NSCDParameters(
        dt=dt,
        gravity=(0.0, 0.0, -cfg["gravity_m_s2"]),
        friction=friction,
        tolerance=cfg["solver"]["tolerance"],
        max_iterations=cfg["solver"]["max_iterations"],
        **extra,
    )


def box_plates(box, top=None):
    """The six fixed walls of the deposition box ``[0, L] x [0, W] x [0, H]``.

    ``top`` replaces the ceiling (a :class:`~asphalt_nscd.nscd.Plate`), e.g. a driven wall.
    """
    from ..nscd import Plate, Plates

    L, W, H = box
    walls = [
        Plate([0, 0, 0], [0, 0, 1]),
        Plate([0, 0, 0], [1, 0, 0]),
        Plate([L, 0, 0], [-1, 0, 0]),
        Plate([0, 0, 0], [0, 1, 0]),
        Plate([0, W, 0], [0, -1, 0]),
        top if top is not None else Plate([0, 0, H], [0, 0, -1]),
    ]
    return Plates(walls)


def _run(sim, n_steps: int, stop=None, label: str = "steps") -> dict:
    """Advance ``sim`` by up to ``n_steps``; ``stop(sim)`` checked every CHECK_EVERY steps.

    Returns a dict: steps, simulated and CPU/wall times, NLGS statistics over the NLGS steps
    (``mean_iterations``, ``max_iterations``, ``unconverged_steps``), and ``linear_steps``
    with their mean conjugate-gradient iterations (the bonded stabilisation's fast path)."""
    tic = time.perf_counter()
    cpu = time.process_time()
    unconverged = 0
    iterations = 0
    max_iterations = 0
    steps = 0
    linear = 0
    linear_iterations = 0
    from tqdm import tqdm

    bar = tqdm(total=int(n_steps), desc=label, unit="step", disable=not PROGRESS, mininterval=PROGRESS_INTERVAL_S)
    for k in range(int(n_steps)):
        st = sim.step()
        bar.update(1)
        steps += 1
        if st.solver == "linear":
            linear += 1
            linear_iterations += st.iterations
        else:
            unconverged += not st.converged
            iterations += st.iterations
            max_iterations = max(max_iterations, st.iterations)
        if PROGRESS and (k + 1) % CHECK_EVERY == 0:
            bar.set_postfix(
                sweeps=f"{iterations / max(steps - linear, 1):.0f}",
                contacts=st.n_contacts,
                unconverged=unconverged,
                refresh=False,
            )
        if stop is not None and (k + 1) % CHECK_EVERY == 0 and stop(sim):
            break
    bar.close()
    speed = np.linalg.norm(sim.spheres.velocity, axis=1)
    return {
        "steps": steps,
        "simulated_time_s": steps * sim.params.dt,
        "time_step_s": sim.params.dt,
        "unconverged_steps": int(unconverged),
        "mean_iterations": iterations / max(steps - linear, 1),
        "max_iterations": int(max_iterations),
        "linear_steps": int(linear),
        "mean_linear_iterations": linear_iterations / max(linear, 1),
        "max_speed_end_m_s": float(speed.max()) if speed.size else 0.0,
        "wall_clock_s": time.perf_counter() - tic,
        "cpu_s": time.process_time() - cpu,
    }


def deposit(position, radius, cfg: dict, geo: dict):
    """Pour the spheres under gravity in the closed box (friction ``friction_deposition``).

    Parameters
    ----------
    position : (N, 3) m, lattice positions; radius : (N,) m.
    cfg : sample config; geo : :func:`.settings.scaled_geometry` of it.

    Returns
    -------
    position : (N, 3) m, info : dict
    """
    from ..nscd import Simulation, Spheres

    dep = cfg["deposition"]
    spheres = Spheres.from_density(np.array(position, dtype=float), radius, cfg["density_deposition_kg_m3"])
    sim = Simulation(
        spheres, box_plates(geo["box"]), None, _params(cfg, dep["time_step_s"], cfg["friction_deposition"])
    )
    g = cfg["gravity_m_s2"]
    z_top = float(np.max(spheres.position[:, 2])) if spheres.n else 0.0
    t_fall = np.sqrt(2.0 * z_top / g) if g > 0 else 0.0
    v_rest = dep["settle_velocity_m_s"]
    measure = dep.get("rest_measure", "max")
    if measure not in ("max", "rms"):
        from ..io import InputError

        raise InputError(f"sample.deposition.rest_measure: expected 'max' or 'rms', got {measure!r}")

    def speed(s):
        v2 = (s.spheres.velocity**2).sum(1)
        return float(np.sqrt(v2.max() if measure == "max" else v2.mean())) if v2.size else 0.0

    def at_rest(s):
        return s.time >= t_fall and speed(s) < v_rest

    n_steps = int(np.ceil(dep["duration_s"] / dep["time_step_s"]))
    info = _run(sim, n_steps, at_rest, "deposition")
    info["rest_measure"] = measure
    info["rest_speed_end_m_s"] = speed(sim)
    info["at_rest"] = bool(info["rest_speed_end_m_s"] < v_rest)
    return sim.spheres.position.copy(), info


def vibrate(position, radius, cfg: dict, geo: dict):
    """Vibrate the top wall on the layer, then lift it and let the layer settle.

    Returns
    -------
    position : (N, 3) m, info : dict (with the layer top before and after).
    """
    from ..nscd import Plate, Simulation, Spheres

    vib = cfg["vibration"]
    r = np.asarray(radius, dtype=float)
    spheres = Spheres.from_density(np.array(position, dtype=float), r, cfg["density_deposition_kg_m3"])
    z0 = float(np.max(spheres.position[:, 2] + r))
    amp = vib["amplitude_mm"] * 1e-3
    omega = 2 * np.pi * vib["frequency_Hz"]
    if vib.get("form", "tap") == "sine":

        def disp(t):
            return np.array([0.0, 0.0, -amp * np.sin(omega * t)])
    else:

        def disp(t):
            return np.array([0.0, 0.0, amp * (1.0 - np.cos(omega * t))])

    # The mass of a driven plate only enters the reported driver force; a finite value
    # avoids inf * 0 in the core's driver-force formula.
    wall = Plate([0.0, 0.0, z0], [0.0, 0.0, -1.0], mode="driven", mass=1.0, displacement=disp)
    params = _params(cfg, vib["time_step_s"], cfg["friction_deposition"])
    info: dict[str, Any] = {"layer_top_before_mm": z0 * 1e3}
    if vib["duration_s"] > 0 and amp > 0:
        sim = Simulation(spheres, box_plates(geo["box"], top=wall), None, params)
        info["shaking"] = _run(sim, int(np.ceil(vib["duration_s"] / vib["time_step_s"])), label="vibration")
        spheres = sim.spheres
    if vib["settle_duration_s"] > 0:
        sim = Simulation(spheres, box_plates(geo["box"]), None, params)
        info["settling"] = _run(sim, int(np.ceil(vib["settle_duration_s"] / vib["time_step_s"])), label="settling")
        spheres = sim.spheres
    info["layer_top_after_mm"] = float(np.max(spheres.position[:, 2] + r)) * 1e3
    return spheres.position.copy(), info


def stabilise(
    position,
    radius,
    mass,
    plate_point,
    plate_normal,
    plate_mass,
    bonds: dict,
    cfg: dict,
    bonded_contact: str | None = None,
):
    """Bonded stabilisation of the flipped sample under gravity (``stabilisation.steps``).

    Parameters
    ----------
    position : (N, 3) m; radius, mass : (N,) m, kg; plate_point, plate_normal : (2, 3);
    plate_mass : (2,) kg (bottom inf = fixed, top free); bonds : dict of
    :func:`.geometry.make_bonds`; cfg : sample config.
    bonded_contact : NSCDParameters.bonded_contact (config ``nscd.bonded_contact``); None:
        the core's default ('after_break': an intact bond is its pair's only law, so the
        spheres cut by a plate plane are not closed contacts and the steps stay linear).

    Returns
    -------
    position : (N, 3) m, info : dict (max displacement, top-plate displacement, broken bonds,
    linear fast-path steps).
    """
    from ..nscd import Bonds, Plate, Plates, Simulation, Spheres
    from ..rheology.laws import GeneralizedBurgers

    st = cfg["stabilisation"]
    x0 = np.array(position, dtype=float)
    info: dict[str, Any] = {"steps": 0}
    if st["steps"] == 0:
        return x0, info
    m = np.asarray(mass, dtype=float)
    spheres = Spheres(position=x0.copy(), radius=radius, mass=m, inertia=0.4 * m * np.asarray(radius) ** 2)
    plates = Plates(
        [
            Plate(plate_point[0], plate_normal[0], mode="fixed"),
            Plate(plate_point[1], plate_normal[1], mode="free", mass=float(plate_mass[1])),
        ]
    )
    law = GeneralizedBurgers.burgers(Em=st["Em_Pa"], eta_m=st["eta_m_Pa_s"], Ek=st["Ek_Pa"], eta_k=st["eta_k_Pa_s"])
    bnd = Bonds.create(spheres, plates, bonds["i"], bonds["j"], law)
    bnd.r_crit[bnd.j < 0] = np.inf
    extra = {} if bonded_contact is None else {"bonded_contact": bonded_contact}
    sim = Simulation(spheres, plates, bnd, _params(cfg, st["time_step_s"], cfg["friction_bonded"], **extra))
    info = _run(sim, st["steps"], label="stabilisation")
    info["bonded_contact"] = sim.params.bonded_contact
    info["max_displacement_mm"] = float(np.max(np.linalg.norm(sim.spheres.position - x0, axis=1))) * 1e3
    info["top_plate_displacement_mm"] = float(np.linalg.norm(sim.plates.point[1] - plate_point[1])) * 1e3
    info["broken_bonds"] = int(sim.bonds.broken.sum())
    return sim.spheres.position.copy(), info
