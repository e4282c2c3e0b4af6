"""Geometric steps of the sample preparation (Section 3.2.1): lattice placement, cut to the
trapezoid, flip, shrink, density, bonds, and the descriptors of the summary.

Frames
------
*Deposition frame*: box ``[0, L] x [0, W] x [0, H]`` with gravity along -z; L is the
specimen height h (the long side lies flat), W the thickness e.

*Specimen frame* (docs/design.md, after the flip): z along h from the base (z = 0, bottom
plate, width B) to the head (z = h, top plate, width b); x the bending direction, centred
(|x| <= w(z)/2); y the thickness, centred (|y| <= e/2). The flip is the rotation by +90 deg
about y that maps the deposition frame to the specimen frame::

    x_spec = zc - z_dep,   y_spec = y_dep - W/2,   z_spec = x_dep

where ``zc`` is the height of the trapezoid's mid-line in the deposited layer.

Choices (the paper does not say)
--------------------------------
* Lattice: cubic cells of edge ``a`` (>= the largest diameter) filling the box from the
  floor; a sphere with d > a/2 takes a whole cell; smaller spheres go eight to a cell, one
  per half-size sub-cell (otherwise the paper's 14 160 spheres would not fit in the
  8000 cells of its 0.25 x 0.025 x 1.6 m box). Spheres and groups are shuffled, and each
  sphere gets a uniform random offset within its (sub-)cell, keeping clear of the walls.
* The trapezoid is centred on the mid-height of the deposited layer,
  ``zc = max(H_layer, B) / 2`` with ``H_layer`` the layer height of ``layer_height.measure``
  (:func:`layer_height`; default the mean height of the layer's surface, which is what the
  paper's "layer of 60 mm" can be compared with, not the top of its highest sphere).
* Bonds: every pair whose surface gap is below ``d_min`` (the smallest diameter of the
  numerical PSD) after the shrink, and every sphere whose gap to a plate is below ``d_min``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


@dataclass(frozen=True)
class Trapezoid:
    """EN 12697-26 trapezoid (m): base width B, head width b, thickness e, height h."""

    B: float
    b: float
    e: float
    h: float

    def __post_init__(self):
        if not (self.B > 0 and self.b > 0 and self.e > 0 and self.h > 0):
            raise ValueError(f"trapezoid dimensions must be > 0, got {self}")

    @property
    def volume(self) -> float:
        """(B + b)/2 * e * h (m^3)."""
        return 0.5 * (self.B + self.b) * self.e * self.h

    def width(self, z):
        """Width along x at height z (m): B at z = 0, b at z = h."""
        return self.B - (self.B - self.b) * np.asarray(z) / self.h

    def contains(self, position) -> np.ndarray:
        """Boolean mask (N,) of points (N, 3) of the specimen frame inside the trapezoid."""
        p = np.asarray(position, dtype=float)
        z = p[:, 2]
        return (z >= 0.0) & (z <= self.h) & (np.abs(p[:, 0]) <= 0.5 * self.width(z)) & (np.abs(p[:, 1]) <= 0.5 * self.e)


def lattice_positions(radius, box, cell: float, rng: np.random.Generator) -> np.ndarray:
    """Random placement of spheres on a cubic lattice filling the box from the floor.

    Parameters
    ----------
    radius : array_like (N,)
        sphere radii (m).
    box : (3,) sequence
        box extents L, W, H (m) of the deposition frame, origin at a corner.
    cell
        lattice spacing a (m), >= the largest diameter.
    rng
        seeded generator (all randomness of the placement comes from it).

    Returns
    -------
    ndarray (N, 3)
        barycentres (m), each sphere inside its own (sub-)cell, hence no overlaps and no
        contact with the walls.

    Raises
    ------
    ValueError
        if a sphere is larger than a cell, the box is narrower than a cell, or the box is
        too low for all spheres.
    """
    r = np.asarray(radius, dtype=float)
    L, W, H = (float(v) for v in box)
    if 2 * r.max() > cell * (1 + 1e-12):
        raise ValueError(f"largest diameter {2 * r.max():.4g} m exceeds the lattice cell {cell:.4g} m")
    n_cells = np.array([int(np.floor(L / cell + 1e-9)), int(np.floor(W / cell + 1e-9)), int(np.floor(H / cell + 1e-9))])
    if n_cells[0] < 1 or n_cells[1] < 1:
        raise ValueError(f"box {L:.4g} x {W:.4g} m is narrower than one lattice cell of {cell:.4g} m")
    origin = 0.5 * (np.array([L, W, H]) - n_cells * cell)
    origin[2] = 0.0

    order = rng.permutation(r.size)
    small = order[2 * r[order] <= 0.5 * cell]
    large = order[2 * r[order] > 0.5 * cell]
    groups = [small[k : k + 8] for k in range(0, small.size, 8)]
    items = [np.array([i]) for i in large] + groups
    n_items = len(items)
    per_layer = n_cells[0] * n_cells[1]
    if n_items > per_layer * n_cells[2]:
        need = int(np.ceil(n_items / per_layer)) * cell
        raise ValueError(
            f"{n_items} lattice cells needed but the box holds {per_layer * n_cells[2]}; box height >= {need:.4g} m"
        )
    item_order = rng.permutation(n_items)
    flat = np.arange(n_items)
    cells = np.stack([flat % n_cells[0], (flat // n_cells[0]) % n_cells[1], flat // per_layer], axis=1)

    sub = 0.5 * cell * np.array([[i, j, k] for k in (0, 1) for j in (0, 1) for i in (0, 1)], dtype=float)
    position = np.empty((r.size, 3))
    for slot, item in enumerate(item_order):
        corner = origin + cells[slot] * cell
        members = items[item]
        if members.size == 1 and 2 * r[members[0]] > 0.5 * cell:
            lows, size = corner[None, :], cell
        else:
            lows, size = corner + sub[: members.size], 0.5 * cell
        free = size - 2 * r[members]  # room to move inside the (sub-)cell
        offset = rng.random((members.size, 3)) * free[:, None]
        position[members] = lows + r[members, None] + offset
    return position


def to_specimen_frame(position, zc: float, width: float) -> np.ndarray:
    """Flip (N, 3) deposition-frame points to the specimen frame (rotation about y, see module)."""
    p = np.asarray(position, dtype=float)
    return np.column_stack([zc - p[:, 2], p[:, 1] - 0.5 * width, p[:, 0]])


#: measures of the layer height (:func:`layer_height`)
LAYER_MEASURES = ("surface", "max")


def layer_top(position, radius) -> float:
    """Top of the highest sphere of the layer, max(z + r) (m)."""
    return float(np.max(np.asarray(position)[:, 2] + np.asarray(radius)))


def layer_height(position, radius, footprint, measure: str = "surface", cell: float = 5e-3) -> float:
    """Height of a deposited layer (m) in the box ``[0, L] x [0, W]`` (``footprint`` = (L, W), m).

    ``surface`` (the height one would measure on the layer): the mean over a grid of square
    columns of side ~``cell`` (m) of the top of the highest sphere in each column; a column
    without a sphere counts 0. ``max``: the top of the highest sphere, max(z + r), which a
    single large sphere resting on the rough surface sets (on the paper-scale layers about
    16 mm above the surface measure).

    Raises
    ------
    ValueError on an unknown measure or a non-positive cell.
    """
    if measure not in LAYER_MEASURES:
        raise ValueError(f"layer height measure must be one of {LAYER_MEASURES}, got {measure!r}")
    p = np.asarray(position, dtype=float)
    top = p[:, 2] + np.asarray(radius, dtype=float)
    if measure == "max" or top.size == 0:
        return float(top.max()) if top.size else 0.0
    if not cell > 0:
        raise ValueError(f"layer height cell must be > 0, got {cell}")
    n = [max(1, int(round(float(extent) / cell))) for extent in footprint]
    ix = [np.clip((p[:, k] / float(footprint[k]) * n[k]).astype(int), 0, n[k] - 1) for k in (0, 1)]
    columns = np.zeros(n)
    np.maximum.at(columns, (ix[0], ix[1]), top)
    return float(columns.mean())


def solid_fraction_profile(
    position, radius, height: float, footprint, dz: float = 2e-3
) -> tuple[np.ndarray, np.ndarray]:
    """Solid fraction of horizontal slices of thickness ``dz`` (m) from the floor to
    ``height`` in a box of ``footprint`` (L, W) m: the exact volume of the sphere caps in each
    slice over the slice volume. Returns (slice mid-heights (S,) m, solid fraction (S,))."""
    p = np.asarray(position, dtype=float)
    r = np.asarray(radius, dtype=float)
    z = p[:, 2]
    edges = np.arange(0.0, height + 0.5 * dz, dz)

    def below(h):  # volume of each sphere below the plane z + h
        t = np.clip(h, -r, r)
        return np.pi * (r**2 * (t + r) - (t**3 + r**3) / 3.0)

    vol = np.array([np.sum(below(edges[k + 1] - z) - below(edges[k] - z)) for k in range(edges.size - 1)])
    return 0.5 * (edges[1:] + edges[:-1]), vol / (footprint[0] * footprint[1] * dz)


def shrink_radii(radius, volume_fraction: float) -> np.ndarray:
    """Radii after removing ``volume_fraction`` of each sphere's volume: r (1 - f)^(1/3)."""
    if not 0.0 <= volume_fraction < 1.0:
        raise ValueError(f"shrink volume fraction must be in [0, 1), got {volume_fraction}")
    return np.asarray(radius, dtype=float) * (1.0 - volume_fraction) ** (1.0 / 3.0)


def sphere_volume(radius) -> np.ndarray:
    """4/3 pi r^3 (m^3), shape of ``radius``."""
    return 4.0 / 3.0 * np.pi * np.asarray(radius, dtype=float) ** 3


def density_for_mass(radius, mass: float) -> float:
    """Uniform density (kg/m^3) giving the spheres the total ``mass`` (kg)."""
    return float(mass / sphere_volume(radius).sum())


def sphere_pairs_within(position, radius, gap: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sphere pairs (i < j) with surface gap ``|x_i - x_j| - r_i - r_j < gap``.

    Returns
    -------
    i, j : ndarray of int (P,)
    distance : ndarray (P,)
        barycentre distance (m).
    """
    p = np.asarray(position, dtype=float)
    r = np.asarray(radius, dtype=float)
    if p.shape[0] < 2:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, np.zeros(0)
    pairs = cKDTree(p).query_pairs(2 * r.max() + gap, output_type="ndarray")
    i, j = pairs[:, 0].astype(np.int64), pairs[:, 1].astype(np.int64)
    dist = np.linalg.norm(p[i] - p[j], axis=1)
    keep = dist - r[i] - r[j] < gap
    order = np.lexsort((j[keep], i[keep]))
    return i[keep][order], j[keep][order], dist[keep][order]


def make_bonds(position, radius, plate_point, plate_normal, d_min: float) -> dict[str, np.ndarray]:
    """Bonds of the sample file (docs/design.md): sphere pairs and sphere-plate pairs whose
    gap is below ``d_min`` (Section 3.1: "gap below d_min").

    Parameters
    ----------
    position : (N, 3), radius : (N,)
        spheres after the shrink (m).
    plate_point, plate_normal : (K, 3)
        a point of each plate plane and its unit normal pointing into the sample; plate k
        gets index ``j = -1 - k``.
    d_min
        gap threshold (m).

    Returns
    -------
    dict with ``i, j`` (int64, (B,)), ``delta0`` (initial surface gap, m), ``l0`` (barycentre
    distance, or centre-to-plane distance, m), ``r_min`` (smaller radius, or the sphere's, m).
    """
    p = np.asarray(position, dtype=float)
    r = np.asarray(radius, dtype=float)
    i, j, dist = sphere_pairs_within(p, r, d_min)
    out = {
        "i": [i],
        "j": [j],
        "delta0": [dist - r[i] - r[j]],
        "l0": [dist],
        "r_min": [np.minimum(r[i], r[j])],
    }
    for k, (point, normal) in enumerate(zip(np.atleast_2d(plate_point), np.atleast_2d(plate_normal))):
        centre_dist = (p - point) @ normal
        idx = np.flatnonzero(centre_dist - r < d_min)
        out["i"].append(idx.astype(np.int64))
        out["j"].append(np.full(idx.size, -1 - k, dtype=np.int64))
        out["delta0"].append(centre_dist[idx] - r[idx])
        out["l0"].append(centre_dist[idx])
        out["r_min"].append(r[idx])
    return {key: np.concatenate(val) for key, val in out.items()}


def coordination_number(position, radius, tolerance: float) -> float:
    """Mean number of contacts per sphere, a contact being a surface gap below ``tolerance`` (m):
    ``2 N_contacts / N``."""
    n = len(radius)
    if n == 0:
        return 0.0
    i, _, _ = sphere_pairs_within(position, radius, tolerance)
    return 2.0 * i.size / n


def max_overlap(position, radius) -> float:
    """Largest interpenetration between two spheres (m); 0 when none overlap."""
    i, j, dist = sphere_pairs_within(position, radius, 0.0)
    r = np.asarray(radius)
    return float(np.max(r[i] + r[j] - dist)) if i.size else 0.0
