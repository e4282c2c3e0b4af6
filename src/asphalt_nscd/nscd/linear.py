"""Fast path: a step of a bonded network without active contacts is a linear system.

With no contact reaction and no breakage, every bond obeys the affine law P_b = c0_b -
G_b (v_i - v_j) (local_laws.py; G_b = F_b^T diag(c_g) F_b, constant for a given dt, theta
and bond parameters). Eliminating the impulses gives, on the translational velocities of
the mobile bodies (spheres of finite mass and free plates),

    (M + sum_b H_b G_b H_b^T) v+ = M v_free + sum_b H_b q_b,

q_b = c0_b - G_b (v_i - v_j)_known (known velocities: fixed spheres, fixed or driven plates).
The matrix is symmetric positive definite and constant while the set of intact bonds does
not change. Two solvers:

* ``cg`` (default): matrix-free preconditioned conjugate gradient (3x3 block-Jacobi
  preconditioner, initial guess = the velocities at the start of the step), stopped at a
  relative residual ``linear_tolerance``. O(B) per iteration and memory; the matrix is
  mass-dominated at the paper's time step (h² theta² K_bond ~ m), so it converges in tens
  of iterations.
  The bond blocks are stored compactly, G_b = c_t I + (c_n - c_t) n n^T (the two
  tangential coefficients of a bond are equal, local_laws.py): 5 numbers per bond instead
  of 9, which matters because the product is memory-bound.
* ``direct``: SuperLU factorisation once per (dt, theta, intact-bond set)
  (:func:`splu_symmetric`: symmetric mode, no pivoting, MMD ordering of A^T + A, the
  setting of harmonic/solver.py), two triangular solves per step, exact to round-off.
  At N = 12 000 (36 000 dofs, 79 000 bonds) the factorisation takes about 5 s, but the
  factor holds 2.9e7 entries and a solve (~0.07 s) is slower than ``cg`` (~0.02 s at
  linear_tolerance 1e-7): ``cg`` remains the default, ``direct`` is the reference.

Bond kinematics: with 'barycentre' the rotations are not coupled by bonds (no torque) and
the unknowns are the translational velocities above. With 'contact' (state.Bonds) the bond
velocity is U_b = L_b x over the blocks of its two bodies, L = [I, -[a_i]x] for the
candidate's translation and rotation, [-I, +[a_j]x] for the antagonist's, and the unknowns
are 3-dof blocks of translation and of rotation: 6 per mobile sphere, 3 more for a free
plate's translation, 3 for a rotating plate's rotation (its translation may be imposed).
The matrix is M + sum_b L_b^T G_b L_b with M the masses and the rotational inertias; the
``cg`` preconditioner is block-Jacobi on these 3x3 blocks (rotation blocks: sum of
[a]x^T G [a]x), the ``direct`` solver assembles the same matrix.

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

from .local_laws import bond_velocity


def dof_map(inv_mass, inv_mass_plate):
    """Unknown-body numbering: (N,) and (P,) arrays of dof blocks (-1 = known velocity)."""
    sph = np.full(len(inv_mass), -1, dtype=np.int64)
    mob = inv_mass > 0
    sph[mob] = np.arange(mob.sum())
    pl = np.full(len(inv_mass_plate), -1, dtype=np.int64)
    pmob = inv_mass_plate > 0
    pl[pmob] = mob.sum() + np.arange(pmob.sum())
    return sph, pl


def splu_symmetric(a, permutation=None):
    """SuperLU factor of a sparse matrix with a symmetric pattern and a dominant diagonal.

    Symmetric mode (``diag_pivot_thresh = 0``, SymmetricMode): the diagonal pivots of the
    fill-reducing ordering are kept, which is what makes the factorisation fast (partial
    pivoting destroys the ordering: > 5 min instead of ~5 s at 36 000 dofs). Valid for
    symmetric positive definite matrices such as the step matrix here; on an indefinite
    symmetric matrix a small pivot may lose accuracy (callers that use the factor as a
    preconditioner check their residual).

    Parameters
    ----------
    a : (n, n) scipy sparse matrix.
    permutation : (n,) int array or None
        None: SuperLU's MMD(A^T + A) ordering. Otherwise a symmetric fill-reducing ordering
        computed by the caller (e.g. METIS nested dissection,
        :mod:`asphalt_nscd.harmonic.ordering`): row and column k of the factorised matrix
        are row and column ``permutation[k]`` of ``a``, and SuperLU keeps that order
        (``permc_spec="NATURAL"``).

    Returns
    -------
    scipy.sparse.linalg.SuperLU (``permutation`` None), else :class:`PermutedLU` (same
    ``solve``, ``L``, ``U``, ``shape`` interface, in the unknowns of ``a``).

    Raises
    ------
    RuntimeError
        (from SuperLU) if the matrix is exactly singular.
    """
    if permutation is None:
        a = sp.csc_matrix(a, copy=True)
        a.sum_duplicates()
        a.sort_indices()
        return splu(a, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                    options={"SymmetricMode": True})
    perm = np.asarray(permutation, np.int64)
    a = sp.csr_matrix(a)[perm][:, perm].tocsc()
    a.sum_duplicates()
    a.sort_indices()
    lu = splu(a, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    return PermutedLU(lu, perm, a.dtype)


class PermutedLU:
    """A SuperLU factor of ``a[perm][:, perm]`` that solves systems in the unknowns of ``a``.

    ``solve(b)``: b (n,) or (n, k), real or complex; a complex right-hand side of a real factor
    (``dtype``) is solved as its real and imaginary columns in one call. ``nnz``: SuperLU's
    count of stored factor entries. ``L``, ``U``: the factors (of the
    permuted matrix) as new sparse matrices (SciPy copies them at each access: read their
    ``nnz`` once, do not keep them).
    """

    def __init__(self, lu, perm, dtype=np.float64):
        self.lu = lu
        self.perm = perm
        self.shape = lu.shape
        self.dtype = np.dtype(dtype)
        self.nnz = lu.nnz

    @property
    def L(self):  # noqa: N802 (SuperLU's name)
        return self.lu.L

    @property
    def U(self):  # noqa: N802
        return self.lu.U

    def solve(self, b):
        b = np.asarray(b)
        x = b[self.perm]
        if np.iscomplexobj(x) and self.dtype.kind != "c":
            col = x.ndim == 1
            x2 = x.reshape(len(x), -1)
            k = x2.shape[1]
            y = self.lu.solve(np.ascontiguousarray(np.hstack([x2.real, x2.imag])))
            y = y[:, :k] + 1j * y[:, k:]
            y = y.ravel() if col else y
        else:
            y = self.lu.solve(np.ascontiguousarray(x))
        out = np.empty_like(y)
        out[self.perm] = y
        return out


def _skew(a):
    """Cross-product matrices (B,3,3) of vectors a (B,3): skew(a) @ x = a x x."""
    z = np.zeros(len(a))
    return np.stack([np.stack([z, -a[:, 2], a[:, 1]], 1), np.stack([a[:, 2], z, -a[:, 0]], 1),
                     np.stack([-a[:, 1], a[:, 0], z], 1)], 1)


class LinearBondSolver:
    """Factorised system of the bonded network for one (dt, theta, intact-bond set).

    Parameters
    ----------
    inv_mass, inv_mass_plate : (N,), (P,) 1/kg (0 = immobile).
    bi, bj, frame, cg : bonds (B,), (B,3,3), (B,3) N s/m; broken : (B,) bool.
    rotation : dict or None — for the 'contact' kinematics: ``arm_i``, ``arm_j`` (B,3) m,
        ``inv_inertia`` (N,) and ``inv_inertia_plate`` (P,3) 1/(kg m²) (0 = no rotation).
        None: 'barycentre' kinematics (translations only).
    """

    def __init__(self, inv_mass, inv_mass_plate, bi, bj, frame, cg, broken, method="cg",
                 tolerance=1e-10, max_iterations=10000, rotation=None):
        if method not in ("cg", "direct"):
            raise ValueError(f"linear solver must be 'cg' or 'direct', got {method!r}")
        self.rot = rotation is not None
        if self.rot:
            self._init_rot(inv_mass, inv_mass_plate, bi, bj, frame, cg, broken, method,
                           tolerance, max_iterations, **rotation)
            return
        self.method = method
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        self.last_iterations = 0
        self.last_residual = 0.0
        self.sph, self.pl = dof_map(inv_mass, inv_mass_plate)
        nb_unknown = int((self.sph >= 0).sum() + (self.pl >= 0).sum())
        self.ndof = 3 * nb_unknown
        self.mass_dof = np.zeros(self.ndof)
        m3 = self.mass_dof.reshape(-1, 3)
        m3[self.sph[self.sph >= 0]] = (1.0 / inv_mass[self.sph >= 0])[:, None]
        m3[self.pl[self.pl >= 0]] = (1.0 / inv_mass_plate[self.pl >= 0])[:, None]
        keep = ~broken
        G = np.einsum("bci,bc,bcj->bij", frame, cg, frame)[keep]
        di = self.sph[bi[keep]]
        jj = bj[keep]
        dj = np.full(len(jj), -1, dtype=np.int64)
        dj[jj >= 0] = self.sph[jj[jj >= 0]]
        dj[jj < 0] = self.pl[-1 - jj[jj < 0]]
        self.di = np.ascontiguousarray(di)
        self.dj = np.ascontiguousarray(dj)
        if method == "cg":
            cgk = cg[keep]
            if not np.array_equal(cgk[:, 1], cgk[:, 2]):
                raise ValueError("the two tangential bond coefficients must be equal")
            self.normal = np.ascontiguousarray(frame[keep, 0, :])
            self.g_t = np.ascontiguousarray(cgk[:, 1])
            self.g_nt = np.ascontiguousarray(cgk[:, 0] - cgk[:, 1])
            nblk = self.ndof // 3
            blocks = np.zeros((nblk, 3, 3))
            blocks[:, [0, 1, 2], [0, 1, 2]] = self.mass_dof.reshape(-1, 3)
            for d in (di, dj):
                ok = d >= 0
                np.add.at(blocks, d[ok], G[ok])
            self.precond = np.ascontiguousarray(np.linalg.inv(blocks)) if nblk else blocks
            self.lu = None
            self.nnz_matrix = self.ndof + 36 * len(G)
            self.nnz_factor = 0
            return
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
        self.lu = splu_symmetric(K) if self.ndof else None
        self.nnz_factor = self.lu.L.nnz + self.lu.U.nnz if self.ndof else 0

    def _init_rot(self, inv_mass, inv_mass_plate, bi, bj, frame, cg, broken, method,
                  tolerance, max_iterations, arm_i, arm_j, inv_inertia, inv_inertia_plate):
        """Set up the 'contact' kinematics system (module docstring)."""
        self.method = method
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        self.last_iterations = 0
        self.last_residual = 0.0
        n, p = len(inv_mass), len(inv_mass_plate)
        # block numbering: translation of spheres, rotation of spheres, plates' translation,
        # plates' rotation (-1 = known velocity)
        mob = inv_mass > 0
        rmob = mob & (inv_inertia > 0)
        pmob = inv_mass_plate > 0
        prmob = np.all(inv_inertia_plate > 0, axis=1)
        counts = np.cumsum([0, mob.sum(), rmob.sum(), pmob.sum(), prmob.sum()])
        self.st = np.full(n, -1, np.int64)
        self.sr = np.full(n, -1, np.int64)
        self.pt = np.full(p, -1, np.int64)
        self.pr = np.full(p, -1, np.int64)
        self.st[mob] = counts[0] + np.arange(mob.sum())
        self.sr[rmob] = counts[1] + np.arange(rmob.sum())
        self.pt[pmob] = counts[2] + np.arange(pmob.sum())
        self.pr[prmob] = counts[3] + np.arange(prmob.sum())
        nblk = int(counts[-1])
        self.ndof = 3 * nblk
        m3 = np.zeros((nblk, 3))
        m3[self.st[mob]] = (1.0 / inv_mass[mob])[:, None]
        m3[self.sr[rmob]] = (1.0 / inv_inertia[rmob])[:, None]
        m3[self.pt[pmob]] = (1.0 / inv_mass_plate[pmob])[:, None]
        m3[self.pr[prmob]] = 1.0 / inv_inertia_plate[prmob]
        self.mass_dof = m3.ravel()
        keep = ~broken
        jj = bj[keep]
        sph = jj >= 0
        kk = np.where(sph, 0, -1 - jj)
        ti = self.st[bi[keep]]
        ri = self.sr[bi[keep]]
        tj = np.where(sph, self.st[np.where(sph, jj, 0)], self.pt[kk] if p else -1)
        rj = np.where(sph, self.sr[np.where(sph, jj, 0)], self.pr[kk] if p else -1)
        self.blk = np.ascontiguousarray(np.stack([ti, ri, tj, rj], 1).astype(np.int64))
        self.arm_i = np.ascontiguousarray(arm_i[keep])
        self.arm_j = np.ascontiguousarray(arm_j[keep])
        cgk = cg[keep]
        if not np.array_equal(cgk[:, 1], cgk[:, 2]):
            raise ValueError("the two tangential bond coefficients must be equal")
        self.normal = np.ascontiguousarray(frame[keep, 0, :])
        self.g_t = np.ascontiguousarray(cgk[:, 1])
        self.g_nt = np.ascontiguousarray(cgk[:, 0] - cgk[:, 1])
        G = np.einsum("bci,bc,bcj->bij", frame, cg, frame)[keep]
        eye = np.broadcast_to(np.eye(3), G.shape)
        # U_b = sum over the bond's blocks of L @ x_block
        L = [eye, -_skew(self.arm_i), -eye, _skew(self.arm_j)]
        if method == "cg":
            blocks = np.zeros((nblk, 3, 3))
            blocks[:, [0, 1, 2], [0, 1, 2]] = m3
            for c in range(4):
                ok = self.blk[:, c] >= 0
                Lc = L[c][ok]
                np.add.at(blocks, self.blk[ok, c], np.einsum("bki,bkl,blj->bij", Lc, G[ok], Lc))
            self.precond = np.ascontiguousarray(np.linalg.inv(blocks)) if nblk else blocks
            self.lu = None
            self.nnz_matrix = self.ndof + 144 * len(G)
            self.nnz_factor = 0
            return
        rows, cols, vals = [np.arange(self.ndof)], [np.arange(self.ndof)], [self.mass_dof]
        r3 = np.arange(3)
        for a in range(4):
            for c in range(4):
                ok = (self.blk[:, a] >= 0) & (self.blk[:, c] >= 0)
                if not ok.any():
                    continue
                da, dc = self.blk[ok, a], self.blk[ok, c]
                rr = (3 * da[:, None, None] + r3[None, :, None]) * np.ones((1, 1, 3), np.int64)
                cc = (3 * dc[:, None, None] + r3[None, None, :]) * np.ones((1, 3, 1), np.int64)
                rows.append(rr.ravel())
                cols.append(cc.ravel())
                vals.append(np.einsum("bki,bkl,blj->bij", L[a][ok], G[ok], L[c][ok]).ravel())
        K = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(self.ndof, self.ndof))
        self.nnz_matrix = K.nnz
        self.lu = splu_symmetric(K) if self.ndof else None
        self.nnz_factor = self.lu.L.nnz + self.lu.U.nnz if self.ndof else 0

    def solve_rot(self, v_free, w_free, vp_free, wp_free, bi, bj, frame, arm_i, arm_j, c0, cg,
                  broken, v, w, vp, wp, impulse, start=None):
        """'contact' kinematics: end-of-step velocities v, w (N,3), vp, wp (P,3) (unknown
        rows written; known rows must hold the imposed values) and bond impulses (B,3).
        ``start``: (v, w, vp, wp) initial guess of ``cg`` (default: the free velocities)."""
        rhs = np.zeros(self.ndof)
        free = (v_free, w_free, vp_free, wp_free)
        _gather_rot(rhs, self.st, self.sr, self.pt, self.pr, *free)
        rhs *= self.mass_dof
        _rhs_rot(rhs, self.st, self.sr, self.pt, self.pr, v, w, vp, wp, bi, bj, frame, arm_i,
                 arm_j, c0, cg, broken)
        if self.method == "direct":
            sol = self.lu.solve(rhs) if self.ndof else rhs
        else:
            sol = np.zeros(self.ndof)
            _gather_rot(sol, self.st, self.sr, self.pt, self.pr, *(start or free))
            it, res = _pcg_rot(self.mass_dof, self.normal, self.g_t, self.g_nt, self.blk,
                               self.arm_i, self.arm_j, self.precond, rhs, sol, self.tolerance,
                               self.max_iterations)
            self.last_iterations, self.last_residual = it, res
        _scatter_rot(sol, self.st, self.sr, self.pt, self.pr, v, w, vp, wp)
        _bond_impulses_rot(bi, bj, frame, arm_i, arm_j, c0, cg, broken, v, w, vp, wp, impulse)

    def solve(self, v_free, vp_free, bi, bj, frame, c0, cg, broken, v, vp, impulse,
              v_start=None, vp_start=None):
        """Velocities at the end of the step (written into v (N,3), vp (P,3): unknown rows
        only; known rows must already hold the imposed velocities) and bond impulses
        impulse (B,3) in the local frames. v_start, vp_start: initial guess of ``cg``
        (default: the free velocities)."""
        if v_start is None:
            v_start, vp_start = v_free, vp_free
        rhs = np.zeros(self.ndof)
        _rhs(rhs, self.sph, self.pl, self.mass_dof, v_free, vp_free, v, vp, bi, bj, frame, c0,
             cg, broken)
        if self.method == "direct":
            sol = self.lu.solve(rhs) if self.ndof else rhs
        else:
            sol = np.zeros(self.ndof)
            _gather(sol, self.sph, self.pl, v_start, vp_start)
            it, res = _pcg(self.mass_dof, self.normal, self.g_t, self.g_nt, self.di, self.dj,
                           self.precond, rhs, sol, self.tolerance, self.max_iterations)
            self.last_iterations, self.last_residual = it, res
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
        if di >= 0 and dj >= 0:  # both velocities unknown: q = F^T c0
            for d in range(3):
                q[d] = frame[b, 0, d] * c0[b, 0] + frame[b, 1, d] * c0[b, 1] \
                    + frame[b, 2, d] * c0[b, 2]
                rhs[3 * di + d] += q[d]
                rhs[3 * dj + d] -= q[d]
            continue
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


@njit(cache=True)
def _gather(x, sph, pl, v, vp):
    for s in range(len(sph)):
        if sph[s] >= 0:
            for d in range(3):
                x[3 * sph[s] + d] = v[s, d]
    for k in range(len(pl)):
        if pl[k] >= 0:
            for d in range(3):
                x[3 * pl[k] + d] = vp[k, d]


@njit(cache=True)
def _matvec(mass_dof, normal, g_t, g_nt, di, dj, x, y):
    """y = (M + sum_b H_b G_b H_b^T) x, matrix-free over the intact bonds, with
    G_b = g_t I + g_nt n n^T (normal (B,3), g_t, g_nt (B,))."""
    for r in range(len(x)):
        y[r] = mass_dof[r] * x[r]
    for b in range(len(di)):
        a = di[b]
        c = dj[b]
        if a >= 0 and c >= 0:
            u0 = x[3 * a] - x[3 * c]
            u1 = x[3 * a + 1] - x[3 * c + 1]
            u2 = x[3 * a + 2] - x[3 * c + 2]
        elif a >= 0:
            u0 = x[3 * a]
            u1 = x[3 * a + 1]
            u2 = x[3 * a + 2]
        elif c >= 0:
            u0 = -x[3 * c]
            u1 = -x[3 * c + 1]
            u2 = -x[3 * c + 2]
        else:  # both velocities imposed: no unknown
            continue
        n0 = normal[b, 0]
        n1 = normal[b, 1]
        n2 = normal[b, 2]
        s = g_nt[b] * (n0 * u0 + n1 * u1 + n2 * u2)
        gt = g_t[b]
        f0 = gt * u0 + s * n0
        f1 = gt * u1 + s * n1
        f2 = gt * u2 + s * n2
        if a >= 0:
            y[3 * a] += f0
            y[3 * a + 1] += f1
            y[3 * a + 2] += f2
        if c >= 0:
            y[3 * c] -= f0
            y[3 * c + 1] -= f1
            y[3 * c + 2] -= f2


@njit(cache=True)
def _precondition(precond, r, z):
    for k in range(precond.shape[0]):
        for d in range(3):
            z[3 * k + d] = (precond[k, d, 0] * r[3 * k] + precond[k, d, 1] * r[3 * k + 1]
                            + precond[k, d, 2] * r[3 * k + 2])


@njit(cache=True)
def _pcg(mass_dof, normal, g_t, g_nt, di, dj, precond, rhs, x, tol, max_iter):
    """Preconditioned conjugate gradient on (M + sum H G H^T) x = rhs, x holding the initial
    guess; stops when |r| <= tol |rhs|. Returns (iterations, relative residual)."""
    n = len(rhs)
    r = np.empty(n)
    z = np.empty(n)
    q = np.empty(n)
    _matvec(mass_dof, normal, g_t, g_nt, di, dj, x, q)
    norm_b = 0.0
    for k in range(n):
        r[k] = rhs[k] - q[k]
        norm_b += rhs[k] * rhs[k]
    norm_b = np.sqrt(norm_b)
    if norm_b == 0.0:
        for k in range(n):
            x[k] = 0.0
        return 0, 0.0
    _precondition(precond, r, z)
    p = z.copy()
    rz = 0.0
    rr = 0.0
    for k in range(n):
        rz += r[k] * z[k]
        rr += r[k] * r[k]
    it = 0
    while np.sqrt(rr) > tol * norm_b and it < max_iter:
        it += 1
        _matvec(mass_dof, normal, g_t, g_nt, di, dj, p, q)
        pq = 0.0
        for k in range(n):
            pq += p[k] * q[k]
        alpha = rz / pq
        rr = 0.0
        rz_new = 0.0
        for blk in range(n // 3):  # fused: update, block-Jacobi preconditioner, dot products
            b3 = 3 * blk
            for d in range(3):
                x[b3 + d] += alpha * p[b3 + d]
                r[b3 + d] -= alpha * q[b3 + d]
            for d in range(3):
                z[b3 + d] = (precond[blk, d, 0] * r[b3] + precond[blk, d, 1] * r[b3 + 1]
                             + precond[blk, d, 2] * r[b3 + 2])
                rr += r[b3 + d] * r[b3 + d]
                rz_new += r[b3 + d] * z[b3 + d]
        beta = rz_new / rz
        rz = rz_new
        for k in range(n):
            p[k] = z[k] + beta * p[k]
    return it, np.sqrt(rr) / norm_b


# ---------------------------------------------------------------- 'contact' kinematics
@njit(cache=True)
def _gather_rot(x, st, sr, pt, pr, v, w, vp, wp):
    """x[block] <- the body velocities of the unknown blocks."""
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


@njit(cache=True)
def _scatter_rot(x, st, sr, pt, pr, v, w, vp, wp):
    """Body velocities of the unknown blocks <- x."""
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


@njit(cache=True)
def _blocks_of(b, bi, bj, st, sr, pt, pr):
    i = bi[b]
    j = bj[b]
    if j >= 0:
        return st[i], sr[i], st[j], sr[j]
    return st[i], sr[i], pt[-1 - j], pr[-1 - j]


@njit(cache=True)
def _rhs_rot(rhs, st, sr, pt, pr, v, w, vp, wp, bi, bj, frame, arm_i, arm_j, c0, cg, broken):
    """rhs += sum_b L_b^T q_b, q_b = F^T (c0 - cg F U_known) (U_known: the bond velocity
    from the known (imposed) blocks only)."""
    for b in range(len(bi)):
        if broken[b]:
            continue
        i = bi[b]
        j = bj[b]
        ti, ri, tj, rj = _blocks_of(b, bi, bj, st, sr, pt, pr)
        u0 = 0.0
        u1 = 0.0
        u2 = 0.0
        if ti < 0:
            u0 += v[i, 0]
            u1 += v[i, 1]
            u2 += v[i, 2]
        if ri < 0:
            u0 += w[i, 1] * arm_i[b, 2] - w[i, 2] * arm_i[b, 1]
            u1 += w[i, 2] * arm_i[b, 0] - w[i, 0] * arm_i[b, 2]
            u2 += w[i, 0] * arm_i[b, 1] - w[i, 1] * arm_i[b, 0]
        if j >= 0:
            vj0, vj1, vj2 = v[j, 0], v[j, 1], v[j, 2]
            wj0, wj1, wj2 = w[j, 0], w[j, 1], w[j, 2]
        else:
            vj0, vj1, vj2 = vp[-1 - j, 0], vp[-1 - j, 1], vp[-1 - j, 2]
            wj0, wj1, wj2 = wp[-1 - j, 0], wp[-1 - j, 1], wp[-1 - j, 2]
        if tj < 0:
            u0 -= vj0
            u1 -= vj1
            u2 -= vj2
        if rj < 0:
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
        _add_force(rhs, ti, ri, arm_i[b, 0], arm_i[b, 1], arm_i[b, 2], q0, q1, q2, 1.0)
        _add_force(rhs, tj, rj, arm_j[b, 0], arm_j[b, 1], arm_j[b, 2], q0, q1, q2, -1.0)


@njit(cache=True, inline="always")
def _add_force(y, t, r, a0, a1, a2, f0, f1, f2, sign):
    """y[t] += sign f, y[r] += sign a x f (blocks of 3; -1 = known, skipped)."""
    if t >= 0:
        y[3 * t] += sign * f0
        y[3 * t + 1] += sign * f1
        y[3 * t + 2] += sign * f2
    if r >= 0:
        y[3 * r] += sign * (a1 * f2 - a2 * f1)
        y[3 * r + 1] += sign * (a2 * f0 - a0 * f2)
        y[3 * r + 2] += sign * (a0 * f1 - a1 * f0)


@njit(cache=True)
def _matvec_rot(mass_dof, normal, g_t, g_nt, blk, arm_i, arm_j, x, y):
    """y = (M + sum_b L_b^T G_b L_b) x over the intact bonds (blk (B,4): translation and
    rotation blocks of i, then of j; G_b = g_t I + g_nt n n^T)."""
    for r in range(len(x)):
        y[r] = mass_dof[r] * x[r]
    for b in range(blk.shape[0]):
        ti = blk[b, 0]
        ri = blk[b, 1]
        tj = blk[b, 2]
        rj = blk[b, 3]
        u0 = 0.0
        u1 = 0.0
        u2 = 0.0
        if ti >= 0:
            u0 += x[3 * ti]
            u1 += x[3 * ti + 1]
            u2 += x[3 * ti + 2]
        if ri >= 0:
            w0 = x[3 * ri]
            w1 = x[3 * ri + 1]
            w2 = x[3 * ri + 2]
            u0 += w1 * arm_i[b, 2] - w2 * arm_i[b, 1]
            u1 += w2 * arm_i[b, 0] - w0 * arm_i[b, 2]
            u2 += w0 * arm_i[b, 1] - w1 * arm_i[b, 0]
        if tj >= 0:
            u0 -= x[3 * tj]
            u1 -= x[3 * tj + 1]
            u2 -= x[3 * tj + 2]
        if rj >= 0:
            w0 = x[3 * rj]
            w1 = x[3 * rj + 1]
            w2 = x[3 * rj + 2]
            u0 -= w1 * arm_j[b, 2] - w2 * arm_j[b, 1]
            u1 -= w2 * arm_j[b, 0] - w0 * arm_j[b, 2]
            u2 -= w0 * arm_j[b, 1] - w1 * arm_j[b, 0]
        n0 = normal[b, 0]
        n1 = normal[b, 1]
        n2 = normal[b, 2]
        s = g_nt[b] * (n0 * u0 + n1 * u1 + n2 * u2)
        gt = g_t[b]
        f0 = gt * u0 + s * n0
        f1 = gt * u1 + s * n1
        f2 = gt * u2 + s * n2
        _add_force(y, ti, ri, arm_i[b, 0], arm_i[b, 1], arm_i[b, 2], f0, f1, f2, 1.0)
        _add_force(y, tj, rj, arm_j[b, 0], arm_j[b, 1], arm_j[b, 2], f0, f1, f2, -1.0)


@njit(cache=True)
def _pcg_rot(mass_dof, normal, g_t, g_nt, blk, arm_i, arm_j, precond, rhs, x, tol, max_iter):
    """Block-Jacobi preconditioned CG of the 'contact' system; x holds the initial guess.
    Returns (iterations, relative residual)."""
    n = len(rhs)
    r = np.empty(n)
    z = np.empty(n)
    q = np.empty(n)
    _matvec_rot(mass_dof, normal, g_t, g_nt, blk, arm_i, arm_j, x, q)
    norm_b = 0.0
    for k in range(n):
        r[k] = rhs[k] - q[k]
        norm_b += rhs[k] * rhs[k]
    norm_b = np.sqrt(norm_b)
    if norm_b == 0.0:
        for k in range(n):
            x[k] = 0.0
        return 0, 0.0
    _precondition(precond, r, z)
    p = z.copy()
    rz = 0.0
    rr = 0.0
    for k in range(n):
        rz += r[k] * z[k]
        rr += r[k] * r[k]
    it = 0
    while np.sqrt(rr) > tol * norm_b and it < max_iter:
        it += 1
        _matvec_rot(mass_dof, normal, g_t, g_nt, blk, arm_i, arm_j, p, q)
        pq = 0.0
        for k in range(n):
            pq += p[k] * q[k]
        alpha = rz / pq
        for k in range(n):
            x[k] += alpha * p[k]
            r[k] -= alpha * q[k]
        _precondition(precond, r, z)
        rr = 0.0
        rz_new = 0.0
        for k in range(n):
            rr += r[k] * r[k]
            rz_new += r[k] * z[k]
        beta = rz_new / rz
        rz = rz_new
        for k in range(n):
            p[k] = z[k] + beta * p[k]
    return it, np.sqrt(rr) / norm_b


@njit(cache=True)
def _bond_impulses_rot(bi, bj, frame, arm_i, arm_j, c0, cg, broken, v, w, vp, wp, impulse):
    for b in range(len(bi)):
        if broken[b]:
            continue
        g0, g1, g2 = bond_velocity(b, bi, bj, arm_i, arm_j, v, w, vp, wp, True)
        for c in range(3):
            ul = frame[b, c, 0] * g0 + frame[b, c, 1] * g1 + frame[b, c, 2] * g2
            impulse[b, c] = c0[b, c] - cg[b, c] * ul
