"""Matrix-free conjugate gradient of the linear fast path (``linear_solver='cg'``).

The step matrix A = M + sum_b L_b^T G_b L_b is applied bond by bond (:func:`_matvec`, which
also applies the previous updates of x and p so that p is read once); the bond blocks
G_b = c_t I + (c_n - c_t) n n^T are stored compactly: sphere-sphere bonds, whose lever arms
lie along n, as 7 numbers (n, c_t, c_n - c_t, al_i, al_j), the others as 11 (n, c_t,
c_n - c_t, a_i, a_j). Preconditioner: block Jacobi on the 3x3 diagonal blocks
(:func:`block_jacobi`). ``threads`` > 1: the bonds are ordered by partitions of the unknowns
(:func:`_partition`) and the product runs on numba threads (:func:`_pcg_threaded`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .._jit import kernel


class CGOperator(NamedTuple):
    """The matrix-free step matrix: diagonal of M mass_dof (ndof,) kg or kg m², compact bonds
    bdat_c (Bc,7|5) float and their blocks blk_c (Bc,4) int32, general bonds bdat_g (Bg,11)
    and blk_g (Bg,4) int32 (blocks: translation and rotation of i, then of j; -1 = known)."""

    mass_dof: np.ndarray
    bdat_c: np.ndarray
    blk_c: np.ndarray
    bdat_g: np.ndarray
    blk_g: np.ndarray


def matrix_free_operator(mass_dof, nblk, blk, frame, cgk, arm_i, arm_j, rot, threads):
    """The :class:`CGOperator` of the intact bonds and their order.

    Parameters
    ----------
    mass_dof (ndof,); nblk : number of unknown blocks; blk (B,4) int64 blocks of the intact
    bonds; frame (B,3,3), cgk (B,3) N s/m (equal tangential coefficients), arm_i, arm_j
    (B,3) m of the intact bonds; rot : 'contact' kinematics; threads : of :func:`_partition`.

    Returns
    -------
    (op, order (B,) of the bonds in op, part_c, part_g (threads+2,) or empty, nrm (B,3),
    gcol [(B,1), (B,1)] = c_t, c_n - c_t; all in the order ``order``).

    Raises
    ------
    ValueError if the two tangential bond coefficients differ.
    """
    if not np.array_equal(cgk[:, 1], cgk[:, 2]):
        raise ValueError("the two tangential bond coefficients must be equal")
    nrm = frame[:, 0, :]
    gcol = [cgk[:, 1:2], (cgk[:, 0] - cgk[:, 1])[:, None]]
    ai, aj = arm_i, arm_j
    al_i = np.einsum("bd,bd->b", ai, nrm)
    al_j = np.einsum("bd,bd->b", aj, nrm)
    # lever arms along the normal (sphere-sphere bonds of state.Bonds.create, up to
    # round-off) are stored as their two components: the compact kernel branch
    par = (np.abs(ai - al_i[:, None] * nrm).max(1) <= 1e-12 * np.abs(ai).max(1)) & (
        np.abs(aj - al_j[:, None] * nrm).max(1) <= 1e-12 * np.abs(aj).max(1)
    )
    if not rot:
        par[:] = True
        al_i[:] = 0.0
        al_j[:] = 0.0
    order, part_c, part_g = _partition(blk, par, nblk, int(threads))
    par = par[order]
    blk = blk[order]
    nrm, ai, aj, al_i, al_j = nrm[order], ai[order], aj[order], al_i[order], al_j[order]
    gcol = [g[order] for g in gcol]
    blk_c = np.ascontiguousarray(blk[par].astype(np.int32))
    arms_c = [al_i[par, None], al_j[par, None]] if rot else []  # unread without
    bdat_c = np.ascontiguousarray(
        np.concatenate(  # rotation blocks
            [nrm[par]] + [g[par] for g in gcol] + arms_c, 1
        )
    )
    blk_g = np.ascontiguousarray(blk[~par].astype(np.int32))
    bdat_g = np.ascontiguousarray(np.concatenate([nrm[~par]] + [g[~par] for g in gcol] + [ai[~par], aj[~par]], 1))
    op = CGOperator(mass_dof, bdat_c, blk_c, bdat_g, blk_g)
    return op, order, part_c, part_g, nrm, gcol


def block_jacobi(m3, blk, L, G):
    """Inverses (nblk, 3, 3) of the diagonal 3x3 blocks of the step matrix: m3 (nblk,3) the
    diagonal of M, blk (B,4) the bonds' blocks, L the four (B,3,3) bond velocity operators,
    G (B,3,3) the bond blocks."""
    blocks = np.zeros((len(m3), 3, 3))
    blocks[:, [0, 1, 2], [0, 1, 2]] = m3
    for c in range(4):
        ok = blk[:, c] >= 0
        Lc = L[c][ok]
        np.add.at(blocks, blk[ok, c], np.einsum("bki,bkl,blj->bij", Lc, G[ok], Lc))
    return np.ascontiguousarray(np.linalg.inv(blocks)) if len(m3) else blocks


def _partition(blk, compact, nblk, threads):
    """Bond order and ranges of the threaded matrix product.

    The unknown blocks are cut into ``threads`` contiguous ranges holding about the same
    number of bonds; a bond whose blocks (-1 = known, ignored) all lie in range t belongs to
    partition t, the others to the last, sequential group. Returns (order (B,) of the
    bonds: compact bonds first grouped by partition, then the general ones likewise,
    part_c and part_g (threads+2,) int64 range starts within the compact and within the
    general bonds); for threads <= 1: (identity, empty, empty).
    """
    nb = len(blk)
    if threads <= 1:
        return np.arange(nb), np.zeros(0, np.int64), np.zeros(0, np.int64)
    big = np.iinfo(np.int64).max
    lo = np.where(blk >= 0, blk, big).min(1)
    hi = blk.max(1)
    lo = np.where(lo == big, 0, lo)
    hi = np.maximum(hi, 0)
    per_blk = np.bincount(lo, minlength=max(nblk, 1))
    cum = np.cumsum(per_blk)
    cuts = np.searchsorted(cum, np.arange(1, threads) * nb / threads)
    cuts = np.concatenate([[0], cuts, [max(nblk, 1)]])
    own = np.searchsorted(cuts, lo, side="right") - 1
    grp = np.where(np.searchsorted(cuts, hi, side="right") - 1 == own, own, threads)
    key = np.where(compact, 0, threads + 1) + grp
    order = np.argsort(key, kind="stable")
    kc = np.sort(grp[compact])
    kg = np.sort(grp[~compact])
    part_c = np.searchsorted(kc, np.arange(threads + 2)).astype(np.int64)
    part_g = np.searchsorted(kg, np.arange(threads + 2)).astype(np.int64)
    return order, part_c, part_g


@kernel
def _matvec(mass_dof, bdat_c, blk_c, bdat, blk, z, beta, p, y, alpha, x):
    """x += alpha p (the previous CG update, fused here to read p once), p <- z + beta p,
    then y = (M + sum_b L_b^T G_b L_b) p matrix-free over the intact bonds; returns p.y.
    G_b = g_t I + g_nt n n^T. blk_c, blk (B,4) int32: translation and rotation blocks of
    i, then of j (-1 = known). Compact bonds bdat_c (Bc,7|5): n, g_t,
    g_nt and the lever arms a_i = al_i n, a_j = al_j n given by al_i, al_j (then w x a =
    al (w x n) and a x f = al g_t (n x u)); general bonds bdat (Bg,11): n, g_t, g_nt, a_i,
    a_j. Arms are read only for rotation blocks."""
    py = 0.0
    for k in range(len(p)):
        pk = p[k]
        x[k] += alpha * pk
        pk = z[k] + beta * pk
        p[k] = pk
        y[k] = mass_dof[k] * pk
        py += pk * y[k]
    return py + _bonds(0, blk_c.shape[0], bdat_c, blk_c, 0, blk.shape[0], bdat, blk, p, y)


@njit(parallel=True)  # not cached: _pcg_threaded
def _matvec_par(mass_dof, bdat_c, blk_c, bdat, blk, part_c, part_g, z, beta, p, y, alpha, x):
    """:func:`_matvec` on threads: the bonds are ordered by partition (LinearBondSolver with
    threads > 1): the bonds of partition t (t < T) touch only its blocks and are summed by
    one thread each, then the bonds across partitions (part_c[T]..part_c[T+1], and the same
    for the general bonds) sequentially."""
    py = 0.0
    for k in prange(len(p)):
        pk = p[k]
        x[k] += alpha * pk
        pk = z[k] + beta * pk
        p[k] = pk
        yk = mass_dof[k] * pk
        y[k] = yk
        py += pk * yk
    nt = len(part_c) - 2
    for t in prange(nt):
        py += _bonds(part_c[t], part_c[t + 1], bdat_c, blk_c, part_g[t], part_g[t + 1], bdat, blk, p, y)
    return py + _bonds(part_c[nt], part_c[nt + 1], bdat_c, blk_c, part_g[nt], part_g[nt + 1], bdat, blk, p, y)


@kernel
def _bonds(lo_c, hi_c, bdat_c, blk_c, lo_g, hi_g, bdat, blk, p, y):
    """y += sum_b L_b^T G_b L_b p over the compact bonds lo_c..hi_c and the general bonds
    lo_g..hi_g (:func:`_matvec`); returns their sum of p^T L^T G L p."""
    py = 0.0
    for b in range(lo_c, hi_c):
        ti = blk_c[b, 0]
        ri = blk_c[b, 1]
        tj = blk_c[b, 2]
        rj = blk_c[b, 3]
        u0 = 0.0
        u1 = 0.0
        u2 = 0.0
        if ti >= 0:
            u0 = p[3 * ti]
            u1 = p[3 * ti + 1]
            u2 = p[3 * ti + 2]
        if tj >= 0:
            u0 -= p[3 * tj]
            u1 -= p[3 * tj + 1]
            u2 -= p[3 * tj + 2]
        n0 = bdat_c[b, 0]
        n1 = bdat_c[b, 1]
        n2 = bdat_c[b, 2]
        rot = ri >= 0 or rj >= 0
        if rot:  # W = al_i w_i - al_j w_j; u += W x n
            w0 = 0.0
            w1 = 0.0
            w2 = 0.0
            if ri >= 0:
                al = bdat_c[b, 5]
                w0 = al * p[3 * ri]
                w1 = al * p[3 * ri + 1]
                w2 = al * p[3 * ri + 2]
            if rj >= 0:
                al = bdat_c[b, 6]
                w0 -= al * p[3 * rj]
                w1 -= al * p[3 * rj + 1]
                w2 -= al * p[3 * rj + 2]
            u0 += w1 * n2 - w2 * n1
            u1 += w2 * n0 - w0 * n2
            u2 += w0 * n1 - w1 * n0
        gt = bdat_c[b, 3]
        s = bdat_c[b, 4] * (n0 * u0 + n1 * u1 + n2 * u2)
        f0 = gt * u0 + s * n0
        f1 = gt * u1 + s * n1
        f2 = gt * u2 + s * n2
        py += u0 * f0 + u1 * f1 + u2 * f2  # p^T L^T G L p
        if ti >= 0:
            y[3 * ti] += f0
            y[3 * ti + 1] += f1
            y[3 * ti + 2] += f2
        if tj >= 0:
            y[3 * tj] -= f0
            y[3 * tj + 1] -= f1
            y[3 * tj + 2] -= f2
        if rot:  # n x f = g_t n x u
            c0 = gt * (n1 * u2 - n2 * u1)
            c1 = gt * (n2 * u0 - n0 * u2)
            c2 = gt * (n0 * u1 - n1 * u0)
            if ri >= 0:
                al = bdat_c[b, 5]
                y[3 * ri] += al * c0
                y[3 * ri + 1] += al * c1
                y[3 * ri + 2] += al * c2
            if rj >= 0:
                al = bdat_c[b, 6]
                y[3 * rj] -= al * c0
                y[3 * rj + 1] -= al * c1
                y[3 * rj + 2] -= al * c2
    for b in range(lo_g, hi_g):
        ti = blk[b, 0]
        ri = blk[b, 1]
        tj = blk[b, 2]
        rj = blk[b, 3]
        u0 = 0.0
        u1 = 0.0
        u2 = 0.0
        if ti >= 0:
            u0 = p[3 * ti]
            u1 = p[3 * ti + 1]
            u2 = p[3 * ti + 2]
        if tj >= 0:
            u0 -= p[3 * tj]
            u1 -= p[3 * tj + 1]
            u2 -= p[3 * tj + 2]
        if ri >= 0:
            w0 = p[3 * ri]
            w1 = p[3 * ri + 1]
            w2 = p[3 * ri + 2]
            u0 += w1 * bdat[b, 7] - w2 * bdat[b, 6]
            u1 += w2 * bdat[b, 5] - w0 * bdat[b, 7]
            u2 += w0 * bdat[b, 6] - w1 * bdat[b, 5]
        if rj >= 0:
            w0 = p[3 * rj]
            w1 = p[3 * rj + 1]
            w2 = p[3 * rj + 2]
            u0 -= w1 * bdat[b, 10] - w2 * bdat[b, 9]
            u1 -= w2 * bdat[b, 8] - w0 * bdat[b, 10]
            u2 -= w0 * bdat[b, 9] - w1 * bdat[b, 8]
        n0 = bdat[b, 0]
        n1 = bdat[b, 1]
        n2 = bdat[b, 2]
        gt = bdat[b, 3]
        s = bdat[b, 4] * (n0 * u0 + n1 * u1 + n2 * u2)
        f0 = gt * u0 + s * n0
        f1 = gt * u1 + s * n1
        f2 = gt * u2 + s * n2
        py += u0 * f0 + u1 * f1 + u2 * f2  # p^T L^T G L p
        if ti >= 0:
            y[3 * ti] += f0
            y[3 * ti + 1] += f1
            y[3 * ti + 2] += f2
        if tj >= 0:
            y[3 * tj] -= f0
            y[3 * tj + 1] -= f1
            y[3 * tj + 2] -= f2
        if ri >= 0:
            a0 = bdat[b, 5]
            a1 = bdat[b, 6]
            a2 = bdat[b, 7]
            y[3 * ri] += a1 * f2 - a2 * f1
            y[3 * ri + 1] += a2 * f0 - a0 * f2
            y[3 * ri + 2] += a0 * f1 - a1 * f0
        if rj >= 0:
            a0 = bdat[b, 8]
            a1 = bdat[b, 9]
            a2 = bdat[b, 10]
            y[3 * rj] -= a1 * f2 - a2 * f1
            y[3 * rj + 1] -= a2 * f0 - a0 * f2
            y[3 * rj + 2] -= a0 * f1 - a1 * f0
    return py


@kernel
def _update(precond, alpha, q, r, z):
    """r -= alpha q, z = P^-1 r (3x3 block Jacobi); returns (r.r, r.z)."""
    rr = 0.0
    rz = 0.0
    for blk in range(precond.shape[0]):
        b3 = 3 * blk
        for d in range(3):
            r[b3 + d] -= alpha * q[b3 + d]
        r0 = r[b3]
        r1 = r[b3 + 1]
        r2 = r[b3 + 2]
        for d in range(3):
            zd = precond[blk, d, 0] * r0 + precond[blk, d, 1] * r1 + precond[blk, d, 2] * r2
            z[b3 + d] = zd
            rz += r[b3 + d] * zd
        rr += r0 * r0 + r1 * r1 + r2 * r2
    return rr, rz


@njit(parallel=True)  # not cached: _pcg_threaded
def _update_par(precond, alpha, q, r, z):
    """:func:`_update` on threads."""
    rr = 0.0
    rz = 0.0
    for blk in prange(precond.shape[0]):
        b3 = 3 * blk
        for d in range(3):
            r[b3 + d] -= alpha * q[b3 + d]
        r0 = r[b3]
        r1 = r[b3 + 1]
        r2 = r[b3 + 2]
        z0 = precond[blk, 0, 0] * r0 + precond[blk, 0, 1] * r1 + precond[blk, 0, 2] * r2
        z1 = precond[blk, 1, 0] * r0 + precond[blk, 1, 1] * r1 + precond[blk, 1, 2] * r2
        z2 = precond[blk, 2, 0] * r0 + precond[blk, 2, 1] * r1 + precond[blk, 2, 2] * r2
        z[b3] = z0
        z[b3 + 1] = z1
        z[b3 + 2] = z2
        rz += r0 * z0 + r1 * z1 + r2 * z2
        rr += r0 * r0 + r1 * r1 + r2 * r2
    return rr, rz


@kernel
def _pcg(op, precond, rhs, x, tol, max_iter, work):
    """Block-Jacobi preconditioned conjugate gradient on (M + sum L^T G L) x = rhs (operator
    op, :class:`CGOperator`; precond (nblk,3,3) from :func:`block_jacobi`), x (ndof,) holding
    the initial guess; stops when |r| <= tol |rhs|. work (4, n): r (final residual on
    return), z, p, q. Sequential kernels only (the threaded variant is
    :func:`_pcg_threaded`). Returns (iterations, relative residual)."""
    mass_dof, bdat_c, blk_c, bdat_g, blk_g = op.mass_dof, op.bdat_c, op.blk_c, op.bdat_g, op.blk_g
    n = len(rhs)
    r = work[0]
    z = work[1]
    p = work[2]
    q = work[3]
    for k in range(n):
        p[k] = 0.0
    _matvec(mass_dof, bdat_c, blk_c, bdat_g, blk_g, x, 0.0, p, q, 0.0, x)  # p <- x, q = A x
    norm_b = 0.0
    for k in range(n):
        r[k] = rhs[k] - q[k]
        norm_b += rhs[k] * rhs[k]
        p[k] = 0.0
    norm_b = np.sqrt(norm_b)
    if norm_b == 0.0:
        for k in range(n):
            x[k] = 0.0
            r[k] = 0.0
        return 0, 0.0
    rr, rz = _update(precond, 0.0, q, r, z)  # z = P^-1 r
    beta = 0.0
    alpha = 0.0
    it = 0
    while np.sqrt(rr) > tol * norm_b and it < max_iter:
        it += 1
        pq = _matvec(mass_dof, bdat_c, blk_c, bdat_g, blk_g, z, beta, p, q, alpha, x)
        alpha = rz / pq
        rr, rz_new = _update(precond, alpha, q, r, z)
        beta = rz_new / rz
        rz = rz_new
    for k in range(n):  # the last update of x
        x[k] += alpha * p[k]
    return it, np.sqrt(rr) / norm_b


def _pcg_threaded(op, precond, rhs, x, tol, max_iter, work, part_c, part_g):
    """:func:`_pcg` on threads (same arguments, plus the bond partitions part_c, part_g of
    :func:`_partition`): the iteration loop runs in Python around the threaded kernels
    :func:`_matvec_par` and :func:`_update_par`.

    Why not one compiled loop: a cached compiled function calling a cached
    ``parallel=True`` one can segfault when loaded from numba's cache, most reliably when
    several processes filled the cache at once (github.com/numba/numba/issues/4807, /8578).
    The Python loop costs a few microseconds per iteration against milliseconds of
    threaded work."""
    mass_dof, bdat_c, blk_c, bdat_g, blk_g = op.mass_dof, op.bdat_c, op.blk_c, op.bdat_g, op.blk_g
    r, z, p, q = work
    p[:] = 0.0
    _matvec_par(mass_dof, bdat_c, blk_c, bdat_g, blk_g, part_c, part_g, x, 0.0, p, q, 0.0, x)
    np.subtract(rhs, q, out=r)
    p[:] = 0.0
    norm_b = float(np.sqrt(rhs @ rhs))
    if norm_b == 0.0:
        x[:] = 0.0
        r[:] = 0.0
        return 0, 0.0
    rr, rz = _update(precond, 0.0, q, r, z)
    beta = alpha = 0.0
    it = 0
    while np.sqrt(rr) > tol * norm_b and it < max_iter:
        it += 1
        pq = _matvec_par(mass_dof, bdat_c, blk_c, bdat_g, blk_g, part_c, part_g, z, beta, p, q, alpha, x)
        alpha = rz / pq
        rr, rz_new = _update_par(precond, alpha, q, r, z)
        beta = rz_new / rz
        rz = rz_new
    x += alpha * p
    return it, float(np.sqrt(rr)) / norm_b
