"""Compiled NSCD core (numba): Moreau-Jean theta-method, Delassus blocks, nonlinear
Gauss-Seidel, Signorini-Coulomb contacts, generalized Burger's bonds (Eqs. 6-26).

Public API (stable; SI units; conventions in :mod:`.state`)
-----------------------------------------------------------
State::

    Spheres(position (N,3), radius (N,), mass (N,), inertia (N,), velocity, angular_velocity)
    Spheres.from_density(position, radius, density)          # mass inf = immobile sphere
    Plate(point (3,), normal (3,) inward, mode='fixed'|'free'|'driven', mass=inf,
          displacement=callable t -> (3,) | (times (T,), disp (T,3)),   # driven plates
          rotation=False, inertia=inf (scalar or (3,) kg m², about point))  # free rotation
    Plates([Plate, ...])   # infinite planes; .angular_velocity, .rotation (P,3) if rotating
    Bonds.create(spheres, plates, i, j, law: GeneralizedBurgers, nu=POISSON_RATIO (0.35, rheology.laws),
                 yield_stress=YIELD_STRESS (2.7e6 Pa))
        # j = sphere index or -1-k for plate k; rest state = current configuration
    NSCDParameters(dt, theta=0.5, gravity=(0,0,-9.81), friction=0.7, tolerance=1e-6,
                   convergence='quad'|'max'|'both', max_iterations=2000, relaxation=1.0,
                   alert_distance=None, fast_path=True,
                   linear_solver='cg'|'cg_ssor'|'direct',
                   linear_tolerance=1e-10, bond_kinematics='contact'|'barycentre')

Time stepping::

    sim = Simulation(spheres, plates, bonds, params, external_force=None)
    st = sim.step()           # StepStats (state.py): solver ('nlgs'|'linear'), iterations,
                              # contacts, bonds, plate_force and driver_force (P,3) N, ...
    df = sim.run(n_steps, callback=None)      # DataFrame of StepStats.as_row()
    write_checkpoint(sim, "x.h5"); read_checkpoint("x.h5", drivers=[...])  # callable drivers again
    sim.bonds.force (B,3) N, bonds.broken (B,), sim.contact_impulse (C,3) N s (/dt = force)
    sim.plate_torque (P,3) N m  # bond torque on each plate about its point, last step

Modules: moreau_jean.py (the time step, phase by phase), detection.py, delassus.py,
local_laws.py (contact Eqs. 6-7, bond Eqs. 12-26), gauss_seidel.py (NLGS), linear/ (the
linear fast path: cg, cg_ssor, direct; also ``splu_symmetric`` and ``PermutedLU``, shared
with harmonic/), condensed.py (contacts inside the fast path), bundles.py (the named
tuples of arrays passed to the kernels), _jit.py, state.py, checkpoint.py, verify.py
(figures.py: its figure), bench.py. Choices and their measurements: docs/choices.md ("NSCD core").
CLI: ``asphalt-nscd verify -o verify.json``, ``asphalt-nscd bench --case bonded|granular``.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the names below, imported on first use (__getattr__)
    from .checkpoint import read_checkpoint, write_checkpoint
    from .moreau_jean import Simulation
    from .state import (
        DRIVEN,
        FIXED,
        FREE,
        YIELD_STRESS,
        Bonds,
        NSCDParameters,
        Plate,
        Plates,
        Spheres,
        StepStats,
        local_frames,
    )

__all__ = [
    "Simulation",
    "Spheres",
    "Plate",
    "Plates",
    "Bonds",
    "NSCDParameters",
    "StepStats",
    "local_frames",
    "read_checkpoint",
    "write_checkpoint",
    "FIXED",
    "FREE",
    "DRIVEN",
    "YIELD_STRESS",
]

#: public name -> the module defining it. The package imports a module when one of its names is first
#: used (PEP 562): a command that only builds the parser, or reads a constant of :mod:`.state`, does not
#: load the compiled kernels (numba, about 0.3 s of CPU per process; docs/choices.md, "Start-up of a job").
_WHERE = {name: ".state" for name in __all__}
_WHERE.update(Simulation=".moreau_jean", read_checkpoint=".checkpoint", write_checkpoint=".checkpoint")


def __getattr__(name: str):
    if name in _WHERE:
        value = getattr(importlib.import_module(_WHERE[name], __name__), name)
        globals()[name] = value
        return value
    try:  # a submodule used as an attribute (nscd.detection)
        return importlib.import_module(f".{name}", __name__)
    except ModuleNotFoundError as exc:
        if exc.name != f"{__name__}.{name}":
            raise
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
