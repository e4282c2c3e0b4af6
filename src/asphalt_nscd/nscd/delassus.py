"""Local Delassus blocks W_aa = H_a^T M^-1 H_a of contacts and bonds.

For a sphere-sphere or sphere-plate contact with the frame (n, t, s), lever arms
-r_i n (candidate) and +r_j n (antagonist sphere), the block is exactly diagonal::

    W_aa = diag(w_n, w_t, w_t),   w_n = 1/m_i + 1/m_j,
                                  w_t = w_n + r_i²/I_i + r_j²/I_j

(the lever arm is parallel to n, so a tangential impulse p_t changes the contact-point
velocity by r²/I p_t and a normal impulse produces no torque). A plate is translational:
its term is 1/m_plate (0 for a fixed or driven plate). A bond acts at the barycentres
(no torque): its block is (1/m_i + 1/m_j) I in any frame. Off-diagonal blocks W_ab are
never formed: the nonlinear Gauss-Seidel works on body velocities (see gauss_seidel.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
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


@njit(cache=True)
def bond_blocks(bi, bj, inv_mass, inv_mass_plate, w):
    """Fill w (B,) (1/kg): the bond Delassus block is w I (barycentric, no torque)."""
    for b in range(len(bi)):
        i = bi[b]
        j = bj[b]
        if j >= 0:
            w[b] = inv_mass[i] + inv_mass[j]
        else:
            w[b] = inv_mass[i] + inv_mass_plate[-1 - j]


def dense_delassus(n_spheres, ci, cj, frames, radius, inv_mass, inv_inertia,
                   inv_mass_plate, rotation=True) -> np.ndarray:
    """Dense global Delassus operator W = H^T M^-1 H (3C, 3C) for small test problems.

    Parameters
    ----------
    ci, cj : (C,) candidate and antagonist (plate ``-1-k``); frames : (C, 3, 3) rows n, t, s.
    rotation : include the lever arms (contacts) or not (bonds, barycentric).
    """
    c = len(ci)
    ndof = 6 * n_spheres + 3 * len(inv_mass_plate)
    H = np.zeros((ndof, 3 * c))
    minv = np.zeros(ndof)
    for s in range(n_spheres):
        minv[6 * s:6 * s + 3] = inv_mass[s]
        minv[6 * s + 3:6 * s + 6] = inv_inertia[s]
    for k in range(len(inv_mass_plate)):
        minv[6 * n_spheres + 3 * k:6 * n_spheres + 3 * k + 3] = inv_mass_plate[k]
    for a in range(c):
        F = frames[a]
        n = F[0]
        for sign, body, arm in ((1.0, ci[a], -radius[ci[a]] * n),
                                (-1.0, cj[a], radius[cj[a]] * n if cj[a] >= 0 else None)):
            if body >= 0:
                H[6 * body:6 * body + 3, 3 * a:3 * a + 3] = sign * F.T
                if rotation:
                    # torque of a unit impulse along each local axis: arm x e
                    H[6 * body + 3:6 * body + 6, 3 * a:3 * a + 3] = sign * np.cross(arm, F).T
            else:
                k = -1 - body
                H[6 * n_spheres + 3 * k:6 * n_spheres + 3 * k + 3, 3 * a:3 * a + 3] = sign * F.T
    return H.T @ (minv[:, None] * H)
