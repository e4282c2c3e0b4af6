"""Periodic start of the 2PB test: the theta-method's steady state is an exact periodic orbit
of the NSCD step map, and one cycle from it gives the converged from-rest result."""

from cli_options import set_options
import dataclasses
import math

import numpy as np
import pytest

from asphalt_nscd.campaign import periodic as periodic_check
from asphalt_nscd.campaign import twopb
from asphalt_nscd.harmonic import periodic
from asphalt_nscd.harmonic.solver import laplace_modulus
from asphalt_nscd.rheology.laws import GeneralizedBurgers
from asphalt_nscd.sample.store import read_sample

LAW_15C = GeneralizedBurgers.burgers(Em=2.43e7, eta_m=3.71e6, Ek=4.84e7, eta_k=7.73e5)
#: a generalized law with three Kelvin-Voigt units and a static spring
LAW_GEN = GeneralizedBurgers(Em=3.0e7, eta_m=2.0e6, Ek=(6e7, 9e7, 2e8), eta_k=(3e6, 4e5, 2e4), E_inf=2e6)


def test_theta_laplace():
    f, h = 10.0, 1e-3
    w = 2 * math.pi * f
    assert periodic.theta_laplace(f, h, 0.5) == pytest.approx(1j * 2 / h * math.tan(w * h / 2), rel=1e-14)
    z = np.exp(1j * w * h)
    assert periodic.theta_laplace(f, h, 0.7) == pytest.approx((z - 1) / (h * (0.7 * z + 0.3)), rel=1e-14)
    # consistent: s_h -> i w as h -> 0, with an O((w h)^2) error at theta = 1/2
    s = periodic.theta_laplace(f, 1e-6, 0.5)
    assert abs(s / (1j * w) - 1) < (w * 1e-6) ** 2
    with pytest.raises(ValueError):
        periodic.theta_laplace(f, 0.06, 0.5)  # fewer than 2 steps per period


def test_laplace_modulus():
    w = 2 * math.pi * 7.0
    assert laplace_modulus(LAW_GEN, 1j * w) == pytest.approx(complex(LAW_GEN.complex_modulus(w)), rel=1e-14)
    s = 3.0 + 40.0j  # off the axis: the law with i w -> s
    d = 1 / LAW_GEN.Em + 1 / (s * LAW_GEN.eta_m) + sum(1 / (e + s * c) for e, c in zip(LAW_GEN.Ek, LAW_GEN.eta_k))
    assert laplace_modulus(LAW_GEN, s) == pytest.approx(LAW_GEN.E_inf + 1 / d, rel=1e-14)

    class Tabulated:
        def complex_modulus(self, omega):
            return 1e7 + 1e6j

    assert laplace_modulus(Tabulated(), 5j) == 1e7 + 1e6j
    with pytest.raises(ValueError, match="imaginary axis"):
        laplace_modulus(Tabulated(), 1 + 5j)


@pytest.mark.parametrize(
    "kinematics,theta,law", [("contact", 0.5, LAW_15C), ("barycentre", 0.5, LAW_15C), ("contact", 0.7, LAW_GEN)]
)
def test_periodic_state_is_an_orbit_of_the_step_map(tiny_sample, kinematics, theta, law):
    """One period (40 steps) after the periodic start every state variable (positions,
    velocities, angular velocities, bond forces, Maxwell and Kelvin-Voigt internal variables)
    is back to its initial value, and in between the positions are a pure sinusoid of the
    period: the state is the exact periodic solution of the discrete scheme."""
    f = 10.0
    s = twopb.TwoPBSettings(
        dt_policy="steps_per_cycle",
        steps_per_cycle=40,
        dt_max_s=1.0,
        theta=theta,
        bond_kinematics=kinematics,
        head_rotation="free" if kinematics == "contact" else "clamped",
    )
    dt = twopb.time_step(f, s)
    sample = read_sample(tiny_sample)
    sim, _ = twopb.build_simulation(sample, law, f, dt, s)
    sim.params.linear_tolerance = 1e-13
    x_rest = sim.spheres.position.copy()
    state = periodic.periodic_state(sim, law, f, s.amplitude_m, s.head_rotation)
    periodic.apply_periodic_state(sim, state)
    X, V = state.position - x_rest, state.velocity
    amp_x = np.abs(state.position - x_rest).max()
    W = state.angular_velocity
    hist = {"x": [], "v": [], "w": [], "F": [], "dk": [], "dc": []}
    for _ in range(40):
        sim.step()
        hist["x"].append(sim.spheres.position - x_rest)
        hist["v"].append(sim.spheres.velocity.copy())
        hist["w"].append(sim.spheres.angular_velocity.copy())
        hist["F"].append(sim.bonds.force.copy())
        hist["dk"].append(sim.bonds.delta_k.copy())
        hist["dc"].append(sim.bonds.delta_c.copy())
    # one period later (40 steps) the state is back: y_40 = y_0
    assert np.abs(hist["x"][-1] - X).max() < 1e-8 * amp_x
    assert np.abs(hist["v"][-1] - V).max() < 1e-8 * np.abs(V).max()
    if kinematics == "contact":
        assert np.abs(W).max() > 0
        assert np.abs(hist["w"][-1] - W).max() < 1e-8 * np.abs(W).max()
    assert np.abs(hist["F"][-1] - state.bond_force).max() < 1e-8 * np.abs(state.bond_force).max()
    assert np.abs(hist["dk"][-1] - state.delta_k).max() < 1e-8 * np.abs(state.delta_k).max()
    assert np.abs(hist["dc"][-1] - state.delta_c).max() < 1e-8 * np.abs(state.delta_c).max()
    # and in between it is a sinusoid of the period: the 40 samples have no other harmonic
    spec = np.fft.rfft(np.array(hist["x"]), axis=0)
    assert np.abs(spec[2:]).max() < 1e-7 * np.abs(spec[1]).max()


#: a solid chain: no Maxwell dashpot (static equilibrium under gravity)
LAW_SOLID = GeneralizedBurgers(Em=3.0e7, eta_m=np.inf, Ek=(6e7, 9e7), eta_k=(3e6, 4e5))
#: a solid through its static spring: the dashpot relaxes, E_inf carries the weight
LAW_STATIC = GeneralizedBurgers(Em=3.0e7, eta_m=2.0e6, Ek=(6e7, 9e7, 2e8), eta_k=(3e6, 4e5, 2e4), E_inf=2e8)


@pytest.mark.parametrize(
    "kinematics,law,creep",
    [
        ("contact", LAW_15C, True),
        ("barycentre", LAW_15C, True),
        ("contact", LAW_SOLID, False),
        ("contact", LAW_STATIC, False),
    ],
)
def test_periodic_state_with_gravity_is_an_orbit_of_the_step_map(tiny_sample, kinematics, law, creep):
    """With gravity on, the periodic state plus the steady state under gravity (head held) is
    an orbit of the step map too: after one period every force, velocity and internal
    variable of the springs is back, and the positions have moved by exactly one period of
    the steady creep (a liquid bond law) or not at all (a solid one). Without the gravity
    part, the same start is not an orbit (gravity's transient)."""
    f = 10.0
    s = twopb.TwoPBSettings(
        dt_policy="steps_per_cycle",
        steps_per_cycle=40,
        dt_max_s=1.0,
        gravity=True,
        bond_kinematics=kinematics,
        head_rotation="free" if kinematics == "contact" else "clamped",
    )
    dt = twopb.time_step(f, s)
    sample = read_sample(tiny_sample)
    errors = {}
    for with_gravity in (True, False):
        sim, _ = twopb.build_simulation(sample, law, f, dt, s)
        sim.params.linear_tolerance = 1e-13
        state = periodic.periodic_state(sim, law, f, s.amplitude_m, s.head_rotation)
        assert state.gravity is not None and state.gravity.creep == creep
        assert state.gravity.residual < 1e-9 and not state.gravity.failed
        if not with_gravity:  # the periodic part alone: gravity starts from rest
            g = state.gravity
            state = dataclasses.replace(
                state,
                position=state.position - g.displacement,
                velocity=state.velocity - g.velocity,
                angular_velocity=state.angular_velocity - g.angular_velocity,
                head_rotation=state.head_rotation - g.head_rotation,
                head_angular_velocity=state.head_angular_velocity - g.head_angular_velocity,
                bond_displacement=state.bond_displacement - g.bond_displacement,
                bond_force=state.bond_force - g.bond_force,
                delta_c=state.delta_c - g.delta_c,
                delta_k=state.delta_k - g.delta_k,
            )
        periodic.apply_periodic_state(sim, state)
        for _ in range(40):
            st = sim.step()
            assert st.solver == "linear"
        drift = 40 * dt * state.gravity.velocity if with_gravity else 0.0
        errors[with_gravity] = (
            np.abs(sim.bonds.force - state.bond_force).max() / np.abs(state.bond_force).max(),
            np.abs(sim.spheres.velocity - state.velocity).max() / np.abs(state.velocity).max(),
            np.abs(sim.bonds.delta_k - state.delta_k).max() / np.abs(state.delta_k).max(),
            np.abs(sim.spheres.position - state.position - drift).max() / s.amplitude_m,
        )
        if with_gravity and creep:
            assert np.abs(state.gravity.velocity).max() > 0
        elif with_gravity:
            assert np.abs(state.gravity.velocity).max() == 0
    assert max(errors[True]) < 1e-8, errors[True]
    assert max(errors[False][:3]) > 1e-3, errors[False]


def test_discrete_state_beats_the_continuous_one(tiny_sample):
    """The continuous steady state (s = i w) is not an orbit of the step map: after one
    period it has drifted by O((w h)^2) where the discrete one has not."""
    f = 10.0
    s = twopb.TwoPBSettings(dt_policy="steps_per_cycle", steps_per_cycle=20, dt_max_s=1.0)
    dt = twopb.time_step(f, s)
    sample = read_sample(tiny_sample)
    err = {}
    for continuous in (False, True):
        sim, _ = twopb.build_simulation(sample, LAW_15C, f, dt, s)
        sim.params.linear_tolerance = 1e-13
        state = periodic.periodic_state(sim, LAW_15C, f, s.amplitude_m, continuous=continuous)
        periodic.apply_periodic_state(sim, state)
        v0 = sim.spheres.velocity.copy()
        for _ in range(20):
            sim.step()
        err[continuous] = np.abs(sim.spheres.velocity - v0).max() / np.abs(v0).max()
    assert err[False] < 1e-8
    assert err[True] > 1e3 * err[False]


def test_periodic_start_gives_the_converged_from_rest_cycle(tiny_sample, tmp_path):
    """At reduced size: one cycle from the periodic start gives the
    last-cycle |E*| of a long from-rest run within 0.1 % and Phi within 0.05 deg, while 5
    cycles from rest have not converged on this lightly damped lattice."""
    s = twopb.TwoPBSettings(
        dt_policy="steps_per_cycle",
        steps_per_cycle=100,
        dt_max_s=1.0,
        checkpoint_every=0,
        start="periodic",
        periodic_cycles=2,
    )
    row, cycles = periodic_check.check_case(
        tiny_sample, LAW_15C, 10.0, s, long_cycles=25, workdir=tmp_path, meta={"mode": "test", "temperature_C": 15.0}
    )
    assert row["start_periodic_run"] == "periodic"
    assert row["periodic_equal"]
    assert abs(row["dE_periodic_pct"]) < 0.1 and abs(row["dphase_periodic_deg"]) < 0.05
    assert not row["rest_converged"] and not row["rest_equal_periodic"]
    assert abs(row["dphase_rest_deg"]) > 0.1
    assert row["steps_rest"] == 500 and row["steps_periodic"] == 200
    # the from-rest run approaches the periodic result: its last cycles agree with it
    assert 5 < row["first_cycle_to_periodic"] <= 25
    assert [c["cycle"] for c in cycles] == list(range(1, 26))
    assert abs(cycles[-1]["dE_to_periodic_pct"]) < 0.1


def test_periodic_cycles_are_identical(tiny_sample, tmp_path):
    """Two cycles from the periodic start reduce to the same |E*| and Phi (no transient)."""
    s = twopb.TwoPBSettings(
        dt_policy="steps_per_cycle",
        steps_per_cycle=60,
        dt_max_s=1.0,
        checkpoint_every=0,
        start="periodic",
        periodic_cycles=2,
        bond_kinematics="barycentre",
        head_rotation="clamped",
        method="time_domain",
    )
    rec = twopb.run_test(tiny_sample, LAW_GEN, 3.0, s, tmp_path / "p.h5", progress=False)
    first = twopb.reduce_test(twopb.truncate_record(rec, 1), 1)
    second = twopb.reduce_test(rec, 1)
    assert second["start"] == "periodic" and second["n_cycles_simulated"] == 2
    assert second["E_norm_MPa"] == pytest.approx(first["E_norm_MPa"], rel=1e-7)
    assert second["phase_deg"] == pytest.approx(first["phase_deg"], abs=1e-6)
    # no inertia to speak of at 3 Hz with barycentre kinematics: the phase is the law's
    _, phase = LAW_GEN.norm_and_phase(2 * np.pi * 3.0)
    assert second["phase_deg"] == pytest.approx(float(phase), abs=0.1)


def test_periodic_start_falls_back_to_rest_when_bonds_would_break(tiny_sample, tmp_path):
    s = twopb.TwoPBSettings(
        dt_policy="steps_per_cycle",
        steps_per_cycle=40,
        dt_max_s=1.0,
        checkpoint_every=0,
        start="periodic",
        n_cycles=2,
        yield_stress_Pa=1.0,
    )
    rec = twopb.run_test(tiny_sample, LAW_15C, 10.0, s, tmp_path / "b.h5", progress=False)
    assert rec["attrs"]["start"] == "rest" and rec["attrs"]["start_requested"] == "periodic"
    assert rec["attrs"]["n_steps"] == 2 * 40  # n_cycles (2) from rest
    assert "break" in rec["attrs"]["start_info"]


def test_resume_with_periodic_start(tiny_sample, tmp_path):
    s = twopb.TwoPBSettings(
        dt_policy="steps_per_cycle",
        steps_per_cycle=60,
        dt_max_s=0.02,
        checkpoint_every=25,
        profile_instants=4,
        start="periodic",
        periodic_cycles=2,
        method="time_domain",
    )
    full = twopb.run_test(tiny_sample, LAW_GEN, 10.0, s, tmp_path / "a.h5", progress=False)
    out = tmp_path / "b.h5"
    assert twopb.run_test(tiny_sample, LAW_GEN, 10.0, s, out, progress=False, stop_after=70) is None
    resumed = twopb.run_test(tiny_sample, LAW_GEN, 10.0, s, out, progress=False)
    np.testing.assert_allclose(resumed["force_N"], full["force_N"], rtol=1e-12, atol=0)
    assert resumed["attrs"]["start"] == "periodic" and len(resumed["force_N"]) == 120
    assert not (tmp_path / "b.h5.ckpt.h5").exists()


def test_settings_validation():
    with pytest.raises(ValueError, match="start"):
        twopb.TwoPBSettings(start="harmonic")
    with pytest.raises(ValueError, match="periodic_cycles"):
        twopb.TwoPBSettings(start="periodic", periodic_cycles=1, window_cycles=2)
    s = twopb.TwoPBSettings(start="periodic", periodic_cycles=1.5, n_cycles=5)
    assert twopb.cycles_of(s) == 1.5 and twopb.cycles_of(s, "rest") == 5
    assert twopb.n_steps_of(10.0, 1e-3, s) == 150 and twopb.n_steps_of(10.0, 1e-3, s, "rest") == 500


def test_mode_settings_start_inheritance():
    camp = {
        "test": {"n_cycles": 5, "start": "rest", "periodic_cycles": 1},
        "paper": {"dt_policy": "fixed"},
        "measured": {"yield_stress_Pa": None, "start": "periodic"},
        "extended": {},
        "dt_study": {},
        "sensitivity": {"start": "periodic"},
        "units_question": {"start": "rest"},
    }
    ms = twopb.mode_settings
    assert ms(camp, "paper")["start"] == "rest" and ms(camp, "paper")["dt_policy"] == "fixed"
    assert ms(camp, "measured")["start"] == "periodic"
    assert ms(camp, "extended")["start"] == "periodic"  # follows the measured mode
    assert ms(camp, "dt_study")["start"] == "rest"  # follows the paper mode
    assert ms(camp, "sensitivity")["start"] == "periodic"  # its own
    assert ms(camp, "units_kPa_nobreak")["yield_stress_Pa"] is None
    camp["extended"]["start"] = "rest"
    assert ms(camp, "extended")["start"] == "rest"
    assert ms(camp, "measured", "barycentre")["bond_kinematics"] == "barycentre"
    for mode in ("paper", "measured", "extended", "dt_study", "sensitivity", "units_kPa"):
        twopb.TwoPBSettings(**ms(camp, mode))  # every mode's settings are valid


def test_periodic_check_cli(tiny_sample, tmp_path):
    import json

    import pandas as pd

    from asphalt_nscd.campaign import cli
    from asphalt_nscd.cli import build_parser, main
    from asphalt_nscd.io import InputError

    def cli_args(cases):
        return build_parser().parse_args(
            ["periodic-check", "--sample", str(tiny_sample), "--cases", *cases, "-o", str(tmp_path / "x.csv")]
        )

    settings = json.dumps(
        {
            "dt_policy": "steps_per_cycle",
            "steps_per_cycle": 40,
            "dt_max_s": 1.0,
            "head_rotation": "clamped",
            "bond_kinematics": "barycentre",
        }
    )
    out = tmp_path / "check.csv"
    assert (
        main(
            [
                "periodic-check",
                "--sample",
                str(tiny_sample),
                "--cases",
                "paper:15:3",
                *set_options(settings),
                "--long-cycles",
                "6",
                "-o",
                str(out),
                "--cycles-table",
                str(tmp_path / "cycles.csv"),
            ]
        )
        == 0
    )
    row = pd.read_csv(out).iloc[0]
    assert row["mode"] == "paper" and row["temperature_C"] == 15 and row["start_periodic_run"] == "periodic"
    assert row["steps_periodic"] == 40 and row["steps_rest"] == 200
    assert len(pd.read_csv(tmp_path / "cycles.csv")) == 6
    with pytest.raises(InputError, match="MODE:T:F"):
        cli._periodic_check(cli_args(cases=["paper:15"]))
    with pytest.raises(InputError, match="--parameters"):
        cli._periodic_check(cli_args(cases=["measured:21:10"]))


@pytest.mark.parametrize("mechanisms", ["free", "supported"])
def test_gravity_state_with_mechanisms_is_exact_on_the_rest_of_the_network(tmp_path, monkeypatch, mechanisms):
    """A sphere hanging by one bond on the side of a lattice (it can roll about the bond's
    contact point: three zero modes of the network) and a second sphere bonded only to it (a
    two-sphere mechanism). The test leaves both out (held_spheres); kept in (as a simulation
    built by hand would), the steady state under gravity solves the rest of the network
    exactly with the weight along the zero modes (found cluster by cluster) either left out
    (free: one period later every bond force is back while the mechanisms fall as they would
    from rest) or cancelled by the support force, which the time domain then applies too
    (supported: every bond force is back and the mechanisms stay in the steady state)."""
    from asphalt_nscd.harmonic import solver
    from asphalt_nscd.sample.lattice import lattice_sample, sample_from_bonds
    from asphalt_nscd.sample.store import write_sample

    base = lattice_sample(40, seed=3, radius_range=(0.9e-3, 1.5e-3), plate_mass=(np.inf, 1e-3))
    b = base.bonds
    k = int(np.argmax(base.position[:, 0]))  # the sphere farthest along +x
    extra = base.position[k] + np.array([2.0 * base.radius[k] + 0.5e-3, 0.0, 0.0])
    extra2 = extra + np.array([2.0 * base.radius[k] + 0.5e-3, 0.0, 0.0])
    n = base.radius.size
    pos = np.vstack([base.position, extra, extra2])
    rad = np.append(base.radius, [base.radius[k], base.radius[k]])
    mass = np.append(base.mass, [base.mass[k], base.mass[k]])
    sample = sample_from_bonds(
        pos,
        rad,
        mass,
        base.plate_point,
        np.append(b["i"], [k, n]),
        np.append(b["j"], [n, n + 1]),
        plate_mass=base.plate_mass,
    )
    path = tmp_path / "mech.h5"
    write_sample(path, sample)
    f = 200.0  # a short period: the mechanisms fall ~0.1 mm in it and touch nothing
    s = twopb.TwoPBSettings(dt_policy="steps_per_cycle", steps_per_cycle=40, dt_max_s=1.0, gravity=True)
    held = solver.held_spheres(read_sample(path))
    assert held[:n].all() and not held[n:].any()  # the two hanging spheres, and only them
    sim, _ = twopb.build_simulation(read_sample(path), LAW_15C, f, twopb.time_step(f, s), s)
    assert sim.n_mechanisms_dropped == 2 and sim.spheres.n == n and len(sim.bonds.i) == len(b["i"])
    assert periodic.periodic_state(sim, LAW_15C, f, s.amplitude_m).gravity.n_mechanisms == 0
    monkeypatch.setattr(solver, "held_spheres", lambda sample, *a, **k: np.ones(sample.radius.size, bool))
    sim, _ = twopb.build_simulation(read_sample(path), LAW_15C, f, twopb.time_step(f, s), s)
    sim.params.linear_tolerance = 1e-13
    state = periodic.periodic_state(sim, LAW_15C, f, s.amplitude_m, s.head_rotation, mechanisms=mechanisms)
    g = state.gravity
    assert g.n_mechanisms >= 3 and not g.failed and g.residual < 1e-9
    assert (np.abs(g.support_force).sum(axis=1) > 0).any() == (mechanisms == "supported")
    assert (np.abs(g.mechanism_acceleration).sum(axis=1) > 0).any() == (mechanisms == "free")
    periodic.apply_periodic_state(sim, state)
    if mechanisms == "supported":
        sim.external_force = g.support_force.copy()
    for _ in range(40):
        assert sim.step().solver == "linear"
    err = np.abs(sim.bonds.force - state.bond_force).max() / np.abs(state.bond_force).max()
    assert err < 1e-8
    fall = np.abs(sim.spheres.velocity[n:] - state.velocity[n:]).max()
    if mechanisms == "free":  # the same start with the weight's whole load on the network is not a steady state
        assert fall > 1e-3  # the mechanisms fall (m/s after one period)
    else:
        assert fall < 1e-6 * max(np.abs(state.velocity).max(), 1e-3)  # supported: they stay
