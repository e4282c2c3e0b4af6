"""The 2PB job on its exact periodic orbit: where the linearity certificate holds, the orbit's
record reduces to the time domain's |E*| and phase (to 0.01 % and 0.001 deg here); where it
fails (a weak bond, a gap that closes under the head motion), the time domain shows the
nonlinearity the certificate names (a bond breaks, a contact becomes active)."""

import dataclasses
import math

import numpy as np
import pytest

from asphalt_nscd.campaign import twopb
from asphalt_nscd.harmonic import orbit
from asphalt_nscd.io import InputError
from asphalt_nscd.rheology.laws import GeneralizedBurgers
from asphalt_nscd.sample.store import read_sample

LAW = GeneralizedBurgers.burgers(Em=2.43e7, eta_m=3.71e6, Ek=4.84e7, eta_k=7.73e5)
BASE = twopb.TwoPBSettings(
    dt_policy="steps_per_cycle",
    steps_per_cycle=200,
    dt_max_s=1.0,
    start="periodic",
    periodic_cycles=1,
    window_cycles=1,
    gravity=True,
    yield_stress_Pa=None,
    checkpoint_every=0,
)


def test_ellipse_semi_major_is_the_largest_real_part():
    rng = np.random.default_rng(7)
    c = rng.normal(size=(20, 3)) + 1j * rng.normal(size=(20, 3))
    t = np.linspace(0, 2 * np.pi, 20001)
    brute = np.sqrt((np.real(c[:, :, None] * np.exp(1j * t)) ** 2).sum(axis=1)).max(axis=1)
    np.testing.assert_allclose(orbit.ellipse_semi_major(c), brute, rtol=1e-7)


@pytest.mark.parametrize("frequency", [3.0, 40.0])
def test_a_certified_job_takes_its_orbit_equal_to_the_time_domain(tiny_sample, tmp_path, frequency):
    """method auto on a certified job takes the orbit (no time step); the same job stepped in
    time gives the same |E*| to 1e-4 (0.01 %) and phase to 1e-3 deg, and a verification job
    records both."""
    rec_o = twopb.run_test(tiny_sample, LAW, frequency, BASE, tmp_path / "o.h5", progress=False)
    rec_t = twopb.run_test(
        tiny_sample, LAW, frequency, dataclasses.replace(BASE, method="time_domain"), tmp_path / "t.h5", progress=False
    )
    rec_v = twopb.run_test(tiny_sample, LAW, frequency, BASE, tmp_path / "v.h5", progress=False, verify=True)
    o, t, v = (twopb.reduce_test(r, 1) for r in (rec_o, rec_t, rec_v))
    assert o["path"] == "orbit" and o["cert_holds"] and t["path"] == "time_domain" and v["path"] == "time_domain"
    assert o["E_norm_MPa"] == pytest.approx(t["E_norm_MPa"], rel=1e-4)
    assert abs(o["phase_deg"] - t["phase_deg"]) < 1e-3
    assert v["verification"] and abs(v["orbit_vs_time_domain_E_pct"]) < 1e-2
    assert abs(v["orbit_vs_time_domain_phase_deg"]) < 1e-3 and v["E_norm_MPa"] == t["E_norm_MPa"]
    assert o["n_steps"] == t["n_steps"]  # the same cycle, on the orbit without stepping (its cost: benchmarks)
    assert t["n_contact_steps"] == 0 and o["n_contact_steps"] == 0  # certified: no contact in the time domain


def test_the_certificate_fails_on_a_weak_bond_and_the_time_domain_breaks_it(tiny_sample, tmp_path):
    weak = dataclasses.replace(BASE, yield_stress_Pa=1e3)
    row = twopb.reduce_test(twopb.run_test(tiny_sample, LAW, 10.0, weak, tmp_path / "w.h5", progress=False), 1)
    assert row["path"] == "time_domain" and not row["cert_holds"] and row["cert_bond_force_ratio"] >= 1.0
    assert "break bonds" in row["path_reason"] and row["n_broken_total"] > 0
    with pytest.raises(InputError, match="not certified linear"):
        twopb.run_test(
            tiny_sample, LAW, 10.0, dataclasses.replace(weak, method="orbit"), tmp_path / "x.h5", progress=False
        )
    strong = dataclasses.replace(BASE, yield_stress_Pa=1e7)
    row = twopb.reduce_test(twopb.run_test(tiny_sample, LAW, 10.0, strong, tmp_path / "s.h5", progress=False), 1)
    assert row["path"] == "orbit" and 0 < row["cert_bond_force_ratio"] < 1.0


def _gap_history(sample_path, settings, frequency, pair):
    """Step the job in time from its periodic start; the gap of ``pair`` (spheres) and the
    largest number of active contacts at each step."""
    sample = read_sample(sample_path)
    dt = twopb.time_step(frequency, settings)
    sim, _ = twopb.build_simulation(sample, LAW, frequency, dt, settings)
    info, state = twopb.periodic_start(sim, LAW, frequency, settings)
    cert = orbit.certify(sim, state, twopb.n_steps_of(frequency, dt, settings, "periodic") * dt)
    i, j = pair if pair is not None else cert.gap_at
    gaps, active = [], []
    for _ in range(twopb.n_steps_of(frequency, dt, settings, "periodic")):
        st = sim.step()
        gaps.append(
            np.linalg.norm(sim.spheres.position[i] - sim.spheres.position[j])
            - sim.spheres.radius[i]
            - sim.spheres.radius[j]
        )
        active.append(st.n_active_contacts)
    return cert, np.array(gaps), np.array(active)


def test_the_gap_margin_is_the_time_domains_and_a_closing_gap_fails(tiny_sample):
    """At a head amplitude of 1 mm the nearest unbonded pair comes within 0.2 mm and stays open:
    the certificate's smallest gap is the time domain's to the between-steps bound; at 2 mm a
    pair closes: the certificate fails naming it, and the time domain has an active contact."""
    f = 10.0
    s = dataclasses.replace(BASE, amplitude_m=1e-3)
    cert, gaps, active = _gap_history(tiny_sample, s, f, None)
    assert cert.holds and cert.n_pairs > 0 and active.max() == 0
    w_dt = 2 * math.pi * f * twopb.time_step(f, s)
    assert cert.min_gap_m <= gaps.min() <= cert.min_gap_m + w_dt**2 * 2e-3  # e(D) < 2 mm
    cert2, _, active2 = _gap_history(tiny_sample, dataclasses.replace(BASE, amplitude_m=2e-3), f, None)
    assert not cert2.holds and cert2.min_gap_m < 0 and "closes" in cert2.reason and active2.max() >= 1


def test_the_support_cancels_the_weight_along_the_zero_modes_only():
    """mechanism_support on a cluster of two spheres with two zero modes (random, orthonormal,
    translations and rotations mixed): the support force leaves no load along either mode,
    it is the smallest such force (the weight's projection on the modes' translations, so no
    larger than the weight), and the free fall is (V^T M V)^-1 V^T f_g along the translations."""
    from types import SimpleNamespace

    from asphalt_nscd.harmonic.periodic import mechanism_support

    rng = np.random.default_rng(4)
    d, spheres = 6, np.array([3, 7])
    V, _ = np.linalg.qr(rng.normal(size=(2 * d, 2)))
    mass_free = np.concatenate([np.r_[np.full(3, 2e-5), np.full(3, 3e-11)], np.r_[np.full(3, 5e-5), np.full(3, 8e-11)]])
    system = SimpleNamespace(
        dof_per_sphere=d, mass_free=np.zeros(100), mechanism_modes=lambda: iter([(np.arange(2 * d), V, 1.0, spheres)])
    )
    system.mass_free[: 2 * d] = mass_free
    mass = np.full(10, 1.0)
    mass[spheres] = [2e-5, 5e-5]
    g = np.array([0.0, 0.0, -9.81])
    support, accel, n_modes = mechanism_support(system, mass, g)
    assert n_modes == 2 and not support[[0, 1, 2, 4, 5, 6, 8, 9]].any()
    T = V[np.r_[0:3, 6:9]]
    fg = (mass[spheres][:, None] * g).ravel()
    np.testing.assert_allclose(T.T @ (fg + support[spheres].ravel()), 0.0, atol=1e-12 * np.abs(fg).max())
    assert np.linalg.norm(support[spheres]) <= np.linalg.norm(fg) * (1 + 1e-12)
    MV = mass_free[:, None] * V
    np.testing.assert_allclose(accel[spheres].ravel(), T @ np.linalg.solve(V.T @ MV, T.T @ fg), rtol=1e-12)


def test_a_floating_cluster_is_left_out_of_the_test(tmp_path):
    """Spheres no chain of bonds ties to a plate carry no load and, under gravity, would fall
    through the sample: the test leaves them out (harmonic.solver.held_spheres)."""
    from asphalt_nscd.harmonic.solver import held_spheres
    from asphalt_nscd.sample.lattice import lattice_sample

    smp = lattice_sample(40, seed=3, radius_range=(0.9e-3, 1.5e-3), plate_mass=(np.inf, 1e-3))
    assert held_spheres(smp).all()
    i, j = smp.bonds["i"], smp.bonds["j"]
    a = 20  # cut every bond of sphere 20: it floats
    keep = (i != a) & (j != a)
    loose = dataclasses.replace(smp, bonds={k: v[keep] for k, v in smp.bonds.items()})
    held = held_spheres(loose)
    assert not held[a] and held.sum() == smp.radius.size - 1
    assert not held_spheres(loose, bond_kinematics="barycentre", head_rotation="clamped")[a]


def test_a_steady_state_under_gravity_that_fails_fails_the_certificate(tiny_sample, tmp_path, monkeypatch):
    """When the steady state under gravity cannot be used (here: a residual bound no solve meets),
    the job starts with gravity from rest, not on its orbit: the certificate fails saying so and
    the job steps in time."""
    from asphalt_nscd.harmonic import periodic

    monkeypatch.setattr(periodic, "GRAVITY_RESIDUAL_MAX", 0.0)
    row = twopb.reduce_test(twopb.run_test(tiny_sample, LAW, 10.0, BASE, tmp_path / "g.h5", progress=False), 1)
    assert not row["cert_holds"] and "steady state under gravity is not used" in row["cert_reason"]
    assert row["path"] == "time_domain"


def test_a_job_that_steps_in_time_takes_its_own_steps_per_cycle(tiny_sample, tmp_path):
    """With time_domain_steps_per_cycle, a job on its orbit keeps the dt policy's step (here the
    paper's fixed 5e-5 s) and a job that steps in time (a verification job) takes 1 / (f N), its
    orbit compared at that same step."""
    s = dataclasses.replace(BASE, dt_policy="fixed", dt_s=5e-5, time_domain_steps_per_cycle=100)
    f = 40.0
    o = twopb.reduce_test(twopb.run_test(tiny_sample, LAW, f, s, tmp_path / "o.h5", progress=False), 1)
    v = twopb.reduce_test(twopb.run_test(tiny_sample, LAW, f, s, tmp_path / "v.h5", progress=False, verify=True), 1)
    assert o["path"] == "orbit" and o["dt_s"] == 5e-5 and o["n_steps"] == 500
    assert v["path"] == "time_domain" and v["dt_s"] == pytest.approx(1 / (f * 100)) and v["n_steps"] == 100
    assert "100 steps per cycle" in v["path_reason"] and abs(v["orbit_vs_time_domain_E_pct"]) < 1e-2
    assert abs(v["E_norm_MPa"] / o["E_norm_MPa"] - 1) < 2e-3  # 100 steps per cycle against 500 (O((w dt)^2))
    with pytest.raises(ValueError, match="time_domain_steps_per_cycle"):
        dataclasses.replace(BASE, time_domain_steps_per_cycle=4)
