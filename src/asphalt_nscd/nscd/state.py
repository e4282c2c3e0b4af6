"""State of an NSCD simulation: rigid spheres, rigid planes (plates/walls), Burger's bonds,
solver parameters and per-step statistics.

All arrays are numpy, SI units (m, kg, s, N). Conventions shared by every module of
:mod:`asphalt_nscd.nscd`:

* An interaction (contact or bond) couples a *candidate* sphere ``i`` and an *antagonist*
  ``j``: a sphere index ``j >= 0`` or a plate ``k`` coded ``j = -1 - k`` (the sample file's
  convention, docs/design.md).
* The local frame rows are ``(n, t, s)``; ``n`` points from the antagonist to the candidate
  (for a plate: the plate's inward normal). The relative velocity is ``U = v_i - v_j``
  (+ rotation terms for contacts) expressed in the local frame; a reaction ``R`` (N) in the
  local frame acts on ``i`` as ``+R`` and on ``j`` as ``-R``. ``R_n >= 0`` is compressive
  for a contact; for a bond ``R = -K delta`` is the restoring force on the candidate.
* An infinite mass (``np.inf``) makes a body immobile (fixed sphere, fixed or driven plate).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from ..rheology.laws import POISSON_RATIO, GeneralizedBurgers, bond_scale, tangential_ratio

#: Plate modes.
FIXED, FREE, DRIVEN = 0, 1, 2
PLATE_MODES = {"fixed": FIXED, "free": FREE, "driven": DRIVEN}

#: NLGS convergence norms (gauss_seidel.nlgs): quadratic mean, maximum, both.
CONVERGENCE_NORMS = {"quad": 0, "max": 1, "both": 2}

#: Bond kinematics (NSCDParameters.bond_kinematics, Bonds; also the harmonic solver's).
BOND_KINEMATICS = ("contact", "barycentre")

#: Head (top plate) rotation of the 2PB test: free to rotate (a Plate with ``rotation=True``)
#: or clamped (translation only); the campaign's and the harmonic solver's option.
HEAD_ROTATIONS = ("free", "clamped")

#: Head displacement amplitude A of the paper's 2PB test, m (Section 3.2.2: 63 µm), the
#: default of the time-domain campaign, the harmonic solver and the verification cases.
HEAD_AMPLITUDE_M = 63e-6

#: Contact of an intact bonded pair (NSCDParameters.bonded_contact).
BONDED_CONTACT = ("after_break", "open_at_bonding", "always")

#: Yield stress of the bonds, Pa (paper, Section 3.1: 2.7 MPa).
YIELD_STRESS = 2.7e6

#: Default (None) of an array field that ``__post_init__`` fills in or requires: typed Any so
#: that the field keeps its array type, which it has once the object is constructed.
_SET_IN_POST_INIT: Any = None


def _as(a, shape_tail, name, dtype=float):
    arr = np.ascontiguousarray(np.asarray(a, dtype=dtype))
    if arr.ndim != 1 + len(shape_tail) or arr.shape[1:] != tuple(shape_tail):
        raise ValueError(f"{name}: expected shape (n, {', '.join(map(str, shape_tail))}) got {arr.shape}")
    return arr


@dataclass
class Spheres:
    """Rigid spheres.

    Attributes
    ----------
    position : (N, 3) float, m — barycentres.
    radius : (N,) float, m.
    mass : (N,) float, kg; ``np.inf`` for an immobile sphere.
    inertia : (N,) float, kg m² — scalar moment of inertia (2/5 m r² for a solid sphere).
    velocity : (N, 3) float, m/s.
    angular_velocity : (N, 3) float, rad/s.
    """

    position: np.ndarray
    radius: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    velocity: np.ndarray = _SET_IN_POST_INIT
    angular_velocity: np.ndarray = _SET_IN_POST_INIT

    def __post_init__(self):
        self.position = _as(self.position, (3,), "position")
        n = len(self.position)
        self.radius = np.ascontiguousarray(np.broadcast_to(np.asarray(self.radius, float), (n,)))
        self.mass = np.ascontiguousarray(np.broadcast_to(np.asarray(self.mass, float), (n,)))
        self.inertia = np.ascontiguousarray(np.broadcast_to(np.asarray(self.inertia, float), (n,)))
        if self.velocity is None:
            self.velocity = np.zeros((n, 3))
        if self.angular_velocity is None:
            self.angular_velocity = np.zeros((n, 3))
        self.velocity = _as(self.velocity, (3,), "velocity").copy()
        self.angular_velocity = _as(self.angular_velocity, (3,), "angular_velocity").copy()
        if np.any(self.radius <= 0) or np.any(self.mass <= 0) or np.any(self.inertia <= 0):
            raise ValueError("radius, mass and inertia must be positive")

    @classmethod
    def from_density(cls, position, radius, density: float) -> "Spheres":
        """Solid spheres of uniform ``density`` (kg/m³): m = 4/3 pi r³ rho, I = 2/5 m r²."""
        r = np.asarray(radius, float)
        m = 4.0 / 3.0 * np.pi * r**3 * density
        return cls(position=position, radius=r, mass=m, inertia=0.4 * m * r**2)

    @property
    def n(self) -> int:
        return len(self.radius)

    @property
    def inv_mass(self) -> np.ndarray:
        return 1.0 / self.mass

    @property
    def inv_inertia(self) -> np.ndarray:
        return 1.0 / self.inertia


@dataclass
class Plate:
    """One rigid infinite plane: translation (fixed, free or driven) and, optionally, free
    rotation about its reference point.

    Parameters
    ----------
    point : (3,) m — a point of the plane (its reference point; moves with the plate).
    normal : (3,) — unit normal pointing into the sample (normalised here).
    mode : 'fixed' | 'free' | 'driven'.
    mass : kg. Used by the dynamics for a free plate; for a driven plate only in the driver
        force (imposed motion), ignored for a fixed one. Default inf.
    displacement : for a driven plate, the imposed displacement of ``point`` from its initial
        position: a callable ``t -> (3,)`` (m), or a tuple ``(times (T,), disp (T, 3))`` of
        samples linearly interpolated (held constant outside).
    rotation : bool — if True the plate rotates freely about ``point`` under the torques of
        its bonds (e.g. the head of a 2PB test, free to rotate as the cantilever of
        EN 12697-26 Eq. 3 while its translation is imposed). Small rotations: the plate's
        orientation (normal) is not updated; contacts do not see the rotation (documented
        limitation, Simulation). Default False (translation only, as before).
    inertia : kg m² — principal moments (3,) about ``point`` along the global axes, or a
        scalar; required (finite, > 0) when ``rotation`` is True.
    """

    point: Sequence[float] | np.ndarray
    normal: Sequence[float] | np.ndarray
    mode: str = "fixed"
    mass: float = np.inf
    displacement: Callable | tuple | None = None
    rotation: bool = False
    inertia: float | Sequence[float] = np.inf

    def __post_init__(self):
        if self.mode not in PLATE_MODES:
            raise ValueError(f"plate mode must be one of {list(PLATE_MODES)}, got {self.mode!r}")
        if self.mode == "driven" and self.displacement is None:
            raise ValueError("a driven plate needs a displacement history")
        if self.mode == "free" and not (np.isfinite(self.mass) and self.mass > 0):
            raise ValueError("a free plate needs a finite positive mass")
        inertia = np.broadcast_to(np.asarray(self.inertia, float), (3,))
        if self.rotation and not (np.all(np.isfinite(inertia)) and np.all(inertia > 0)):
            raise ValueError("a rotating plate needs finite positive moments of inertia")


class Plates:
    """All plates of a simulation as arrays (P plates).

    Attributes
    ----------
    point : (P, 3) m — current reference points; ``point0`` the initial ones.
    normal : (P, 3) — unit inward normals.
    mass : (P,) kg; mode : (P,) int (FIXED, FREE, DRIVEN).
    velocity : (P, 3) m/s — mean velocity over the last step for driven plates.
    drivers : list of P displacement histories (None unless driven).
    rotates : (P,) bool; inertia : (P, 3) kg m² (principal, global axes, about ``point``).
    angular_velocity : (P, 3) rad/s; rotation : (P, 3) rad — accumulated small rotation
        vector (zero for plates that do not rotate).
    """

    def __init__(self, plates: Sequence[Plate] = ()):
        plates = list(plates)
        p = len(plates)
        self.point = np.zeros((p, 3))
        self.normal = np.zeros((p, 3))
        self.mass = np.full(p, np.inf)
        self.mode = np.zeros(p, dtype=np.int64)
        self.drivers: list = []
        self.rotates = np.zeros(p, dtype=bool)
        self.inertia = np.full((p, 3), np.inf)
        for k, pl in enumerate(plates):
            self.rotates[k] = bool(pl.rotation)
            self.inertia[k] = np.broadcast_to(np.asarray(pl.inertia, float), (3,))
            self.point[k] = np.asarray(pl.point, float)
            nrm = np.asarray(pl.normal, float)
            self.normal[k] = nrm / np.linalg.norm(nrm)
            self.mass[k] = float(pl.mass)
            self.mode[k] = PLATE_MODES[pl.mode]
            self.drivers.append(pl.displacement if pl.mode == "driven" else None)
        self.point0 = self.point.copy()
        self.velocity = np.zeros((p, 3))
        self.angular_velocity = np.zeros((p, 3))
        self.rotation = np.zeros((p, 3))

    @property
    def n(self) -> int:
        return len(self.mass)

    @property
    def inv_mass(self) -> np.ndarray:
        """1/m for free plates, 0 for fixed and driven ones (imposed kinematics)."""
        inv = np.zeros(self.n)
        free = self.mode == FREE
        inv[free] = 1.0 / self.mass[free]
        return inv

    @property
    def inv_inertia(self) -> np.ndarray:
        """(P, 3) 1/(kg m²): inverse principal moments of rotating plates, 0 otherwise."""
        inv = np.zeros((self.n, 3))
        inv[self.rotates] = 1.0 / self.inertia[self.rotates]
        return inv

    def imposed_displacement(self, k: int, t: float) -> np.ndarray:
        """Imposed displacement (3,) m of driven plate ``k`` at time ``t`` (s)."""
        drv = self.drivers[k]
        if callable(drv):
            return np.asarray(drv(t), dtype=float).reshape(3)
        times, disp = drv
        disp = np.asarray(disp, float)
        return np.array([np.interp(t, times, disp[:, c]) for c in range(3)])


@dataclass
class Bonds:
    """Generalized Burger's bonds (Maxwell in series with NK Kelvin-Voigt units, optional
    parallel spring), one per bonded pair (Eqs. 12-13, 20-26, 30-33, 8-11).

    Where the bond acts is chosen by ``NSCDParameters.bond_kinematics``:

    * ``'contact'`` (default): at the bond's contact point c = x_i + (r_i + delta0/2) e, e the
      unit vector from sphere i towards the other body (the plate: minus its inward normal),
      i.e. the middle of the gap on the line of centres (as harmonic/network.py). The local
      velocity is U = frame @ ((v_i + w_i x a_i) - (v_j + w_j x a_j)) with the lever arms
      a_i = c - x_i, a_j = c - x_j (plate: c - its reference point, the centre of its
      rotation), fixed at their initial values (small strain); the force acts at c, so it
      carries a torque a x R on both bodies, and a rigid rotation of a bonded pair strains
      no bond. The displacement ``displacement`` (local frame) is accumulated from U by the
      theta-method (orientations are not tracked).
    * ``'barycentre'``: at the barycentres, no torque (the former core): the bond
      displacement is ``delta = frame @ ((x_i - x_j) - rest)`` from the positions. A rigid
      rotation of a pair strains its tangential springs (spurious bending stiffness).

    The bond frame (n, t, s) is that of the initial configuration (small strain, consistent
    with the harmonic solver); ``rest`` is the initial relative position (sphere-plate:
    relative to the plate's reference point).

    Attributes (B bonds, NK Kelvin-Voigt units; index 0 = normal, 1 = tangential)
    ----------
    i, j : (B,) int — candidate sphere, antagonist sphere or plate ``-1-k``.
    delta0 : (B,) m initial gap; l0 : (B,) m initial barycentre (or centre-plane) distance;
    r_min : (B,) m; section : (B,) m² = pi r_min²; r_crit : (B,) N = yield_stress * section.
    frame : (B, 3, 3) rows n, t, s; rest : (B, 3) m.
    arm_i, arm_j : (B, 3) m — lever arms c - x_i and c - x_j (plate: c - plate point).
    displacement : (B, 3) m — bond displacement delta (local frame) of the 'contact'
        kinematics, accumulated step by step (unused by 'barycentre').
    Km, Cm, Kinf : (B, 2) N/m, N s/m, N/m; Kk, Ck : (B, NK, 2).
    force : (B, 3) N — total bond force at the end of the last step (local frame).
    delta_c : (B, 3) m — Maxwell dashpot displacement; delta_k : (B, NK, 3) m — Kelvin-Voigt.
    broken : (B,) bool.
    """

    i: np.ndarray
    j: np.ndarray
    delta0: np.ndarray
    l0: np.ndarray
    r_min: np.ndarray
    frame: np.ndarray
    rest: np.ndarray
    Km: np.ndarray
    Cm: np.ndarray
    Kk: np.ndarray
    Ck: np.ndarray
    Kinf: np.ndarray
    r_crit: np.ndarray
    arm_i: np.ndarray = _SET_IN_POST_INIT
    arm_j: np.ndarray = _SET_IN_POST_INIT
    displacement: np.ndarray = _SET_IN_POST_INIT
    force: np.ndarray = _SET_IN_POST_INIT
    delta_c: np.ndarray = _SET_IN_POST_INIT
    delta_k: np.ndarray = _SET_IN_POST_INIT
    broken: np.ndarray = _SET_IN_POST_INIT
    law: dict = field(default_factory=dict)

    def __post_init__(self):
        b = len(self.i)
        nk = self.Kk.shape[1]
        if self.force is None:
            self.force = np.zeros((b, 3))
        if self.delta_c is None:
            self.delta_c = np.zeros((b, 3))
        if self.delta_k is None:
            self.delta_k = np.zeros((b, nk, 3))
        if self.broken is None:
            self.broken = np.zeros(b, dtype=bool)
        if self.displacement is None:
            self.displacement = np.zeros((b, 3))
        for name in ("arm_i", "arm_j"):
            if getattr(self, name) is None:
                raise ValueError(f"Bonds.{name} (lever arms (B, 3), m) is required")

    @property
    def n(self) -> int:
        return len(self.i)

    @property
    def section(self) -> np.ndarray:
        return np.pi * self.r_min**2

    @classmethod
    def empty(cls, n_kelvin: int = 1) -> "Bonds":
        z = np.zeros(0)
        return cls(
            i=np.zeros(0, np.int64),
            j=np.zeros(0, np.int64),
            delta0=z,
            l0=z,
            r_min=z,
            frame=np.zeros((0, 3, 3)),
            rest=np.zeros((0, 3)),
            Km=np.zeros((0, 2)),
            Cm=np.zeros((0, 2)),
            Kk=np.zeros((0, n_kelvin, 2)),
            Ck=np.zeros((0, n_kelvin, 2)),
            Kinf=np.zeros((0, 2)),
            r_crit=z,
            arm_i=np.zeros((0, 3)),
            arm_j=np.zeros((0, 3)),
        )

    @classmethod
    def create(
        cls,
        spheres: Spheres,
        plates: Plates,
        i,
        j,
        law: GeneralizedBurgers,
        nu: float = POISSON_RATIO,
        yield_stress: float = YIELD_STRESS,
    ) -> "Bonds":
        """Bonds between candidate spheres ``i`` and antagonists ``j`` (sphere index, or
        ``-1-k`` for plate k) in the current configuration, which is taken as the rest state.

        Micro law of each bond: ``law`` (macro, Pa, Pa s) scaled by pi r_min²/l0 (Eqs.
        30-33) in the normal direction, times 1/(2(1+nu)) in the tangential ones (Eqs. 8-11).

        Parameters
        ----------
        i, j : (B,) int.
        law : macro generalized Burger's law (the paper: N = 1, E_inf = 0).
        nu : Poisson's ratio of Eqs. 8-11. yield_stress : Pa (R_crit = yield_stress pi r_min²).

        Raises
        ------
        ValueError if an index is out of range or a pair is degenerate (l0 <= 0).
        """
        i = np.asarray(i, dtype=np.int64).reshape(-1)
        j = np.asarray(j, dtype=np.int64).reshape(-1)
        if len(i) != len(j):
            raise ValueError("i and j differ in length")
        if len(i) == 0:
            return cls.empty(law.n_kelvin)
        if i.min() < 0 or i.max() >= spheres.n or j.max() >= spheres.n or (j < -plates.n).any():
            raise ValueError("bond index out of range")
        x = spheres.position
        sph = j >= 0
        rest = np.empty((len(i), 3))
        normal = np.empty((len(i), 3))
        rest[sph] = x[i[sph]] - x[j[sph]]
        kk = -1 - j[~sph]
        rest[~sph] = x[i[~sph]] - plates.point[kk]
        l0 = np.empty(len(i))
        l0[sph] = np.linalg.norm(rest[sph], axis=1)
        l0[~sph] = np.einsum("ij,ij->i", rest[~sph], plates.normal[kk])
        if np.any(l0 <= 0):
            raise ValueError("bond with non-positive barycentre distance l0")
        normal[sph] = rest[sph] / l0[sph, None]
        normal[~sph] = plates.normal[kk]
        r_i = spheres.radius[i]
        r_min = r_i.copy()
        r_min[sph] = np.minimum(r_i[sph], spheres.radius[j[sph]])
        delta0 = l0 - r_i
        delta0[sph] -= spheres.radius[j[sph]]
        frame = local_frames(normal)
        # contact point c = x_i + (r_i + delta0/2) e, e from i towards the other body; n
        # points from the antagonist to i for both kinds of bond, so e = -n
        c = x[i] - (r_i + 0.5 * delta0)[:, None] * normal
        arm_i = c - x[i]
        arm_j = np.empty_like(arm_i)
        arm_j[sph] = c[sph] - x[j[sph]]
        arm_j[~sph] = c[~sph] - plates.point[kk]
        a = bond_scale(r_min, l0)  # Eqs. 30-33
        ratio = np.array([1.0, tangential_ratio(nu)])  # Eqs. 8-11
        nk = law.n_kelvin
        Km = law.Em * a[:, None] * ratio
        Cm = law.eta_m * a[:, None] * ratio
        Kk = np.array(law.Ek).reshape(1, nk, 1) * a[:, None, None] * ratio
        Ck = np.array(law.eta_k).reshape(1, nk, 1) * a[:, None, None] * ratio
        Kinf = law.E_inf * a[:, None] * ratio
        r_crit = yield_stress * np.pi * r_min**2
        return cls(
            i=i,
            j=j,
            delta0=delta0,
            l0=l0,
            r_min=r_min,
            frame=frame,
            rest=rest,
            Km=Km,
            Cm=Cm,
            Kk=np.ascontiguousarray(Kk),
            Ck=np.ascontiguousarray(Ck),
            Kinf=Kinf,
            r_crit=r_crit,
            arm_i=arm_i,
            arm_j=arm_j,
            law={**law.as_dict(), "nu": nu, "yield_stress": yield_stress},
        )


def local_frames(normal: np.ndarray) -> np.ndarray:
    """Orthonormal frames (B, 3, 3) with rows (n, t, s) from unit normals (B, 3).

    t is n x e where e is the global axis least aligned with n; s = n x t.
    """
    normal = np.atleast_2d(normal)
    idx = np.argmin(np.abs(normal), axis=1)
    e = np.zeros_like(normal)
    e[np.arange(len(normal)), idx] = 1.0
    t = np.cross(normal, e)
    t /= np.linalg.norm(t, axis=1)[:, None]
    s = np.cross(normal, t)
    return np.ascontiguousarray(np.stack([normal, t, s], axis=1))


@dataclass
class NSCDParameters:
    """Solver parameters.

    Attributes
    ----------
    dt : time step, s (paper: 5e-5 s).
    theta : Moreau-Jean theta in [0.5, 1]. Default 0.5: second order and free of numerical
        damping for the smooth (bonded) dynamics, so the phase angle of a viscoelastic test is
        not biased by the integrator (theta = 1 adds damping and an O(omega dt) phase error);
        also LMGC90's default. The same theta weights the internal variables of the bonds
        (theta = 1 gives the paper's backward-Euler Kelvin-Voigt update, Eq. 26).
    gravity : (3,) m/s².
    friction : Coulomb coefficient mu (0.2 deposition, 0.7 test).
    tolerance : NLGS convergence on the relative change of reactions between sweeps.
    convergence : which LMGC90-style norm is tested: 'quad' (quadratic mean, default, as
        LMGC90's usual "Quad"), 'max' (maximum relative to the rms) or 'both'. Both values
        are returned in StepStats whatever the choice.
    max_iterations : NLGS sweeps per step.
    relaxation : NLGS relaxation omega in (0, 1]: R <- omega R_local + (1-omega) R_old.
    alert_distance : m — pairs with gap below it are contact candidates. None: 0.5 x the
        smallest radius. It must exceed the largest relative displacement in one step: the
        simulation raises it automatically to 2 h max|v_free| when needed.
    fast_path : use the linear solver (:mod:`.linear`) on steps with no active contact and
        no bond breakage (falls back to NLGS automatically).
    linear_solver : 'cg' (matrix-free conjugate gradient, 3x3 block-Jacobi preconditioner),
        'cg_ssor' (the same with symmetric successive over-relaxation on the body blocks,
        Eisenstat's form, Galerkin initial guess; sequential, ignores ``threads``) or 'direct' (a sparse
        factorisation of the step matrix per intact-bond set, ``direct_factorisation``).
    direct_factorisation : 'cholesky' (default: cholespy's sparse Cholesky, 20-25 % faster per
        solve on paper-scale samples) or 'superlu' (SuperLU, symmetric mode) (:mod:`.linear.direct`).
    linear_tolerance : relative residual of 'cg' and 'cg_ssor'.
    linear_ssor_omega : relaxation factor omega in (0, 2) of 'cg_ssor' (symmetric successive
        over-relaxation, :mod:`.linear`); 1 = symmetric Gauss-Seidel.
    fast_path_contacts : most contacts that the fast path solves itself when its linear
        solution closes them: their Signorini-Coulomb problem on the Delassus operator
        condensed over the bonds (:mod:`.condensed`; exact, the NLGS's solution to its
        tolerance); with more, or 0 (default: the former behaviour), the step is redone by
        NLGS over all bonds and contacts.
    bond_kinematics : 'contact' (default; bond at the contact point, with torques, 6 DOF per
        sphere in the linear fast path) or 'barycentre' (the former core: at the barycentres,
        no torque). See :class:`Bonds`; same option as the harmonic solver.
    bonded_contact : when a bonded pair (sphere-sphere or sphere-plate) is also a unilateral
        contact (Signorini-Coulomb, Eqs. 6-7). 'after_break' (default): its intact bond is
        its only interaction law and the contact exists from the step after the bond breaks
        ("the frictional contact conditions (Eqs. 6 and 7) are applied instead", Section
        3.1); 'open_at_bonding': also while the bond is intact, for the pairs with a
        positive gap at bonding (delta0 > 0) -- the paper's "the viscoelastic Burger's model
        acts together with the frictional contact law ... when a frictional contact is
        produced (delta_n = 0) the generated contact forces are added", restricted to the
        pairs the shrink of Section 3.2.1 opened; 'always': every pair, also those that
        overlapped at bonding (the former core: a sphere cut by a plate plane at bonding
        is a closed contact from the first step). Detection skips the excluded pairs
        (detection.Exclusions). docs/choices.md gives the reasons and the cost.
    threads : numba threads of the parallel kernels (conjugate gradient of the fast path,
        bond laws); 1 (default) = the sequential kernels. At most the numba thread pool
        (NUMBA_NUM_THREADS). An execution setting, not stored in checkpoints; results agree
        with the sequential ones to round-off (tests/unit/test_nscd_threads.py).
    """

    dt: float
    theta: float = 0.5
    gravity: Sequence[float] = (0.0, 0.0, -9.81)
    friction: float = 0.7
    tolerance: float = 1e-6
    convergence: str = "quad"
    max_iterations: int = 2000
    relaxation: float = 1.0
    alert_distance: float | None = None
    fast_path: bool = True
    linear_solver: str = "cg"
    direct_factorisation: str = "cholesky"
    linear_tolerance: float = 1e-10
    linear_ssor_omega: float = 1.2
    fast_path_contacts: int = 0
    bond_kinematics: str = "contact"
    threads: int = 1
    bonded_contact: str = "after_break"

    def __post_init__(self):
        import numba

        if not (isinstance(self.threads, (int, np.integer)) and 1 <= self.threads <= numba.config.NUMBA_NUM_THREADS):
            raise ValueError(
                f"threads must be an integer in [1, NUMBA_NUM_THREADS = "
                f"{numba.config.NUMBA_NUM_THREADS}], got {self.threads!r}"
            )
        self.threads = int(self.threads)
        if self.bond_kinematics not in BOND_KINEMATICS:
            raise ValueError(f"bond_kinematics must be one of {BOND_KINEMATICS}, got {self.bond_kinematics!r}")
        if self.bonded_contact not in BONDED_CONTACT:
            raise ValueError(f"bonded_contact must be one of {BONDED_CONTACT}, got {self.bonded_contact!r}")
        if self.convergence not in CONVERGENCE_NORMS:
            raise ValueError(f"convergence must be one of {list(CONVERGENCE_NORMS)}, got {self.convergence!r}")
        if self.linear_solver not in ("cg", "cg_ssor", "direct"):
            raise ValueError(f"linear_solver must be 'cg', 'cg_ssor' or 'direct', got {self.linear_solver!r}")
        from .linear.direct import FACTORISATIONS

        if self.direct_factorisation not in FACTORISATIONS:
            raise ValueError(f"direct_factorisation must be one of {FACTORISATIONS}, got {self.direct_factorisation!r}")
        if not (0.0 < self.linear_ssor_omega < 2.0):
            raise ValueError(f"linear_ssor_omega must lie in (0, 2), got {self.linear_ssor_omega}")
        if not (isinstance(self.fast_path_contacts, (int, np.integer)) and self.fast_path_contacts >= 0):
            raise ValueError(f"fast_path_contacts must be an integer >= 0, got {self.fast_path_contacts!r}")
        self.fast_path_contacts = int(self.fast_path_contacts)
        if not (self.dt > 0):
            raise ValueError(f"dt must be > 0, got {self.dt}")
        if not (0.5 <= self.theta <= 1.0):
            raise ValueError(f"theta must lie in [0.5, 1], got {self.theta}")
        if not (0.0 < self.relaxation <= 1.0):
            raise ValueError(f"relaxation must lie in (0, 1], got {self.relaxation}")
        if self.friction < 0 or self.tolerance <= 0 or self.max_iterations < 1:
            raise ValueError("friction >= 0, tolerance > 0 and max_iterations >= 1 required")
        self.gravity = np.asarray(self.gravity, dtype=float).reshape(3)


@dataclass
class StepStats:
    """Statistics of one time step.

    time : s, end of step. solver : 'nlgs' or 'linear'. iterations : NLGS sweeps, or
    conjugate-gradient iterations on the linear path (0 for its direct solver).
    residual_quad / residual_max : final relative change of reactions.
    converged : bool. n_contacts : candidates; n_active_contacts : with R_n > 0.
    n_bonds : intact bonds; n_broken : bonds broken in this step; n_broken_total.
    plate_force : (P, 3) N, mean force exerted by the spheres on each plate over the step.
    driver_force : (P, 3) N, force the driver must apply to a driven or fixed plate to
        impose its motion, including its inertia: m a - m g - plate_force, with
        a = theta a(t+) + (1-theta) a(t-) the theta-average of the imposed motion's
        acceleration (second differences with step dt), consistent to second order with
        plate_force = P/dt, P = dt (theta R+ + (1-theta) R-); for theta = 0.5 both are the
        values at the step midpoint t - dt/2 to O(dt²). A driven plate of infinite mass
        (and a fixed plate) reports -plate_force (inertia not counted).
    dissipated : J, energy dissipated in the step by contacts and bonds (>= 0 up to round-off).
    """

    time: float
    solver: str
    iterations: int
    residual_quad: float
    residual_max: float
    converged: bool
    n_contacts: int
    n_active_contacts: int
    n_bonds: int
    n_broken: int
    n_broken_total: int
    plate_force: np.ndarray
    driver_force: np.ndarray
    dissipated: float

    def as_row(self) -> dict:
        """Flat dict (plate forces expanded to plate{k}_F{x,y,z}_N columns)."""
        row = {
            k: getattr(self, k)
            for k in (
                "time",
                "solver",
                "iterations",
                "residual_quad",
                "residual_max",
                "converged",
                "n_contacts",
                "n_active_contacts",
                "n_bonds",
                "n_broken",
                "n_broken_total",
                "dissipated",
            )
        }
        for k in range(len(self.plate_force)):
            for c, ax in enumerate("xyz"):
                row[f"plate{k}_F{ax}_N"] = float(self.plate_force[k, c])
                row[f"plate{k}_driver_F{ax}_N"] = float(self.driver_force[k, c])
        return row
