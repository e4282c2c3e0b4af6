"""Broad and narrow phase contact detection in O(N) with a uniform cell list.

Cells have the size of the largest sphere diameter plus the search distance, so every
pair closer than that lies in the same or one of the 26 neighbouring cells. Spheres are
bucketed by a counting sort (O(N)); each sphere is tested against the spheres of higher
index in its 27 cells. Planes are infinite: every sphere is tested against every plate
(O(N P), P ~ 6). The grid is a dense box over the spheres' bounding box; its cell size is
enlarged if it would hold more than 8 N + 1000 cells.

Verlet skin: :class:`CandidateList` keeps the pairs closer than alert + skin and re-runs
the cell-list search only when the largest sphere displacement since the last search (x 2,
plus the largest plate displacement) exceeds the skin; in between, only the gaps and
frames of the stored pairs are recomputed (narrow phase, O(C)). The result is identical to
a fresh search at every step.

Contact frames: n from the antagonist to the candidate (unit centre-to-centre vector, or
the plate's inward normal), t = n x e (e the global axis least aligned with n), s = n x t.

Excluded pairs (:class:`Exclusions`, from :func:`bonded_exclusions`): the pairs whose intact
bond is their interaction law (``NSCDParameters.bonded_contact``) are skipped inside the
search kernels, by a per-sphere list (CSR) of excluded sphere partners and a per-sphere,
per-plate flag; they never enter the candidate list. A new exclusion set (a bond broke)
forces a fresh search at the next call of :meth:`CandidateList.contacts`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._jit import kernel


class Exclusions:
    """Pairs that contact detection skips (module docstring).

    Attributes
    ----------
    ptr : (N+1,) int64, nbr : (M,) int64 — CSR: the excluded sphere partners of sphere a
        are ``nbr[ptr[a]:ptr[a+1]]`` (both directions, sorted).
    plate : (N, P) uint8 — 1 where the pair (sphere a, plate k) is excluded.
    """

    def __init__(self, ptr, nbr, plate):
        self.ptr = np.ascontiguousarray(ptr, dtype=np.int64)
        self.nbr = np.ascontiguousarray(nbr, dtype=np.int64)
        self.plate = np.ascontiguousarray(plate, dtype=np.uint8)

    @classmethod
    def none(cls, n_spheres: int, n_plates: int) -> "Exclusions":
        return cls(np.zeros(n_spheres + 1, np.int64), np.zeros(0, np.int64), np.zeros((n_spheres, n_plates), np.uint8))


def bonded_exclusions(n_spheres: int, n_plates: int, i, j) -> Exclusions:
    """:class:`Exclusions` of the pairs (i[b], j[b]) (state.py convention: j a sphere index
    or ``-1-k`` for plate k).

    Raises
    ------
    ValueError if an index is out of range.
    """
    i = np.asarray(i, dtype=np.int64).reshape(-1)
    j = np.asarray(j, dtype=np.int64).reshape(-1)
    if len(i) != len(j):
        raise ValueError("i and j differ in length")
    if len(i) and (i.min() < 0 or i.max() >= n_spheres or j.max() >= n_spheres or j.min() < -n_plates):
        raise ValueError("excluded pair index out of range")
    sph = j >= 0
    a = np.concatenate([i[sph], j[sph]])
    b = np.concatenate([j[sph], i[sph]])
    order = np.lexsort((b, a))
    ptr = np.zeros(n_spheres + 1, np.int64)
    np.cumsum(np.bincount(a, minlength=n_spheres), out=ptr[1:])
    plate = np.zeros((n_spheres, n_plates), np.uint8)
    plate[i[~sph], -1 - j[~sph]] = 1
    return Exclusions(ptr, b[order], plate)


@njit(cache=True)
def _grid(pos, cell):
    n = pos.shape[0]
    lo = np.empty(3)
    hi = np.empty(3)
    for d in range(3):
        lo[d] = pos[:, d].min()
        hi[d] = pos[:, d].max()
    while True:
        dims = np.empty(3, dtype=np.int64)
        for d in range(3):
            dims[d] = int((hi[d] - lo[d]) / cell) + 1
        if dims[0] * dims[1] * dims[2] <= 8 * n + 1000:
            break
        cell *= 1.5
    ncell = dims[0] * dims[1] * dims[2]
    cid = np.empty(n, dtype=np.int64)
    for a in range(n):
        cx = int((pos[a, 0] - lo[0]) / cell)
        cy = int((pos[a, 1] - lo[1]) / cell)
        cz = int((pos[a, 2] - lo[2]) / cell)
        cid[a] = (cx * dims[1] + cy) * dims[2] + cz
    start = np.zeros(ncell + 1, dtype=np.int64)
    for a in range(n):
        start[cid[a] + 1] += 1
    for c in range(ncell):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for a in range(n):
        order[fill[cid[a]]] = a
        fill[cid[a]] += 1
    return dims, cid, start, order


@njit(cache=True)
def _pairs(pos, rad, max_gap, count_only, out_i, out_j, out_gap, ex_ptr, ex_nbr):
    n = pos.shape[0]
    if n < 2:
        return 0
    cell = 2.0 * rad.max() + max_gap
    dims, cid, start, order = _grid(pos, cell)
    m = 0
    for a in range(n):
        c = cid[a]
        cz = c % dims[2]
        cy = (c // dims[2]) % dims[1]
        cx = c // (dims[1] * dims[2])
        for dx in range(-1, 2):
            x = cx + dx
            if x < 0 or x >= dims[0]:
                continue
            for dy in range(-1, 2):
                y = cy + dy
                if y < 0 or y >= dims[1]:
                    continue
                for dz in range(-1, 2):
                    z = cz + dz
                    if z < 0 or z >= dims[2]:
                        continue
                    cc = (x * dims[1] + y) * dims[2] + z
                    for q in range(start[cc], start[cc + 1]):
                        b = order[q]
                        if b <= a:
                            continue
                        d0 = pos[a, 0] - pos[b, 0]
                        d1 = pos[a, 1] - pos[b, 1]
                        d2 = pos[a, 2] - pos[b, 2]
                        gap = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) - rad[a] - rad[b]
                        if gap < max_gap:
                            excluded = False
                            for e in range(ex_ptr[a], ex_ptr[a + 1]):
                                if ex_nbr[e] == b:
                                    excluded = True
                                    break
                            if excluded:
                                continue
                            if not count_only:
                                out_i[m] = a
                                out_j[m] = b
                                out_gap[m] = gap
                            m += 1
    return m


def sphere_pairs(position, radius, max_gap, exclude: Exclusions | None = None):
    """Sphere pairs (a < b) with surface gap < max_gap (m), except the pairs ``exclude``
    lists.

    Returns
    -------
    i, j : (M,) int64; gap : (M,) float, m (negative = overlap).
    """
    pos = np.ascontiguousarray(position, dtype=float)
    rad = np.ascontiguousarray(radius, dtype=float)
    if exclude is None:
        exclude = Exclusions.none(len(rad), 0)
    dummy_i = np.empty(0, np.int64)
    dummy_g = np.empty(0)
    m = _pairs(pos, rad, float(max_gap), True, dummy_i, dummy_i, dummy_g, exclude.ptr, exclude.nbr)
    out_i = np.empty(m, np.int64)
    out_j = np.empty(m, np.int64)
    out_g = np.empty(m)
    _pairs(pos, rad, float(max_gap), False, out_i, out_j, out_g, exclude.ptr, exclude.nbr)
    return out_i, out_j, out_g


@njit(cache=True)
def _plate_pairs(pos, rad, pts, nrm, max_gap, count_only, out_i, out_k, out_gap, ex_plate):
    m = 0
    for a in range(pos.shape[0]):
        for k in range(pts.shape[0]):
            if ex_plate[a, k]:
                continue
            gap = (
                (pos[a, 0] - pts[k, 0]) * nrm[k, 0]
                + (pos[a, 1] - pts[k, 1]) * nrm[k, 1]
                + (pos[a, 2] - pts[k, 2]) * nrm[k, 2]
            ) - rad[a]
            if gap < max_gap:
                if not count_only:
                    out_i[m] = a
                    out_k[m] = k
                    out_gap[m] = gap
                m += 1
    return m


def plate_pairs(position, radius, plate_point, plate_normal, max_gap, exclude: Exclusions | None = None):
    """Sphere-plate pairs with gap (centre-to-plane distance - radius) < max_gap (m), except
    the pairs ``exclude`` lists.

    Returns i (M,) sphere indices, k (M,) plate indices, gap (M,) m.
    """
    pos = np.ascontiguousarray(position, dtype=float)
    rad = np.ascontiguousarray(radius, dtype=float)
    pts = np.ascontiguousarray(plate_point, dtype=float).reshape(-1, 3)
    nrm = np.ascontiguousarray(plate_normal, dtype=float).reshape(-1, 3)
    if exclude is None:
        exclude = Exclusions.none(len(rad), len(pts))
    if exclude.plate.shape != (len(rad), len(pts)):
        raise ValueError(f"exclude.plate: expected shape {(len(rad), len(pts))}, got {exclude.plate.shape}")
    e_i = np.empty(0, np.int64)
    e_g = np.empty(0)
    m = _plate_pairs(pos, rad, pts, nrm, float(max_gap), True, e_i, e_i, e_g, exclude.plate)
    out_i = np.empty(m, np.int64)
    out_k = np.empty(m, np.int64)
    out_g = np.empty(m)
    _plate_pairs(pos, rad, pts, nrm, float(max_gap), False, out_i, out_k, out_g, exclude.plate)
    return out_i, out_k, out_g


@kernel
def _frames(ci, cj, pos, nrm_plate, frame):
    for a in range(len(ci)):
        i = ci[a]
        j = cj[a]
        if j >= 0:
            n0 = pos[i, 0] - pos[j, 0]
            n1 = pos[i, 1] - pos[j, 1]
            n2 = pos[i, 2] - pos[j, 2]
            norm = np.sqrt(n0**2 + n1**2 + n2**2)
            n0 /= norm
            n1 /= norm
            n2 /= norm
        else:
            n0 = nrm_plate[-1 - j, 0]
            n1 = nrm_plate[-1 - j, 1]
            n2 = nrm_plate[-1 - j, 2]
        # e: the global axis least aligned with n
        e0 = 0.0
        e1 = 0.0
        e2 = 0.0
        if abs(n1) < abs(n0):
            if abs(n2) < abs(n1):
                e2 = 1.0
            else:
                e1 = 1.0
        elif abs(n2) < abs(n0):
            e2 = 1.0
        else:
            e0 = 1.0
        t0 = n1 * e2 - n2 * e1
        t1 = n2 * e0 - n0 * e2
        t2 = n0 * e1 - n1 * e0
        tn = np.sqrt(t0**2 + t1**2 + t2**2)
        t0 /= tn
        t1 /= tn
        t2 /= tn
        frame[a, 0, 0] = n0
        frame[a, 0, 1] = n1
        frame[a, 0, 2] = n2
        frame[a, 1, 0] = t0
        frame[a, 1, 1] = t1
        frame[a, 1, 2] = t2
        frame[a, 2, 0] = n1 * t2 - n2 * t1
        frame[a, 2, 1] = n2 * t0 - n0 * t2
        frame[a, 2, 2] = n0 * t1 - n1 * t0


def detect_contacts(position, radius, plate_point, plate_normal, alert_distance, exclude: Exclusions | None = None):
    """Contact candidates (gap < alert_distance) with their frames, except the pairs
    ``exclude`` lists.

    Returns
    -------
    ci : (C,) int64 candidate spheres; cj : (C,) int64 antagonist sphere or ``-1-k``;
    gap : (C,) m; frame : (C, 3, 3) rows n, t, s.
    """
    si, sj, sg = sphere_pairs(position, radius, alert_distance, exclude)
    pi_, pk, pg = plate_pairs(position, radius, plate_point, plate_normal, alert_distance, exclude)
    ci = np.concatenate([si, pi_])
    cj = np.concatenate([sj, -1 - pk])
    gap = np.concatenate([sg, pg])
    frame = np.empty((len(ci), 3, 3))
    _frames(
        ci,
        cj,
        np.ascontiguousarray(position, dtype=float),
        np.ascontiguousarray(plate_normal, dtype=float).reshape(-1, 3),
        frame,
    )
    return ci, cj, gap, frame


@kernel
def _narrow(ci, cj, pos, rad, pts, nrm, gap):
    for a in range(len(ci)):
        i = ci[a]
        j = cj[a]
        if j >= 0:
            d0 = pos[i, 0] - pos[j, 0]
            d1 = pos[i, 1] - pos[j, 1]
            d2 = pos[i, 2] - pos[j, 2]
            gap[a] = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) - rad[i] - rad[j]
        else:
            k = -1 - j
            gap[a] = (
                (pos[i, 0] - pts[k, 0]) * nrm[k, 0]
                + (pos[i, 1] - pts[k, 1]) * nrm[k, 1]
                + (pos[i, 2] - pts[k, 2]) * nrm[k, 2]
            ) - rad[i]


class CandidateList:
    """Contact candidates with a Verlet skin (see module docstring).

    Parameters
    ----------
    alert_distance : m, contacts are the pairs with gap < alert_distance.
    skin : m, extra search distance (default: alert_distance).
    """

    def __init__(self, alert_distance: float, skin: float | None = None):
        self.alert = float(alert_distance)
        self.skin = float(alert_distance if skin is None else skin)
        self.x_ref: np.ndarray | None = None
        self.p_ref: np.ndarray | None = None
        self.n_searches = 0
        self.exclude: Exclusions | None = None

    def set_exclusions(self, exclude: Exclusions | None) -> None:
        """Pairs to skip from now on (None: none); the next call searches afresh."""
        self.exclude = exclude
        self.x_ref = None

    def contacts(self, position, radius, plate_point, plate_normal):
        """Contacts (ci, cj, gap, frame) as :func:`detect_contacts` returns them."""
        pos = np.ascontiguousarray(position, dtype=float)
        pts = np.ascontiguousarray(plate_point, dtype=float).reshape(-1, 3)
        nrm = np.ascontiguousarray(plate_normal, dtype=float).reshape(-1, 3)
        stale = self.x_ref is None or self.x_ref.shape != pos.shape
        if not stale:
            dx = np.sqrt(((pos - self.x_ref) ** 2).sum(1)).max() if len(pos) else 0.0
            dp = np.sqrt(((pts - self.p_ref) ** 2).sum(1)).max() if len(pts) else 0.0
            stale = 2.0 * dx + dp > self.skin
        if stale:
            ci, cj, _, _ = detect_contacts(pos, radius, pts, nrm, self.alert + self.skin, self.exclude)
            self.ci, self.cj = ci, cj
            self.x_ref = pos.copy()
            self.p_ref = pts.copy()
            self.n_searches += 1
        gap = np.empty(len(self.ci))
        _narrow(self.ci, self.cj, pos, np.ascontiguousarray(radius, dtype=float), pts, nrm, gap)
        keep = gap < self.alert
        ci, cj, gap = self.ci[keep], self.cj[keep], gap[keep]
        frame = np.empty((len(ci), 3, 3))
        _frames(ci, cj, pos, nrm, frame)
        return ci, cj, gap, frame
