"""The discrete forecast with bonds from physics: mortar bridges and skeleton contacts, no fitted factor.

A mix's sample (:mod:`.formulation`, Section 3.2.1) is tested in uniaxial compression by the
harmonic solver (:mod:`.dem`, :class:`.dem.Response`): every bond is a mortar bridge, and the
pairs that touched in the vibrated packing are also skeleton contacts. Both laws come from the
binder, the constituents and the mix's volumetrics:

* **Mortar bridge** (every bond, geometric factor g_b = pi r_min^2 / (delta0 + t_m), :func:`.dem.bond_geometry`):
  the mortar's complex Young's modulus E*_mortar (:mod:`.mortar`: filler in binder, air in mastic,
  fine aggregate in porous mastic, by the packing-limited differential scheme) in series with the
  two stones' elastic compliance under a bond of radius a_b = r_min (a rigid punch on each
  half-space, Boussinesq: k = a E_s / (1 - nu_s^2) for the two in series):

      1 / k_b = 1 / (g_b E*_mortar) + (1 - nu_s^2) / (a_b E_s)  ~=  (1 / g_b) [1 / E*_mortar + chi / E_s']

  with chi the bonds' g_b-weighted mean of g_b / a_b (the series term taken uniform over the
  bonds, so that the response stays a function of one modulus per class: :class:`.dem.Response`).
  Options: ``confinement`` (:func:`confined_bridge`), the air in ``pockets`` (dense bridges, the pockets'
  share of the matrix off their section), the fine aggregate's pressed skeleton (:func:`.mortar.granular_skeleton`),
  beside the films or as the direct contacts of a contact network (:func:`.mortar.contact_network`).
* **Skeleton contact** (pairs in contact in the packing): two stones separated by a mastic film of
  the mix's average film thickness h (:func:`.formulation.film_thickness_m`, times
  ``film_factor``). The film squeezed between spheres of effective radius R (Reynolds'
  lubrication, by the correspondence principle; Chan & Horn 1985, J. Chem. Phys. 83, 5311) has
  k_film = 6 pi G*_mastic R^2 / h; the stones under the film's pressurized zone a_c = sqrt(2 R h)
  add k_stone = a_c E_s'. In series, per unit R^2 (the class weight of the film decomposition):

      e_2 = [h / (6 pi G*_mastic) + <R^1.5> / (E_s' sqrt(2 h))]^-1

  cold, the stones carry the contact (elastic); warm, the film does (the mastic's phase).
  ``skeleton_exponent`` n < 1 replaces the film by a parabolic element anchored at the stone's
  stiffness, e_stone (e_film / e_stone)^n (Huet 1963): n = 1 is the film itself. Options, in parallel
  with the film: Hertz contacts of the stones, their patches kept from the compaction (:func:`hertz_contact`).

E*_mix = e_1 F(zeta), zeta = e_2 / e_1 (:meth:`.dem.Response.factor`, ``skeleton="film"``).

Constants (:data:`CONSTANTS`): every one has a documented physical range and a default inside it.
``dem_physical`` takes the defaults: nothing is fitted on mixes. The ladder (:data:`STEPS`) frees them one
at a time, each fitted on the training mixes of a fold inside its range (least squares of ln|E*| and the
phase in radians, from several starts); a constant that ends at its bound is reported (``at_bound``).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..io import InputError


@dataclass(frozen=True)
class Constant:
    """A physical constant of the discrete forecast: its default, documented range and source."""

    default: float
    low: float
    high: float
    unit: str
    source: str


#: the constants of the physical bond laws (:mod:`.mortar` gives the sources of the constituents')
CONSTANTS = {
    "fine_packing": Constant(
        0.80,
        0.634,
        0.90,
        "-",
        "packing limit of the fine aggregate in the mortar: random close packing of equal spheres 0.634 "
        "(Berryman 1983) to a graded sand's 0.9 (de Larrard 1999, compressible packing model)",
    ),
    "skeleton_exponent": Constant(
        1.0, 0.0, 1.0, "-", "0 an elastic skeleton, 1 the mastic film itself (a parabolic element, Huet 1963)"
    ),
    "film_factor": Constant(
        1.0,
        0.05,
        1.5,
        "-",
        "contact film / average film thickness: SEM films 0.5-2.4 um around fillers (Adv. Mater. Sci. Eng. "
        "2021, 8894970) to 1.3 x the formula's 9-13 um",
    ),
    "skeleton_scale": Constant(
        1.0,
        0.0,
        1.0,
        "-",
        "the parabolic skeleton's stiffness at the stone's modulus over the stone's (nothing stiffer than the "
        "stone it joins: at most 1)",
    ),
    "E_stone_Pa": Constant(
        55e9, 30e9, 90e9, "Pa", "AASHTO HB-17 rock moduli (Wang 2011, Tables 2.1-2.2): dolostone 29 to quartzite 66 GPa"
    ),
}
#: the ladder: each model's name and the constants it fits (the others at their defaults)
STEPS = (
    ("dem_physical", ()),
    ("dem_c1", ("fine_packing",)),
    ("dem_c2", ("fine_packing", "skeleton_exponent")),
    ("dem_c3", ("fine_packing", "skeleton_exponent", "film_factor")),
    ("dem_c4", ("fine_packing", "skeleton_exponent", "film_factor", "E_stone_Pa")),
)
#: the parabolic skeleton's steps: the skeleton contacts as mortar-bridge geometry with
#: e_2 = C_s E_s' (E*_mortar / E_s')^n (:func:`bond_moduli`, ``skeleton="parabolic"``)
PARABOLIC_STEPS = (
    ("dem_p2", ("skeleton_scale", "skeleton_exponent")),
    ("dem_p3", ("fine_packing", "skeleton_scale", "skeleton_exponent")),
)
ALL_STEPS = STEPS + PARABOLIC_STEPS
#: the step each step adds constants to (its gain is measured against it)
PREVIOUS = {**{a: b for (b, _), (a, _) in zip(STEPS, STEPS[1:])}, "dem_p2": "dem_physical", "dem_p3": "dem_p2"}
STEP_NAMES = tuple(name for name, _ in ALL_STEPS)
#: grid of the stone modulus on which the mortar is tabulated (Pa; interpolated in ln E_s between)
E_STONE_GRID = np.geomspace(CONSTANTS["E_stone_Pa"].low, CONSTANTS["E_stone_Pa"].high, 5)
#: nodes of the crowding s = -phi_max ln(1 - phi / phi_max) at which the fine-aggregate stage is tabulated
_S_NODES = 25
#: a packing limit within this factor of the mix's fine fraction is read as this factor (the mortar jammed)
JAMMED = 1.02


@functools.lru_cache(maxsize=64)
def _stone_weights(ln_E: float) -> np.ndarray:
    """(len(E_STONE_GRID),) weights w with sum_i w_i y_i = the cubic spline through (ln E_i, y_i) at ln_E."""
    from scipy.interpolate import CubicSpline

    return CubicSpline(np.log(E_STONE_GRID), np.eye(E_STONE_GRID.size))(ln_E)


class MixMortar:
    """One mix's mastic and mortar at its conditions, tabulated for any fine packing limit and stone.

    The last stage of :func:`.mortar.mortar_moduli` (fine aggregate in porous mastic) depends on the
    packing limit phi_max only through the crowding s = -phi_max ln(1 - phi / phi_max): its
    equations in s do not contain phi_max. So one integration in s per stone modulus of
    :data:`E_STONE_GRID` serves every phi_max; :meth:`moduli` interpolates (cubic in s, cubic in
    ln E_s, on ln of the complex moduli).

    Parameters
    ----------
    G_binder_Pa, delta_deg : (n,) the binder at the mix's conditions (Pa, degrees).
    volumes : the mix's phase volumes (:func:`.formulation.phase_volumes`).
    air_phase : where the air voids enter (:data:`.mortar.AIR_PHASES`): ``mastic`` (the fine aggregate
        then goes into porous mastic) or ``mortar`` (into dense mastic, the air added to the mortar
        at every query, after the fine stage's cap) or ``pockets`` (a dense mortar, the air's share
        of the matrix, :attr:`pockets`, taken off the bridges' section by :class:`PhysicalDem`) or
        ``binder`` (the air in the binder, every inclusion's fraction over the space it shares with it).
    """

    def __init__(self, G_binder_Pa, delta_deg, volumes: dict, air_phase: str = "mastic"):
        #: the air pockets' share of the matrix, taken off the bridges' section (``air_phase="pockets"``; else 0)
        self.pockets = 0.0
        if air_phase == "pockets":
            matrix = volumes["binder"] + volumes["filler"] + volumes["fine"] + volumes["air"]
            self.pockets = volumes["air"] / matrix
            volumes = {**volumes, "air": 0.0}
        from scipy.interpolate import CubicSpline

        from .mortar import Constituents, Inclusion, differential_scheme, hs_upper, mortar_moduli, shear_bulk

        self.air_phase = air_phase
        air_in_matrix = volumes["air"] if air_phase in ("mastic", "binder") else 0.0
        self.phi_fine = volumes["fine"] / (volumes["binder"] + volumes["filler"] + air_in_matrix + volumes["fine"])
        #: the air's fraction of the mortar, added at every query (``air_phase="mortar"``; 0 otherwise)
        self.phi_air_mortar = (
            0.0
            if air_phase != "mortar"
            else volumes["air"] / (volumes["binder"] + volumes["filler"] + volumes["air"] + volumes["fine"])
        )
        #: the least packing limit this mix reads (a limit closer to its fraction is taken as this one: jammed)
        self.packing_floor = max(CONSTANTS["fine_packing"].low, JAMMED * self.phi_fine)
        s_max = float(-self.packing_floor * np.log1p(-self.phi_fine / self.packing_floor))
        s_grid = np.linspace(0.0, s_max, _S_NODES)
        # every stone of the grid at once: the stones along the first axis, (E grid, 1) against (n,)
        Ks, Gs = (a[:, None] for a in shear_bulk(E_STONE_GRID, Constituents().nu_stone))
        G_b, d_b = np.asarray(G_binder_Pa, float)[None, :], np.asarray(delta_deg, float)[None, :]
        m = mortar_moduli(G_b, d_b, {**volumes, "fine": 0.0}, Constituents(), air_phase, stone_Pa=(Ks, Gs))
        K, G = m["porous_mastic"]
        Ku, Gu = hs_upper((K, G), Ks, Gs, self.phi_fine)
        rows_K, rows_G = [np.log(K)], [np.log(G)]
        for ds in np.diff(s_grid):  # at phi_max = 1 the crowding u is s: each step continues from the last
            K, G = differential_scheme(K, G, [Inclusion(Ks, Gs, -np.expm1(-ds))], 1.0, steps=12)
            rows_K.append(np.log(K))
            rows_G.append(np.log(G))
        self._s = s_grid
        kg = np.stack([np.array(rows_K), np.array(rows_G)], axis=2)  # (s, E grid, 2, n)
        self._along_s = CubicSpline(s_grid, kg, axis=0)  # s -> (E grid, 2, n)
        self._cap_nodes = np.log(np.abs(np.stack([Ku, Gu], axis=1)))  # (E grid, 2, n): ln of the HS upper bounds
        self._lnGm_nodes = np.log(m["mastic"][1])  # (E grid, n)

    def moduli(self, fine_packing: float, E_stone_Pa: float) -> tuple[np.ndarray, np.ndarray]:
        """(E*_mortar, G*_mastic): complex (n,) Pa at the packing limit and stone modulus given; a
        limit below :attr:`packing_floor` reads the mortar at the floor (:meth:`jammed` says so)."""
        from .mortar import young

        (K, G), Gm = self.bulk_shear(fine_packing, E_stone_Pa)
        return young(K, G), Gm

    def bulk_shear(
        self,
        fine_packing: float,
        E_stone_Pa: float,
        skeleton: tuple[float, float] | None = None,
        neighbours: float | None = None,
    ) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
        """((K*, G*) of the mortar, G*_mastic): complex (n,) Pa, as :meth:`moduli`. ``skeleton``: (K, G) (Pa,
        real) of the fine aggregate's own skeleton (:func:`.mortar.granular_skeleton`), added to the fine stage's
        moduli before their cap at the Hashin-Shtrikman upper bound (the sum is capped like the estimate).
        ``neighbours``: with a skeleton, the fine aggregate as a contact network (:func:`.mortar.contact_network`)
        of direct contacts (the skeleton beside the films) and films (the fine stage's estimate) instead of the
        sum of the two; None: the sum."""
        p = max(float(fine_packing), self.packing_floor)
        s = float(-p * np.log1p(-self.phi_fine / p))
        x = np.log(E_stone_Pa)
        w = _stone_weights(float(x))  # the cubic spline in ln E_s as weights of the grid's values
        lnK, lnG = np.tensordot(w, self._along_s(min(s, self._s[-1])), axes=1)
        if skeleton is not None:
            from .mortar import contact_network

            K, G = np.exp(lnK), np.exp(lnG)
            if neighbours is None:
                lnK, lnG = np.log(K + skeleton[0]), np.log(G + skeleton[1])
            else:
                lnK = np.log(contact_network(K + skeleton[0], K, neighbours))
                lnG = np.log(contact_network(G + skeleton[1], G, neighbours))
        cK, cG = np.tensordot(w, self._cap_nodes, axes=1)
        lnK = np.where(lnK.real > cK, cK + 1j * lnK.imag, lnK)
        lnG = np.where(lnG.real > cG, cG + 1j * lnG.imag, lnG)
        K, G = np.exp(lnK), np.exp(lnG)
        if self.phi_air_mortar > 0.0:
            from .mortar import Inclusion, differential_scheme

            K, G = differential_scheme(K, G, [Inclusion(0.0, 0.0, self.phi_air_mortar)], 1.0, steps=12)
        return (K, G), np.exp(np.tensordot(w, self._lnGm_nodes, axes=1))

    def jammed(self, fine_packing: float) -> bool:
        """Whether the mix's fine aggregate is within 2 % of the packing limit (read at the floor)."""
        return bool(fine_packing < self.packing_floor)


def plane_strain_stone(constants: dict) -> float:
    """E_s' = E_s / (1 - nu_s^2) (Pa) of the stones, from ``constants["E_stone_Pa"]`` and the
    aggregate's Poisson's ratio (:class:`.mortar.Constituents`)."""
    from .mortar import Constituents

    nu = Constituents().nu_stone
    return constants["E_stone_Pa"] / (1.0 - nu**2)


def bond_moduli(
    constants: dict, E_mortar, G_mastic, film_m: float, response, skeleton: str = "film", E_bridge=None
) -> tuple[np.ndarray, np.ndarray]:
    """(e_1, zeta) of one sample at its conditions (module docstring).

    constants : the values of :data:`CONSTANTS` (all of them). E_mortar, G_mastic : complex (n,)
    Pa (:meth:`MixMortar.moduli`). film_m : the mix's average film thickness (m). response :
    the sample's :class:`.dem.Response` (``chi_bridge``, ``skeleton_r15``). E_bridge : the bridges'
    modulus (complex (n,) Pa; :func:`confined_bridge`), E_mortar when None (a free bridge).
    Returns e_1 (Pa, complex (n,)) and zeta = e_2 / e_1 (m^-1 x m, complex (n,))."""
    Es = plane_strain_stone(constants)
    e1 = 1.0 / (1.0 / (E_mortar if E_bridge is None else E_bridge) + response.chi_bridge / Es)
    if skeleton == "parabolic":  # per unit g_b, like a bridge: C_s E_s' (E*_mortar / E_s')^n
        n = constants["skeleton_exponent"]
        e2 = constants["skeleton_scale"] * Es * np.exp(n * np.log(E_mortar / Es))
        return e1, e2 / e1
    if not np.isfinite(response.skeleton_r15):  # no skeleton contact in the sample
        return e1, np.zeros_like(e1)
    h = constants["film_factor"] * film_m
    e_film = 6.0 * np.pi * G_mastic / h
    e_stone = Es * np.sqrt(2.0 * h) / response.skeleton_r15
    n = constants["skeleton_exponent"]
    if n != 1.0:
        e_film = e_stone * np.exp(n * np.log(e_film / e_stone))
    e2 = 1.0 / (1.0 / e_film + 1.0 / e_stone)
    return e1, e2 / e1


#: bins of ln S over which a sample's bond shape factors are condensed (:func:`shape_nodes`)
SHAPE_BINS = 48


def shape_nodes(response) -> tuple[np.ndarray, np.ndarray]:
    """(S nodes, weights): the sample's bond shape factors (:attr:`.dem.Response.bridge_shape`) condensed
    into :data:`SHAPE_BINS` bins of ln S, each node its bin's g_b-weighted mean S and weight its share of
    sum g_b (the weights sum to 1). Raises InputError if the response predates the shape factors."""
    S, g = np.asarray(response.bridge_shape, float), np.asarray(response.bridge_weight, float)
    if S.size == 0 or S.size != g.size or not np.all(np.isfinite(S)) or np.any(S <= 0):
        raise InputError(
            f"DEM response of mix {response.mix_id} (seed {response.seed}): no bond shape factors "
            "(written before the confined bridges); delete it and rerun forecast-response"
        )
    edges = np.linspace(np.log(S.min()), np.log(S.max()) + 1e-12, SHAPE_BINS + 1)
    k = np.clip(np.searchsorted(edges, np.log(S), side="right") - 1, 0, SHAPE_BINS - 1)
    w = np.bincount(k, weights=g, minlength=SHAPE_BINS)
    keep = w > 0
    nodes = np.bincount(k, weights=g * S, minlength=SHAPE_BINS)[keep] / w[keep]
    return nodes, w[keep] / w.sum()


def confined_bridge(K, G, shapes: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """The bridges' modulus with their confinement: sum_b g_b E_c(S_b) / sum_b g_b (complex (n,) Pa), E_c of
    :func:`.mortar.confined_modulus` with the mortar's (K*, G*) (n,) and each bond's shape factor S_b, the
    bonds condensed in ``shapes`` = :func:`shape_nodes` of the sample's response (computed once per fit). The
    mean over the bonds weighted by g_b is the modulus that gives the bonds' summed stiffness (a Voigt
    mean: exact where every bond stretches alike, an upper estimate otherwise); the tangential stiffness
    follows the normal one by the Eqs. 8-11 ratio, as for a free bridge."""
    from .mortar import confined_modulus

    nodes, w = shapes
    Ec = confined_modulus(np.asarray(K)[None, :], np.asarray(G)[None, :], nodes[:, None])
    return w @ Ec


def hertz_contact(E_mix_abs, strain: float, response, E_stone_prime: float, pressure: float = 0.0) -> np.ndarray:
    """The skeleton contacts' Hertz stiffness per unit R^2 (Pa/m, real (n,)) at the test's stress.

    Two equal stones in elastic contact under a normal force N have k = (6 E*^2 R N)^(1/3) (Hertz
    1882; Johnson 1985, Contact Mechanics, Eq. 4.23 differentiated), E* = E_s' / 2 the contact
    modulus of two stones of plane-strain modulus E_s' = E_s / (1 - nu_s^2), R the contact's
    effective radius. N is the mean force the test's stress sigma = |E*_mix| strain gives the
    skeleton contacts (Love-Weber: N = sigma V / sum l, :attr:`.dem.Response.skeleton_v_over_l`);
    per unit R^2 with R^(-5/3) taken as 1 / <R^(5/3)> over the contacts (``skeleton_r53``).

    With a compaction ``pressure`` p_c the stress is max(sigma, p_c): the contacts' patches were
    pressed by the compactor's p_c (AASHTO T 312's 600 kPa) and the binder holds them pressed, so
    under a smaller load a patch keeps the radius a_c of that load and its stiffness 2 a_c E*, the
    flat punch's (Sneddon 1965, Int. J. Eng. Sci. 3, 47; the unloading stiffness of a contact loaded past the
    test's load, Thornton 1997, J. Appl. Mech. 64, 383), a stiffness the temperature does not change.

    E_mix_abs : (n,) |E*| of the sample (Pa). strain : the test's axial strain amplitude (-).
    pressure : the compaction pressure (Pa; 0: none).
    Raises InputError if the response predates these contacts (its scalars are NaN)."""
    if not (np.isfinite(response.skeleton_v_over_l) and np.isfinite(response.skeleton_r53)):
        raise InputError(
            f"DEM response of mix {response.mix_id} (seed {response.seed}): no skeleton contact geometry "
            "(written before the Hertz contacts); delete it and rerun forecast-response"
        )
    N = np.maximum(np.asarray(E_mix_abs, float) * float(strain), float(pressure)) * response.skeleton_v_over_l
    return (6.0 * (0.5 * E_stone_prime) ** 2 * N) ** (1.0 / 3.0) / response.skeleton_r53


#: iterations of the Hertz contacts' fixed point (their force follows the sample's own modulus)
HERTZ_ITERATIONS = 60
#: its tolerance on ln|E*|
HERTZ_TOLERANCE = 1e-9


#: step of the forward differences of the bond moduli in the fits' Jacobian, as a fraction of each constant's range
#: (:meth:`PhysicalDem._log_modulus_jacobian`; the Schur sum's own slope is exact)
JACOBIAN_STEP = 1e-7

#: (mix, binder, volumes, air phase) -> (MixMortar, film thickness), built once per process
_MORTARS: dict = {}


@dataclass(frozen=True)
class BondPhysics:
    """The bond laws' physics options (recorded in every fit, stated on the page).

    air_phase : where the air voids enter the mortar (:data:`.mortar.AIR_PHASES`).
    contact_strain : the test's axial strain amplitude at which the skeleton contacts also touch as
        Hertz contacts of the stones (:func:`hertz_contact`, in parallel with their mastic film;
        the film skeleton only), in (0, 0.01); None: no Hertz contact.
    confinement : the mortar bridges as layers bonded to their stones, stiffened by their bulk
        modulus (:func:`confined_bridge`); False: free bridges of the mortar's Young's modulus.
    compaction_pressure : the compactor's pressure (Pa, in (0, 1e8)) that pressed the skeleton
        contacts' patches (:func:`hertz_contact`, the film skeleton only; with ``contact_strain``
        the larger of the two stresses); None: no compaction patch.
    fine_skeleton_pressure : the pressure (Pa, in (0, 1e8)) that pressed the contacts of the mortar's fine
        aggregate: their skeleton (:func:`.mortar.granular_skeleton` at the mortar's fine fraction) is
        added to the mortar's bulk and shear moduli (the two share the strain: a Voigt sum), the sum
        capped at the Hashin-Shtrikman upper bound (:meth:`MixMortar.bulk_shear`); None: none.
    fine_neighbours : with a fine skeleton, the number of neighbours z (in (6, 50)) each fine particle shares a
        mortar bridge with, 6 of them direct contacts (the isostatic skeleton): the mortar is the effective
        medium of that contact network (:func:`.mortar.contact_network`) instead of the Voigt sum; None: the sum.

    Raises InputError for an option outside its range, or ``fine_neighbours`` without a fine skeleton.
    """

    air_phase: str = "mastic"
    contact_strain: float | None = None
    confinement: bool = False
    compaction_pressure: float | None = None
    fine_skeleton_pressure: float | None = None
    fine_neighbours: float | None = None

    def __post_init__(self):
        from .mortar import AIR_PHASES, FINE_COORDINATION

        if self.air_phase not in AIR_PHASES:
            raise InputError(f"bond physics: air phase {self.air_phase!r}; expected one of {AIR_PHASES}")
        for name in ("contact_strain", "compaction_pressure", "fine_skeleton_pressure", "fine_neighbours"):
            value = getattr(self, name)
            if value is None:
                continue
            try:
                object.__setattr__(self, name, float(value))
            except (TypeError, ValueError):
                raise InputError(f"bond physics: {name.replace('_', ' ')} {value!r}; expected a number") from None
        if self.contact_strain is not None and not 0.0 < self.contact_strain < 0.01:
            raise InputError(f"bond physics: contact strain {self.contact_strain}; expected in (0, 0.01)")
        for name in ("compaction_pressure", "fine_skeleton_pressure"):  # the pressures' one range
            value = getattr(self, name)
            if value is not None and not 0.0 < value < 1e8:
                raise InputError(f"bond physics: {name.replace('_', ' ')} {value} Pa; expected in (0, 1e8)")
        if self.fine_neighbours is not None:
            if self.fine_skeleton_pressure is None:
                raise InputError("bond physics: fine neighbours need a fine skeleton pressure (the direct contacts)")
            if (
                not FINE_COORDINATION < self.fine_neighbours < 50.0
            ):  # more than the isostatic skeleton's direct contacts
                raise InputError(
                    f"bond physics: fine neighbours {self.fine_neighbours}; expected in ({FINE_COORDINATION:g}, 50)"
                )

    @classmethod
    def from_config(cls, dem: dict) -> "BondPhysics":
        """The options of the ``forecast.dem`` section (``air_phase``, ``contact_strain``,
        ``bridge_confinement``, ``compaction_pressure_Pa``, ``fine_skeleton_pressure_Pa``,
        ``fine_contact_neighbours``; absent keys at their defaults)."""
        return cls(
            air_phase=str(dem.get("air_phase") or "mastic"),
            contact_strain=dem.get("contact_strain"),
            confinement=bool(dem.get("bridge_confinement", False)),
            compaction_pressure=dem.get("compaction_pressure_Pa"),
            fine_skeleton_pressure=dem.get("fine_skeleton_pressure_Pa"),
            fine_neighbours=dem.get("fine_contact_neighbours"),
        )

    @property
    def touching(self) -> bool:
        """Whether the skeleton contacts touch (Hertz contacts or the compaction's patches)."""
        return self.contact_strain is not None or self.compaction_pressure is not None


class PhysicalDem:
    """A model of the ladder (:data:`STEPS`): the physical bond laws with ``free`` constants fitted.

    Parameters
    ----------
    name : one of :data:`STEP_NAMES`.
    responses : mix_id -> list of :class:`.dem.Response` (one per seed; with the film decomposition).
    cut_mm : the samples' PSD cut (the mortar's fine aggregate is what passes it).
    free : the constants to fit (default: the step's).
    starts : starting points of the fit (1: the middle of every range; 3: also its quarter points).
    variant : the sample variant of ``responses`` (:func:`.formulation.variant_name`; "" the base sample).
    physics : the bond laws' physics options (:class:`BondPhysics`; default: none).
    """

    coefficients = "physical"

    def __init__(
        self,
        name: str,
        responses: dict,
        cut_mm: float,
        free: tuple | None = None,
        starts: int = 3,
        variant: str = "",
        physics: BondPhysics = BondPhysics(),
    ):
        steps = dict(ALL_STEPS)
        if name not in steps and free is None:
            raise InputError(f"physical DEM model {name!r}: expected one of {STEP_NAMES}")
        self.model, self.responses, self.cut_mm, self.variant = name, responses, float(cut_mm), str(variant)
        self.free = tuple(steps[name] if free is None else free)
        #: starts of the fit: 1 the middle of every range; 3 also its quarter points
        self.starts = int(starts)
        #: the skeleton law: the film (:data:`STEPS`) or the parabolic element (:data:`PARABOLIC_STEPS`)
        self.skeleton = "parabolic" if name in dict(PARABOLIC_STEPS) else "film"
        self.bond_physics = physics
        unknown = sorted(set(self.free) - set(CONSTANTS))
        if unknown:
            raise InputError(
                f"physical DEM model {name!r}: unknown constants {unknown}; expected among {list(CONSTANTS)}"
            )

    def available(self, table: pd.DataFrame) -> bool:
        """Whether some mix of ``table`` has a usable sample response with its skeleton decomposition."""
        return bool(self._usable() & set(table["mix_id"]))

    def _usable(self) -> set:
        return {m for m, rs in self.responses.items() if all(r.usable and r.lam_f.size for r in rs)}

    def _cells(self, rows: pd.DataFrame) -> list:
        """(row indices, MixMortar, film thickness, responses, shapes) per usable mix of ``rows``; shapes:
        each response's :func:`shape_nodes` with confined bridges, else None for each."""
        from .formulation import film_thickness_m, phase_volumes

        out = []
        usable = self._usable()
        for mix_id, idx in rows.groupby("mix_id", sort=False).indices.items():
            if mix_id not in self.responses:
                raise InputError(f"DEM model: no sample response for mix {mix_id!r}")
            if mix_id not in usable:
                continue
            r = rows.iloc[idx]
            G = r["binder_G_mix_MPa"].to_numpy(float) * 1e6
            d = r["binder_delta_mix_deg"].to_numpy(float)
            mix = r.iloc[0]
            volumes = phase_volumes(mix, self.cut_mm)
            key = (mix_id, G.tobytes(), d.tobytes(), tuple(sorted(volumes.items())), self.bond_physics.air_phase)
            if key not in _MORTARS:  # shared by every model of the process: the ladder's steps read the same mortar
                _MORTARS[key] = (MixMortar(G, d, volumes, self.bond_physics.air_phase), film_thickness_m(mix))
            responses = self.responses[mix_id]
            shapes = [shape_nodes(r) if self.bond_physics.confinement else None for r in responses]
            out.append((idx, *_MORTARS[key], responses, shapes))
        return out

    def constants(self, x) -> dict:
        """All constants: the defaults with the free ones set to ``x`` (in :attr:`free` order)."""
        c = {k: v.default for k, v in CONSTANTS.items()}
        c.update(dict(zip(self.free, map(float, x))))
        return c

    def _bond_parts(self, cells: list, constants: dict) -> list:
        """(e_1, zeta) of every response of every cell (:func:`bond_moduli`): a list per cell of
        (response, e_1, zeta) with complex (m,) arrays, m the cell's rows. No Schur sum: the cheap part."""
        from .mortar import Constituents, granular_skeleton, young

        out = []
        pressure = self.bond_physics.fine_skeleton_pressure
        for _, mortar, film, responses, shapes in cells:
            skeleton = (  # the fine aggregate's own skeleton beside the mortar's suspension estimate
                None
                if pressure is None
                else granular_skeleton(constants["E_stone_Pa"], Constituents().nu_stone, mortar.phi_fine, pressure)
            )
            (K, G), Gm = mortar.bulk_shear(
                constants["fine_packing"], constants["E_stone_Pa"], skeleton, self.bond_physics.fine_neighbours
            )
            Em = young(K, G)
            parts = []
            for resp, shape in zip(responses, shapes):
                Eb = (Em if shape is None else confined_bridge(K, G, shape)) * (1.0 - mortar.pockets)
                parts.append((resp, *bond_moduli(constants, Em, Gm, film, resp, self.skeleton, E_bridge=Eb)))
            out.append(parts)
        return out

    @property
    def _weights(self) -> str:
        return "mortar" if self.skeleton == "parabolic" else "film"

    @property
    def _touches(self) -> bool:
        """Whether the film skeleton's contacts also touch (Hertz contacts or the compaction's patches: a fixed
        point in the sample's modulus, which the fits difference as a whole)."""
        return self.skeleton == "film" and self.bond_physics.touching

    def _log_modulus(self, cells: list, n: int, constants: dict, parts: list | None = None) -> np.ndarray:
        """ln E*_sample (Pa, complex) of every row (NaN where a mix has no usable sample); ``parts``: the
        cells' :meth:`_bond_parts` at ``constants`` when already computed."""
        out = np.full(n, np.nan + 0j)
        parts = self._bond_parts(cells, constants) if parts is None else parts
        for (idx, *_), cell_parts in zip(cells, parts):
            logs = []
            for resp, e1, zeta in cell_parts:
                E = e1 * resp.factor(zeta, skeleton=self._weights)
                if self._touches:
                    E = self._with_touching(E, e1, zeta, resp, constants)
                logs.append(np.log(E))
            out[idx] = np.mean(logs, axis=0)
        return out

    def _log_modulus_jacobian(self, cells: list, n: int, x, base: list | None = None) -> np.ndarray:
        """d ln E*_sample / d x (complex (n, p), x the free constants in :attr:`free` order) by the chain
        rule through the Schur sum: ln E = mean over the responses of ln e_1 + ln F(zeta), so
        d ln E = d e_1 / e_1 + (F'(zeta) / F(zeta)) d zeta, F and F' exact (one pass of
        :meth:`.dem.Response.factor_and_slope`), d e_1 and d zeta by forward differences of the cheap
        part (:meth:`_bond_parts`, step :data:`JACOBIAN_STEP` of each constant's range, taken inward
        at an upper bound). Without the touching contacts only (their fixed point is not differentiated
        here; :meth:`fit` uses finite differences of the whole model there). ``base``: the cells'
        :meth:`_bond_parts` at ``x`` when already computed (the residuals' call at the same point)."""
        x = np.asarray(x, float)
        base = self._bond_parts(cells, self.constants(x)) if base is None else base
        shifted = []
        for j, name in enumerate(self.free):
            lo, hi = CONSTANTS[name].low, CONSTANTS[name].high
            h = JACOBIAN_STEP * (hi - lo)
            if x[j] + h > hi:
                h = -h
            xj = x.copy()
            xj[j] += h
            shifted.append((h, self._bond_parts(cells, self.constants(xj))))
        J = np.full((n, len(self.free)), np.nan + 0j)
        for c, (idx, *_) in enumerate(cells):
            acc = np.zeros((len(idx), len(self.free)), complex)
            for r, (resp, e1, zeta) in enumerate(base[c]):
                F, dF = resp.factor_and_slope(zeta, skeleton=self._weights)
                for j, (h, parts) in enumerate(shifted):
                    _, e1j, zj = parts[c][r]
                    acc[:, j] += (e1j - e1) / (h * e1) + (dF / F) * (zj - zeta) / h
            J[idx] = acc / len(base[c])
        return J

    def _with_touching(self, E, e1, zeta, resp, constants: dict) -> np.ndarray:
        """E*_sample (Pa, complex (n,)) with the Hertz contacts or the compaction's patches in parallel
        with the films: E = e_1 F(zeta + e_H / e_1) (:func:`hertz_contact`). With the test's strain e_H
        follows |E| and this is the fixed point (a contraction: e_H grows as |E|^(1/3)); with the
        patches alone e_H is fixed and one evaluation is the answer. Raises InputError if the fixed
        point does not converge."""
        Es = plane_strain_stone(constants)
        strain = self.bond_physics.contact_strain or 0.0
        for _ in range(HERTZ_ITERATIONS):
            eh = hertz_contact(np.abs(E), strain, resp, Es, self.bond_physics.compaction_pressure or 0.0)
            new = e1 * resp.factor(zeta + eh / e1, skeleton="film")
            if not strain:  # the patches' stiffness does not follow the sample's modulus
                return new
            done = np.max(np.abs(np.log(np.abs(new / E)))) < HERTZ_TOLERANCE
            E = new
            if done:
                return E
        raise InputError(f"mix {resp.mix_id}: the Hertz contacts' fixed point did not converge")

    def fit(self, train: pd.DataFrame) -> dict:
        """The constants of a fold (module docstring): the free ones fitted on ``train`` inside their
        ranges from the range's midpoint and both quarter points of every constant, the best kept;
        ``cost`` (in-sample), ``n_rows``, ``at_bound`` (names of constants at a bound), ``jammed``
        (training mixes read at their packing floor)."""
        from scipy.optimize import least_squares

        rows = train.dropna(subset=["E_norm_MPa", "phase_deg"])
        rows = rows[rows["mix_id"].isin(self._usable())].reset_index(drop=True)
        y = np.log(rows["E_norm_MPa"].to_numpy(float) * 1e6) + 1j * np.radians(rows["phase_deg"].to_numpy(float))
        cells = self._cells(rows)
        if not self.free:
            c = self.constants(())
            r = self._log_modulus(cells, len(rows), c) - y
            return {
                **c,
                "cost": float(np.sum(np.abs(r) ** 2) / 2),
                "n_rows": len(rows),
                "at_bound": [],
                "jammed": self._jammed(cells, c),
                **self.physics(),
            }
        lo = np.array([CONSTANTS[k].low for k in self.free])
        hi = np.array([CONSTANTS[k].high for k in self.free])

        last: dict = {}  # the bond parts of the last residuals' point, which SciPy's Jacobian call then repeats

        def resid(x):
            c = self.constants(x)
            last["x"], last["parts"] = np.array(x, float), self._bond_parts(cells, c)
            r = self._log_modulus(cells, len(rows), c, last["parts"]) - y
            return np.concatenate([r.real, r.imag])

        def jac(x):
            base = last["parts"] if np.array_equal(last.get("x"), x) else None
            J = self._log_modulus_jacobian(cells, len(rows), x, base)
            return np.concatenate([J.real, J.imag])

        # the Jacobian through the Schur sum's exact slope; finite differences of the whole model where
        # the touching contacts' fixed point enters (diff_step: relative to x)
        jacobian = "2-point" if self._touches else jac
        starts = [lo + f * (hi - lo) for f in (0.5, 0.25, 0.75)[: max(1, self.starts)]]
        fits = [
            least_squares(resid, x0, jac=jacobian, bounds=(lo, hi), x_scale=hi - lo, diff_step=1e-4) for x0 in starts
        ]
        best = min(fits, key=lambda f: f.cost)
        at = np.isclose(best.x, lo, rtol=0, atol=1e-3 * (hi - lo)) | np.isclose(
            best.x, hi, rtol=0, atol=1e-3 * (hi - lo)
        )
        c = self.constants(best.x)
        return {
            **c,
            "cost": float(best.cost),
            "n_rows": len(rows),
            "at_bound": [k for k, a in zip(self.free, at) if a],
            "starts_agree": bool(max(f.cost for f in fits) - best.cost <= 1e-6 * max(best.cost, 1e-12)),
            "jammed": self._jammed(cells, c),
            **self.physics(),
        }

    def physics(self) -> dict:
        """The bond laws' physics options this model ran with (recorded in every fit, stated on the page)."""
        return dataclasses.asdict(self.bond_physics)

    @staticmethod
    def _jammed(cells, constants) -> list:
        return sorted({str(c[3][0].mix_id) for c in cells if c[1].jammed(constants["fine_packing"])})

    def predict(self, state: dict, rows: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, str]:
        """(|E*| MPa, phase deg, "model") of ``rows`` with the fold's constants ``state``."""
        c = {k: float(state[k]) for k in CONSTANTS}
        lf = self._log_modulus(self._cells(rows), len(rows), c)
        return np.exp(lf.real) / 1e6, np.degrees(lf.imag), "model"
