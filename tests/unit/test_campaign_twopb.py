"""Numerical 2PB test: dt policy, resume after interruption, recovery of the Burger's phase."""

import numpy as np
import pytest

from asphalt_nscd.campaign import twopb
from asphalt_nscd.harmonic.network import network_from_sample
from asphalt_nscd.rheology.laws import GeneralizedBurgers

LAW_15C = GeneralizedBurgers.burgers(Em=2.43e7, eta_m=3.71e6, Ek=4.84e7, eta_k=7.73e5)


def test_time_step_policies():
    fixed = twopb.TwoPBSettings(dt_policy="fixed", dt_s=5e-5)
    assert twopb.time_step(0.1, fixed) == 5e-5
    spc = twopb.TwoPBSettings(dt_policy="steps_per_cycle", steps_per_cycle=500, dt_max_s=1e-3)
    assert twopb.time_step(40.0, spc) == pytest.approx(5e-5)
    assert twopb.time_step(0.1, spc) == 1e-3  # capped
    assert twopb.n_steps_of(40.0, 5e-5, spc) == 2500
    with pytest.raises(ValueError):
        twopb.TwoPBSettings(dt_policy="adaptive")


def test_resume_gives_the_uninterrupted_run(tiny_sample, tmp_path):
    s = twopb.TwoPBSettings(
        n_cycles=2,
        dt_policy="steps_per_cycle",
        steps_per_cycle=60,
        dt_max_s=0.02,
        checkpoint_every=25,
        profile_instants=4,
    )
    full = twopb.run_test(tiny_sample, LAW_15C, 10.0, s, tmp_path / "a.h5", progress=False)
    out = tmp_path / "b.h5"
    assert twopb.run_test(tiny_sample, LAW_15C, 10.0, s, out, progress=False, stop_after=70) is None
    assert (tmp_path / "b.h5.ckpt.h5").exists() and not out.exists()
    resumed = twopb.run_test(tiny_sample, LAW_15C, 10.0, s, out, progress=False)
    np.testing.assert_allclose(resumed["force_N"], full["force_N"], rtol=1e-12, atol=0)
    np.testing.assert_allclose(resumed["profile"]["vx_m_s"], full["profile"]["vx_m_s"], rtol=1e-12)
    assert not (tmp_path / "b.h5.ckpt.h5").exists()
    assert not (tmp_path / "b.h5.partial.npz").exists()
    back = twopb.read_record(out)
    np.testing.assert_array_equal(back["force_N"], resumed["force_N"])
    assert back["stats"]["linear"].shape == (120,)


def test_reduction_recovers_burgers_phase(tiny_sample, tmp_path):
    """Without inertia (light spheres and head at 3 Hz) every bond shares one law, so the
    sample's force is E*(w) times a real geometric stiffness: Psi = Burger's phase.
    Barycentre kinematics and clamped head: with the contact kinematics and a free head this
    40-sphere lattice is so compliant in bending that the sphere inertia dominates the force
    at 3 Hz (the harmonic solver agrees: psi = 136 deg), so the premise does not hold."""
    s = twopb.TwoPBSettings(
        n_cycles=3,
        dt_policy="steps_per_cycle",
        steps_per_cycle=200,
        checkpoint_every=0,
        bond_kinematics="barycentre",
        head_rotation="clamped",
    )
    rec = twopb.run_test(tiny_sample, LAW_15C, 3.0, s, tmp_path / "r.h5", progress=False)
    row = twopb.reduce_test(rec, window_cycles=1)
    _, phase = LAW_15C.norm_and_phase(2 * np.pi * 3.0)
    assert row["phase_deg"] == pytest.approx(float(phase), abs=0.1)
    assert row["z0_m"] == pytest.approx(63e-6, rel=1e-6)
    assert row["force_residual"] < 0.02
    # the two force readings agree where the head inertia is negligible
    assert row["E_norm_MPa_other_reading"] == pytest.approx(row["E_norm_MPa"], rel=1e-3)
    assert row["n_nlgs_steps"] == 0 and row["n_broken_total"] == 0


def test_bond_strength_option(tiny_sample):
    """yield_stress_Pa sets R_crit = sigma_y pi r_min^2; None gives unbreakable bonds."""
    from asphalt_nscd.sample.store import read_sample

    sample = read_sample(tiny_sample)
    sim, _ = twopb.build_simulation(sample, LAW_15C, 10.0, 1e-4, twopb.TwoPBSettings())
    np.testing.assert_allclose(sim.bonds.r_crit, 2.7e6 * np.pi * sim.bonds.r_min**2)
    sim, _ = twopb.build_simulation(sample, LAW_15C, 10.0, 1e-4, twopb.TwoPBSettings(yield_stress_Pa=None))
    assert np.isinf(sim.bonds.r_crit).all()


def test_build_simulation_passes_the_kinematics_options(tiny_sample):
    from asphalt_nscd.sample.store import read_sample

    sample = read_sample(tiny_sample)
    sim, _ = twopb.build_simulation(sample, LAW_15C, 10.0, 1e-4, twopb.TwoPBSettings())
    assert sim.params.bond_kinematics == "contact"
    assert sim.plates.rotates.tolist() == [False, True]
    np.testing.assert_allclose(sim.plates.inertia[1], network_from_sample(sample).plate_inertia)
    assert np.all(sim.plates.inertia[1] > 0)
    old = twopb.TwoPBSettings(bond_kinematics="barycentre", head_rotation="clamped")
    sim, _ = twopb.build_simulation(sample, LAW_15C, 10.0, 1e-4, old)
    assert sim.params.bond_kinematics == "barycentre" and not sim.plates.rotates.any()
    with pytest.raises(ValueError, match="head_rotation"):
        twopb.TwoPBSettings(head_rotation="hinged")


def test_build_simulation_does_not_move_the_sample(tiny_sample):
    """The simulation owns its positions: running it leaves the SampleData (which may build
    the next simulation, e.g. in campaign-bench) at the sample file's configuration."""
    from asphalt_nscd.sample.store import read_sample

    sample = read_sample(tiny_sample)
    before = sample.position.copy()
    sim, _ = twopb.build_simulation(sample, LAW_15C, 10.0, 1e-4, twopb.TwoPBSettings())
    for _ in range(5):
        sim.step()
    assert np.abs(sim.spheres.position - before).max() > 0
    np.testing.assert_array_equal(sample.position, before)


def test_rig_state_file_is_what_the_job_computes_and_refuses_another_sample(tiny_sample, tmp_path, monkeypatch):
    """``rig-state`` writes the held spheres and the law-free gravity solution a job would
    compute (harmonic.solver.held_spheres, harmonic.periodic.gravity_unit); a job given the file
    reads them instead of computing them and gives the same record; the file is refused,
    naming the key, for another sample file or other settings."""
    import dataclasses
    import shutil

    import h5py

    from asphalt_nscd.cli import main
    from asphalt_nscd.harmonic import periodic, solver
    from asphalt_nscd.io import InputError
    from asphalt_nscd.sample.store import read_sample

    s = twopb.TwoPBSettings(
        n_cycles=1, dt_policy="steps_per_cycle", steps_per_cycle=40, dt_max_s=0.02, gravity=True, start="periodic"
    )
    rig = tmp_path / "rig.h5"
    twopb.write_rig_state(tiny_sample, s, rig)
    held, unit, reference = twopb.read_rig_state(rig, tiny_sample, s)
    np.testing.assert_array_equal(
        held, solver.held_spheres(read_sample(tiny_sample), s.bond_kinematics, s.head_rotation, s.nu)
    )
    assert np.abs(unit.displacement).max() > 0 and unit.failed == "" and unit.residual <= periodic.GRAVITY_RESIDUAL_MAX
    own = twopb.run_test(tiny_sample, LAW_15C, 10.0, s, tmp_path / "own.h5", progress=False)
    rest = dataclasses.replace(s, start="rest")  # a rest start takes the support force from the unit
    own_rest = twopb.run_test(tiny_sample, LAW_15C, 10.0, rest, tmp_path / "own_rest.h5", progress=False)

    def not_again(*args, **kwargs):
        raise AssertionError("the job computed what its rig state holds")

    monkeypatch.setattr(solver, "held_spheres", not_again)
    monkeypatch.setattr(periodic, "gravity_unit", not_again)
    monkeypatch.setattr(solver.HarmonicSystem, "_pattern", not_again)  # G comes assembled
    monkeypatch.setattr(solver, "nested_dissection", not_again)  # and ordered
    read = twopb.run_test(tiny_sample, LAW_15C, 10.0, s, tmp_path / "read.h5", progress=False, rig_state=rig)
    assert read["attrs"]["start"] == own["attrs"]["start"] == "periodic"
    np.testing.assert_array_equal(read["force_N"], own["force_N"])
    monkeypatch.setattr(periodic, "mechanism_support", not_again)
    read_rest = twopb.run_test(
        tiny_sample, LAW_15C, 10.0, rest, tmp_path / "read_rest.h5", progress=False, rig_state=rig
    )
    assert read_rest["attrs"]["start"] == own_rest["attrs"]["start"] == "rest"
    np.testing.assert_array_equal(read_rest["force_N"], own_rest["force_N"])
    monkeypatch.undo()
    # the reference is the system's own G and ordering, and only its own network's
    system = periodic.harmonic_system(twopb.build_simulation(read_sample(tiny_sample), LAW_15C, 10.0, 1e-3, s)[0])
    for name, block in system.reference_state()["G"].items():
        assert (block != reference["G"][name]).nnz == 0
    np.testing.assert_array_equal(system.permutation(), reference["permutation"])
    with pytest.raises(ValueError, match="another network"):
        solver.HarmonicSystem(
            system.network, nu=0.35, regularisation=0.0, reference={**reference, "network_sha256": "0"}
        )
    with pytest.raises(ValueError, match="options"):
        solver.HarmonicSystem(system.network, nu=0.3, regularisation=0.0, reference=reference)

    # the command writes the same file content from a --config's settings
    assert main(["rig-state", "--sample", str(tiny_sample), "--set", "gravity=true", "-o", str(tmp_path / "c.h5")]) == 0
    with h5py.File(tmp_path / "c.h5") as a, h5py.File(rig) as b:
        np.testing.assert_array_equal(a["gravity/displacement"][()], b["gravity/displacement"][()])
    other = tmp_path / "s2.h5"
    shutil.copy(tiny_sample, other)
    with open(other, "ab") as fh:  # another file: its SHA-256 differs
        fh.write(b"\0")
    with pytest.raises(InputError, match="sample_sha256"):
        twopb.read_rig_state(rig, other, s)
    with pytest.raises(InputError, match="nu is 0.35"):
        twopb.read_rig_state(rig, tiny_sample, dataclasses.replace(s, nu=0.3))
    with pytest.raises(InputError, match="gravity is True"):
        twopb.read_rig_state(rig, tiny_sample, dataclasses.replace(s, gravity=False))
    with pytest.raises(InputError, match="not a rig-state file"):
        twopb.read_rig_state(tiny_sample, tiny_sample, s)
