"""Delassus blocks, NLGS convergence reporting, driver force, checkpoint/restart."""

import numpy as np
import pytest

from asphalt_nscd.nscd import (Bonds, NSCDParameters, Plate, Plates, Simulation, Spheres,
                               read_checkpoint)
from asphalt_nscd.nscd.delassus import contact_blocks, dense_delassus
from asphalt_nscd.nscd.detection import detect_contacts
from asphalt_nscd.nscd.verify import LAW_15C, random_bonded_network


def test_contact_blocks_equal_dense_delassus_diagonal():
    rng = np.random.default_rng(0)
    pos = np.array([[0, 0, 0.01], [0.019, 0.002, 0.012], [0.0, 0.02, 0.011]])
    rad = np.array([0.01, 0.009, 0.011])
    s = Spheres.from_density(pos, rad, 2600.0)
    plates = Plates([Plate([0, 0, 0], [0, 0, 1], mode="free", mass=0.3)])
    ci, cj, gap, frame = detect_contacts(s.position, s.radius, plates.point, plates.normal, 0.005)
    assert len(ci) >= 4
    W = dense_delassus(s.n, ci, cj, frame, s.radius, s.inv_mass, s.inv_inertia,
                       plates.inv_mass)
    wn, wt = np.empty(len(ci)), np.empty(len(ci))
    contact_blocks(ci, cj, s.inv_mass, s.inv_inertia, s.radius, plates.inv_mass, wn, wt)
    for a in range(len(ci)):
        blk = W[3 * a:3 * a + 3, 3 * a:3 * a + 3]
        np.testing.assert_allclose(blk, np.diag([wn[a], wt[a], wt[a]]), rtol=1e-12,
                                   atol=1e-12 * wt[a])
    assert rng is not None


def test_step_reports_iterations_and_residual():
    s = Spheres.from_density([[0, 0, 0.01], [0, 0, 0.03]], [0.01, 0.01], 2600.0)
    sim = Simulation(s, Plates([Plate([0, 0, 0], [0, 0, 1])]), None,
                     NSCDParameters(dt=1e-4, tolerance=1e-9))
    df = sim.run(20)
    assert (df.iterations >= 1).all() and df.converged.all()
    assert (df.residual_quad <= 1e-9).all() and (df.residual_max <= 1e-9).all()
    assert df.n_active_contacts.iloc[-1] == 2


def test_driver_force_includes_plate_inertia():
    """Free sphere-less driven plate: the driver force is m a (minus gravity)."""
    s = Spheres.from_density([[0, 0, 1.0]], [0.01], 2600.0)  # far away
    amp, w, m = 1e-3, 2 * np.pi * 5, 0.235
    plates = Plates([Plate([0, 0, 0], [0, 0, 1], mode="driven", mass=m,
                           displacement=lambda t: np.array([amp * np.sin(w * t), 0, 0]))])
    sim = Simulation(s, plates, None, NSCDParameters(dt=1e-4, gravity=(0, 0, 0)))
    df = sim.run(400)
    t = df.time.to_numpy()
    # acceleration of the mean-velocity sequence, centred at t - dt
    expected = -m * amp * w**2 * np.sin(w * (t - 1e-4))
    np.testing.assert_allclose(df.plate0_driver_Fx_N.to_numpy()[5:], expected[5:],
                               atol=1e-3 * m * amp * w**2)


def test_checkpoint_restart_is_exact(tmp_path):
    def make():
        s, plates, bonds = random_bonded_network(n=27)
        return Simulation(s, plates, bonds, NSCDParameters(dt=5e-5))

    ref = make()
    ref.run(20)
    sim = make()
    sim.run(10)
    sim.save_checkpoint(tmp_path / "ck.h5")
    drivers = sim.plates.drivers
    back = read_checkpoint(tmp_path / "ck.h5", drivers=drivers)
    assert back.step_index == 10 and back.time == pytest.approx(sim.time)
    back.run(10)
    np.testing.assert_array_equal(back.spheres.position, ref.spheres.position)
    np.testing.assert_array_equal(back.bonds.force, ref.bonds.force)
    np.testing.assert_array_equal(back.bonds.delta_k, ref.bonds.delta_k)


def test_bonds_create_micro_parameters():
    s = Spheres(position=[[0, 0, 0], [0.005, 0, 0]], radius=[0.002, 0.0015], mass=[1, 1],
                inertia=[1, 1])
    b = Bonds.create(s, Plates([]), [1], [0], LAW_15C)
    a = np.pi * 0.0015**2 / 0.005
    assert b.Km[0, 0] == pytest.approx(LAW_15C.Em * a)
    assert b.Km[0, 1] == pytest.approx(LAW_15C.Em * a / 2.7)
    assert b.delta0[0] == pytest.approx(0.0015)
    assert b.r_crit[0] == pytest.approx(2.7e6 * np.pi * 0.0015**2)
    np.testing.assert_allclose(b.frame[0, 0], [1, 0, 0])


def test_bad_parameters_raise():
    with pytest.raises(ValueError):
        NSCDParameters(dt=1e-4, theta=0.3)
    with pytest.raises(ValueError):
        Plate([0, 0, 0], [0, 0, 1], mode="driven")
