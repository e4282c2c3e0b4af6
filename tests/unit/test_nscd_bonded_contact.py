"""An intact bonded pair is not a contact (NSCDParameters.bonded_contact = 'after_break'):
detection skips it, a bonded sphere cut by a plate plane keeps the linear fast path, and
the contact (Signorini) appears once the bond breaks."""

import h5py
import numpy as np
import pytest

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
from asphalt_nscd.nscd import detection
from asphalt_nscd.nscd.verify import LAW_15C

#: every test here also runs as Python (tests/unit/test_nscd_kernels_python.py)
pytestmark = pytest.mark.kernels

R = 2e-3
RHO = 2600.0


def test_detection_skips_excluded_pairs_only():
    rng = np.random.default_rng(7)
    pos = rng.uniform(0, 0.03, (250, 3))
    rad = rng.uniform(1e-3, 2e-3, 250)
    pts = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.03]])
    nrm = np.array([[0, 0, 1.0], [0, 0, -1.0]])
    ci, cj, _, _ = detection.detect_contacts(pos, rad, pts, nrm, 1e-3)
    every = set(zip(ci.tolist(), cj.tolist()))
    sph = [p for p in every if p[1] >= 0]
    plt = [p for p in every if p[1] < 0]
    drop = sph[::3] + plt[::2] + [(0, 1)]  # (0, 1) need not be a candidate
    ex = detection.bonded_exclusions(len(rad), 2, [p[0] for p in drop], [p[1] for p in drop])
    ci2, cj2, gap2, frame2 = detection.detect_contacts(pos, rad, pts, nrm, 1e-3, ex)
    kept = set(zip(ci2.tolist(), cj2.tolist()))
    assert kept == every - set(drop)
    assert len(kept) < len(every)
    # an excluded pair given as (j, i) is excluded too (the CSR holds both directions)
    ex_rev = detection.bonded_exclusions(len(rad), 2, [p[1] for p in sph[::3]], [p[0] for p in sph[::3]])
    ci3, cj3, _, _ = detection.detect_contacts(pos, rad, pts, nrm, 1e-3, ex_rev)
    assert set(zip(ci3.tolist(), cj3.tolist())) == every - set(sph[::3])
    # the Verlet list follows a new exclusion set at once
    cl = detection.CandidateList(1e-3)
    cl.set_exclusions(ex)
    assert set(zip(*[a.tolist() for a in cl.contacts(pos, rad, pts, nrm)[:2]])) == kept
    cl.set_exclusions(None)
    assert set(zip(*[a.tolist() for a in cl.contacts(pos, rad, pts, nrm)[:2]])) == every


def test_bonded_exclusions_rejects_bad_indices():
    with pytest.raises(ValueError, match="out of range"):
        detection.bonded_exclusions(3, 1, [0], [-2])
    with pytest.raises(ValueError, match="out of range"):
        detection.bonded_exclusions(3, 1, [0], [3])
    with pytest.raises(ValueError, match="bonded_contact"):
        NSCDParameters(dt=1e-4, bonded_contact="sometimes")


def _sphere_on_plate(z=0.75 * R, r_crit=None):
    """One sphere of radius R whose centre is z above a fixed plate (z < R: the sphere
    crosses the plane), bonded to it."""
    m = 4.0 / 3.0 * np.pi * R**3 * RHO
    s = Spheres(position=[[0.0, 0.0, z]], radius=[R], mass=[m], inertia=[0.4 * m * R**2])
    plates = Plates([Plate([0, 0, 0], [0, 0, 1], mode="fixed")])
    b = Bonds.create(s, plates, [0], [-1], LAW_15C)
    if r_crit is not None:
        b.r_crit[:] = r_crit
    return s, plates, b


@pytest.mark.parametrize("kinematics", ["contact", "barycentre"])
def test_bonded_sphere_cut_by_plate_is_not_a_contact(kinematics):
    s, plates, b = _sphere_on_plate()
    assert b.delta0[0] < 0
    sim = Simulation(s, plates, b, NSCDParameters(dt=5e-5, bond_kinematics=kinematics))
    df = sim.run(20)
    assert (df.n_contacts == 0).all()
    assert (df.solver == "linear").all()
    assert s.position[0, 2] < 0.75 * R  # the bond alone carries the weight: it sinks
    # the former behaviour: the overlapping pair is a closed contact, every step NLGS
    s, plates, b = _sphere_on_plate()
    sim = Simulation(s, plates, b, NSCDParameters(dt=5e-5, bond_kinematics=kinematics, bonded_contact="always"))
    df = sim.run(20)
    assert (df.n_active_contacts == 1).all()
    assert (df.solver == "nlgs").all()


def test_contact_appears_when_the_bond_breaks_and_signorini_holds():
    """Weight plus a growing downward push F(t) = -m g t / t1 on the bonded sphere cut by the
    plate: the bond breaks (R_crit = 3 m g), the sphere-plate contact appears at the next
    step and holds the sphere (Signorini with the initial overlap: no further sinking)."""
    m = 4.0 / 3.0 * np.pi * R**3 * RHO
    h, th, t1 = 5e-5, 0.5, 5e-3
    s, plates, b = _sphere_on_plate(r_crit=3.0 * m * 9.81)

    def push(t):
        return np.array([[0.0, 0.0, -m * 9.81 * t / t1]])

    sim = Simulation(s, plates, b, NSCDParameters(dt=h, theta=th, tolerance=1e-12), external_force=push)
    rows = []
    for _ in range(300):
        st = sim.step()
        rows.append(
            (
                st.n_broken_total,
                st.n_contacts,
                st.n_active_contacts,
                st.solver,
                s.position[0, 2],
                s.velocity[0, 2],
                sim.contact_impulse.copy(),
                sim.time,
            )
        )
    broken = np.array([r[0] for r in rows])
    k_break = int(np.argmax(broken > 0))
    assert broken[-1] == 1 and 10 < k_break < 250  # broke after some steps of loading
    assert all(r[1] == 0 and r[3] == "linear" for r in rows[:k_break])  # no contact while intact
    assert all(r[1] == 1 and r[2] == 1 and r[3] == "nlgs" for r in rows[k_break + 1 :])
    # from the second contact step on the sphere is at rest on the plate (U_n = 0, no
    # further penetration) and the impulse balances weight and push over the step
    z = np.array([r[4] for r in rows[k_break + 2 :]])
    vz = np.array([r[5] for r in rows[k_break + 2 :]])
    np.testing.assert_allclose(vz, 0.0, atol=1e-12)
    np.testing.assert_allclose(z, z[0], rtol=0, atol=1e-15)
    t = rows[-1][7]
    f_theta = th * push(t)[0, 2] + (1 - th) * push(t - h)[0, 2]
    np.testing.assert_allclose(rows[-1][6][0, 0], (m * 9.81 - f_theta) * h, rtol=1e-9)


def test_sphere_pair_contact_after_break():
    """Two spheres pushed together: while bonded ('after_break') they interpenetrate under
    the bond law alone; after breaking, Signorini stops them."""
    m = 4.0 / 3.0 * np.pi * R**3 * RHO
    pos = np.array([[0.0, 0.0, 0.0], [2 * R + 1e-4, 0.0, 0.0]])
    s = Spheres(position=pos, radius=[R, R], mass=[np.inf, m], inertia=[np.inf, 0.4 * m * R**2])
    b = Bonds.create(s, Plates([]), [1], [0], LAW_15C.scaled(1e-3))
    b.r_crit[:] = np.inf
    push = np.array([[0, 0, 0], [-5e-2, 0, 0]])
    sim = Simulation(s, None, b, NSCDParameters(dt=5e-5, gravity=(0, 0, 0), tolerance=1e-12), external_force=push)
    df = sim.run(300)
    gap = np.linalg.norm(s.position[1] - s.position[0]) - 2 * R
    assert gap < 0 and (df.n_contacts == 0).all() and (df.solver == "linear").all()
    b.broken[:] = True  # the bond breaks: the overlapping pair becomes a contact
    df = sim.run(50)
    assert (df.n_active_contacts == 1).all()
    assert abs(s.velocity[1, 0]) < 1e-12  # U_n = 0 under the push: Signorini holds


def test_open_at_bonding_and_checkpoint(tmp_path):
    """'open_at_bonding' skips only the intact pairs that overlapped at bonding; the policy
    is checkpointed, and a checkpoint without it restarts with the former behaviour."""
    m = 4.0 / 3.0 * np.pi * R**3 * RHO
    pos = np.array([[0.0, 0.0, 0.75 * R], [0.0, 0.0, 0.75 * R + 2 * R + 5e-4]])
    s = Spheres(position=pos, radius=[R, R], mass=[m, m], inertia=[0.4 * m * R**2] * 2)
    plates = Plates([Plate([0, 0, 0], [0, 0, 1], mode="fixed")])
    b = Bonds.create(s, plates, [0, 1], [-1, 0], LAW_15C)
    assert b.delta0[0] < 0 < b.delta0[1]
    p = NSCDParameters(dt=5e-5, bonded_contact="open_at_bonding")
    sim = Simulation(s, plates, b, p)
    np.testing.assert_array_equal(sim.excluded_bonds(), [True, False])
    st = sim.step()
    assert st.n_contacts == 1  # the open sphere pair only, not the overlapping plate pair
    assert sorted([sim.contact_i[0], sim.contact_j[0]]) == [0, 1]
    write_checkpoint(sim, tmp_path / "ck.h5")
    assert read_checkpoint(tmp_path / "ck.h5").params.bonded_contact == "open_at_bonding"
    with h5py.File(tmp_path / "ck.h5", "a") as f:
        del f["params"].attrs["bonded_contact"]
    assert read_checkpoint(tmp_path / "ck.h5").params.bonded_contact == "always"
    b.broken[:] = [True, False]
    np.testing.assert_array_equal(sim.excluded_bonds(), [False, False])
