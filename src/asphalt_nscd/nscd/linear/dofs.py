"""Unknowns of the linear fast path: the numbering of the velocity blocks, the right-hand
side of the step's system and the bond impulses of its solution.

The unknowns are 3-dof blocks, numbered body by body, a body's translation block followed
by its rotation block ('contact' kinematics only): mobile spheres, free plates and rotating
plates; known velocities (fixed spheres, fixed or driven plates) are not unknowns.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._jit import helper, kernel
from ..local_laws import bond_velocity


class DofMap(NamedTuple):
    """Unknown block of each body (:func:`dof_numbering`): translation st and rotation sr
    (N,) of the spheres, pt and pr (P,) of the plates; int64, -1 = known velocity."""

    st: np.ndarray
    sr: np.ndarray
    pt: np.ndarray
    pr: np.ndarray


def skew(a):
    """Cross-product matrices (B,3,3) of vectors a (B,3): skew(a) @ x = a x x."""
    z = np.zeros(len(a))
    return np.stack(
        [np.stack([z, -a[:, 2], a[:, 1]], 1), np.stack([a[:, 2], z, -a[:, 0]], 1), np.stack([-a[:, 1], a[:, 0], z], 1)],
        1,
    )


def dof_numbering(inv_mass, inv_mass_plate, inv_inertia=None, inv_inertia_plate=None):
    """Block numbering of the unknowns, body by body (translation, then rotation).

    Parameters
    ----------
    inv_mass (N,), inv_mass_plate (P,) 1/kg (0 = known translation); inv_inertia (N,) and
    inv_inertia_plate (P,3) 1/(kg m²) (0 = known rotation), None = no rotation unknown
    ('barycentre' kinematics).

    Returns
    -------
    st, sr (N,), pt, pr (P,) int64 block indices (-1 = known velocity) and m3 (nblk, 3) the
    diagonal of M (masses and principal inertias).
    """
    inv_mass = np.asarray(inv_mass, float)
    inv_mass_plate = np.asarray(inv_mass_plate, float)
    n, p = len(inv_mass), len(inv_mass_plate)
    mob = inv_mass > 0
    pmob = inv_mass_plate > 0
    if inv_inertia is None:
        rmob = np.zeros(n, bool)
        prmob = np.zeros(p, bool)
    else:
        rmob = mob & (np.asarray(inv_inertia, float) > 0)
        prmob = np.all(np.asarray(inv_inertia_plate, float).reshape(p, 3) > 0, axis=1)
    count = np.concatenate([mob.astype(np.int64) + rmob, pmob.astype(np.int64) + prmob])
    first = np.concatenate([[0], np.cumsum(count)])
    st = np.where(mob, first[:n], -1)
    sr = np.where(rmob, first[:n] + mob, -1)
    pt = np.where(pmob, first[n:-1], -1)
    pr = np.where(prmob, first[n:-1] + pmob, -1)
    nblk = int(first[-1])
    m3 = np.zeros((nblk, 3))
    m3[st[mob]] = (1.0 / inv_mass[mob])[:, None]
    m3[pt[pmob]] = (1.0 / inv_mass_plate[pmob])[:, None]
    if inv_inertia is not None:
        m3[sr[rmob]] = (1.0 / np.asarray(inv_inertia, float)[rmob])[:, None]
        m3[pr[prmob]] = 1.0 / np.asarray(inv_inertia_plate, float).reshape(p, 3)[prmob]
    return st, sr, pt, pr, m3


@kernel
def _gather(x, dofs, vel):
    """x[block] <- the body velocities (bundles.Velocities) of the unknown blocks of dofs
    (:class:`DofMap`)."""
    st, sr, pt, pr = dofs.st, dofs.sr, dofs.pt, dofs.pr
    v, w, vp, wp = vel.v, vel.w, vel.vp, vel.wp
    for s in range(len(st)):
        for d in range(3):
            if st[s] >= 0:
                x[3 * st[s] + d] = v[s, d]
            if sr[s] >= 0:
                x[3 * sr[s] + d] = w[s, d]
    for k in range(len(pt)):
        for d in range(3):
            if pt[k] >= 0:
                x[3 * pt[k] + d] = vp[k, d]
            if pr[k] >= 0:
                x[3 * pr[k] + d] = wp[k, d]


@kernel
def _scatter(x, dofs, vel):
    """Body velocities (bundles.Velocities) of the unknown blocks of dofs (:class:`DofMap`)
    <- x."""
    st, sr, pt, pr = dofs.st, dofs.sr, dofs.pt, dofs.pr
    v, w, vp, wp = vel.v, vel.w, vel.vp, vel.wp
    for s in range(len(st)):
        for d in range(3):
            if st[s] >= 0:
                v[s, d] = x[3 * st[s] + d]
            if sr[s] >= 0:
                w[s, d] = x[3 * sr[s] + d]
    for k in range(len(pt)):
        for d in range(3):
            if pt[k] >= 0:
                vp[k, d] = x[3 * pt[k] + d]
            if pr[k] >= 0:
                wp[k, d] = x[3 * pr[k] + d]


@helper
def _add_force(y, t, r, arm, b, f0, f1, f2, sign):
    """y[t] += sign f, y[r] += sign arm[b] x f (blocks of 3; -1 = known, skipped)."""
    if t >= 0:
        y[3 * t] += sign * f0
        y[3 * t + 1] += sign * f1
        y[3 * t + 2] += sign * f2
    if r >= 0:
        a0 = arm[b, 0]
        a1 = arm[b, 1]
        a2 = arm[b, 2]
        y[3 * r] += sign * (a1 * f2 - a2 * f1)
        y[3 * r + 1] += sign * (a2 * f0 - a0 * f2)
        y[3 * r + 2] += sign * (a0 * f1 - a1 * f0)


@kernel
def _rhs(rhs, mass_dof, dofs, free, known, bonds, c0, cg, rot):
    """rhs (ndof,) = M x_free + sum_b L_b^T q_b, q_b = F^T (c0 - cg F U_known) (U_known: the
    bond velocity from the known blocks only; rotations enter only when rot).

    mass_dof (ndof,) kg or kg m²; dofs : :class:`DofMap`; free : bundles.Velocities, the
    free velocities; known : bundles.Velocities whose known rows hold the imposed
    velocities; bonds : bundles.BondGeometry; c0 (B,3) N s, cg (B,3) N s/m
    (local_laws.bond_predict)."""
    st, sr, pt, pr = dofs.st, dofs.sr, dofs.pt, dofs.pr
    v, w, vp, wp = known.v, known.w, known.vp, known.wp
    bi, bj, frame, arm_i, arm_j, broken = (bonds.i, bonds.j, bonds.frame, bonds.arm_i, bonds.arm_j, bonds.broken)
    _gather(rhs, dofs, free)
    for k in range(len(rhs)):
        rhs[k] *= mass_dof[k]
    for b in range(len(bi)):
        if broken[b]:
            continue
        i = bi[b]
        j = bj[b]
        ti = st[i]
        ri = sr[i]
        if j >= 0:
            tj = st[j]
            rj = sr[j]
            vj0, vj1, vj2 = v[j, 0], v[j, 1], v[j, 2]
            wj0, wj1, wj2 = w[j, 0], w[j, 1], w[j, 2]
        else:
            tj = pt[-1 - j]
            rj = pr[-1 - j]
            vj0, vj1, vj2 = vp[-1 - j, 0], vp[-1 - j, 1], vp[-1 - j, 2]
            wj0, wj1, wj2 = wp[-1 - j, 0], wp[-1 - j, 1], wp[-1 - j, 2]
        u0 = 0.0
        u1 = 0.0
        u2 = 0.0
        if ti < 0:
            u0 += v[i, 0]
            u1 += v[i, 1]
            u2 += v[i, 2]
        if tj < 0:
            u0 -= vj0
            u1 -= vj1
            u2 -= vj2
        if rot and ri < 0:
            u0 += w[i, 1] * arm_i[b, 2] - w[i, 2] * arm_i[b, 1]
            u1 += w[i, 2] * arm_i[b, 0] - w[i, 0] * arm_i[b, 2]
            u2 += w[i, 0] * arm_i[b, 1] - w[i, 1] * arm_i[b, 0]
        if rot and rj < 0:
            u0 -= wj1 * arm_j[b, 2] - wj2 * arm_j[b, 1]
            u1 -= wj2 * arm_j[b, 0] - wj0 * arm_j[b, 2]
            u2 -= wj0 * arm_j[b, 1] - wj1 * arm_j[b, 0]
        q0 = 0.0
        q1 = 0.0
        q2 = 0.0
        for c in range(3):
            ul = frame[b, c, 0] * u0 + frame[b, c, 1] * u1 + frame[b, c, 2] * u2
            pc = c0[b, c] - cg[b, c] * ul
            q0 += frame[b, c, 0] * pc
            q1 += frame[b, c, 1] * pc
            q2 += frame[b, c, 2] * pc
        if not rot:
            ri = -1
            rj = -1
        _add_force(rhs, ti, ri, arm_i, b, q0, q1, q2, 1.0)
        _add_force(rhs, tj, rj, arm_j, b, q0, q1, q2, -1.0)


@kernel
def bond_impulses(bonds, c0, cg, vel, impulse, rot):
    """impulse (B,3) N s = c0 - cg F U of the intact bonds (Eq. 25; U: local_laws.bond_velocity
    of the velocities vel, bundles.Velocities; bonds : bundles.BondGeometry; c0 (B,3) N s,
    cg (B,3) N s/m)."""
    bi, bj, frame, arm_i, arm_j, broken = (bonds.i, bonds.j, bonds.frame, bonds.arm_i, bonds.arm_j, bonds.broken)
    v, w, vp, wp = vel.v, vel.w, vel.vp, vel.wp
    for b in range(len(bi)):
        if broken[b]:
            continue
        g0, g1, g2 = bond_velocity(b, bi, bj, arm_i, arm_j, v, w, vp, wp, rot)
        for c in range(3):
            ul = frame[b, c, 0] * g0 + frame[b, c, 1] * g1 + frame[b, c, 2] * g2
            impulse[b, c] = c0[b, c] - cg[b, c] * ul
