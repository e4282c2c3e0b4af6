"""The mortar the discrete model's bonds carry: binder, filler, fine aggregate and air, by micromechanics.

Phases (volume fractions: :func:`asphalt_nscd.forecast.formulation.phase_volumes`): binder +
filler (below 0.075 mm) = mastic; mastic + air voids = porous mastic; porous mastic + fine
aggregate (0.075 mm to the PSD cut) = mortar, the matrix between the discrete model's spheres.
Where the air voids sit is a choice (``air_phase``, :data:`AIR_PHASES`): ``mastic`` (the default)
homogenizes them with the filler; ``mortar`` adds them last, to the mortar of dense mastic and fine
aggregate (voids of 0.1 mm to a few mm are the size of the fine aggregate, not of the filler);
``pockets`` leaves the mortar dense, the voids between the coarse stones; ``binder`` puts them in
the binder, every inclusion's fraction over the space it shares with the air. Every phase is
isotropic and linear viscoelastic; by the correspondence principle (Hashin 1965, J. Appl. Mech. 32,
630-636) an elastic estimate written for complex K*, G* gives the composite's complex moduli at one
frequency and temperature. Stone (filler and fine aggregate): real K_s, G_s from E_s, nu_s. Binder: complex
G_b* from its master curve, real bulk modulus K_b (glassy binder is compressible; at warm
temperatures |G_b*| << K_b and the binder is nearly incompressible). Air: K = G = 0.

Estimate: the differential scheme (Roscoe 1952; McLaughlin 1977; Norris 1985, Mech. Mater. 4,
1-16): inclusions are added in small steps, each step dilute in the current composite. For
spherical inclusions j of fraction dphi in a matrix (K, G), with zeta(K, G) = G (9K + 8G) /
(6 (K + 2G)):

    dK = sum_j w_j (K_j - K) (K + 4G/3) / (K_j + 4G/3) dphi / c(phi)
    dG = sum_j w_j (G_j - G) (G + zeta) / (G_j + zeta)  dphi / c(phi)

with w_j each inclusion's share and the crowding factor c(phi) = 1 - phi / phi_max: an added
particle replaces only the matrix not already trapped between particles, so the estimate
stiffens without bound as phi approaches the packing limit phi_max for rigid particles (the
Krieger-Dougherty law G / G_m = (1 - phi / phi_max)^(-2.5 phi_max) for rigid spheres in an
incompressible matrix: Krieger & Dougherty 1959, Trans. Soc. Rheol. 3, 137-152; Mooney 1951),
and tends to the stone's own moduli there for a finite stone. phi_max = 1 is Norris's scheme.
Its dilute limit is Eshelby's (Einstein's 1 + 2.5 phi for rigid spheres). The estimate is
realizable only inside the Hashin-Shtrikman bounds (:func:`hashin_shtrikman`), which hold for any
isotropic arrangement of the phases, particles in contact included; near phi_max the crowded
estimate can exceed the upper one. So the mortar's |E*| is capped at the upper bound of its
phases' magnitudes (:func:`hs_cap`, keeping the estimate's phase angle): with Norris's scheme
(phi_max = 1) the cap never acts (the tests check it), with crowding it acts only on a glassy
matrix near its packing limit.

Packing limits: the filler's and the fine aggregate's random close packing from their own size
distribution (:func:`random_close_packing`), capped below by the monodisperse value 0.634.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: random close packing of equal spheres (Scott & Kilgour 1969; Berryman 1983, Phys. Rev. A 27, 1053)
RCP_MONODISPERSE = 0.634


def shear_bulk(E, nu) -> tuple[np.ndarray, np.ndarray]:
    """(K, G) of an isotropic solid from Young's modulus ``E`` (Pa) and Poisson's ratio ``nu``."""
    E, nu = np.asarray(E, float), np.asarray(nu, float)
    return E / (3.0 * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def young(K, G):
    """Young's modulus E = 9 K G / (3 K + G) of (K, G) (real or complex, Pa; arrays of one shape)."""
    K, G = np.asarray(K), np.asarray(G)
    return 9.0 * K * G / (3.0 * K + G)


def _zeta(K, G):
    return G * (9.0 * K + 8.0 * G) / (6.0 * (K + 2.0 * G))


def hashin_shtrikman(K, G, phi) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """Hashin-Shtrikman-Walpole bounds on the bulk and shear moduli of an isotropic composite of
    n elastic phases (Hashin & Shtrikman 1963, J. Mech. Phys. Solids 11, 127-140; Walpole 1966,
    J. Mech. Phys. Solids 14, 151-162; Berryman 1995, in Rock Physics and Phase Relations, AGU):

        K_HS = [sum_i phi_i / (K_i + 4/3 G_z)]^-1 - 4/3 G_z
        G_HS = [sum_i phi_i / (G_i + zeta_z)]^-1 - zeta_z,   zeta_z = zeta(K_z, G_z)

    with (K_z, G_z) = the smallest moduli for the lower bounds, the largest for the upper ones.

    Parameters
    ----------
    K, G : (n, ...) real arrays, Pa: the phases' moduli (a void: 0, 0).
    phi : (n, ...) volume fractions summing to 1 over the first axis.

    Returns
    -------
    ((K_low, G_low), (K_up, G_up)) : arrays of the trailing shape, Pa.
    """
    K, G, phi = (np.asarray(a, float) for a in (K, G, phi))
    out = []
    for pick in (np.min, np.max):
        Kz, Gz = pick(K, axis=0), pick(G, axis=0)
        zeta = np.where(Gz > 0, _zeta(Kz, np.maximum(Gz, 1e-300)), 0.0)
        with np.errstate(divide="ignore"):
            Kb = 1.0 / np.sum(phi / (K + 4.0 / 3.0 * Gz), axis=0) - 4.0 / 3.0 * Gz
            Gb = 1.0 / np.sum(phi / (G + zeta), axis=0) - zeta
        out.append((np.nan_to_num(Kb, posinf=np.inf), np.nan_to_num(Gb, posinf=np.inf)))
    return out[0], out[1]


def dilute(Km, Gm, Ki, Gi, phi):
    """Eshelby's dilute estimate of spheres (Ki, Gi) at fraction ``phi`` in a matrix (Km, Gm):
    K = Km + phi (Ki - Km) (Km + 4/3 Gm) / (Ki + 4/3 Gm), G = Gm + phi (Gi - Gm) (Gm + zeta_m) /
    (Gi + zeta_m) (real or complex, Pa). The first-order term of every estimate here."""
    zm = _zeta(Km, Gm)
    K = Km + phi * (Ki - Km) * (Km + 4.0 / 3.0 * Gm) / (Ki + 4.0 / 3.0 * Gm)
    G = Gm + phi * (Gi - Gm) * (Gm + zm) / (Gi + zm)
    return K, G


@dataclass(frozen=True)
class Inclusion:
    """One kind of spherical inclusion: moduli ``K, G`` (Pa, scalars or arrays broadcasting with
    the matrix) and volume fraction ``phi`` in the final composite."""

    K: object
    G: object
    phi: object


def differential_scheme(Km, Gm, inclusions, phi_max=1.0, steps: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """The packing-limited differential scheme (module docstring) for complex moduli.

    Integrated in the crowding variable u = -ln(1 - phi / phi_max) for the compliances 1/K and
    1/G, where the equations are smooth: in the moduli themselves they are stiff (voids in a
    nearly incompressible binder relax its bulk modulus a million times faster than its shear
    modulus), in the compliances they are not. Classical Runge-Kutta, ``steps`` steps, vectorized
    over the cells (400 steps: 1e-10 relative against the closed forms and an implicit Radau
    integration in the tests).

    Parameters
    ----------
    Km, Gm : complex arrays of one shape (Pa): the matrix (binder or mastic) at each condition.
    inclusions : list of :class:`Inclusion`, added together in proportion to their fractions
        (moduli and fractions scalars or arrays broadcasting with Km).
    phi_max : packing limit of the inclusions (scalar or array broadcasting with Km), in
        (sum of phi, 1]; 1 is Norris's scheme.
    steps : Runge-Kutta steps.

    Returns
    -------
    (K, G) : complex arrays of the broadcast shape, Pa.

    Raises
    ------
    ValueError
        if a total fraction is not below ``phi_max``, ``phi_max`` is outside (0, 1], or a matrix
        modulus is not finite and non-zero.
    """
    Km, Gm = np.asarray(Km, complex), np.asarray(Gm, complex)
    phis = [np.asarray(i.phi, float) for i in inclusions]
    pm = np.asarray(phi_max, float)
    shape = np.broadcast(Km, Gm, pm, *phis).shape
    total = np.broadcast_to(sum(phis), shape) if phis else np.zeros(shape)
    if np.any((pm <= 0) | (pm > 1)):
        raise ValueError(f"packing limit phi_max must be in (0, 1], got {np.unique(pm)}")
    if np.any(total >= pm):
        raise ValueError(f"inclusion fraction {np.max(total):.4g} at or above its packing limit {np.min(pm):.4g}")
    if not (np.all(np.isfinite(Km)) and np.all(np.isfinite(Gm)) and np.all(Km != 0) and np.all(Gm != 0)):
        raise ValueError("matrix moduli must be finite and non-zero")
    if not np.any(total):  # nothing to add: the matrix itself (the integration would not move)
        return np.broadcast_to(Km, shape).copy(), np.broadcast_to(Gm, shape).copy()
    w = [np.divide(p, total, out=np.zeros(shape), where=total > 0) for p in phis]
    Ki = [np.asarray(i.K, complex) for i in inclusions]
    Gi = [np.asarray(i.G, complex) for i in inclusions]
    h = -np.log1p(-total / pm) / steps

    def rate(x):
        K, G = 1.0 / x[0], 1.0 / x[1]
        z = _zeta(K, G)
        dK = sum(wj * (Kj - K) * (K + 4.0 / 3.0 * G) / (Kj + 4.0 / 3.0 * G) for wj, Kj in zip(w, Ki))
        dG = sum(wj * (Gj - G) * (G + z) / (Gj + z) for wj, Gj in zip(w, Gi))
        return np.array([-(x[0] ** 2) * dK * pm, -(x[1] ** 2) * dG * pm])  # d(1/K)/du, d(1/G)/du

    x = np.array([np.broadcast_to(1.0 / Km, shape), np.broadcast_to(1.0 / Gm, shape)])
    for _ in range(steps):
        a = rate(x)
        b = rate(x + 0.5 * h * a)
        c = rate(x + 0.5 * h * b)
        d = rate(x + h * c)
        x = x + h / 6.0 * (a + 2.0 * b + 2.0 * c + d)
    return 1.0 / x[0], 1.0 / x[1]


@dataclass(frozen=True)
class Constituents:
    """The physical constants of the mortar's constituents (SI), each with its documented range.

    ``E_stone_Pa``, ``nu_stone``: the aggregate's Young's modulus and Poisson's ratio (AASHTO
    HB-17 means via Wang 2011, Tables 2.1-2.2: granite 52.7 GPa / 0.20, basalt 56.1 / 0.23,
    quartzite 66.1 / 0.14, limestone 39.3 / 0.23, dolostone 29.1 / 0.29; range 30-90 GPa).
    ``K_binder_Pa``: the binder's bulk modulus, taken constant (a glassy binder, G about 1 GPa
    and nu about 0.35, has K about 3 GPa; at service temperatures |G*| << K and the binder is
    nearly incompressible, nu about 0.495: Zhang et al. 2015, Adv. Mater. Sci. Eng. 937126;
    range 2-4 GPa). ``filler_packing``: the filler's packing limit, 1 - Rigden voids (EN 13043
    categories V28/45: 0.55-0.72). ``fine_packing``: the fine aggregate's packing limit in the
    mortar (random close packing of graded sand; at least the monodisperse 0.634, at most 0.9).
    """

    E_stone_Pa: float = 55e9
    nu_stone: float = 0.20
    K_binder_Pa: float = 3e9
    filler_packing: float = 0.65
    fine_packing: float = 0.80

    #: documented range of each constant (low, high)
    RANGES = {
        "E_stone_Pa": (30e9, 90e9),
        "nu_stone": (0.10, 0.30),
        "K_binder_Pa": (2e9, 4e9),
        "filler_packing": (0.55, 0.72),
        "fine_packing": (RCP_MONODISPERSE, 0.90),
    }

    def stone(self) -> tuple[float, float]:
        """(K, G) of the stone, Pa."""
        K, G = shear_bulk(self.E_stone_Pa, self.nu_stone)
        return float(K), float(G)

    def outside_ranges(self) -> list[str]:
        """Names of the constants outside their documented range (empty when all are inside)."""
        return [k for k, (lo, hi) in self.RANGES.items() if not lo <= getattr(self, k) <= hi]


#: where the air voids enter the mortar (module docstring). In ``mastic``, ``mortar`` and ``pockets`` an
#: inclusion's fraction is taken over a matrix that leaves some of the air out, so at a fixed VMA less binder
#: and more air pack the filler or the fine aggregate closer and stiffen the mortar; in ``binder`` (filler in
#: binder + air, fine aggregate in binder + air + filler) the aggregate's packing is set by the aggregate
#: alone, and air in place of binder softens the mortar at every condition.
AIR_PHASES = ("mastic", "mortar", "pockets", "binder")


def mortar_moduli(
    G_binder_Pa,
    delta_deg,
    volumes: dict,
    constituents: Constituents = Constituents(),
    air_phase: str = "mastic",
    stone_Pa: tuple | None = None,
) -> dict:
    """The complex moduli of the mastic, the porous mastic and the mortar (module docstring).

    Parameters
    ----------
    G_binder_Pa, delta_deg : arrays of one shape: the binder's |G*| (Pa) and phase angle
        (degrees) at each condition.
    volumes : the mix's phase volumes (:func:`asphalt_nscd.forecast.formulation.phase_volumes`:
        ``binder, filler, fine, air``, fractions of the mix).
    constituents : the physical constants (:class:`Constituents`).
    air_phase : ``mastic`` (air in the mastic, then the fine aggregate) or ``mortar`` (the fine
        aggregate in the dense mastic, then the air in that mortar; ``porous_mastic`` is then the
        mastic itself) or ``pockets`` (no air in the mortar: ``mortar`` with the air left out) or
        ``binder`` (air in the binder, then the filler, then the fine aggregate, each inclusion's
        fraction over the whole space it shares with the air; ``mastic`` and ``porous_mastic`` are
        then both the porous mastic).
    stone_Pa : the stone's (K_s, G_s) in Pa, arrays broadcasting with the conditions (several
        stones at once: shape (m, 1) against the conditions' (n,) gives (m, n) moduli); default
        ``constituents.stone()``.

    Returns
    -------
    dict of (K, G) complex arrays (Pa) under ``mastic``, ``porous_mastic``, ``mortar``, and the
    inclusion fractions used: ``phi_filler`` (filler in mastic), ``phi_air`` (air in the porous
    mastic, or in the mortar), ``phi_fine`` (fine aggregate in its matrix).

    Raises
    ------
    ValueError
        if an inclusion fraction reaches its packing limit (the mix's fine aggregate or filler
        would be packed denser than the limit allows), or for an unknown ``air_phase``.
    """
    if air_phase not in AIR_PHASES:
        raise ValueError(f"air_phase {air_phase!r}: expected one of {AIR_PHASES}")
    if air_phase == "pockets":
        volumes, air_phase = {**volumes, "air": 0.0}, "mortar"
    G = np.asarray(G_binder_Pa, float) * np.exp(1j * np.radians(np.asarray(delta_deg, float)))
    Ks, Gs = constituents.stone() if stone_Pa is None else stone_Pa
    mastic = volumes["binder"] + volumes["filler"]
    phi_f = volumes["filler"] / mastic
    G = np.broadcast_to(G, np.broadcast(G, Ks, Gs).shape)
    Kb = np.full(G.shape, complex(constituents.K_binder_Pa))
    if air_phase == "binder":
        phi_a = volumes["air"] / (volumes["binder"] + volumes["air"])
        b = differential_scheme(Kb, G, [Inclusion(0.0, 0.0, phi_a)], 1.0)
        phi_f = volumes["filler"] / (mastic + volumes["air"])
        m = hs_cap(*differential_scheme(*b, [Inclusion(Ks, Gs, phi_f)], constituents.filler_packing), b, Ks, Gs, phi_f)
        phi_s = volumes["fine"] / (mastic + volumes["air"] + volumes["fine"])
        r = hs_cap(*differential_scheme(*m, [Inclusion(Ks, Gs, phi_s)], constituents.fine_packing), m, Ks, Gs, phi_s)
        return {"mastic": m, "porous_mastic": m, "mortar": r, "phi_filler": phi_f, "phi_air": phi_a, "phi_fine": phi_s}
    m = hs_cap(
        *differential_scheme(Kb, G, [Inclusion(Ks, Gs, phi_f)], constituents.filler_packing), (Kb, G), Ks, Gs, phi_f
    )
    if air_phase == "mortar":
        phi_s = volumes["fine"] / (mastic + volumes["fine"])
        phi_a = volumes["air"] / (mastic + volumes["fine"] + volumes["air"])
        d = hs_cap(*differential_scheme(*m, [Inclusion(Ks, Gs, phi_s)], constituents.fine_packing), m, Ks, Gs, phi_s)
        r = differential_scheme(*d, [Inclusion(0.0, 0.0, phi_a)], 1.0)
        return {"mastic": m, "porous_mastic": m, "mortar": r, "phi_filler": phi_f, "phi_air": phi_a, "phi_fine": phi_s}
    phi_a = volumes["air"] / (mastic + volumes["air"])
    phi_s = volumes["fine"] / (mastic + volumes["air"] + volumes["fine"])
    p = differential_scheme(*m, [Inclusion(0.0, 0.0, phi_a)], 1.0)
    r = hs_cap(*differential_scheme(*p, [Inclusion(Ks, Gs, phi_s)], constituents.fine_packing), p, Ks, Gs, phi_s)
    return {"mastic": m, "porous_mastic": p, "mortar": r, "phi_filler": phi_f, "phi_air": phi_a, "phi_fine": phi_s}


def hs_upper(matrix, Ks, Gs, phi: float) -> tuple[np.ndarray, np.ndarray]:
    """The Hashin-Shtrikman upper bounds (Pa) on the bulk and shear moduli of a two-phase composite of
    the matrix's magnitudes (|K_m|, |G_m|: a pair of arrays) and the stone (Ks, Gs: scalars or arrays
    broadcasting with the matrix) at stone fraction ``phi``."""
    Km, Gm = (np.abs(np.asarray(a)) for a in matrix)
    shape = np.broadcast(Km, Gm, Ks, Gs).shape
    (_, _), (Ku, Gu) = hashin_shtrikman(
        np.array([np.broadcast_to(Km, shape), np.broadcast_to(np.asarray(Ks, float), shape)]),
        np.array([np.broadcast_to(Gm, shape), np.broadcast_to(np.asarray(Gs, float), shape)]),
        np.array([np.full(shape, 1.0 - phi), np.full(shape, phi)]),
    )
    return Ku, Gu


def hs_cap(K, G, matrix, Ks, Gs, phi: float) -> tuple[np.ndarray, np.ndarray]:
    """(K, G) with each magnitude capped at :func:`hs_upper`, the phase angle of each modulus kept
    (module docstring). Complex arrays, Pa."""
    Ku, Gu = hs_upper(matrix, Ks, Gs, phi)
    K, G = np.asarray(K), np.asarray(G)
    return np.where(np.abs(K) > Ku, K * Ku / np.abs(K), K), np.where(np.abs(G) > Gu, G * Gu / np.abs(G), G)


def rigid_inclusion_factor(phi) -> np.ndarray:
    """G_eff / G_matrix of rigid spheres at volume fraction ``phi`` (0 <= phi < 1) in an
    incompressible matrix by the Hashin-Shtrikman lower bound, which is also the Mori-Tanaka
    estimate: 1 + (5/2) phi / (1 - phi) (dilute limit: Einstein's 1 + 2.5 phi). The mortar of the
    legacy models ``dem`` and ``dem_extended`` (:func:`hs_lower_mortar_modulus`).

    Raises ValueError for phi outside [0, 1)."""
    phi = np.asarray(phi, float)
    if np.any((phi < 0) | (phi >= 1)):
        raise ValueError(f"inclusion volume fraction must be in [0, 1), got {phi}")
    return 1.0 + 2.5 * phi / (1.0 - phi)


def hs_lower_mortar_modulus(G_binder_Pa, delta_deg, phi_filler: float, phi_fine: float) -> np.ndarray:
    """Complex Young's modulus E* (Pa) of the legacy models' mortar: 3 |G*| e^{i delta} times the
    mastic's and the mortar's :func:`rigid_inclusion_factor` (a real factor: the mortar keeps the
    binder's phase angle)."""
    G = np.asarray(G_binder_Pa, float) * np.exp(1j * np.radians(np.asarray(delta_deg, float)))
    return 3.0 * G * rigid_inclusion_factor(phi_filler) * rigid_inclusion_factor(phi_fine)


def confined_modulus(K, G, shape) -> np.ndarray:
    """The apparent compression modulus E_c of a bonded layer of mortar between two stones.

    A layer of radius a and thickness h bonded to rigid faces cannot bulge freely: its pressure
    builds up from the free edge inwards, and the thinner the layer, the more of its load the
    bulk modulus carries. With the shape factor S = a / (2 h) (loaded area over free lateral area),
    the pressure solution of a thin compressible circular layer (Gent 2001, Engineering with Rubber,
    2nd ed., ch. 8; Kelly & Konstantinidis 2011, Mechanics of Rubber Bearings for Seismic and
    Vibration Isolation, ch. 3), plus the layer's own Young's modulus E for its unconfined stretch
    (as in Gent & Lindley 1959, Proc. Inst. Mech. Eng. 173, 111: E_c = E (1 + 2 S^2)), is

        E_c = E + K [1 - 2 I_1(x) / (x I_0(x))],   x = 2 S sqrt(12 G / K)

    Limits (tested): S -> 0 gives E; an incompressible layer (K >> G) gives E (1 + 2 S^2), Gent and
    Lindley's; a wide compressible layer (x -> infinity) gives E + K. By the correspondence principle
    K and G may be complex (Pa): cold, the binder's G is a fair part of K and the layer stiffens
    little; warm, |G*| << K and the bulk modulus props the layer up.

    K, G : complex or real arrays of one shape (Pa). shape : S (-), broadcast against them.
    Returns E_c (complex, the broadcast shape, Pa). Raises ValueError for a negative shape factor.
    """
    from scipy.special import ive

    S = np.asarray(shape, float)
    if np.any(S < 0):
        raise ValueError("confined_modulus: the shape factor S = a / (2 h) must be >= 0")
    K, G = np.asarray(K, complex), np.asarray(G, complex)
    x = 2.0 * S * np.sqrt(12.0 * G / K)
    small = np.abs(x) < 1e-3
    xs = np.where(small, 1.0, x)
    # 1 - 2 I1 / (x I0), even in x (either root serves); its series x^2/8 - x^4/96 where x is small
    lateral = np.where(small, x**2 / 8.0 - x**4 / 96.0, 1.0 - 2.0 * ive(1, xs) / (xs * ive(0, xs)))
    return young(K, G) + K * lateral


#: coordination number of the fine aggregate's contact network: the isostatic value 2d of frictionless spheres
#: at jamming in three dimensions (O'Hern, Silbert, Liu & Nagel 2003, Phys. Rev. E 68, 011306)
FINE_COORDINATION = 6.0


def granular_skeleton(E_stone_Pa, nu_stone: float, phi, pressure_Pa: float, coordination: float = FINE_COORDINATION):
    """(K, G) (Pa, real, the broadcast shape of ``E_stone_Pa`` and ``phi``) of a random packing of equal
    elastic spheres whose contacts were pressed by a hydrostatic ``pressure_Pa`` and kept their patches:
    the effective medium of smooth (frictionless) Hertz contacts (Walton 1987, J. Mech. Phys. Solids
    35, 213-226; as in Mavko, Mukerji & Dvorkin 2009, The Rock Physics Handbook, 2nd ed., section 5.4):

        K = [C^2 phi^2 mu_s^2 P / (18 pi^2 (1 - nu_s)^2)]^(1/3),   G = 3 K / 5

    with C the ``coordination`` number, phi the spheres' volume fraction (the solid fraction), mu_s =
    E_s / (2 (1 + nu_s)). A contact's tangent stiffness 2 a E* at the patch radius a of its load is the
    stiffness a patch held at that radius keeps under a smaller load (the flat punch; Sneddon 1965):
    so the medium is the skeleton of the fine aggregate pressed at compaction, whatever the temperature.
    Independent of the spheres' size. Raises ValueError for a negative pressure or phi outside [0, 1]."""
    phi = np.asarray(phi, float)
    if pressure_Pa < 0 or np.any((phi < 0) | (phi > 1)):
        raise ValueError(f"granular_skeleton: pressure {pressure_Pa} Pa >= 0 and phi {phi} in [0, 1] expected")
    mu = np.asarray(E_stone_Pa, float) / (2.0 * (1.0 + nu_stone))
    K = np.cbrt(coordination**2 * phi**2 * mu**2 * pressure_Pa / (18.0 * np.pi**2 * (1.0 - nu_stone) ** 2))
    return K, 0.6 * K


def contact_network(direct, film, neighbours: float):
    """The modulus (Pa, complex, the broadcast shape of ``direct`` and ``film``) of a random contact network of
    the fine aggregate whose particles each share a mortar bridge with ``neighbours`` others, of which the 2d =
    :data:`FINE_COORDINATION` of the jammed packing's isostatic skeleton (d = 3; O'Hern, Silbert, Liu & Nagel
    2003, Phys. Rev. E 68, 011306) are direct contacts of modulus ``direct`` and the rest films of modulus ``film``.

    The effective medium of a central-force network of two bond kinds, a fraction p of kind a and 1 - p of kind b
    (Feng, Thorpe & Garboczi 1985, Phys. Rev. B 31, 276-280; the scalar form of Kirkpatrick 1973, Rev. Mod. Phys.
    45, 574-588), solves

        p (a - M) / (a + c M) + (1 - p) (b - M) / (b + c M) = 0,   c = z / (2 d) - 1,

    a quadratic in M whose root with a positive real part is taken. Its rigidity threshold (b = 0: M = a (p - p*)
    / (1 - p*)) is p* = 2d / z; an isostatic skeleton has p = 2d / z = p*: the direct contacts sit at the threshold,
    so the network's modulus is neither the direct contacts' nor the films' but in between, M ~ sqrt(a b / c) as
    b -> 0 (Lichtenecker's logarithmic mixing): warm, where the films soften, the network keeps half the binder's
    phase angle. Limits (tested): a = b gives a; p -> 1 gives a; real a > b > 0 give b < M < a.

    direct, film : Pa, real or complex, of one broadcast shape (by the correspondence principle). neighbours :
    z > 2d. Raises ValueError for z <= 2d (the direct contacts would be all the contacts or more)."""
    if not neighbours > FINE_COORDINATION:
        raise ValueError(f"contact_network: {neighbours} neighbours; expected more than 2d = {FINE_COORDINATION:g}")
    a, b = np.asarray(direct, complex), np.asarray(film, complex)
    p, c = FINE_COORDINATION / neighbours, neighbours / FINE_COORDINATION - 1.0
    B = p * (a * c - b) + (1.0 - p) * (b * c - a)
    root = np.sqrt(B * B + 4.0 * a * b * c)
    M = (B + root) / (2.0 * c)
    return np.where(M.real > 0, M, (B - root) / (2.0 * c))
