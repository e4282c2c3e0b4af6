"""Checkpoint/restart of a full :class:`~.moreau_jean.Simulation` state in HDF5 (h5py).

Layout: groups ``spheres``, ``plates``, ``bonds``, ``contacts`` (last step's contacts and
impulses, for the warm start), ``params`` (attributes), ``solver`` (the previous
velocities used to extrapolate the initial guess of the iterative linear solver, so that a
restart is bit-identical); root attributes ``time``,
``step_index``, ``alert_distance``. Sampled plate drivers ``(times, disp)`` are stored in
``plates/driver_<k>/{times,disp}``; callable drivers must be passed again on reading.
The file is written atomically (asphalt_nscd.io.atomic_path).
"""

from __future__ import annotations

import json

import h5py
import numpy as np

from ..io import InputError, atomic_path
from .state import DRIVEN, Bonds, NSCDParameters, Plate, Plates, Spheres

_SPHERE = ("position", "radius", "mass", "inertia", "velocity", "angular_velocity")
_PLATE = ("point", "point0", "normal", "mass", "mode", "velocity", "rotates", "inertia", "angular_velocity", "rotation")
_BOND = (
    "i",
    "j",
    "delta0",
    "l0",
    "r_min",
    "frame",
    "rest",
    "Km",
    "Cm",
    "Kk",
    "Ck",
    "Kinf",
    "r_crit",
    "arm_i",
    "arm_j",
    "displacement",
    "force",
    "delta_c",
    "delta_k",
    "broken",
)
_PARAMS = (
    "dt",
    "theta",
    "gravity",
    "friction",
    "tolerance",
    "convergence",
    "max_iterations",
    "relaxation",
    "alert_distance",
    "fast_path",
    "linear_solver",
    "linear_tolerance",
    "bond_kinematics",
    "bonded_contact",
    "fast_path_contacts",
    "direct_factorisation",
)


def write_checkpoint(sim, path) -> None:
    """Write the state of ``sim`` to ``path`` (HDF5)."""
    with atomic_path(path) as tmp:
        with h5py.File(tmp, "w") as f:
            f.attrs["time"] = sim.time
            f.attrs["step_index"] = sim.step_index
            f.attrs["alert_distance"] = sim.alert_distance
            g = f.create_group("spheres")
            for k in _SPHERE:
                g[k] = getattr(sim.spheres, k)
            g = f.create_group("plates")
            for k in _PLATE:
                g[k] = getattr(sim.plates, k)
            g["plate_external_force"] = sim.plate_external_force
            for index, drv in enumerate(sim.plates.drivers):
                if drv is not None and not callable(drv):
                    d = g.create_group(f"driver_{index}")
                    d["times"] = np.asarray(drv[0], float)
                    d["disp"] = np.asarray(drv[1], float)
            g = f.create_group("bonds")
            for k in _BOND:
                g[k] = getattr(sim.bonds, k)
            g["impulse"] = sim.bond_impulse
            g.attrs["law"] = json.dumps(sim.bonds.law)
            g = f.create_group("contacts")
            g["i"] = sim.contact_i
            g["j"] = sim.contact_j
            g["impulse"] = sim.contact_impulse
            g["frame"] = sim.contact_frame
            if sim._v_before is not None:  # initial guess of the iterative linear solver
                g = f.create_group("solver")
                g["v_before"] = sim._v_before
                g["vp_before"] = sim._vp_before
                g["w_before"] = sim._w_before
                g["wp_before"] = sim._wp_before
                for age, fields in enumerate(sim._older):  # the older fields of the Galerkin start
                    for name, arr in zip(("v", "w", "vp", "wp"), fields):
                        g[f"{name}_before{age + 2}"] = arr
            g = f.create_group("params")
            for k in _PARAMS:
                val = getattr(sim.params, k)
                g.attrs[k] = np.nan if val is None else val
            if sim.external_force is not None and not callable(sim.external_force):
                f["external_force"] = np.asarray(sim.external_force, float)


def read_checkpoint(path, drivers=None, external_force=None):
    """Rebuild a Simulation from ``path``.

    Raises
    ------
    InputError if the file misses a group or a driven plate has no driver.
    """
    from .moreau_jean import Simulation

    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise InputError(f"{path}: cannot open checkpoint ({exc})") from exc
    with f:
        for grp in ("spheres", "plates", "bonds", "contacts", "params"):
            if grp not in f:
                raise InputError(f"{path}: checkpoint group '{grp}' missing")
        s = {k: f["spheres"][k][()] for k in _SPHERE}
        spheres = Spheres(**s)
        gp = f["plates"]
        mode = gp["mode"][()]
        plate_list = []
        for k in range(len(mode)):
            drv = None
            if mode[k] == DRIVEN:
                if drivers is not None and k < len(drivers) and drivers[k] is not None:
                    drv = drivers[k]
                elif f"driver_{k}" in gp:
                    drv = (gp[f"driver_{k}/times"][()], gp[f"driver_{k}/disp"][()])
                else:
                    raise InputError(f"{path}: plate {k} is driven; pass its driver in drivers")
            name = {0: "fixed", 1: "free", 2: "driven"}[int(mode[k])]
            plate_list.append(
                Plate(
                    point=gp["point0"][k],
                    normal=gp["normal"][k],
                    mode=name,
                    mass=float(gp["mass"][k]),
                    displacement=drv,
                    rotation=bool(gp["rotates"][k]),
                    inertia=gp["inertia"][k],
                )
            )
        plates = Plates(plate_list)
        plates.point[:] = gp["point"][()]
        plates.velocity[:] = gp["velocity"][()]
        plates.angular_velocity[:] = gp["angular_velocity"][()]
        plates.rotation[:] = gp["rotation"][()]
        gb = f["bonds"]
        bonds = Bonds(**{k: gb[k][()] for k in _BOND}, law=json.loads(gb.attrs["law"]))
        # checkpoints written before bonded_contact existed ran with the former behaviour
        # (and before fast_path_contacts existed, with every closing contact sent to NLGS)
        pa = {
            k: f["params"].attrs[k]
            for k in _PARAMS
            if k not in ("bonded_contact", "fast_path_contacts", "direct_factorisation")
        }
        pa["bonded_contact"] = str(f["params"].attrs.get("bonded_contact", "always"))
        pa["fast_path_contacts"] = int(f["params"].attrs.get("fast_path_contacts", 0))
        # (and before direct_factorisation existed, with SuperLU)
        pa["direct_factorisation"] = str(f["params"].attrs.get("direct_factorisation", "superlu"))
        ad = float(pa["alert_distance"])
        pa["alert_distance"] = None if np.isnan(ad) else ad
        pa["max_iterations"] = int(pa["max_iterations"])
        pa["fast_path"] = bool(pa["fast_path"])
        pa["linear_solver"] = str(pa["linear_solver"])
        pa["convergence"] = str(pa["convergence"])
        pa["bond_kinematics"] = str(pa["bond_kinematics"])
        params = NSCDParameters(**pa)
        if external_force is None and "external_force" in f:
            external_force = f["external_force"][()]
        sim = Simulation(spheres, plates, bonds, params, external_force=external_force)
        sim.plate_external_force[:] = gp["plate_external_force"][()]
        sim.time = float(f.attrs["time"])
        sim.step_index = int(f.attrs["step_index"])
        sim.alert_distance = float(f.attrs["alert_distance"])
        sim._candidates = type(sim._candidates)(sim.alert_distance)
        sim.bond_impulse[:] = gb["impulse"][()]
        if "solver" in f:
            sim._v_before = f["solver/v_before"][()]
            sim._vp_before = f["solver/vp_before"][()]
            sim._w_before = f["solver/w_before"][()]
            sim._wp_before = f["solver/wp_before"][()]
            sim._older = [
                tuple(f[f"solver/{name}_before{k}"][()] for name in ("v", "w", "vp", "wp"))
                for k in (2, 3)
                if f"solver/v_before{k}" in f
            ]
        gc = f["contacts"]
        sim.contact_i = gc["i"][()]
        sim.contact_j = gc["j"][()]
        sim.contact_impulse = gc["impulse"][()]
        sim.contact_frame = gc["frame"][()]
    return sim
