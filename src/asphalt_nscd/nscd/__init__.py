"""Compiled NSCD core (numba): Moreau-Jean theta-method, Delassus blocks, nonlinear
Gauss-Seidel, Signorini-Coulomb contacts, generalized Burger's bonds (Eqs. 6-26).

Public API (stable; SI units; conventions in :mod:`.state`)
-----------------------------------------------------------
State::

    Spheres(position (N,3), radius (N,), mass (N,), inertia (N,), velocity, angular_velocity)
    Spheres.from_density(position, radius, density)          # mass inf = immobile sphere
    Plate(point (3,), normal (3,) inward, mode='fixed'|'free'|'driven', mass=inf,
          displacement=callable t -> (3,) | (times (T,), disp (T,3)))   # driven plates
    Plates([Plate, ...])                                       # infinite planes, translation only
    Bonds.create(spheres, plates, i, j, law: GeneralizedBurgers, nu=0.35, yield_stress=2.7e6)
        # j = sphere index or -1-k for plate k; rest state = current configuration
    NSCDParameters(dt, theta=0.5, gravity=(0,0,-9.81), friction=0.7, tolerance=1e-6,
                   convergence='quad'|'max'|'both', max_iterations=2000, relaxation=1.0,
                   alert_distance=None, fast_path=True, linear_solver='cg'|'direct',
                   linear_tolerance=1e-10)
    NSCDParameters.from_config(config['nscd'], dt, friction, gravity)

Time stepping::

    sim = Simulation(spheres, plates, bonds, params, external_force=None)
    st = sim.step()           # StepStats: time, solver ('nlgs'|'linear'), iterations,
                              # residual_quad, residual_max, converged, n_contacts,
                              # n_active_contacts, n_bonds, n_broken, n_broken_total,
                              # plate_force (P,3) N (spheres -> plate), driver_force (P,3) N
                              # (force the driver applies, incl. plate inertia), dissipated J
    df = sim.run(n_steps, callback=None)      # DataFrame of StepStats.as_row()
    sim.save_checkpoint("x.h5"); Simulation.load_checkpoint("x.h5", drivers=[...])
    sim.bonds.force (B,3) N, bonds.broken (B,), sim.contact_impulse (C,3) N s (/dt = force)

Helpers: ``detection.sphere_pairs(position, radius, max_gap)`` and
``detection.plate_pairs(...)`` (cell lists, O(N)) to find bonded pairs;
``verify.phase_error_table(law, omegas, dts, thetas)``; ``bench.run_bench(...)``.
CLI: ``asphalt-nscd verify -o verify.json``, ``asphalt-nscd bench --case bonded|granular``.
"""

from .checkpoint import read_checkpoint, write_checkpoint
from .moreau_jean import Simulation
from .state import (DRIVEN, FIXED, FREE, YIELD_STRESS, Bonds, NSCDParameters, Plate, Plates,
                    Spheres, StepStats, local_frames)

__all__ = ["Simulation", "Spheres", "Plate", "Plates", "Bonds", "NSCDParameters", "StepStats",
           "local_frames", "read_checkpoint", "write_checkpoint", "FIXED", "FREE", "DRIVEN",
           "YIELD_STRESS"]
