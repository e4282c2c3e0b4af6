"""Moreau-Jean time stepping (theta-method) of spheres, plates and bonds: the public
:class:`Simulation`.

One step of length h from t- to t+ = t- + h (Jean 1999; Eq. 14 of the paper):

1. plates: a driven plate gets the mean velocity (u(t+) - u(t-))/h of its imposed
   displacement for the whole step; a free plate's free velocity includes gravity;
2. free velocities v_free = v- + h M^-1 (m g + f_ext,theta), f_ext,theta = theta f(t+) +
   (1-theta) f(t-) when the external force is a callable, else the array as given;
3. detection at the start-of-step configuration (cell lists, gap < alert distance;
   pairs whose intact bond is their only law skipped, ``NSCDParameters.bonded_contact``),
   warm start of contact impulses from the previous step (matched by pair), of bond
   impulses from the previous step;
4. solve for the impulses: the linear fast path (linear.py) when allowed and valid (a few
   contacts that it closes solved on their Delassus operator condensed over the bonds,
   condensed.py, ``NSCDParameters.fast_path_contacts``), else nonlinear Gauss-Seidel
   (gauss_seidel.py);
5. bonds: internal variables, forces, breakage (local_laws.bond_update);
6. positions x+ = x- + h (theta v+ + (1-theta) v-) (spheres and free plates); driven plates
   at their imposed position; rotations are integrated only as angular velocities (the
   orientation of a sphere does not enter any law; a rotating plate accumulates its small
   rotation vector in ``Plates.rotation``).

Bond kinematics (``NSCDParameters.bond_kinematics``, state.Bonds): with 'contact' the
bonds act at their contact points with lever arms (torques on spheres and on rotating
plates); the linear fast path then has 6 DOF per sphere (linear.py). Rotating plates
(``Plate(rotation=True)``): translation as their mode says (e.g. driven), free rotation
about their reference point under the bond torques. Contacts do not see a plate's rotation
(their plate velocity is its translation, and they exert no torque on it): adequate for the
small head rotations of a bonded 2PB test, where the head's load passes through bonds.

Reported plate forces: ``plate_force`` = impulse / h of the spheres on the plate, i.e.
theta R(t+) + (1-theta) R(t-); ``driver_force`` = m (a_theta - g) - plate_force with a_theta
the same theta-average of the exact imposed acceleration (``_imposed_acceleration``), so the
inertia term is consistent with the reaction to O(h²) (the former (v+ - v-)/h of the
mean plate velocities was the acceleration at t-, a first-order lag of h/2: 0.06-1.6 deg of
phase at 40 Hz, h = 5e-5 s). Plates of infinite mass report -plate_force.

The default theta = 0.5 is justified in :class:`NSCDParameters`.
"""

from __future__ import annotations

import time as _time
from typing import Callable

import numba
import numpy as np

from . import condensed, detection, gauss_seidel, local_laws
from .delassus import bond_blocks, bond_blocks_contact, contact_blocks
from .linear import LinearBondSolver, bond_impulses
from .state import (CONVERGENCE_NORMS, DRIVEN, FIXED, FREE, Bonds, NSCDParameters, Plates,
                    Spheres, StepStats)


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

    def __init__(self, spheres: Spheres, plates: Plates | None = None,
                 bonds: Bonds | None = None, params: NSCDParameters | None = None,
                 external_force: np.ndarray | Callable | None = None):
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
        self._linear = None
        self._linear_key = None
        self._coef_key = None
        self._bond_work = None  # per-step bond work arrays, reused (bond_predict fills them)
        #: (P, 3) N m, mean torque of the bonds on each plate about its reference point over
        #: the last step ('contact' kinematics; zero with 'barycentre').
        self.plate_torque = np.zeros((self.plates.n, 3))
        self.linear_iterations = 0
        self._v_before = None
        self._vp_before = None
        self._w_before = None
        self._wp_before = None
        #: the velocity fields two and three steps before, most recent first (the third and
        #: fourth fields of cg_ssor's Galerkin start)
        self._older = []
        self.timings = {"detection": 0.0, "solve": 0.0, "bonds": 0.0, "other": 0.0}
        if self.params.alert_distance is None:
            self.alert_distance = 0.5 * float(spheres.radius.min()) if spheres.n else 0.0
        else:
            self.alert_distance = float(self.params.alert_distance)
        self._candidates = detection.CandidateList(self.alert_distance)
        self._exclusion_key = None

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
            detection.bonded_exclusions(self.spheres.n, self.plates.n, bnd.i[mask], bnd.j[mask])
            if mask.any() else None)
        self._exclusion_key = key

    # ------------------------------------------------------------------ one step
    def step(self) -> StepStats:
        """Advance by one time step ``params.dt``; returns its :class:`StepStats`."""
        tic = _time.perf_counter()
        p = self.params
        if p.threads > 1:
            numba.set_num_threads(p.threads)
        h, th = p.dt, p.theta
        sph, pls, bnd = self.spheres, self.plates, self.bonds
        t0, t1 = self.time, self.time + h
        inv_m = sph.inv_mass
        inv_i = sph.inv_inertia
        inv_mp = pls.inv_mass
        inv_ip = pls.inv_inertia
        finite = np.isfinite(sph.mass)
        rot = p.bond_kinematics == "contact"

        # 1. plates
        vp_start = pls.velocity.copy()
        new_point = pls.point.copy()
        for k in range(pls.n):
            if pls.mode[k] == DRIVEN:
                u0 = pls.imposed_displacement(k, t0)
                u1 = pls.imposed_displacement(k, t1)
                vp_start[k] = (u1 - u0) / h
                new_point[k] = pls.point0[k] + u1
            elif pls.mode[k] == FIXED:
                vp_start[k] = 0.0
        vp = vp_start.copy()
        wp_start = np.where(pls.rotates[:, None], pls.angular_velocity, 0.0)
        wp = wp_start.copy()
        free_p = pls.mode == FREE
        if free_p.any():
            vp[free_p] += h * (p.gravity
                               + self.plate_external_force[free_p] / pls.mass[free_p, None])

        # 2. free velocities
        v_m = sph.velocity.copy()
        w_m = sph.angular_velocity.copy()
        v = v_m.copy()
        v[finite] += h * p.gravity
        fext = self._external(t0, t1)
        if fext is not None:
            v[finite] += h * fext[finite] * inv_m[finite, None]
        v[~finite] = 0.0
        w = w_m.copy()
        w[~finite] = 0.0
        v_free = v.copy()
        vp_free = vp.copy()

        # 3. detection and warm start; the alert distance is raised (never lowered) when the
        # free velocities could close a larger gap within the step
        t_a = _time.perf_counter()
        vmax = np.sqrt((v_free**2).sum(1).max()) if len(v_free) else 0.0
        if pls.n:
            vmax += np.sqrt((vp_free**2).sum(1).max())
        if 2.0 * h * vmax > self._candidates.alert:
            self._candidates.alert = 2.0 * h * vmax
            self._candidates.skin = max(self._candidates.skin, self._candidates.alert)
            self._candidates.x_ref = None
            self.alert_distance = self._candidates.alert
        self._update_exclusions()
        ci, cj, gap, cframe = self._candidates.contacts(sph.position, sph.radius, pls.point,
                                                        pls.normal)
        cP = self._warm_contacts(ci, cj, cframe)
        cwn = np.empty(len(ci))
        cwt = np.empty(len(ci))
        contact_blocks(ci, cj, inv_m, inv_i, sph.radius, inv_mp, cwn, cwt)
        t_b = _time.perf_counter()
        self.timings["detection"] += t_b - t_a

        # bonds: affine laws of the step
        nb = bnd.n
        if self._bond_work is None or self._bond_work[0].shape[0] != nb:
            self._bond_work = (tuple(np.zeros((nb, 3)) for _ in range(4)) + (np.zeros(nb),)
                               + (np.zeros((nb, 3, 3)), np.zeros((nb, 3, 3))))
        # all entries rewritten by the kernels below
        c0, cg, d_m, u_m, bw, bW, bA = self._bond_work
        if nb:
            coef, i_den = self._bond_coefficients()
            local_laws.bond_predict(bnd.i, bnd.j, bnd.frame, bnd.rest, sph.position, v_m,
                                    pls.point, vp_start, coef, i_den, bnd.Kk, bnd.Ck,
                                    bnd.Kinf, bnd.force, bnd.delta_c, bnd.delta_k, bnd.broken,
                                    h, th, c0, cg, d_m, u_m, bnd.arm_i, bnd.arm_j, w_m,
                                    wp_start, bnd.displacement, rot)
        bP = self.bond_impulse
        bP[bnd.broken] = 0.0
        t_c = _time.perf_counter()
        self.timings["bonds"] += t_c - t_b

        # 4. solve
        solver = "nlgs"
        it, quad, maxm, conv = 0, 0.0, 0.0, True
        if p.fast_path and nb and self._fast_path(v_free, vp_free, c0, cg, v, vp, bP, inv_m,
                                                  inv_mp, ci, cj, cframe, gap, w, h,
                                                  wp, inv_i, inv_ip, rot, cP):
            solver = "linear"
            it = self.linear_iterations
        else:
            v[:] = v_free
            vp[:] = vp_free
            w[:] = w_m
            w[~finite] = 0.0
            wp[:] = wp_start
            if nb:  # Delassus blocks of the bonds: needed by NLGS only
                if rot:
                    bond_blocks_contact(bnd.i, bnd.j, bnd.frame, bnd.arm_i, bnd.arm_j, inv_m,
                                        inv_i, inv_mp, inv_ip, cg, bW, bA)
                else:
                    bond_blocks(bnd.i, bnd.j, inv_m, inv_mp, bw)
            gauss_seidel.apply_impulses(ci, cj, cframe, sph.radius, cP, bnd.i, bnd.j,
                                        bnd.frame, bP, v, w, vp, inv_m, inv_i, inv_mp,
                                        bnd.arm_i, bnd.arm_j, wp, inv_ip, rot)
            it, quad, maxm, conv = gauss_seidel.nlgs(
                ci, cj, cframe, gap, cwn, cwt, cP, bnd.i, bnd.j, bnd.frame, bw, c0, cg, bP,
                bnd.broken, sph.radius, v, w, vp, inv_m, inv_i, inv_mp, h, p.friction,
                p.tolerance, p.relaxation, p.max_iterations, CONVERGENCE_NORMS[p.convergence],
                bnd.arm_i, bnd.arm_j, bW, bA, wp, inv_ip, rot)
        t_d = _time.perf_counter()
        self.timings["solve"] += t_d - t_c

        # 5. bonds update
        n_new, diss_b = 0, 0.0
        if nb:
            n_new, diss_b = local_laws.bond_update(
                bnd.i, bnd.j, bnd.frame, coef, i_den, bnd.Kk, bnd.Ck, bnd.Kinf, bnd.r_crit,
                bnd.force, bnd.delta_c, bnd.delta_k, bnd.broken, h, th, d_m, u_m, v, vp, bP,
                bnd.arm_i, bnd.arm_j, w, wp, bnd.displacement, rot)
        # contact dissipation: -P . (theta U+ + (1-theta) U-)
        diss_c = 0.0
        if cP.any():
            u_plus = np.empty((len(ci), 3))
            u_minus = np.empty((len(ci), 3))
            self._contact_velocities(ci, cj, cframe, v, w, vp, u_plus)
            self._contact_velocities(ci, cj, cframe, v_m, w_m, vp_start, u_minus)
            diss_c = float(-(cP * (th * u_plus + (1 - th) * u_minus)).sum())
        t_e = _time.perf_counter()
        self.timings["bonds"] += t_e - t_d

        # plate forces (mean over the step) from contacts and bonds
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
            if rot:
                np.add.at(self.plate_torque, -1 - bnd.j[bp], np.cross(bnd.arm_j[bp], -g / h))
        driver = np.zeros((pls.n, 3))
        for k in range(pls.n):
            if pls.mode[k] == DRIVEN and np.isfinite(pls.mass[k]):
                # theta-average of the exact imposed acceleration: consistent with the
                # bond/contact impulses P = h (theta R+ + (1-theta) R-) in plate_force
                acc = (th * self._imposed_acceleration(k, t1)
                       + (1 - th) * self._imposed_acceleration(k, t0))
                driver[k] = pls.mass[k] * (acc - p.gravity) - plate_force[k]
            elif pls.mode[k] in (DRIVEN, FIXED):  # infinite mass: inertia not counted
                driver[k] = -plate_force[k]

        # 6. positions
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
                pls.point[k] = new_point[k]
        pls.velocity[:] = vp
        pls.rotation += h * (th * wp + (1 - th) * wp_start)
        pls.angular_velocity[:] = wp
        self.contact_i, self.contact_j = ci, cj
        self.contact_impulse, self.contact_frame = cP, cframe
        self.time = t1
        self.step_index += 1
        self.timings["other"] += _time.perf_counter() - t_e + (t_a - tic)
        return StepStats(time=t1, solver=solver, iterations=int(it), residual_quad=float(quad),
                         residual_max=float(maxm), converged=bool(conv), n_contacts=len(ci),
                         n_active_contacts=int((cP[:, 0] > 0).sum()),
                         n_bonds=self.n_intact_bonds(), n_broken=int(n_new),
                         n_broken_total=int(bnd.broken.sum()), plate_force=plate_force,
                         driver_force=driver, dissipated=float(diss_b + diss_c))

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
            local_laws.bond_coefficients(bnd.Km, bnd.Cm, bnd.Kk, bnd.Ck, p.dt, p.theta,
                                         *self._coef)
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
        return (pls.imposed_displacement(k, t + h) - 2.0 * pls.imposed_displacement(k, t)
                + u_m) / (h * h)

    def _contact_velocities(self, ci, cj, cframe, v, w, vp, out):
        gauss_seidel.contact_velocities(ci, cj, cframe, self.spheres.radius, v, w, vp, out)

    def _warm_contacts(self, ci, cj, cframe):
        """Impulses of the previous step's contacts on the same pairs, re-expressed in the
        new frames (global vectors projected); zero for new contacts."""
        cP = np.zeros((len(ci), 3))
        if len(self.contact_i) == 0 or len(ci) == 0 or not self.contact_impulse.any():
            return cP
        base = self.spheres.n + self.plates.n + 1
        old_key = self.contact_i * base + np.where(self.contact_j >= 0, self.contact_j,
                                                   self.spheres.n - 1 - self.contact_j)
        new_key = ci * base + np.where(cj >= 0, cj, self.spheres.n - 1 - cj)
        order = np.argsort(old_key)
        sk = old_key[order]
        pos = np.searchsorted(sk, new_key)
        pos = np.minimum(pos, len(sk) - 1)
        hit = sk[pos] == new_key
        if hit.any():
            src = order[pos[hit]]
            g = np.einsum("ac,acd->ad", self.contact_impulse[src], self.contact_frame[src])
            cP[hit] = np.einsum("acd,ad->ac", cframe[hit], g)
            # keep the warm start inside the friction cone
            pn = np.maximum(cP[:, 0], 0.0)
            pt = np.hypot(cP[:, 1], cP[:, 2])
            lim = self.params.friction * pn
            scale = np.where(pt > lim, lim / np.maximum(pt, 1e-300), 1.0)
            cP[:, 0] = pn
            cP[:, 1:] *= scale[:, None]
        return cP

    def _fast_path(self, v_free, vp_free, c0, cg, v, vp, bP, inv_m, inv_mp, ci, cj, cframe,
                   gap, w, h, wp, inv_i, inv_ip, rot, cP) -> bool:
        """Try the linear solver; True if its solution is the solution of the step (then
        v, vp, bP, cP, and with rot also w, wp, hold it). Contacts that the linear solution
        closes are solved on their Delassus operator condensed over the bonds
        (:mod:`.condensed`) when there are at most ``fast_path_contacts`` of them."""
        bnd = self.bonds
        p = self.params
        key = (p.dt, p.theta, int(bnd.broken.sum()), bnd.n, p.linear_solver,
               p.linear_tolerance, rot, p.threads, p.linear_ssor_omega)
        if self._linear_key != key:
            rotation = None
            if rot:
                rotation = dict(arm_i=bnd.arm_i, arm_j=bnd.arm_j, inv_inertia=inv_i,
                                inv_inertia_plate=inv_ip)
            self._linear = LinearBondSolver(inv_m, inv_mp, bnd.i, bnd.j, bnd.frame, cg,
                                            bnd.broken, method=p.linear_solver,
                                            tolerance=p.linear_tolerance, rotation=rotation,
                                            threads=p.threads, ssor_omega=p.linear_ssor_omega)
            self._linear_key = key
        v_try = v_free.copy()
        vp_try = vp_free.copy()
        w_try = w.copy()
        wp_try = wp.copy()
        P_try = np.zeros_like(bP)
        # initial guess of the iterative solver: linear extrapolation of the velocities
        v0, vp0 = self.spheres.velocity, self.plates.velocity
        w0, wp0 = self.spheres.angular_velocity, self.plates.angular_velocity
        previous = None  # cg_ssor: Galerkin combination of the last two to four velocity fields
        if self._v_before is not None and self._v_before.shape == v0.shape:
            previous = ((v0, w0, vp0, wp0),
                        (self._v_before, self._w_before if rot else w0, self._vp_before,
                         self._wp_before if rot else wp0))
            for old in self._older:
                if old[0].shape != v0.shape:
                    break
                previous += ((old[0], old[1] if rot else w0, old[2], old[3] if rot else wp0),)
            v0 = 2.0 * v0 - self._v_before
            vp0 = 2.0 * vp0 - self._vp_before
            if rot and self._w_before is not None:
                w0 = 2.0 * w0 - self._w_before
                wp0 = 2.0 * wp0 - self._wp_before
        self._linear.solve(v_free, w.copy(), vp_free, wp.copy(), bnd.i, bnd.j, bnd.frame,
                           bnd.arm_i, bnd.arm_j, c0, cg, bnd.broken, v_try, w_try, vp_try,
                           wp_try, P_try, start=(v0, w0, vp0, wp0), previous=previous)
        self.linear_iterations = self._linear.last_iterations
        # contacts must stay open with zero reaction, or be solved by the condensed problem
        # (cP keeps its warm start for NLGS until the fast path has succeeded)
        closed = None
        if len(ci):
            u = np.empty((len(ci), 3))
            self._contact_velocities(ci, cj, cframe, v_try, w_try, vp_try, u)
            if np.any(u[:, 0] + np.maximum(gap, 0.0) / h < 0.0):
                if p.fast_path_contacts > 0:
                    closed = condensed.solve_contacts(
                        self._linear, ci, cj, cframe, gap, self.spheres.radius, inv_i, v_try,
                        w_try, vp_try, wp_try, u, h, p.friction, p.fast_path_contacts)
                if closed is None:
                    bP[:] = P_try  # warm start for NLGS
                    return False
                bond_impulses(bnd.i, bnd.j, bnd.frame, bnd.arm_i, bnd.arm_j, c0, cg,
                              bnd.broken, v_try, w_try, vp_try, wp_try, P_try, rot)
        cP[:] = 0.0 if closed is None else closed
        v[:] = v_try
        vp[:] = vp_try
        w[:] = w_try
        wp[:] = wp_try
        bP[:] = P_try
        return True
