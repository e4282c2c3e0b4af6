"""Harmonic solver of a bonded sample: closed forms (single bond, series, parallel), the
solver paths, load-free clusters and input errors."""

import h5py
import numpy as np
import pytest

from asphalt_nscd.harmonic.network import network_from_sample
from asphalt_nscd.sample.lattice import lattice_sample, sample_from_bonds
from asphalt_nscd.sample.store import read_sample, write_sample
from asphalt_nscd.harmonic.solver import HarmonicSystem
from asphalt_nscd.io import InputError
from asphalt_nscd.rheology.laws import GeneralizedBurgers, bond_scale, tangential_ratio

LAW = GeneralizedBurgers.burgers(Em=2.02e7, eta_m=1.79e6, Ek=2.72e7, eta_k=4.61e5)  # 20 degC
A = 63e-6
#: The kinematics of the time-domain NSCD core: bonds at the barycentres, head translating.
BARY = {"bond_kinematics": "barycentre", "head_rotation": "clamped"}
RT = tangential_ratio(0.35)


def make(tmp_path, position, radius, i, j, mass=None, top_z=0.01, plate_mass=0.235, name="s"):
    """Write a tiny sample (plates at z = 0 and z = top_z) and read it back."""
    position = np.asarray(position, float)
    radius = np.broadcast_to(np.asarray(radius, float), (len(position),))
    mass = np.full(len(position), 1e-4) if mass is None else np.asarray(mass, float)
    path = tmp_path / f"{name}.h5"
    write_sample(
        path,
        sample_from_bonds(position, radius, mass, [[0, 0, 0], [0, 0, top_z]], i, j, plate_mass=(np.inf, plate_mass)),
    )
    return path, HarmonicSystem(network_from_sample(read_sample(path)), **BARY)


def k_of(r_min, l0, omega, law=LAW):
    """Normal bond stiffness a_b E*(w) (Eqs. 30-33)."""
    return bond_scale(r_min, l0) * law.complex_modulus(omega)


@pytest.mark.parametrize("f", [3.0, 40.0, 400.0])
def test_single_bond_with_mass_closed_form(tmp_path, f):
    # one sphere bonded to the top plate only: R = kt (A - u), (kt - w^2 m) u = kt A
    m = 2e-3
    _, system = make(tmp_path, [[0, 0, 0.007]], 1e-3, [0], [-2], mass=[m])
    w = 2 * np.pi * f
    kt = RT * k_of(1e-3, 0.003, w)
    u = kt * A / (kt - w**2 * m)
    sol = system.solve_law(LAW, f, inertia="full")
    assert sol.reaction[0] == pytest.approx(kt * (A - u), rel=1e-9)
    assert sol.force[0] == pytest.approx(kt * (A - u) - w**2 * 0.235 * A, rel=1e-9)
    assert sol.displacement[0, 0] == pytest.approx(u, rel=1e-9)
    # quasi-static: the sphere follows the head, no bond force; F carries -w^2 mu A
    sol0 = system.solve_law(LAW, f, inertia="none")
    assert abs(sol0.reaction[0]) < 1e-12 * abs(kt * A)
    assert sol0.mu_kg == pytest.approx(0.135 * m + 0.235)
    assert sol0.force[0] == pytest.approx(-(w**2) * sol0.mu_kg * A, rel=1e-9)


def test_vertical_chain_in_series_tangential(tmp_path):
    z = np.array([1.5, 4.0, 6.5, 8.5]) * 1e-3
    r = np.array([1.0, 1.2, 0.8, 1.0]) * 1e-3
    pos = np.column_stack([np.zeros(4), np.zeros(4), z])
    i = [0, 0, 1, 2, 3]
    j = [-1, 1, 2, 3, -2]
    _, system = make(tmp_path, pos, r, i, j, top_z=0.01)
    f = 10.0
    w = 2 * np.pi * f
    r_min = [r[0], min(r[0], r[1]), min(r[1], r[2]), min(r[2], r[3]), r[3]]
    l0 = [z[0], z[1] - z[0], z[2] - z[1], z[3] - z[2], 0.01 - z[3]]
    kt = RT * k_of(np.array(r_min), np.array(l0), w)
    expected = A / np.sum(1.0 / kt)
    sol = system.solve_law(LAW, f, inertia="none")
    assert sol.reaction[0] == pytest.approx(expected, rel=1e-10)
    assert abs(sol.reaction[1]) < 1e-12 and abs(sol.reaction[2]) < 1e-12


def test_series_through_a_normal_bond(tmp_path):
    # bottom -(tangential)- s0 -(normal, along x)- s1 -(tangential)- top
    pos = [[0, 0, 5e-3], [4e-3, 0, 5e-3]]
    _, system = make(tmp_path, pos, 1e-3, [0, 0, 1], [-1, 1, -2], top_z=0.01)
    w = 2 * np.pi * 25.0
    k_bottom = RT * k_of(1e-3, 5e-3, w)
    k_mid = k_of(1e-3, 4e-3, w)
    k_top = RT * k_of(1e-3, 5e-3, w)
    sol = system.solve_law(LAW, 25.0, inertia="none")
    assert sol.reaction[0] == pytest.approx(A / (1 / k_bottom + 1 / k_mid + 1 / k_top), rel=1e-10)


def test_columns_in_parallel(tmp_path):
    radii = np.array([0.8, 1.0, 1.4]) * 1e-3
    heights = np.array([3.0, 5.0, 6.0]) * 1e-3
    pos = np.column_stack([[0, 5e-3, 10e-3], np.zeros(3), heights])
    _, system = make(tmp_path, pos, radii, [0, 0, 1, 1, 2, 2], [-1, -2] * 3, top_z=0.01)
    w = 2 * np.pi * 6.0
    kb = RT * k_of(radii, heights, w)
    kt = RT * k_of(radii, 0.01 - heights, w)
    sol = system.solve_law(LAW, 6.0, inertia="none")
    assert sol.reaction[0] == pytest.approx(A * np.sum(1 / (1 / kb + 1 / kt)), rel=1e-10)


def test_oblique_bond_against_dense_assembly(tmp_path):
    pos = np.array([[0, 0, 3e-3], [2.5e-3, 1e-3, 6e-3]])
    m = np.array([3e-4, 5e-4])
    _, system = make(tmp_path, pos, 1e-3, [0, 0, 1], [-1, 1, -2], mass=m, top_z=0.01)
    f = 40.0
    w = 2 * np.pi * f
    d = pos[1] - pos[0]
    l01 = np.linalg.norm(d)
    blocks = []
    for n, l0 in ((np.array([0, 0, 1.0]), 3e-3), (d / l01, l01), (np.array([0, 0, -1.0]), 4e-3)):
        kn = k_of(1e-3, l0, w)
        blocks.append(kn * np.outer(n, n) + RT * kn * (np.eye(3) - np.outer(n, n)))
    K = np.zeros((6, 6), complex)
    K[:3, :3] += blocks[0] + blocks[1]
    K[3:, 3:] += blocks[1] + blocks[2]
    K[:3, 3:] -= blocks[1]
    K[3:, :3] -= blocks[1]
    dyn = K - w**2 * np.diag(np.repeat(m, 3))
    up = np.array([A, 0, 0])
    u = np.linalg.solve(dyn, np.concatenate([np.zeros(3), blocks[2] @ up]))
    reaction = blocks[2] @ (up - u[3:])
    for solver in ("reuse", "direct"):
        sol = system.solve_law(LAW, f, inertia="full", solver=solver)
        np.testing.assert_allclose(sol.reaction, reaction, rtol=1e-9, atol=1e-12 * abs(reaction[0]))
        np.testing.assert_allclose(sol.displacement.ravel(), u, rtol=1e-9, atol=1e-20)


def test_generalized_law_complex_stiffness(tmp_path):
    law = GeneralizedBurgers(Em=3e7, eta_m=2e6, Ek=(5e7, 9e7), eta_k=(4e5, 3e4), E_inf=1e5)
    _, system = make(tmp_path, [[0, 0, 4e-3]], 1e-3, [0, 0], [-1, -2], top_z=0.01)
    w = 2 * np.pi * 10.0
    kb, kt = RT * k_of(1e-3, 4e-3, w, law), RT * k_of(1e-3, 6e-3, w, law)
    sol = system.solve_law(law, 10.0, inertia="none")
    assert sol.reaction[0] == pytest.approx(A / (1 / kb + 1 / kt), rel=1e-10)


def test_reuse_and_direct_agree_on_a_lattice(tmp_path):
    g = lattice_sample(200, seed=3)
    path = tmp_path / "lattice.h5"
    write_sample(path, g)
    system = HarmonicSystem(network_from_sample(read_sample(path)), **BARY)
    for f in (0.1, 10.0, 100.0):
        a = system.solve_law(LAW, f, inertia="full", solver="reuse", rtol=1e-13)
        b = system.solve_law(LAW, f, inertia="full", solver="direct")
        np.testing.assert_allclose(a.force, b.force, rtol=1e-9, atol=1e-12 * abs(b.force[0]))
        assert a.residual < 1e-10 and b.residual < 1e-10


def test_quasi_static_response_is_the_law_times_a_real_stiffness(tmp_path):
    # K(w) = E*(w) G: without inertia F/A / E*(w) is one real number at every frequency
    g = lattice_sample(150, seed=5)
    path = tmp_path / "lattice.h5"
    write_sample(path, g)
    system = HarmonicSystem(network_from_sample(read_sample(path)), **BARY)
    ratios = []
    for f in (0.01, 1.0, 30.0, 100.0):
        sol = system.solve_law(LAW, f, inertia="none")
        ratios.append(sol.reaction[0] / A / LAW.complex_modulus(2 * np.pi * f))
    ratios = np.array(ratios)
    assert np.all(np.abs(ratios.imag) < 1e-10 * np.abs(ratios.real))
    np.testing.assert_allclose(ratios.real, ratios.real[0], rtol=1e-10)


def test_load_free_clusters_are_removed(tmp_path):
    # column s0 between the plates + a bonded pair (s1, s2) touching no plate
    pos = [[0, 0, 5e-3], [8e-3, 0, 5e-3], [11e-3, 0, 5e-3]]
    _, system = make(tmp_path, pos, 1e-3, [0, 0, 1], [-1, -2, 2], top_z=0.01)
    _, alone = make(tmp_path, pos[:1], 1e-3, [0, 0], [-1, -2], top_z=0.01, name="alone")
    assert system.n_load_free == 2
    for inertia in ("none", "full"):
        a = system.solve_law(LAW, 10.0, inertia=inertia)
        b = alone.solve_law(LAW, 10.0, inertia=inertia)
        assert a.reaction[0] == pytest.approx(b.reaction[0], rel=1e-12)
        assert np.all(a.displacement[1:] == 0)


def test_bad_inputs(tmp_path):
    path, system = make(tmp_path, [[0, 0, 5e-3]], 1e-3, [0, 0], [-1, -2])
    with pytest.raises(ValueError, match="inertia"):
        system.solve_law(LAW, 10.0, inertia="partial")
    with pytest.raises(ValueError, match="solver"):
        system.solve_law(LAW, 10.0, solver="cg")
    with pytest.raises(InputError, match="not found"):
        network_from_sample(read_sample(tmp_path / "missing.h5"))
    with h5py.File(path, "a") as h5:
        del h5["bonds/l0"]
    with pytest.raises(InputError, match="bonds/l0"):
        network_from_sample(read_sample(path))
    path2, _ = make(tmp_path, [[0, 0, 5e-3]], 1e-3, [0, 0], [-1, -2], name="bad")
    with h5py.File(path2, "a") as h5:
        h5["bonds/j"][0] = 5
    with pytest.raises(InputError, match="bonds/j"):
        network_from_sample(read_sample(path2))
