"""Named bundles of arrays passed to the compiled kernels of the NSCD core.

Each bundle is a :class:`typing.NamedTuple` of NumPy arrays (and, for the options, numbers),
which numba compiles in nopython mode and caches like separate arguments; a kernel unpacks
the fields it needs at its top, so its loops are unchanged. The same bundles run as plain
Python with ``NUMBA_DISABLE_JIT=1``.

Shapes: N spheres, P plates, B bonds, C contacts, NK Kelvin–Voigt elements per bond.
Indices of the antagonist body j: j >= 0 a sphere, j < 0 the plate -1 - j.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Velocities(NamedTuple):
    """Body velocities: spheres v (N,3) m/s and w (N,3) rad/s, plates vp (P,3) m/s and wp
    (P,3) rad/s."""

    v: np.ndarray
    w: np.ndarray
    vp: np.ndarray
    wp: np.ndarray


class Bodies(NamedTuple):
    """Inertia of the bodies: sphere radii (N,) m, inverse masses (N,) 1/kg and inertias (N,)
    1/(kg m²) (0 = immobile or rotation not integrated), plate inverse masses (P,) 1/kg and
    inverse principal inertias (P,3) 1/(kg m²) in global axes (0 = no rotation)."""

    radius: np.ndarray
    inv_mass: np.ndarray
    inv_inertia: np.ndarray
    inv_mass_plate: np.ndarray
    inv_inertia_plate: np.ndarray


class BondGeometry(NamedTuple):
    """Bonds' bodies i, j (B,) int, local frames (B,3,3) (rows n, t, s), lever arms arm_i,
    arm_j (B,3) m from the barycentres to the contact point ('contact' kinematics), broken
    (B,) bool (state.Bonds)."""

    i: np.ndarray
    j: np.ndarray
    frame: np.ndarray
    arm_i: np.ndarray
    arm_j: np.ndarray
    broken: np.ndarray


class BondState(NamedTuple):
    """Bond laws and internal variables (state.Bonds): the step's reciprocals coef (B,3,2)
    and i_den (B,NK,2) (local_laws.bond_coefficients), Kelvin–Voigt stiffnesses Kk (B,NK,2)
    N/m and viscosities Ck (B,NK,2) N s/m, parallel spring Kinf (B,2) N/m, strength r_crit
    (B,) N, force (B,3) N, dashpot and Kelvin–Voigt displacements delta_c (B,3) and delta_k
    (B,NK,3) m, rest vectors rest (B,3) m and accumulated displacement disp (B,3) m; the
    last index 2 of the parameters is 0 normal, 1 tangential."""

    coef: np.ndarray
    i_den: np.ndarray
    Kk: np.ndarray
    Ck: np.ndarray
    Kinf: np.ndarray
    r_crit: np.ndarray
    force: np.ndarray
    delta_c: np.ndarray
    delta_k: np.ndarray
    rest: np.ndarray
    disp: np.ndarray


class BondStep(NamedTuple):
    """A step's affine bond laws P = c0 - c_g U (Eq. 25): c0 (B,3) N s, cg (B,3) N s/m, the
    start-of-step displacement delta_m (B,3) m and velocity u_m (B,3) m/s in the local
    frames (local_laws.bond_predict); the Delassus blocks of NLGS, w (B,) s/kg
    ('barycentre': W_bb = w I), W (B,3,3) and A_inv = (I + diag(c_g) W)^-1 (B,3,3)
    ('contact', delassus.bond_blocks_contact); the impulses impulse (B,3) N s."""

    c0: np.ndarray
    cg: np.ndarray
    delta_m: np.ndarray
    u_m: np.ndarray
    w: np.ndarray
    W: np.ndarray
    A_inv: np.ndarray
    impulse: np.ndarray


class Contacts(NamedTuple):
    """Contact candidates: bodies i, j (C,) int, local frames (C,3,3), gaps (C,) m, diagonal
    Delassus blocks wn, wt (C,) s/kg (delassus.contact_blocks), impulses (C,3) N s."""

    i: np.ndarray
    j: np.ndarray
    frame: np.ndarray
    gap: np.ndarray
    wn: np.ndarray
    wt: np.ndarray
    impulse: np.ndarray


class StepOptions(NamedTuple):
    """Time step h (s), theta of the Moreau–Jean method, rot (True = 'contact' bond
    kinematics: bond velocities at the contact point, torques on the bodies)."""

    h: float
    theta: float
    rot: bool


class NLGSOptions(NamedTuple):
    """Nonlinear Gauss–Seidel: time step h (s), friction coefficient mu, tolerance tol,
    relaxation relax, at most max_iter sweeps, convergence norm (0 quadratic, 1 maximum,
    2 both; state.CONVERGENCE_NORMS), rot as in :class:`StepOptions`."""

    h: float
    mu: float
    tol: float
    relax: float
    max_iter: int
    norm: int
    rot: bool
