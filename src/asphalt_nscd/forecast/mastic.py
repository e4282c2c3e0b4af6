"""The mortar the discrete model's bonds carry: binder, filler and fine aggregate, by micromechanics.

Binder + filler (below 0.075 mm) = mastic; mastic + fine aggregate (0.075 mm to the PSD cut) =
mortar, the matrix between the spheres (volume fractions: :func:`asphalt_nscd.forecast.formulation.phase_volumes`).
Each step stiffens its matrix by the Hashin-Shtrikman lower bound for rigid spherical
inclusions in an incompressible matrix, which is also the Mori-Tanaka estimate (Hashin &
Shtrikman 1963, J. Mech. Phys. Solids 11, 127-140; Christensen 1979, Mechanics of Composite
Materials, Ch. IV):

    G_eff / G_matrix = 1 + (5/2) phi / (1 - phi)                          (dilute limit: Einstein, 1 + 2.5 phi)

The factor is real, so by the elastic-viscoelastic correspondence principle (Hashin 1965, J.
Appl. Mech. 32, 630-636) it multiplies the complex shear modulus: the mortar keeps the binder's
phase angle at every condition. Its Young's modulus is E* = 3 G* (incompressible).

Choice (docs/choices.md, Forecast): the estimate holds for any phi < 1 but stays a lower bound
where the particles touch (a mortar's fine aggregate, phi about 0.7); the discrete model's
global constant carries the level, and the bound's variation from mix to mix is what is
forecast.
"""

from __future__ import annotations

import numpy as np


def rigid_inclusion_factor(phi) -> np.ndarray:
    """G_eff / G_matrix of rigid spheres at volume fraction ``phi`` (0 <= phi < 1) in an
    incompressible matrix: the Hashin-Shtrikman lower bound (module docstring).

    Raises ValueError for phi outside [0, 1)."""
    phi = np.asarray(phi, float)
    if np.any((phi < 0) | (phi >= 1)):
        raise ValueError(f"inclusion volume fraction must be in [0, 1), got {phi}")
    return 1.0 + 2.5 * phi / (1.0 - phi)


def mortar_modulus(G_binder_Pa, delta_deg, phi_filler: float, phi_fine: float) -> np.ndarray:
    """Complex Young's modulus E* (Pa) of the mortar from the binder's |G*| (Pa) and phase angle
    (degrees) at the same conditions (arrays of one shape): 3 |G*| e^{i delta} times the
    mastic's and the mortar's :func:`rigid_inclusion_factor`."""
    G = np.asarray(G_binder_Pa, float) * np.exp(1j * np.radians(np.asarray(delta_deg, float)))
    return 3.0 * G * rigid_inclusion_factor(phi_filler) * rigid_inclusion_factor(phi_fine)
