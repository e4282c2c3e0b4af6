"""Network factor NF_s of a sample and the corrected micro-macro transfer.

Eqs. 30-33 give every bond the macro law scaled by its geometry, k_n = a_b E*(w),
a_b = pi r_min^2 / l0, and k_t = k_n / (2 (1 + nu)) (Eqs. 8-11); they assume that the
sample then has the complex modulus E*(w). Without inertia the stiffness of the bonded
network is K(w) = E*(w) G with G real and independent of the law (:mod:`.solver`), so the
EN 12697-26 modulus of the sample (Eqs. 1-5, inertia-free) is exactly

    E_sample(w) = NF_s E*(w),       NF_s = gamma R_x / (A E*(w))

with a *real* network factor NF_s that depends only on the sample, the bond kinematics, the
head rotation and nu — not on the law, the temperature or the frequency. gamma is the form
factor of Eq. 3 (1/mm, the sample's geometry), A the head amplitude and R the force the head
exerts on its bonds (:class:`.solver.HarmonicSolution`). Eqs. 30-33 assume NF_s = 1.

Correction (the "transfer correction" of the extended campaign mode): calibrate the bonds
with E*(w) / NF_s, i.e. divide every modulus and viscosity of the law by NF_s
(``GeneralizedBurgers.scaled(1 / NF_s)``); the inertia-free sample modulus is then E*(w)
exactly, and the time-domain test differs from it only by the inertia not captured by the
lumped mass of Eq. 1 and by the time integration.

NF_s is computed here from one real factorisation of G and one back-substitution
(``HarmonicSystem.solve_law(..., inertia="none", solver="reuse")``) with a unit elastic law
(E* = 1 Pa at every frequency); R_x is used directly, so the lumped inertia term of Eq. 1
(which cancels exactly without inertia) adds no round-off.

The JSON written by ``asphalt-nscd harmonic-transfer`` (:func:`transfer_json`) and read by
``asphalt-nscd run-2pb --network-factor-json`` (:func:`read_transfer_json`)::

    {"network_factor": NF_s, "sample": name, "bond_kinematics": ..., "head_rotation": ...,
     "nu": ..., "inertia": "none", "imag_relative": Im(NF)/Re(NF), "units": {...}, ...}
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..io import InputError, read_json
from ..nscd.state import BOND_KINEMATICS, HEAD_AMPLITUDE_M, HEAD_ROTATIONS
from ..rheology.laws import POISSON_RATIO
from .solver import HarmonicSystem

#: Keys a transfer JSON must hold (:func:`read_transfer_json`).
TRANSFER_KEYS = ("network_factor", "sample", "bond_kinematics", "head_rotation", "nu")


def unit_elastic_law():
    """Elastic law with E*(w) = 1 Pa at every frequency (a Maxwell spring without dashpot)."""
    from ..rheology.laws import GeneralizedBurgers

    return GeneralizedBurgers(Em=1.0, eta_m=np.inf, Ek=(), eta_k=())


def network_factor(
    system: HarmonicSystem,
    geometry_mm: dict,
    law=None,
    frequency_Hz: float = 1.0,
    amplitude: float = HEAD_AMPLITUDE_M,
    solver: str = "reuse",
) -> complex:
    """Complex network factor E_sample(w) / E*(w) of the inertia-free sample (module docstring).

    Parameters
    ----------
    system : HarmonicSystem
        The prepared sample (its bond kinematics, head rotation and nu).
    geometry_mm : dict
        ``b_mm, B_mm, e_mm, h_mm`` of the specimen (gamma, Eq. 3; :func:`asphalt_nscd.sample.store.specimen_geometry_mm`).
    law : object with ``complex_modulus(omega)`` (Pa), optional
        Any macro law; default :func:`unit_elastic_law`. The result does not depend on it.
    frequency_Hz : float
        Frequency f, Hz (w = 2 pi f); the result does not depend on it.
    amplitude : float
        Head amplitude A, m (the model is linear: no influence).
    solver : {"reuse", "direct"}
        ``reuse``: one real LU of G, one back-substitution; ``direct``: one complex LU of
        E*(w) G (an independent check that NF_s is real and law independent).

    Returns
    -------
    complex
        NF_s (the imaginary part is round-off: K(w) = E*(w) G).

    Raises
    ------
    ValueError
        on a non-positive frequency or amplitude, or an unknown solver.
    """
    from .response import specimen_for

    if not (frequency_Hz > 0 and amplitude > 0):
        raise ValueError(f"frequency_Hz and amplitude must be > 0, got {frequency_Hz}, {amplitude}")
    law = unit_elastic_law() if law is None else law
    sol = system.solve_law(law, frequency_Hz, amplitude=amplitude, inertia="none", solver=solver)
    gamma = specimen_for(system, geometry_mm).gamma_per_mm
    # Eq. 1 without inertia: E (MPa) = gamma (1/mm) R_x (N) / A (mm)
    e_sample = gamma * complex(sol.reaction[0]) / (amplitude * 1e3) * 1e6  # Pa
    return e_sample / complex(law.complex_modulus(2.0 * np.pi * frequency_Hz))


def transfer_json(
    sample_path, nu: float = POISSON_RATIO, bond_kinematics: str = "contact", head_rotation: str = "free"
) -> dict:
    """The network factor of a sample file as the transfer JSON (module docstring).

    Parameters
    ----------
    sample_path : path of a sample file (docs/design.md format).
    nu : Poisson's ratio of Eqs. 8-11.
    bond_kinematics : {"contact", "barycentre"}; head_rotation : {"free", "clamped"}
        The kinematics of the time-domain test the factor corrects (config
        ``nscd.bond_kinematics``, ``campaign.test.head_rotation``).

    Returns
    -------
    dict, JSON-serialisable: ``network_factor`` (real NF_s), ``imag_relative``, ``sample``,
    ``sample_path``, ``bond_kinematics``, ``head_rotation``, ``nu``, ``inertia``, ``law``,
    ``frequency_Hz``, ``n_free_dof``, ``n_load_free``, ``residual``, ``units``,
    ``definition``, ``source``.

    Raises
    ------
    InputError
        if the sample file is missing or malformed, an option is invalid, or NF_s is not a
        positive finite number (e.g. a sample whose head carries no bond).
    """
    from ..sample.store import read_sample, specimen_geometry_mm
    from .network import network_from_sample

    sample = read_sample(sample_path)
    network = network_from_sample(sample)
    try:
        system = HarmonicSystem(network, nu=nu, bond_kinematics=bond_kinematics, head_rotation=head_rotation)
    except ValueError as exc:
        raise InputError(f"{sample_path}: --nu/--bond-kinematics/--head-rotation: {exc}") from None
    law = unit_elastic_law()
    f = 1.0
    sol = system.solve_law(law, f, inertia="none", solver="reuse")
    nf = network_factor(system, specimen_geometry_mm(sample), law=law, frequency_Hz=f)
    if not (np.isfinite(nf.real) and nf.real > 0):
        raise InputError(
            f"{sample_path}: network factor {nf.real!r} is not a positive finite number (does any bond reach the head?)"
        )
    return {
        "network_factor": float(nf.real),
        "imag_relative": float(nf.imag / nf.real),
        "sample": network.name,
        "sample_path": str(sample_path),
        "bond_kinematics": bond_kinematics,
        "head_rotation": head_rotation,
        "nu": float(nu),
        "inertia": "none",
        "law": "unit elastic law (E* = 1 Pa at every frequency)",
        "frequency_Hz": f,
        "n_free_dof": int(sol.n_free_dof),
        "n_load_free": int(sol.n_load_free),
        "residual": float(sol.residual),
        "units": {
            "network_factor": "1 (sample |E*| / macro |E*|, EN 12697-26 Eqs. 1-5, no inertia)",
            "nu": "1",
            "frequency_Hz": "Hz",
        },
        "definition": "NF_s = gamma R_x / (A E*(w)); the sample's inertia-free modulus is NF_s E*(w) for "
        "every law (K(w) = E*(w) G); correction: bonds calibrated with E*(w) / NF_s",
        "source": "asphalt_nscd.harmonic.transfer (harmonic solver, one real factorisation of G)",
    }


def read_transfer_json(
    path,
    sample: str | None = None,
    bond_kinematics: str | None = None,
    head_rotation: str | None = None,
    nu: float | None = None,
) -> dict:
    """Read and check a transfer JSON (output of ``asphalt-nscd harmonic-transfer``).

    The optional arguments are the settings of the run that applies the factor; each given
    one must match the file's (the factor depends on them).

    Returns
    -------
    dict: the file's content with ``network_factor`` (float > 0) checked.

    Raises
    ------
    InputError
        naming the file and the key: unreadable or not JSON, not an object, a missing key
        (:data:`TRANSFER_KEYS`), ``network_factor`` not a positive finite number, an unknown
        ``bond_kinematics`` / ``head_rotation``, ``nu`` not a number, or a mismatch with the
        given sample name or settings.
    """
    obj = read_json(path, "transfer JSON")
    if not isinstance(obj, dict):
        raise InputError(f"{path}: expected a JSON object with keys {list(TRANSFER_KEYS)}")
    missing = [k for k in TRANSFER_KEYS if k not in obj]
    if missing:
        raise InputError(f"{path}: missing key(s) {missing} (expected an output of 'asphalt-nscd harmonic-transfer')")
    nf = obj["network_factor"]
    if isinstance(nf, bool) or not isinstance(nf, (int, float)) or not (math.isfinite(nf) and nf > 0):
        raise InputError(f"{path}: key 'network_factor': expected a positive finite number, got {nf!r}")
    for key, allowed in (("bond_kinematics", BOND_KINEMATICS), ("head_rotation", HEAD_ROTATIONS)):
        if obj[key] not in allowed:
            raise InputError(f"{path}: key '{key}': expected one of {list(allowed)}, got {obj[key]!r}")
    if isinstance(obj["nu"], bool) or not isinstance(obj["nu"], (int, float)):
        raise InputError(f"{path}: key 'nu': expected a number, got {obj['nu']!r}")
    checks = (
        ("sample", sample, obj["sample"] == sample),
        ("bond_kinematics", bond_kinematics, obj["bond_kinematics"] == bond_kinematics),
        ("head_rotation", head_rotation, obj["head_rotation"] == head_rotation),
        ("nu", nu, nu is not None and math.isclose(float(obj["nu"]), float(nu), rel_tol=1e-12)),
    )
    for key, want, ok in checks:
        if want is not None and not ok:
            raise InputError(f"{path}: key '{key}': the factor was computed for {obj[key]!r}, the run uses {want!r}")
    obj["network_factor"] = float(nf)
    return obj


def corrected_law(
    law,
    transfer_path,
    sample: str | None = None,
    bond_kinematics: str | None = None,
    head_rotation: str | None = None,
    nu: float | None = None,
):
    """The transfer correction of a macro law for one sample (module docstring): the law
    divided by the sample's network factor NF_s read from ``transfer_path``
    (``law.scaled(1 / NF_s)``: every modulus and viscosity), so that the bonds are calibrated
    with E*(w) / NF_s.

    Parameters
    ----------
    law : GeneralizedBurgers (Pa, Pa s).
    transfer_path : the sample's transfer JSON (output of ``asphalt-nscd harmonic-transfer``).
    sample, bond_kinematics, head_rotation, nu : the run's sample name and settings; each
        given one must match the file's (:func:`read_transfer_json`).

    Returns
    -------
    (GeneralizedBurgers, float): the corrected law and NF_s.

    Raises
    ------
    InputError
        from :func:`read_transfer_json`, naming the file and the key.
    """
    nf = read_transfer_json(
        transfer_path, sample=sample, bond_kinematics=bond_kinematics, head_rotation=head_rotation, nu=nu
    )["network_factor"]
    return law.scaled(1.0 / nf), nf


def write_transfer(sample_path, output, **options) -> dict:
    """:func:`transfer_json` of ``sample_path`` written atomically to ``output`` (JSON)."""
    from ..io import write_json

    obj = transfer_json(Path(sample_path), **options)
    write_json(obj, output)
    return obj
