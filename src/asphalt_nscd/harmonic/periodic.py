"""Periodic start of the numerical 2PB test: the time-discrete steady state of the linear sample.

While no bond breaks and no contact closes, the bonded 2PB sample is a linear system, so its
periodic steady state under the head motion u(t) = A sin(w t) can be computed directly and
the test started in it (``campaign.test.start: periodic``): one cycle then measures what the
paper's from-rest protocol reaches after its transient.

* :func:`theta_laplace` -- the effective Laplace variable of the Moreau-Jean theta-method,
  s_h = (z - 1) / (h (theta z + 1 - theta)), z = exp(i w h). The harmonic problem
  (K(s_h) + s_h^2 M) U = F (:meth:`asphalt_nscd.harmonic.solver.HarmonicSystem.solve_law`,
  ``laplace``) gives the exact periodic orbit of the step map, not of the continuous
  equations, so a run started on it has no transient.
* :func:`network_of` -- the harmonic model of a simulation from the core's own bonds (rest
  lengths, contact points, lever arms as ``Bonds.create`` computed them), without the
  harmonic solver's rotational regularisation.
* :func:`periodic_state` -- the initial state at t = 0 (head at u(0) = 0, moving at +A w):
  sphere positions, velocities, angular velocities, head rotation and every bond's
  displacement, force and internal variables (Maxwell dashpot ``delta_c``, Kelvin-Voigt
  units ``delta_k``), every quantity y_0 = Re(-i Y) of its phasor Y. ``breaks`` reports a
  steady force amplitude at or above a bond's strength R_crit: the test is then not linear
  and :func:`asphalt_nscd.campaign.twopb.start_test` starts it from rest.
* :func:`gravity_state` -- the steady state under the sample's weight with the head held,
  superposed on the periodic one when the simulation has gravity: steady creep for a liquid
  bond law, static equilibrium for a solid one; zero modes of weakly held spheres
  (mechanisms) are taken out of the load, and a static solve whose residual exceeds
  :data:`GRAVITY_RESIDUAL_MAX` is not used (gravity then starts from rest).
* :func:`apply_periodic_state` -- writes a state into a Simulation at step 0.

The cost is one harmonic solution of the sample (a real factorisation and a few GMRES
iterations). ``asphalt-nscd periodic-check`` (:func:`asphalt_nscd.campaign.periodic.check_case`)
measures the equivalence with the from-rest protocol; the derivation, the measurements and
the treatment of gravity and mechanisms are in docs/choices.md ("Periodic start of the 2PB
test").
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..rheology.laws import POISSON_RATIO


def theta_laplace(frequency_Hz: float, dt: float, theta: float) -> complex:
    """Effective Laplace variable s_h (1/s) of the Moreau-Jean theta-method at f (module
    docstring): (z - 1) / (dt (theta z + 1 - theta)), z = exp(i 2 pi f dt); exactly
    i (2/dt) tan(pi f dt) at theta = 1/2.

    Raises
    ------
    ValueError
        if f dt >= 1/2 (fewer than 2 steps per period) or theta is outside [0.5, 1].
    """
    if not (0.5 <= theta <= 1.0):
        raise ValueError(f"theta must lie in [0.5, 1], got {theta}")
    phase = 2.0 * math.pi * float(frequency_Hz) * float(dt)
    if not (0.0 < phase < math.pi):
        raise ValueError(f"f dt = {frequency_Hz * dt} must lie in (0, 1/2)")
    if theta == 0.5:
        return 1j * (2.0 / dt) * math.tan(0.5 * phase)
    z = complex(math.cos(phase), math.sin(phase))
    return (z - 1.0) / (dt * (theta * z + 1.0 - theta))


@dataclass
class PeriodicState:
    """Initial state of a periodic start (arrays in the core's layout, SI units).

    position, velocity, angular_velocity : (N, 3) m, m/s, rad/s.
    head_rotation, head_angular_velocity : (3,) rad, rad/s.
    bond_displacement, bond_force, delta_c : (B, 3) m, N, m (bond local frames).
    delta_k : (B, NK, 3) m.
    laplace : complex, 1/s — s_h used (or i w with ``continuous``).
    force_ratio : max over bonds of the steady force amplitude / R_crit (0 if unbreakable).
    breaks : bool — force_ratio >= 1 (the linear steady state would break bonds).
    solve_s : wall time of the harmonic solve, s; gmres_iterations : int.
    head_force : complex, N — the harmonic head force phasor (x), for information.
    gravity : GravityState superposed (None: the simulation has no gravity).
    phasors : the orbit's phasors at t = 0, y_n = Re(Y z^n) + gravity part at step n (z =
        exp(i w dt)): ``displacement``, ``rotation`` (N, 3), ``head_rotation``,
        ``head_translation`` (3,), ``bond_force``, ``bond_displacement`` (B, 3) complex (SI;
        :mod:`asphalt_nscd.harmonic.orbit` certifies and samples the orbit from them).
    """

    position: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    head_rotation: np.ndarray
    head_angular_velocity: np.ndarray
    bond_displacement: np.ndarray
    bond_force: np.ndarray
    delta_c: np.ndarray
    delta_k: np.ndarray
    laplace: complex
    force_ratio: float
    breaks: bool
    solve_s: float
    gmres_iterations: int
    head_force: complex
    gravity: "GravityState | None" = None
    phasors: dict | None = None


#: how the weakly held spheres' zero modes meet gravity (``campaign.test.mechanisms``): ``supported``
#: -- a force on their barycentres cancels their weight along the zero modes, in the steady state
#: and in the time domain alike (:func:`mechanism_support`); ``free`` -- nothing holds them: they
#: fall along their zero modes (a sphere held by two bonds swings about the line through both
#: until it meets a neighbour), which the steady state leaves out and the certificate must cover
MECHANISMS = ("supported", "free")

#: most iterative refinements of the static solve under gravity (the network is ill-conditioned:
#: its softest modes are 1e8 times softer than its stiffest on small samples); they stop once the
#: residual is below GRAVITY_RESIDUAL_MAX or stops falling
GRAVITY_REFINEMENTS = 8
#: largest relative residual of the static solve under gravity for the state to be used: the
#: rest of the load acts along the network's softest (near-zero) modes, which no solve resolves;
#: measured on the paper-scale samples 5e-8 to 8e-8 (a few soft rotational modes of spheres with
#: 3-5 bonds), against the head force an unbalanced force 1e-7 of it or less, and the orbit then
#: within 2e-4 % of the time domain (docs/choices.md); the certificate bounds that ratio per job
GRAVITY_RESIDUAL_MAX = 1e-6


@dataclass
class GravityState:
    """Steady state of the bonded 2PB sample under its weight with the head held
    (:func:`gravity_state`; arrays in the core's layout, SI units).

    displacement, velocity, angular_velocity : (N, 3) m, m/s, rad/s — from the rest
        configuration at t = 0 (the spheres' rotations enter only the bonds, ``bond_*``).
    head_rotation, head_angular_velocity : (3,) rad, rad/s.
    bond_displacement, bond_force, delta_c : (B, 3); delta_k : (B, NK, 3) (bond local frames).
    creep : bool — steady creep (liquid chain) or static equilibrium (solid chain).
    residual : relative residual |P F_g - G U_1| / |P F_g| of the refined static solve (P
        removes the load along the mechanisms' zero modes).
    n_mechanisms : zero modes of weakly held clusters (module docstring, :data:`MECHANISMS`).
    support_force : (N, 3) N -- with ``mechanisms='supported'``, the force on the barycentres of
        the weakly held spheres that cancels their weight along their zero modes (the time domain
        applies it as the simulation's external force); zero otherwise.
    mechanism_acceleration : (N, 3) m/s^2 -- with ``mechanisms='free'``, the free fall of the
        weakly held spheres along their zero modes under their weight, which the steady state
        leaves out (the certificate adds 1/2 a T^2 to their motion); zero otherwise.
    failed : the reason the steady state is not used (zero state: gravity from rest), or ''.
    sag_m : largest displacement at t = 0, m; solve_s : wall time, s.
    load_N : Euclidean norm of the weights (N, the load whose relative ``residual`` is left).
    """

    displacement: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    head_rotation: np.ndarray
    head_angular_velocity: np.ndarray
    bond_displacement: np.ndarray
    bond_force: np.ndarray
    delta_c: np.ndarray
    delta_k: np.ndarray
    creep: bool
    residual: float
    n_mechanisms: int
    failed: str
    sag_m: float
    solve_s: float
    support_force: np.ndarray | None = None
    mechanism_acceleration: np.ndarray | None = None
    load_N: float = 0.0

    def info(self) -> dict:
        """JSON-ready summary (the record's ``start_info['gravity']``)."""
        sup = self.support_force if self.support_force is not None else np.zeros((0, 3))
        return {
            "creep": self.creep,
            "residual": self.residual,
            "n_mechanisms": self.n_mechanisms,
            "failed": self.failed,
            "sag_m": self.sag_m,
            "solve_s": self.solve_s,
            "support_force_max_N": float(np.sqrt((sup**2).sum(axis=1)).max()) if len(sup) else 0.0,
            "n_supported_spheres": int((np.abs(sup).sum(axis=1) > 0).sum()) if len(sup) else 0,
        }


def network_of(sim):
    """The harmonic model (:class:`asphalt_nscd.harmonic.network.BondNetwork`) of a 2PB
    simulation at rest, from the core's own state: positions, radii, masses and rotational
    inertias of its spheres, its plates (bottom fixed, top = plate 1 with its mass and
    rotational inertia) and its bonds' i, j, l0, r_min as ``Bonds.create`` computed them from
    the positions. (The sample file's stored ``bonds/l0`` may differ from the stored
    positions, e.g. by up to 0.8 % for head bonds of the default samples, where the
    stabilisation moved the spheres after bonding; the core takes the positions as the rest
    state, so the periodic state must too.)"""
    import dataclasses

    from .network import network_from_arrays

    sph, pls, b = sim.spheres, sim.plates, sim.bonds
    net = network_from_arrays(
        sph.position,
        sph.mass,
        pls.normal[:2],
        [np.inf, pls.mass[1]],
        b.i,
        b.j,
        b.l0,
        b.r_min,
        radius=sph.radius,
        rotational_inertia=sph.inertia,
        plate_point=pls.point[:2],
        head_size_m=(1.0, 1.0),
    )
    head = pls.inertia[1] if pls.rotates[1] else np.zeros(3)
    return dataclasses.replace(net, plate_inertia=np.array(head, float))


def harmonic_system(sim, head_rotation: str = "free", nu: float = POISSON_RATIO, reference: dict | None = None):
    """The :class:`asphalt_nscd.harmonic.solver.HarmonicSystem` of :func:`network_of` (sim) that the
    periodic and gravity states solve: the core's bond kinematics, the head's rotation (clamped
    under the barycentre kinematics, where the head's rotation is not modelled), Poisson's ratio
    ``nu`` (Eqs. 8-11) and no rotational regularisation (the inertia makes the dynamic matrix
    regular, and the core has no such spring). ``reference``: that system's
    :meth:`~asphalt_nscd.harmonic.solver.HarmonicSystem.reference_state` computed before (a
    rig state), whose G and ordering it takes instead of assembling them.

    Raises
    ------
    ValueError for a ``reference`` that does not fit the network.
    """
    from .solver import HarmonicSystem

    p = sim.params
    head = head_rotation if p.bond_kinematics == "contact" else "clamped"
    network = network_of(sim)
    return HarmonicSystem(
        network,
        nu=nu,
        bond_kinematics=p.bond_kinematics,
        head_rotation=head,
        regularisation=0.0,
        reference=reference,
    )


def _bond_displacement(bonds, X, TH, THp, up, contact: bool) -> np.ndarray:
    """Displacement (B, 3) of every bond in its local frame for sphere displacements X and
    rotations TH (N, 3), head rotation THp (3,) and head translation up (3,), real or
    complex: frame (Delta_i - Delta_j), Delta = X + Theta x arm (contact kinematics) or X."""
    i, j = bonds.i, bonds.j
    sph = j >= 0
    di = X[i] + (np.cross(TH[i], bonds.arm_i) if contact else 0.0)
    dj = np.zeros_like(di)
    dj[sph] = X[j[sph]] + (np.cross(TH[j[sph]], bonds.arm_j[sph]) if contact else 0.0)
    top = j == -2
    dj[top] = up + (np.cross(THp[None, :], bonds.arm_j[top]) if contact else 0.0)
    return np.einsum("bcd,bd->bc", bonds.frame, di - dj)


def _bond_laws(bonds):
    """Km, Cm, Kinf (B, 3) and Kk, Ck (B, NK, 3) of the bonds per local component."""
    comp = [0, 1, 1]  # normal, tangential, tangential
    return (bonds.Km[:, comp], bonds.Cm[:, comp], bonds.Kinf[:, comp], bonds.Kk[:, :, comp], bonds.Ck[:, :, comp])


def mechanism_support(system, mass, gravity) -> tuple[np.ndarray, np.ndarray, int]:
    """The weakly held spheres of a HarmonicSystem (its ``mechanism_modes``, the system's sphere
    layout) under the weight of spheres of ``mass`` (N,) kg in ``gravity`` (3,) m/s^2:
    (support force (N, 3) N, free-fall acceleration (N, 3) m/s^2, number of zero modes).

    Per cluster with zero modes V (its free DOFs, translation rows T): the support is the weight
    projected onto the span of T, f_s = -T (T^T T)^+ T^T f_g, so that V^T (f_g + f_s) = 0 (no
    zero mode is loaded) with the smallest force; the free fall is T a, a = (V^T M V)^-1 V^T f_g
    (the mass matrix's M of the DOFs)."""
    n = len(mass)
    support = np.zeros((n, 3))
    accel = np.zeros((n, 3))
    d = system.dof_per_sphere
    g = np.asarray(gravity, float)
    n_modes = 0
    for dofs, V, _, spheres in system.mechanism_modes():
        n_modes += V.shape[1]
        k = len(spheres)
        trans = (np.arange(k)[:, None] * d + np.arange(3)).ravel()  # the clusters' translation rows in dofs
        T = V[trans]  # (3k, m)
        fg = (mass[spheres][:, None] * g[None, :]).ravel()  # (3k,)
        support[spheres] = (-T @ np.linalg.pinv(T.T @ T) @ (T.T @ fg)).reshape(k, 3)
        MV = system.mass_free[dofs, None] * V
        a = np.linalg.solve(V.T @ MV, T.T @ fg)
        accel[spheres] = (T @ a).reshape(k, 3)
    return support, accel, n_modes


def support_force(
    sim, head_rotation: str = "free", nu: float = POISSON_RATIO, system=None, unit: "GravityUnit | None" = None
) -> np.ndarray:
    """The support force (N, 3) N of the weakly held spheres of a 2PB simulation under its gravity
    (:func:`mechanism_support` on :func:`network_of` (sim)); zero without gravity or mechanisms.
    ``system``: its :func:`harmonic_system`, built before (optional); ``unit``: its
    :func:`gravity_unit` with the same ``head_rotation`` and ``nu`` (e.g. from a rig state), whose
    support force it returns without solving (optional)."""
    p = sim.params
    g = np.asarray(p.gravity, float)
    if not np.any(g != 0.0) or p.bond_kinematics != "contact":
        return np.zeros((sim.spheres.n, 3))
    if unit is not None:
        return unit.support_force.copy()
    if system is None:
        system = harmonic_system(sim, head_rotation, nu)
    return mechanism_support(system, sim.spheres.mass, g)[0]


@dataclass
class GravityUnit:
    """The law-free part of :func:`gravity_state`: the solution U_1 of G U_1 = F_g (reference
    stiffness G of the bonds, :meth:`asphalt_nscd.harmonic.solver.HarmonicSystem._reference_blocks`,
    stiffened along the mechanisms' zero modes; F_g the weights, less the load along those modes).
    Every bond of a job follows one macro law, so the gravity state of any law is U_1 scaled by
    that law's compliance (:func:`gravity_state`): U_1 depends on the sample, the kinematics,
    ``nu``, the gravity and ``mechanisms`` only, and a campaign computes it once per sample
    (:func:`gravity_unit`; its file, :mod:`asphalt_nscd.campaign.twopb`).

    displacement, rotation : (N, 3) m/Pa-like unit solution of the spheres (translation, rotation).
    head_rotation : (3,) the head's.
    residual, n_mechanisms, failed : as :class:`GravityState`.
    support_force, mechanism_acceleration : (N, 3) N and m/s^2, :func:`mechanism_support`
        (both computed; :func:`gravity_state` keeps the one its ``mechanisms`` uses).
    """

    displacement: np.ndarray
    rotation: np.ndarray
    head_rotation: np.ndarray
    residual: float
    n_mechanisms: int
    failed: str
    support_force: np.ndarray
    mechanism_acceleration: np.ndarray


def gravity_unit(
    sim, head_rotation: str = "free", nu: float = POISSON_RATIO, system=None, mechanisms: str = "supported"
) -> GravityUnit:
    """The law-free part U_1 of the gravity state of a 2PB simulation (:class:`GravityUnit`;
    arguments as :func:`gravity_state`, whose factorisation of G it is). All zero when the
    gravity is zero.

    Raises
    ------
    ValueError on an unknown ``mechanisms``.
    """
    if mechanisms not in MECHANISMS:
        raise ValueError(f"mechanisms must be one of {MECHANISMS}, got {mechanisms!r}")
    p = sim.params
    contact = p.bond_kinematics == "contact"
    head = head_rotation if contact else "clamped"
    sph = sim.spheres
    n = sph.n
    g = np.asarray(p.gravity, float)
    X1 = np.zeros((n, 3))
    TH1 = np.zeros((n, 3))
    THp1 = np.zeros(3)
    support, accel = np.zeros((n, 3)), np.zeros((n, 3))
    residual, n_mech, failed = 0.0, 0, ""
    if np.any(g != 0.0):
        import scipy.sparse as sp

        if system is None:
            system = harmonic_system(sim, head_rotation, nu)
        d = system.dof_per_sphere
        act = np.flatnonzero(system.active)
        rhs = np.zeros(system.n_free)
        rhs[: d * act.size].reshape(-1, d)[:, :3] = sph.mass[act, None] * g[None, :]
        # zero modes of weakly held spheres (mechanisms), cluster by cluster (:func:`mechanism_support`):
        # their weight along the zero modes is cancelled by the support force (supported) or left out
        # of the load, the spheres' free fall (free); G is stiffened along them
        support, accel, n_mech = mechanism_support(system, sph.mass, g)
        if mechanisms == "supported":
            rhs[: d * act.size].reshape(-1, d)[:, :3] += support[act]
        extra_r, extra_c, extra_v = [], [], []
        for dofs, V, scale, _ in system.mechanism_modes():
            if mechanisms == "free":
                MV = system.mass_free[dofs, None] * V
                rhs[dofs] -= MV @ np.linalg.solve(V.T @ MV, V.T @ rhs[dofs])
            extra_r.append(np.repeat(dofs, dofs.size))
            extra_c.append(np.tile(dofs, dofs.size))
            extra_v.append(scale * (V @ V.T).ravel())
        g0 = system._reference_blocks()["ff"]
        a = g0
        if extra_v:
            a = (
                g0
                + sp.csc_matrix(
                    (np.concatenate(extra_v), (np.concatenate(extra_r), np.concatenate(extra_c))), shape=g0.shape
                )
            ).tocsc()
        u = np.zeros_like(rhs)
        try:
            lu = system.factorise(a, "G + mechanisms (gravity)")
            u = lu.solve(rhs)
            norm = max(float(np.linalg.norm(rhs)), 1e-300)
            residual = float(np.linalg.norm(rhs - g0 @ u) / norm)
            for _ in range(GRAVITY_REFINEMENTS):
                if residual <= GRAVITY_RESIDUAL_MAX:
                    break
                refined = u + lu.solve(rhs - g0 @ u)
                r_new = float(np.linalg.norm(rhs - g0 @ refined) / norm)
                if not r_new < residual:
                    break
                u, residual = refined, r_new
        except RuntimeError as exc:
            residual, failed = float("inf"), f"factorisation failed ({exc})"
        if not residual <= GRAVITY_RESIDUAL_MAX:
            failed = failed or (
                f"residual {residual:.3g} > {GRAVITY_RESIDUAL_MAX:g} (a mechanism of several "
                "spheres?): gravity starts from rest"
            )
            u = np.zeros_like(rhs)
        q = u[: d * act.size].reshape(-1, d)
        X1[act] = q[:, :3]
        if contact:
            TH1[act] = q[:, 3:]
        if head == "free":
            THp1 = u[d * act.size : d * act.size + 3].copy()
    return GravityUnit(
        displacement=X1,
        rotation=TH1,
        head_rotation=THp1,
        residual=residual,
        n_mechanisms=n_mech,
        failed=failed,
        support_force=support,
        mechanism_acceleration=accel,
    )


def gravity_state(
    sim,
    law,
    head_rotation: str = "free",
    nu: float = POISSON_RATIO,
    system=None,
    mechanisms: str = "supported",
    unit: GravityUnit | None = None,
) -> GravityState:
    """Steady state of the 2PB simulation under its gravity with the head held (module
    docstring): steady creep for a liquid bond law, static equilibrium for a solid one.

    Parameters
    ----------
    sim : asphalt_nscd.nscd.Simulation at rest (as :func:`periodic_state`), gravity
        ``sim.params.gravity`` (m/s^2).
    law : GeneralizedBurgers (Pa, Pa s), the macro law of the bonds.
    head_rotation, nu : as :func:`periodic_state`.
    system : the HarmonicSystem of :func:`network_of` (sim) with these options and no
        rotational regularisation, to reuse (optional; :func:`periodic_state` passes its own).
    mechanisms : :data:`MECHANISMS` -- ``supported``: the weight of the weakly held spheres along
        their zero modes is cancelled by ``support_force`` (which the time domain must apply too);
        ``free``: that load is left out of the steady state and its free fall reported
        (``mechanism_acceleration``).
    unit : the :func:`gravity_unit` of this simulation with these options, computed before
        (optional; without it the function computes it, factorising G).

    Returns
    -------
    GravityState (all zero when the gravity is zero).

    Raises
    ------
    ValueError if the law is not a generalized Burger's model, on an unknown ``mechanisms``, or
    for a ``unit`` of another number of spheres.
    """
    tic = time.perf_counter()
    if not all(hasattr(law, k) for k in ("Em", "eta_m", "Ek", "eta_k", "E_inf")):
        raise ValueError(f"gravity_state: {type(law).__name__} is not a generalized Burger's law")
    if mechanisms not in MECHANISMS:
        raise ValueError(f"mechanisms must be one of {MECHANISMS}, got {mechanisms!r}")
    p = sim.params
    contact = p.bond_kinematics == "contact"
    b = sim.bonds
    n = sim.spheres.n
    g = np.asarray(p.gravity, float)
    liquid = np.isfinite(law.eta_m) and law.E_inf == 0.0
    if liquid:  # steady creep: U_0 = c0 U_1 (springs), V = U_1 / eta_m (Maxwell dashpot)
        c0, c1 = 1.0 / law.Em + sum(1.0 / e for e in law.Ek), 1.0 / law.eta_m
    else:  # static equilibrium at the static modulus E(0)
        chain = 0.0 if np.isfinite(law.eta_m) else 1.0 / (1.0 / law.Em + sum(1.0 / e for e in law.Ek))
        c0, c1 = 1.0 / (law.E_inf + chain), 0.0
    if unit is None:
        unit = gravity_unit(sim, head_rotation=head_rotation, nu=nu, system=system, mechanisms=mechanisms)
    elif unit.displacement.shape != (n, 3):
        raise ValueError(f"gravity_state: the unit state has {unit.displacement.shape[0]} spheres, the simulation {n}")
    X1, TH1, THp1 = unit.displacement, unit.rotation, unit.head_rotation
    residual, n_mech, failed = unit.residual, unit.n_mechanisms, unit.failed
    support, accel = unit.support_force, unit.mechanism_acceleration
    X0, TH0, THp0 = c0 * X1, c0 * TH1, c0 * THp1
    delta = _bond_displacement(b, X0, TH0, THp0, np.zeros(3), contact)
    Km, Cm, Kinf, Kk, Ck = _bond_laws(b)
    dashpot = np.isfinite(Cm)
    if liquid:  # dashpots at 0, springs and Kelvin-Voigt units at the steady force
        r_ch = -delta / (1.0 / Km + (1.0 / Kk).sum(axis=1))
        d_c = np.zeros_like(delta)
    else:
        j0 = 1.0 / Km + (1.0 / Kk).sum(axis=1)
        r_ch = np.where(dashpot, 0.0, -delta / j0)
        d_c = np.where(dashpot, delta, 0.0)
    d_k = -r_ch[:, None, :] / Kk
    return GravityState(
        displacement=X0,
        velocity=c1 * X1,
        angular_velocity=c1 * TH1,
        head_rotation=THp0,
        head_angular_velocity=c1 * THp1,
        bond_displacement=delta,
        bond_force=r_ch - Kinf * delta,
        delta_c=d_c,
        delta_k=np.ascontiguousarray(d_k),
        creep=bool(liquid),
        residual=residual,
        n_mechanisms=n_mech,
        failed=failed,
        sag_m=float(np.abs(X0).max()) if n else 0.0,
        solve_s=time.perf_counter() - tic,
        support_force=support if mechanisms == "supported" else np.zeros((n, 3)),
        mechanism_acceleration=accel if mechanisms == "free" else np.zeros((n, 3)),
        load_N=float(np.linalg.norm(sim.spheres.mass * np.linalg.norm(g))) if n else 0.0,
    )


def periodic_state(
    sim,
    law,
    frequency_Hz: float,
    amplitude_m: float,
    head_rotation: str = "free",
    nu: float = POISSON_RATIO,
    continuous: bool = False,
    system=None,
    mechanisms: str = "supported",
    gravity: GravityUnit | None = None,
) -> PeriodicState:
    """Periodic steady state of the 2PB test built by :func:`asphalt_nscd.campaign.twopb.build_simulation` (module
    docstring), before its first step.

    Parameters
    ----------
    sim : asphalt_nscd.nscd.Simulation at rest (time 0, bonds' rest = current configuration),
        bottom plate 0 fixed, top plate 1 driven; its harmonic model is :func:`network_of`.
    law : GeneralizedBurgers, macro law of the bonds (Pa, Pa s) as given to Bonds.create.
    frequency_Hz, amplitude_m : head motion u(t) = A sin(2 pi f t), Hz and m.
    head_rotation : 'free' | 'clamped' (TwoPBSettings.head_rotation).
    nu : Poisson's ratio of Eqs. 8-11.
    continuous : solve at s = i w (the continuous steady state) instead of s_h (for the
        measurement of what the discrete correction buys).
    system : the :func:`harmonic_system` of ``sim`` with these options, to reuse (optional;
        e.g. built from a rig state's reference).
    mechanisms : of :func:`gravity_state` (:data:`MECHANISMS`).
    gravity : the :func:`gravity_unit` of ``sim`` with these options, computed before (optional:
        :func:`gravity_state`'s ``unit``).

    Returns
    -------
    PeriodicState
    """
    tic = time.perf_counter()
    p = sim.params
    contact = p.bond_kinematics == "contact"
    if system is None:
        system = harmonic_system(sim, head_rotation, nu)
    s = 1j * 2.0 * math.pi * frequency_Hz if continuous else theta_laplace(frequency_Hz, p.dt, p.theta)
    sol = system.solve_law(law, frequency_Hz, amplitude=amplitude_m, inertia="full", solver="reuse", laplace=s)
    rot = -1j  # phasor of A sin(w t) from that of A cos(w t)
    X = rot * sol.displacement
    TH = rot * (sol.rotation if sol.rotation is not None else np.zeros_like(sol.displacement))
    THp = rot * (sol.head_rotation if sol.head_rotation is not None else np.zeros(3, complex))
    up = rot * np.array([amplitude_m, 0.0, 0.0], complex)
    if not contact:
        TH = np.zeros_like(TH)
        THp = np.zeros(3, complex)
    b = sim.bonds
    delta = _bond_displacement(b, X, TH, THp, up, contact)
    Km, Cm, Kinf, Kk, Ck = _bond_laws(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_c = np.where(np.isinf(Cm), 0.0, 1.0 / (s * Cm))
    J = 1.0 / Km + inv_c + (1.0 / (Kk + s * Ck)).sum(axis=1)
    r_ch = -delta / J
    force = r_ch - Kinf * delta
    d_c = -r_ch * inv_c
    d_k = -r_ch[:, None, :] / (Kk + s * Ck)
    g = gravity_state(
        sim, law, head_rotation=head_rotation, nu=nu, system=system, mechanisms=mechanisms, unit=gravity
    )  # zero without gravity
    # peak force per bond: the steady (gravity) force plus the periodic amplitude
    amp_n = np.abs(g.bond_force[:, 0]) + np.abs(force[:, 0])
    amp_t = np.sqrt(g.bond_force[:, 1] ** 2 + g.bond_force[:, 2] ** 2) + np.sqrt(
        np.abs(force[:, 1]) ** 2 + np.abs(force[:, 2]) ** 2
    )
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = np.where(np.isfinite(b.r_crit), np.maximum(amp_n, amp_t) / b.r_crit, 0.0)
    ratio = float(ratios.max()) if len(ratios) else 0.0
    return PeriodicState(
        position=sim.spheres.position + g.displacement + np.real(X),
        velocity=g.velocity + np.real(s * X),
        angular_velocity=g.angular_velocity + np.real(s * TH),
        head_rotation=g.head_rotation + np.real(THp),
        head_angular_velocity=g.head_angular_velocity + np.real(s * THp),
        bond_displacement=g.bond_displacement + np.real(delta),
        bond_force=g.bond_force + np.real(force),
        delta_c=g.delta_c + np.real(d_c),
        delta_k=np.ascontiguousarray(g.delta_k + np.real(d_k)),
        laplace=complex(s),
        force_ratio=ratio,
        breaks=ratio >= 1.0,
        solve_s=time.perf_counter() - tic,
        gmres_iterations=int(getattr(system, "last_gmres_iterations", 0)),
        head_force=complex(rot * sol.force[0]),
        gravity=g if np.any(p.gravity) else None,
        phasors={
            "displacement": X,
            "rotation": TH,
            "head_rotation": THp,
            "head_translation": up,
            "bond_force": force,
            "bond_displacement": delta,
            "frequency_Hz": float(frequency_Hz),
            "amplitude_m": float(amplitude_m),
            "gravity_state": g,
        },
    )


def apply_periodic_state(sim, state: PeriodicState) -> None:
    """Set the state arrays of a Simulation at rest (time 0) to ``state`` in place.

    Only the public state of the core is written (Spheres, Plates and Bonds fields); the
    top plate (index 1) gets the head rotation when it rotates.

    Raises
    ------
    ValueError if the simulation has advanced or the shapes differ.
    """
    if sim.step_index != 0:
        raise ValueError("a periodic start applies to a simulation at step 0")
    sph, b, pls = sim.spheres, sim.bonds, sim.plates
    if (
        state.position.shape != sph.position.shape
        or state.bond_force.shape != b.force.shape
        or state.delta_k.shape != b.delta_k.shape
    ):
        raise ValueError("periodic state and simulation differ in shape")
    sph.position[:] = state.position
    sph.velocity[:] = state.velocity
    sph.angular_velocity[:] = state.angular_velocity
    if pls.n > 1 and pls.rotates[1]:
        pls.rotation[1] = state.head_rotation
        pls.angular_velocity[1] = state.head_angular_velocity
    b.displacement[:] = state.bond_displacement
    b.force[:] = state.bond_force
    b.delta_c[:] = state.delta_c
    b.delta_k[:] = state.delta_k
