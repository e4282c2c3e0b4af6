"""Nonlinear Gauss-Seidel (NLGS) over contacts and bonds, on body velocities.

The global problem of a step is U = H^T v, v = v_free + M^-1 H P, with a local law per
interaction (local_laws.py). The sweep visits the bonds, then the contacts, in a fixed
order (symmetric or reversed sweeps, and contacts sorted from top to bottom along
gravity, were tried on a granular bed: no fewer iterations); an open contact with zero
impulse is skipped after a test on its normal velocity alone (same result, less work);
each visit computes the local velocity from the current body velocities, removes
its own contribution (b = U - W_aa P_old), solves its local law exactly, relaxes
(P <- omega P_loc + (1-omega) P_old) and pushes the change of impulse back into the body
velocities. Off-diagonal Delassus blocks are thus never formed (cost O(nnz H) a sweep).
Bonds with the 'contact' kinematics (``rot`` True) use their velocity at the contact point
(local_laws.bond_velocity), the full block W_bb and A_inv = (I + diag(c_g) W_bb)^-1
(delassus.bond_blocks_contact), and push torques a x g onto both bodies (a rotating plate
included: inverse principal inertia (P,3) in global axes).

Convergence (LMGC90 style, on the change of reactions between two sweeps):
    quad = sqrt(sum |dP_a|² / sum |P_a|²)          (quadratic mean)
    maxm = max |dP_a| / (sqrt(sum |P_a|² / n))      (maximum, relative to the rms)
The criterion tested against the tolerance is chosen by ``norm``: 0 = quad (LMGC90's
usual "Quad"), 1 = maxm, 2 = both; both values are returned. The sweep is sequential
(deterministic).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .local_laws import bond_velocity, contact_local_solve


@njit(cache=True, inline="always")
def _push_contact(a, dp0, dp1, dp2, ci, cj, frame, radius, v, w, vp, inv_mass, inv_inertia,
                  inv_mass_plate):
    """Add the global effect of a change (dp0, dp1, dp2) of contact a's local impulse."""
    i = ci[a]
    j = cj[a]
    g0 = frame[a, 0, 0] * dp0 + frame[a, 1, 0] * dp1 + frame[a, 2, 0] * dp2
    g1 = frame[a, 0, 1] * dp0 + frame[a, 1, 1] * dp1 + frame[a, 2, 1] * dp2
    g2 = frame[a, 0, 2] * dp0 + frame[a, 1, 2] * dp1 + frame[a, 2, 2] * dp2
    n0 = frame[a, 0, 0]
    n1 = frame[a, 0, 1]
    n2 = frame[a, 0, 2]
    # n x g; candidate: arm -r_i n, torque arm x g = -r_i n x g
    c0 = n1 * g2 - n2 * g1
    c1 = n2 * g0 - n0 * g2
    c2 = n0 * g1 - n1 * g0
    mi = inv_mass[i]
    ii = -radius[i] * inv_inertia[i]
    v[i, 0] += mi * g0
    v[i, 1] += mi * g1
    v[i, 2] += mi * g2
    w[i, 0] += ii * c0
    w[i, 1] += ii * c1
    w[i, 2] += ii * c2
    if j >= 0:
        # antagonist: arm +r_j n, force -g, torque arm x (-g) = -r_j n x g
        mj = inv_mass[j]
        ij = -radius[j] * inv_inertia[j]
        v[j, 0] -= mj * g0
        v[j, 1] -= mj * g1
        v[j, 2] -= mj * g2
        w[j, 0] += ij * c0
        w[j, 1] += ij * c1
        w[j, 2] += ij * c2
    else:
        k = -1 - j
        mk = inv_mass_plate[k]
        vp[k, 0] -= mk * g0
        vp[k, 1] -= mk * g1
        vp[k, 2] -= mk * g2


@njit(cache=True, inline="always")
def contact_velocity(a, ci, cj, frame, radius, v, w, vp, out):
    """Local relative velocity (n, t, s) of contact a at the contact point into out (3,)."""
    i = ci[a]
    j = cj[a]
    n0 = frame[a, 0, 0]
    n1 = frame[a, 0, 1]
    n2 = frame[a, 0, 2]
    ri = radius[i]
    # v_i + w_i x (-r_i n)
    g0 = v[i, 0] - ri * (w[i, 1] * n2 - w[i, 2] * n1)
    g1 = v[i, 1] - ri * (w[i, 2] * n0 - w[i, 0] * n2)
    g2 = v[i, 2] - ri * (w[i, 0] * n1 - w[i, 1] * n0)
    if j >= 0:
        rj = radius[j]
        # - (v_j + w_j x (r_j n))
        g0 -= v[j, 0] + rj * (w[j, 1] * n2 - w[j, 2] * n1)
        g1 -= v[j, 1] + rj * (w[j, 2] * n0 - w[j, 0] * n2)
        g2 -= v[j, 2] + rj * (w[j, 0] * n1 - w[j, 1] * n0)
    else:
        k = -1 - j
        g0 -= vp[k, 0]
        g1 -= vp[k, 1]
        g2 -= vp[k, 2]
    for c in range(3):
        out[c] = frame[a, c, 0] * g0 + frame[a, c, 1] * g1 + frame[a, c, 2] * g2


@njit(cache=True)
def contact_velocities(ci, cj, frame, radius, v, w, vp, out):
    """Local relative velocities (C,3) of all contacts into out."""
    u = np.empty(3)
    for a in range(len(ci)):
        contact_velocity(a, ci, cj, frame, radius, v, w, vp, u)
        out[a, 0] = u[0]
        out[a, 1] = u[1]
        out[a, 2] = u[2]


@njit(cache=True, inline="always")
def _push_bond(b, dp, bi, bj, frame, v, vp, inv_mass, inv_mass_plate, arm_i, arm_j, w, wp,
               inv_inertia, inv_inertia_plate, rot):
    """Add the global effect of a change dp (3,) of bond b's local impulse: +g on i, -g on
    j (g = F^T dp) at the barycentres, plus the torques a x g at c when rot."""
    i = bi[b]
    j = bj[b]
    g0 = frame[b, 0, 0] * dp[0] + frame[b, 1, 0] * dp[1] + frame[b, 2, 0] * dp[2]
    g1 = frame[b, 0, 1] * dp[0] + frame[b, 1, 1] * dp[1] + frame[b, 2, 1] * dp[2]
    g2 = frame[b, 0, 2] * dp[0] + frame[b, 1, 2] * dp[1] + frame[b, 2, 2] * dp[2]
    mi = inv_mass[i]
    v[i, 0] += mi * g0
    v[i, 1] += mi * g1
    v[i, 2] += mi * g2
    if j >= 0:
        mj = inv_mass[j]
        v[j, 0] -= mj * g0
        v[j, 1] -= mj * g1
        v[j, 2] -= mj * g2
    else:
        k = -1 - j
        mk = inv_mass_plate[k]
        vp[k, 0] -= mk * g0
        vp[k, 1] -= mk * g1
        vp[k, 2] -= mk * g2
    if rot:
        a0 = arm_i[b, 0]
        a1 = arm_i[b, 1]
        a2 = arm_i[b, 2]
        ii = inv_inertia[i]
        w[i, 0] += ii * (a1 * g2 - a2 * g1)
        w[i, 1] += ii * (a2 * g0 - a0 * g2)
        w[i, 2] += ii * (a0 * g1 - a1 * g0)
        a0 = arm_j[b, 0]
        a1 = arm_j[b, 1]
        a2 = arm_j[b, 2]
        if j >= 0:
            ij = inv_inertia[j]
            w[j, 0] -= ij * (a1 * g2 - a2 * g1)
            w[j, 1] -= ij * (a2 * g0 - a0 * g2)
            w[j, 2] -= ij * (a0 * g1 - a1 * g0)
        else:
            k = -1 - j
            wp[k, 0] -= inv_inertia_plate[k, 0] * (a1 * g2 - a2 * g1)
            wp[k, 1] -= inv_inertia_plate[k, 1] * (a2 * g0 - a0 * g2)
            wp[k, 2] -= inv_inertia_plate[k, 2] * (a0 * g1 - a1 * g0)


@njit(cache=True)
def apply_impulses(ci, cj, cframe, radius, cP, bi, bj, bframe, bP, v, w, vp, inv_mass,
                   inv_inertia, inv_mass_plate, barm_i, barm_j, wp, inv_inertia_plate, rot):
    """v <- v + M^-1 H P for all contact (C,3) and bond (B,3) impulses (warm start); bond
    lever arms barm_i, barm_j (B,3), plate angular velocities wp (P,3) used when rot."""
    for a in range(len(ci)):
        _push_contact(a, cP[a, 0], cP[a, 1], cP[a, 2], ci, cj, cframe, radius, v, w, vp,
                      inv_mass, inv_inertia, inv_mass_plate)
    for b in range(len(bi)):
        _push_bond(b, bP[b], bi, bj, bframe, v, vp, inv_mass, inv_mass_plate, barm_i, barm_j,
                   w, wp, inv_inertia, inv_inertia_plate, rot)


@njit(cache=True)
def nlgs(ci, cj, cframe, cgap, cwn, cwt, cP, bi, bj, bframe, bw, bc0, bcg, bP, broken,
         radius, v, w, vp, inv_mass, inv_inertia, inv_mass_plate, h, mu, tol, relax,
         max_iter, norm, barm_i, barm_j, bW, bA_inv, wp, inv_inertia_plate, rot):
    """Nonlinear Gauss-Seidel sweeps until convergence.

    On entry v (N,3), w (N,3), vp (P,3), wp (P,3) must already include the impulses cP
    (C,3), bP (B,3) (see apply_impulses). Contacts: gap (C,) m, blocks cwn, cwt (C,). Bonds:
    affine law P = bc0 - bcg U (B,3); 'barycentre' (rot False): block bw (B,) (times I);
    'contact' (rot True): lever arms barm_i, barm_j (B,3), blocks bW (B,3,3) and bA_inv
    (B,3,3) (delassus.bond_blocks_contact). Returns (iterations, quad, maxm, converged).
    """
    nc = len(ci)
    nb = len(bi)
    u = np.empty(3)
    dp = np.empty(3)
    ul = np.empty(3)
    rhs = np.empty(3)
    quad = 0.0
    maxm = 0.0
    it = 0
    converged = False
    n_int = nc + nb
    if n_int == 0:
        return 0, 0.0, 0.0, True
    while it < max_iter:
        it += 1
        sum_d2 = 0.0
        sum_p2 = 0.0
        max_d2 = 0.0
        for b in range(nb):
            if broken[b]:
                continue
            if rot:
                g0, g1, g2 = bond_velocity(b, bi, bj, barm_i, barm_j, v, w, vp, wp, rot)
                for c in range(3):
                    ul[c] = bframe[b, c, 0] * g0 + bframe[b, c, 1] * g1 + bframe[b, c, 2] * g2
                for c in range(3):
                    bfree = ul[c] - (bW[b, c, 0] * bP[b, 0] + bW[b, c, 1] * bP[b, 1]
                                     + bW[b, c, 2] * bP[b, 2])
                    rhs[c] = bc0[b, c] - bcg[b, c] * bfree
                for c in range(3):
                    p_new = (bA_inv[b, c, 0] * rhs[0] + bA_inv[b, c, 1] * rhs[1]
                             + bA_inv[b, c, 2] * rhs[2])
                    p_new = relax * p_new + (1.0 - relax) * bP[b, c]
                    dp[c] = p_new - bP[b, c]
                for c in range(3):
                    bP[b, c] += dp[c]
            else:
                i = bi[b]
                j = bj[b]
                for c in range(3):
                    acc = 0.0
                    for d in range(3):
                        vj = v[j, d] if j >= 0 else vp[-1 - j, d]
                        acc += bframe[b, c, d] * (v[i, d] - vj)
                    bfree = acc - bw[b] * bP[b, c]
                    p_new = (bc0[b, c] - bcg[b, c] * bfree) / (1.0 + bcg[b, c] * bw[b])
                    p_new = relax * p_new + (1.0 - relax) * bP[b, c]
                    dp[c] = p_new - bP[b, c]
                    bP[b, c] = p_new
            _push_bond(b, dp, bi, bj, bframe, v, vp, inv_mass, inv_mass_plate, barm_i, barm_j,
                       w, wp, inv_inertia, inv_inertia_plate, rot)
            d2 = dp[0] ** 2 + dp[1] ** 2 + dp[2] ** 2
            sum_d2 += d2
            sum_p2 += bP[b, 0] ** 2 + bP[b, 1] ** 2 + bP[b, 2] ** 2
            max_d2 = max(max_d2, d2)
        for a in range(nc):
            if cP[a, 0] == 0.0 and cP[a, 1] == 0.0 and cP[a, 2] == 0.0:
                # open contact without impulse: the normal velocity n.(v_i - v_j) (rotations
                # do not contribute: (w x n).n = 0) decides alone whether it stays open
                i = ci[a]
                j = cj[a]
                un = 0.0
                for d in range(3):
                    vj = v[j, d] if j >= 0 else vp[-1 - j, d]
                    un += cframe[a, 0, d] * (v[i, d] - vj)
                if un + max(cgap[a], 0.0) / h >= 0.0:
                    continue
            contact_velocity(a, ci, cj, cframe, radius, v, w, vp, u)
            bn = u[0] - cwn[a] * cP[a, 0]
            bt = u[1] - cwt[a] * cP[a, 1]
            bs = u[2] - cwt[a] * cP[a, 2]
            pn, pt, ps = contact_local_solve(bn, bt, bs, cgap[a], h, cwn[a], cwt[a], mu)
            pn = relax * pn + (1.0 - relax) * cP[a, 0]
            pt = relax * pt + (1.0 - relax) * cP[a, 1]
            ps = relax * ps + (1.0 - relax) * cP[a, 2]
            d0 = pn - cP[a, 0]
            d1 = pt - cP[a, 1]
            d2_ = ps - cP[a, 2]
            cP[a, 0] = pn
            cP[a, 1] = pt
            cP[a, 2] = ps
            if d0 != 0.0 or d1 != 0.0 or d2_ != 0.0:
                _push_contact(a, d0, d1, d2_, ci, cj, cframe, radius, v, w, vp, inv_mass,
                              inv_inertia, inv_mass_plate)
            dd = d0 * d0 + d1 * d1 + d2_ * d2_
            sum_d2 += dd
            sum_p2 += pn * pn + pt * pt + ps * ps
            max_d2 = max(max_d2, dd)
        if sum_p2 <= 0.0:
            quad = 0.0
            maxm = 0.0
            converged = True
            break
        quad = math.sqrt(sum_d2 / sum_p2)
        maxm = math.sqrt(max_d2) / math.sqrt(sum_p2 / n_int)
        if ((norm == 0 and quad <= tol) or (norm == 1 and maxm <= tol)
                or (norm == 2 and quad <= tol and maxm <= tol)):
            converged = True
            break
    return it, quad, maxm, converged
