"""The bonded sample as a linear network: reading and writing the sample file, test samples.

A numerical sample (``results/samples/<sample>.h5``, format of docs/design.md) is read into a
:class:`BondNetwork`: sphere barycentres and masses, the two plates, and for every bond the
two bodies, the unit vector n of the bond frame in the initial configuration and the
geometric factor a_b = pi r_min^2 / l0 of Eqs. 30-33.

Bond frame (docs/design.md): for a sphere-sphere bond n = (x_j - x_i)/|x_j - x_i|; for a
sphere-plate bond n is the plate normal. The linearised bond stiffness depends on n only
through n n^T, so the sign of n does not matter.

Contact point of a bond (used by ``bond_kinematics="contact"`` of :mod:`.solver`): the middle
of the gap on the line of centres, c = x_i + (r_i + delta0/2) e with e the unit vector from
sphere i towards the other body (e = n for sphere-sphere bonds, minus the plate normal for
sphere-plate bonds), delta0 = l0 - r_i - r_j (sphere-sphere) or l0 - r_i (sphere-plate).

Top-plate (head) rotational inertia, used when the head is free to rotate: the head is a
steel cuboid (density :data:`PLATE_DENSITY_KG_M3`) of the sample file's top-plate mass m
(0.235 kg scaled with the sample) and footprint b x e (root attributes ``b_m, e_m`` of the
sample file, the specimen's head; else the x-y extent of the top-plate bonds' contact
points), of thickness t = m / (rho b e). It rotates about the head-face centre
``plates/point[1]``: I = diag(m (e^2 + t^2)/12, m (b^2 + t^2)/12, m (b^2 + e^2)/12) +
m (t/2)^2 diag(1, 1, 0) (parallel-axis term of the face offset). The mass coupling between
the imposed head translation and the head rotation (centre of mass t/2 above the face) is
neglected.

:func:`write_sample` writes the same format; :func:`lattice_sample` builds a bonded sample of
spheres on a jittered cubic lattice between two plates (for tests and the benchmark; the
physical samples come from ``asphalt_nscd.sample``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io import InputError, atomic_path
from ..rheology.laws import bond_scale

#: Datasets the harmonic solver needs, with their expected trailing shape.
REQUIRED = {
    "spheres/position": (3,),
    "spheres/radius": (),
    "spheres/mass": (),
    "plates/point": (3,),
    "plates/normal": (3,),
    "plates/mass": (),
    "bonds/i": (),
    "bonds/j": (),
    "bonds/l0": (),
    "bonds/r_min": (),
}
#: Steel density of the head plate (rotational inertia, module docstring), kg/m^3.
PLATE_DENSITY_KG_M3 = 7850.0


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


def contact_points(position, radius, plate_normal, i, j, l0) -> np.ndarray:
    """Contact points c = x_i + (r_i + delta0/2) e of the bonds, shape (B, 3), m.

    e points from sphere i to the other body; delta0 = l0 - r_i - r_j (sphere-sphere) or
    l0 - r_i (sphere-plate), so r_i + delta0/2 = (l0 + r_i - r_j)/2 or (l0 + r_i)/2.
    """
    sph = j >= 0
    d = np.empty((len(i), 3))
    d[sph] = position[j[sph]] - position[i[sph]]
    d[sph] /= np.linalg.norm(d[sph], axis=1, keepdims=True)
    d[~sph] = -plate_normal[-1 - j[~sph]]
    other = np.where(sph, radius[np.where(sph, j, 0)], 0.0)
    arm = 0.5 * (np.asarray(l0, float) + radius[i] - other)
    return position[i] + arm[:, None] * d


def head_inertia(mass: float, b_m: float, e_m: float,
                 density_kg_m3: float = PLATE_DENSITY_KG_M3) -> np.ndarray:
    """Moments of inertia (3,) kg m^2 of the head about its face centre (module docstring).

    A steel cuboid of mass ``mass`` (kg), footprint ``b_m`` (along x) x ``e_m`` (along y), m.
    """
    if not (mass > 0 and np.isfinite(mass)) or b_m <= 0 or e_m <= 0:
        return np.zeros(3)
    t = mass / (density_kg_m3 * b_m * e_m)
    return np.array([mass * (e_m**2 + t**2) / 12 + mass * t**2 / 4,
                     mass * (b_m**2 + t**2) / 12 + mass * t**2 / 4,
                     mass * (b_m**2 + e_m**2) / 12])


def network_from_arrays(position, mass, plate_normal, plate_mass, i, j, l0, r_min,
                        name: str = "sample", radius=None, rotational_inertia=None,
                        plate_point=None, head_size_m=None) -> BondNetwork:
    """Build a :class:`BondNetwork` from the arrays of the sample file (shapes as there).

    ``radius`` (N,) m: without it there are no contact points and only the barycentre
    kinematics is available; ``rotational_inertia`` (N,) kg m^2 defaults to
    2/5 m r^2; ``plate_point`` (2, 3) m to the origin; ``head_size_m`` = (b, e) m of the head
    (default: x-y extent of the contact points of the top-plate bonds).

    Raises
    ------
    ValueError
        on inconsistent shapes or indices, non-positive masses, r_min or l0.
    """
    position = np.asarray(position, float).reshape(-1, 3)
    mass = np.asarray(mass, float).ravel()
    i = np.asarray(i, np.int64).ravel()
    j = np.asarray(j, np.int64).ravel()
    n_sph = position.shape[0]
    if mass.shape != (n_sph,):
        raise ValueError(f"spheres/mass has shape {mass.shape}, expected ({n_sph},)")
    if np.any(~(mass > 0)):
        raise ValueError("sphere masses must be positive")
    if i.shape != j.shape or np.shape(l0) != i.shape or np.shape(r_min) != i.shape:
        raise ValueError("bonds/i, bonds/j, bonds/l0 and bonds/r_min must have the same length")
    if np.any((i < 0) | (i >= n_sph)):
        raise ValueError(f"bonds/i must lie in [0, {n_sph})")
    if np.any((j >= n_sph) | (j < -2) | (j == i)):
        raise ValueError(f"bonds/j must lie in [0, {n_sph}) (other sphere) or be -1/-2 (plates)")
    plate_normal = np.asarray(plate_normal, float).reshape(2, 3)
    plate_normal = plate_normal / np.linalg.norm(plate_normal, axis=1, keepdims=True)
    plate_mass = np.asarray(plate_mass, float).ravel()
    plate_point = (np.zeros((2, 3)) if plate_point is None
                   else np.asarray(plate_point, float).reshape(2, 3))
    contact = inertia = None
    if radius is not None:
        radius = np.asarray(radius, float).ravel()
        if radius.shape != (n_sph,) or np.any(~(radius > 0)):
            raise ValueError(f"spheres/radius must be positive with shape ({n_sph},)")
        contact = contact_points(position, radius, plate_normal, i, j, l0)
        inertia = (0.4 * mass * radius**2 if rotational_inertia is None
                   else np.asarray(rotational_inertia, float).ravel())
        if inertia.shape != (n_sph,) or np.any(~(inertia > 0)):
            raise ValueError(f"spheres/inertia must be positive with shape ({n_sph},)")
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
        normal=bond_normals(position, plate_normal, i, j),
        scale=bond_scale(r_min, l0),
        name=name,
        radius=radius,
        rotational_inertia=inertia,
        contact_point=contact,
        plate_point=plate_point,
        plate_inertia=head_inertia(float(plate_mass[1]), *map(float, head_size_m)),
    )


def read_sample(path: str | Path) -> BondNetwork:
    """Read a sample file (docs/design.md format) into a :class:`BondNetwork`.

    Raises
    ------
    InputError
        if the file is missing, a dataset is absent or has the wrong shape, or the bond
        data are inconsistent; the message names the file and the dataset.
    """
    import h5py

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: sample file not found")
    data = {}
    try:
        with h5py.File(path, "r") as h5:
            for key, tail in REQUIRED.items():
                if key not in h5:
                    raise InputError(f"{path}: dataset '{key}' missing (see docs/design.md)")
                value = h5[key][()]
                if value.shape[1:] != tail:
                    raise InputError(f"{path}: dataset '{key}' has shape {value.shape}, "
                                     f"expected (n,{','.join(map(str, tail))})")
                data[key] = value
            if "spheres/inertia" in h5:
                data["spheres/inertia"] = h5["spheres/inertia"][()]
            head = None
            if "b_m" in h5.attrs and "e_m" in h5.attrs:
                head = (float(h5.attrs["b_m"]), float(h5.attrs["e_m"]))
    except OSError as exc:
        raise InputError(f"{path}: not a readable HDF5 sample file ({exc})") from exc
    if data["plates/point"].shape[0] != 2:
        raise InputError(f"{path}: 'plates/point' must have 2 rows (bottom, top)")
    try:
        return network_from_arrays(
            data["spheres/position"], data["spheres/mass"], data["plates/normal"],
            data["plates/mass"], data["bonds/i"], data["bonds/j"], data["bonds/l0"],
            data["bonds/r_min"], name=path.stem, radius=data["spheres/radius"],
            rotational_inertia=data.get("spheres/inertia"), plate_point=data["plates/point"],
            head_size_m=head)
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from exc


def write_sample(path: str | Path, position, radius, mass, plate_point, i, j,
                 plate_mass=(np.inf, 0.235), density_kg_m3: float = 3415.0,
                 seed: int = 0, d_min_m: float = 2e-3, config: dict | None = None) -> None:
    """Write a bonded sample in the docs/design.md format (atomically).

    Plates are horizontal (normals +z at the bottom, -z at the top, into the sample).
    ``delta0``, ``l0`` and ``r_min`` of every bond are computed from the geometry.

    Parameters
    ----------
    position : (N, 3) m; radius, mass : (N,) m, kg; plate_point : (2, 3) m;
    i, j : (B,) bond bodies (j = -1 bottom, -2 top plate); plate_mass : (2,) kg.
    """
    import h5py

    position = np.asarray(position, float)
    radius = np.asarray(radius, float)
    i = np.asarray(i, np.int64)
    j = np.asarray(j, np.int64)
    plate_point = np.asarray(plate_point, float)
    plate_normal = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    l0 = np.empty(len(i))
    r_min = np.empty(len(i))
    delta0 = np.empty(len(i))
    sph = j >= 0
    l0[sph] = np.linalg.norm(position[j[sph]] - position[i[sph]], axis=1)
    r_min[sph] = np.minimum(radius[i[sph]], radius[j[sph]])
    delta0[sph] = l0[sph] - radius[i[sph]] - radius[j[sph]]
    k = -1 - j[~sph]
    l0[~sph] = np.abs(np.einsum("bk,bk->b", position[i[~sph]] - plate_point[k], plate_normal[k]))
    r_min[~sph] = radius[i[~sph]]
    delta0[~sph] = l0[~sph] - radius[i[~sph]]
    units = {"spheres/position": "m", "spheres/radius": "m", "spheres/mass": "kg",
             "spheres/inertia": "kg m2", "plates/point": "m", "plates/normal": "1",
             "plates/mass": "kg", "bonds/i": "1", "bonds/j": "1", "bonds/delta0": "m",
             "bonds/l0": "m", "bonds/r_min": "m"}
    with atomic_path(path) as tmp:
        with h5py.File(tmp, "w") as h5:
            h5["spheres/position"] = position
            h5["spheres/radius"] = radius
            h5["spheres/mass"] = np.asarray(mass, float)
            h5["spheres/inertia"] = 0.4 * np.asarray(mass, float) * radius**2
            h5["plates/point"] = plate_point
            h5["plates/normal"] = plate_normal
            h5["plates/mass"] = np.asarray(plate_mass, float)
            h5["bonds/i"] = i
            h5["bonds/j"] = j
            h5["bonds/delta0"] = delta0
            h5["bonds/l0"] = l0
            h5["bonds/r_min"] = r_min
            h5.attrs["units"] = json.dumps(units)
            h5.attrs["seed"] = int(seed)
            h5.attrs["scale"] = 1.0
            h5.attrs["density_kg_m3"] = float(density_kg_m3)
            h5.attrs["friction"] = 0.7
            h5.attrs["d_min_m"] = float(d_min_m)
            h5.attrs["config"] = json.dumps(config or {})
            h5.attrs["stage"] = "final"


def lattice_sample(n_spheres: int, seed: int = 0, spacing: float = 4.0e-3,
                   aspect=(1.0, 0.5, 4.0), radius_range=(1.0e-3, 1.6e-3), jitter: float = 0.05,
                   density_kg_m3: float = 3415.0, d_min: float = 2e-3):
    """Spheres on a jittered cubic lattice with bonds where the gap is below ``d_min``.

    A stand-in for a prepared sample (same file format) for tests and the benchmark. Sites are
    jittered by up to ``jitter`` x spacing per axis; with the defaults no two spheres touch
    (2 r_max + 2 sqrt(3) jitter spacing < spacing, so the time-domain run has no contact) and
    the face neighbours are bonded (coordination about 6). The lattice has ``aspect`` cells along (x, y, z) scaled so that it
    holds at least ``n_spheres`` sites; the first ``n_spheres`` sites are kept. Spheres of the
    lowest (highest) layer are bonded to the bottom (top) plate.

    Returns
    -------
    dict with position (N, 3) m, radius (N,) m, mass (N,) kg, plate_point (2, 3) m,
    i, j (B,) — the arguments of :func:`write_sample`.
    """
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(seed)
    a = np.asarray(aspect, float)
    k = (n_spheres / np.prod(a)) ** (1.0 / 3.0)
    nx, ny = (max(1, int(np.ceil(k * a[0]))), max(1, int(np.ceil(k * a[1]))))
    nz = int(np.ceil(n_spheres / (nx * ny)))
    grid = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1)
    sites = grid.reshape(-1, 3)
    sites = sites[np.lexsort((sites[:, 0], sites[:, 1], sites[:, 2]))][:n_spheres]
    position = (sites + 0.5) * spacing + rng.uniform(-jitter, jitter, size=sites.shape) * spacing
    radius = rng.uniform(*radius_range, size=n_spheres)
    mass = density_kg_m3 * 4.0 / 3.0 * np.pi * radius**3
    tree = cKDTree(position)
    pairs = tree.query_pairs(2 * radius_range[1] + d_min, output_type="ndarray")
    gap = (np.linalg.norm(position[pairs[:, 1]] - position[pairs[:, 0]], axis=1)
           - radius[pairs[:, 0]] - radius[pairs[:, 1]])
    pairs = pairs[gap < d_min]
    z_bottom, z_top = 0.0, (sites[:, 2].max() + 1.0) * spacing
    bottom = np.flatnonzero(sites[:, 2] == 0)
    top = np.flatnonzero(sites[:, 2] == sites[:, 2].max())
    i = np.concatenate([pairs[:, 0], bottom, top])
    j = np.concatenate([pairs[:, 1], np.full(len(bottom), -1), np.full(len(top), -2)])
    return {"position": position, "radius": radius, "mass": mass,
            "plate_point": np.array([[0.0, 0.0, z_bottom], [0.0, 0.0, z_top]]), "i": i, "j": j}
