"""Small bonded test samples in the sample-file format (docs/design.md), for the tests and the
benchmarks; the physical samples come from :mod:`.prepare`.

:func:`sample_from_bonds` builds a :class:`~.store.SampleData` from given spheres and bonded
pairs between two horizontal plates (normals +z at the bottom, -z at the top, into the
sample), computing ``delta0, l0, r_min`` of every bond from the geometry;
:func:`lattice_sample` places spheres on a jittered cubic lattice and bonds its near
neighbours. Write either with :func:`.store.write_sample`.
"""

from __future__ import annotations

import numpy as np

from .store import SampleData


def sample_from_bonds(
    position,
    radius,
    mass,
    plate_point,
    i,
    j,
    plate_mass=(np.inf, 0.235),
    density_kg_m3: float = 3415.0,
    seed: int = 0,
    d_min_m: float = 2e-3,
    config: dict | None = None,
) -> SampleData:
    """A bonded sample between horizontal plates with the bond geometry of docs/design.md.

    Parameters
    ----------
    position : (N, 3) m; radius, mass : (N,) m, kg; plate_point : (2, 3) m;
    i, j : (B,) bond bodies (j = -1 bottom, -2 top plate); plate_mass : (2,) kg.
    density_kg_m3, seed, d_min_m, config : root attributes of the file.

    Returns
    -------
    SampleData with l0 = barycentre distance (sphere-sphere) or centre-to-plane distance
    (sphere-plate), r_min = smaller radius (or the sphere's), delta0 = l0 - r_i - r_j (or
    l0 - r_i), m.
    """
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
    attrs = {
        "seed": int(seed),
        "scale": 1.0,
        "density_kg_m3": float(density_kg_m3),
        "friction": 0.7,
        "d_min_m": float(d_min_m),
        "config": config or {},
        "stage": "final",
    }
    return SampleData(
        position=position,
        radius=radius,
        mass=np.asarray(mass, float),
        plate_point=plate_point,
        plate_normal=plate_normal,
        plate_mass=np.asarray(plate_mass, float),
        bonds={"i": i, "j": j, "delta0": delta0, "l0": l0, "r_min": r_min},
        attrs=attrs,
    )


def lattice_sample(
    n_spheres: int,
    seed: int = 0,
    spacing: float = 4.0e-3,
    aspect=(1.0, 0.5, 4.0),
    radius_range: tuple[float, float] = (1.0e-3, 1.6e-3),
    jitter: float = 0.05,
    density_kg_m3: float = 3415.0,
    d_min: float = 2e-3,
    plate_mass=(np.inf, 0.235),
) -> SampleData:
    """Spheres on a jittered cubic lattice with bonds where the gap is below ``d_min``.

    A stand-in for a prepared sample (same file format) for tests and the benchmark. Sites are
    jittered by up to ``jitter`` x spacing per axis; with the defaults no two spheres touch
    (2 r_max + 2 sqrt(3) jitter spacing < spacing, so the time-domain run has no contact) and
    the face neighbours are bonded (coordination about 6). The lattice has ``aspect`` cells
    along (x, y, z) scaled so that it holds at least ``n_spheres`` sites; the first
    ``n_spheres`` sites are kept. Spheres of the lowest (highest) layer are bonded to the
    bottom (top) plate (:func:`sample_from_bonds`, top-plate mass ``plate_mass[1]`` kg).
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
    gap = (
        np.linalg.norm(position[pairs[:, 1]] - position[pairs[:, 0]], axis=1)
        - radius[pairs[:, 0]]
        - radius[pairs[:, 1]]
    )
    pairs = pairs[gap < d_min]
    z_bottom, z_top = 0.0, (sites[:, 2].max() + 1.0) * spacing
    bottom = np.flatnonzero(sites[:, 2] == 0)
    top = np.flatnonzero(sites[:, 2] == sites[:, 2].max())
    i = np.concatenate([pairs[:, 0], bottom, top])
    j = np.concatenate([pairs[:, 1], np.full(len(bottom), -1), np.full(len(top), -2)])
    return sample_from_bonds(
        position,
        radius,
        mass,
        [[0.0, 0.0, z_bottom], [0.0, 0.0, z_top]],
        i,
        j,
        plate_mass=plate_mass,
        density_kg_m3=density_kg_m3,
        seed=seed,
        d_min_m=d_min,
    )
