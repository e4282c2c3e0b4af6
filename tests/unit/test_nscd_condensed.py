"""Contacts in the linear fast path (nscd/condensed.py): the condensed Signorini-Coulomb
problem gives the step the nonlinear Gauss-Seidel gives, sticking and sliding."""

import numpy as np
import pytest

from asphalt_nscd.nscd import NSCDParameters, Simulation
from asphalt_nscd.nscd.linear import LinearBondSolver
from asphalt_nscd.nscd.verify import pressed_sphere_network, random_bonded_network

MU = 0.7


def _sim(push, fast, solver="direct", kinematics="contact", max_contacts=16, tolerance=1e-12):
    s, plates, bonds, force = pressed_sphere_network(push)
    params = NSCDParameters(
        dt=5e-5,
        friction=MU,
        tolerance=tolerance,
        max_iterations=100000,
        gravity=(0, 0, -9.81),
        fast_path=fast,
        linear_solver=solver,
        linear_tolerance=1e-13,
        bond_kinematics=kinematics,
        fast_path_contacts=max_contacts,
    )
    return Simulation(s, plates, bonds, params, external_force=force)


@pytest.mark.kernels
@pytest.mark.parametrize("kinematics", ["contact", "barycentre"])
@pytest.mark.parametrize("solver", ["cg", "cg_ssor", "direct"])
@pytest.mark.parametrize("push", [2.0, 0.3])
def test_condensed_contacts_match_nlgs(push, solver, kinematics):
    """Step by step, a sphere pressed against the side of the bonded block by 2 or 0.3 times
    its weight (sticking and slipping by turns): the fast path keeps the steps with a closed
    contact and gives NLGS's velocities, contact and bond impulses (NLGS at tolerance
    1e-12)."""
    fast = _sim(push, True, solver, kinematics)
    ref = _sim(push, False, kinematics=kinematics)
    n_closed = 0
    for _ in range(40):
        st_f, st_r = fast.step(), ref.step()
        assert st_f.solver == "linear" and st_r.solver == "nlgs"
        assert st_f.n_active_contacts == st_r.n_active_contacts
        n_closed += st_r.n_active_contacts > 0
        v_scale = np.abs(ref.spheres.velocity).max()
        np.testing.assert_allclose(fast.spheres.velocity, ref.spheres.velocity, atol=1e-8 * v_scale)
        np.testing.assert_allclose(
            fast.spheres.angular_velocity,
            ref.spheres.angular_velocity,
            atol=1e-8 * np.abs(ref.spheres.angular_velocity).max(),
        )
        np.testing.assert_allclose(fast.bond_impulse, ref.bond_impulse, atol=1e-8 * np.abs(ref.bond_impulse).max())
        if st_r.n_active_contacts:
            np.testing.assert_array_equal(fast.contact_i, ref.contact_i)
            np.testing.assert_array_equal(fast.contact_j, ref.contact_j)
            np.testing.assert_allclose(
                fast.contact_impulse, ref.contact_impulse, atol=1e-5 * np.abs(ref.contact_impulse).max()
            )
    assert n_closed >= 10  # pressed: the contact is closed most of the time


@pytest.mark.kernels
def test_condensed_contact_obeys_coulomb():
    """Over 200 steps of the pressed sphere (the block under the head's motion) every closed
    contact of the fast path obeys Coulomb's law: |P_t| <= mu P_n, and where the contact
    point slips, |P_t| = mu P_n with P_t opposing the slip. Both regimes occur."""
    sim = _sim(2.0, True)
    n_stick = n_slip = 0
    for _ in range(200):
        assert sim.step().solver == "linear"
        closed = np.flatnonzero(sim.contact_impulse[:, 0] > 0)
        if not len(closed):
            continue
        a = closed[0]
        P = sim.contact_impulse[a]
        pt = np.hypot(P[1], P[2])
        u = np.empty((len(sim.contact_i), 3))
        sim._contact_velocities(
            sim.contact_i,
            sim.contact_j,
            sim.contact_frame,
            sim.spheres.velocity,
            sim.spheres.angular_velocity,
            sim.plates.velocity,
            u,
        )
        ut = u[a, 1:]
        assert pt <= MU * P[0] * (1 + 1e-9)
        if np.linalg.norm(ut) > 1e-9 * np.abs(sim.spheres.velocity).max():
            n_slip += 1
            assert pt == pytest.approx(MU * P[0], rel=1e-9)
            assert np.dot(ut, P[1:]) / (np.linalg.norm(ut) * pt) == pytest.approx(-1.0, abs=1e-6)
        else:
            n_stick += 1
    assert n_stick >= 20 and n_slip >= 5


@pytest.mark.kernels
def test_fast_path_gives_up_beyond_max_contacts():
    """With fast_path_contacts = 0 (the default) a closing contact sends the step to NLGS."""
    sim = _sim(2.0, True, max_contacts=0)
    st = sim.step()
    assert st.n_active_contacts == 1 and st.solver == "nlgs"


@pytest.mark.parametrize("kinematics", ["contact", "barycentre"])
def test_response_columns_solve_the_linear_system(kinematics):
    """LinearBondSolver.response: A^-1 columns from 'cg' and 'cg_ssor' equal the direct
    solve's, and A (direct) applied to them gives the unit vectors."""
    s, plates, bonds = random_bonded_network(n=27)
    rng = np.random.default_rng(0)
    cg = rng.uniform(1.0, 2.0, (bonds.n, 1)) * np.array([[3.0, 1.0, 1.0]])
    rotation = None
    if kinematics == "contact":
        rotation = dict(
            arm_i=bonds.arm_i, arm_j=bonds.arm_j, inv_inertia=s.inv_inertia, inv_inertia_plate=plates.inv_inertia
        )
    solvers = {
        m: LinearBondSolver(
            s.inv_mass,
            plates.inv_mass,
            bonds.i,
            bonds.j,
            bonds.frame,
            cg * 10 * s.mass.mean(),
            bonds.broken,
            method=m,
            tolerance=1e-13,
            rotation=rotation,
        )
        for m in ("direct", "cg", "cg_ssor")
    }
    ref = solvers["direct"]
    nblk = ref.ndof // 3
    for block in (0, nblk // 2, nblk - 1):
        col = ref.response(block)
        e = np.zeros((ref.ndof, 3))
        e[3 * block : 3 * block + 3] = np.eye(3)
        np.testing.assert_allclose(ref.lu.solve(e), col, rtol=0, atol=1e-12 * np.abs(col).max())
        assert ref.response(block) is col  # cached
        for m in ("cg", "cg_ssor"):
            np.testing.assert_allclose(solvers[m].response(block), col, rtol=0, atol=1e-9 * np.abs(col).max())
    with pytest.raises(IndexError, match="unknown block"):
        ref.response(nblk)


@pytest.mark.kernels
def test_local_block_solve_satisfies_signorini_coulomb():
    """local_solve_block on random full 3x3 Delassus blocks, strongly coupled ones included
    (mu |W_nt| > W_nn, where a projected iteration on the diagonal failed): the impulse
    lies in the cone and U = b + W P obeys the law — open with P = 0, sticking with U = 0,
    or sliding with U_n = 0, |P_t| = mu P_n and U_t opposite to P_t."""
    from asphalt_nscd.nscd.condensed import local_solve_block

    rng = np.random.default_rng(7)
    h, kinds = 2e-4, set()
    for trial in range(400):
        Q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        W = Q @ np.diag(10.0 ** rng.uniform(1, 5, 3)) @ Q.T
        b = rng.normal(size=3) * 1e-3
        gap = rng.choice([0.0, -1e-9, 1e-8])
        mu = rng.choice([0.0, 0.3, 0.7])
        pn, pt, ps, ok = local_solve_block(b[0], b[1], b[2], gap, h, W, 0, mu)
        assert ok, (W, b, gap, mu)
        P = np.array([pn, pt, ps])
        U = b + W @ P
        un = U[0] + max(gap, 0.0) / h
        scale = np.abs(b).max() + max(gap, 0) / h
        assert pn >= 0.0 and np.hypot(pt, ps) <= mu * pn * (1 + 1e-9) + 1e-300
        if pn == 0.0:
            kinds.add("open")
            assert un >= 0.0
            continue
        assert abs(un) <= 1e-9 * scale
        if mu == 0.0:  # frictionless: no tangential impulse, any slip
            assert pt == ps == 0.0
            continue
        ut = U[1:]
        if np.linalg.norm(ut) <= 1e-9 * scale:
            kinds.add("stick")
        else:
            kinds.add("slide")
            assert np.hypot(pt, ps) == pytest.approx(mu * pn, rel=1e-9)
            assert np.dot(ut, P[1:]) / (np.linalg.norm(ut) * np.hypot(pt, ps)) == pytest.approx(-1.0, abs=1e-7)
    assert kinds == {"open", "stick", "slide"}


@pytest.mark.kernels
@pytest.mark.parametrize("solver", ["cg", "cg_ssor"])
def test_unconverged_columns_send_the_contact_step_to_nlgs(solver):
    """Where a column of A^-1 (:meth:`LinearBondSolver.response`) does not converge, the
    steps with a closing contact are redone by NLGS, the others stay on the fast path, and
    every step gives NLGS's answer."""
    fast = _sim(2.0, True, solver)
    ref = _sim(2.0, False)
    assert fast.step().solver == "linear"
    ref.step()
    ls = fast._linear
    plain = ls.response

    def one_iteration(block):
        ls._columns.clear()
        keep, ls.max_iterations = ls.max_iterations, 1
        try:
            return plain(block)
        finally:
            ls.max_iterations = keep

    ls.response = one_iteration
    kinds = []
    for _ in range(40):
        st_f, st_r = fast.step(), ref.step()
        kinds.append((st_f.solver, st_r.n_active_contacts > 0))
        np.testing.assert_allclose(
            fast.spheres.velocity, ref.spheres.velocity, atol=1e-8 * np.abs(ref.spheres.velocity).max()
        )
    assert all(k == ("nlgs" if closed else "linear") for k, closed in kinds)
    assert sum(closed for _, closed in kinds) >= 10 and fast.linear_unconverged == 0
