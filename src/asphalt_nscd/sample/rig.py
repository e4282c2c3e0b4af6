"""The 2PB rig: a prepared sample between the fixed base plate and the driven head, its bonds
given a law, as an NSCD simulation ready to step.

:func:`setup` is the one builder of the numerical 2PB test (the campaign's jobs,
:func:`asphalt_nscd.campaign.twopb.build_simulation`; the time-domain check of the harmonic
solution, :mod:`asphalt_nscd.harmonic.timedomain`; their benchmarks); the returned
:class:`asphalt_nscd.nscd.Simulation` advances one Moreau-Jean step per ``step()``. The
harmonic solver reads the same sample as a linear network
(:func:`asphalt_nscd.harmonic.network.network_from_sample`) with the same head inertia
(:func:`head_inertia_of`), so that the two solve the same rig.

Set-up: the sample's spheres (a copy of the positions: a run moves them), the bottom plate
fixed, the top plate (the head, its mass from the sample file) driven by ``displacement(t) ->
(x, y, z)`` (m) and, with ``head_rotation='free'``, free to rotate with the inertia of a steel
cuboid; bonds created from the sample file with the macro law scaled per bond
(``Bonds.create``: Eqs. 30-33, 8-11), a Poisson ratio and a yield stress.

Head inertia: the head is a steel cuboid (density :data:`PLATE_DENSITY_KG_M3`) of the sample
file's top-plate mass m (0.235 kg scaled with the sample) and footprint b x e (root attributes
``b_m, e_m`` of the sample file, the specimen's head; else the x-y extent of the top-plate
bonds' contact points), of thickness t = m / (rho b e). It rotates about the head-face centre
``plates/point[1]``: I = diag(m (e^2 + t^2)/12, m (b^2 + t^2)/12, m (b^2 + e^2)/12) + m (t/2)^2
diag(1, 1, 0) (parallel-axis term of the face offset). The mass coupling between the imposed
head translation and the head rotation (centre of mass t/2 above the face) is neglected.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..io import InputError
from ..nscd.state import HEAD_ROTATIONS, YIELD_STRESS
from ..rheology.laws import POISSON_RATIO

#: Steel density of the head plate (rotational inertia, module docstring), kg/m^3.
PLATE_DENSITY_KG_M3 = 7850.0


def kinematics(cfg: dict) -> dict:
    """The rig's kinematics in a merged, checked workflow config (:func:`asphalt_nscd.config.checked`;
    its values are config/config.yaml's unless an overlay changes them): ``bond_kinematics``
    (``nscd.bond_kinematics``), ``head_rotation`` (``campaign.test.head_rotation``) and ``nu``
    (``campaign.test.nu``, Poisson's ratio of Eqs. 8-11). What the time-domain test runs with
    outside a campaign mode's overrides, read here once for the commands that check or correct it
    (harmonic-compare, -transfer, -resolution)."""
    test = cfg["campaign"]["test"]
    return {
        "bond_kinematics": cfg["nscd"]["bond_kinematics"],
        "head_rotation": test["head_rotation"],
        "nu": float(test["nu"]),
    }


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


def head_inertia(mass: float, b_m: float, e_m: float, density_kg_m3: float = PLATE_DENSITY_KG_M3) -> np.ndarray:
    """Moments of inertia (3,) kg m^2 of the head about its face centre (module docstring).

    A steel cuboid of mass ``mass`` (kg), footprint ``b_m`` (along x) x ``e_m`` (along y), m;
    zeros for a mass that is not positive and finite or an empty footprint.
    """
    if not (mass > 0 and np.isfinite(mass)) or b_m <= 0 or e_m <= 0:
        return np.zeros(3)
    t = mass / (density_kg_m3 * b_m * e_m)
    return np.array(
        [
            mass * (e_m**2 + t**2) / 12 + mass * t**2 / 4,
            mass * (b_m**2 + t**2) / 12 + mass * t**2 / 4,
            mass * (b_m**2 + e_m**2) / 12,
        ]
    )


def head_inertia_of(sample) -> np.ndarray:
    """Moments of inertia (3,) kg m^2 of a sample's head (module docstring): footprint
    :attr:`asphalt_nscd.sample.store.SampleData.head_size_m`, else the x-y extent of the top-plate
    bonds' contact points."""
    size = sample.head_size_m
    if size is None:
        i, j = sample.bonds["i"], sample.bonds["j"]
        contact = contact_points(sample.position, sample.radius, sample.plate_normal, i, j, sample.bonds["l0"])
        top = contact[j == -2]
        size = tuple(np.ptp(top[:, :2], axis=0)) if len(top) else (0.0, 0.0)
    return head_inertia(float(sample.plate_mass[1]), *map(float, size))


def setup(
    sample,
    law,
    displacement,
    params,
    head_rotation: str = "clamped",
    nu: float = POISSON_RATIO,
    yield_stress: float = YIELD_STRESS,
    held: np.ndarray | None = None,
):
    """The NSCD simulation of the 2PB test on ``sample`` (SampleData; module docstring).

    Parameters
    ----------
    sample : SampleData of the sample store.
    law : GeneralizedBurgers (Pa, Pa s), the macro law of the bonds.
    displacement : callable t (s) -> (x, y, z) (m), the head's imposed motion.
    params : NSCDParameters of the run (time step, theta, gravity, bond kinematics, ...).
    head_rotation : ``clamped`` (the head only translates) or ``free`` (it rotates with
        :func:`head_inertia_of`).
    nu : Poisson's ratio of Eqs. 8-11.  yield_stress : Pa (inf: unbreakable bonds).
    held : (N,) bool, the spheres the rig holds (default: all); the others are left out, as
        :func:`asphalt_nscd.harmonic.solver.held_spheres` finds them.

    Returns
    -------
    asphalt_nscd.nscd.Simulation, with ``n_mechanisms_dropped`` (spheres left out).

    Raises
    ------
    InputError if the head is free to rotate but has no positive finite inertia.
    ValueError on an unknown ``head_rotation`` or a ``held`` mask of the wrong shape.
    """
    from ..nscd import Bonds, Plate, Plates, Simulation, Spheres
    from .store import subsample

    if head_rotation not in HEAD_ROTATIONS:
        raise ValueError(f"head_rotation must be one of {HEAD_ROTATIONS}, got {head_rotation!r}")
    n_dropped = 0
    if held is not None:
        held = np.asarray(held, bool)
        if held.shape != sample.radius.shape:
            raise ValueError(f"held: expected a mask of shape {sample.radius.shape}, got {held.shape}")
        n_dropped = int((~held).sum())
        if n_dropped:
            sample = subsample(sample, held)
    spheres = Spheres(
        position=np.array(sample.position, dtype=float), radius=sample.radius, mass=sample.mass, inertia=sample.inertia
    )
    head: dict[str, Any] = {}
    if head_rotation == "free":
        inertia = head_inertia_of(sample)
        if not np.all((inertia > 0) & np.isfinite(inertia)):
            raise InputError(
                f"head_rotation 'free': the head has no positive finite rotational "
                f"inertia (top-plate mass {sample.plate_mass[1]} kg, moments "
                f"{inertia} kg m²)"
            )
        head = {"rotation": True, "inertia": inertia}
    plates = Plates(
        [
            Plate(sample.plate_point[0], sample.plate_normal[0], mode="fixed"),
            Plate(
                sample.plate_point[1],
                sample.plate_normal[1],
                mode="driven",
                mass=float(sample.plate_mass[1]),
                displacement=displacement,
                **head,
            ),
        ]
    )
    bonds = Bonds.create(spheres, plates, sample.bonds["i"], sample.bonds["j"], law, nu=nu, yield_stress=yield_stress)
    sim = Simulation(spheres, plates, bonds, params)
    sim.n_mechanisms_dropped = n_dropped
    return sim
