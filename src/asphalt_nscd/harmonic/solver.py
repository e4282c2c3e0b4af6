"""Periodic steady state of a bonded sample under a harmonic head displacement.

In the small-strain complex modulus test no bond breaks and no frictional contact opens or
closes, so the numerical sample is a linear viscoelastic network of rigid spheres. Under the
imposed top-plate displacement x_top(t) = Re(A e^{i w t}) every unknown is a phasor, and the
steady state solves one complex sparse linear system per (T, f):

    (K(w) - w^2 M)_ff u_f = -K(w)_fp u_p,           u_p = (A, 0, 0)   (top plate)

Model (docs/design.md, "Bond law")
----------------------------------
* Bond b between bodies a and c with unit vector n (initial frame) has the complex 3x3
  stiffness  K_b(w) = k_n(w) n n^T + k_t(w) (I - n n^T)  with
  k_n(w) = a_b E*(w),  a_b = pi r_min^2 / l0  (Eqs. 30-33),  k_t = k_n / (2 (1 + nu))
  (Eqs. 8-11), E*(w) the complex modulus of the macro law (Burger's, Eqs. 27-29, or any
  :class:`~asphalt_nscd.rheology.laws.GeneralizedBurgers`; any object with a
  ``complex_modulus(omega)`` method works). It is the exact frequency response of the
  time-domain bond law (Maxwell + Kelvin-Voigt in series per direction, Eqs. 15-24) when
  every bond stays intact and the rotation of the frame is negligible (small strain).
* Bond kinematics (option ``bond_kinematics``; the paper does not say where the bond acts):

  ``contact`` (default) — 6 DOF per sphere (u, theta). K_b acts on the relative displacement
      of the bond's contact point c (middle of the gap on the line of centres, see
      :mod:`.network`):  Delta = (u_c + theta_c x (c - x_c)) - (u_a + theta_a x (c - x_a)),
      so the bond force, applied at c, carries a torque on both bodies and a rigid rotation
      of a bonded pair strains no bond. Rotational inertia: ``spheres/inertia``.
  ``barycentre`` — 3 DOF per sphere: Delta = u_c - u_a at the barycentres, no torque. This is
      the time-domain NSCD core as it is (kept for the time-domain comparison). A rigid
      rotation moves barycentres tangentially relative to each other, so the tangential
      springs resist it: in bending (2PB) the sample is spuriously stiff — the network factor
      of sample s1 (221 spheres) is 88.7 with ``barycentre`` vs 2.65 with ``contact``
      (clamped head, no inertia; ``results/harmonic/kinematics_study.csv``).

  Zero-stiffness modes of ``contact``: a bond is a point spring, so a sphere with one bond
  can spin about the bond axis and roll about c, and a sphere on a straight line of bonds
  can spin about it. These modes are regularised by a rotational spring on the relative
  rotation theta_c - theta_a of every bond, of stiffness eps k_n(w) |c - x_a|^2 with
  eps = :data:`ROTATIONAL_REGULARISATION` (1e-10): it has the law of the bond (so
  K(w) = E*(w) G still holds), makes G positive definite (every active cluster is bonded
  to a plate; with a free head, at least one cluster must join both plates, else the head's
  rigid rotation is free and SuperLU reports a singular factor), and resists no rigid-body
  motion. Exact zero-energy modes v of the free DOFs are not loaded (K_pf v = 0), so they
  do not change the head force; soft but non-zero modes are stiffened by O(eps): the head
  force changes linearly with eps, by
  2.4e-5 (relative) at eps = 1e-8 and 2.4e-7 at 1e-10 against eps = 0 on a 150-sphere
  jittered lattice, and by < 1e-5 for eps in [1e-10, 1e-6] on sample s1. With inertia the
  rotational masses also make the dynamic matrix regular. With ``barycentre`` + ``free``
  the same spring (l = |c - plates/point[1]|) holds the head's spin when all head bonds lie
  on one line through its centre.
* Head rotation (option ``head_rotation``): ``free`` (default) — the head (top plate) rotates
  about the centre of its face ``plates/point[1]`` under the bond moments, as the cantilever
  loaded at the head that the form factor gamma of EN 12697-26 Eq. 3 assumes; its rotational
  inertia is that of a steel cuboid of the head's size (:mod:`.network`). Sphere-plate
  bonds then see the head's displacement at c, u_top + theta_top x (c - plates/point[1]).
  ``clamped`` — the head only translates (the NSCD core's driven plate).
  ``contact`` + ``free`` is the consistent choice for Eq. 3 and the workflow's default.
* Verification (tests/unit/test_harmonic_kinematics.py): a bonded pair under a rigid
  rotation carries no force with ``contact`` and k_t theta x (x_j - x_i) with
  ``barycentre``; axial series/parallel closed forms hold for every option; a two-chain
  ladder cantilever with a free head matches an independent dense assembly (1e-9) and its
  tip compliance has the Euler-Bernoulli L^3 / (3 EI) term, EI = k_n s w^2 / 2, to 1e-9.
* Bottom plate fixed; head translated by (A, 0, 0) (imposed, the paper's "z" is along x).
* Spheres in bonded clusters touching no plate carry no load: their steady-state
  displacement is zero (no force reaches them); they are removed and counted.

What the simulated force contains, and mu (Eq. 1)
-------------------------------------------------
Eq. 1 reads E1 = gamma (F0/z0 cos Psi + 1e-6 mu w^2) with mu = 0.135 M + m: the lab force
is the load-cell force at the head, which contains the inertia of the moving mass m and of
the specimen, and the standard adds back an estimate of it. Here M is the mass of the
spheres of the sample file (sum of ``spheres/mass``; 0.6 kg in the paper) and m its top-plate
mass (``plates/mass[1]``, 0.235 kg), scaled with the sample. The force F (x component) is:

``inertia="full"`` (default; what the time-domain test measures)
    the sphere masses are in the dynamics and F is the force the actuator applies to the
    head, F = R_x - w^2 m A, with R = K_pf u_f + K_pp u_p the force the head exerts on its
    bonds (minus the sum of the bond forces on the top plate). This is the driver force of
    the NSCD core (``StepStats.driver_force``, which includes the plate inertia).
    mu = 0.135 M + m is applied as in the lab; the remaining inertia error (the sample's
    distributed mass vs 0.135 M) is part of the model response, and vanishes as w -> 0.
``inertia="none"``
    no mass in the dynamics (quasi-static network); the force is reported as
    F = R_x - w^2 mu A, i.e. as a load cell would read it were the inertia exactly the
    lumped one of EN 12697-26, so that Eq. 1 with the same mu returns the inertia-free
    network modulus exactly.

Without inertia K(w) = E*(w) G with G real when all bonds share one law, so the network's
response is E*(w) times a real geometric stiffness: the "network factor" is then a real
constant and the phase of the sample equals that of the macro law.

Linear solver: SciPy's SuperLU (``scipy.sparse.linalg.splu``). The matrices are complex
symmetric (not Hermitian) with a symmetric pattern: SuperLU in symmetric mode with the
MMD(A^T + A) ordering gave half the fill of COLAMD (19.5e6 vs 33.8e6 factor entries,
8.7 s vs 11.0 s for one complex factorisation of a 12,000-sphere lattice, 36,000 DOF). When
every bond follows one law, K(w) = E*(w) G with G real and independent of T and f, so G is
factorised once per sample in real arithmetic (2.6 s on the same lattice) and each (T, f)
costs a back-substitution (0.2 s), plus a few GMRES iterations preconditioned by G^-1 when
inertia is included (w^2 m / k << 1 far below the first resonance; 1.5 s). The general path
for per-bond laws (:meth:`HarmonicSystem.solve`) factorises the complex matrix at each (T, f).
With ``bond_kinematics="contact"`` (6 DOF per sphere, 72,003 unknowns on the same lattice
with a free head) the 6x6 bond blocks raise the fill: measured on a loaded 2-core machine
(``harmonic-bench --n 12000 --td-steps 0 --skip-direct``), setup 10.6 s vs 1.8 s, real
factorisation 103 s vs 6.6 s, back-substitution 1.1 s vs 0.14 s, GMRES with inertia 68 s vs
2.2 s (more iterations, each dearer), i.e. 182 s vs 10.5 s for the first (T, f).
SciPy has no sparse Cholesky or nested-dissection ordering; a geometric nested dissection
tried here did not beat MMD(A^T + A) (28e6 entries). Measurements: ``asphalt-nscd
harmonic-bench`` (results/harmonic/bench.json).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

from ..nscd.linear import splu_symmetric
from ..rheology.laws import tangential_ratio
from .network import BondNetwork

INERTIA_MODES = ("none", "full")
BOND_KINEMATICS = ("contact", "barycentre")
HEAD_ROTATIONS = ("free", "clamped")
#: Relative stiffness eps of the regularising rotational bond spring (module docstring).
ROTATIONAL_REGULARISATION = 1e-10
SOLVERS = ("reuse", "direct")
#: EN 12697-26 lumped-mass factor of the specimen in mu = 0.135 M + m (Eq. 1).
SPECIMEN_MASS_FACTOR = 0.135


@dataclass
class HarmonicSolution:
    """Steady state at one angular frequency.

    Attributes
    ----------
    frequency_Hz : float
    force : (3,) complex, N
        Force F at the head (x component is the test force; content: module docstring).
    reaction : (3,) complex, N
        R = K_pf u_f + K_pp u_p, minus the sum of the bond forces on the top plate.
    displacement : (N, 3) complex, m
        Sphere displacement phasors (zero for the removed load-free clusters).
    amplitude_m : float
        Imposed head displacement amplitude A.
    mu_kg : float
        Mass factor of Eq. 1, 0.135 M + m (kg).
    sample_mass_kg, plate_mass_kg : float
        M (spheres) and m (top plate) of the sample file, kg.
    inertia : str
        "none" or "full" (see the module docstring).
    n_free_dof, n_load_free : int
        Unknowns solved for; spheres in load-free clusters.
    solve_time_s : float
        Wall time of assembly + solve.
    residual : float
        Relative residual |A u - b| / |b| of the linear system.
    solver : str
        "reuse" or "direct" (see :meth:`HarmonicSystem.solve_law`).
    rotation : (N, 3) complex, rad
        Sphere rotation phasors (zero with the barycentre kinematics).
    head_rotation : (3,) complex, rad
        Head rotation phasor (zero when clamped).
    """

    frequency_Hz: float
    force: np.ndarray
    reaction: np.ndarray
    displacement: np.ndarray
    amplitude_m: float
    mu_kg: float
    sample_mass_kg: float
    plate_mass_kg: float
    inertia: str
    n_free_dof: int
    n_load_free: int
    solve_time_s: float
    residual: float
    solver: str = "direct"
    rotation: np.ndarray | None = None
    head_rotation: np.ndarray | None = None

    @property
    def psi_deg(self) -> float:
        """Phase lead of the force on the displacement, degrees."""
        return float(np.degrees(np.angle(self.force[0] / self.amplitude_m)))

    @property
    def F0_N(self) -> float:
        return float(abs(self.force[0]))


class HarmonicSystem:
    """The bonded network prepared for repeated harmonic solves (pattern built once).

    Parameters
    ----------
    network : BondNetwork
    nu : float
        Poisson's ratio of the tangential ratio 1/(2(1+nu)) (Eqs. 8-11).
    bond_kinematics : {"contact", "barycentre"}
        Where the bond acts; 6 or 3 DOF per sphere (module docstring).
    head_rotation : {"free", "clamped"}
        Whether the head rotates (3 more unknowns) or only translates (module docstring).
    regularisation : float
        eps of the regularising rotational bond spring (``contact`` only; module docstring).

    Raises
    ------
    ValueError
        on an unknown option, negative ``regularisation``, or ``contact`` without radii.
    """

    def __init__(self, network: BondNetwork, nu: float = 0.35,
                 bond_kinematics: str = "contact", head_rotation: str = "free",
                 regularisation: float = ROTATIONAL_REGULARISATION):
        if bond_kinematics not in BOND_KINEMATICS:
            raise ValueError(f"bond_kinematics must be one of {BOND_KINEMATICS}, "
                             f"got {bond_kinematics!r}")
        if head_rotation not in HEAD_ROTATIONS:
            raise ValueError(f"head_rotation must be one of {HEAD_ROTATIONS}, "
                             f"got {head_rotation!r}")
        if bond_kinematics == "contact" and network.contact_point is None:
            raise ValueError("bond_kinematics='contact' needs the sphere radii (contact points)")
        if not regularisation >= 0:
            raise ValueError(f"regularisation must be >= 0, got {regularisation}")
        self.network = network
        self.t_ratio = tangential_ratio(nu)
        self.bond_kinematics = bond_kinematics
        self.head_rotation = head_rotation
        self.regularisation = float(regularisation)
        contact = bond_kinematics == "contact"
        n_sph = network.n_spheres
        i, j = network.i, network.j
        # Load-free clusters: connected components of the sphere graph touching no plate.
        sph = j >= 0
        graph = sp.coo_matrix((np.ones(sph.sum()), (i[sph], j[sph])), shape=(n_sph, n_sph))
        _, label = connected_components(graph, directed=False)
        anchored = np.zeros(label.max() + 1 if n_sph else 0, bool)
        anchored[label[i[~sph]]] = True
        self.active = anchored[label]
        self.n_load_free = int(n_sph - self.active.sum())
        n_act = int(self.active.sum())
        self.dof_per_sphere = 6 if contact else 3
        d = self.dof_per_sphere
        n_head_rot = 3 if head_rotation == "free" else 0
        self.n_free = d * n_act + n_head_rot
        # Global DOF of the 6 coordinates (u, theta) of every body; -1 = fixed / not a DOF.
        # Bodies 0..n_sph-1 spheres, n_sph bottom plate (fixed), n_sph+1 top plate whose
        # translation is prescribed (DOFs n_free..n_free+2, the "p" block).
        gdof = -np.ones((n_sph + 2, 6), np.int64)
        act = np.flatnonzero(self.active)
        gdof[act, :d] = d * np.arange(n_act)[:, None] + np.arange(d)
        gdof[n_sph + 1, :3] = self.n_free + np.arange(3)
        if n_head_rot:
            gdof[n_sph + 1, 3:] = d * n_act + np.arange(3)
        self.keep = self.active[i]  # bonds of load-free clusters carry nothing
        a_body = i[self.keep]
        c_body = np.where(j >= 0, j, n_sph - 1 - j)[self.keep]  # -1 -> n_sph, -2 -> n_sph + 1
        n = network.normal[self.keep]
        # Point where the bond acts: contact point, or the barycentre of sphere i.
        point = network.contact_point[self.keep] if contact else network.position[a_body]
        centre = np.vstack([network.position, network.plate_point if network.plate_point
                            is not None else np.zeros((2, 3))])
        # L (B, 6, 6) per side: (relative displacement at the point, relative rotation)
        # = L_c q_c - L_a q_a with L = [[I, -skew(point - centre)], [0, I]].
        arm_a = point - centre[a_body]
        lever_a, lever_c = _lever(arm_a), _lever(point - centre[c_body])
        nb = len(a_body)
        pn = np.einsum("bk,bl->bkl", n, n)
        unit_n = np.zeros((nb, 6, 6))
        unit_t = np.zeros((nb, 6, 6))
        unit_n[:, :3, :3] = pn
        unit_t[:, :3, :3] = np.eye(3) - pn
        # Regularising rotational spring eps k_n l^2 (module docstring): l = |c - x_a| with
        # the contact kinematics; with the barycentre one only the head rotates, l = |c - p|.
        arm = arm_a if contact else point - centre[c_body]
        arm2 = np.einsum("bk,bk->b", arm, arm)
        unit_n[:, 3:, 3:] = (self.regularisation * arm2)[:, None, None] * np.eye(3)
        rows, cols, un, ut, src = [], [], [], [], []
        bidx = np.arange(nb)
        for s_body, s_lev, t_body, t_lev, sign in ((a_body, lever_a, a_body, lever_a, 1.0),
                                                   (c_body, lever_c, c_body, lever_c, 1.0),
                                                   (a_body, lever_a, c_body, lever_c, -1.0),
                                                   (c_body, lever_c, a_body, lever_a, -1.0)):
            r_dof = gdof[s_body]  # (B, 6)
            c_dof = gdof[t_body]
            vn = sign * np.einsum("bki,bkl,blj->bij", s_lev, unit_n, t_lev)
            vt = sign * np.einsum("bki,bkl,blj->bij", s_lev, unit_t, t_lev)
            rr = np.broadcast_to(r_dof[:, :, None], (nb, 6, 6))
            cc = np.broadcast_to(c_dof[:, None, :], (nb, 6, 6))
            ok = (rr >= 0) & (cc >= 0) & ((vn != 0) | (vt != 0))
            rows.append(rr[ok])
            cols.append(cc[ok])
            un.append(vn[ok])
            ut.append(vt[ok])
            src.append(np.broadcast_to(bidx[:, None, None], (nb, 6, 6))[ok])
        rows = np.concatenate(rows)
        cols = np.concatenate(cols)
        self._unit_n = np.concatenate(un)
        self._unit_t = np.concatenate(ut)
        self._src = np.concatenate(src)
        n_all = self.n_free + 3
        lin = rows * n_all + cols
        uniq, self._inverse = np.unique(lin, return_inverse=True)
        self._n_uniq = len(uniq)
        u_rows, u_cols = uniq // n_all, uniq % n_all
        # Split the unique entries into the blocks ff, fp (rows free) and pf, pp (rows top).
        self._blocks = {}
        for name, rsel, csel in (("ff", u_rows < self.n_free, u_cols < self.n_free),
                                 ("fp", u_rows < self.n_free, u_cols >= self.n_free),
                                 ("pf", u_rows >= self.n_free, u_cols < self.n_free),
                                 ("pp", u_rows >= self.n_free, u_cols >= self.n_free)):
            sel = np.flatnonzero(rsel & csel)
            r0 = 0 if name[0] == "f" else self.n_free
            c0 = 0 if name[1] == "f" else self.n_free
            shape = (self.n_free if name[0] == "f" else 3, self.n_free if name[1] == "f" else 3)
            self._blocks[name] = (sel, u_rows[sel] - r0, u_cols[sel] - c0, shape)
        mass = np.zeros((n_act, d))
        mass[:, :3] = network.mass[act, None]
        if contact:
            mass[:, 3:] = network.rotational_inertia[act, None]
        head = np.asarray(network.plate_inertia if network.plate_inertia is not None
                          else np.zeros(3), float)[:n_head_rot]
        self.mass_free = np.concatenate([mass.ravel(), head])

    def bond_stiffness(self, law, omega: float) -> tuple[np.ndarray, np.ndarray]:
        """Complex normal and tangential stiffness of every bond, (B,) each, N/m.

        k_n = a_b E*(w) (Eqs. 30-33), k_t = k_n / (2 (1 + nu)) (Eqs. 8-11).
        """
        e = complex(law.complex_modulus(omega))
        kn = self.network.scale * e
        return kn, kn * self.t_ratio

    def blocks(self, kn, kt) -> dict:
        """Sparse blocks ff, fp, pf, pp of K(w) for per-bond stiffnesses kn, kt (B,) N/m."""
        kn = np.asarray(kn)[self.keep]
        kt = np.asarray(kt)[self.keep]
        entry = kn[self._src] * self._unit_n + kt[self._src] * self._unit_t
        data = (np.bincount(self._inverse, weights=entry.real, minlength=self._n_uniq)
                + 1j * np.bincount(self._inverse, weights=entry.imag, minlength=self._n_uniq))
        out = {}
        for name, (sel, r, c, shape) in self._blocks.items():
            out[name] = sp.csc_matrix((data[sel], (r, c)), shape=shape)
        return out

    def _reference(self) -> dict:
        """Real reference stiffness G = K(k_n = a_b, k_t = a_b / (2(1+nu))) and its LU factor.

        When every bond follows the same law, K(w) = E*(w) G; G is factorised once per sample.
        """
        if not hasattr(self, "_ref"):
            kn = self.network.scale.astype(complex)
            blk = {k: sp.csc_matrix((v.data.real.copy(), v.indices, v.indptr), shape=v.shape)
                   for k, v in self.blocks(kn, kn * self.t_ratio).items()}
            blk["lu"] = splu_symmetric(blk["ff"]) if self.n_free else None
            self._ref = blk
        return self._ref

    def solve(self, kn, kt, omega: float, amplitude: float = 63e-6,
              inertia: str = "full") -> HarmonicSolution:
        """Steady state for per-bond stiffnesses kn, kt (B,) complex N/m at w (rad/s).

        One complex sparse LU (SuperLU, symmetric mode, MMD(A^T+A) ordering) per call: the
        general path, for bond laws that differ from bond to bond.

        Parameters
        ----------
        amplitude : float
            Head displacement amplitude A, m (paper: 63e-6).
        inertia : {"none", "full"}
            See the module docstring (masses in the dynamics, content of the force F).

        Raises
        ------
        ValueError
            on an unknown option.
        """
        _check_inertia(inertia)
        t0 = time.perf_counter()
        blk = self.blocks(kn, kt)
        up = np.array([amplitude, 0.0, 0.0], complex)
        a_ff = blk["ff"]
        if inertia != "none":
            a_ff = a_ff - omega**2 * sp.diags(self.mass_free.astype(complex), format="csc")
        rhs = -(blk["fp"] @ up)
        uf = splu_symmetric(a_ff).solve(rhs) if self.n_free else np.zeros(0, complex)
        residual = _relative_residual(a_ff, uf, rhs)
        reaction = blk["pf"] @ uf + blk["pp"] @ up
        return self._solution(omega, uf, reaction, amplitude, inertia, residual, t0, "direct")

    def solve_law(self, law, frequency_Hz: float, amplitude: float = 63e-6,
                  inertia: str = "full", solver: str = "reuse",
                  rtol: float = 1e-12) -> HarmonicSolution:
        """Steady state with every bond following ``law`` scaled by a_b (Eqs. 30-33, 8-11).

        Parameters
        ----------
        law : object with ``complex_modulus(omega)`` (Pa), e.g. GeneralizedBurgers
            The macro law; every bond gets k_n = a_b E*(w), k_t = k_n / (2 (1 + nu)).
        frequency_Hz : float
            Test frequency f, Hz (w = 2 pi f).
        solver : {"reuse", "direct"}
            ``reuse``: K(w) = E*(w) G, the real G is factorised once per sample; without
            inertia the solution is a back-substitution, with inertia
            (G - w^2/E* M) u = -G_fp u_p is solved by GMRES preconditioned with G^-1 to the
            relative tolerance ``rtol``; if GMRES does not reach ``rtol`` within 200 x 50
            iterations (near a resonance, or near-mechanisms of G) the call falls back to
            ``direct`` (the solution's ``solver`` then reads "direct").
            ``direct``: one complex LU per call (:meth:`solve`).

        Raises
        ------
        ValueError
            on an unknown option.
        """
        _check_inertia(inertia)
        if solver not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}")
        omega = 2.0 * np.pi * float(frequency_Hz)
        e = complex(law.complex_modulus(omega))
        if solver == "direct":
            kn = self.network.scale * e
            return self.solve(kn, kn * self.t_ratio, omega, amplitude=amplitude, inertia=inertia)
        t0 = time.perf_counter()
        ref = self._reference()
        up = np.array([amplitude, 0.0, 0.0], complex)
        rhs = -(ref["fp"] @ up)
        uf = np.zeros(self.n_free, complex)
        residual = 0.0
        if self.n_free:
            lu = ref["lu"]

            def g_inv(v):
                v = np.asarray(v).ravel()
                return lu.solve(np.ascontiguousarray(v.real)) + 1j * lu.solve(
                    np.ascontiguousarray(v.imag))

            u0 = g_inv(rhs)
            if inertia == "none":
                uf = u0
                residual = _relative_residual(ref["ff"], uf, rhs)
            else:
                shift = omega**2 / e
                m = self.mass_free
                op = spla.LinearOperator((self.n_free,) * 2, dtype=complex,
                                         matvec=lambda v: ref["ff"] @ v - shift * (m * v.ravel()))
                prec = spla.LinearOperator((self.n_free,) * 2, dtype=complex, matvec=g_inv)
                uf, info = spla.gmres(op, rhs.astype(complex), x0=u0, rtol=rtol, atol=0.0,
                                      M=prec, restart=50, maxiter=200)
                if info != 0:
                    # G^-1 is a poor preconditioner when G has near-mechanisms (soft
                    # rotational modes, module docstring): fall back to the complex LU.
                    return self.solve(e * self.network.scale,
                                      e * self.network.scale * self.t_ratio, omega,
                                      amplitude=amplitude, inertia=inertia)
                residual = float(np.linalg.norm(op @ uf - rhs) / np.linalg.norm(rhs))
        reaction = e * (ref["pf"] @ uf + ref["pp"] @ up)
        return self._solution(omega, uf, reaction, amplitude, inertia, residual, t0, "reuse")

    def _solution(self, omega, uf, reaction, amplitude, inertia, residual, t0, solver):
        up = np.array([amplitude, 0.0, 0.0], complex)
        m_top = float(self.network.plate_mass[1])
        sample_mass = self.network.sample_mass
        mu = SPECIMEN_MASS_FACTOR * sample_mass + m_top
        force = reaction - omega**2 * (m_top if inertia == "full" else mu) * up
        d = self.dof_per_sphere
        n_act = int(self.active.sum())
        q = np.asarray(uf)[:d * n_act].reshape(-1, d)
        disp = np.zeros((self.network.n_spheres, 3), complex)
        rot = np.zeros((self.network.n_spheres, 3), complex)
        disp[self.active] = q[:, :3]
        if d == 6:
            rot[self.active] = q[:, 3:]
        head = np.zeros(3, complex)
        if self.head_rotation == "free":
            head = np.asarray(uf)[d * n_act:d * n_act + 3]
        return HarmonicSolution(
            frequency_Hz=omega / (2 * np.pi), force=force, reaction=reaction,
            displacement=disp, amplitude_m=amplitude,
            mu_kg=mu, sample_mass_kg=sample_mass, plate_mass_kg=m_top, inertia=inertia, n_free_dof=self.n_free,
            n_load_free=self.n_load_free, solve_time_s=time.perf_counter() - t0,
            residual=residual, solver=solver, rotation=rot, head_rotation=head)


def _lever(arm) -> np.ndarray:
    """(B, 6, 6) maps [[I, -skew(arm)], [0, I]]: (u, theta) -> (u + theta x arm, theta)."""
    out = np.zeros((len(arm), 6, 6))
    out[:, :3, :3] = np.eye(3)
    out[:, 3:, 3:] = np.eye(3)
    x, y, z = arm[:, 0], arm[:, 1], arm[:, 2]
    # -skew(arm) = [[0, z, -y], [-z, 0, x], [y, -x, 0]]
    out[:, 0, 4], out[:, 0, 5] = z, -y
    out[:, 1, 3], out[:, 1, 5] = -z, x
    out[:, 2, 3], out[:, 2, 4] = y, -x
    return out


def _check_inertia(inertia: str) -> None:
    if inertia not in INERTIA_MODES:
        raise ValueError(f"inertia must be one of {INERTIA_MODES}, got {inertia!r}")


def _relative_residual(a, x, b) -> float:
    norm_b = np.linalg.norm(b)
    return float(np.linalg.norm(a @ x - b) / norm_b) if norm_b > 0 else 0.0
