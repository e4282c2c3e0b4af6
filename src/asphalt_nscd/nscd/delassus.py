"""Local Delassus blocks W_aa = H_a^T M^-1 H_a of contacts and bonds.

For a sphere-sphere or sphere-plate contact with the frame (n, t, s), lever arms
-r_i n (candidate) and +r_j n (antagonist sphere), the block is exactly diagonal::

    W_aa = diag(w_n, w_t, w_t),   w_n = 1/m_i + 1/m_j,
                                  w_t = w_n + r_i²/I_i + r_j²/I_j

(the lever arm is parallel to n, so a tangential impulse p_t changes the contact-point
velocity by r²/I p_t and a normal impulse produces no torque). A plate is translational:
its term is 1/m_plate (0 for a fixed or driven plate). A bond with the 'barycentre'
kinematics acts at the barycentres (no torque): its block is (1/m_i + 1/m_j) I in any frame.
With the 'contact' kinematics (state.Bonds) it acts at c with lever arms a_i, a_j, and the
block is full (:func:`bond_blocks_contact`)::

    W_bb = F [ (1/m_i + 1/m_j) I + [a_i]x^T D_i [a_i]x + [a_j]x^T D_j [a_j]x ] F^T

with D = I/I_sphere for a sphere, diag(1/I_plate) for a rotating plate (0 otherwise) and
[a]x the cross-product matrix. Off-diagonal blocks W_ab are
never formed: the nonlinear Gauss-Seidel works on body velocities (see gauss_seidel.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._jit import helper, kernel


@kernel
def contact_blocks(ci, cj, inv_mass, inv_inertia, radius, inv_mass_plate, wn, wt):
    """Fill wn (C,) and wt (C,) (1/kg) of the diagonal contact Delassus blocks."""
    for a in range(len(ci)):
        i = ci[a]
        j = cj[a]
        n_part = inv_mass[i]
        t_part = radius[i] * radius[i] * inv_inertia[i]
        if j >= 0:
            n_part += inv_mass[j]
            t_part += radius[j] * radius[j] * inv_inertia[j]
        else:
            n_part += inv_mass_plate[-1 - j]
        wn[a] = n_part
        wt[a] = n_part + t_part


@kernel
def bond_blocks(bi, bj, inv_mass, inv_mass_plate, w):
    """Fill w (B,) (1/kg): the bond Delassus block is w I (barycentric, no torque)."""
    for b in range(len(bi)):
        i = bi[b]
        j = bj[b]
        if j >= 0:
            w[b] = inv_mass[i] + inv_mass[j]
        else:
            w[b] = inv_mass[i] + inv_mass_plate[-1 - j]


@helper
def _add_rot(W, a0, a1, a2, d0, d1, d2):
    """W += [a]x^T diag(d) [a]x (3x3, global axes)."""
    # rows of [a]x: (0, -a2, a1), (a2, 0, -a0), (-a1, a0, 0)
    S = ((0.0, -a2, a1), (a2, 0.0, -a0), (-a1, a0, 0.0))
    for r in range(3):
        for c in range(3):
            W[r, c] += d0 * S[0][r] * S[0][c] + d1 * S[1][r] * S[1][c] + d2 * S[2][r] * S[2][c]


@njit(cache=True)
def bond_blocks_contact(
    bi, bj, frame, arm_i, arm_j, inv_mass, inv_inertia, inv_mass_plate, inv_inertia_plate, cg, W, A_inv
):
    """Full bond Delassus blocks of the 'contact' kinematics (module docstring).

    Parameters
    ----------
    frame : (B,3,3) rows n, t, s; arm_i, arm_j : (B,3) m; inv_inertia : (N,) 1/(kg m²);
    inv_inertia_plate : (P,3) 1/(kg m²) (principal, global axes; 0 = no rotation);
    cg : (B,3) N s/m, the bond laws' c_g (local_laws.bond_predict).

    Outputs (filled): W (B,3,3) 1/kg in the local frame, and A_inv (B,3,3) =
    (I + diag(cg) W)^-1 of the bond's local solve (gauss_seidel.nlgs).
    """
    Wg = np.empty((3, 3))
    A = np.empty((3, 3))
    for b in range(len(bi)):
        i = bi[b]
        j = bj[b]
        mt = inv_mass[i] + (inv_mass[j] if j >= 0 else inv_mass_plate[-1 - j])
        for r in range(3):
            for c in range(3):
                Wg[r, c] = mt if r == c else 0.0
        d = inv_inertia[i]
        _add_rot(Wg, arm_i[b, 0], arm_i[b, 1], arm_i[b, 2], d, d, d)
        if j >= 0:
            d = inv_inertia[j]
            _add_rot(Wg, arm_j[b, 0], arm_j[b, 1], arm_j[b, 2], d, d, d)
        else:
            k = -1 - j
            _add_rot(
                Wg,
                arm_j[b, 0],
                arm_j[b, 1],
                arm_j[b, 2],
                inv_inertia_plate[k, 0],
                inv_inertia_plate[k, 1],
                inv_inertia_plate[k, 2],
            )
        for r in range(3):
            for c in range(3):
                acc = 0.0
                for p in range(3):
                    for q in range(3):
                        acc += frame[b, r, p] * Wg[p, q] * frame[b, c, q]
                W[b, r, c] = acc
        for r in range(3):
            for c in range(3):
                A[r, c] = (1.0 if r == c else 0.0) + cg[b, r] * W[b, r, c]
        det = (
            A[0, 0] * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1])
            - A[0, 1] * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
            + A[0, 2] * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0])
        )
        idet = 1.0 / det
        A_inv[b, 0, 0] = (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]) * idet
        A_inv[b, 0, 1] = (A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]) * idet
        A_inv[b, 0, 2] = (A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]) * idet
        A_inv[b, 1, 0] = (A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]) * idet
        A_inv[b, 1, 1] = (A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]) * idet
        A_inv[b, 1, 2] = (A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]) * idet
        A_inv[b, 2, 0] = (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]) * idet
        A_inv[b, 2, 1] = (A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]) * idet
        A_inv[b, 2, 2] = (A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]) * idet
