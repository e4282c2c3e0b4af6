"""Moreau–Jean time stepping (theta-method) of spheres, plates and bonds: the public
:class:`Simulation`.

One step of length h from t- to t+ = t- + h (Jean 1999; Eq. 14 of the paper) runs these
phases of :meth:`Simulation.step`, in order:

1. :meth:`~Simulation._plate_motion`: a driven plate gets the mean velocity
   (u(t+) - u(t-))/h of its imposed displacement for the whole step;
2. :meth:`~Simulation._free_velocities`: v_free = v- + h M^-1 (m g + f_ext,theta),
   f_ext,theta = theta f(t+) + (1-theta) f(t-) when the external force is a callable, else
   the array as given; a free plate's free velocity includes gravity;
3. :meth:`~Simulation._detect_contacts`: detection at the start-of-step configuration
   (cell lists, gap < alert distance; pairs whose intact bond is their only law skipped,
   ``NSCDParameters.bonded_contact``), warm start of the contact impulses from the previous
   step (matched by pair); :meth:`~Simulation._predict_bonds`: the affine bond laws of the
   step (Eq. 25), bond impulses warm-started from the previous step;
4. :meth:`~Simulation._solve_impulses`: the linear fast path (linear/) when allowed and
   valid (a few contacts that it closes solved on their Delassus operator condensed over
   the bonds, condensed.py, ``NSCDParameters.fast_path_contacts``), else nonlinear
   Gauss–Seidel (gauss_seidel.py) on Signorini–Coulomb (Eqs. 6-7) and the bond laws;
5. :meth:`~Simulation._update_bonds`: internal variables, forces, breakage (Eqs. 12-13,
   15-26; local_laws.bond_update); :meth:`~Simulation._contact_dissipation`,
   :meth:`~Simulation._plate_forces`: the step's dissipation and plate forces;
6. :meth:`~Simulation._integrate`: positions x+ = x- + h (theta v+ + (1-theta) v-)
   (spheres and free plates); driven plates at their imposed position; rotations are
   integrated only as angular velocities (the orientation of a sphere does not enter any
   law; a rotating plate accumulates its small rotation vector in ``Plates.rotation``).

Bond kinematics (``NSCDParameters.bond_kinematics``, state.Bonds): with 'contact' the
bonds act at their contact points with lever arms (torques on spheres and on rotating
plates); the linear fast path then has 6 DOF per sphere (linear/). Rotating plates
(``Plate(rotation=True)``): translation as their mode says (e.g. driven), free rotation
about their reference point under the bond torques. Contacts do not see a plate's rotation
(their plate velocity is its translation, and they exert no torque on it): adequate for the
small head rotations of a bonded 2PB test, where the head's load passes through bonds.

Plate forces: :meth:`Simulation._plate_forces`; the default theta = 0.5: :class:`NSCDParameters`;
kernel arguments: the named tuples of :mod:`.bundles`.
"""

from __future__ import annotations

import time as _time
from typing import Callable, NamedTuple

import numba
import numpy as np

from . import condensed, detection, gauss_seidel, local_laws
from .bundles import Bodies, BondGeometry, BondState, BondStep, Contacts, NLGSOptions, StepOptions, Velocities
from .delassus import bond_blocks, bond_blocks_contact, contact_blocks
from .linear import LinearBondSolver, bond_impulses
from .state import CONVERGENCE_NORMS, DRIVEN, FIXED, FREE, Bonds, NSCDParameters, Plates, Spheres, StepStats


class _PlateMotion(NamedTuple):
    """The plates over a step (:meth:`Simulation._plate_motion`): velocity (P,3) m/s and
    angular velocity (P,3) rad/s of the step, point (P,3) m at its end for the driven and
    fixed plates."""

    velocity: np.ndarray
    angular: np.ndarray
    point: np.ndarray


class Simulation:
    """An NSCD simulation: state + parameters + :meth:`step`.

    Parameters
    ----------
    spheres : Spheres; plates : Plates (may be empty); bonds : Bonds or None.
    params : NSCDParameters.
    external_force : optional (N,3) array (N) or callable ``t -> (N,3)`` applied to the
        spheres' barycentres (gravity is added separately from ``params.gravity``).

    Attributes
    ----------
    time : s; step_index : int; stats : list of StepStats (when ``record=True`` in run).
    contact_i, contact_j, contact_impulse : contacts of the last step, impulses (C,3) N s in
        the local frames (reaction = impulse / dt).
    bond_impulse : (B,3) N s, last step's bond impulses (local frames).
    """

    #: spheres left out of the test because the bond network does not hold them; set only by
    #: :func:`asphalt_nscd.sample.rig.setup`
    n_mechanisms_dropped: int

    def __init__(
        self,
        spheres: Spheres,
        plates: Plates | None = None,
        bonds: Bonds | None = None,
        params: NSCDParameters | None = None,
        external_force: np.ndarray | Callable | None = None,
    ):
        if params is None:
            raise ValueError("params (NSCDParameters) is required")
        self.spheres = spheres
        self.plates = plates if plates is not None else Plates([])
        self.bonds = bonds if bonds is not None else Bonds.empty()
        self.params = params
        self.external_force = external_force
        self.plate_external_force = np.zeros((self.plates.n, 3))
        self.time = 0.0
        self.step_index = 0
        self.bond_impulse = np.zeros((self.bonds.n, 3))
        self.contact_i = np.zeros(0, np.int64)
        self.contact_j = np.zeros(0, np.int64)
        self.contact_impulse = np.zeros((0, 3))
        self.contact_frame = np.zeros((0, 3, 3))
        self._linear: LinearBondSolver | None = None
        self._linear_key: tuple | None = None
        self._coef_key: tuple | None = None
        self._bond_work: BondStep | None = None  # per-step bond work arrays, reused (bond_predict fills them)
        #: (P, 3) N m, mean torque of the bonds on each plate about its reference point over
        #: the last step ('contact' kinematics; zero with 'barycentre').
        self.plate_torque = np.zeros((self.plates.n, 3))
        self.linear_iterations = 0
        #: steps whose linear fast path ran to its iteration limit above its tolerance and were
        #: redone by NLGS (:func:`.linear.solver.reached`; since this object was made, not checkpointed)
        self.linear_unconverged = 0
        self._v_before: np.ndarray | None = None
        self._vp_before: np.ndarray | None = None
        self._w_before: np.ndarray | None = None
        self._wp_before: np.ndarray | None = None
        #: the velocity fields two and three steps before, most recent first (the third and
        #: fourth fields of cg_ssor's Galerkin start)
        self._older: list[tuple] = []
        self.timings = {"detection": 0.0, "solve": 0.0, "bonds": 0.0, "other": 0.0}
        if self.params.alert_distance is None:
            self.alert_distance = 0.5 * float(spheres.radius.min()) if spheres.n else 0.0
        else:
            self.alert_distance = float(self.params.alert_distance)
        self._candidates = detection.CandidateList(self.alert_distance)
        self._exclusion_key: tuple | None = None

    # ------------------------------------------------------------------ helpers
    def _external(self, t0, t1):
        f = self.external_force
        if f is None:
            return None
        if callable(f):
            th = self.params.theta
            return th * np.asarray(f(t1), float) + (1 - th) * np.asarray(f(t0), float)
        return np.asarray(f, float)

    def n_intact_bonds(self) -> int:
        return int((~self.bonds.broken).sum())

    def excluded_bonds(self) -> np.ndarray:
        """(B,) bool: the bonds whose pair is not a contact candidate now
        (``params.bonded_contact``: intact bonds; with 'open_at_bonding' only those with
        delta0 <= 0; none with 'always')."""
        bnd = self.bonds
        policy = self.params.bonded_contact
        if policy == "always":
            return np.zeros(bnd.n, bool)
        mask = ~bnd.broken
        if policy == "open_at_bonding":
            mask &= bnd.delta0 <= 0.0
        return mask

    def _update_exclusions(self) -> None:
        """Give detection the pairs to skip when the policy or the intact-bond set changed
        (bonds only break, so their count identifies the set)."""
        bnd = self.bonds
        key = (self.params.bonded_contact, bnd.n, int(bnd.broken.sum()), id(bnd.i))
        if key == self._exclusion_key:
            return
        mask = self.excluded_bonds()
        self._candidates.set_exclusions(
            detection.bonded_exclusions(self.spheres.n, self.plates.n, bnd.i[mask], bnd.j[mask]) if mask.any() else None
        )
        self._exclusion_key = key

    # ------------------------------------------------------------------ one step
    def step(self) -> StepStats:
        """Advance by one time step ``params.dt`` (Moreau–Jean, Eq. 14); returns its
        :class:`StepStats`. The phases, in order: :meth:`_plate_motion`,
        :meth:`_free_velocities`, :meth:`_detect_contacts`, :meth:`_predict_bonds`,
        :meth:`_solve_impulses`, :meth:`_update_bonds`, :meth:`_contact_dissipation`,
        :meth:`_plate_forces`, :meth:`_integrate`."""
        tic = _time.perf_counter()
        p = self.params
        if p.threads > 1:
            numba.set_num_threads(p.threads)
        t0, t1 = self.time, self.time + p.dt
        bodies, bonds = self._bodies(), self._bond_geometry()
        plate = self._plate_motion(t0, t1)
        start, free = self._free_velocities(t0, t1, plate, bodies)
        end = Velocities(*(a.copy() for a in free))

        t_a = _time.perf_counter()
        contacts = self._detect_contacts(free, bodies)
        t_b = _time.perf_counter()
        self.timings["detection"] += t_b - t_a

        law = self._bond_state() if self.bonds.n else None
        bond_step = self._predict_bonds(bonds, law, start)
        t_c = _time.perf_counter()
        self.timings["bonds"] += t_c - t_b

        solver, it, quad, maxm, conv = self._solve_impulses(free, end, contacts, bonds, bond_step, bodies)
        t_d = _time.perf_counter()
        self.timings["solve"] += t_d - t_c

        n_new, diss_b = self._update_bonds(bonds, law, bond_step, end)
        diss_c = self._contact_dissipation(contacts, start, end)
        t_e = _time.perf_counter()
        self.timings["bonds"] += t_e - t_d

        plate_force, driver = self._plate_forces(contacts, bond_step.impulse, t0, t1)
        self._integrate(start, end, plate.point)
        cP = contacts.impulse
        self.contact_i, self.contact_j = contacts.i, contacts.j
        self.contact_impulse, self.contact_frame = cP, contacts.frame
        self.time = t1
        self.step_index += 1
        self.timings["other"] += _time.perf_counter() - t_e + (t_a - tic)
        return StepStats(
            time=t1,
            solver=solver,
            iterations=int(it),
            residual_quad=float(quad),
            residual_max=float(maxm),
            converged=bool(conv),
            n_contacts=len(contacts.i),
            n_active_contacts=int((cP[:, 0] > 0).sum()),
            n_bonds=self.n_intact_bonds(),
            n_broken=int(n_new),
            n_broken_total=int(self.bonds.broken.sum()),
            plate_force=plate_force,
            driver_force=driver,
            dissipated=float(diss_b + diss_c),
        )

    # ------------------------------------------------------------------ phases of a step
    def _plate_motion(self, t0, t1) -> _PlateMotion:
        """Phase 1: the plates' velocities over the step [t0, t1] (s), the imposed part of the
        Moreau–Jean step (Eq. 14). A driven plate moves at the mean velocity
        (u(t1) - u(t0))/h of its imposed displacement u and ends at point0 + u(t1); a fixed
        plate is at rest; a free plate keeps its velocity (its gravity and external force
        enter the free velocities, :meth:`_free_velocities`). Only rotating plates have an
        angular velocity."""
        pls, h = self.plates, self.params.dt
        velocity = pls.velocity.copy()
        point = pls.point.copy()
        for k in range(pls.n):
            if pls.mode[k] == DRIVEN:
                u0 = pls.imposed_displacement(k, t0)
                u1 = pls.imposed_displacement(k, t1)
                velocity[k] = (u1 - u0) / h
                point[k] = pls.point0[k] + u1
            elif pls.mode[k] == FIXED:
                velocity[k] = 0.0
        angular = np.where(pls.rotates[:, None], pls.angular_velocity, 0.0)
        return _PlateMotion(velocity, angular, point)

    def _free_velocities(self, t0, t1, plate: _PlateMotion, bodies: Bodies):
        """Phase 2: the velocities at the start of the step and the free velocities
        v_free = v- + h M^-1 (m g + f_ext,theta) (Eq. 14 without the reactions),
        f_ext,theta = theta f(t1) + (1-theta) f(t0) when the external force is a callable,
        else the array as given; immobile spheres (infinite mass) get zero velocities; free
        plates get gravity and their external force. Returns (start, free), two
        :class:`~.bundles.Velocities` (the plates' start velocities: those of
        :meth:`_plate_motion`)."""
        p, sph, pls = self.params, self.spheres, self.plates
        h = p.dt
        finite = np.isfinite(sph.mass)
        vp = plate.velocity.copy()
        wp = plate.angular.copy()
        free_p = pls.mode == FREE
        if free_p.any():
            vp[free_p] += h * (p.gravity + self.plate_external_force[free_p] / pls.mass[free_p, None])
        v_m = sph.velocity.copy()
        w_m = sph.angular_velocity.copy()
        v = v_m.copy()
        v[finite] += h * np.asarray(p.gravity)  # an array once the parameters are constructed
        fext = self._external(t0, t1)
        if fext is not None:
            v[finite] += h * fext[finite] * bodies.inv_mass[finite, None]
        v[~finite] = 0.0
        w = w_m.copy()
        w[~finite] = 0.0
        return (Velocities(v_m, w_m, plate.velocity, plate.angular), Velocities(v, w, vp, wp))

    def _detect_contacts(self, free: Velocities, bodies: Bodies) -> Contacts:
        """Phase 3: contact candidates at the start-of-step configuration (cell lists, gap
        below the alert distance; pairs whose intact bond is their only law skipped,
        ``NSCDParameters.bonded_contact``), their impulses warm-started from the previous
        step (:meth:`_warm_contacts`) and their diagonal Delassus blocks (Eqs. 6-7 act on
        them). The alert distance is raised (never lowered) when the free velocities could
        close a larger gap within the step."""
        sph, pls, h = self.spheres, self.plates, self.params.dt
        vmax = np.sqrt((free.v**2).sum(1).max()) if len(free.v) else 0.0
        if pls.n:
            vmax += np.sqrt((free.vp**2).sum(1).max())
        if 2.0 * h * vmax > self._candidates.alert:
            self._candidates.alert = 2.0 * h * vmax
            self._candidates.skin = max(self._candidates.skin, self._candidates.alert)
            self._candidates.x_ref = None
            self.alert_distance = self._candidates.alert
        self._update_exclusions()
        ci, cj, gap, cframe = self._candidates.contacts(sph.position, sph.radius, pls.point, pls.normal)
        cP = self._warm_contacts(ci, cj, cframe)
        cwn = np.empty(len(ci))
        cwt = np.empty(len(ci))
        contact_blocks(ci, cj, bodies.inv_mass, bodies.inv_inertia, bodies.radius, bodies.inv_mass_plate, cwn, cwt)
        return Contacts(ci, cj, cframe, gap, cwn, cwt, cP)

    def _predict_bonds(self, bonds: BondGeometry, law: BondState | None, start: Velocities) -> BondStep:
        """The step's affine bond laws P = c0 - c_g U+ (Eq. 25, from the theta-method of the
        generalized Burger's law, Eqs. 15-24; local_laws.bond_predict) from the state and
        velocities at the start of the step; the impulses of broken bonds are zeroed. The
        work arrays are reused from step to step (every entry is rewritten)."""
        bnd = self.bonds
        nb = bnd.n
        if self._bond_work is None or self._bond_work.c0.shape[0] != nb:
            self._bond_work = BondStep(
                np.zeros((nb, 3)),
                np.zeros((nb, 3)),
                np.zeros((nb, 3)),
                np.zeros((nb, 3)),
                np.zeros(nb),
                np.zeros((nb, 3, 3)),
                np.zeros((nb, 3, 3)),
                self.bond_impulse,
            )
        if self._bond_work.impulse is not self.bond_impulse:
            self._bond_work = self._bond_work._replace(impulse=self.bond_impulse)
        if nb:
            local_laws.bond_predict(
                bonds, law, self.spheres.position, self.plates.point, start, self._step_options(), self._bond_work
            )
        self.bond_impulse[bnd.broken] = 0.0
        return self._bond_work

    def _solve_impulses(
        self,
        free: Velocities,
        end: Velocities,
        contacts: Contacts,
        bonds: BondGeometry,
        bond_step: BondStep,
        bodies: Bodies,
    ):
        """Phase 4: the impulses of the step and the end-of-step velocities end (written in
        place; on entry a copy of free). The linear fast path (:mod:`.linear`) when allowed
        and valid (contacts it closes solved on their Delassus operator condensed over the
        bonds, :mod:`.condensed`), else nonlinear Gauss-Seidel on the contact (Eqs. 6-7) and
        bond (Eq. 25) laws (:mod:`.gauss_seidel`). Returns (solver 'linear' or 'nlgs',
        iterations, quad, maxm, converged)."""
        p = self.params
        if p.fast_path and self.bonds.n and self._fast_path(free, end, contacts, bonds, bond_step, bodies):
            return "linear", self.linear_iterations, 0.0, 0.0, True
        for a, b in zip(end, free):
            a[:] = b
        rot = self._rot()
        if self.bonds.n:  # Delassus blocks of the bonds: needed by NLGS only
            bnd = self.bonds
            if rot:
                bond_blocks_contact(
                    bnd.i,
                    bnd.j,
                    bnd.frame,
                    bnd.arm_i,
                    bnd.arm_j,
                    bodies.inv_mass,
                    bodies.inv_inertia,
                    bodies.inv_mass_plate,
                    bodies.inv_inertia_plate,
                    bond_step.cg,
                    bond_step.W,
                    bond_step.A_inv,
                )
            else:
                bond_blocks(bnd.i, bnd.j, bodies.inv_mass, bodies.inv_mass_plate, bond_step.w)
        gauss_seidel.apply_impulses(contacts, bonds, bond_step, bodies, end, rot)
        opts = NLGSOptions(
            p.dt, p.friction, p.tolerance, p.relaxation, p.max_iterations, CONVERGENCE_NORMS[p.convergence], rot
        )
        it, quad, maxm, conv = gauss_seidel.nlgs(contacts, bonds, bond_step, bodies, end, opts)
        return "nlgs", it, quad, maxm, conv

    def _update_bonds(self, bonds: BondGeometry, law: BondState | None, bond_step: BondStep, end: Velocities):
        """Phase 5: the bonds' internal variables and forces at the end of the step (the
        theta-method of Eqs. 15-26) and breakage (Eqs. 12-13; local_laws.bond_update).
        Returns (number of bonds broken in the step, energy dissipated by the bonds, J)."""
        if not self.bonds.n:
            return 0, 0.0
        return local_laws.bond_update(bonds, law, bond_step, end, self._step_options())

    def _contact_dissipation(self, contacts: Contacts, start: Velocities, end: Velocities) -> float:
        """Energy (J) dissipated by the contacts (Eqs. 6-7) in the step:
        -P . (theta U+ + (1-theta) U-) with U+, U- their local velocities at the end and start
        of the step."""
        cP = contacts.impulse
        if not cP.any():
            return 0.0
        th = self.params.theta
        n = len(contacts.i)
        u_plus = np.empty((n, 3))
        u_minus = np.empty((n, 3))
        self._contact_velocities(contacts.i, contacts.j, contacts.frame, end.v, end.w, end.vp, u_plus)
        self._contact_velocities(contacts.i, contacts.j, contacts.frame, start.v, start.w, start.vp, u_minus)
        return float(-(cP * (th * u_plus + (1 - th) * u_minus)).sum())

    def _plate_forces(self, contacts: Contacts, bP, t0, t1):
        """Mean forces (P,3) N on the plates over the step (impulses P = h (theta R+ +
        (1-theta) R-) of Eq. 14 and Eq. 25), and the bond torques
        ``plate_torque`` (P,3) N m about their points ('contact' kinematics).

        ``plate_force`` = impulse / h of the spheres on the plate (contacts and bonds), i.e.
        theta R(t1) + (1-theta) R(t0); ``driver_force`` = m (a_theta - g) - plate_force with
        a_theta the same theta-average of the exact imposed acceleration
        (:meth:`_imposed_acceleration`), consistent with the reaction to O(h²); plates of
        infinite mass report -plate_force. Returns (plate_force, driver_force)."""
        p, pls, bnd = self.params, self.plates, self.bonds
        h, th = p.dt, p.theta
        cj, cP, cframe = contacts.j, contacts.impulse, contacts.frame
        nb = bnd.n
        plate_force = np.zeros((pls.n, 3))
        on_plate = cj < 0
        if on_plate.any():
            g = np.einsum("ac,acd->ad", cP[on_plate], cframe[on_plate])
            np.add.at(plate_force, -1 - cj[on_plate], -g / h)
        bp = (bnd.j < 0) if nb else np.zeros(0, bool)
        self.plate_torque = np.zeros((pls.n, 3))
        if nb and bp.any():
            g = np.einsum("ac,acd->ad", bP[bp], bnd.frame[bp])
            np.add.at(plate_force, -1 - bnd.j[bp], -g / h)
            if self._rot():
                np.add.at(self.plate_torque, -1 - bnd.j[bp], np.cross(bnd.arm_j[bp], -g / h))
        driver = np.zeros((pls.n, 3))
        for k in range(pls.n):
            if pls.mode[k] == DRIVEN and np.isfinite(pls.mass[k]):
                # theta-average of the exact imposed acceleration: consistent with the
                # bond/contact impulses P = h (theta R+ + (1-theta) R-) in plate_force
                acc = th * self._imposed_acceleration(k, t1) + (1 - th) * self._imposed_acceleration(k, t0)
                driver[k] = pls.mass[k] * (acc - p.gravity) - plate_force[k]
            elif pls.mode[k] in (DRIVEN, FIXED):  # infinite mass: inertia not counted
                driver[k] = -plate_force[k]
        return plate_force, driver

    def _integrate(self, start: Velocities, end: Velocities, driven_point):
        """Phase 6: positions x+ = x- + h (theta v+ + (1-theta) v-) of the spheres and free
        plates (Eq. 14); driven and fixed plates at driven_point (P,3) m (their imposed
        position, :meth:`_plate_motion`); rotations only as angular velocities (a sphere's
        orientation enters no law), a rotating plate accumulating its small rotation vector
        in ``Plates.rotation``. The start velocities are kept for the initial guess of the
        iterative linear solvers."""
        h, th = self.params.dt, self.params.theta
        sph, pls = self.spheres, self.plates
        v_m, w_m, vp_start, wp_start = start
        v, w, vp, wp = end
        if self._v_before is not None:
            self._older = [(self._v_before, self._w_before, self._vp_before, self._wp_before)] + self._older[:1]
        self._v_before, self._vp_before = v_m, vp_start
        self._w_before, self._wp_before = w_m, wp_start
        sph.position += h * (th * v + (1 - th) * v_m)
        sph.velocity[:] = v
        sph.angular_velocity[:] = w
        for k in range(pls.n):
            if pls.mode[k] == FREE:
                pls.point[k] += h * (th * vp[k] + (1 - th) * vp_start[k])
            else:
                pls.point[k] = driven_point[k]
        pls.velocity[:] = vp
        pls.rotation += h * (th * wp + (1 - th) * wp_start)
        pls.angular_velocity[:] = wp

    def run(self, n_steps: int, callback: Callable | None = None):
        """Run ``n_steps`` steps; ``callback(sim, stats)`` after each. Returns a pandas
        DataFrame of :meth:`StepStats.as_row` rows."""
        import pandas as pd

        rows = []
        for _ in range(int(n_steps)):
            st = self.step()
            rows.append(st.as_row())
            if callback is not None:
                callback(self, st)
        return pd.DataFrame(rows)

    # ------------------------------------------------------------------ internals
    def _bond_coefficients(self):
        """Reciprocals of the bond laws for the current (dt, theta), computed once
        (local_laws.bond_coefficients). Like the linear fast path's matrix, they assume
        that the bond parameters (Km, Cm, Kk, Ck) are not changed in place during a run."""
        bnd, p = self.bonds, self.params
        key = (p.dt, p.theta, bnd.n, bnd.Kk.shape[1], id(bnd.Km), id(bnd.Kk))
        if self._coef_key != key:
            self._coef = (np.empty((bnd.n, 3, 2)), np.empty((bnd.n, bnd.Kk.shape[1], 2)))
            local_laws.bond_coefficients(bnd.Km, bnd.Cm, bnd.Kk, bnd.Ck, p.dt, p.theta, *self._coef)
            self._coef_key = key
        return self._coef

    def _imposed_acceleration(self, k, t):
        """Acceleration (3,) m/s2 of driven plate k's imposed motion u(t) at time t (s).

        Central second difference with step h = dt, (u(t+h) - 2 u(t) + u(t-h)) / h2, whose
        error is h2 u^(4) / 12 (relative (omega h)2 / 12 = 1.3e-5 for 40 Hz at h = 5e-5 s);
        u(t-h) is taken as u(0) for t - h < 0 (plate at rest before the drive starts).
        """
        h = self.params.dt
        pls = self.plates
        u_m = pls.imposed_displacement(k, max(t - h, 0.0))
        return (pls.imposed_displacement(k, t + h) - 2.0 * pls.imposed_displacement(k, t) + u_m) / (h * h)

    def _contact_velocities(self, ci, cj, cframe, v, w, vp, out):
        gauss_seidel.contact_velocities(ci, cj, cframe, self.spheres.radius, v, w, vp, out)

    def _warm_contacts(self, ci, cj, cframe):
        """Impulses of the previous step's contacts on the same pairs, re-expressed in the
        new frames (global vectors projected); zero for new contacts."""
        cP = np.zeros((len(ci), 3))
        if len(self.contact_i) == 0 or len(ci) == 0 or not self.contact_impulse.any():
            return cP
        base = self.spheres.n + self.plates.n + 1
        old_key = self.contact_i * base + np.where(
            self.contact_j >= 0, self.contact_j, self.spheres.n - 1 - self.contact_j
        )
        new_key = ci * base + np.where(cj >= 0, cj, self.spheres.n - 1 - cj)
        order = np.argsort(old_key)
        sk = old_key[order]
        pos = np.minimum(np.searchsorted(sk, new_key), len(sk) - 1)
        src = np.where(sk[pos] == new_key, order[pos], -1)
        gauss_seidel.warm_impulses(
            src, self.contact_impulse, self.contact_frame, np.ascontiguousarray(cframe), self.params.friction, cP
        )
        return cP

    def _rot(self) -> bool:
        """True with the 'contact' bond kinematics (bond torques, rotation unknowns)."""
        return self.params.bond_kinematics == "contact"

    def _bodies(self) -> Bodies:
        sph, pls = self.spheres, self.plates
        return Bodies(sph.radius, sph.inv_mass, sph.inv_inertia, pls.inv_mass, pls.inv_inertia)

    def _bond_geometry(self) -> BondGeometry:
        bnd = self.bonds
        return BondGeometry(bnd.i, bnd.j, bnd.frame, bnd.arm_i, bnd.arm_j, bnd.broken)

    def _bond_state(self) -> BondState:
        bnd = self.bonds
        coef, i_den = self._bond_coefficients()
        return BondState(
            coef,
            i_den,
            bnd.Kk,
            bnd.Ck,
            bnd.Kinf,
            bnd.r_crit,
            bnd.force,
            bnd.delta_c,
            bnd.delta_k,
            bnd.rest,
            bnd.displacement,
        )

    def _step_options(self) -> StepOptions:
        return StepOptions(self.params.dt, self.params.theta, self._rot())

    def _linear_solver(self, bodies: Bodies) -> LinearBondSolver:
        """The linear fast path's solver of the current (dt, theta, intact-bond set, solver
        settings), rebuilt when one of them changed."""
        bnd, p = self.bonds, self.params
        rot = self._rot()
        key = (
            p.dt,
            p.theta,
            int(bnd.broken.sum()),
            bnd.n,
            p.linear_solver,
            p.linear_tolerance,
            rot,
            p.threads,
            p.linear_ssor_omega,
        )
        if self._linear_key != key:
            assert self._bond_work is not None  # the step's bond laws are predicted before the solve
            rotation = None
            if rot:
                rotation = dict(
                    arm_i=bnd.arm_i,
                    arm_j=bnd.arm_j,
                    inv_inertia=bodies.inv_inertia,
                    inv_inertia_plate=bodies.inv_inertia_plate,
                )
            self._linear = LinearBondSolver(
                bodies.inv_mass,
                bodies.inv_mass_plate,
                bnd.i,
                bnd.j,
                bnd.frame,
                self._bond_work.cg,
                bnd.broken,
                method=p.linear_solver,
                tolerance=p.linear_tolerance,
                rotation=rotation,
                threads=p.threads,
                ssor_omega=p.linear_ssor_omega,
                factorisation=p.direct_factorisation,
            )
            self._linear_key = key
        assert self._linear is not None  # built with its key
        return self._linear

    def _initial_guess(self):
        """Initial guess of the iterative linear solvers: (start, previous). start: the
        linear extrapolation in time of the body velocities (:class:`~.bundles.Velocities`);
        previous: for cg_ssor's Galerkin start, the velocity fields at the start of the step
        and up to three steps before (most recent first), or None on the first step."""
        rot = self._rot()
        v0, vp0 = self.spheres.velocity, self.plates.velocity
        w0, wp0 = self.spheres.angular_velocity, self.plates.angular_velocity
        previous = None
        if self._v_before is not None and self._v_before.shape == v0.shape:
            previous = (
                Velocities(v0, w0, vp0, wp0),
                Velocities(
                    self._v_before, self._w_before if rot else w0, self._vp_before, self._wp_before if rot else wp0
                ),
            )
            for old in self._older:
                if old[0].shape != v0.shape:
                    break
                previous += (Velocities(old[0], old[1] if rot else w0, old[2], old[3] if rot else wp0),)
            v0 = 2.0 * v0 - self._v_before
            vp0 = 2.0 * vp0 - self._vp_before
            if rot and self._w_before is not None:
                w0 = 2.0 * w0 - self._w_before
                wp0 = 2.0 * wp0 - self._wp_before
        return Velocities(v0, w0, vp0, wp0), previous

    def _fast_path(
        self,
        free: Velocities,
        end: Velocities,
        contacts: Contacts,
        bonds: BondGeometry,
        bond_step: BondStep,
        bodies: Bodies,
    ) -> bool:
        """Try the linear solver (:mod:`.linear`); True if its solution is the solution of
        the step: then end, the bond impulses and the contact impulses hold it. An iterative
        solve that ran to its iteration limit above its tolerance is not: False, counted in
        ``linear_unconverged``, its bond impulses NLGS's warm start. Contacts
        that the linear solution closes are solved on their Delassus operator condensed over
        the bonds (:mod:`.condensed`) when there are at most ``fast_path_contacts`` of them;
        otherwise False, with the linear bond impulses left as NLGS's warm start (the
        contact impulses keep theirs)."""
        p = self.params
        h, rot = p.dt, self._rot()
        solver = self._linear_solver(bodies)
        trial = Velocities(*(a.copy() for a in end))
        P_try = np.zeros_like(bond_step.impulse)
        start, previous = self._initial_guess()
        solver.solve(free, bonds, bond_step.c0, bond_step.cg, trial, P_try, start=start, previous=previous)
        self.linear_iterations = solver.last_iterations
        if not solver.last_converged:  # not the system's solution: NLGS, warm-started from it
            self.linear_unconverged += 1
            bond_step.impulse[:] = P_try
            return False
        # contacts must stay open with zero reaction, or be solved by the condensed problem
        ci, cj, cframe, gap = contacts.i, contacts.j, contacts.frame, contacts.gap
        closed = None
        if len(ci):
            u = np.empty((len(ci), 3))
            self._contact_velocities(ci, cj, cframe, trial.v, trial.w, trial.vp, u)
            if np.any(u[:, 0] + np.maximum(gap, 0.0) / h < 0.0):
                if p.fast_path_contacts > 0:
                    closed = condensed.solve_contacts(
                        solver,
                        ci,
                        cj,
                        cframe,
                        gap,
                        bodies.radius,
                        bodies.inv_inertia,
                        *trial,
                        u,
                        h,
                        p.friction,
                        p.fast_path_contacts,
                    )
                if closed is None:
                    bond_step.impulse[:] = P_try  # warm start for NLGS
                    return False
                bond_impulses(bonds, bond_step.c0, bond_step.cg, trial, P_try, rot)
        contacts.impulse[:] = 0.0 if closed is None else closed
        for a, b in zip(end, trial):
            a[:] = b
        bond_step.impulse[:] = P_try
        return True
