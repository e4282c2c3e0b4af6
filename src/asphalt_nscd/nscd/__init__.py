"""Compiled NSCD core (numba): Moreau-Jean theta-method, Delassus blocks, nonlinear
Gauss-Seidel, Signorini-Coulomb contacts, generalized Burger's bonds (Eqs. 6-26).

Public API (stable; SI units; conventions in :mod:`.state`)
-----------------------------------------------------------
State::

    Spheres(position (N,3), radius (N,), mass (N,), inertia (N,), velocity, angular_velocity)
    Spheres.from_density(position, radius, density)          # mass inf = immobile sphere
    Plate(point (3,), normal (3,) inward, mode='fixed'|'free'|'driven', mass=inf,
          displacement=callable t -> (3,) | (times (T,), disp (T,3)),   # driven plates
          rotation=False, inertia=inf (scalar or (3,) kg m², about point))  # free rotation
    Plates([Plate, ...])   # infinite planes; .angular_velocity, .rotation (P,3) if rotating
    Bonds.create(spheres, plates, i, j, law: GeneralizedBurgers, nu=POISSON_RATIO (0.35, rheology.laws),
                 yield_stress=YIELD_STRESS (2.7e6 Pa))
        # j = sphere index or -1-k for plate k; rest state = current configuration
    NSCDParameters(dt, theta=0.5, gravity=(0,0,-9.81), friction=0.7, tolerance=1e-6,
                   convergence='quad'|'max'|'both', max_iterations=2000, relaxation=1.0,
                   alert_distance=None, fast_path=True, linear_solver='cg'|'direct',
                   linear_tolerance=1e-10, bond_kinematics='contact'|'barycentre')

Time stepping::

    sim = Simulation(spheres, plates, bonds, params, external_force=None)
    st = sim.step()           # StepStats: time, solver ('nlgs'|'linear'), iterations,
                              # residual_quad, residual_max, converged, n_contacts,
                              # n_active_contacts, n_bonds, n_broken, n_broken_total,
                              # plate_force (P,3) N (spheres -> plate), driver_force (P,3) N
                              # (force the driver applies, incl. plate inertia from the exact
                              # imposed acceleration, theta-averaged; none if mass inf),
                              # dissipated J
    df = sim.run(n_steps, callback=None)      # DataFrame of StepStats.as_row()
    write_checkpoint(sim, "x.h5"); read_checkpoint("x.h5", drivers=[...])  # callable drivers again
    sim.bonds.force (B,3) N, bonds.broken (B,), sim.contact_impulse (C,3) N s (/dt = force)
    sim.plate_torque (P,3) N m  # bond torque on each plate about its point, last step

Choices (details in the module docstrings)
------------------------------------------
* theta = 0.5 by default (second order, no numerical damping of the bonded dynamics; the
  phase error vs omega dt and theta is measured by ``verify.phase_error_table``).
* Contacts: Signorini on U_n + max(g,0)/h (LMGC90 IQS-like), Coulomb on the 3D cone solved
  exactly (diagonal isotropic Delassus block of spheres and planes; local_laws.py).
* Bonds: ``bond_kinematics='contact'`` (default) — the bond acts at its contact point c
  (middle of the gap on the line of centres) with lever arms c - x (fixed, small strain):
  its force carries torques, a rigid rotation of a bonded pair strains no bond, the
  Delassus block is a full 3x3 and the linear fast path has 6 DOF per sphere;
  ``'barycentre'`` — the former core: force at the barycentres, no torque (the tangential
  springs resist rigid rotations: a 2PB sample is ~90x too stiff in bending). Same options
  as asphalt_nscd.harmonic. Frame of the initial configuration (small strain); generalized
  Burger's law integrated by the theta-method (theta = 1 is the
  paper's Eq. 26); breakage when |R_n| or |R_t| > R_crit, then Eqs. 6-7; a bonded pair
  that also touches gets both forces.
* Plates may rotate freely about their reference point (``rotation=True``; e.g. the 2PB
  head, driven in translation): bonds exert torques on them ('contact' kinematics);
  contacts ignore the plate rotation (documented in moreau_jean.py).
* Steps with no active contact and no breakage are solved as a linear system (linear.py,
  preconditioned CG; 'direct' = symmetric-mode SuperLU, exact but slower per step at
  12 000 spheres), otherwise NLGS; ``StepStats.solver`` says which. The configured CG
  residual 1e-7 resolves the phase angle to ~1e-5 deg (tests/unit/test_nscd_linear.py).
* Kernels: numba without reference counting (_jit.py: 5-15x faster bond and contact
  loops); ``NSCDParameters.threads`` > 1 runs the conjugate gradient on numba threads
  (same results to round-off; default 1).
* ``StepStats.driver_force`` = m (a_theta - g) - plate_force, a_theta = theta a(t+) +
  (1-theta) a(t-) of the imposed motion: consistent with plate_force to O(dt²).

Helper shared with other steps: ``linear.splu_symmetric(a, permutation=None)`` (SuperLU,
symmetric mode, MMD(A^T+A) ordering, or a caller's fill-reducing ordering such as METIS
nested dissection, returning a ``linear.PermutedLU``) for sparse SPD matrices.

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
