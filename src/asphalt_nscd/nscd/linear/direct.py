"""Direct solve of the linear fast path (``linear_solver='direct'``) and the symmetric-mode
SuperLU factorisation shared with the harmonic solver.

The step matrix A = M + sum_b L_b^T G_b L_b (symmetric positive definite) is assembled as a
sparse matrix (:func:`assemble_matrix`) and factorised once per (dt, theta, intact-bond set) by
:func:`factor_spd`: a sparse Cholesky factor (``cholesky``, cholespy's supernodal CPU solver;
default) or SuperLU in symmetric mode (``superlu``, :func:`splu_symmetric`); a step costs two
triangular solves, exact to round-off. Measured on the step matrix of a paper-scale sample
(54,417 unknowns, 5.4 million non-zeros, one thread): a solve 0.024-0.025 s of CPU with
cholespy against 0.031 s with SuperLU (MMD or METIS ordering), the factorisation 3.6-3.7 s
against 2.7-2.9 s (1.97 s with METIS); PARDISO (pypardiso) 0.060 s per solve
(docs/choices.md, NSCD core: the direct solve). The harmonic solver keeps SuperLU: its complex
symmetric systems are not positive definite.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu


def assemble_matrix(mass_dof, blk, L, G):
    """The step matrix (ndof, ndof) scipy CSC: diagonal mass_dof (ndof,) plus the bond
    blocks L_a^T G L_c (blk (B,4) unknown blocks of the bonds, -1 = known; L the four (B,3,3)
    bond velocity operators; G (B,3,3))."""
    ndof = len(mass_dof)
    rows, cols, vals = [np.arange(ndof)], [np.arange(ndof)], [mass_dof]
    r3 = np.arange(3)
    for a in range(4):
        for c in range(4):
            ok = (blk[:, a] >= 0) & (blk[:, c] >= 0)
            if not ok.any():
                continue
            da, dc = blk[ok, a], blk[ok, c]
            rr = (3 * da[:, None, None] + r3[None, :, None]) * np.ones((1, 1, 3), np.int64)
            cc = (3 * dc[:, None, None] + r3[None, None, :]) * np.ones((1, 3, 1), np.int64)
            rows.append(rr.ravel())
            cols.append(cc.ravel())
            vals.append(np.einsum("bki,bkl,blj->bij", L[a][ok], G[ok], L[c][ok]).ravel())
    return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(ndof, ndof))


#: factorisations of the step matrix (:func:`factor_spd`)
FACTORISATIONS = ("cholesky", "superlu")


class CholeskyFactor:
    """Sparse Cholesky factor of a symmetric positive definite matrix (cholespy's
    ``CholeskySolverD``, its own fill-reducing ordering): ``solve(b)`` for b (n,) real, ``shape``;
    ``nnz`` None (cholespy does not report its factor's size)."""

    def __init__(self, a):
        from cholespy import CholeskySolverD, MatrixType

        a = sp.coo_matrix(a)
        a.sum_duplicates()
        self.shape = a.shape
        self.nnz = None
        self._solver = CholeskySolverD(
            int(a.shape[0]),
            a.row.astype(np.int32),
            a.col.astype(np.int32),
            np.ascontiguousarray(a.data, np.float64),
            MatrixType.COO,
        )

    def solve(self, b):
        b = np.ascontiguousarray(b, np.float64)
        x = np.empty_like(b)
        self._solver.solve(b, x)
        return x


def factor_spd(a, factorisation: str = "cholesky"):
    """The factor of a symmetric positive definite sparse matrix ``a`` (n, n) with ``solve(b)``:
    :class:`CholeskyFactor` (``cholesky``) or :func:`splu_symmetric` (``superlu``).

    Raises
    ------
    ValueError on an unknown factorisation; RuntimeError (SuperLU) on an exactly singular matrix.
    """
    if factorisation == "cholesky":
        return CholeskyFactor(a)
    if factorisation == "superlu":
        return splu_symmetric(a)
    raise ValueError(f"factorisation must be one of {FACTORISATIONS}, got {factorisation!r}")


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
        return splu(a, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
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
