"""Nonlinear Gauss-Seidel (NLGS) over contacts and bonds, on body velocities.

The global problem of a step is U = H^T v, v = v_free + M^-1 H P, with a local law per
interaction (local_laws.py). The sweep visits the bonds, then the contacts, in a fixed
order; an open contact with zero
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

from ._jit import helper, kernel
from .local_laws import bond_velocity, contact_local_solve


@helper
def _push_contact(a, dp0, dp1, dp2, ci, cj, frame, radius, v, w, vp, inv_mass, inv_inertia, inv_mass_plate):
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


@helper
def contact_velocity(a, ci, cj, frame, radius, v, w, vp):
    """Local relative velocity (n, t, s) (3 floats, m/s) of contact a at the contact
    point."""
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
    return (
        frame[a, 0, 0] * g0 + frame[a, 0, 1] * g1 + frame[a, 0, 2] * g2,
        frame[a, 1, 0] * g0 + frame[a, 1, 1] * g1 + frame[a, 1, 2] * g2,
        frame[a, 2, 0] * g0 + frame[a, 2, 1] * g1 + frame[a, 2, 2] * g2,
    )


@kernel
def contact_velocities(ci, cj, frame, radius, v, w, vp, out):
    """Local relative velocities (C,3) of all contacts into out."""
    for a in range(len(ci)):
        out[a, 0], out[a, 1], out[a, 2] = contact_velocity(a, ci, cj, frame, radius, v, w, vp)


@kernel
def warm_impulses(src, old_impulse, old_frame, frame, friction, out):
    """Warm start (C,3) into ``out`` (zeroed by the caller): contact a with a previous contact on the
    same pair (``src[a]`` >= 0, its row in the previous step's arrays) takes that contact's local
    impulse ``old_impulse`` (M,3) as a global vector (``old_frame`` (M,3,3) rows the local axes)
    projected on its new frame ``frame`` (C,3,3), then kept inside the friction cone
    ``|P_t| <= friction P_n`` (P_n >= 0); the others stay zero."""
    for a in range(len(src)):
        b = src[a]
        if b < 0:
            continue
        p0, p1, p2 = old_impulse[b, 0], old_impulse[b, 1], old_impulse[b, 2]
        g0 = p0 * old_frame[b, 0, 0] + p1 * old_frame[b, 1, 0] + p2 * old_frame[b, 2, 0]
        g1 = p0 * old_frame[b, 0, 1] + p1 * old_frame[b, 1, 1] + p2 * old_frame[b, 2, 1]
        g2 = p0 * old_frame[b, 0, 2] + p1 * old_frame[b, 1, 2] + p2 * old_frame[b, 2, 2]
        # summed in the order of NumPy's einsum (first and last term, then the middle): the warm start, and
        # so the chaotic deposition's trajectory, is bit for bit that of the vectorized form it replaces
        pn = (frame[a, 0, 0] * g0 + frame[a, 0, 2] * g2) + frame[a, 0, 1] * g1
        t1 = (frame[a, 1, 0] * g0 + frame[a, 1, 2] * g2) + frame[a, 1, 1] * g1
        t2 = (frame[a, 2, 0] * g0 + frame[a, 2, 2] * g2) + frame[a, 2, 1] * g1
        pn = max(pn, 0.0)
        pt = math.hypot(t1, t2)
        lim = friction * pn
        scale = lim / max(pt, 1e-300) if pt > lim else 1.0
        out[a, 0] = pn
        out[a, 1] = t1 * scale
        out[a, 2] = t2 * scale


@helper
def _push_bond(
    b,
    dp0,
    dp1,
    dp2,
    bi,
    bj,
    frame,
    v,
    vp,
    inv_mass,
    inv_mass_plate,
    arm_i,
    arm_j,
    w,
    wp,
    inv_inertia,
    inv_inertia_plate,
    rot,
):
    """Add the global effect of a change (dp0, dp1, dp2) of bond b's local impulse: +g on
    i, -g on j (g = F^T dp) at the barycentres, plus the torques a x g at c when rot."""
    i = bi[b]
    j = bj[b]
    g0 = frame[b, 0, 0] * dp0 + frame[b, 1, 0] * dp1 + frame[b, 2, 0] * dp2
    g1 = frame[b, 0, 1] * dp0 + frame[b, 1, 1] * dp1 + frame[b, 2, 1] * dp2
    g2 = frame[b, 0, 2] * dp0 + frame[b, 1, 2] * dp1 + frame[b, 2, 2] * dp2
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


@kernel
def apply_impulses(contacts, bonds, step, bodies, vel, rot):
    """v <- v + M^-1 H P for all contact and bond impulses (warm start).

    contacts : bundles.Contacts (impulse (C,3) N s read); bonds : bundles.BondGeometry;
    step : bundles.BondStep (impulse (B,3) N s read); bodies : bundles.Bodies;
    vel : bundles.Velocities, updated in place (plate angular velocities wp (P,3) only when
    rot, the 'contact' kinematics)."""
    ci, cj, cframe, cP = contacts.i, contacts.j, contacts.frame, contacts.impulse
    bi, bj, bframe, barm_i, barm_j = bonds.i, bonds.j, bonds.frame, bonds.arm_i, bonds.arm_j
    bP = step.impulse
    radius, inv_mass, inv_inertia = bodies.radius, bodies.inv_mass, bodies.inv_inertia
    inv_mass_plate, inv_inertia_plate = bodies.inv_mass_plate, bodies.inv_inertia_plate
    v, w, vp, wp = vel.v, vel.w, vel.vp, vel.wp
    for a in range(len(ci)):
        _push_contact(
            a, cP[a, 0], cP[a, 1], cP[a, 2], ci, cj, cframe, radius, v, w, vp, inv_mass, inv_inertia, inv_mass_plate
        )
    for b in range(len(bi)):
        _push_bond(
            b,
            bP[b, 0],
            bP[b, 1],
            bP[b, 2],
            bi,
            bj,
            bframe,
            v,
            vp,
            inv_mass,
            inv_mass_plate,
            barm_i,
            barm_j,
            w,
            wp,
            inv_inertia,
            inv_inertia_plate,
            rot,
        )


@kernel
def nlgs(contacts, bonds, step, bodies, vel, opts):
    """Nonlinear Gauss-Seidel sweeps until convergence (Eqs. 6-7 for the contacts, the affine
    bond law of Eq. 25).

    contacts : bundles.Contacts, gap (C,) m, blocks wn, wt (C,) s/kg, impulse (C,3) N s
        updated in place;
    bonds : bundles.BondGeometry; step : bundles.BondStep, affine law P = c0 - cg U (B,3),
        with 'barycentre' (opts.rot False) the block w (B,) (times I), with 'contact'
        (opts.rot True) the blocks W (B,3,3) and A_inv (B,3,3)
        (delassus.bond_blocks_contact); impulse (B,3) N s updated in place;
    bodies : bundles.Bodies; vel : bundles.Velocities, which on entry must already include
        the impulses (see apply_impulses), updated in place;
    opts : bundles.NLGSOptions (h, mu, tol, relax, max_iter, norm, rot).

    Returns (iterations, quad, maxm, converged).
    """
    ci, cj, cframe, cgap = contacts.i, contacts.j, contacts.frame, contacts.gap
    cwn, cwt, cP = contacts.wn, contacts.wt, contacts.impulse
    bi, bj, bframe, broken = bonds.i, bonds.j, bonds.frame, bonds.broken
    barm_i, barm_j = bonds.arm_i, bonds.arm_j
    bw, bc0, bcg, bP, bW, bA_inv = step.w, step.c0, step.cg, step.impulse, step.W, step.A_inv
    radius, inv_mass, inv_inertia = bodies.radius, bodies.inv_mass, bodies.inv_inertia
    inv_mass_plate, inv_inertia_plate = bodies.inv_mass_plate, bodies.inv_inertia_plate
    v, w, vp, wp = vel.v, vel.w, vel.vp, vel.wp
    h, mu, tol, relax = opts.h, opts.mu, opts.tol, opts.relax
    max_iter, norm, rot = opts.max_iter, opts.norm, opts.rot
    nc = len(ci)
    nb = len(bi)
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
            g0, g1, g2 = bond_velocity(b, bi, bj, barm_i, barm_j, v, w, vp, wp, rot)
            if rot:
                ul0 = bframe[b, 0, 0] * g0 + bframe[b, 0, 1] * g1 + bframe[b, 0, 2] * g2
                ul1 = bframe[b, 1, 0] * g0 + bframe[b, 1, 1] * g1 + bframe[b, 1, 2] * g2
                ul2 = bframe[b, 2, 0] * g0 + bframe[b, 2, 1] * g1 + bframe[b, 2, 2] * g2
                p0 = bP[b, 0]
                p1 = bP[b, 1]
                p2 = bP[b, 2]
                r0 = bc0[b, 0] - bcg[b, 0] * (ul0 - (bW[b, 0, 0] * p0 + bW[b, 0, 1] * p1 + bW[b, 0, 2] * p2))
                r1 = bc0[b, 1] - bcg[b, 1] * (ul1 - (bW[b, 1, 0] * p0 + bW[b, 1, 1] * p1 + bW[b, 1, 2] * p2))
                r2 = bc0[b, 2] - bcg[b, 2] * (ul2 - (bW[b, 2, 0] * p0 + bW[b, 2, 1] * p1 + bW[b, 2, 2] * p2))
                n0 = bA_inv[b, 0, 0] * r0 + bA_inv[b, 0, 1] * r1 + bA_inv[b, 0, 2] * r2
                n1 = bA_inv[b, 1, 0] * r0 + bA_inv[b, 1, 1] * r1 + bA_inv[b, 1, 2] * r2
                n2 = bA_inv[b, 2, 0] * r0 + bA_inv[b, 2, 1] * r1 + bA_inv[b, 2, 2] * r2
                dp0 = relax * n0 + (1.0 - relax) * p0 - p0
                dp1 = relax * n1 + (1.0 - relax) * p1 - p1
                dp2 = relax * n2 + (1.0 - relax) * p2 - p2
                bP[b, 0] += dp0
                bP[b, 1] += dp1
                bP[b, 2] += dp2
            else:
                ww = bw[b]
                # component c: P = (c0 - cg (U - w P_old)) / (1 + cg w), relaxed
                acc = bframe[b, 0, 0] * g0 + bframe[b, 0, 1] * g1 + bframe[b, 0, 2] * g2
                pn = (bc0[b, 0] - bcg[b, 0] * (acc - ww * bP[b, 0])) / (1.0 + bcg[b, 0] * ww)
                pn = relax * pn + (1.0 - relax) * bP[b, 0]
                dp0 = pn - bP[b, 0]
                bP[b, 0] = pn
                acc = bframe[b, 1, 0] * g0 + bframe[b, 1, 1] * g1 + bframe[b, 1, 2] * g2
                pn = (bc0[b, 1] - bcg[b, 1] * (acc - ww * bP[b, 1])) / (1.0 + bcg[b, 1] * ww)
                pn = relax * pn + (1.0 - relax) * bP[b, 1]
                dp1 = pn - bP[b, 1]
                bP[b, 1] = pn
                acc = bframe[b, 2, 0] * g0 + bframe[b, 2, 1] * g1 + bframe[b, 2, 2] * g2
                pn = (bc0[b, 2] - bcg[b, 2] * (acc - ww * bP[b, 2])) / (1.0 + bcg[b, 2] * ww)
                pn = relax * pn + (1.0 - relax) * bP[b, 2]
                dp2 = pn - bP[b, 2]
                bP[b, 2] = pn
            _push_bond(
                b,
                dp0,
                dp1,
                dp2,
                bi,
                bj,
                bframe,
                v,
                vp,
                inv_mass,
                inv_mass_plate,
                barm_i,
                barm_j,
                w,
                wp,
                inv_inertia,
                inv_inertia_plate,
                rot,
            )
            d2 = dp0 * dp0 + dp1 * dp1 + dp2 * dp2
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
            u0, u1, u2 = contact_velocity(a, ci, cj, cframe, radius, v, w, vp)
            bn = u0 - cwn[a] * cP[a, 0]
            bt = u1 - cwt[a] * cP[a, 1]
            bs = u2 - cwt[a] * cP[a, 2]
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
                _push_contact(a, d0, d1, d2_, ci, cj, cframe, radius, v, w, vp, inv_mass, inv_inertia, inv_mass_plate)
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
        if (norm == 0 and quad <= tol) or (norm == 1 and maxm <= tol) or (norm == 2 and quad <= tol and maxm <= tol):
            converged = True
            break
    return it, quad, maxm, converged
