"""Conjugate gradient preconditioned by symmetric successive over-relaxation on the body
blocks (``linear_solver='cg_ssor'``), in Eisenstat's form.

A body is the group of unknown blocks of one sphere or plate (translation and rotation
together, up to 6x6); M = (D/w + L) (D/w)^-1 (D/w + U) with w = NSCDParameters.
linear_ssor_omega. The preconditioned product costs one backward and one forward
triangular solve over the bonds (:func:`_upper_solve`, :func:`_lower_solve`) and no product
with A (:func:`_pcg_ssor`). The initial guess is the Galerkin (A-norm optimal) combination
of the velocity fields of the last steps (:func:`_galerkin_gram`,
:func:`_galerkin_combine`; LinearBondSolver._galerkin_start). Sequential only.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .._jit import helper, kernel
from .cg import _matvec


class SSORStructure(NamedTuple):
    """Body blocks and bond lists of the SSOR preconditioner (:func:`ssor_structure`):
    bfirst, bcount (nbody,) first dof and dof count of each body, Dinv (nbody,6,6) the
    inverse relaxed diagonal blocks; lower (l*) and upper (u*) coupling lists, compact
    (lcptr, lcidx, lcdat; ucptr, ucidx, ucdat) and general (lptr, lidx, ldat; uptr, uidx,
    udat)."""

    bfirst: np.ndarray
    bcount: np.ndarray
    Dinv: np.ndarray
    lcptr: np.ndarray
    lcidx: np.ndarray
    lcdat: np.ndarray
    lptr: np.ndarray
    lidx: np.ndarray
    ldat: np.ndarray
    ucptr: np.ndarray
    ucidx: np.ndarray
    ucdat: np.ndarray
    uptr: np.ndarray
    uidx: np.ndarray
    udat: np.ndarray


#: Field names of :class:`SSORStructure` (keys of :func:`ssor_structure`'s dict).
_SSOR_KEYS = SSORStructure._fields

#: :func:`_pcg_ssor` stops above its tolerance when this many true-residual checks in a row have not halved the
#: smallest true residual checked, or when this many times the iterations of its first check have passed since its
#: last: the recurrence has reached the accuracy that rounding lets it attain
STALL_CHECKS = 10


def ssor_structure(st, sr, pt, pr, m3, blk, L, G, bdat_all, omega=1.0):
    """Body blocks and bond lists of the SSOR-preconditioned conjugate gradient.

    A body is the group of unknown blocks of one sphere or plate (translation and/or
    rotation: 1 or 2 consecutive blocks of the numbering of :func:`dof_numbering`). The
    matrix A = M + sum_b L_b^T G_b L_b splits into body-diagonal blocks D (up to 6x6, the
    translation-rotation coupling of a body included) and off-diagonal blocks, one per bond
    between two bodies with unknowns, ordered by body index: L (lower) and U = L^T.

    Parameters
    ----------
    st, sr, pt, pr : block indices of :func:`dof_numbering`; m3 (nblk, 3) diagonal of M;
    blk (B,4) int64 blocks (ti, ri, tj, rj) of each intact bond (-1 = known); L : the four
    (B,3,3) kinematic operators of the bond (U_b = sum_c L[c] x_blk[c]); G (B,3,3);
    bdat_all (B,11): n, g_t, g_nt, a_i, a_j of each bond.

    Returns
    -------
    dict: ``bfirst``, ``bcount`` (nbody,) first block and block count of each body;
    ``D``, ``Dinv`` (nbody, 6, 6) body blocks (identity on absent rows); ``lptr``,
    ``lbond``, ``lside`` (bonds whose other body has a lower index, by body; side 0 = the
    body is the bond's candidate i, 1 = its antagonist j), ``uptr``, ``ubond``, ``uside``
    (other body of higher index); ``bdat`` (B,11), ``blk`` (B,4) int32.
    """
    nblk = len(m3)
    first = []
    for s_t, s_r in list(zip(st, sr)) + list(zip(pt, pr)):
        ids = [int(b) for b in (s_t, s_r) if b >= 0]
        if ids:
            first.append((min(ids), len(ids)))
    first.sort()
    bfirst = np.array([f for f, _ in first], np.int64)
    bcount = np.array([c for _, c in first], np.int64)
    nbody = len(bfirst)
    body_of = np.full(max(nblk, 1), -1, np.int64)
    for k in range(nbody):
        body_of[bfirst[k] : bfirst[k] + bcount[k]] = k
    D = np.zeros((nbody, 6, 6))
    idx = np.arange(3)
    for k in range(nbody):
        for q in range(bcount[k]):
            D[k, 3 * q + idx, 3 * q + idx] = m3[bfirst[k] + q]
        for q in range(bcount[k], 2):
            D[k, 3 * q + idx, 3 * q + idx] = 1.0  # absent rows: identity (zero right-hand side)
    sides = ((0, 1), (2, 3))
    for side in sides:
        for c in side:
            for c2 in side:
                ok = (blk[:, c] >= 0) & (blk[:, c2] >= 0)
                if not ok.any():
                    continue
                body = body_of[blk[ok, c]]
                o1 = 3 * (blk[ok, c] - bfirst[body])
                o2 = 3 * (blk[ok, c2] - bfirst[body])
                block = np.einsum("bki,bkl,blj->bij", L[c][ok], G[ok], L[c2][ok])
                for a in range(3):
                    for e in range(3):
                        np.add.at(D, (body, o1 + a, o2 + e), block[:, a, e])
    Dinv = omega * np.linalg.inv(D) if nbody else D.copy()
    bi_body = np.where(
        blk[:, 0] >= 0,
        body_of[np.maximum(blk[:, 0], 0)],
        np.where(blk[:, 1] >= 0, body_of[np.maximum(blk[:, 1], 0)], -1),
    )
    bj_body = np.where(
        blk[:, 2] >= 0,
        body_of[np.maximum(blk[:, 2], 0)],
        np.where(blk[:, 3] >= 0, body_of[np.maximum(blk[:, 3], 0)], -1),
    )
    both = np.flatnonzero((bi_body >= 0) & (bj_body >= 0))
    hi = np.maximum(bi_body[both], bj_body[both])
    lo = np.minimum(bi_body[both], bj_body[both])
    side_hi = (bj_body[both] == hi).astype(np.int64)  # side of the higher body in the bond
    o = np.argsort(hi, kind="stable")
    lptr = np.searchsorted(hi[o], np.arange(nbody + 1)).astype(np.int64)
    rev = nbody - 1 - lo  # the upper solve visits the bodies from the last: entries in that order
    o2 = np.argsort(rev, kind="stable")
    uptr = np.searchsorted(rev[o2], np.arange(nbody + 1)).astype(np.int64)
    lidx, ldat = _pack(both[o], side_hi[o], blk, bdat_all, bfirst, body_of)
    uidx, udat = _pack(both[o2], 1 - side_hi[o2], blk, bdat_all, bfirst, body_of)
    rot = bool((blk[:, [1, 3]] >= 0).any())
    out = {"bfirst": bfirst, "bcount": bcount, "D": np.ascontiguousarray(D), "Dinv": np.ascontiguousarray(Dinv)}
    for pre, ptr, idx, dat in (("l", lptr, lidx, ldat), ("u", uptr, uidx, udat)):
        (
            out[pre + "cptr"],
            out[pre + "cidx"],
            out[pre + "cdat"],
            out[pre + "ptr"],
            out[pre + "idx"],
            out[pre + "dat"],
        ) = _split_compact(ptr, idx, dat, rot)
    return out


def _pack(bond, own, blk, bdat, bfirst, body_of):
    """Entries of a triangular solve, in its visiting order: idx (E,4) int32 = other side's
    translation and rotation blocks (-1 = known), own translation and rotation offsets in
    the own body's 6-vector (-1 = absent); dat (E,11) = n, g_t, g_nt, the other side's arm,
    the own side's arm."""
    other = 1 - own
    e = np.arange(len(bond))
    t_o = blk[bond, 2 * other]
    r_o = blk[bond, 2 * other + 1]
    t_k = blk[bond, 2 * own]
    r_k = blk[bond, 2 * own + 1]
    body = body_of[np.where(t_k >= 0, t_k, r_k)]
    first = bfirst[body] if len(body) else np.zeros(0, np.int64)
    idx = np.stack(
        [t_o, r_o, np.where(t_k >= 0, 3 * (t_k - first), -1), np.where(r_k >= 0, 3 * (r_k - first), -1)], 1
    ).astype(np.int32)
    arm_o = np.where((other == 0)[:, None], bdat[bond, 5:8], bdat[bond, 8:11])
    arm_k = np.where((own == 0)[:, None], bdat[bond, 5:8], bdat[bond, 8:11])
    dat = np.concatenate([bdat[bond, :5], arm_o, arm_k], 1) if len(e) else np.zeros((0, 11))
    return np.ascontiguousarray(idx.reshape(-1, 4)), np.ascontiguousarray(dat)


def _split_compact(ptr, idx, dat, rot):
    """Split the entries of a triangular solve (:func:`_pack`, grouped by visited body via
    ``ptr``) into compact and general ones. Compact: the own body has its translation block
    first (offset 0) and, with ``rot``, its rotation block next (offset 3); the other side is
    a body with translation block t and, with ``rot``, rotation block t + 1; both lever arms
    lie along the normal (sphere-sphere bonds of state.Bonds.create), stored as two numbers.
    Returns cptr (nbody+1) int64, cidx (Ec,) int32 first unknown (3 t) of the other side,
    cdat (Ec, 7): n, g_t, g_nt, al_other, al_own (without ``rot``: (Ec, 5)), then ptr, idx,
    dat of the general entries (same layout as :func:`_pack`)."""
    nrm = dat[:, :3]
    al_o = np.einsum("bd,bd->b", dat[:, 5:8], nrm)
    al_k = np.einsum("bd,bd->b", dat[:, 8:11], nrm)
    if rot:
        ok = (idx[:, 0] >= 0) & (idx[:, 1] == idx[:, 0] + 1) & (idx[:, 2] == 0) & (idx[:, 3] == 3)
        ok &= np.abs(dat[:, 5:8] - al_o[:, None] * nrm).max(1, initial=0.0) <= 1e-12 * np.abs(dat[:, 5:8]).max(
            1, initial=0.0
        )
        ok &= np.abs(dat[:, 8:11] - al_k[:, None] * nrm).max(1, initial=0.0) <= 1e-12 * np.abs(dat[:, 8:11]).max(
            1, initial=0.0
        )
        cdat = np.concatenate([dat[:, :5], al_o[:, None], al_k[:, None]], 1)[ok]
    else:
        ok = (idx[:, 0] >= 0) & (idx[:, 1] < 0) & (idx[:, 2] == 0) & (idx[:, 3] < 0)
        cdat = dat[ok, :5]
    owner = np.repeat(np.arange(len(ptr) - 1), np.diff(ptr))
    cptr = np.searchsorted(owner[ok], np.arange(len(ptr))).astype(np.int64)
    gptr = np.searchsorted(owner[~ok], np.arange(len(ptr))).astype(np.int64)
    return (
        cptr,
        np.ascontiguousarray((3 * idx[ok, 0]).astype(np.int32)),
        np.ascontiguousarray(cdat.reshape(-1, 7 if rot else 5)),
        gptr,
        np.ascontiguousarray(idx[~ok]),
        np.ascontiguousarray(dat[~ok]),
    )


@helper
def _couple(e, idx, dat, y):
    """Force f = G s_other(y) and torque a_own x f of entry e of a triangular solve
    (:func:`_pack`): L_own^T f is minus the off-diagonal block of the bond times y
    (A_ko = sigma_k sigma_o L_k^T G L_o, sigma_i = 1, sigma_j = -1); s(y) = y_t + y_r x a is
    the velocity of the other side at the contact point."""
    t = idx[e, 0]
    r = idx[e, 1]
    u0 = 0.0
    u1 = 0.0
    u2 = 0.0
    if t >= 0:
        u0 = y[3 * t]
        u1 = y[3 * t + 1]
        u2 = y[3 * t + 2]
    if r >= 0:
        w0 = y[3 * r]
        w1 = y[3 * r + 1]
        w2 = y[3 * r + 2]
        u0 += w1 * dat[e, 7] - w2 * dat[e, 6]
        u1 += w2 * dat[e, 5] - w0 * dat[e, 7]
        u2 += w0 * dat[e, 6] - w1 * dat[e, 5]
    n0 = dat[e, 0]
    n1 = dat[e, 1]
    n2 = dat[e, 2]
    gt = dat[e, 3]
    s = dat[e, 4] * (n0 * u0 + n1 * u1 + n2 * u2)
    f0 = gt * u0 + s * n0
    f1 = gt * u1 + s * n1
    f2 = gt * u2 + s * n2
    a0 = dat[e, 8]
    a1 = dat[e, 9]
    a2 = dat[e, 10]
    return f0, f1, f2, a1 * f2 - a2 * f1, a2 * f0 - a0 * f2, a0 * f1 - a1 * f0


@helper
def _solve_body(k, m, bfirst, bcount, Dinv, cptr, cidx, cdat, ptr, idx, dat, rhs, y, side_out, lower, c_side):
    """One body of a triangular solve: s = rhs_k + sum of the entries' L_k^T f (scalars:
    no memory round trip), y_k = Dinv_k s; side_out_k = s (lower: D y_k) or
    rhs_k - c_side s (upper). m: position of the body in the visiting order (index of the
    entry pointers). Compact entries (:func:`_split_compact`) first, then the general ones
    (:func:`_couple`)."""
    f = 3 * bfirst[k]
    six = bcount[k] == 2
    s0 = rhs[f]
    s1 = rhs[f + 1]
    s2 = rhs[f + 2]
    s3 = 0.0
    s4 = 0.0
    s5 = 0.0
    if six:
        s3 = rhs[f + 3]
        s4 = rhs[f + 4]
        s5 = rhs[f + 5]
    six_c = cdat.shape[1] == 7  # compact entries of 6-dof bodies (else translations only)
    for e in range(cptr[m], cptr[m + 1]):
        o = cidx[e]
        n0 = cdat[e, 0]
        n1 = cdat[e, 1]
        n2 = cdat[e, 2]
        gt = cdat[e, 3]
        u0 = y[o]
        u1 = y[o + 1]
        u2 = y[o + 2]
        if six_c:  # arms along n: u = y_t + al_o (y_r x n)
            ao = cdat[e, 5]
            w0 = ao * y[o + 3]
            w1 = ao * y[o + 4]
            w2 = ao * y[o + 5]
            u0 += w1 * n2 - w2 * n1
            u1 += w2 * n0 - w0 * n2
            u2 += w0 * n1 - w1 * n0
        sn = cdat[e, 4] * (n0 * u0 + n1 * u1 + n2 * u2)
        s0 += gt * u0 + sn * n0
        s1 += gt * u1 + sn * n1
        s2 += gt * u2 + sn * n2
        if six_c:
            ak = cdat[e, 6] * gt  # a_own x f = al_own g_t (n x u)
            s3 += ak * (n1 * u2 - n2 * u1)
            s4 += ak * (n2 * u0 - n0 * u2)
            s5 += ak * (n0 * u1 - n1 * u0)
    for e in range(ptr[m], ptr[m + 1]):
        f0, f1, f2, c0, c1, c2 = _couple(e, idx, dat, y)
        if idx[e, 2] == 0:
            s0 += f0
            s1 += f1
            s2 += f2
        qr = idx[e, 3]
        if qr == 3:
            s3 += c0
            s4 += c1
            s5 += c2
        elif qr == 0:
            s0 += c0
            s1 += c1
            s2 += c2
    if lower:
        side_out[f] = s0
        side_out[f + 1] = s1
        side_out[f + 2] = s2
    else:
        side_out[f] = rhs[f] - c_side * s0
        side_out[f + 1] = rhs[f + 1] - c_side * s1
        side_out[f + 2] = rhs[f + 2] - c_side * s2
    if six:
        if lower:
            side_out[f + 3] = s3
            side_out[f + 4] = s4
            side_out[f + 5] = s5
        else:
            side_out[f + 3] = rhs[f + 3] - c_side * s3
            side_out[f + 4] = rhs[f + 4] - c_side * s4
            side_out[f + 5] = rhs[f + 5] - c_side * s5
        for a in range(6):
            y[f + a] = (
                Dinv[k, a, 0] * s0
                + Dinv[k, a, 1] * s1
                + Dinv[k, a, 2] * s2
                + Dinv[k, a, 3] * s3
                + Dinv[k, a, 4] * s4
                + Dinv[k, a, 5] * s5
            )
    else:
        for a in range(3):
            y[f + a] = Dinv[k, a, 0] * s0 + Dinv[k, a, 1] * s1 + Dinv[k, a, 2] * s2


@kernel
def _lower_solve(bfirst, bcount, Dinv, cptr, cidx, cdat, lptr, lidx, ldat, rhs, y, dy):
    """y = (D + L)^-1 rhs, body by body in increasing order; also dy = D y = rhs - L y (a
    by-product). D: the (relaxed) body blocks of :func:`ssor_structure`."""
    for k in range(len(bfirst)):
        _solve_body(k, k, bfirst, bcount, Dinv, cptr, cidx, cdat, lptr, lidx, ldat, rhs, y, dy, True, 1.0)


@kernel
def _upper_solve(bfirst, bcount, Dinv, cptr, cidx, cdat, uptr, uidx, udat, rhs, y, uy, c_side):
    """y = (D + U)^-1 rhs, body by body in decreasing order; also uy = rhs - c_side D y
    (c_side = 1: U y). The entries of the m-th body visited (k = nbody - 1 - m) are
    uptr[m]..uptr[m+1] (and cptr[m]..cptr[m+1])."""
    nbody = len(bfirst)
    for m in range(nbody):
        _solve_body(
            nbody - 1 - m, m, bfirst, bcount, Dinv, cptr, cidx, cdat, uptr, uidx, udat, rhs, y, uy, False, c_side
        )


@njit(cache=True)
def _pcg_ssor(op, ss, rhs, x, tol, max_iter, work, omega, ax, have_ax):
    """Conjugate gradient on A x = rhs preconditioned by symmetric successive
    over-relaxation on the body blocks, M = (D_w + L) D_w^-1 (D_w + U), D_w = D / omega
    (ss.Dinv holds D_w^-1; ss : :class:`SSORStructure`, op : cg.CGOperator), with Eisenstat's trick: A = (D_w + L) + (D_w + U) - K0,
    K0 = (2 - omega) D_w; CG on A^ = (D_w + L)^-1 A (D_w + U)^-1 (preconditioner D_w), whose
    product costs one backward and one forward triangular solve,
    A^ v = t + (D_w + L)^-1 (v - K0 t), t = (D_w + U)^-1 v (v - K0 t and D_w (D_w + L)^-1
    (.) are by-products of the solves). x holds the initial guess; the iteration tracks
    x = (D_w + U)^-1 x^ directly (x += alpha t).
    ax (n,): A x of the initial guess on input when ``have_ax`` (LinearBondSolver.solve
    knows it for the extrapolated guess), else computed; on return A x of the solution.
    Stopping: the preconditioned residual (r^T M^-1 r)^1/2 is to fall by the factor by
    which the true residual must fall, tol |rhs| / |rhs - A x0|; then the true residual
    |rhs - A x| is computed, and the run stops if it is <= tol |rhs|, else the factor is
    tightened by the missing ratio. A check never changes the iterates, only where the run
    stops. Below the accuracy that rounding lets the recurrence attain, the run stops above
    tol: when r^T M^-1 r is no longer positive (breakdown); when :data:`STALL_CHECKS` checks in
    a row have not halved the smallest true residual checked; when a check forced after
    :data:`STALL_CHECKS` times the iterations of the first check without another has not
    halved it. Without these, a tolerance of 1e-13 on a 246-unknown network (its rounding floor
    1.07e-13) ran to ``max_iter`` = 10,000 iterations with a product with A in each, the solution
    no longer changing after 30; one of 1e-20 on a 192-unknown network iterated the recurrence
    alone to ``max_iter``. work (9, n).
    Returns (iterations, |rhs - A x| / |rhs|, number of true-residual products); the residual
    exceeds tol after a stall or at ``max_iter``."""
    mass_dof, bdat_c, blk_c, bdat_g, blk_g = op.mass_dof, op.bdat_c, op.blk_c, op.bdat_g, op.blk_g
    ss_bfirst, ss_bcount, ss_Dinv = ss.bfirst, ss.bcount, ss.Dinv
    ss_lcptr, ss_lcidx, ss_lcdat, ss_lptr, ss_lidx, ss_ldat = (ss.lcptr, ss.lcidx, ss.lcdat, ss.lptr, ss.lidx, ss.ldat)
    ss_ucptr, ss_ucidx, ss_ucdat, ss_uptr, ss_uidx, ss_udat = (ss.ucptr, ss.ucidx, ss.ucdat, ss.uptr, ss.uidx, ss.udat)
    n = len(rhs)
    rh = work[0]
    z = work[1]
    p = work[2]
    q = work[3]
    t = work[4]
    tmp = work[5]
    dq = work[6]
    scratch = work[7]
    dummy = work[8]
    c_side = 2.0 - omega
    inv_c = 1.0 / c_side
    checks = 0
    if not have_ax:
        for k in range(n):
            scratch[k] = 0.0
        _matvec(mass_dof, bdat_c, blk_c, bdat_g, blk_g, x, 0.0, scratch, ax, 0.0, dummy)
    norm_b = 0.0
    rr = 0.0
    for k in range(n):
        tmp[k] = rhs[k] - ax[k]
        norm_b += rhs[k] * rhs[k]
        rr += tmp[k] * tmp[k]
        p[k] = 0.0
    norm_b = np.sqrt(norm_b)
    if norm_b == 0.0:
        for k in range(n):
            x[k] = 0.0
            ax[k] = 0.0
        return 0, 0.0, checks
    res = np.sqrt(rr) / norm_b
    if res <= tol:
        if have_ax:  # ax: the product itself (not a combination), as after iterations
            for k in range(n):
                scratch[k] = 0.0
            _matvec(mass_dof, bdat_c, blk_c, bdat_g, blk_g, x, 0.0, scratch, ax, 0.0, dummy)
        return 0, res, checks
    # r^ = (D_w + L)^-1 (b - A x), z = D_w r^
    _lower_solve(ss_bfirst, ss_bcount, ss_Dinv, ss_lcptr, ss_lcidx, ss_lcdat, ss_lptr, ss_lidx, ss_ldat, tmp, rh, z)
    rz = 0.0
    for k in range(n):
        rz += rh[k] * z[k]
    # reference of the stopping test: (r0^T M^-1 r0)^1/2 |rhs| / |r0|
    ref = np.sqrt(max(rz, 0.0)) / res
    tol_eff = tol
    beta = 0.0
    it = 0
    best = res  # smallest true residual checked (the initial one first)
    stalled = 0  # checks in a row that have not halved it
    first = 0  # iterations to the first check
    last = 0  # iteration of the last check
    while it < max_iter:
        it += 1
        # p <- z + beta p; t = (D_w + U)^-1 p, tmp = p - K0 t; q = (D_w + L)^-1 tmp,
        # dq = D_w q; A^ p = q + t
        for k in range(n):
            p[k] = z[k] + beta * p[k]
        _upper_solve(
            ss_bfirst, ss_bcount, ss_Dinv, ss_ucptr, ss_ucidx, ss_ucdat, ss_uptr, ss_uidx, ss_udat, p, t, tmp, c_side
        )
        _lower_solve(ss_bfirst, ss_bcount, ss_Dinv, ss_lcptr, ss_lcidx, ss_lcdat, ss_lptr, ss_lidx, ss_ldat, tmp, q, dq)
        pq = 0.0
        for k in range(n):
            q[k] += t[k]
            pq += p[k] * q[k]
        alpha = rz / pq
        rz_new = 0.0
        for k in range(n):
            x[k] += alpha * t[k]
            rh[k] -= alpha * q[k]
            # D_w A^ p = D_w t + D_w (D_w + L)^-1 tmp, D_w t = (p - tmp) / (2 - omega)
            z[k] -= alpha * ((p[k] - tmp[k]) * inv_c + dq[k])
            rz_new += rh[k] * z[k]
        forced = checks > 0 and it - last >= STALL_CHECKS * first
        if np.sqrt(max(rz_new, 0.0)) <= tol_eff * ref or it == max_iter or forced:
            for k in range(n):
                scratch[k] = 0.0
            _matvec(mass_dof, bdat_c, blk_c, bdat_g, blk_g, x, 0.0, scratch, ax, 0.0, dummy)
            checks += 1
            rr = 0.0
            for k in range(n):
                d = rhs[k] - ax[k]
                rr += d * d
            res = np.sqrt(rr) / norm_b
            if res <= tol or rz_new <= 0.0:
                return it, res, checks
            if res <= 0.5 * best:
                stalled = 0
            else:
                stalled += 1
                if stalled >= STALL_CHECKS or forced:
                    return it, res, checks
            best = min(best, res)
            if checks == 1:
                first = it
            last = it
            tol_eff *= max(0.5 * tol / res, 1e-3)
        beta = rz_new / rz
        rz = rz_new
    return it, res, checks


@kernel
def _galerkin_gram(x, ax, rhs, diff, G, b, u, au):
    """Gram matrix G = U^T A U and b = U^T rhs of :meth:`LinearBondSolver._galerkin_start`
    (outputs, (m, m) and (m,), zeroed here) in one pass: U = diff @ x (rows: the basis of
    successive differences of the past solutions x, shape (m, n)); A U from their products
    ax; the mixed terms are the mean of their two symmetric forms. u, au: (m,) work."""
    m = x.shape[0]
    for a in range(m):
        b[a] = 0.0
        for c in range(m):
            G[a, c] = 0.0
    for k in range(x.shape[1]):
        for a in range(m):
            u[a] = 0.0
            au[a] = 0.0
            for c in range(m):
                u[a] += diff[a, c] * x[c, k]
                au[a] += diff[a, c] * ax[c, k]
        for a in range(m):
            b[a] += u[a] * rhs[k]
            for c in range(m):
                G[a, c] += 0.5 * (u[a] * au[c] + u[c] * au[a])


@kernel
def _galerkin_combine(coef, x, ax, m, out, aout):
    """out = sum_c coef[c] x[c], aout = sum_c coef[c] ax[c] over the first m fields."""
    for k in range(x.shape[1]):
        s = 0.0
        a = 0.0
        for c in range(m):
            s += coef[c] * x[c, k]
            a += coef[c] * ax[c, k]
        out[k] = s
        aout[k] = a
