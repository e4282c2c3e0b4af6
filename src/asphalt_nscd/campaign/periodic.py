"""Periodic start of the numerical 2PB test: the time-discrete steady state of the linear sample.

Why
---
From rest (the paper's protocol: 5 cycles) the head's sudden start excites the sample's
elastic modes and the slow relaxation of its bonds; the last cycle is measured once that
transient has died out. While no bond breaks and no contact closes, the bonded sample is a
linear system, so its periodic steady state under u(t) = A sin(w t) can be computed directly
and the test started *in* it: one cycle then measures what the from-rest run reaches after
its transient (``campaign.test.start: periodic``, ``campaign.test.periodic_cycles``).

The steady state of the theta-method, not of the continuous equations
---------------------------------------------------------------------
Every first-order relation of a Moreau-Jean step has the form y+ - y- = h (theta ydot+ +
(1 - theta) ydot-) (positions from velocities, velocities from the impulse of the bond
forces, the bond displacement from the relative velocity, the Maxwell dashpot and each
Kelvin-Voigt unit: :mod:`asphalt_nscd.nscd.local_laws`), and the driven head sits exactly at
u(t_n) at the end of every step. A periodic solution y_n = Re(Y z^n), z = exp(i w h), of the
step map therefore satisfies the continuous equations with every time derivative i w
replaced by the effective Laplace variable of the scheme::

    s_h = (z - 1) / (h (theta z + 1 - theta)),    theta = 1/2:  s_h = i (2/h) tan(w h / 2)

i.e. the harmonic problem (K(s_h) + s_h^2 M) U = F with the bond law's modulus E(s_h)
(:meth:`asphalt_nscd.harmonic.solver.HarmonicSystem.solve_law`, ``laplace``). This is
the *exact* periodic orbit of the discrete map, to the conjugate-gradient tolerance of the
fast path, provided the harmonic model is the core's: it is built from the simulation's own
bonds (:func:`network_of`: l0, contact points and lever arms as ``Bonds.create`` computed
them, the head's inertia) and without the harmonic solver's rotational regularisation (the
inertia keeps the dynamic matrix regular). A run started on it has no transient: on the
40-sphere test lattice the state after one period equals the initial one to 1e-10
(tests/unit/test_campaign_periodic.py), and on the 221-sphere default sample cycles 1, 2 and 3
after the start reduce to the same |E*| to 1e-11. The continuous steady state (s = i w)
would leave an O((w h)^2) transient (``asphalt-nscd periodic-check --continuous``; at 500
steps per cycle it changes |E*| by < 0.015 % and Phi by < 0.003 deg, docs/choices.md).
Hence one cycle is enough (``periodic_cycles: 1``).

Initial state (t = 0, head at u(0) = 0, moving at +A w)
-------------------------------------------------------
With the phasors of a head displacement A cos(w t) and u(t) = A sin(w t) = Re(-i A e^{iwt}),
every quantity is y_0 = Re(-i Y):

* sphere positions x_0 = x_rest + Re(-i X), velocities Re(-i s_h X), angular velocities
  Re(-i s_h Theta); the head's rotation Re(-i Theta_p) and angular velocity Re(-i s_h
  Theta_p) (free head; the 'barycentre' kinematics exerts no torque, so its head does not
  rotate and the harmonic model is solved with a clamped head);
* per bond (local frame n, t, s of :class:`asphalt_nscd.nscd.Bonds`, the core's sign
  convention U = velocity of i minus that of j at the contact point): the displacement
  delta = frame (Delta_i - Delta_j), Delta = X + Theta x arm (contact kinematics) or X
  (barycentre); per direction the chain compliance J = 1/Km + 1/(s_h Cm) + sum_k
  1/(Kk + s_h Ck), the chain force R_ch = -delta / J, the Maxwell dashpot's displacement
  delta_c = -R_ch / (s_h Cm), each Kelvin-Voigt unit's delta_k = -R_ch / (Kk + s_h Ck) and
  the bond force R = R_ch - Kinf delta (state.Bonds fields ``displacement, delta_c, delta_k,
  force``).

Validity (checked, else the run starts from rest): the test must be linear. If the
steady-state force amplitude of a bond reaches its strength R_crit (|R_n| or
sqrt(|R_t|^2 + |R_s|^2), an upper bound of the tangential peak), the bond would break and
the state is not the test's steady state: :func:`periodic_state` reports it
(``breaks``) and :func:`asphalt_nscd.campaign.twopb.run_test` falls back to the rest start
with ``n_cycles`` (recorded in the record and row as ``start``). 
Gravity (the simulation's ``params.gravity``, on in the paper's protocol) is a constant load
and, the test being linear, its response superposes on the periodic one. Left to start
from rest, it is a transient of its own: switched on at t = 0, the sample's weight excites
its lowest modes, which the bonds' small loss (a few degrees of phase at low temperature)
damps over many cycles (at paper scale about 1 % and 1-2 deg at 40 Hz after one cycle).
The periodic start therefore begins in the steady state under gravity with the head held
(:func:`gravity_state`), the limit of the paper's stabilisation "by activating gravity"
with the bond law of the test temperature, plus the periodic state: the head force of the
first cycle is then the converged one, the constant weight adding only an offset. The
steady state under gravity is the exact fixed point of the step map for a constant load:

* a liquid chain (Maxwell dashpot, E_inf = 0): steady creep. Every bond carries the static
  force of the sample's weight (constant), the Kelvin-Voigt units have crept to R/Kk, and
  the Maxwell dashpots flow at R/Cm, so every sphere moves at a constant velocity
  V = U_1 / eta_m with U_1 = G^-1 F_g (G the network's stiffness per unit modulus, F_g the
  weights): positions x_0 + n h V, all forces constant, exactly integrated by the
  theta-method;
* a solid chain (E_inf > 0, or no dashpot): static equilibrium U_1 / E(0), the chain's
  force relaxed to zero when it has a dashpot.

Every bond law of the campaign is a multiple a_b of one macro law (Eqs. 30-33), so one
solve with G (the core's network, no regularisation) gives both, refined
(:data:`GRAVITY_REFINEMENTS` steps). G is singular where a sphere is a mechanism: a sphere
held by one bond rolls about the bond's contact point, one held by two spins about the line
through both (at paper scale a dozen of ~9,000 spheres). Each such motion v is a zero mode of
the whole network (it strains no bond), so it carries no force in the linear test and is
moved by its weight alone, from either start in the same way. The steady state is therefore
computed on the rest of the network: the part of the weight that accelerates the zero modes V,
M V a with a = (V^T M V)^-1 V^T F_g (their free fall), is removed from the load, and
G + c V V^T (c the cluster's own stiffness scale) is factorised, which changes nothing on the
other modes; the zero modes start at rest and fall, as from rest (``n_mechanisms`` in the
record). If the refined residual still exceeds
:data:`GRAVITY_RESIDUAL_MAX` (a mechanism of several spheres that no sphere shows alone) the
steady state is not used: gravity then starts from rest, as in the paper's protocol
(``failed`` in the record). Spheres of clusters bonded to no plate fall freely from either
start and are left at rest.

The solve costs one harmonic solution of the sample (a real factorisation and 4-14 GMRES
iterations; ``solve_s`` in the record): 0.05-0.17 s on the 221-sphere default sample and
0.5-0.6 s of CPU on a 1,641-sphere one, i.e. 5-10 steps of a measured-mode job
(``campaign-bench --per-job`` counts it).

``asphalt-nscd periodic-check`` (:func:`check_case`) measures the equivalence on any sample
and list of (mode, T, f): the table of docs/choices.md.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass

import numpy as np

from ..rheology.laws import POISSON_RATIO

START_MODES = ("rest", "periodic")


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


#: iterative refinements of the static solve under gravity (the network is ill-conditioned:
#: its softest modes are 1e8 times softer than its stiffest on small samples)
GRAVITY_REFINEMENTS = 2
#: largest relative residual of the static solve under gravity for the state to be used
GRAVITY_RESIDUAL_MAX = 1e-8


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
    n_mechanisms : zero modes of weakly held clusters taken out of the load (module docstring).
    failed : the reason the steady state is not used (zero state: gravity from rest), or ''.
    sag_m : largest displacement at t = 0, m; solve_s : wall time, s.
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

    def info(self) -> dict:
        """JSON-ready summary (the record's ``start_info['gravity']``)."""
        return {"creep": self.creep, "residual": self.residual, "n_mechanisms": self.n_mechanisms,
                "failed": self.failed, "sag_m": self.sag_m, "solve_s": self.solve_s}


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

    from ..harmonic.network import network_from_arrays

    sph, pls, b = sim.spheres, sim.plates, sim.bonds
    net = network_from_arrays(sph.position, sph.mass, pls.normal[:2], [np.inf, pls.mass[1]], b.i, b.j,
                              b.l0, b.r_min, radius=sph.radius, rotational_inertia=sph.inertia,
                              plate_point=pls.point[:2], head_size_m=(1.0, 1.0))
    head = pls.inertia[1] if pls.rotates[1] else np.zeros(3)
    return dataclasses.replace(net, plate_inertia=np.array(head, float))


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
    return (bonds.Km[:, comp], bonds.Cm[:, comp], bonds.Kinf[:, comp], bonds.Kk[:, :, comp],
            bonds.Ck[:, :, comp])


def gravity_state(sim, law, head_rotation: str = "free", nu: float = POISSON_RATIO) -> GravityState:
    """Steady state of the 2PB simulation under its gravity with the head held (module
    docstring): steady creep for a liquid bond law, static equilibrium for a solid one.

    Parameters
    ----------
    sim : asphalt_nscd.nscd.Simulation at rest (as :func:`periodic_state`), gravity
        ``sim.params.gravity`` (m/s^2).
    law : GeneralizedBurgers (Pa, Pa s), the macro law of the bonds.
    head_rotation, nu : as :func:`periodic_state`.

    Returns
    -------
    GravityState (all zero when the gravity is zero).

    Raises
    ------
    ValueError if the law is not a generalized Burger's model.
    """
    from ..harmonic.solver import HarmonicSystem

    tic = time.perf_counter()
    if not all(hasattr(law, k) for k in ("Em", "eta_m", "Ek", "eta_k", "E_inf")):
        raise ValueError(f"gravity_state: {type(law).__name__} is not a generalized Burger's law")
    p = sim.params
    contact = p.bond_kinematics == "contact"
    head = head_rotation if contact else "clamped"
    sph, b = sim.spheres, sim.bonds
    n = sph.n
    g = np.asarray(p.gravity, float)
    liquid = np.isfinite(law.eta_m) and law.E_inf == 0.0
    if liquid:  # steady creep: U_0 = c0 U_1 (springs), V = U_1 / eta_m (Maxwell dashpot)
        c0, c1 = 1.0 / law.Em + sum(1.0 / e for e in law.Ek), 1.0 / law.eta_m
    else:       # static equilibrium at the static modulus E(0)
        chain = 0.0 if np.isfinite(law.eta_m) else 1.0 / (1.0 / law.Em + sum(1.0 / e for e in law.Ek))
        c0, c1 = 1.0 / (law.E_inf + chain), 0.0
    X1 = np.zeros((n, 3))
    TH1 = np.zeros((n, 3))
    THp1 = np.zeros(3)
    residual, n_mech, failed = 0.0, 0, ""
    if np.any(g != 0.0):
        import scipy.sparse as sp

        net = network_of(sim)
        system = HarmonicSystem(net, nu=nu, bond_kinematics=p.bond_kinematics, head_rotation=head,
                                regularisation=0.0)
        d = system.dof_per_sphere
        act = np.flatnonzero(system.active)
        rhs = np.zeros(system.n_free)
        rhs[:d * act.size].reshape(-1, d)[:, :3] = sph.mass[act, None] * g[None, :]
        g0 = system._reference_blocks()["ff"]
        # zero modes of weakly held spheres (mechanisms), cluster by cluster: the load that
        # accelerates them, M V a with a = (V^T M V)^-1 V^T F (their free fall, the same from
        # rest), is removed; G is stiffened along them
        extra_r, extra_c, extra_v = [], [], []
        for dofs, V, scale, _ in system.mechanism_modes():
            n_mech += V.shape[1]
            MV = system.mass_free[dofs, None] * V
            rhs[dofs] -= MV @ np.linalg.solve(V.T @ MV, V.T @ rhs[dofs])
            extra_r.append(np.repeat(dofs, dofs.size))
            extra_c.append(np.tile(dofs, dofs.size))
            extra_v.append(scale * (V @ V.T).ravel())
        a = g0
        if extra_v:
            a = (g0 + sp.csc_matrix((np.concatenate(extra_v), (np.concatenate(extra_r), np.concatenate(extra_c))),
                                    shape=g0.shape)).tocsc()
        u = np.zeros_like(rhs)
        try:
            lu = system.factorise(a, "G + mechanisms (gravity)")
            u = lu.solve(rhs)
            for _ in range(GRAVITY_REFINEMENTS):
                u = u + lu.solve(rhs - g0 @ u)
            residual = float(np.linalg.norm(rhs - g0 @ u) / max(np.linalg.norm(rhs), 1e-300))
        except RuntimeError as exc:
            residual, failed = float("inf"), f"factorisation failed ({exc})"
        if not residual <= GRAVITY_RESIDUAL_MAX:
            failed = failed or (f"residual {residual:.3g} > {GRAVITY_RESIDUAL_MAX:g} (a mechanism of several "
                                "spheres?): gravity starts from rest")
            u = np.zeros_like(rhs)
        q = u[:d * act.size].reshape(-1, d)
        X1[act] = q[:, :3]
        if contact:
            TH1[act] = q[:, 3:]
        if head == "free":
            THp1 = u[d * act.size:d * act.size + 3].copy()
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
        displacement=X0, velocity=c1 * X1, angular_velocity=c1 * TH1,
        head_rotation=THp0, head_angular_velocity=c1 * THp1, bond_displacement=delta,
        bond_force=r_ch - Kinf * delta, delta_c=d_c, delta_k=np.ascontiguousarray(d_k), creep=bool(liquid),
        residual=residual, n_mechanisms=n_mech, failed=failed, sag_m=float(np.abs(X0).max()) if n else 0.0,
        solve_s=time.perf_counter() - tic)


def periodic_state(sim, law, frequency_Hz: float, amplitude_m: float,
                   head_rotation: str = "free", nu: float = POISSON_RATIO,
                   continuous: bool = False, system=None) -> PeriodicState:
    """Periodic steady state of the 2PB test built by ``twopb.build_simulation`` (module
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
    system : a HarmonicSystem of :func:`network_of` (sim) with the same options, to reuse
        (optional; built with the rotational regularisation off: the inertia makes the
        dynamic matrix regular, and the core has no such spring).

    Returns
    -------
    PeriodicState
    """
    from ..harmonic.solver import HarmonicSystem

    tic = time.perf_counter()
    p = sim.params
    contact = p.bond_kinematics == "contact"
    head = head_rotation if contact else "clamped"
    if system is None:
        system = HarmonicSystem(network_of(sim), nu=nu, bond_kinematics=p.bond_kinematics,
                                head_rotation=head, regularisation=0.0)
    s = (1j * 2.0 * math.pi * frequency_Hz if continuous
         else theta_laplace(frequency_Hz, p.dt, p.theta))
    sol = system.solve_law(law, frequency_Hz, amplitude=amplitude_m, inertia="full",
                           solver="reuse", laplace=s)
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
    g = gravity_state(sim, law, head_rotation=head_rotation, nu=nu)  # zero without gravity
    # peak force per bond: the steady (gravity) force plus the periodic amplitude
    amp_n = np.abs(g.bond_force[:, 0]) + np.abs(force[:, 0])
    amp_t = (np.sqrt(g.bond_force[:, 1] ** 2 + g.bond_force[:, 2] ** 2)
             + np.sqrt(np.abs(force[:, 1]) ** 2 + np.abs(force[:, 2]) ** 2))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(np.isfinite(b.r_crit), np.maximum(amp_n, amp_t) / b.r_crit, 0.0)
    ratio = float(ratio.max()) if len(ratio) else 0.0
    return PeriodicState(
        position=sim.spheres.position + g.displacement + np.real(X),
        velocity=g.velocity + np.real(s * X), angular_velocity=g.angular_velocity + np.real(s * TH),
        head_rotation=g.head_rotation + np.real(THp),
        head_angular_velocity=g.head_angular_velocity + np.real(s * THp),
        bond_displacement=g.bond_displacement + np.real(delta), bond_force=g.bond_force + np.real(force),
        delta_c=g.delta_c + np.real(d_c), delta_k=np.ascontiguousarray(g.delta_k + np.real(d_k)),
        laplace=complex(s), force_ratio=ratio, breaks=ratio >= 1.0, solve_s=time.perf_counter() - tic,
        gmres_iterations=int(getattr(system, "last_gmres_iterations", 0)),
        head_force=complex(rot * sol.force[0]), gravity=g if np.any(p.gravity) else None)


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
    if state.position.shape != sph.position.shape or state.bond_force.shape != b.force.shape \
            or state.delta_k.shape != b.delta_k.shape:
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


#: Equality tolerances of the periodic start against the converged from-rest result: |E*| relative, Phi absolute.
TOLERANCE_E_REL = 1e-3
TOLERANCE_PHASE_DEG = 0.05


def _close(e, phase, e_ref, phase_ref) -> bool:
    return bool(abs(e / e_ref - 1.0) <= TOLERANCE_E_REL and abs(phase - phase_ref) <= TOLERANCE_PHASE_DEG)


def check_case(sample_path, law, frequency_Hz: float, settings, long_cycles: int = 20,
               rest_cycles: float | None = None, continuous: bool = False, workdir=None,
               meta: dict | None = None) -> tuple[dict, list[dict]]:
    """Compare the periodic start with the from-rest protocol on one (sample, law, f).

    Runs (records in ``workdir``, a temporary directory by default): from rest for
    ``long_cycles`` cycles (the reference; its first ``rest_cycles`` cycles, default
    ``settings.n_cycles``, are the paper's protocol, since the imposed motion does not depend
    on the run's length); from the periodic start for ``settings.periodic_cycles`` cycles;
    with ``continuous`` also from the continuous steady state (s = i w). Every run is
    reduced over its last ``settings.window_cycles`` cycles with ``settings.force_reading``.

    Returns
    -------
    (row, cycles)
        row: ``meta`` + temperature/frequency, dt_s, steps_per_period, the starts' |E*| (MPa)
        and Phi (deg): ``E_rest_MPa, phase_rest_deg`` (after rest_cycles),
        ``E_long_MPa, phase_long_deg`` (after long_cycles), ``E_periodic_MPa,
        phase_periodic_deg`` (and ``*_continuous``), differences to the long reference
        ``dE_rest_pct, dphase_rest_deg, dE_periodic_pct, dphase_periodic_deg`` (and
        continuous), ``dE_long_pct, dphase_long_deg`` = the long run's last-cycle change
        over its last 5 cycles (its own convergence), ``rest_converged`` and
        ``periodic_equal`` (within :data:`TOLERANCE_E_REL`, :data:`TOLERANCE_PHASE_DEG`),
        ``first_cycle_to_periodic`` (first from-rest cycle within the tolerances of the
        periodic start, -1 if none), steps per job (``steps_rest, steps_periodic``), mean
        solver iterations per step (``iterations_rest_first_cycle, iterations_rest_cycle_N,
        iterations_rest_last_cycle, iterations_periodic``), NLGS steps, the periodic solve
        time and steady bond force / strength, and the start the periodic run used.
        cycles: one dict per from-rest cycle k (1..long_cycles) with its |E*|, Phi and the
        differences to the periodic start.
    """
    import dataclasses
    import tempfile
    from pathlib import Path

    from . import twopb

    rest_cycles = float(settings.n_cycles if rest_cycles is None else rest_cycles)
    if long_cycles < rest_cycles:
        raise ValueError(f"long_cycles ({long_cycles}) must be >= rest_cycles ({rest_cycles})")
    base = dataclasses.replace(settings, checkpoint_every=0)
    w = base.window_cycles
    meta = dict(meta or {})
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        tmp = Path(tmp)
        long_set = dataclasses.replace(base, start="rest", n_cycles=float(long_cycles))
        rec = twopb.run_test(sample_path, law, frequency_Hz, long_set, tmp / "rest.h5", meta=meta,
                             progress=False)
        per_set = dataclasses.replace(base, start="periodic")
        runs = {"periodic": twopb.run_test(sample_path, law, frequency_Hz, per_set, tmp / "periodic.h5",
                                           meta=meta, progress=False)}
        if continuous:
            runs["continuous"] = twopb.run_test(sample_path, law, frequency_Hz, per_set, tmp / "cont.h5",
                                                meta=meta, progress=False, continuous_start=True)
    dt = float(rec["attrs"]["dt_s"])
    per_period = 1.0 / (frequency_Hz * dt)
    red = {k: twopb.reduce_test(r, w) for k, r in runs.items()}
    long_row = twopb.reduce_test(rec, w)
    rest_row = twopb.reduce_test(twopb.truncate_record(rec, rest_cycles), w)
    prev = twopb.reduce_test(twopb.truncate_record(rec, long_cycles - 5), w) if long_cycles - 5 >= w else long_row
    e_per, ph_per = red["periodic"]["E_norm_MPa"], red["periodic"]["phase_deg"]
    it = np.asarray(rec["stats"]["iterations"], float)

    def cycle_mean(k):  # mean iterations over cycle k (1-based)
        a, b = int(round((k - 1) * per_period)), int(round(k * per_period))
        return float(it[a:b].mean())

    cycles = []
    first = -1
    for k in range(int(math.ceil(w)), long_cycles + 1):
        r = twopb.reduce_test(twopb.truncate_record(rec, k), w)
        ok = _close(r["E_norm_MPa"], r["phase_deg"], e_per, ph_per)
        if ok and first < 0:
            first = k
        elif not ok:
            first = -1
        cycles.append({**meta, "temperature_C": meta.get("temperature_C"), "frequency_Hz": frequency_Hz,
                       "cycle": k, "E_norm_MPa": r["E_norm_MPa"], "phase_deg": r["phase_deg"],
                       "dE_to_periodic_pct": 100.0 * (r["E_norm_MPa"] / e_per - 1.0),
                       "dphase_to_periodic_deg": r["phase_deg"] - ph_per,
                       "iterations_mean": cycle_mean(k)})
    e_l, ph_l = long_row["E_norm_MPa"], long_row["phase_deg"]
    info = json.loads(runs["periodic"]["attrs"]["start_info"])
    row = {**meta, "frequency_Hz": frequency_Hz, "dt_s": dt, "steps_per_period": per_period,
           "rest_cycles": rest_cycles, "long_cycles": long_cycles,
           "periodic_cycles": base.periodic_cycles, "window_cycles": w,
           "E_rest_MPa": rest_row["E_norm_MPa"], "phase_rest_deg": rest_row["phase_deg"],
           "E_long_MPa": e_l, "phase_long_deg": ph_l,
           "E_periodic_MPa": e_per, "phase_periodic_deg": ph_per,
           "dE_rest_pct": 100.0 * (rest_row["E_norm_MPa"] / e_l - 1.0),
           "dphase_rest_deg": rest_row["phase_deg"] - ph_l,
           "dE_periodic_pct": 100.0 * (e_per / e_l - 1.0), "dphase_periodic_deg": ph_per - ph_l,
           "dE_long_pct": 100.0 * (e_l / prev["E_norm_MPa"] - 1.0),
           "dphase_long_deg": ph_l - prev["phase_deg"],
           "dE_rest_to_periodic_pct": 100.0 * (rest_row["E_norm_MPa"] / e_per - 1.0),
           "dphase_rest_to_periodic_deg": rest_row["phase_deg"] - ph_per,
           "rest_converged": _close(rest_row["E_norm_MPa"], rest_row["phase_deg"], e_l, ph_l),
           "periodic_equal": _close(e_per, ph_per, e_l, ph_l),
           "rest_equal_periodic": _close(rest_row["E_norm_MPa"], rest_row["phase_deg"], e_per, ph_per),
           "first_cycle_to_periodic": first,
           "steps_rest": twopb.n_steps_of(frequency_Hz, dt, dataclasses.replace(base, n_cycles=rest_cycles), "rest"),
           "steps_periodic": int(runs["periodic"]["attrs"]["n_steps"]),
           "iterations_rest_first_cycle": cycle_mean(1),
           f"iterations_rest_cycle_{int(rest_cycles)}": cycle_mean(int(rest_cycles)),
           "iterations_rest_last_cycle": cycle_mean(long_cycles),
           "iterations_periodic": float(np.mean(runs["periodic"]["stats"]["iterations"])),
           "n_nlgs_steps_rest": int(long_row["n_nlgs_steps"]),
           "n_nlgs_steps_periodic": int(red["periodic"]["n_nlgs_steps"]),
           "n_broken_rest": int(long_row["n_broken_total"]),
           "start_periodic_run": runs["periodic"]["attrs"]["start"],
           "periodic_solve_s": info.get("solve_s", float("nan")),
           "periodic_force_ratio": info.get("force_ratio", float("nan")),
           "cpu_rest_s_per_cycle": float(rec["attrs"]["cpu_time_s"]) / long_cycles,
           "cpu_periodic_s": float(runs["periodic"]["attrs"]["cpu_time_s"])}
    if continuous:
        c = red["continuous"]
        row.update({"E_continuous_MPa": c["E_norm_MPa"], "phase_continuous_deg": c["phase_deg"],
                    "dE_continuous_pct": 100.0 * (c["E_norm_MPa"] / e_l - 1.0),
                    "dphase_continuous_deg": c["phase_deg"] - ph_l,
                    "dE_continuous_to_periodic_pct": 100.0 * (c["E_norm_MPa"] / e_per - 1.0),
                    "dphase_continuous_to_periodic_deg": c["phase_deg"] - ph_per})
    return row, cycles
