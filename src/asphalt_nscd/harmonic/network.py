"""The bonded sample as a linear network.

A numerical sample (``results/samples/<sample>.h5``, format of docs/design.md), read by the
sample store (:func:`asphalt_nscd.sample.store.read_sample`), becomes a :class:`BondNetwork`
(:func:`network_from_sample`): sphere barycentres and masses, the two plates, and for every
bond the two bodies, the unit vector n of the bond frame in the initial configuration and the
geometric factor a_b = pi r_min^2 / l0 of Eqs. 30-33.

Bond frame (docs/design.md): for a sphere-sphere bond n = (x_j - x_i)/|x_j - x_i|; for a
sphere-plate bond n is the plate normal. The linearised bond stiffness depends on n only
through n n^T, so the sign of n does not matter.

Contact point of a bond (used by ``bond_kinematics="contact"`` of :mod:`.solver`): the middle
of the gap on the line of centres, c = x_i + (r_i + delta0/2) e with e the unit vector from
sphere i towards the other body (e = n for sphere-sphere bonds, minus the plate normal for
sphere-plate bonds), delta0 = l0 - r_i - r_j (sphere-sphere) or l0 - r_i (sphere-plate).

Top-plate (head) rotational inertia, used when the head is free to rotate: the steel cuboid of
the 2PB rig (:mod:`asphalt_nscd.sample.rig`, :func:`asphalt_nscd.sample.rig.head_inertia`),
about the head-face centre ``plates/point[1]``.

Test samples (a jittered lattice, given spheres and bonds) come from
:mod:`asphalt_nscd.sample.lattice`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..rheology.laws import bond_scale
from ..sample.rig import contact_points, head_inertia


@dataclass(frozen=True)
class BondNetwork:
    """Rigid spheres linked by bonds, between a fixed bottom plate and a driven top plate.

    Attributes
    ----------
    position : (N, 3) float, m
        Sphere barycentres.
    mass : (N,) float, kg
        Sphere masses.
    plate_mass : (2,) float, kg
        Bottom (inf, fixed) and top plate masses.
    plate_normal : (2, 3) float
        Unit plate normals (row 0 bottom, row 1 top).
    i, j : (B,) int
        Bonded bodies; ``j = -1`` bottom plate, ``j = -2`` top plate (docs/design.md).
    normal : (B, 3) float
        Unit vector n of each bond frame in the initial configuration.
    scale : (B,) float, m
        a_b = pi r_min^2 / l0 (Eqs. 30-33).
    name : str
        Sample name (file stem).
    radius : (N,) float, m
        Sphere radii.
    rotational_inertia : (N,) float, kg m^2
        Sphere moments of inertia (``spheres/inertia``, else 2/5 m r^2).
    contact_point : (B, 3) float, m
        Contact point c of each bond (module docstring).
    plate_point : (2, 3) float, m
        Reference points of the plates; the head rotates about ``plate_point[1]``.
    plate_inertia : (3,) float, kg m^2
        Principal moments of inertia of the head about ``plate_point[1]`` (module docstring).
    """

    position: np.ndarray
    mass: np.ndarray
    plate_mass: np.ndarray
    plate_normal: np.ndarray
    i: np.ndarray
    j: np.ndarray
    normal: np.ndarray
    scale: np.ndarray
    name: str = "sample"
    radius: np.ndarray | None = None
    rotational_inertia: np.ndarray | None = None
    contact_point: np.ndarray | None = None
    plate_point: np.ndarray | None = None
    plate_inertia: np.ndarray | None = None

    @property
    def n_spheres(self) -> int:
        return int(self.position.shape[0])

    @property
    def n_bonds(self) -> int:
        return int(self.i.shape[0])

    @property
    def sample_mass(self) -> float:
        """Total mass of the spheres, kg (M of the mass factor mu = 0.135 M + m)."""
        return float(self.mass.sum())

    def digest(self) -> str:
        """SHA-256 (hex) of every array of the network, in field order: two networks with the same
        digest give the same harmonic system to the last bit (a rig state's reference is taken
        only by the network it was computed on)."""
        import dataclasses
        import hashlib

        h = hashlib.sha256()
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(value, np.ndarray):
                h.update(f"{field.name} {value.dtype.str} {value.shape}".encode())
                h.update(np.ascontiguousarray(value).tobytes())
        return h.hexdigest()


def bond_normals(position, plate_normal, i, j) -> np.ndarray:
    """Unit bond directions n, shape (B, 3), in the initial configuration.

    Sphere-sphere: (x_j - x_i)/|x_j - x_i|; sphere-plate k (j = -1 - k): plate normal k.

    Raises
    ------
    ValueError
        if two bonded barycentres coincide.
    """
    n = np.empty((len(i), 3))
    plate = j < 0
    d = position[j[~plate]] - position[i[~plate]]
    length = np.linalg.norm(d, axis=1)
    if np.any(length <= 0):
        raise ValueError("bonded spheres with coincident barycentres")
    n[~plate] = d / length[:, None]
    n[plate] = plate_normal[-1 - j[plate]]
    return n


def network_from_arrays(
    position,
    mass,
    plate_normal,
    plate_mass,
    i,
    j,
    l0,
    r_min,
    name: str = "sample",
    radius=None,
    rotational_inertia=None,
    plate_point=None,
    head_size_m=None,
) -> BondNetwork:
    """Build a :class:`BondNetwork` from the arrays of the sample file (shapes as there).

    ``radius`` (N,) m: without it there are no contact points and only the barycentre
    kinematics is available; ``rotational_inertia`` (N,) kg m^2 defaults to
    2/5 m r^2; ``plate_point`` (2, 3) m to the origin; ``head_size_m`` = (b, e) m of the head
    (default: x-y extent of the contact points of the top-plate bonds). The arrays are taken
    as consistent: the sample store checks a file's (:func:`asphalt_nscd.sample.store.
    read_sample`), the core's state is consistent by construction.
    """
    position = np.asarray(position, float).reshape(-1, 3)
    mass = np.asarray(mass, float).ravel()
    i = np.asarray(i, np.int64).ravel()
    j = np.asarray(j, np.int64).ravel()
    plate_normal = np.asarray(plate_normal, float).reshape(2, 3)
    plate_normal = plate_normal / np.linalg.norm(plate_normal, axis=1, keepdims=True)
    plate_mass = np.asarray(plate_mass, float).ravel()
    plate_point = np.zeros((2, 3)) if plate_point is None else np.asarray(plate_point, float).reshape(2, 3)
    normal = bond_normals(position, plate_normal, i, j)
    contact = inertia = None
    if radius is not None:
        radius = np.asarray(radius, float).ravel()
        contact = contact_points(position, radius, plate_normal, i, j, l0)
        inertia = (
            0.4 * mass * radius**2 if rotational_inertia is None else np.asarray(rotational_inertia, float).ravel()
        )
    if head_size_m is None:
        top = contact[j == -2] if contact is not None else position[i[j == -2]]
        head_size_m = np.ptp(top[:, :2], axis=0) if len(top) else (0.0, 0.0)
    return BondNetwork(
        position=position,
        mass=mass,
        plate_mass=plate_mass,
        plate_normal=plate_normal,
        i=i,
        j=j,
        normal=normal,
        scale=bond_scale(r_min, l0),
        name=name,
        radius=radius,
        rotational_inertia=inertia,
        contact_point=contact,
        plate_point=plate_point,
        plate_inertia=head_inertia(float(plate_mass[1]), *map(float, head_size_m)),
    )


def network_from_sample(sample) -> BondNetwork:
    """The :class:`BondNetwork` of a sample read by the store (:class:`asphalt_nscd.sample.store.
    SampleData`, arrays checked there), named after it; the head size (b, e) is the root
    attributes ``b_m, e_m`` when present (module docstring)."""
    return network_from_arrays(
        sample.position,
        sample.mass,
        sample.plate_normal,
        sample.plate_mass,
        sample.bonds["i"],
        sample.bonds["j"],
        sample.bonds["l0"],
        sample.bonds["r_min"],
        name=sample.name,
        radius=sample.radius,
        rotational_inertia=sample.inertia,
        plate_point=sample.plate_point,
        head_size_m=sample.head_size_m,
    )
