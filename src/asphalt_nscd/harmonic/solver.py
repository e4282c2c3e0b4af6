"""Periodic steady state of a bonded sample under a harmonic head displacement.

In the small-strain complex modulus test no bond breaks and no frictional contact opens or
closes, so the numerical sample is a linear viscoelastic network of rigid spheres. Under the
imposed top-plate displacement x_top(t) = Re(A e^{i w t}) every unknown is a phasor, and the
steady state solves one complex sparse linear system per (T, f):

    (K(w) - w^2 M)_ff u_f = -K(w)_fp u_p,           u_p = (A, 0, 0)   (top plate)

Model (docs/design.md, "Bond law")
----------------------------------
* 3 translational DOF per sphere: the bond force acts at the barycentres and carries no
  torque, so rotations neither load nor are loaded by the bonds and drop out.
* Bond b between bodies a and c with unit vector n (initial frame) has the complex 3x3
  stiffness  K_b(w) = k_n(w) n n^T + k_t(w) (I - n n^T)  with
  k_n(w) = a_b E*(w),  a_b = pi r_min^2 / l0  (Eqs. 30-33),  k_t = k_n / (2 (1 + nu))
  (Eqs. 8-11), E*(w) the complex modulus of the macro law (Burger's, Eqs. 27-29, or any
  :class:`~asphalt_nscd.rheology.laws.GeneralizedBurgers`; any object with a
  ``complex_modulus(omega)`` method works). It is the exact frequency response of the
  time-domain bond law (Maxwell + Kelvin-Voigt in series per direction, Eqs. 15-24) when
  every bond stays intact and the rotation of the frame is negligible (small strain).
* Bottom plate fixed; top plate translated by (A, 0, 0) (imposed, the paper's "z" is along x).
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

from ..rheology.laws import tangential_ratio
from .network import BondNetwork

INERTIA_MODES = ("none", "full")
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
    """

    def __init__(self, network: BondNetwork, nu: float = 0.35):
        self.network = network
        self.t_ratio = tangential_ratio(nu)
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
        # DOF numbering: active spheres 0..3n_act-1 (free), then the top plate (3 prescribed).
        body = -np.ones(n_sph + 2, np.int64)  # body index -> column block; -1 = not a DOF
        body[np.flatnonzero(self.active)] = np.arange(self.active.sum())
        n_act = int(self.active.sum())
        body[n_sph + 1] = n_act  # top plate (j = -2 -> n_sph + 1 after the shift below)
        self.n_free = 3 * n_act
        a_body = body[i]
        c_body = body[np.where(j >= 0, j, n_sph - 1 - j)]  # j=-1 -> n_sph (bottom), -2 -> top
        self.keep = a_body >= 0  # bonds of load-free clusters carry nothing
        a_body, c_body = a_body[self.keep], c_body[self.keep]
        n = network.normal[self.keep]
        self.pn = np.einsum("bk,bl->bkl", n, n).reshape(-1, 9)
        self.pt = np.eye(3).reshape(1, 9) - self.pn
        # COO entries of the four blocks (a,a), (c,c), (a,c), (c,a); bottom plate dropped.
        loc_r = np.repeat(np.arange(3), 3)
        loc_c = np.tile(np.arange(3), 3)
        rows, cols, sign, src = [], [], [], []
        nb = len(a_body)
        bidx = np.arange(nb)
        has_c = c_body >= 0
        for ra, ca, s, mask in ((a_body, a_body, 1.0, np.ones(nb, bool)),
                                (c_body, c_body, 1.0, has_c),
                                (a_body, c_body, -1.0, has_c),
                                (c_body, a_body, -1.0, has_c)):
            rows.append((3 * ra[mask])[:, None] + loc_r)
            cols.append((3 * ca[mask])[:, None] + loc_c)
            sign.append(np.full(mask.sum(), s))
            src.append(bidx[mask])
        rows = np.concatenate(rows).ravel()
        cols = np.concatenate(cols).ravel()
        self._sign = np.concatenate(sign)
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
        self.mass_free = np.repeat(network.mass[self.active], 3)

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
        vals = (kn[:, None] * self.pn + kt[:, None] * self.pt)  # (B, 9)
        entry = (vals[self._src] * self._sign[:, None]).ravel()
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
            blk["lu"] = _factorise(blk["ff"]) if self.n_free else None
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
        uf = _factorise(a_ff).solve(rhs) if self.n_free else np.zeros(0, complex)
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
            relative tolerance ``rtol``. ``direct``: one complex LU per call (:meth:`solve`).

        Raises
        ------
        ValueError
            on an unknown option, or if GMRES does not reach ``rtol``.
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
                    raise ValueError(f"GMRES did not reach rtol={rtol} (info={info}) at "
                                     f"f={frequency_Hz} Hz: the frequency may be near a "
                                     "resonance of the sample; use solver='direct'")
                residual = float(np.linalg.norm(op @ uf - rhs) / np.linalg.norm(rhs))
        reaction = e * (ref["pf"] @ uf + ref["pp"] @ up)
        return self._solution(omega, uf, reaction, amplitude, inertia, residual, t0, "reuse")

    def _solution(self, omega, uf, reaction, amplitude, inertia, residual, t0, solver):
        up = np.array([amplitude, 0.0, 0.0], complex)
        m_top = float(self.network.plate_mass[1])
        sample_mass = self.network.sample_mass
        mu = SPECIMEN_MASS_FACTOR * sample_mass + m_top
        force = reaction - omega**2 * (m_top if inertia == "full" else mu) * up
        disp = np.zeros((self.network.n_spheres, 3), complex)
        disp[self.active] = np.asarray(uf).reshape(-1, 3)
        return HarmonicSolution(
            frequency_Hz=omega / (2 * np.pi), force=force, reaction=reaction,
            displacement=disp, amplitude_m=amplitude,
            mu_kg=mu, sample_mass_kg=sample_mass, plate_mass_kg=m_top, inertia=inertia, n_free_dof=self.n_free,
            n_load_free=self.n_load_free, solve_time_s=time.perf_counter() - t0,
            residual=residual, solver=solver)


def _check_inertia(inertia: str) -> None:
    if inertia not in INERTIA_MODES:
        raise ValueError(f"inertia must be one of {INERTIA_MODES}, got {inertia!r}")


def _factorise(a):
    """SuperLU factor of a sparse matrix with symmetric pattern (symmetric mode, MMD(A^T+A))."""
    a = sp.csc_matrix(a, copy=True)
    a.sort_indices()
    a.data = np.ascontiguousarray(a.data)
    return spla.splu(a, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})


def _relative_residual(a, x, b) -> float:
    norm_b = np.linalg.norm(b)
    return float(np.linalg.norm(a @ x - b) / norm_b) if norm_b > 0 else 0.0
