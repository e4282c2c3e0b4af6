"""Harmonic (frequency-domain) solver of a bonded sample: the exact periodic steady state of
the discrete model under the 2PB head motion, one complex sparse solve per (T, f).

Public API (SI inside; MPa, degrees, Hz, degC at the edges)::

    from asphalt_nscd.sample.store import read_sample, specimen_geometry_mm  # the sample store
    from asphalt_nscd.harmonic.network import network_from_sample
    from asphalt_nscd.harmonic.solver import HarmonicSystem
    from asphalt_nscd.harmonic.response import harmonic_rows

    sample = read_sample("results/samples/s1.h5")
    system = HarmonicSystem(network_from_sample(sample), nu=0.35,   # rheology.laws.POISSON_RATIO
                            bond_kinematics="contact", head_rotation="free")  # the defaults
    sol = system.solve_law(law, frequency_Hz=10.0, inertia="full")   # law: any object with
    sol.force, sol.psi_deg, sol.mu_kg                                 # complex_modulus(omega)
    rows = harmonic_rows(system, law, 15.0, [3, 10, 40], specimen_geometry_mm(sample))  # Eqs. 1-5
    system.solve(kn, kt, omega)        # per-bond complex stiffnesses (B,) N/m (general laws)

Bond kinematics: ``contact`` (6 DOF per sphere, bond force at the contact point with torques;
default) or ``barycentre`` (3 DOF, no torque: the NSCD core, which spuriously stiffens bending);
head rotation ``free`` (default, the cantilever of EN 12697-26 Eq. 3) or ``clamped``. See
:mod:`.solver`.

Modules: :mod:`.network` (sample -> bond network), :mod:`.solver` (assembly, solvers,
content of the force, the mechanisms and the spheres the network holds), :mod:`.response` (EN 12697-26 rows, macro law, network factor),
:mod:`.ordering` (METIS nested-dissection ordering of the sparse factorisations),
:mod:`.timedomain` (the same test through the NSCD core, on the 2PB rig of
:mod:`asphalt_nscd.sample.rig`), :mod:`.periodic` (the periodic steady state the 2PB test may
start in), :mod:`.analysis` (sensitivity, comparison, network factor tables, benchmark),
:mod:`.figures` (their figures), :mod:`.cli` (subcommands).
"""
