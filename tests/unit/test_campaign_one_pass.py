"""A 2PB job builds what it needs once: one read of the sample, one harmonic system (besides
the one per pass of :func:`asphalt_nscd.harmonic.solver.held_spheres`), one bond network per
system, and no factorisation it has made before. The counts are of calls (not times), on the
40-sphere lattice sample; they are the minimum of the job's steps, so that a change that builds
something again fails here."""

import functools

import pytest

from asphalt_nscd.campaign import twopb
from asphalt_nscd.rheology.laws import GeneralizedBurgers

LAW_15C = GeneralizedBurgers.burgers(Em=2.43e7, eta_m=3.71e6, Ek=4.84e7, eta_k=7.73e5)

#: settings of the counted jobs (a short periodic start, unbreakable bonds: linear, certified)
BASE = dict(start="periodic", periodic_cycles=1.0, steps_per_cycle=40, checkpoint_every=0, yield_stress_Pa=None)

#: job -> (its settings over BASE, with a rig-state file, the path it takes, the counts)
JOBS = {
    # the orbit: the held spheres' system and the job's, one shifted factor of G - sigma M
    "orbit": (
        {},
        False,
        "orbit",
        {"read_sample": 1, "held_spheres": 1, "HarmonicSystem": 2, "network_from_arrays": 2, "factorise": 1},
    ),
    # under gravity in the time domain at its own dt: one system and one gravity factor of G for both
    # set-ups (the policy's dt for the certificate, the own dt for the steps), a shifted factor per dt
    "time_domain_own_dt_gravity": (
        {"gravity": True, "method": "time_domain", "time_domain_steps_per_cycle": 30},
        False,
        "time_domain",
        {"read_sample": 1, "held_spheres": 1, "HarmonicSystem": 2, "network_from_arrays": 2, "factorise": 3},
    ),
    # the same with the rig state: held spheres, gravity solution and G read, not computed
    "time_domain_own_dt_gravity_rig_state": (
        {"gravity": True, "method": "time_domain", "time_domain_steps_per_cycle": 30},
        True,
        "time_domain",
        {"read_sample": 1, "held_spheres": 0, "HarmonicSystem": 1, "network_from_arrays": 1, "factorise": 2},
    ),
}


def _count_calls(monkeypatch) -> dict:
    """Wrap the sample read, the held spheres, the harmonic system's construction and
    factorisation and the bond network's construction so that each call is counted."""
    import asphalt_nscd.harmonic.network as network
    import asphalt_nscd.harmonic.solver as solver
    import asphalt_nscd.sample.store as store

    counts: dict = {}

    def counted(owner, name, key):
        original = getattr(owner, name)

        @functools.wraps(original)
        def wrapper(*args, **kwargs):
            counts[key] = counts.get(key, 0) + 1
            return original(*args, **kwargs)

        monkeypatch.setattr(owner, name, wrapper)

    counted(store, "read_sample", "read_sample")
    counted(solver, "held_spheres", "held_spheres")
    counted(solver.HarmonicSystem, "__init__", "HarmonicSystem")
    counted(solver.HarmonicSystem, "factorise", "factorise")
    counted(network, "network_from_arrays", "network_from_arrays")
    return counts


@pytest.mark.parametrize("job", sorted(JOBS))
def test_a_job_builds_each_thing_once(job, tiny_sample, tmp_path, monkeypatch):
    over, with_rig_state, path, want = JOBS[job]
    s = twopb.TwoPBSettings(**BASE, **over)
    rig_state = None
    if with_rig_state:
        rig_state = tmp_path / "rig.h5"
        twopb.write_rig_state(tiny_sample, s, rig_state)
    counts = _count_calls(monkeypatch)
    rec = twopb.run_test(tiny_sample, LAW_15C, 10.0, s, tmp_path / "job.h5", progress=False, rig_state=rig_state)
    assert rec["attrs"]["path"] == path and rec["attrs"]["start"] == "periodic"
    assert {k: counts.get(k, 0) for k in want} == want
