"""The linear system of a bonded step (:class:`LinearBondSolver`): builds the unknowns, the
step matrix and the chosen solver ('cg', 'cg_ssor', 'direct') once per (dt, theta,
intact-bond set), then solves each step.
"""

from __future__ import annotations

import numpy as np

from ..bundles import Velocities
from .cg import _matvec, _pcg, _pcg_threaded, block_jacobi, matrix_free_operator
from .direct import assemble_matrix, factor_spd
from .dofs import DofMap, _gather, _rhs, _scatter, bond_impulses, dof_numbering, skew
from .ssor import _SSOR_KEYS, SSORStructure, _galerkin_combine, _galerkin_gram, _pcg_ssor, ssor_structure

#: Methods of :class:`LinearBondSolver` (and values of NSCDParameters.linear_solver).
LINEAR_SOLVERS = ("cg", "cg_ssor", "direct")


class LinearSolveError(RuntimeError):
    """An iterative solve of :class:`LinearBondSolver` ran to its ``max_iterations`` with its
    relative residual above its tolerance: its solution is not the system's."""


def reached(iterations: int, residual: float, tolerance: float, max_iterations: int) -> bool:
    """Whether an iterative solve gave the system's solution: its relative residual met the
    tolerance, or it stopped before ``max_iterations`` (``cg_ssor`` stops early at the floor
    rounding allows, its residual then reported above a tolerance below that floor:
    :func:`.ssor._pcg_ssor`). A solve that ran to ``max_iterations`` above its tolerance did not."""
    return residual <= tolerance or iterations < max_iterations


class LinearBondSolver:
    """The linear system of the bonded network for one (dt, theta, intact-bond set).

    Parameters
    ----------
    inv_mass, inv_mass_plate : (N,), (P,) 1/kg (0 = immobile).
    bi, bj, frame, cg : bonds (B,), (B,3,3), (B,3) N s/m; broken : (B,) bool.
    method : 'cg', 'cg_ssor' or 'direct' (:mod:`asphalt_nscd.nscd.linear`); tolerance :
    relative residual of the conjugate gradients; max_iterations : of the conjugate
    gradients.
    threads : > 1: 'cg' runs on that many numba threads (bonds ordered by partitions of the
        unknowns, cg._partition); 1: sequential kernels.
    ssor_omega : relaxation of 'cg_ssor', in (0, 2).
    factorisation : of 'direct': 'cholesky' (default) or 'superlu' (:func:`.direct.factor_spd`).
    rotation : dict or None — for the 'contact' kinematics: ``arm_i``, ``arm_j`` (B,3) m,
        ``inv_inertia`` (N,) and ``inv_inertia_plate`` (P,3) 1/(kg m²) (0 = no rotation).
        None: 'barycentre' kinematics (translations only).

    Raises
    ------
    ValueError for an unknown method, ssor_omega outside (0, 2), or unequal tangential
    bond coefficients ('cg', 'cg_ssor').
    """

    def __init__(
        self,
        inv_mass,
        inv_mass_plate,
        bi,
        bj,
        frame,
        cg,
        broken,
        method="cg",
        tolerance=1e-10,
        max_iterations=10000,
        rotation=None,
        threads=1,
        ssor_omega=1.0,
        factorisation="cholesky",
    ):
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
            st, sr, pt, pr, m3 = dof_numbering(
                inv_mass, inv_mass_plate, rotation["inv_inertia"], rotation["inv_inertia_plate"]
            )
        else:
            arm_i = arm_j = np.zeros((nb, 3))
            st, sr, pt, pr, m3 = dof_numbering(inv_mass, inv_mass_plate)
        self.st, self.sr, self.pt, self.pr = st, sr, pt, pr
        self.dofs = DofMap(st, sr, pt, pr)
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
            op, order, self.part_c, self.part_g, nrm, gcol = matrix_free_operator(
                self.mass_dof, nblk, self.blk, frame[keep], cgk, arm_i[keep], arm_j[keep], self.rot, threads
            )
            self.blk = self.blk[order]
            G, L = G[order], [x[order] for x in L]
            self.op = op
            self.bdat_c, self.blk_c, self.bdat_g, self.blk_g = (op.bdat_c, op.blk_c, op.bdat_g, op.blk_g)
            self.precond = block_jacobi(m3, self.blk, L, G)
            self.nnz_matrix = self.ndof + (144 if self.rot else 36) * len(G)
            self._work = np.zeros((4, self.ndof))
            if method == "cg_ssor":
                ai, aj = arm_i[keep][order], arm_j[keep][order]
                bdat_all = np.concatenate([nrm] + gcol + [ai, aj], 1)
                ss = ssor_structure(st, sr, pt, pr, m3, self.blk, L, G, bdat_all, self.ssor_omega)
                self._ssor = SSORStructure(*(ss[k] for k in _SSOR_KEYS))
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
        K = assemble_matrix(self.mass_dof, self.blk, L, G)
        self.nnz_matrix = K.nnz
        self.lu = factor_spd(K, factorisation) if self.ndof else None
        #: stored factor entries (SuperLU's L and U), None where the factorisation does not report them
        self.nnz_factor = (
            (None if self.lu is None or factorisation != "superlu" else self.lu.L.nnz + self.lu.U.nnz)
            if self.ndof
            else 0
        )

    def solve(self, free, bonds, c0, cg, out, impulse, start=None, previous=None):
        """End-of-step velocities and bond impulses.

        Parameters
        ----------
        free : bundles.Velocities, the free velocities m/s, rad/s (with 'barycentre' the
            angular ones are not used).
        bonds : bundles.BondGeometry (state.Bonds); c0 (B,3) N s, cg (B,3) N s/m
            (local_laws.bond_predict).
        out : bundles.Velocities, outputs: unknown rows written; known rows must hold the
            imposed values.
        impulse (B,3) N s: output, local frames.
        start : bundles.Velocities, initial guess of ``cg`` (default: the free velocities).
        previous : ``cg_ssor`` only — a tuple of bundles.Velocities, at the start of the
            step, one step earlier and up to two more, or None. The initial guess is then the
            Galerkin (A-norm optimal) combination of these velocity fields
            (:meth:`_galerkin_start`), which contains the linear extrapolation ``start``;
            ``start`` is used without them.
        """
        rhs = np.empty(self.ndof)
        _rhs(rhs, self.mass_dof, self.dofs, free, out, bonds, c0, cg, self.rot)
        if self.method == "direct":
            sol = self.lu.solve(rhs) if self.ndof else rhs
        elif self.method == "cg_ssor":
            sol, ax = self._spare
            have = previous is not None and self._galerkin_start(previous, rhs, sol, ax)
            if not have:
                _gather(sol, self.dofs, start or free)
            it, res, checks = _pcg_ssor(
                self.op,
                self._ssor,
                rhs,
                sol,
                self.tolerance,
                self.max_iterations,
                self._work,
                self.ssor_omega,
                ax,
                have,
            )
            self.last_checks = checks
            self.last_extrapolated = bool(have)
            self.last_iterations, self.last_residual = it, res
            # (sol, A sol) becomes the most recent cached pair; the oldest pair is recycled
            self._cache.insert(0, (sol, ax))
            self._spare = (
                list(self._cache.pop()) if len(self._cache) > 4 else [np.zeros(self.ndof), np.zeros(self.ndof)]
            )
        else:
            sol = np.empty(self.ndof)
            _gather(sol, self.dofs, start or free)
            it, res = self._run_cg(rhs, sol, self._work)
            self.last_iterations, self.last_residual = it, res
        _scatter(sol, self.dofs, out)
        bond_impulses(bonds, c0, cg, out, impulse, self.rot)

    @property
    def last_converged(self) -> bool:
        """Whether the last :meth:`solve` gave the system's solution (:func:`reached` of its iterations and
        residual; always with 'direct', which reports none)."""
        return reached(self.last_iterations, self.last_residual, self.tolerance, self.max_iterations)

    def _run_cg(self, rhs, x, work):
        """:func:`_pcg` on this operator, or :func:`_pcg_threaded` with threads > 1."""
        args = (self.op, self.precond, rhs, x, self.tolerance, self.max_iterations, work)
        if len(self.part_c):
            return _pcg_threaded(*args, self.part_c, self.part_g)
        return _pcg(*args)

    def gather(self, v, w, vp, wp):
        """The unknowns x (ndof,) of body velocities v, w (N,3), vp, wp (P,3)."""
        x = np.empty(self.ndof)
        _gather(x, self.dofs, Velocities(v, w, vp, wp))
        return x

    def scatter(self, x, v, w, vp, wp):
        """Write the unknowns x (ndof,) into the body velocities (known rows untouched)."""
        _scatter(x, self.dofs, Velocities(v, w, vp, wp))

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
        LinearSolveError if a column's iterative solve ran to ``max_iterations`` above its
            tolerance (:func:`reached`; nothing cached).
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
                it, res, _ = _pcg_ssor(
                    self.op,
                    self._ssor,
                    rhs,
                    x,
                    self.tolerance,
                    self.max_iterations,
                    np.zeros((9, self.ndof)),
                    self.ssor_omega,
                    np.zeros(self.ndof),
                    False,
                )
            else:
                it, res = self._run_cg(rhs, x, np.zeros((4, self.ndof)))
            if not reached(it, res, self.tolerance, self.max_iterations):
                raise LinearSolveError(
                    f"response of block {block}, axis {d}: relative residual {res:.3g} above the tolerance "
                    f"{self.tolerance:.3g} after {it} iterations ({self.method})"
                )
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
        _matvec(
            self.mass_dof,
            self.bdat_c,
            self.blk_c,
            self.bdat_g,
            self.blk_g,
            x,
            0.0,
            np.zeros(self.ndof),
            ax,
            0.0,
            np.zeros(self.ndof),
        )
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
            _gather(x[k], self.dofs, previous[k])
        ax = self._abasis[:m]
        for k in range(m):
            ax[k] = self._product(x[k])
        diff = np.array([[1.0, 0.0, 0.0, 0.0], [1.0, -1.0, 0.0, 0.0], [1.0, -2.0, 1.0, 0.0], [1.0, -3.0, 3.0, -1.0]])[
            :m, :m
        ]
        G, b = np.zeros((m, m)), np.zeros(m)
        _galerkin_gram(x, ax, rhs, diff, G, b, np.zeros(m), np.zeros(m))
        if not G[0, 0] > 0.0:
            return False
        keep = 1
        for k in range(1, m):  # Cholesky-like pivot test: drop what the span already holds
            sub = G[: k + 1, : k + 1]
            if np.linalg.eigvalsh(sub).min() > 1e-12 * np.abs(np.diag(sub)).max():
                keep = k + 1
            else:
                break
        c = np.linalg.solve(G[:keep, :keep], b[:keep])
        coef = c @ diff[:keep]  # coefficients of x_n, x_n-1, ...
        _galerkin_combine(np.pad(coef, (0, 4 - coef.size)), x, ax, m, x0, ax0)
        return True
