"""Bond kinematics of the NSCD core ('contact' vs 'barycentre') and rotating plates."""

import numpy as np
import pytest

from asphalt_nscd.harmonic.network import network_from_sample
from asphalt_nscd.sample.lattice import lattice_sample
from asphalt_nscd.sample.store import read_sample, write_sample
from asphalt_nscd.harmonic.response import harmonic_rows
from asphalt_nscd.harmonic.solver import HarmonicSystem
from asphalt_nscd.harmonic.timedomain import time_domain_row
from asphalt_nscd.nscd import (
    Bonds,
    NSCDParameters,
    Plate,
    Plates,
    Simulation,
    Spheres,
    read_checkpoint,
    write_checkpoint,
)
from asphalt_nscd.nscd.verify import LAW_15C, case_creep, random_bonded_network, rigid_rotation_force
from asphalt_nscd.rheology.laws import GeneralizedBurgers

GEOMETRY = {"b_mm": 25.0, "B_mm": 56.0, "e_mm": 25.0, "h_mm": 250.0}
LAW_30 = GeneralizedBurgers.burgers(Em=1.30e7, eta_m=3.45e5, Ek=9.31e6, eta_k=1.31e5)


@pytest.mark.kernels
@pytest.mark.parametrize("with_plate", [False, True])
def test_rigid_rotation_strains_no_bond_with_contact_kinematics(with_plate):
    contact = rigid_rotation_force("contact", with_plate)
    barycentre = rigid_rotation_force("barycentre", with_plate)
    assert barycentre > 1e-3  # N: the tangential springs resist the rotation
    assert contact <= 1e-12 * barycentre


@pytest.mark.kernels
def test_contact_point_and_lever_arms():
    s = Spheres(position=[[0, 0, 0], [0.005, 0, 0.004]], radius=[0.002, 0.001], mass=[1, 1], inertia=[1, 1])
    plates = Plates([Plate([0, 0, -0.003], [0, 0, 1])])
    b = Bonds.create(s, plates, [1, 0], [0, -1], LAW_15C)
    # sphere-sphere: c on the line of centres, r_i + delta0/2 from x_i
    l0 = np.hypot(0.005, 0.004)
    e = -np.array([0.005, 0, 0.004]) / l0
    np.testing.assert_allclose(b.arm_i[0], (0.001 + (l0 - 0.003) / 2) * e, atol=1e-15)
    np.testing.assert_allclose(b.arm_i[0] - b.arm_j[0], -np.array([0.005, 0, 0.004]), atol=1e-15)
    # sphere-plate: c at mid-gap below the sphere; arm_j from the plate's reference point
    np.testing.assert_allclose(b.arm_i[1], [0, 0, -0.0025], atol=1e-15)
    np.testing.assert_allclose(b.arm_j[1], [0, 0, 0.0005], atol=1e-15)


@pytest.mark.kernels
@pytest.mark.parametrize("kinematics", ["contact", "barycentre"])
@pytest.mark.parametrize("direction", ["normal", "tangential"])
def test_two_sphere_creep_closed_form(direction, kinematics):
    rows = case_creep(direction, kinematics=kinematics)
    assert all(r["passed"] for r in rows), rows
    assert max(r["relative_error"] for r in rows) < 1e-3


@pytest.mark.kernels
def test_bond_torque_rotates_a_free_sphere():
    """A tangential force at the barycentre of a sphere bonded to a fixed one: with 'contact'
    the bond (at c) applies a torque a_i x R, and the angular momentum balance of the
    step holds, I dw = h (a_i x F_bond) (impulse form); 'barycentre': no rotation."""
    for kinematics in ("contact", "barycentre"):
        pos = np.array([[0.0, 0, 0], [4.5e-3, 0, 0]])
        s = Spheres(position=pos, radius=[2e-3, 2e-3], mass=[np.inf, 1e-4], inertia=[np.inf, 1.6e-10])
        b = Bonds.create(s, Plates([]), [1], [0], LAW_15C)
        f = np.zeros((2, 3))
        f[1, 1] = 1.0
        sim = Simulation(
            s, None, b, NSCDParameters(dt=1e-5, gravity=(0, 0, 0), bond_kinematics=kinematics), external_force=f
        )
        sim.step()
        g = b.frame[0].T @ sim.bond_impulse[0]  # global impulse on sphere 1, N s
        if kinematics == "barycentre":
            assert np.all(s.angular_velocity == 0)
        else:
            expected = np.cross(b.arm_i[0], g) / 1.6e-10
            np.testing.assert_allclose(s.angular_velocity[1], expected, rtol=1e-9)
            assert abs(s.angular_velocity[1, 2]) > 0


@pytest.mark.parametrize("head_rotation", ["free", "clamped"])
def test_bonded_cantilever_matches_the_harmonic_solver(tmp_path, head_rotation):
    """A 12-sphere column (lattice 1 x 1 x 12 cells, bonded to both plates) bent by the head
    at 3 Hz: time domain (contact kinematics) vs the harmonic solver, same options."""
    path = tmp_path / "column.h5"
    write_sample(path, lattice_sample(12, seed=2, radius_range=(1.0e-3, 1.5e-3)))
    options = {"bond_kinematics": "contact", "head_rotation": head_rotation}
    system = HarmonicSystem(network_from_sample(read_sample(path)), **options)
    ref = harmonic_rows(system, LAW_30, 30.0, [3.0], GEOMETRY, inertia="full", solver="direct")[0]
    td = time_domain_row(path, LAW_30, 3.0, GEOMETRY, 1e-4, **options)
    assert td["n_nlgs_steps"] == 0  # no contact closes: every step on the linear path
    assert td["E_norm_MPa"] == pytest.approx(ref["E_norm_MPa"], rel=5e-3)
    assert td["phase_deg"] == pytest.approx(ref["phase_deg"], abs=0.1)


def test_free_head_is_softer_than_clamped_and_barycentre(tmp_path):
    path = tmp_path / "column.h5"
    write_sample(path, lattice_sample(12, seed=2, radius_range=(1.0e-3, 1.5e-3)))
    e = {}
    for kin, head in (("contact", "free"), ("contact", "clamped"), ("barycentre", "clamped")):
        e[kin, head] = time_domain_row(path, LAW_30, 10.0, GEOMETRY, 2e-4, bond_kinematics=kin, head_rotation=head)[
            "E_norm_MPa"
        ]
    assert e["contact", "free"] < e["contact", "clamped"] < e["barycentre", "clamped"]


def test_dissipation_is_non_negative_with_contact_kinematics():
    s, plates, bonds = random_bonded_network(n=27)
    plates.rotates[1] = True  # the driven head also rotates
    plates.inertia[1] = 1e-5
    sim = Simulation(s, plates, bonds, NSCDParameters(dt=5e-5, gravity=(0, 0, 0)))
    d = sim.run(400).dissipated.to_numpy()
    assert d.max() > 0
    assert d.min() >= -1e-9 * d.max()
    assert np.abs(sim.plates.angular_velocity[1]).max() > 0
    assert np.abs(sim.plate_torque[1]).max() > 0


@pytest.mark.kernels
@pytest.mark.parametrize("fast_path", [True, False])
def test_rotating_head_angular_momentum_balance(fast_path):
    """The head's angular velocity changes by the bond torque impulse / its inertia."""
    s, plates, bonds = random_bonded_network(n=27)
    plates.rotates[1] = True
    plates.inertia[1] = [2e-5, 3e-5, 4e-5]
    sim = Simulation(
        s,
        plates,
        bonds,
        NSCDParameters(dt=5e-5, gravity=(0, 0, 0), fast_path=fast_path, tolerance=1e-12, max_iterations=100000),
    )
    for _ in range(30):
        w0 = sim.plates.angular_velocity[1].copy()
        sim.step()
        dw = sim.plates.angular_velocity[1] - w0
        np.testing.assert_allclose(
            dw * plates.inertia[1],
            5e-5 * sim.plate_torque[1],
            rtol=1e-6,
            atol=1e-9 * np.abs(5e-5 * sim.plate_torque[1]).max(),
        )


@pytest.mark.kernels
def test_checkpoint_restart_with_rotating_head_is_exact(tmp_path):
    def make():
        s, plates, bonds = random_bonded_network(n=27)
        plates.rotates[1] = True
        plates.inertia[1] = 1e-5
        return Simulation(s, plates, bonds, NSCDParameters(dt=5e-5))

    ref = make()
    ref.run(20)
    sim = make()
    sim.run(10)
    write_checkpoint(sim, tmp_path / "ck.h5")
    back = read_checkpoint(tmp_path / "ck.h5", drivers=sim.plates.drivers)
    assert back.params.bond_kinematics == "contact" and back.plates.rotates[1]
    back.run(10)
    np.testing.assert_array_equal(back.spheres.angular_velocity, ref.spheres.angular_velocity)
    np.testing.assert_array_equal(back.plates.angular_velocity, ref.plates.angular_velocity)
    np.testing.assert_array_equal(back.bonds.force, ref.bonds.force)


@pytest.mark.kernels
def test_bad_options():
    with pytest.raises(ValueError, match="bond_kinematics"):
        NSCDParameters(dt=1e-4, bond_kinematics="centre")
    with pytest.raises(ValueError, match="rotating plate"):
        Plate([0, 0, 0], [0, 0, 1], rotation=True)
