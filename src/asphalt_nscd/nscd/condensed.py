"""Contacts inside the linear fast path: the Signorini-Coulomb problem condensed on the bonds.

Keeps a step of the linear fast path (:mod:`.linear`) in which a few unbonded contacts
close on that path, instead of redoing it by nonlinear Gauss-Seidel over all bonds. Exact,
not a penalty:

While the bonds are linear, the step's unknown velocities x obey A x = rhs + J^T P
(linear/: A = M + sum_b L_b^T G_b L_b), where P (3|C|,) are the local impulses (n, t, s)
of a set C of contacts and J (3|C|, ndof) their velocity Jacobian: the contact velocity is
U = J x (:func:`asphalt_nscd.nscd.gauss_seidel.contact_velocity`: v_i + r_i n x w_i - v_j +
r_j n x w_j, or - v_plate, in the contact frame) and J^T P the impulses and torques the
contact applies (the same operator as ``_push_contact``). With x_lin = A^-1 rhs the linear
solution of the step,

    U = U_lin + W P,    W = J A^-1 J^T    (the Delassus operator of C condensed over the bonds)

a dense 3|C| x 3|C| matrix. The Signorini condition U_n + max(g, 0)/h >= 0 _|_ P_n >= 0 and
Coulomb's law (Eqs. 6-7, the same velocity-level form as the NLGS: local_laws) are solved on
it by nonlinear block Gauss-Seidel (:func:`condensed_nlgs`). Unlike a contact's own block in
the full problem (diagonal: local_laws.contact_local_solve), a condensed block W_kk is full:
the bonds couple the normal and tangential directions, so each contact's local problem is
solved exactly with its full block (:func:`local_solve_block`: open, sticking P = -W^-1 b,
or sliding along the direction, found by scan and bisection, whose slip velocity opposes
it). Then x = x_lin + A^-1 J^T P and the bond impulses follow from their
affine laws (linear.bond_impulses). This is the problem the NLGS of the whole step solves,
with the bonds eliminated exactly instead of iterated, hence the same solution to the NLGS
tolerance (tests/unit/test_nscd_condensed.py).

A^-1 J^T needs the columns of A^-1 of the unknown blocks (translation, rotation) of the
bodies that C touches: solved once per linear system and cached
(:meth:`asphalt_nscd.nscd.linear.LinearBondSolver.response`); the contact frames change at
every step but enter only through J. With 'barycentre' bond kinematics the rotations are
not unknowns of A: a contact torque changes the sphere's own angular velocity only
(response I^-1).

Active set: C starts as the contacts the linear solution violates (U_n + max(g,0)/h < 0);
contacts that the corrected solution violates join C and the small problem is solved again
(at most ``rounds`` times). The function gives up (the caller redoes the step by NLGS over
everything) when C would hold more than ``max_contacts`` contacts or the small NLGS does not
converge.
"""

from __future__ import annotations

import math

import numpy as np

from ._jit import helper, kernel
from .gauss_seidel import contact_velocities
from .linear import LinearSolveError, skew


@helper
def _slide_residual(theta, bn, bt, bs, W, r, mu):
    """Sliding along direction (cos theta, sin theta) of the local (t, s) plane: P = p_n (1,
    mu cos, mu sin) with U_n = 0. Returns (p_n, f, along): f = 0 and along >= 0 when the
    slip velocity U_t opposes the direction (f: its cross product with the direction,
    along: the component of -U_t along it); p_n <= 0 when no such p_n exists."""
    c = math.cos(theta)
    sn = math.sin(theta)
    den = W[r, r] + mu * (W[r, r + 1] * c + W[r, r + 2] * sn)
    if den <= 0.0:
        return -1.0, 0.0, -1.0
    pn = -bn / den
    ut = bt + pn * (W[r + 1, r] + mu * (W[r + 1, r + 1] * c + W[r + 1, r + 2] * sn))
    us = bs + pn * (W[r + 2, r] + mu * (W[r + 2, r + 1] * c + W[r + 2, r + 2] * sn))
    return pn, sn * ut - c * us, -(c * ut + sn * us)


@helper
def local_solve_block(bn, bt, bs, gap, h, W, r, mu):
    """Exact Signorini-Coulomb impulse (Pn, Pt, Ps) of one contact whose own Delassus block
    W[r:r+3, r:r+3] (1/kg) is full (normal-tangential coupling through the bonds): local
    free velocity (bn, bt, bs) m/s excluding its own impulse, gap m, step h s. Open if
    bn + max(gap,0)/h >= 0; else sticking, P = -W^-1 b, if that lies in the cone; else
    sliding, P = p_n (1, mu cos, mu sin) with U_n = 0 and the slip velocity opposite to
    the direction, found by a scan of 720 directions of the arc where p_n > 0 and
    bisection. Returns (Pn, Pt, Ps, ok); ok False when no sliding solution is found."""
    bn = bn + max(gap, 0.0) / h
    if bn >= 0.0:
        return 0.0, 0.0, 0.0, True
    a00 = W[r, r]
    a01 = W[r, r + 1]
    a02 = W[r, r + 2]
    a10 = W[r + 1, r]
    a11 = W[r + 1, r + 1]
    a12 = W[r + 1, r + 2]
    a20 = W[r + 2, r]
    a21 = W[r + 2, r + 1]
    a22 = W[r + 2, r + 2]
    det = a00 * (a11 * a22 - a12 * a21) - a01 * (a10 * a22 - a12 * a20) + a02 * (a10 * a21 - a11 * a20)
    trial_t = -bt
    trial_s = -bs
    if det > 0.0:
        pn = -((a11 * a22 - a12 * a21) * bn - (a01 * a22 - a02 * a21) * bt + (a01 * a12 - a02 * a11) * bs) / det
        pt = -(-(a10 * a22 - a12 * a20) * bn + (a00 * a22 - a02 * a20) * bt - (a00 * a12 - a02 * a10) * bs) / det
        ps = -((a10 * a21 - a11 * a20) * bn - (a00 * a21 - a01 * a20) * bt + (a00 * a11 - a01 * a10) * bs) / det
        if pn > 0.0 and math.sqrt(pt * pt + ps * ps) <= mu * pn:
            return pn, pt, ps, True
        trial_t = pt
        trial_s = ps
    if mu == 0.0:  # frictionless: P = (p_n, 0, 0), U_n = 0
        return -bn / a00, 0.0, 0.0, a00 > 0.0
    # sliding: roots of f with p_n > 0 and along >= 0; the one nearest the trial direction
    # (the sticking impulse's, else the opposite of the free slip). p_n > 0 where
    # den(theta) = W_nn + mu (W_nt cos + W_ns sin) = A + B cos(theta - phi) > 0: the whole
    # circle if B < A, else the arc |theta - phi| < arccos(-A/B), on which f is continuous;
    # scanned in x with theta = phi + arc sin(pi x / 2), which crowds the points towards the
    # arc's ends (p_n -> infinity there, where roots lie close to the end).
    ref = math.atan2(trial_s, trial_t)
    big = mu * math.sqrt(a01 * a01 + a02 * a02)
    whole = big < a00
    phi = ref if whole else math.atan2(a02, a01)
    arc = math.pi if whole else math.acos(-a00 / big)
    n_scan = 720
    best = 0.0
    best_d = 1e300
    x0 = 0.0
    f0 = 0.0
    first = 0 if whole else 1  # den = 0 at the arc's ends
    for k in range(first, n_scan + 1 - first):
        x1 = -1.0 + 2.0 * k / n_scan
        t1 = phi + (arc * x1 if whole else arc * math.sin(0.5 * math.pi * x1))
        pn1, f1, al1 = _slide_residual(t1, bn, bt, bs, W, r, mu)
        if k > first and ((f0 <= 0.0 <= f1) or (f1 <= 0.0 <= f0)):
            lo = x0
            hi = x1
            flo = f0
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                tm = phi + (arc * mid if whole else arc * math.sin(0.5 * math.pi * mid))
                pm, fm, am = _slide_residual(tm, bn, bt, bs, W, r, mu)
                if (fm <= 0.0) == (flo <= 0.0):
                    lo = mid
                    flo = fm
                else:
                    hi = mid
            mid = 0.5 * (lo + hi)
            tm = phi + (arc * mid if whole else arc * math.sin(0.5 * math.pi * mid))
            pm, fm, am = _slide_residual(tm, bn, bt, bs, W, r, mu)
            d = abs(math.atan2(math.sin(tm - ref), math.cos(tm - ref)))
            if pm > 0.0 and am >= 0.0 and d < best_d:
                best = tm
                best_d = d
        x0 = x1
        f0 = f1
    if best_d == 1e300:
        return 0.0, 0.0, 0.0, False
    pm, fm, am = _slide_residual(best, bn, bt, bs, W, r, mu)
    return pm, mu * pm * math.cos(best), mu * pm * math.sin(best), True


@kernel
def condensed_nlgs(W, u_free, gap, h, mu, tol, max_iter, P):
    """Nonlinear (block) Gauss-Seidel on the condensed contact problem U = u_free + W P.

    W (3C, 3C) 1/kg, u_free (3C,) m/s (local n, t, s per contact), gap (C,) m, h s, mu:
    Coulomb coefficient; P (3C,) N s: initial guess on entry, solution on return. Each
    contact's local problem is solved exactly with its full 3x3 block
    (:func:`local_solve_block`). Stops when the change of P over a sweep is <= tol |P| (or
    P = 0). Returns (sweeps, converged).
    """
    nc = len(gap)
    n3 = 3 * nc
    it = 0
    while it < max_iter:
        it += 1
        sum_d2 = 0.0
        sum_p2 = 0.0
        for k in range(nc):
            r = 3 * k
            u0 = u_free[r]
            u1 = u_free[r + 1]
            u2 = u_free[r + 2]
            for m in range(n3):
                if m < r or m >= r + 3:
                    pm = P[m]
                    u0 += W[r, m] * pm
                    u1 += W[r + 1, m] * pm
                    u2 += W[r + 2, m] * pm
            pn, pt, ps, ok = local_solve_block(u0, u1, u2, gap[k], h, W, r, mu)
            if not ok:
                return it, False
            d0 = pn - P[r]
            d1 = pt - P[r + 1]
            d2 = ps - P[r + 2]
            P[r] = pn
            P[r + 1] = pt
            P[r + 2] = ps
            sum_d2 += d0 * d0 + d1 * d1 + d2 * d2
            sum_p2 += pn * pn + pt * pt + ps * ps
        if sum_p2 == 0.0 or math.sqrt(sum_d2) <= tol * math.sqrt(sum_p2):
            return it, True
    return it, False


def _jacobian(sel, ci, cj, cframe, radius, inv_inertia, solver):
    """J (3|C|, 3|Y|) of the contacts ``sel`` on the body blocks Y they touch, and Y as a list
    of keys: ('A', block) for an unknown block of the linear system, ('R', sphere) for a
    rotation outside it ('barycentre' kinematics; response I^-1)."""
    keys, index, entries = [], {}, []

    def add(key, k, coef):
        if key not in index:
            index[key] = len(keys)
            keys.append(key)
        entries.append((k, index[key], coef))

    normal_x = skew(cframe[sel, 0])
    for k, a in enumerate(sel):
        F = cframe[a]
        nx = normal_x[k]
        for body, sign in ((ci[a], 1.0), (cj[a], -1.0)):
            if body >= 0:
                if solver.st[body] >= 0:
                    add(("A", int(solver.st[body])), k, sign * F)
                rot = radius[body] * F @ nx  # r (n x w): the same sign for i and j
                if solver.rot:
                    if solver.sr[body] >= 0:
                        add(("A", int(solver.sr[body])), k, rot)
                elif inv_inertia[body] > 0.0:
                    add(("R", int(body)), k, rot)
            elif len(solver.pt) and solver.pt[-1 - body] >= 0:
                add(("A", int(solver.pt[-1 - body])), k, -F)
    J = np.zeros((3 * len(sel), 3 * len(keys)))
    for k, c, coef in entries:
        J[3 * k : 3 * k + 3, 3 * c : 3 * c + 3] += coef
    return J, keys


def solve_contacts(
    solver,
    ci,
    cj,
    cframe,
    gap,
    radius,
    inv_inertia,
    v,
    w,
    vp,
    wp,
    u_lin,
    h,
    mu,
    max_contacts,
    tol=1e-12,
    max_iter=10000,
    rounds=8,
):
    """Contact impulses of a fast-path step whose linear solution closes contacts.

    Parameters
    ----------
    solver : the step's :class:`asphalt_nscd.nscd.linear.LinearBondSolver`.
    ci, cj (C,), cframe (C,3,3), gap (C,) m: the step's contact candidates (detection.py);
    radius (N,) m, inv_inertia (N,) 1/(kg m²).
    v, w (N,3), vp, wp (P,3): the linear solution of the step on entry (m/s, rad/s); on
        success the corrected velocities (else unchanged).
    u_lin (C,3) m/s: the local contact velocities of that linear solution
        (gauss_seidel.contact_velocities; the caller's validity test computed them).
    h : s; mu : Coulomb coefficient; max_contacts : most contacts in the condensed problem.
    tol, max_iter : of :func:`condensed_nlgs`; rounds : active-set rounds.

    Returns
    -------
    (C,3) N s local impulses of every candidate (zero for the open ones), or None when the
    step is to be redone by NLGS (more than ``max_contacts`` closing, no convergence, or a
    column of A^-1 whose solve did not converge: :meth:`LinearBondSolver.response`).
    Bond impulses are not updated here (the caller applies linear.bond_impulses).
    """
    nc = len(ci)
    slack = np.maximum(gap, 0.0) / h
    active = [int(a) for a in np.flatnonzero(u_lin[:, 0] + slack < 0.0)]
    x_lin = solver.gather(v, w, vp, wp)
    P = np.zeros((nc, 3))
    u = np.empty((nc, 3))
    for _ in range(rounds):
        if len(active) > max_contacts:
            return None
        sel = np.array(active, dtype=np.int64)
        J, keys = _jacobian(sel, ci, cj, cframe, radius, inv_inertia, solver)
        R = np.zeros((J.shape[1], J.shape[1]))
        cols = {}
        for c, (kind, b) in enumerate(keys):
            if kind == "A":
                try:
                    cols[c] = solver.response(b)
                except LinearSolveError:  # a column of A^-1 not converged: NLGS redoes the step
                    return None
                for r, (kind_r, b_r) in enumerate(keys):
                    if kind_r == "A":
                        R[3 * r : 3 * r + 3, 3 * c : 3 * c + 3] = cols[c][3 * b_r : 3 * b_r + 3]
            else:
                R[3 * c : 3 * c + 3, 3 * c : 3 * c + 3] = inv_inertia[b] * np.eye(3)
        Pc = np.ascontiguousarray(P[sel].ravel())
        _, ok = condensed_nlgs(
            J @ R @ J.T,
            np.ascontiguousarray(u_lin[sel].ravel()),
            np.ascontiguousarray(gap[sel]),
            h,
            mu,
            tol,
            max_iter,
            Pc,
        )
        if not ok:
            return None
        q = J.T @ Pc  # impulses on the body blocks
        x = x_lin.copy()
        v_n, w_n, vp_n, wp_n = v.copy(), w.copy(), vp.copy(), wp.copy()
        for c, (kind, b) in enumerate(keys):
            if kind == "A":
                x += cols[c] @ q[3 * c : 3 * c + 3]
            else:
                w_n[b] += inv_inertia[b] * q[3 * c : 3 * c + 3]
        solver.scatter(x, v_n, w_n, vp_n, wp_n)
        P[sel] = Pc.reshape(-1, 3)
        contact_velocities(ci, cj, cframe, radius, v_n, w_n, vp_n, u)
        closing = u[:, 0] + slack < 0.0
        closing[sel] = False
        if not closing.any():
            v[:], w[:], vp[:], wp[:] = v_n, w_n, vp_n, wp_n
            return P
        active += [int(a) for a in np.flatnonzero(closing)]
    return None
