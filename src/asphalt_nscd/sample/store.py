"""The sample store: the sample file (HDF5, docs/design.md "Sample file") and ParaView output
(meshio VTU).

One reader and one writer for the file format: the preparation writes it
(:mod:`.prepare`), the NSCD campaign (:mod:`asphalt_nscd.campaign.twopb`) and the harmonic
solver (:func:`asphalt_nscd.harmonic.network.network_from_sample`) read it as a
:class:`SampleData`. :func:`read_sample` checks every dataset's presence and shape and the
consistency of the bond data, so the readers downstream get valid arrays.

Besides the attributes of docs/design.md the root carries the scaled specimen dimensions
``B_m, b_m, e_m, h_m`` (the ``scale`` option changes them) and ``n_spheres``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..io import InputError, atomic_path, rebuild_hint

if TYPE_CHECKING:
    from ..lab.en12697 import Specimen2PB

UNITS = {
    "spheres/position": "m",
    "spheres/radius": "m",
    "spheres/mass": "kg",
    "spheres/inertia": "kg m^2",
    "plates/point": "m",
    "plates/normal": "1",
    "plates/mass": "kg",
    "bonds/i": "1",
    "bonds/j": "1",
    "bonds/delta0": "m",
    "bonds/l0": "m",
    "bonds/r_min": "m",
}
#: Trailing shape of each dataset (the leading axis is the number of spheres, plates or bonds).
SHAPES = {name: ((3,) if name in ("spheres/position", "plates/point", "plates/normal") else ()) for name in UNITS}


@dataclass
class SampleData:
    """A prepared sample in the specimen frame (all SI; shapes as in docs/design.md)."""

    position: np.ndarray  # (N, 3) m
    radius: np.ndarray  # (N,) m
    mass: np.ndarray  # (N,) kg
    plate_point: np.ndarray  # (2, 3) m
    plate_normal: np.ndarray  # (2, 3)
    plate_mass: np.ndarray  # (2,) kg, bottom inf
    bonds: dict  # i, j, delta0, l0, r_min
    attrs: dict = field(default_factory=dict)
    name: str = "sample"  # the file stem when read

    @property
    def inertia(self) -> np.ndarray:
        """2/5 m r^2 (kg m^2), (N,)."""
        return 0.4 * self.mass * self.radius**2

    @property
    def head_size_m(self) -> tuple[float, float] | None:
        """The head's footprint (b, e), m: the root attributes ``b_m, e_m``; None without them."""
        if "b_m" in self.attrs and "e_m" in self.attrs:
            return float(self.attrs["b_m"]), float(self.attrs["e_m"])
        return None


def subsample(sample: SampleData, keep) -> SampleData:
    """The sample with only the spheres of mask ``keep`` (N,) and the bonds between kept
    bodies (sphere indices renumbered; plates kept); ``attrs['n_spheres']`` updated."""
    keep = np.asarray(keep, bool)
    new = -np.ones(keep.size, np.int64)
    new[keep] = np.arange(int(keep.sum()))
    i, j = np.asarray(sample.bonds["i"]), np.asarray(sample.bonds["j"])
    ok = keep[i] & ((j < 0) | keep[np.maximum(j, 0)])
    bonds = {k: np.asarray(v)[ok] for k, v in sample.bonds.items()}
    bonds["i"] = new[i[ok]]
    bonds["j"] = np.where(j[ok] >= 0, new[np.maximum(j[ok], 0)], j[ok])
    attrs = {**sample.attrs, "n_spheres": int(keep.sum())}
    return SampleData(
        position=sample.position[keep],
        radius=sample.radius[keep],
        mass=sample.mass[keep],
        plate_point=sample.plate_point,
        plate_normal=sample.plate_normal,
        plate_mass=sample.plate_mass,
        bonds=bonds,
        attrs=attrs,
        name=sample.name,
    )


#: Standard 2PB trapezoid (EN 12697-26 Annex A, the paper's specimen), mm.
STANDARD_SPECIMEN_MM = {"b_mm": 25.0, "B_mm": 56.0, "e_mm": 25.0, "h_mm": 250.0}


def specimen_geometry_mm(sample: SampleData) -> dict:
    """Specimen dimensions ``b_mm, B_mm, e_mm, h_mm`` of a sample, mm: the root attributes
    ``b_m, B_m, e_m, h_m`` (the scaled specimen) where present, else the standard trapezoid
    (:data:`STANDARD_SPECIMEN_MM`)."""
    return {
        key: float(sample.attrs[key.replace("_mm", "_m")]) * 1e3 if key.replace("_mm", "_m") in sample.attrs else value
        for key, value in STANDARD_SPECIMEN_MM.items()
    }


def specimen_of(sample: SampleData) -> Specimen2PB:
    """EN 12697-26 specimen of a sample (:class:`asphalt_nscd.lab.en12697.Specimen2PB`): the
    scaled geometry of :func:`specimen_geometry_mm`, M = sum of the sphere masses, m = top-plate
    mass (kg)."""
    from ..lab.en12697 import Specimen2PB

    return Specimen2PB(M_kg=float(sample.mass.sum()), m_kg=float(sample.plate_mass[1]), **specimen_geometry_mm(sample))


def write_sample(path: str | Path, data: SampleData) -> None:
    """Write the sample file atomically (HDF5 through h5py)."""
    import h5py

    with atomic_path(path) as tmp:
        with h5py.File(tmp, "w") as f:
            f["spheres/position"] = data.position
            f["spheres/radius"] = data.radius
            f["spheres/mass"] = data.mass
            f["spheres/inertia"] = data.inertia
            f["plates/point"] = data.plate_point
            f["plates/normal"] = data.plate_normal
            f["plates/mass"] = data.plate_mass
            for key in ("i", "j"):
                f[f"bonds/{key}"] = np.asarray(data.bonds[key], dtype=np.int64)
            for key in ("delta0", "l0", "r_min"):
                f[f"bonds/{key}"] = np.asarray(data.bonds[key], dtype=float)
            for name, unit in UNITS.items():
                f[name].attrs["unit"] = unit
            f.attrs["units"] = json.dumps(UNITS)
            for key, value in data.attrs.items():
                f.attrs[key] = json.dumps(value) if isinstance(value, (dict, list)) else value


def read_sample(path: str | Path) -> SampleData:
    """Read and check a sample file written by :func:`write_sample` (``name``: the file stem).

    Raises
    ------
    InputError
        naming the file and the dataset: the file is missing or not HDF5, a dataset of
        docs/design.md is absent or has the wrong shape, the sphere, plate or bond arrays
        disagree in length, a bond index is out of range (``bonds/i`` in [0, N), ``bonds/j``
        in [0, N) other than i, or -1/-2 for the plates), or a mass, radius, ``l0`` or
        ``r_min`` is not positive.
    """
    import h5py

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: sample file not found")
    data = {}
    try:
        with h5py.File(path, "r") as f:
            for name, tail in SHAPES.items():
                if name not in f:
                    raise InputError(f"{path}: dataset '{name}' missing (see docs/design.md)")
                value = f[name][()]
                if value.shape[1:] != tail:
                    raise InputError(
                        f"{path}: dataset '{name}' has shape {value.shape}, expected (n,{','.join(map(str, tail))})"
                    )
                data[name] = value
            attrs = {}
            for key, value in f.attrs.items():
                if isinstance(value, bytes):
                    value = value.decode()
                if key in ("units", "config") and isinstance(value, str):
                    value = json.loads(value)
                attrs[key] = value.item() if isinstance(value, np.generic) else value
    except OSError as exc:
        raise InputError(f"{path}: not a readable HDF5 sample file ({exc}); {rebuild_hint(path)}") from exc
    _check_arrays(path, data)
    return SampleData(
        position=data["spheres/position"],
        radius=data["spheres/radius"],
        mass=data["spheres/mass"],
        plate_point=data["plates/point"],
        plate_normal=data["plates/normal"],
        plate_mass=data["plates/mass"],
        bonds={k: data[f"bonds/{k}"] for k in ("i", "j", "delta0", "l0", "r_min")},
        attrs=attrs,
        name=path.stem,
    )


def _check_arrays(path, data: dict) -> None:
    """The consistency checks of :func:`read_sample` on the datasets ``data`` (name -> array)."""
    n = len(data["spheres/position"])
    rows = {
        "spheres": (n, "one per sphere"),
        "plates": (2, "bottom and top plate"),
        "bonds": (len(data["bonds/i"]), "one per bond, as 'bonds/i'"),
    }
    for name, value in data.items():
        want, what = rows[name.split("/")[0]]
        if len(value) != want:
            raise InputError(f"{path}: dataset '{name}' has {len(value)} rows, expected {want} ({what})")
    i, j = data["bonds/i"], data["bonds/j"]
    if np.any((i < 0) | (i >= n)):
        raise InputError(f"{path}: dataset 'bonds/i' must lie in [0, {n})")
    if np.any((j >= n) | (j < -2) | (j == i)):
        raise InputError(
            f"{path}: dataset 'bonds/j' must lie in [0, {n}) (another sphere) or be -1/-2 (bottom/top plate)"
        )
    for name in ("spheres/mass", "spheres/radius", "bonds/l0", "bonds/r_min"):
        if np.any(~(data[name] > 0)):
            raise InputError(f"{path}: dataset '{name}' must be positive")


def write_vtu(path: str | Path, position, radius, point_data: dict | None = None) -> None:
    """Spheres as VTK vertices with ``radius`` and ``diameter`` point fields (m).

    In ParaView: Glyph filter, glyph type Sphere, scale array ``diameter``, scale factor 1.
    """
    import meshio

    position = np.asarray(position, dtype=float)
    radius = np.asarray(radius, dtype=float)
    data = {"radius": radius, "diameter": 2 * radius}
    for key, value in (point_data or {}).items():
        data[key] = np.asarray(value)
    mesh = meshio.Mesh(position, [("vertex", np.arange(len(radius)).reshape(-1, 1))], point_data=data)
    with atomic_path(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")


def write_bonds_vtu(path: str | Path, data: SampleData) -> None:
    """Sphere-sphere bonds as VTK lines between barycentres, with ``delta0, l0, r_min`` cell fields."""
    import meshio

    ss = data.bonds["j"] >= 0
    lines = np.column_stack([data.bonds["i"][ss], data.bonds["j"][ss]])
    cell_data = {k: [np.asarray(data.bonds[k])[ss]] for k in ("delta0", "l0", "r_min")}
    mesh = meshio.Mesh(data.position, [("line", lines)], cell_data=cell_data)
    with atomic_path(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
