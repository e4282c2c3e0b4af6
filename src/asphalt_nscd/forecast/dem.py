"""The discrete forecast: a mix's sample, bonds from its mortar, the aggregate skeleton, and its modulus.

The sample of a mix (:mod:`.formulation`, prepared by Section 3.2.1) is tested in uniaxial
compression between its two plates, head clamped, without inertia: the harmonic steady state of
:class:`asphalt_nscd.harmonic.solver.HarmonicSystem` with the head driven along the specimen's
height (``axis=2``), E* = (F / A) / (u / H) = F / (L u) for the cube of side L.

Bond laws (replacing Eqs. 30-33, which calibrate bonds to the mix's own modulus). Every bond is
a mortar bridge: k = e_1(w) g_b, k_t = k / (2 (1 + nu)) (Eqs. 8-11), g_b = pi r_min^2 / (delta0 + t_m)
(the gap left by the shrink to the mix's coarse-aggregate volume, at least the contact tolerance,
plus the mix's mean mortar thickness t_m, :func:`mortar_thickness`); E*_mortar from the binder and
the fines (:mod:`.mortar`, :func:`.mortar.hs_lower_mortar_modulus`).

* ``dem``: e_1 = C_m E*_mortar(w). One constant.
* ``dem_extended`` adds what rigid spheres in a mortar lack: the stones' own compliance in series,
  e_1 = [1 / (C_m E*_mortar) + 1 / (C_a E_agg)]^-1, and the aggregate skeleton: on the pairs in
  contact in the vibrated packing (gap below the project's contact tolerance, 1 % of d_min, before
  the shrink) a contact e_2 g_b, e_2 = C_s E_agg (E*_mortar / E_agg)^n_s, a parabolic element of
  Huet's kind (Huet 1963): n_s = 0 an elastic skeleton, n_s = 1 one that follows the mortar, its
  phase n_s times the mortar's. E_agg = 4.2e6 psi (Hirsch's). Constants C_m, C_a, C_s, n_s.

With e_1 factored out, K(w) = e_1 (G_m + zeta G_s), zeta = e_2 / e_1, G_m and G_s real: the
response is a rational function of the one complex number zeta. :func:`sample_response` solves
G_s,ff v = lambda G_m,ff v once per sample (dense: :func:`pencil_projections`); with u_p the head's unit
displacement, a = G_m,fp u_p, b = G_s,fp u_p, alpha = V^T a, beta = V^T b,

    F(zeta) = u_p.G_m,pp.u_p + zeta u_p.G_s,pp.u_p - sum_k (alpha_k + zeta beta_k)^2 / (1 + zeta lambda_k)

exactly (the Schur complement on the head), at O(n) per zeta: a fold's constants are fitted on
hundreds of (mix, condition) cells without another factorisation. Calibration in each fold
(:class:`DemModel`): least squares of the complex-log residuals (ln|E*|, phase in rad) of the
training mixes (ln C_m in closed form for ``dem``); several seeds: geometric mean of their factors.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from numba import njit

from ..io import InputError

#: aggregate modulus, Pa: 4.2e6 psi (Christensen, Pellinen & Bonaquist 2003, the Hirsch model)
E_AGGREGATE_PA = 4.2e6 * 6894.757293168361
MODELS = ("dem", "dem_extended")


@dataclass
class Response:
    """The uniaxial response of one sample as a function of zeta (module docstring).

    ``lam, alpha, beta`` (n,) float: the generalized eigenvalues and the projections of the
    head's coupling vectors; ``p0, p1`` float (N/m per unit modulus); ``side_m``: L.
    """

    mix_id: str
    seed: int
    side_m: float
    p0: float
    p1: float
    lam: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    n_spheres: int
    n_bonds: int
    n_skeleton: int
    p1_f: float = np.nan
    lam_f: np.ndarray = field(default_factory=lambda: np.zeros(0))
    alpha_f: np.ndarray = field(default_factory=lambda: np.zeros(0))
    beta_f: np.ndarray = field(default_factory=lambda: np.zeros(0))
    chi_bridge: float = np.nan
    skeleton_r15: float = np.nan
    #: V / sum of the skeleton contacts' branch lengths (m^2): a stress sigma gives them the mean normal force
    #: sigma V / sum(l) (Love-Weber: sigma_kk V = sum_c N_c l_c); NaN without skeleton contacts
    skeleton_v_over_l: float = np.nan
    #: <R_eff^(5/3)> over the skeleton contacts, weighted as the film decomposition (R_eff^2), m^(5/3)
    skeleton_r53: float = np.nan
    #: (B,) each bond's shape factor as a layer of mortar bonded to its two stones, S_b = a / (2 h) = g_b / (2 pi a)
    #: (a = r_min the bond's radius, h its length, :func:`bond_geometry`): the loaded area pi a^2 over the free
    #: lateral area 2 pi a h (:func:`.mortar.confined_modulus`); empty in a response written before the confined bridges
    bridge_shape: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: (B,) each bond's geometric factor g_b (m; :func:`bond_geometry`), the weight of its shape factor
    bridge_weight: np.ndarray = field(default_factory=lambda: np.zeros(0))
    cpu_s: float = 0.0
    #: the sample variant (:func:`.formulation.variant_name`); "" for the base sample
    variant: str = ""

    @classmethod
    def empty(cls, mix_id: str, seed: int, sample) -> "Response":
        """The response of a sample that carries no load between its plates: NaN everywhere, so
        that the discrete models forecast its mix as missing and leave it out of their fits."""
        return cls(
            str(mix_id),
            int(seed),
            float(sample.attrs.get("h_m", np.nan)),
            np.nan,
            np.nan,
            np.zeros(0),
            np.zeros(0),
            np.zeros(0),
            int(sample.radius.size),
            int(sample.bonds["i"].size),
            0,
        )

    @property
    def usable(self) -> bool:
        return bool(np.isfinite(self.p0))

    def factor(self, zeta, skeleton: str = "mortar") -> np.ndarray:
        """E*_sample / e_1 at each zeta (complex array): F(zeta) / L (``skeleton``: :meth:`factor_and_slope`)."""
        p1, lam, alpha, beta = self._pencil(skeleton)
        z = np.asarray(zeta, complex)
        flat = np.ascontiguousarray(z.ravel())
        s = _schur_sum(
            flat,
            np.ascontiguousarray(lam, float),
            np.ascontiguousarray(alpha, float),
            np.ascontiguousarray(beta, float),
        )
        return (self.p0 + z * p1 - s.reshape(z.shape)) / self.side_m

    def _pencil(self, skeleton: str):
        if skeleton == "mortar":
            return self.p1, self.lam, self.alpha, self.beta
        if skeleton == "film":
            return self.p1_f, self.lam_f, self.alpha_f, self.beta_f
        raise ValueError(f"skeleton weighting {skeleton!r}: expected 'mortar' or 'film'")

    def factor_and_slope(self, zeta, skeleton: str = "mortar") -> tuple[np.ndarray, np.ndarray]:
        """:meth:`factor` and its derivative with respect to zeta, at each zeta (complex arrays).

        ``skeleton``: ``mortar`` (the skeleton pairs weighted as mortar bridges, g_b; ``dem_extended``)
        or ``film`` (weighted R_eff^2, the squeeze film of a contact: :mod:`.physical`)."""
        p1, lam, alpha, beta = self._pencil(skeleton)
        z = np.asarray(zeta, complex)
        s, ds = _schur_sum_and_slope(
            np.ascontiguousarray(z.ravel()),
            np.ascontiguousarray(lam, float),
            np.ascontiguousarray(alpha, float),
            np.ascontiguousarray(beta, float),
        )
        return (self.p0 + z * p1 - s.reshape(z.shape)) / self.side_m, (p1 - ds.reshape(z.shape)) / self.side_m

    def save(self, path) -> None:
        """Write the response (``.npz``, atomic)."""
        from ..io import atomic_path

        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            arrays: dict = {k: np.asarray(v) for k, v in self.__dict__.items()}
            np.savez(fh, **arrays)

    @classmethod
    def load(cls, path) -> "Response":
        """Read a response written by :meth:`save`; InputError naming the file otherwise."""
        try:
            with np.load(path) as data:
                kw = {k: data[k] for k in data.files}
        except (OSError, ValueError) as exc:
            raise InputError(f"{path}: not a DEM response file of 'forecast-response' ({exc})") from None
        kw.setdefault("variant", "")  # written before sample variants existed: the base sample
        for name in ("skeleton_v_over_l", "skeleton_r53"):  # written before the Hertz contacts: unknown
            kw.setdefault(name, np.nan)
        for name in ("bridge_shape", "bridge_weight"):  # written before the confined bridges: unknown
            kw.setdefault(name, np.zeros(0))
        missing = sorted(set(cls.__dataclass_fields__) - set(kw))
        if missing:
            raise InputError(f"{path}: DEM response without {missing}")
        scalars = {"mix_id": str, "seed": int, "side_m": float, "p0": float, "p1": float, "p1_f": float}
        scalars |= {"n_spheres": int, "n_bonds": int, "n_skeleton": int, "cpu_s": float}
        scalars |= {"chi_bridge": float, "skeleton_r15": float, "variant": str}
        scalars |= {"skeleton_v_over_l": float, "skeleton_r53": float}
        return cls(**{k: (scalars[k](kw[k]) if k in scalars else kw[k]) for k in cls.__dataclass_fields__})


@njit(cache=True)
def _schur_sum(zeta, lam, alpha, beta):  # pragma: no cover - compiled
    """sum_k (alpha_k + zeta beta_k)^2 / (1 + zeta lam_k) for each zeta: (m,) complex."""
    out = np.empty(zeta.size, np.complex128)
    for i in range(zeta.size):
        zr, zi = zeta[i].real, zeta[i].imag
        sr = 0.0
        si = 0.0
        for k in range(lam.size):
            ar = alpha[k] + zr * beta[k]
            ai = zi * beta[k]
            nr = ar * ar - ai * ai  # (alpha + zeta beta)^2
            ni = 2.0 * ar * ai
            dr = 1.0 + zr * lam[k]
            di = zi * lam[k]
            inv = 1.0 / (dr * dr + di * di)
            sr += (nr * dr + ni * di) * inv
            si += (ni * dr - nr * di) * inv
        out[i] = complex(sr, si)
    return out


@njit(cache=True)
def _schur_sum_and_slope(zeta, lam, alpha, beta):  # pragma: no cover - compiled
    """:func:`_schur_sum` and its derivative with respect to zeta, sum_k q_k (2 beta_k - lam_k q_k) with
    q_k = (alpha_k + zeta beta_k) / (1 + zeta lam_k): two (m,) complex arrays."""
    s = np.empty(zeta.size, np.complex128)
    ds = np.empty(zeta.size, np.complex128)
    for i in range(zeta.size):
        zr, zi = zeta[i].real, zeta[i].imag
        sr = 0.0
        si = 0.0
        tr = 0.0
        ti = 0.0
        for k in range(lam.size):
            ar = alpha[k] + zr * beta[k]
            ai = zi * beta[k]
            dr = 1.0 + zr * lam[k]
            di = zi * lam[k]
            inv = 1.0 / (dr * dr + di * di)
            qr = (ar * dr + ai * di) * inv  # q = a / d
            qi = (ai * dr - ar * di) * inv
            sr += ar * qr - ai * qi  # a q = a^2 / d
            si += ar * qi + ai * qr
            wr = 2.0 * beta[k] - lam[k] * qr
            wi = -lam[k] * qi
            tr += qr * wr - qi * wi
            ti += qr * wi + qi * wr
        s[i] = complex(sr, si)
        ds[i] = complex(tr, ti)
    return s, ds


def shrink_factor(sample) -> float:
    """The radius factor of the sample's shrink: its recorded ``shrink_radius_factor``, else the
    smallest radius over half the smallest class diameter (every sphere shrinks by one factor)."""
    if "shrink_radius_factor" in sample.attrs:
        return float(sample.attrs["shrink_radius_factor"])
    return float(2.0 * sample.radius.min() / float(sample.attrs["d_min_m"]))


def mortar_thickness(sample) -> float:
    """t_m (m): the mortar's volume per unit area of the spheres' surface in the specimen,
    (1 - phi) / (3 phi) r_32 with phi the spheres' volume fraction and r_32 their Sauter mean
    radius: the mean thickness of the matrix around a coarse particle, added to each bond's gap."""
    r = sample.radius
    phi = float((4.0 / 3.0) * np.pi * np.sum(r**3) / (sample.attrs["B_m"] * sample.attrs["e_m"] * sample.attrs["h_m"]))
    return float((1.0 - phi) / (3.0 * phi) * np.sum(r**3) / np.sum(r**2))


def skeleton_bonds(sample, tolerance: float | None = None) -> np.ndarray:
    """(B,) bool: the bonds whose bodies were in contact in the vibrated packing, before the
    shrink: gap below ``tolerance`` (m; default the project's contact tolerance, 1 % of d_min,
    :data:`asphalt_nscd.sample.prepare.CONTACT_TOLERANCE`)."""
    from ..sample.prepare import CONTACT_TOLERANCE

    tol = CONTACT_TOLERANCE * float(sample.attrs["d_min_m"]) if tolerance is None else tolerance
    f = shrink_factor(sample)
    b = sample.bonds
    r = sample.radius
    i, j = b["i"], b["j"]
    grown = r[i] * (1.0 / f - 1.0) + np.where(j >= 0, r[np.maximum(j, 0)] * (1.0 / f - 1.0), 0.0)
    return (b["delta0"] - grown) < tol


def bond_geometry(sample) -> tuple[np.ndarray, np.ndarray]:
    """(g, skeleton): each bond's geometric factor g_b = pi r_min^2 / (max(delta0, tol) + t_m) (m;
    module docstring, tol the contact tolerance) and the (B,) bool mask of :func:`skeleton_bonds`.
    A bond's normal stiffness is e_1 g_b (1 + zeta skeleton_b), N/m."""
    from ..sample.prepare import CONTACT_TOLERANCE

    film = np.maximum(sample.bonds["delta0"], CONTACT_TOLERANCE * float(sample.attrs["d_min_m"]))
    return np.pi * sample.bonds["r_min"] ** 2 / (film + mortar_thickness(sample)), skeleton_bonds(sample)


def bond_moduli(state: dict, e_mortar) -> tuple[np.ndarray, np.ndarray]:
    """(e_1, zeta) of ``dem_extended`` (module docstring) for the constants ``state`` (``C_m, C_a,
    C_s, n_s``; ``dem``: ``C_m`` alone) and the mortar's complex modulus ``e_mortar`` (Pa, array):
    e_1 Pa complex, zeta = e_2 / e_1 complex."""
    e = np.asarray(e_mortar, complex)
    c_a, c_s, n_s = state.get("C_a", np.inf), state.get("C_s", 0.0), state.get("n_s", 0.0)
    u = 1.0 / (state["C_m"] * e)
    v = 0.0 if c_a == np.inf else 1.0 / (c_a * E_AGGREGATE_PA)
    zeta = c_s * E_AGGREGATE_PA * np.exp(n_s * np.log(e / E_AGGREGATE_PA)) * (u + v)
    return 1.0 / (u + v), zeta


def sample_response(sample, mix_id: str = "", seed: int = 0) -> Response:
    """The :class:`Response` of a prepared cube (module docstring).

    Raises InputError if the sample's head carries no bond, the mortar network has a free mode or
    LAPACK fails on its generalized eigenproblem."""
    import scipy.linalg as sl

    from ..harmonic.network import network_from_sample
    from ..harmonic.solver import HarmonicSystem

    t0 = time.process_time()
    network = network_from_sample(sample)
    system = HarmonicSystem(network, head_rotation="clamped")
    g, skel = bond_geometry(sample)
    gm = system.blocks(g, g * system.t_ratio)
    gs = system.blocks(g * skel, g * skel * system.t_ratio)
    a, b = gm["fp"][:, 2].toarray().ravel(), gs["fp"][:, 2].toarray().ravel()
    if not np.any(a):
        raise InputError(f"sample {sample.name}: no bond reaches the head plate")
    A, B = gm["ff"].toarray(), gs["ff"].toarray()
    reff = contact_radius(sample)
    w = reff**2 * skel
    gf = system.blocks(w, w * system.t_ratio)
    b_f = gf["fp"][:, 2].toarray().ravel()
    try:
        chol = sl.cholesky(A, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        raise InputError(f"sample {sample.name}: the mortar network has a free mode (G_m not positive definite)")
    try:
        lam, (alpha0, beta) = pencil_projections(chol, B, [a, b])
        lam_f, (alpha_f, beta_f) = pencil_projections(chol, gf["ff"].toarray(), [a, b_f])
    except np.linalg.LinAlgError as exc:  # LAPACK's failure, as the full eigh raised it before
        raise InputError(f"sample {sample.name}: the generalized eigenproblem of its network failed ({exc})")
    r_bond = sample.bonds["r_min"]
    i, j = sample.bonds["i"], sample.bonds["j"]
    branch = sample.radius[i] + np.where(j >= 0, sample.radius[np.maximum(j, 0)], 0.0)  # a wall contact: r_i
    volume = float(sample.attrs["B_m"] * sample.attrs["e_m"] * sample.attrs["h_m"])
    return Response(
        mix_id=str(mix_id),
        seed=int(seed),
        side_m=float(sample.attrs["h_m"]),
        p0=float(gm["pp"][2, 2]),
        p1=float(gs["pp"][2, 2]),
        lam=lam,
        alpha=alpha0,
        beta=beta,
        n_spheres=int(sample.radius.size),
        n_bonds=int(sample.bonds["i"].size),
        n_skeleton=int(skel.sum()),
        p1_f=float(gf["pp"][2, 2]),
        lam_f=lam_f,
        alpha_f=alpha_f,
        beta_f=beta_f,
        chi_bridge=float((gm["pp"][2, 2] - alpha0 @ alpha0) / _head_stiffness(system, r_bond)),
        skeleton_r15=float(np.sum(w * reff**1.5) / np.sum(w)) if np.any(skel) else np.nan,
        skeleton_v_over_l=float(volume / np.sum(branch[skel])) if np.any(skel) else np.nan,
        skeleton_r53=float(np.sum(w * reff ** (5.0 / 3.0)) / np.sum(w)) if np.any(skel) else np.nan,
        bridge_shape=g / (2.0 * np.pi * r_bond),  # S_b = a / (2 h) = g_b / (2 pi a), a = r_min, g_b = pi a^2 / h
        bridge_weight=np.asarray(g, float),
        cpu_s=time.process_time() - t0,
    )


def pencil_projections(chol: np.ndarray, M: np.ndarray, vectors) -> tuple[np.ndarray, list[np.ndarray]]:
    """The generalized eigenvalues of M v = lambda A v, A = L L^T, and the projections V^T x of each x of
    ``vectors`` on the A-orthonormal eigenvectors V, without forming V.

    ``chol``: (n, n) the lower Cholesky factor L of A (SPD); ``M``: (n, n) symmetric; ``vectors``: (n,)
    arrays. Returns lam (n,) ascending and one (n,) array per vector. With C = L^-1 M L^-T = U diag(lam) U^T,
    V = L^-T U and V^T x = U^T (L^-1 x); C is reduced to tridiagonal form T = Q^T C Q (LAPACK ``sytrd``, the
    blocked Householder reduction), T = W diag(lam) W^T by divide and conquer (``stevd``, the tridiagonal
    only), and U^T y = W^T (Q^T y) with Q's reflectors applied to the vectors (O(n^2) each): the back
    transformations of the eigenvectors (the O(n^3) part of a full ``eigh`` past the reduction) are not
    done. Each eigenvector's sign is LAPACK's choice, as in ``eigh``: the Schur sums use products of two
    projections only. Raises numpy.linalg.LinAlgError if LAPACK reports a failure (Golub & Van Loan 2013,
    sections 8.3 and 8.4; Cuppen 1981)."""
    import scipy.linalg as sl
    from scipy.linalg import lapack

    n = chol.shape[0]
    c, info = lapack.dsygst(M, chol, itype=1, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"dsygst: info {info}")
    lwork = int(lapack.dsytrd_lwork(n, lower=1)[0])
    c, d, e, tau, info = lapack.dsytrd(c, lower=1, lwork=max(lwork, 1), overwrite_a=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"dsytrd: info {info}")
    lam, w, info = lapack.dstevd(d, e, compute_v=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"dstevd: info {info}")
    y = sl.solve_triangular(chol, np.column_stack(vectors), lower=True, check_finite=False)
    for i in range(n - 1):  # Q^T y = H(n-1) ... H(1) y, H(i) = I - tau_i v v^T, v = (0.., 1, c[i+2:, i])
        v = c[i + 1 :, i].copy()
        v[0] = 1.0
        y[i + 1 :] -= tau[i] * np.outer(v, v @ y[i + 1 :])
    p = w.T @ y
    return lam, [p[:, k].copy() for k in range(p.shape[1])]


def _head_stiffness(system, k) -> float:
    """The head's stiffness (N/m, along the height) of the network with bond stiffnesses k (B,) N/m
    (tangential k times the Eqs. 8-11 ratio): a real sparse solve."""
    blk = system.blocks(k, k * system.t_ratio)
    u = system.factorise(blk["ff"], "head stiffness").solve(-blk["fp"][:, 2].toarray().ravel())
    return float(blk["pp"][2, 2] + (blk["pf"] @ u)[2])


def contact_radius(sample) -> np.ndarray:
    """(B,) m: each bond's effective radius R_eff = r_i r_j / (r_i + r_j) (a sphere-plate bond: r_i)."""
    r = sample.radius
    i, j = sample.bonds["i"], sample.bonds["j"]
    rj = np.where(j >= 0, r[np.maximum(j, 0)], np.inf)
    return 1.0 / (1.0 / r[i] + 1.0 / rj)


def time_domain_check(
    sample, e1: complex, zeta: complex, frequency_Hz: float, steps_per_cycle: int = 400, **kw
) -> dict:
    """The forecast's modulus of ``sample`` at one condition checked in the time domain: the bonds
    e_1 g_b (1 + zeta skeleton_b) (:func:`bond_geometry`; tangential times the Eqs. 8-11 ratio)
    stepped by the NSCD core (:func:`asphalt_nscd.harmonic.timedomain.uniaxial_time_domain_row`),
    against the harmonic solve of the same network with the spheres' inertia (the time domain's
    exact twin) and the quasi-static :class:`Response` the forecast uses.

    e1 : complex Pa; zeta : complex; frequency_Hz : Hz; ``kw``: passed to the time-domain row.

    Returns
    -------
    dict
        ``E_time_domain_MPa, phase_time_domain_deg``, ``E_harmonic_MPa, phase_harmonic_deg``,
        ``E_response_MPa, phase_response_deg`` (E* = F / (L u)), ``td_vs_harmonic_E_pct,
        td_vs_harmonic_phase_deg``, ``inertia_E_pct`` (harmonic with inertia against the
        quasi-static response), ``steps_per_cycle, n_steps, n_nonlinear_steps, cpu_s``.
    """
    from ..harmonic.network import network_from_sample
    from ..harmonic.solver import HarmonicSystem
    from ..harmonic.timedomain import uniaxial_time_domain_row

    g, skel = bond_geometry(sample)
    system = HarmonicSystem(network_from_sample(sample), head_rotation="clamped")
    kn = e1 * g * (1.0 + zeta * skel)
    td = uniaxial_time_domain_row(sample, kn, kn * system.t_ratio, frequency_Hz, steps_per_cycle=steps_per_cycle, **kw)
    omega, side = 2.0 * np.pi * frequency_Hz, float(sample.attrs["h_m"])
    harmonic = system.solve(kn, kn * system.t_ratio, omega, amplitude=1.0, inertia="full", axis=2).reaction[2]
    quasi_static = e1 * sample_response(sample).factor(zeta) * side
    out = {}
    for name, k in (("time_domain", td["stiffness"]), ("harmonic", harmonic), ("response", quasi_static)):
        out[f"E_{name}_MPa"] = float(abs(k) / side / 1e6)
        out[f"phase_{name}_deg"] = float(np.degrees(np.angle(k)))
    out["td_vs_harmonic_E_pct"] = 100.0 * (out["E_time_domain_MPa"] / out["E_harmonic_MPa"] - 1.0)
    out["td_vs_harmonic_phase_deg"] = out["phase_time_domain_deg"] - out["phase_harmonic_deg"]
    out["inertia_E_pct"] = 100.0 * (out["E_harmonic_MPa"] / out["E_response_MPa"] - 1.0)
    out.update({"steps_per_cycle": steps_per_cycle, **{k: td[k] for k in ("n_steps", "n_nonlinear_steps", "cpu_s")}})
    return out


#: starting points (ln C_m, ln C_a, ln C_s, n_s) of the ``dem_extended`` least squares; on the shipped
#: table starts spread over this box reach one optimum on both binder routes (``starts_agree``)
STARTS = ((0.0, 0.0, -4.0, 0.2), (4.0, 1.0, -6.0, 0.6))
#: bounds of ln C of every constant
LN_BOUNDS = (-25.0, 25.0)
#: bounds of the skeleton's exponent n_s: 0 an elastic skeleton, 1 one that follows the mortar
N_BOUNDS = (0.0, 1.0)


class DemModel:
    """``dem`` or ``dem_extended`` with its constants fitted on the training mixes of a fold.

    Parameters
    ----------
    name : one of :data:`MODELS`.
    responses : mix_id -> list of :class:`Response` (one per seed).
    cut_mm : the samples' PSD cut (the mortar's fine aggregate is what passes it).
    skeleton_exponent : n_s held at this value (0: the elastic skeleton) instead of fitted.
    """

    coefficients = "recalibrated"

    def __init__(self, name: str, responses: dict, cut_mm: float, skeleton_exponent: float | None = None):
        if name not in MODELS:
            raise InputError(f"DEM model {name!r}: expected one of {MODELS}")
        self.model, self.responses, self.cut_mm = name, responses, float(cut_mm)
        self.skeleton_exponent = skeleton_exponent

    def available(self, table: pd.DataFrame) -> bool:
        """Whether some mix of ``table`` has a usable sample response (the others are forecast as
        missing values and left out of the fits)."""
        usable = {m for m, resp in self.responses.items() if all(r.usable for r in resp)}
        return bool(usable & set(table["mix_id"]))

    def _cells(self, rows: pd.DataFrame) -> list:
        """(row indices, E*_mortar (Pa), responses) per mix of ``rows``."""
        from .formulation import phase_volumes
        from .mortar import hs_lower_mortar_modulus as mortar_modulus

        out = []
        for mix_id, idx in rows.groupby("mix_id", sort=False).indices.items():
            if mix_id not in self.responses:
                raise InputError(f"DEM model: no sample response for mix {mix_id!r}")
            if not all(resp.usable for resp in self.responses[mix_id]):
                continue  # a sample that carries no load: forecast as missing
            r = rows.iloc[idx]
            v = phase_volumes(r.iloc[0], self.cut_mm)
            G, d = r["binder_G_mix_MPa"].to_numpy(float) * 1e6, r["binder_delta_mix_deg"].to_numpy(float)
            out.append((idx, mortar_modulus(G, d, v["phi_filler"], v["phi_fine"]), self.responses[mix_id]))
        return out

    def _log_modulus(self, cells: list, n: int, x, slopes: bool = False):
        """ln E*_sample (Pa, complex) of every row for the constants x = (ln C_m, ln C_a, ln C_s,
        n_s), and with ``slopes`` its derivatives with respect to them, (n, 4) complex (module
        docstring)."""
        out = np.full(n, np.nan + 0j)
        jac = np.zeros((n, 4), complex)
        c_m, c_a, c_s = np.exp(x[:3])
        state = {"C_m": c_m, "C_a": c_a, "C_s": c_s, "n_s": x[3]}
        for idx, e, responses in cells:
            e1, zeta = bond_moduli(state, e)
            ratio = np.log(e / E_AGGREGATE_PA)
            fs = [resp.factor_and_slope(zeta) for resp in responses]
            out[idx] = np.log(e1) + np.mean([np.log(f) for f, _ in fs], axis=0)
            if slopes:
                g = zeta * np.mean([d / f for f, d in fs], axis=0)  # d ln(factor) / d ln(zeta)
                wu = e1 / (c_m * e)  # the mortar's share of the bond's compliance, u / (u + v)
                wv = 1.0 - wu
                jac[idx] = np.column_stack([wu * (1.0 - g), wv * (1.0 - g), g, g * ratio])
        return (out, jac) if slopes else out

    def fit(self, train: pd.DataFrame) -> dict:
        """The constants of a fold, by least squares of the complex-log residuals of the training
        rows (module docstring): ``C_m`` (``dem``), ``C_m, C_a, C_s, n_s`` (``dem_extended``), with
        the in-sample ``cost`` and ``at_bound`` (a constant at :data:`LN_BOUNDS` or :data:`N_BOUNDS`)."""
        from scipy.optimize import least_squares

        rows = train.dropna(subset=["E_norm_MPa", "phase_deg"])
        usable = {m for m, resp in self.responses.items() if all(r.usable for r in resp)}
        rows = rows[rows["mix_id"].isin(usable)].reset_index(drop=True)
        y = np.log(rows["E_norm_MPa"].to_numpy(float) * 1e6) + 1j * np.radians(rows["phase_deg"].to_numpy(float))
        cells = self._cells(rows)
        if self.model == "dem":
            lf = self._log_modulus(cells, len(rows), (0.0, np.inf, -np.inf, 0.0))
            ln_c = float(np.mean(y.real - lf.real))
            res = y - lf - ln_c
            return {"C_m": float(np.exp(ln_c)), "cost": float(np.sum(np.abs(res) ** 2) / 2), "n_rows": len(rows)}

        memo: dict = {}

        def evaluate(x):
            key = tuple(np.asarray(x, float))
            if key not in memo:
                memo.clear()
                memo[key] = self._log_modulus(cells, len(rows), x, slopes=True)
            return memo[key]

        def resid(x):
            r = evaluate(x)[0] - y
            return np.concatenate([r.real, r.imag])

        def jac(x):
            j = evaluate(x)[1]
            return np.concatenate([j.real, j.imag])

        lower, upper = [LN_BOUNDS[0]] * 3 + [N_BOUNDS[0]], [LN_BOUNDS[1]] * 3 + [N_BOUNDS[1]]
        if self.skeleton_exponent is not None:  # n_s held: a bound pair of width 0 is not allowed, so 1e-12
            n = float(self.skeleton_exponent)
            lower[3], upper[3] = n, n + 1e-12
        starts = [(*x0[:3], min(max(x0[3], lower[3]), upper[3])) for x0 in STARTS]
        fits = [least_squares(resid, x0, jac=jac, bounds=(lower, upper)) for x0 in starts]
        best = min(fits, key=lambda f: f.cost)
        c = np.exp(best.x[:3])
        at_bound = np.isclose(best.x, lower, atol=1e-3) | np.isclose(best.x, upper, atol=1e-3)
        at_bound[3] &= self.skeleton_exponent is None
        return {
            "C_m": float(c[0]),
            "C_a": float(c[1]),
            "C_s": float(c[2]),
            "n_s": float(best.x[3]),
            "at_bound": bool(at_bound.any()),
            "starts_agree": bool(max(f.cost for f in fits) - best.cost <= 1e-6 * max(best.cost, 1e-12)),
            "cost": float(best.cost),
            "n_rows": len(rows),
        }

    def predict(self, state: dict, rows: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, str]:
        """(|E*| MPa, phase deg, "model") of ``rows`` with the fold's constants ``state``."""
        x = (
            (np.log(state["C_m"]), np.inf, -np.inf, 0.0)
            if self.model == "dem"
            else (*np.log([state["C_m"], state["C_a"], state["C_s"]]), state["n_s"])
        )
        lf = self._log_modulus(self._cells(rows), len(rows), x)
        return np.exp(lf.real) / 1e6, np.degrees(lf.imag), "model"
