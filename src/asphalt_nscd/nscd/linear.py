"""Fast path: a step of a bonded network without active contacts is a linear system.

With no contact reaction and no breakage, every bond obeys the affine law P_b = c0_b -
G_b (v_i - v_j) (local_laws.py; G_b = F_b^T diag(c_g) F_b, constant for a given dt, theta
and bond parameters). Eliminating the impulses gives, on the translational velocities of
the mobile bodies (spheres of finite mass and free plates),

    (M + sum_b H_b G_b H_b^T) v+ = M v_free + sum_b H_b q_b,

q_b = c0_b - G_b (v_i - v_j)_known (known velocities: fixed spheres, fixed or driven plates).
The matrix is symmetric positive definite and constant while the set of intact bonds does
not change, so it is factorised once (SuperLU, scipy.sparse.linalg.splu) and each step
costs one assembly of the right-hand side and two triangular solves. Rotations are not
coupled by bonds (no torque).

Validity is checked after the solve by the caller (moreau_jean.py): every contact candidate
must satisfy U_n + max(g, 0)/h >= 0 with zero reaction, and no bond may exceed R_crit;
otherwise the step is redone by NLGS. The test tests/unit/test_nscd_linear.py checks that
both paths give the same reactions to the NLGS tolerance.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit
from scipy.sparse.linalg import splu


def dof_map(inv_mass, inv_mass_plate):
    """Unknown-body numbering: (N,) and (P,) arrays of dof blocks (-1 = known velocity)."""
    sph = np.full(len(inv_mass), -1, dtype=np.int64)
    mob = inv_mass > 0
    sph[mob] = np.arange(mob.sum())
    pl = np.full(len(inv_mass_plate), -1, dtype=np.int64)
    pmob = inv_mass_plate > 0
    pl[pmob] = mob.sum() + np.arange(pmob.sum())
    return sph, pl


class LinearBondSolver:
    """Factorised system of the bonded network for one (dt, theta, intact-bond set).

    Parameters
    ----------
    mass : (N,) kg; mass_plate : (P,) kg (only free plates are unknowns).
    inv_mass, inv_mass_plate : (N,), (P,) 1/kg (0 = immobile).
    bi, bj, frame, cg : bonds (B,), (B,3,3), (B,3) N s/m; broken : (B,) bool.
    """

    def __init__(self, inv_mass, inv_mass_plate, bi, bj, frame, cg, broken):
        self.sph, self.pl = dof_map(inv_mass, inv_mass_plate)
        nb_unknown = int((self.sph >= 0).sum() + (self.pl >= 0).sum())
        self.ndof = 3 * nb_unknown
        self.mass_dof = np.zeros(self.ndof)
        self.mass_dof.reshape(-1, 3)[self.sph[self.sph >= 0]] = (1.0 / inv_mass[self.sph >= 0])[:, None]
        self.mass_dof.reshape(-1, 3)[self.pl[self.pl >= 0]] = (1.0 / inv_mass_plate[self.pl >= 0])[:, None]
        keep = ~broken
        G = np.einsum("bci,bc,bcj->bij", frame, cg, frame)[keep]
        di = self.sph[bi[keep]]
        jj = bj[keep]
        dj = np.full(len(jj), -1, dtype=np.int64)
        dj[jj >= 0] = self.sph[jj[jj >= 0]]
        dj[jj < 0] = self.pl[-1 - jj[jj < 0]]
        rows, cols, vals = [np.arange(self.ndof)], [np.arange(self.ndof)], [self.mass_dof]
        r3 = np.arange(3)
        for da, db, sign in ((di, di, 1.0), (dj, dj, 1.0), (di, dj, -1.0), (dj, di, -1.0)):
            ok = (da >= 0) & (db >= 0)
            rr = (3 * da[ok, None, None] + r3[None, :, None]) * np.ones((1, 1, 3), np.int64)
            cc = (3 * db[ok, None, None] + r3[None, None, :]) * np.ones((1, 3, 1), np.int64)
            rows.append(rr.ravel())
            cols.append(cc.ravel())
            vals.append((sign * G[ok]).ravel())
        K = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(self.ndof, self.ndof))
        self.nnz_matrix = K.nnz
        self.lu = splu(K, permc_spec="MMD_AT_PLUS_A") if self.ndof else None
        self.nnz_factor = self.lu.L.nnz + self.lu.U.nnz if self.ndof else 0

    def solve(self, v_free, vp_free, bi, bj, frame, c0, cg, broken, v, vp, impulse):
        """Velocities at the end of the step (written into v (N,3), vp (P,3): unknown rows
        only; known rows must already hold the imposed velocities) and bond impulses
        impulse (B,3) in the local frames."""
        rhs = np.zeros(self.ndof)
        _rhs(rhs, self.sph, self.pl, self.mass_dof, v_free, vp_free, v, vp, bi, bj, frame, c0,
             cg, broken)
        sol = self.lu.solve(rhs) if self.ndof else rhs
        _scatter(sol, self.sph, self.pl, v, vp)
        _bond_impulses(bi, bj, frame, c0, cg, broken, v, vp, impulse)


@njit(cache=True)
def _rhs(rhs, sph, pl, mass_dof, v_free, vp_free, v, vp, bi, bj, frame, c0, cg, broken):
    for s in range(len(sph)):
        if sph[s] >= 0:
            for d in range(3):
                rhs[3 * sph[s] + d] = mass_dof[3 * sph[s] + d] * v_free[s, d]
    for k in range(len(pl)):
        if pl[k] >= 0:
            for d in range(3):
                rhs[3 * pl[k] + d] = mass_dof[3 * pl[k] + d] * vp_free[k, d]
    q = np.empty(3)
    uk = np.empty(3)
    for b in range(len(bi)):
        if broken[b]:
            continue
        i = bi[b]
        j = bj[b]
        di = sph[i]
        dj = sph[j] if j >= 0 else pl[-1 - j]
        # known part of the relative velocity
        for d in range(3):
            vi = v[i, d] if di < 0 else 0.0
            if j >= 0:
                vj = v[j, d] if dj < 0 else 0.0
            else:
                vj = vp[-1 - j, d] if dj < 0 else 0.0
            uk[d] = vi - vj
        for d in range(3):
            acc = 0.0
            for c in range(3):
                ul = frame[b, c, 0] * uk[0] + frame[b, c, 1] * uk[1] + frame[b, c, 2] * uk[2]
                acc += frame[b, c, d] * (c0[b, c] - cg[b, c] * ul)
            q[d] = acc
        for d in range(3):
            if di >= 0:
                rhs[3 * di + d] += q[d]
            if dj >= 0:
                rhs[3 * dj + d] -= q[d]


@njit(cache=True)
def _scatter(sol, sph, pl, v, vp):
    for s in range(len(sph)):
        if sph[s] >= 0:
            for d in range(3):
                v[s, d] = sol[3 * sph[s] + d]
    for k in range(len(pl)):
        if pl[k] >= 0:
            for d in range(3):
                vp[k, d] = sol[3 * pl[k] + d]


@njit(cache=True)
def _bond_impulses(bi, bj, frame, c0, cg, broken, v, vp, impulse):
    for b in range(len(bi)):
        if broken[b]:
            continue
        i = bi[b]
        j = bj[b]
        for c in range(3):
            acc = 0.0
            for d in range(3):
                vj = v[j, d] if j >= 0 else vp[-1 - j, d]
                acc += frame[b, c, d] * (v[i, d] - vj)
            impulse[b, c] = c0[b, c] - cg[b, c] * acc
