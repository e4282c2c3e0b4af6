"""Local laws: Signorini-Coulomb contact (Eqs. 6-7) and the generalized Burger's bond
(Eqs. 12-13, 15-26), written for the Moreau-Jean theta-method on impulses P = h r.

Contact (Eqs. 6-7), exact on the 3D cone
----------------------------------------
The unknown is the impulse P = (P_n, P_t, P_s) of the step. With the other interactions
frozen the local velocity is U = b + W_aa P with W_aa = diag(w_n, w_t, w_t) exactly for
spheres and planes (delassus.py). The gap enters as in LMGC90's IQS law: Signorini is
imposed on U_n + max(g, 0)/h, so an open contact may close within the step but never
penetrates, and an existing overlap is not pushed out (no energy injected). The standard
NSCD local solution, exact as W_aa is diagonal and isotropic in the tangent plane:

1. b_n + max(g,0)/h >= 0          -> P = 0 (no contact / separation);
2. P_n = -(b_n + max(g,0)/h)/w_n, P_T = -b_T/w_t (stick prediction);
3. if |P_T| > mu P_n              -> P_T <- mu P_n P_T/|P_T| (slide: the projection of the
   prediction on the cone along the W_aa metric, which with isotropic w_t is radial).

Bond (generalized Burger's: Maxwell Km, Cm in series with NK Kelvin-Voigt Kk, Ck, all in
parallel with a spring Kinf), per local component (n, t, s)
-----------------------------------------------------------------------------------------
Series decomposition delta = delta_m + delta_c + sum_k delta_k (Eq. 15) with R_ch = -Km
delta_m = -Cm d(delta_c)/dt = -Kk delta_k - Ck d(delta_k)/dt (Eqs. 21-24), integrated by the
theta-method (theta = 1 gives Eqs. 16-19 and the Kelvin-Voigt update of Eq. 26,
delta_k+ = (Ck delta_k- - h R+)/(Ck + h Kk) in our sign convention)::

    delta_k+ = a_k - b_k R_ch+,  a_k = [Ck dk- - h(1-th)(R_ch- + Kk dk-)]/(Ck + h th Kk),
                                 b_k = h th/(Ck + h th Kk)
    delta+   = A - C R_ch+,      A = dc- - h(1-th) R_ch-/Cm + sum a_k,
                                 C = 1/Km + h th/Cm + sum b_k
    R+ = R_ch+ - Kinf delta+ = A/C - K_eff delta+,   K_eff = 1/C + Kinf,
    delta+ = delta- + h((1-th) U- + th U+).

The impulse of the step is P = h (th R+ + (1-th) R-), hence the modified local law (Eq. 25)
is affine: P = c0 - c_g U+ with c0 = h (th R_pred + (1-th) R-), R_pred = A/C - K_eff
(delta- + h(1-th) U-), c_g = h² th² K_eff, and with U = b + w P the local solution is
P = (c0 - c_g b)/(1 + c_g w) per component (barycentre kinematics; with the contact
kinematics W_bb is a full 3x3 block and P = (I + diag(c_g) W_bb)^-1 (c0 - c_g b),
gauss_seidel.py). U: :func:`bond_velocity` (state.Bonds kinematics; delta- is
``Bonds.displacement`` with 'contact', from the positions with 'barycentre'). Breakage
(Eqs. 12-13): |R_n+| or |(R_t+, R_s+)| > R_crit breaks the bond at the end of the step.
"""

from __future__ import annotations

import math

from ._jit import helper, kernel


@helper
def contact_local_solve(bn, bt, bs, gap, h, wn, wt, mu):
    """Exact Signorini-Coulomb impulse (Pn, Pt, Ps) (N s) for local free velocity (bn, bt, bs)
    (m/s, excluding this contact's own impulse), gap (m), step h (s), blocks wn, wt (1/kg)."""
    bn_eff = bn + max(gap, 0.0) / h
    if bn_eff >= 0.0 or wn <= 0.0:
        return 0.0, 0.0, 0.0
    pn = -bn_eff / wn
    pt = -bt / wt
    ps = -bs / wt
    norm_t = math.sqrt(pt * pt + ps * ps)
    limit = mu * pn
    if norm_t > limit:
        scale = limit / norm_t
        pt *= scale
        ps *= scale
    return pn, pt, ps


@helper
def bond_velocity(b, bi, bj, arm_i, arm_j, v, w, vp, wp, rot):
    """Global relative velocity (3 floats, m/s) of bond b: v_i - v_j ('barycentre', rot
    False), or (v_i + w_i x a_i) - (v_j + w_j x a_j) at the contact point (rot True; a plate
    antagonist k contributes vp_k + wp_k x a_j)."""
    i = bi[b]
    j = bj[b]
    if j >= 0:
        u0 = v[i, 0] - v[j, 0]
        u1 = v[i, 1] - v[j, 1]
        u2 = v[i, 2] - v[j, 2]
    else:
        k = -1 - j
        u0 = v[i, 0] - vp[k, 0]
        u1 = v[i, 1] - vp[k, 1]
        u2 = v[i, 2] - vp[k, 2]
    if rot:
        a0 = arm_i[b, 0]
        a1 = arm_i[b, 1]
        a2 = arm_i[b, 2]
        u0 += w[i, 1] * a2 - w[i, 2] * a1
        u1 += w[i, 2] * a0 - w[i, 0] * a2
        u2 += w[i, 0] * a1 - w[i, 1] * a0
        a0 = arm_j[b, 0]
        a1 = arm_j[b, 1]
        a2 = arm_j[b, 2]
        if j >= 0:
            u0 -= w[j, 1] * a2 - w[j, 2] * a1
            u1 -= w[j, 2] * a0 - w[j, 0] * a2
            u2 -= w[j, 0] * a1 - w[j, 1] * a0
        else:
            k = -1 - j
            u0 -= wp[k, 1] * a2 - wp[k, 2] * a1
            u1 -= wp[k, 2] * a0 - wp[k, 0] * a2
            u2 -= wp[k, 0] * a1 - wp[k, 1] * a0
    return u0, u1, u2


@kernel
def bond_coefficients(Km, Cm, Kk, Ck, h, theta, coef, i_den):
    """Reciprocals of the step (constant for given bond parameters, h and theta), so that
    bond_predict and bond_update need no division: coef (B,3,2) = [1/Km, 1/Cm, 1/C] with
    C = 1/Km + h theta/Cm + sum_k h theta/(Ck + h theta Kk) (module docstring), and
    i_den (B,NK,2) = 1/(Ck + h theta Kk); index 2 = 0 normal, 1 tangential."""
    nk = Kk.shape[1]
    for b in range(Km.shape[0]):
        for p in range(2):
            coef[b, 0, p] = 1.0 / Km[b, p]
            coef[b, 1, p] = 1.0 / Cm[b, p]
            cc = coef[b, 0, p] + h * theta * coef[b, 1, p]
            for k in range(nk):
                i_den[b, k, p] = 1.0 / (Ck[b, k, p] + h * theta * Kk[b, k, p])
                cc += h * theta * i_den[b, k, p]
            coef[b, 2, p] = 1.0 / cc


@kernel
def bond_predict(bonds, law, x, xp, start, opts, step):
    """Per-bond affine law coefficients for the step (Eq. 25; see module docstring).

    bonds : bundles.BondGeometry; law : bundles.BondState (coef (B,3,2), i_den (B,NK,2)
    from :func:`bond_coefficients`, bond parameters (B,2)/(B,NK,2), internal variables and
    the accumulated displacement disp (B,3) m read); x (N,3) m sphere positions and xp (P,3)
    m plate points at the start of the step; start : bundles.Velocities at the start of the
    step (plates: their velocities of the step); opts : bundles.StepOptions (h, theta, rot;
    rot True = 'contact' kinematics).
    Outputs in step (bundles.BondStep, filled): c0 (B,3) N s, cg (B,3) N s/m, delta_m (B,3)
    m = delta-, u_m (B,3) m/s = U-. Broken bonds get c0 = cg = 0.
    """
    bi, bj, frame, arm_i, arm_j, broken = (bonds.i, bonds.j, bonds.frame, bonds.arm_i, bonds.arm_j, bonds.broken)
    coef, i_den, Kk, Ck, Kinf = law.coef, law.i_den, law.Kk, law.Ck, law.Kinf
    force, delta_c, delta_k, rest, disp = law.force, law.delta_c, law.delta_k, law.rest, law.disp
    v, w, vp, wp = start.v, start.w, start.vp, start.wp
    h, theta, rot = opts.h, opts.theta, opts.rot
    c0, cg, delta_m, u_m = step.c0, step.cg, step.delta_m, step.u_m
    nk = Kk.shape[1]
    for b in range(len(bi)):
        if broken[b]:
            for c in range(3):
                c0[b, c] = 0.0
                cg[b, c] = 0.0
                delta_m[b, c] = 0.0
                u_m[b, c] = 0.0
            continue
        i = bi[b]
        j = bj[b]
        if j >= 0:
            r0 = x[i, 0] - x[j, 0] - rest[b, 0]
            r1 = x[i, 1] - x[j, 1] - rest[b, 1]
            r2 = x[i, 2] - x[j, 2] - rest[b, 2]
        else:
            k = -1 - j
            r0 = x[i, 0] - xp[k, 0] - rest[b, 0]
            r1 = x[i, 1] - xp[k, 1] - rest[b, 1]
            r2 = x[i, 2] - xp[k, 2] - rest[b, 2]
        u0, u1, u2 = bond_velocity(b, bi, bj, arm_i, arm_j, v, w, vp, wp, rot)
        for c in range(3):
            p = 0 if c == 0 else 1
            if rot:
                dl = disp[b, c]
            else:
                dl = frame[b, c, 0] * r0 + frame[b, c, 1] * r1 + frame[b, c, 2] * r2
            ul = frame[b, c, 0] * u0 + frame[b, c, 1] * u1 + frame[b, c, 2] * u2
            delta_m[b, c] = dl
            u_m[b, c] = ul
            r_ch = force[b, c] + Kinf[b, p] * dl
            A = delta_c[b, c] - h * (1.0 - theta) * r_ch * coef[b, 1, p]
            for k in range(nk):
                A += (
                    Ck[b, k, p] * delta_k[b, k, c] - h * (1.0 - theta) * (r_ch + Kk[b, k, p] * delta_k[b, k, c])
                ) * i_den[b, k, p]
            k_eff = coef[b, 2, p] + Kinf[b, p]
            r_pred = A * coef[b, 2, p] - k_eff * (dl + h * (1.0 - theta) * ul)
            c0[b, c] = h * (theta * r_pred + (1.0 - theta) * force[b, c])
            cg[b, c] = h * h * theta * theta * k_eff


@kernel
def bond_update(bonds, law, step, end, opts):
    """End-of-step update of the bond state (Eqs. 12-13, 15-26).

    bonds : bundles.BondGeometry (broken (B,) updated); law : bundles.BondState, whose force
    (B,3) N, delta_c, delta_k are updated in place and disp (B,3) receives delta+ (the
    accumulated displacement of the 'contact' kinematics); step : bundles.BondStep from
    :func:`bond_predict` (delta_m, u_m read; impulse (B,3) N s zeroed for newly broken
    bonds); end : bundles.Velocities at the end of the step; opts : bundles.StepOptions.

    Marks broken bonds (|R_n| or |R_T| > r_crit) and zeroes their force and impulse. Returns
    (number newly broken, energy dissipated by the bonds in the step, J): -P . (delta+ -
    delta-)/h - (E+ - E-), with E the energy stored in the springs.
    """
    bi, bj, frame, arm_i, arm_j, broken = (bonds.i, bonds.j, bonds.frame, bonds.arm_i, bonds.arm_j, bonds.broken)
    coef, i_den, Kk, Ck, Kinf, r_crit = law.coef, law.i_den, law.Kk, law.Ck, law.Kinf, law.r_crit
    force, delta_c, delta_k, disp = law.force, law.delta_c, law.delta_k, law.disp
    delta_m, u_m, impulse = step.delta_m, step.u_m, step.impulse
    v, w, vp, wp = end.v, end.w, end.vp, end.wp
    h, theta, rot = opts.h, opts.theta, opts.rot
    nk = Kk.shape[1]
    n_new = 0
    dissipated = 0.0
    for b in range(len(bi)):
        if broken[b]:
            continue
        u0, u1, u2 = bond_velocity(b, bi, bj, arm_i, arm_j, v, w, vp, wp, rot)
        for c in range(3):
            p = 0 if c == 0 else 1
            up = frame[b, c, 0] * u0 + frame[b, c, 1] * u1 + frame[b, c, 2] * u2
            dl = delta_m[b, c]
            dp = dl + h * ((1.0 - theta) * u_m[b, c] + theta * up)
            r_ch_m = force[b, c] + Kinf[b, p] * dl
            e_old = 0.5 * r_ch_m * r_ch_m * coef[b, 0, p] + 0.5 * Kinf[b, p] * dl * dl
            A = delta_c[b, c] - h * (1.0 - theta) * r_ch_m * coef[b, 1, p]
            for k in range(nk):
                e_old += 0.5 * Kk[b, k, p] * delta_k[b, k, c] ** 2
                A += (
                    Ck[b, k, p] * delta_k[b, k, c] - h * (1.0 - theta) * (r_ch_m + Kk[b, k, p] * delta_k[b, k, c])
                ) * i_den[b, k, p]
            r_ch_p = (A - dp) * coef[b, 2, p]
            e_new = 0.5 * r_ch_p * r_ch_p * coef[b, 0, p] + 0.5 * Kinf[b, p] * dp * dp
            for k in range(nk):  # a_k recomputed (same operations): no work array
                ak = (
                    Ck[b, k, p] * delta_k[b, k, c] - h * (1.0 - theta) * (r_ch_m + Kk[b, k, p] * delta_k[b, k, c])
                ) * i_den[b, k, p]
                delta_k[b, k, c] = ak - h * theta * i_den[b, k, p] * r_ch_p
                e_new += 0.5 * Kk[b, k, p] * delta_k[b, k, c] ** 2
            delta_c[b, c] -= h * (theta * r_ch_p + (1.0 - theta) * r_ch_m) * coef[b, 1, p]
            force[b, c] = r_ch_p - Kinf[b, p] * dp
            disp[b, c] = dp
            dissipated += -impulse[b, c] * (dp - dl) / h - (e_new - e_old)
        rt = math.sqrt(force[b, 1] ** 2 + force[b, 2] ** 2)
        if abs(force[b, 0]) > r_crit[b] or rt > r_crit[b]:
            broken[b] = True
            n_new += 1
            for c in range(3):
                force[b, c] = 0.0
                impulse[b, c] = 0.0
    return n_new, dissipated
