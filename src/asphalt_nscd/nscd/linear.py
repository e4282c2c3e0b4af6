"""Fast path: a step of a bonded network without active contacts is a linear system.

With no contact reaction and no breakage, every bond obeys the affine law P_b = c0_b -
G_b U_b (local_laws.py; G_b = F_b^T diag(c_g) F_b, constant for a given dt, theta and bond
parameters) with U_b = L_b x its relative velocity. Eliminating the impulses gives, on the
unknown velocities x,

    (M + sum_b L_b^T G_b L_b) x = M x_free + sum_b L_b^T q_b,

q_b = F_b^T (c0_b - diag(c_g) F_b U_b,known) (U_b,known: the part of the bond velocity
from known velocities: fixed spheres, fixed or driven plates). The matrix is symmetric
positive definite and constant while the set of intact bonds does not change.

Unknowns and kinematics (one code path for both): the unknowns are 3-dof blocks, numbered
body by body, a body's translation block followed by its rotation block. With
'barycentre' bond kinematics the rotations are not coupled by bonds (no torque) and only
translation blocks exist (mobile spheres, free plates), L_b = [I, -I]. With 'contact'
(state.Bonds) the bond velocity is taken at the contact point with the lever arms a_i,
a_j: L_b = [I, -[a_i]x] on the candidate's (translation, rotation) and [-I, +[a_j]x] on the
antagonist's; a mobile sphere has 6 dof, a free plate 3 more, a rotating plate's rotation
3 (its translation may be imposed). M holds the masses and rotational inertias.

Solvers:

* ``cg`` (default): matrix-free preconditioned conjugate gradient (:func:`_pcg`), stopped
  at a relative residual |r| <= ``linear_tolerance`` |rhs|. Per iteration one pass over the
  bonds (:func:`_matvec`, which also returns p.Kp and applies the previous updates of x and
  p, so that p is read once) and one fused pass over the vectors (update of r,
  preconditioner, dot products). The bond blocks
  are stored compactly, G_b = c_t I + (c_n - c_t) n n^T (the two tangential coefficients of
  a bond are equal, local_laws.py): n, c_t, c_n - c_t and the lever arms packed in one
  array; the arms of sphere-sphere bonds lie along n (state.Bonds.create) and are stored
  as two numbers (7 per bond instead of 11, and fewer operations: w x a = al (w x n),
  a x f = al c_t (n x u)); other bonds (sphere-plate) keep their full arms.
  Preconditioner: block Jacobi on the 3x3 diagonal blocks (translation or rotation of a
  body), inverted once per matrix.
  Initial guess: the caller's (moreau_jean.py: linear extrapolation in time of the body
  velocities). The matrix is mass-dominated at the paper's time step (h² theta² K_bond ~
  m), so CG converges in a few tens of iterations (about 25 at N = 12 000 and relative
  residual 1e-7). Tried without gain (same iteration count, bench at N = 12 000): the
  A-norm projection on the span of the last 4 solutions as initial guess (it contains the
  linear and quadratic extrapolations), and 6x6 blocks (a sphere's translation and
  rotation together: 25.0 instead of 25.4 iterations, a dearer preconditioner).
* ``cg_ssor``: the same conjugate gradient preconditioned by symmetric successive
  over-relaxation on the body blocks (SSOR, NSCDParameters.linear_ssor_omega, default 1.2;
  a sphere's translation and rotation together, up to 6x6, :func:`ssor_structure`),
  M = (D/w + L) (D/w)^-1 (D/w + U), run in Eisenstat's form (:func:`_pcg_ssor`): the
  preconditioned product costs one backward and one forward triangular solve, each a pass
  over the bonds (half the work of a product with A each: one side of the bond), and no
  product with A. The entries of the triangular solves between two 6-dof spheres (3-dof
  with 'barycentre') with arms along the normal are stored compactly (7 numbers and one
  index, :func:`_split_compact`), the others in the general 11-number form. Stopping test
  on the preconditioned residual (free), which must fall by the factor by which the true
  residual must fall (tol |rhs| / |r0|), confirmed by the true residual
  |rhs - A x| <= tol |rhs| (one product; continued with a tighter factor if not met).
  Initial guess: the Galerkin (A-norm optimal) combination of the velocity fields at the
  start of the step and up to three steps earlier (``previous`` of
  :meth:`LinearBondSolver.solve`; it contains the linear extrapolation, and a sinusoid plus
  a linear trend exactly: the periodic start under gravity), whose products with A are
  those the solver computed for its last solutions (the confirming product above): the
  guess costs one pass over a few vectors and no pass over the bonds. In the periodic steady state of
  the bench sample (``bench --start periodic``) it leaves a residual of about 4e-7 |rhs|
  against 1.6e-4 for the extrapolation: 1.6 iterations per step instead of 5 (and 12 for
  ``cg``). From rest (the transient of a sudden start, gravity on) the residual of any
  combination of past velocities stays at 20-50 % of |rhs| (the right-hand side is not
  predictable from them) and SSOR needs about 10 iterations against 26 for ``cg``.
  Sequential only (``threads`` ignored). Measured numbers: docs/choices.md.
* ``direct``: SuperLU factorisation once per (dt, theta, intact-bond set)
  (:func:`splu_symmetric`: symmetric mode, no pivoting, MMD ordering of A^T + A, the
  setting of harmonic/solver.py), two triangular solves per step, exact to round-off.
  At N = 12 000 (36 000 dofs, 79 000 bonds, 'barycentre') the factorisation takes about
  5 s and the factor holds 2.9e7 entries: a solve (~0.07 s) is slower than ``cg``, which
  remains the default; ``direct`` is the reference.

Validity is checked after the solve by the caller (moreau_jean.py): every contact candidate
must satisfy U_n + max(g, 0)/h >= 0 with zero reaction, and no bond may exceed R_crit;
otherwise the step is redone by NLGS -- unless at most ``NSCDParameters.fast_path_contacts``
contacts close, which are then solved on their Delassus operator condensed over the bonds
(condensed.py, with the columns of A^-1 of :meth:`LinearBondSolver.response`). The test tests/unit/test_nscd_linear.py checks that
both paths give the same reactions to the NLGS tolerance.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit, prange
from scipy.sparse.linalg import splu

from ._jit import helper, kernel
from .local_laws import bond_velocity


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


#: Methods of :class:`LinearBondSolver` (and values of NSCDParameters.linear_solver).
LINEAR_SOLVERS = ("cg", "cg_ssor", "direct")
_SSOR_KEYS = ("bfirst", "bcount", "Dinv", "lcptr", "lcidx", "lcdat", "lptr", "lidx", "ldat",
              "ucptr", "ucidx", "ucdat", "uptr", "uidx", "udat")


def skew(a):
    """Cross-product matrices (B,3,3) of vectors a (B,3): skew(a) @ x = a x x."""
    z = np.zeros(len(a))
    return np.stack([np.stack([z, -a[:, 2], a[:, 1]], 1), np.stack([a[:, 2], z, -a[:, 0]], 1),
                     np.stack([-a[:, 1], a[:, 0], z], 1)], 1)


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


class LinearBondSolver:
    """The linear system of the bonded network for one (dt, theta, intact-bond set).

    Parameters
    ----------
    inv_mass, inv_mass_plate : (N,), (P,) 1/kg (0 = immobile).
    bi, bj, frame, cg : bonds (B,), (B,3,3), (B,3) N s/m; broken : (B,) bool.
    method : 'cg' or 'direct' (module docstring); tolerance : relative residual of 'cg';
    max_iterations : of 'cg'.
    threads : > 1: the conjugate gradient runs on that many numba threads (bonds ordered
        by partitions of the unknowns, :func:`_partition`); 1: sequential kernels.
    rotation : dict or None — for the 'contact' kinematics: ``arm_i``, ``arm_j`` (B,3) m,
        ``inv_inertia`` (N,) and ``inv_inertia_plate`` (P,3) 1/(kg m²) (0 = no rotation).
        None: 'barycentre' kinematics (translations only).

    Raises
    ------
    ValueError for an unknown method, or unequal tangential bond coefficients
    ('cg').
    """

    def __init__(self, inv_mass, inv_mass_plate, bi, bj, frame, cg, broken, method="cg",
                 tolerance=1e-10, max_iterations=10000, rotation=None, threads=1,
                 ssor_omega=1.0):
        if method not in LINEAR_SOLVERS:
            raise ValueError(f"linear solver must be one of {LINEAR_SOLVERS}, got {method!r}")
        if not 0.0 < ssor_omega < 2.0:
            raise ValueError(f"ssor_omega must lie in (0, 2), got {ssor_omega!r}")
        self.method = method
        self.ssor_omega = float(ssor_omega)
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        self.last_iterations = 0
        self.last_residual = 0.0
        self.rot = rotation is not None
        self._columns = {}  # unknown block -> (ndof, 3) columns of A^-1 (:meth:`response`)
        nb = len(bi)
        if self.rot:
            arm_i, arm_j = rotation["arm_i"], rotation["arm_j"]
            st, sr, pt, pr, m3 = dof_numbering(inv_mass, inv_mass_plate,
                                               rotation["inv_inertia"],
                                               rotation["inv_inertia_plate"])
        else:
            arm_i = arm_j = np.zeros((nb, 3))
            st, sr, pt, pr, m3 = dof_numbering(inv_mass, inv_mass_plate)
        self.st, self.sr, self.pt, self.pr = st, sr, pt, pr
        nblk = len(m3)
        self.ndof = 3 * nblk
        self.mass_dof = np.ascontiguousarray(m3.ravel())
        keep = ~np.asarray(broken, bool)
        jj = bj[keep]
        sph = jj >= 0
        kk = np.where(sph, 0, -1 - jj)
        js = np.where(sph, jj, 0)
        ti = st[bi[keep]]
        ri = sr[bi[keep]]
        tj = np.where(sph, st[js], pt[kk] if len(pt) else -1)
        rj = np.where(sph, sr[js], pr[kk] if len(pr) else -1)
        self.blk = np.ascontiguousarray(np.stack([ti, ri, tj, rj], 1).astype(np.int64))
        cgk = cg[keep]
        G = np.einsum("bci,bc,bcj->bij", frame[keep], cgk, frame[keep])
        eye = np.broadcast_to(np.eye(3), G.shape)
        L = [eye, -skew(arm_i[keep]), -eye, skew(arm_j[keep])]  # U_b = sum_c L[c] x_blk[c]
        self.nnz_factor = 0
        self.lu = None
        if method in ("cg", "cg_ssor"):
            if not np.array_equal(cgk[:, 1], cgk[:, 2]):
                raise ValueError("the two tangential bond coefficients must be equal")
            nrm = frame[keep, 0, :]
            gcol = [cgk[:, 1:2], (cgk[:, 0] - cgk[:, 1])[:, None]]
            ai, aj = arm_i[keep], arm_j[keep]
            al_i = np.einsum("bd,bd->b", ai, nrm)
            al_j = np.einsum("bd,bd->b", aj, nrm)
            # lever arms along the normal (sphere-sphere bonds of state.Bonds.create, up to
            # round-off) are stored as their two components: the compact kernel branch
            par = (np.abs(ai - al_i[:, None] * nrm).max(1) <= 1e-12 * np.abs(ai).max(1)) \
                & (np.abs(aj - al_j[:, None] * nrm).max(1) <= 1e-12 * np.abs(aj).max(1))
            if not self.rot:
                par[:] = True
                al_i[:] = 0.0
                al_j[:] = 0.0
            order, self.part_c, self.part_g = _partition(self.blk, par, nblk, int(threads))
            par = par[order]
            self.blk = self.blk[order]
            G, L = G[order], [x[order] for x in L]
            nrm, ai, aj, al_i, al_j = nrm[order], ai[order], aj[order], al_i[order], al_j[order]
            gcol = [g[order] for g in gcol]
            self.blk_c = np.ascontiguousarray(self.blk[par].astype(np.int32))
            arms_c = [al_i[par, None], al_j[par, None]] if self.rot else []  # unread without
            self.bdat_c = np.ascontiguousarray(np.concatenate(  # rotation blocks
                [nrm[par]] + [g[par] for g in gcol] + arms_c, 1))
            self.blk_g = np.ascontiguousarray(self.blk[~par].astype(np.int32))
            self.bdat_g = np.ascontiguousarray(np.concatenate(
                [nrm[~par]] + [g[~par] for g in gcol] + [ai[~par], aj[~par]], 1))
            self._init_precond(m3, L, G)
            self.nnz_matrix = self.ndof + (144 if self.rot else 36) * len(G)
            self._work = np.zeros((4, self.ndof))
            if method == "cg_ssor":
                bdat_all = np.concatenate([nrm] + gcol + [ai, aj], 1)
                ss = ssor_structure(st, sr, pt, pr, m3, self.blk, L, G, bdat_all,
                                    self.ssor_omega)
                self._ssor = tuple(ss[k] for k in _SSOR_KEYS)
                self._work = np.zeros((9, self.ndof))
                # products with A of the last solutions (x, A x), most recent first: the
                # initial guess of the next solve is their Galerkin combination
                self._cache = []
                self._spare = [np.zeros(self.ndof) for _ in range(2)]
                self._basis = np.zeros((4, self.ndof))
                self._abasis = np.zeros((4, self.ndof))
                self.last_checks = 0
                self.last_extrapolated = False
                self.last_reused = 0
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

    def _init_precond(self, m3, L, G):
        """Inverses (nblk, 3, 3) of the diagonal 3x3 blocks of the matrix."""
        blocks = np.zeros((len(m3), 3, 3))
        blocks[:, [0, 1, 2], [0, 1, 2]] = m3
        for c in range(4):
            ok = self.blk[:, c] >= 0
            Lc = L[c][ok]
            np.add.at(blocks, self.blk[ok, c], np.einsum("bki,bkl,blj->bij", Lc, G[ok], Lc))
        self.precond = np.ascontiguousarray(np.linalg.inv(blocks)) if len(m3) else blocks

    def solve(self, v_free, w_free, vp_free, wp_free, bi, bj, frame, arm_i, arm_j, c0, cg,
              broken, v, w, vp, wp, impulse, start=None, previous=None):
        """End-of-step velocities and bond impulses.

        Parameters
        ----------
        v_free, w_free (N,3), vp_free, wp_free (P,3): free velocities m/s, rad/s (with
        'barycentre' the angular ones are not used); bonds (B,...) as in state.Bonds; c0
        (B,3) N s, cg (B,3) N s/m (local_laws.bond_predict).
        v, w, vp, wp: outputs, unknown rows written; known rows must hold the imposed
        values. impulse (B,3) N s: output, local frames.
        start: (v, w, vp, wp) initial guess of ``cg`` (default: the free velocities).
        previous: ``cg_ssor`` only — ((v, w, vp, wp) at the start of the step, the same one
            step earlier), or None. The initial guess is then the Galerkin (A-norm optimal)
            combination of these two velocity fields (:meth:`_galerkin_start`), which
            contains the linear extrapolation ``start``; ``start`` is used without them.
        """
        rhs = np.empty(self.ndof)
        _rhs(rhs, self.mass_dof, self.st, self.sr, self.pt, self.pr, v_free, w_free, vp_free,
             wp_free, v, w, vp, wp, bi, bj, frame, arm_i, arm_j, c0, cg, broken, self.rot)
        if self.method == "direct":
            sol = self.lu.solve(rhs) if self.ndof else rhs
        elif self.method == "cg_ssor":
            sol, ax = self._spare
            have = previous is not None and self._galerkin_start(previous, rhs, sol, ax)
            if not have:
                _gather(sol, self.st, self.sr, self.pt, self.pr,
                        *(start or (v_free, w_free, vp_free, wp_free)))
            it, res, checks = _pcg_ssor(
                self.mass_dof, self.bdat_c, self.blk_c, self.bdat_g, self.blk_g, *self._ssor,
                rhs, sol, self.tolerance, self.max_iterations, self._work, self.ssor_omega,
                ax, have)
            self.last_checks = checks
            self.last_extrapolated = bool(have)
            self.last_iterations, self.last_residual = it, res
            # (sol, A sol) becomes the most recent cached pair; the oldest pair is recycled
            self._cache.insert(0, (sol, ax))
            self._spare = list(self._cache.pop()) if len(self._cache) > 4 else \
                [np.zeros(self.ndof), np.zeros(self.ndof)]
        else:
            sol = np.empty(self.ndof)
            _gather(sol, self.st, self.sr, self.pt, self.pr,
                    *(start or (v_free, w_free, vp_free, wp_free)))
            it, res = self._run_cg(rhs, sol, self._work)
            self.last_iterations, self.last_residual = it, res
        _scatter(sol, self.st, self.sr, self.pt, self.pr, v, w, vp, wp)
        bond_impulses(bi, bj, frame, arm_i, arm_j, c0, cg, broken, v, w, vp, wp, impulse,
                       self.rot)

    def _run_cg(self, rhs, x, work):
        """:func:`_pcg` on this operator, or :func:`_pcg_threaded` with threads > 1."""
        args = (self.mass_dof, self.bdat_c, self.blk_c, self.bdat_g, self.blk_g, self.precond, rhs, x,
                self.tolerance, self.max_iterations, work)
        if len(self.part_c):
            return _pcg_threaded(*args, self.part_c, self.part_g)
        return _pcg(*args)

    def gather(self, v, w, vp, wp):
        """The unknowns x (ndof,) of body velocities v, w (N,3), vp, wp (P,3)."""
        x = np.empty(self.ndof)
        _gather(x, self.st, self.sr, self.pt, self.pr, v, w, vp, wp)
        return x

    def scatter(self, x, v, w, vp, wp):
        """Write the unknowns x (ndof,) into the body velocities (known rows untouched)."""
        _scatter(x, self.st, self.sr, self.pt, self.pr, v, w, vp, wp)

    def response(self, block):
        """Columns (ndof, 3) of A^-1 for the unknown 3-dof block ``block``: the velocity
        response of the bonded network to a unit impulse (N s, or N m s on a rotation
        block) along each axis of that block. Solved on first use with this solver's method
        and tolerance from a zero initial guess (so the same numbers whenever it is asked)
        and cached: A is constant for a solver. Used by the contacts of the fast path
        (:mod:`.condensed`).

        Raises
        ------
        IndexError if ``block`` is not an unknown block (0 <= block < ndof / 3).
        """
        col = self._columns.get(block)
        if col is not None:
            return col
        if not 0 <= block < self.ndof // 3:
            raise IndexError(f"unknown block {block} outside [0, {self.ndof // 3})")
        col = np.zeros((self.ndof, 3))
        for d in range(3):
            rhs = np.zeros(self.ndof)
            rhs[3 * block + d] = 1.0
            if self.method == "direct":
                col[:, d] = self.lu.solve(rhs)
                continue
            x = col[:, d].copy()
            if self.method == "cg_ssor":
                _pcg_ssor(self.mass_dof, self.bdat_c, self.blk_c, self.bdat_g, self.blk_g,
                          *self._ssor, rhs, x, self.tolerance, self.max_iterations,
                          np.zeros((9, self.ndof)), self.ssor_omega, np.zeros(self.ndof),
                          False)
            else:
                self._run_cg(rhs, x, np.zeros((4, self.ndof)))
            col[:, d] = x
        self._columns[block] = col
        return col

    def _product(self, x):
        """A x (n,) of a vector: the cached product of an equal (bit for bit) recent
        solution, else one matrix-free product. The cached product is itself the product
        computed from that solution (:func:`_pcg_ssor`), so either way the result is the
        same numbers (a resumed run reproduces the uninterrupted one)."""
        for xc, axc in self._cache:
            if np.array_equal(xc, x):
                self.last_reused += 1
                return axc
        ax = np.zeros(self.ndof)
        _matvec(self.mass_dof, self.bdat_c, self.blk_c, self.bdat_g, self.blk_g, x, 0.0,
                np.zeros(self.ndof), ax, 0.0, np.zeros(self.ndof))
        return ax

    def _galerkin_start(self, previous, rhs, x0, ax0):
        """Initial guess x0 (and ax0 = A x0) minimising the A-norm of the error over the span
        of the velocity fields of ``previous`` (x_n, x_n-1 and, when given, x_n-2, x_n-3; the
        linear extrapolation 2 x_n - x_n-1 of moreau_jean.py lies in it, so the guess is never
        worse in that norm), in the better-conditioned basis of the successive backward
        differences u1 = x_n, u2 = x_n - x_n-1, u3 = x_n - 2 x_n-1 + x_n-2, u4 = the third
        difference: x0 = U c, G c = U^T rhs with G = U^T A U. Four fields hold a sinusoid
        plus a linear trend exactly (the recurrence of the roots exp(+-i w h), 1, 1): the
        velocities after a periodic start with a steady creep under gravity (constant) and
        the mechanisms falling under their weight (a ramp). The products A x are those of
        the last solutions (:meth:`_product`):
        no pass over the bonds when the previous steps were solved here. Basis vectors that
        add nothing (relative pivot below 1e-12) are dropped. Returns False (x0, ax0 unset)
        when the span is empty (at rest)."""
        self.last_reused = 0
        m = min(len(previous), 4)
        x = self._basis[:m]
        for k in range(m):
            _gather(x[k], self.st, self.sr, self.pt, self.pr, *previous[k])
        ax = self._abasis[:m]
        for k in range(m):
            ax[k] = self._product(x[k])
        diff = np.array([[1.0, 0.0, 0.0, 0.0], [1.0, -1.0, 0.0, 0.0], [1.0, -2.0, 1.0, 0.0],
                         [1.0, -3.0, 3.0, -1.0]])[:m, :m]
        G, b = np.zeros((m, m)), np.zeros(m)
        _galerkin_gram(x, ax, rhs, diff, G, b, np.zeros(m), np.zeros(m))
        if not G[0, 0] > 0.0:
            return False
        keep = 1
        for k in range(1, m):  # Cholesky-like pivot test: drop what the span already holds
            sub = G[:k + 1, :k + 1]
            if np.linalg.eigvalsh(sub).min() > 1e-12 * np.abs(np.diag(sub)).max():
                keep = k + 1
            else:
                break
        c = np.linalg.solve(G[:keep, :keep], b[:keep])
        coef = c @ diff[:keep]  # coefficients of x_n, x_n-1, ...
        _galerkin_combine(np.pad(coef, (0, 4 - coef.size)), x, ax, m, x0, ax0)
        return True


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


@kernel
def _gather(x, st, sr, pt, pr, v, w, vp, wp):
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


@kernel
def _scatter(x, st, sr, pt, pr, v, w, vp, wp):
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
def _rhs(rhs, mass_dof, st, sr, pt, pr, v_free, w_free, vp_free, wp_free, v, w, vp, wp, bi,
         bj, frame, arm_i, arm_j, c0, cg, broken, rot):
    """rhs = M x_free + sum_b L_b^T q_b, q_b = F^T (c0 - cg F U_known) (U_known: the bond
    velocity from the known blocks only; rotations enter only when rot)."""
    _gather(rhs, st, sr, pt, pr, v_free, w_free, vp_free, wp_free)
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
def _matvec_par(mass_dof, bdat_c, blk_c, bdat, blk, part_c, part_g, z, beta, p, y, alpha,
                x):
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
        py += _bonds(part_c[t], part_c[t + 1], bdat_c, blk_c, part_g[t], part_g[t + 1], bdat,
                     blk, p, y)
    return py + _bonds(part_c[nt], part_c[nt + 1], bdat_c, blk_c, part_g[nt], part_g[nt + 1],
                       bdat, blk, p, y)


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
def _pcg(mass_dof, bdat_c, blk_c, bdat_g, blk_g, precond, rhs, x, tol, max_iter, work):
    """Block-Jacobi preconditioned conjugate gradient on (M + sum L^T G L) x = rhs, x
    holding the initial guess; stops when |r| <= tol |rhs|. work (4, n): r (final residual
    on return), z, p, q. Sequential kernels only (the threaded variant is
    :func:`_pcg_threaded`). Returns (iterations, relative residual)."""
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


def _pcg_threaded(mass_dof, bdat_c, blk_c, bdat_g, blk_g, precond, rhs, x, tol, max_iter,
                  work, part_c, part_g):
    """:func:`_pcg` on threads (same arguments, plus the bond partitions part_c, part_g of
    :func:`_partition`): the iteration loop runs in Python around the threaded kernels
    :func:`_matvec_par` and :func:`_update_par`.

    Why not one compiled loop: a cached compiled function calling a cached
    ``parallel=True`` one can segfault when loaded from numba's cache, most reliably when
    several processes filled the cache at once (github.com/numba/numba/issues/4807, /8578).
    The Python loop costs a few microseconds per iteration against milliseconds of
    threaded work."""
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
        pq = _matvec_par(mass_dof, bdat_c, blk_c, bdat_g, blk_g, part_c, part_g, z, beta, p,
                         q, alpha, x)
        alpha = rz / pq
        rr, rz_new = _update_par(precond, alpha, q, r, z)
        beta = rz_new / rz
        rz = rz_new
    x += alpha * p
    return it, float(np.sqrt(rr)) / norm_b


@kernel
def bond_impulses(bi, bj, frame, arm_i, arm_j, c0, cg, broken, v, w, vp, wp, impulse, rot):
    """impulse (B,3) = c0 - cg F U of the intact bonds (U: local_laws.bond_velocity)."""
    for b in range(len(bi)):
        if broken[b]:
            continue
        g0, g1, g2 = bond_velocity(b, bi, bj, arm_i, arm_j, v, w, vp, wp, rot)
        for c in range(3):
            ul = frame[b, c, 0] * g0 + frame[b, c, 1] * g1 + frame[b, c, 2] * g2
            impulse[b, c] = c0[b, c] - cg[b, c] * ul


# --------------------------------------------------------------------------------------
# Symmetric Gauss-Seidel (SSOR, omega = 1) preconditioner on body blocks, Eisenstat's trick
# --------------------------------------------------------------------------------------
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
        body_of[bfirst[k]:bfirst[k] + bcount[k]] = k
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
    bi_body = np.where(blk[:, 0] >= 0, body_of[np.maximum(blk[:, 0], 0)],
                       np.where(blk[:, 1] >= 0, body_of[np.maximum(blk[:, 1], 0)], -1))
    bj_body = np.where(blk[:, 2] >= 0, body_of[np.maximum(blk[:, 2], 0)],
                       np.where(blk[:, 3] >= 0, body_of[np.maximum(blk[:, 3], 0)], -1))
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
    out = {"bfirst": bfirst, "bcount": bcount, "D": np.ascontiguousarray(D),
           "Dinv": np.ascontiguousarray(Dinv)}
    for pre, ptr, idx, dat in (("l", lptr, lidx, ldat), ("u", uptr, uidx, udat)):
        (out[pre + "cptr"], out[pre + "cidx"], out[pre + "cdat"], out[pre + "ptr"],
         out[pre + "idx"], out[pre + "dat"]) = _split_compact(ptr, idx, dat, rot)
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
    idx = np.stack([t_o, r_o, np.where(t_k >= 0, 3 * (t_k - first), -1),
                    np.where(r_k >= 0, 3 * (r_k - first), -1)], 1).astype(np.int32)
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
        ok = (idx[:, 0] >= 0) & (idx[:, 1] == idx[:, 0] + 1) & (idx[:, 2] == 0) \
            & (idx[:, 3] == 3)
        ok &= np.abs(dat[:, 5:8] - al_o[:, None] * nrm).max(1, initial=0.0) \
            <= 1e-12 * np.abs(dat[:, 5:8]).max(1, initial=0.0)
        ok &= np.abs(dat[:, 8:11] - al_k[:, None] * nrm).max(1, initial=0.0) \
            <= 1e-12 * np.abs(dat[:, 8:11]).max(1, initial=0.0)
        cdat = np.concatenate([dat[:, :5], al_o[:, None], al_k[:, None]], 1)[ok]
    else:
        ok = (idx[:, 0] >= 0) & (idx[:, 1] < 0) & (idx[:, 2] == 0) & (idx[:, 3] < 0)
        cdat = dat[ok, :5]
    owner = np.repeat(np.arange(len(ptr) - 1), np.diff(ptr))
    cptr = np.searchsorted(owner[ok], np.arange(len(ptr))).astype(np.int64)
    gptr = np.searchsorted(owner[~ok], np.arange(len(ptr))).astype(np.int64)
    return (cptr, np.ascontiguousarray((3 * idx[ok, 0]).astype(np.int32)),
            np.ascontiguousarray(cdat.reshape(-1, 7 if rot else 5)), gptr,
            np.ascontiguousarray(idx[~ok]), np.ascontiguousarray(dat[~ok]))


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
def _solve_body(k, m, bfirst, bcount, Dinv, cptr, cidx, cdat, ptr, idx, dat, rhs, y,
                side_out, lower, c_side):
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
            y[f + a] = (Dinv[k, a, 0] * s0 + Dinv[k, a, 1] * s1 + Dinv[k, a, 2] * s2
                        + Dinv[k, a, 3] * s3 + Dinv[k, a, 4] * s4 + Dinv[k, a, 5] * s5)
    else:
        for a in range(3):
            y[f + a] = Dinv[k, a, 0] * s0 + Dinv[k, a, 1] * s1 + Dinv[k, a, 2] * s2


@kernel
def _lower_solve(bfirst, bcount, Dinv, cptr, cidx, cdat, lptr, lidx, ldat, rhs, y, dy):
    """y = (D + L)^-1 rhs, body by body in increasing order; also dy = D y = rhs - L y (a
    by-product). D: the (relaxed) body blocks of :func:`ssor_structure`."""
    for k in range(len(bfirst)):
        _solve_body(k, k, bfirst, bcount, Dinv, cptr, cidx, cdat, lptr, lidx, ldat, rhs, y,
                    dy, True, 1.0)


@kernel
def _upper_solve(bfirst, bcount, Dinv, cptr, cidx, cdat, uptr, uidx, udat, rhs, y, uy,
                 c_side):
    """y = (D + U)^-1 rhs, body by body in decreasing order; also uy = rhs - c_side D y
    (c_side = 1: U y). The entries of the m-th body visited (k = nbody - 1 - m) are
    uptr[m]..uptr[m+1] (and cptr[m]..cptr[m+1]). (Fusing the conjugate gradient's vector
    updates into the solves, per body, made them slower: 0.92 x with contact kinematics,
    0.83 x with barycentre, same run.)"""
    nbody = len(bfirst)
    for m in range(nbody):
        _solve_body(nbody - 1 - m, m, bfirst, bcount, Dinv, cptr, cidx, cdat, uptr, uidx,
                    udat, rhs, y, uy, False, c_side)


@njit(cache=True)
def _pcg_ssor(mass_dof, bdat_c, blk_c, bdat_g, blk_g, ss_bfirst, ss_bcount, ss_Dinv,
              ss_lcptr, ss_lcidx, ss_lcdat, ss_lptr, ss_lidx, ss_ldat, ss_ucptr, ss_ucidx,
              ss_ucdat, ss_uptr, ss_uidx, ss_udat, rhs, x, tol, max_iter, work, omega, ax,
              have_ax):
    """Conjugate gradient on A x = rhs preconditioned by symmetric successive
    over-relaxation on the body blocks, M = (D_w + L) D_w^-1 (D_w + U), D_w = D / omega
    (ss_Dinv holds D_w^-1), with Eisenstat's trick: A = (D_w + L) + (D_w + U) - K0,
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
    tightened by the missing ratio. work (9, n).
    Returns (iterations, |rhs - A x| / |rhs|, number of true-residual products)."""
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
    _lower_solve(ss_bfirst, ss_bcount, ss_Dinv, ss_lcptr, ss_lcidx, ss_lcdat, ss_lptr,
                 ss_lidx, ss_ldat, tmp, rh, z)
    rz = 0.0
    for k in range(n):
        rz += rh[k] * z[k]
    # reference of the stopping test: (r0^T M^-1 r0)^1/2 |rhs| / |r0|
    ref = np.sqrt(max(rz, 0.0)) / res
    tol_eff = tol
    beta = 0.0
    it = 0
    while it < max_iter:
        it += 1
        # p <- z + beta p; t = (D_w + U)^-1 p, tmp = p - K0 t; q = (D_w + L)^-1 tmp,
        # dq = D_w q; A^ p = q + t
        for k in range(n):
            p[k] = z[k] + beta * p[k]
        _upper_solve(ss_bfirst, ss_bcount, ss_Dinv, ss_ucptr, ss_ucidx, ss_ucdat, ss_uptr,
                     ss_uidx, ss_udat, p, t, tmp, c_side)
        _lower_solve(ss_bfirst, ss_bcount, ss_Dinv, ss_lcptr, ss_lcidx, ss_lcdat, ss_lptr,
                     ss_lidx, ss_ldat, tmp, q, dq)
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
        if np.sqrt(max(rz_new, 0.0)) <= tol_eff * ref or it == max_iter:
            for k in range(n):
                scratch[k] = 0.0
            _matvec(mass_dof, bdat_c, blk_c, bdat_g, blk_g, x, 0.0, scratch, ax, 0.0, dummy)
            checks += 1
            rr = 0.0
            for k in range(n):
                d = rhs[k] - ax[k]
                rr += d * d
            res = np.sqrt(rr) / norm_b
            if res <= tol:
                return it, res, checks
            tol_eff *= max(0.5 * tol / res, 1e-3)
        beta = rz_new / rz
        rz = rz_new
    return it, res, checks
