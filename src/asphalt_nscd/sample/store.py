"""Sample file (HDF5, docs/design.md "Sample file") and ParaView output (meshio VTU).

Besides the attributes of docs/design.md the root carries the scaled specimen dimensions
``B_m, b_m, e_m, h_m`` (the ``scale`` option changes them) and ``n_spheres``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io import InputError, atomic_path

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

    @property
    def inertia(self) -> np.ndarray:
        """2/5 m r^2 (kg m^2), (N,)."""
        return 0.4 * self.mass * self.radius**2


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
    """Read a sample file written by :func:`write_sample`.

    Raises
    ------
    InputError
        if the file is missing or lacks a dataset of docs/design.md.
    """
    import h5py

    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: sample file not found")
    with h5py.File(path, "r") as f:
        missing = [name for name in UNITS if name not in f]
        if missing:
            raise InputError(f"{path}: missing datasets {missing}")
        attrs = {}
        for key, value in f.attrs.items():
            if isinstance(value, bytes):
                value = value.decode()
            if key in ("units", "config") and isinstance(value, str):
                value = json.loads(value)
            attrs[key] = value.item() if isinstance(value, np.generic) else value
        return SampleData(
            position=f["spheres/position"][()],
            radius=f["spheres/radius"][()],
            mass=f["spheres/mass"][()],
            plate_point=f["plates/point"][()],
            plate_normal=f["plates/normal"][()],
            plate_mass=f["plates/mass"][()],
            bonds={k: f[f"bonds/{k}"][()] for k in ("i", "j", "delta0", "l0", "r_min")},
            attrs=attrs,
        )


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
