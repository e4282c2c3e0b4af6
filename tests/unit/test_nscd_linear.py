"""Linear fast path: same reactions as NLGS, automatic fallback on contact or breakage."""

import numpy as np
import pytest

from asphalt_nscd.nscd import NSCDParameters, Simulation
from asphalt_nscd.nscd.verify import LAW_15C, random_bonded_network


def _run(
    fast,
    solver="cg",
    n_steps=30,
    contacts=False,
    gravity=(0, 0, 0),
    n=40,
    kick=0.0,
    kinematics="contact",
    bonded_contact="after_break",
):
    law = LAW_15C.scaled(1e-3) if kick else LAW_15C  # soft bonds: the thrown sphere hits
    s, plates, bonds = random_bonded_network(n=n, contacts=contacts, law=law)
    s.velocity[1, 0] = -kick  # sphere 1 thrown at its neighbour 0 (lattice along x)
    if kick:
        bonds.r_crit[:] = np.inf
    params = NSCDParameters(
        dt=5e-5,
        friction=0.7,
        tolerance=1e-11,
        max_iterations=50000,
        gravity=gravity,
        fast_path=fast,
        linear_solver=solver,
        linear_tolerance=1e-13,
        bond_kinematics=kinematics,
        bonded_contact=bonded_contact,
    )
    sim = Simulation(s, plates, bonds, params)
    df = sim.run(n_steps)
    return sim, df


@pytest.mark.kernels
@pytest.mark.parametrize("kinematics", ["contact", "barycentre"])
@pytest.mark.parametrize("solver", ["cg", "cg_ssor", "direct"])
def test_fast_path_matches_nlgs(solver, kinematics):
    sim_f, df_f = _run(True, solver, kinematics=kinematics)
    sim_g, df_g = _run(False, kinematics=kinematics)
    assert (df_f.solver == "linear").all()
    assert (df_g.solver == "nlgs").all()
    scale = np.abs(sim_g.bonds.force).max()
    assert scale > 0
    np.testing.assert_allclose(sim_f.bonds.force, sim_g.bonds.force, atol=1e-8 * scale)
    np.testing.assert_allclose(df_f.plate1_Fx_N, df_g.plate1_Fx_N, atol=1e-8 * np.abs(df_g.plate1_Fx_N).max())
    if kinematics == "contact":  # the rotations are unknowns of the linear path too
        w_scale = np.abs(sim_g.spheres.angular_velocity).max()
        assert w_scale > 0
        np.testing.assert_allclose(sim_f.spheres.angular_velocity, sim_g.spheres.angular_velocity, atol=1e-7 * w_scale)


@pytest.mark.parametrize("kinematics", ["contact", "barycentre"])
def test_direct_cholesky_equals_superlu(kinematics):
    """The two factorisations of the direct fast path (cholespy's Cholesky, the default, and
    SuperLU in symmetric mode) give the same steps to round-off, under gravity with a driven
    head."""
    out = {}
    for fact in ("cholesky", "superlu"):
        s, plates, bonds = random_bonded_network(n=64)
        s.velocity[:] = np.random.default_rng(5).normal(0, 1e-3, s.velocity.shape)
        params = NSCDParameters(
            dt=5e-5,
            gravity=(0, 0, -9.81),
            linear_solver="direct",
            bond_kinematics=kinematics,
            direct_factorisation=fact,
        )
        sim = Simulation(s, plates, bonds, params)
        df = sim.run(20)
        assert (df.solver == "linear").all()
        out[fact] = (bonds.force.copy(), s.velocity.copy(), df.plate1_Fx_N.to_numpy())
    for a, b in zip(out["cholesky"], out["superlu"]):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * np.abs(b).max())
    with pytest.raises(ValueError, match="direct_factorisation"):
        NSCDParameters(dt=5e-5, direct_factorisation="lu")


@pytest.mark.kernels
@pytest.mark.parametrize("bonded_contact", ["always", "open_at_bonding"])
def test_fast_path_falls_back_when_contacts_close(bonded_contact):
    """A sphere thrown at its bonded neighbour (open gap at bonding), with the contact of
    intact bonded pairs enabled: the contact activates, those steps are solved by NLGS (the
    others by the linear path) and agree with a pure NLGS run."""
    sim_f, df_f = _run(True, contacts=True, n_steps=60, kick=5.0, bonded_contact=bonded_contact)
    sim_g, df_g = _run(False, contacts=True, n_steps=60, kick=5.0, bonded_contact=bonded_contact)
    assert (df_f.n_active_contacts > 0).any()
    assert set(df_f.solver[df_f.n_active_contacts > 0]) == {"nlgs"}
    assert (df_f.solver == "linear").any()
    scale = np.abs(sim_g.bonds.force).max()
    np.testing.assert_allclose(sim_f.bonds.force, sim_g.bonds.force, atol=1e-6 * scale)


@pytest.mark.kernels
def test_fast_path_refactorises_after_breakage():
    s, plates, bonds = random_bonded_network(n=27)
    bonds.r_crit[:] = np.inf
    bonds.r_crit[0] = 1e-9  # this bond breaks at the first step
    params = NSCDParameters(dt=5e-5, gravity=(0, 0, -9.81))
    sim = Simulation(s, plates, bonds, params)
    st = sim.step()
    assert st.n_broken == 1 and bonds.broken[0]
    n_before = sim._linear_key
    st = sim.step()
    assert st.solver == "linear"
    assert sim._linear_key != n_before
    assert np.all(bonds.force[0] == 0.0)


def _phase_deg(linear_solver, linear_tolerance, n=1000, f=40.0, dt=5e-5):
    """Phase (deg) of the sphere force on the driven plate of the bench's 2PB-like sample at
    -10 degC (Table 3 read in Pa), fitted over the second cycle of a 40 Hz drive.
    Barycentre kinematics: with the (softer) contact kinematics a few contacts close in this
    sample and those steps go through NLGS, which would mix its tolerance into the test."""
    from asphalt_nscd.nscd.bench import bonded_sample
    from asphalt_nscd.rheology.laws import GeneralizedBurgers

    law = GeneralizedBurgers.burgers(Em=3.98e7, eta_m=6.28e7, Ek=9.56e8, eta_k=1.49e7)
    s, plates, bonds = bonded_sample(n, law=law)
    sim = Simulation(
        s,
        plates,
        bonds,
        NSCDParameters(
            dt=dt, linear_solver=linear_solver, linear_tolerance=linear_tolerance, bond_kinematics="barycentre"
        ),
    )
    df = sim.run(int(round(2 / f / dt)))
    assert (df.solver == "linear").all()
    t = df.time.to_numpy() - dt / 2
    sel = t > 1 / f
    w = 2 * np.pi * f
    basis = np.c_[np.sin(w * t[sel]), np.cos(w * t[sel]), np.ones(sel.sum())]
    c = np.linalg.lstsq(basis, -df.plate1_Fx_N.to_numpy()[sel], rcond=None)[0]
    return np.degrees(np.angle(c[0] + 1j * c[1]))


def test_cg_tolerance_resolves_phase_angle():
    """The conjugate gradient at the configured relative residual 1e-7 gives the phase angle
    of the exact (direct) solve to 1e-3 degree (the target resolution is 0.01 degree)."""
    exact = _phase_deg("direct", 1e-10)
    assert abs(_phase_deg("cg", 1e-7) - exact) < 1e-3


@pytest.mark.kernels
@pytest.mark.parametrize("kinematics", ["contact", "barycentre"])
@pytest.mark.parametrize("top", ["driven", "free", "rotating"])
def test_ssor_cg_matches_direct_solve(kinematics, top):
    """The SSOR-preconditioned conjugate gradient (Eisenstat's form) gives the direct
    (SuperLU) solution of the same step to its tolerance, with fewer iterations than the
    block-Jacobi one; plates as bodies of the triangular solves: a free top plate (3
    unknowns) and a driven top plate that rotates (3 rotation unknowns, 'contact')."""
    from asphalt_nscd.nscd import Plate, Plates

    results = {}
    for solver in ("direct", "cg", "cg_ssor"):
        s, plates, bonds = random_bonded_network(n=64)
        z_top = float(plates.point[1, 2])
        if top == "free":
            plates = Plates([Plate([0, 0, 0], [0, 0, 1]), Plate([0, 0, z_top], [0, 0, -1], mode="free", mass=0.235)])
        elif top == "rotating":
            plates = Plates(
                [
                    Plate([0, 0, 0], [0, 0, 1]),
                    Plate(
                        [0, 0, z_top],
                        [0, 0, -1],
                        mode="driven",
                        mass=0.235,
                        rotation=True,
                        inertia=1e-4,
                        displacement=lambda t: np.array([63e-6 * np.sin(250 * t), 0, 0]),
                    ),
                ]
            )
        s.velocity[:] = np.random.default_rng(3).normal(0, 1e-3, s.velocity.shape)
        params = NSCDParameters(
            dt=5e-5, gravity=(0, 0, -9.81), linear_solver=solver, linear_tolerance=1e-10, bond_kinematics=kinematics
        )
        sim = Simulation(s, plates, bonds, params)
        iters = [sim.step().iterations for _ in range(5)]
        assert sim.step().solver == "linear"
        results[solver] = (
            bonds.force.copy(),
            s.velocity.copy(),
            plates.velocity.copy(),
            plates.angular_velocity.copy(),
            np.mean(iters),
        )
    ref = results["direct"]
    for solver in ("cg", "cg_ssor"):
        got = results[solver]
        for a, b in zip(got[:4], ref[:4]):
            np.testing.assert_allclose(a, b, atol=1e-7 * max(np.abs(b).max(), 1e-30))
    assert results["cg_ssor"][4] < results["cg"][4]


@pytest.mark.kernels
@pytest.mark.parametrize("kinematics", ["contact", "barycentre"])
@pytest.mark.parametrize("omega", [1.0, 1.4])
def test_ssor_structure_reproduces_the_matrix(kinematics, omega):
    """D + L + U assembled from the SSOR structure (body blocks and packed bond entries,
    compact and general) equals the step matrix of the direct path; the relaxed triangular
    solves invert D / omega + L and D / omega + U."""
    from asphalt_nscd.nscd import linear

    s, plates, bonds = random_bonded_network(n=27)
    cg = np.zeros((bonds.n, 3))
    cg[:, 0], cg[:, 1:] = 3e-4, 1e-4
    # lever arms off the normal on a few bonds: general (11-number) entries
    bonds.arm_i[:6] += 0.05 * np.abs(bonds.arm_i[:6]).max() * bonds.frame[:6, 1]
    rot = None
    if kinematics == "contact":
        rot = dict(
            arm_i=bonds.arm_i, arm_j=bonds.arm_j, inv_inertia=s.inv_inertia, inv_inertia_plate=plates.inv_inertia
        )
    direct = linear.LinearBondSolver(
        s.inv_mass, plates.inv_mass, bonds.i, bonds.j, bonds.frame, cg, bonds.broken, method="direct", rotation=rot
    )
    ssor = linear.LinearBondSolver(
        s.inv_mass,
        plates.inv_mass,
        bonds.i,
        bonds.j,
        bonds.frame,
        cg,
        bonds.broken,
        method="cg_ssor",
        rotation=rot,
        ssor_omega=omega,
    )
    ss = dict(zip(linear._SSOR_KEYS, ssor._ssor))
    # compact entries; with rotations also general ones (the bonds with off-normal arms)
    assert len(ss["lcidx"]) > 0 and len(ss["ucidx"]) > 0
    assert (len(ss["uidx"]) > 0 and len(ss["lidx"]) > 0) == (rot is not None)
    assert ss["lcdat"].shape[1] == (7 if rot else 5)
    n = ssor.ndof
    A = np.zeros((n, n))
    for k in range(n):  # columns of A by the matrix-free product
        e = np.zeros(n)
        e[k] = 1.0
        A[:, k] = _matvec_dense(ssor, e)
    # the matrix-free product is the direct path's matrix (its SuperLU factor inverts it)
    x = np.random.default_rng(0).normal(size=n)
    np.testing.assert_allclose(direct.lu.solve(A @ x), x, rtol=1e-8, atol=1e-8 * np.abs(x).max())
    # (D/w + L)^-1 and (D/w + U)^-1 of the SSOR kernels invert the triangular parts of A
    bfirst, bcount = ss["bfirst"], ss["bcount"]
    blocks = np.repeat(np.arange(len(bfirst)), 3 * bcount)
    same = blocks[:, None] == blocks[None, :]
    Dw = np.where(same, A, 0.0) / omega
    DL = Dw + np.where(blocks[:, None] > blocks[None, :], A, 0.0)
    DU = Dw + np.where(blocks[:, None] < blocks[None, :], A, 0.0)
    y = np.zeros(n)
    d = np.zeros(n)
    low = [ss[k] for k in ("lcptr", "lcidx", "lcdat", "lptr", "lidx", "ldat")]
    up = [ss[k] for k in ("ucptr", "ucidx", "ucdat", "uptr", "uidx", "udat")]
    linear._lower_solve(bfirst, bcount, ss["Dinv"], *low, x, y, d)
    np.testing.assert_allclose(DL @ y, x, rtol=1e-9, atol=1e-9 * np.abs(x).max())
    np.testing.assert_allclose(d, Dw @ y, rtol=1e-9, atol=1e-9 * np.abs(d).max())
    linear._upper_solve(bfirst, bcount, ss["Dinv"], *up, x, y, d, 2.0 - omega)
    np.testing.assert_allclose(DU @ y, x, rtol=1e-9, atol=1e-9 * np.abs(x).max())
    np.testing.assert_allclose(d, x - (2.0 - omega) * Dw @ y, rtol=1e-9, atol=1e-9 * np.abs(x).max())


def _matvec_dense(solver, p):
    from asphalt_nscd.nscd import linear

    n = solver.ndof
    q = np.zeros(n)
    linear._matvec(
        solver.mass_dof,
        solver.bdat_c,
        solver.blk_c,
        solver.bdat_g,
        solver.blk_g,
        p.copy(),
        0.0,
        np.zeros(n),
        q,
        0.0,
        np.zeros(n),
    )
    return q


def test_ssor_galerkin_start_reuses_the_products_of_the_last_solutions():
    """cg_ssor: the initial guess combines the last four velocity fields (Galerkin); their
    products with A are those stored with the last solutions (no pass over the bonds), and
    each stored product is bit for bit the product of its solution, so that a solver
    without them (a resumed run) computes the same numbers. A velocity field that is not
    a stored solution (changed between steps) gets its product computed, in each of the four
    steps whose Galerkin start holds it."""

    s, plates, bonds = random_bonded_network(n=40)
    params = NSCDParameters(
        dt=5e-5, friction=0.7, gravity=(0, 0, -9.81), fast_path=True, linear_solver="cg_ssor", linear_tolerance=1e-10
    )
    sim = Simulation(s, plates, bonds, params)
    reused = []
    for _ in range(6):
        assert sim.step().solver == "linear"
        reused.append(sim._linear.last_reused if sim._linear.last_extrapolated else -1)
    assert reused == [-1, 1, 2, 3, 4, 4]  # step 2: the rest state (zero) is not a solution
    ls = sim._linear
    for x, ax in ls._cache:
        np.testing.assert_array_equal(ax, _matvec_dense(ls, x))
    s.velocity[3] += 1e-3  # the start of the next step is no longer a stored solution
    sim.step()
    assert ls.last_reused == 3 and ls.last_residual <= 1e-10
    for _ in range(3):  # the changed field is one of the four of the next three steps
        sim.step()
        assert ls.last_reused == 3
    sim.step()
    assert ls.last_reused == 4


def test_ssor_galerkin_start_cuts_iterations_in_a_smooth_motion():
    """Where the velocities change smoothly (a slow harmonic drive), the Galerkin start
    leaves a smaller residual than the linear extrapolation (which lies in its span): fewer
    iterations than the block-Jacobi CG started from the extrapolation, same solution."""
    runs = {}
    for solver in ("cg", "cg_ssor"):
        s, plates, bonds = random_bonded_network(n=40)
        params = NSCDParameters(
            dt=5e-5, friction=0.7, gravity=(0, 0, 0), fast_path=True, linear_solver=solver, linear_tolerance=1e-10
        )
        sim = Simulation(
            s, plates, bonds, params, external_force=lambda t: np.tile([0.0, 0.0, 1e-3 * np.sin(50 * t)], (40, 1))
        )
        its = [sim.step().iterations for _ in range(40)]
        runs[solver] = (np.array(its), sim.bonds.force.copy())
    scale = np.abs(runs["cg"][1]).max()
    np.testing.assert_allclose(runs["cg_ssor"][1], runs["cg"][1], atol=1e-7 * scale)
    assert runs["cg_ssor"][0][10:].mean() < 0.5 * runs["cg"][0][10:].mean()


@pytest.mark.kernels
@pytest.mark.parametrize("kinematics", ["contact", "barycentre"])
def test_ssor_cg_stops_at_the_accuracy_rounding_allows(kinematics):
    """cg_ssor asked for a residual at or below what double precision can attain (1e-15,
    1e-20): it stops far short of its 10,000 iterations (breakdown, or checks that no longer
    halve the true residual: ssor.STALL_CHECKS), at the direct solution to rounding, and says
    so (a residual above the tolerance). At a reachable tolerance it meets it, checked once or
    twice."""
    from asphalt_nscd.nscd.linear.ssor import _pcg_ssor

    s, plates, bonds = random_bonded_network(n=64)
    params = NSCDParameters(
        dt=5e-5, gravity=(0, 0, -9.81), linear_solver="cg_ssor", linear_tolerance=1e-10, bond_kinematics=kinematics
    )
    sim = Simulation(s, plates, bonds, params)
    assert sim.step().solver == "linear"
    ls = sim._linear
    A = np.column_stack([_matvec_dense(ls, e) for e in np.eye(ls.ndof)])
    rhs = np.random.default_rng(5).normal(size=ls.ndof)
    exact = np.linalg.solve(A, rhs)

    def solve(tol):
        x = np.zeros(ls.ndof)
        it, res, checks = _pcg_ssor(
            ls.op, ls._ssor, rhs, x, tol, 10000, np.zeros((9, ls.ndof)), ls.ssor_omega, np.zeros(ls.ndof), False
        )
        np.testing.assert_allclose(np.linalg.norm(rhs - A @ x) / np.linalg.norm(rhs), res, rtol=1e-6, atol=1e-15)
        return x, it, res, checks

    x, it, res, checks = solve(1e-10)
    assert res <= 1e-10 and checks <= 2
    np.testing.assert_allclose(x, exact, atol=1e-8 * np.abs(exact).max())
    for tol in (1e-15, 1e-20):
        x, it, res, checks = solve(tol)
        assert it < 1000, (tol, it, checks)
        assert res < 1e-12
        np.testing.assert_allclose(x, exact, atol=1e-10 * np.abs(exact).max())
    assert res > 1e-20  # at rounding's floor, reported above the tolerance


@pytest.mark.kernels
@pytest.mark.parametrize("solver", ["cg", "cg_ssor"])
def test_unconverged_linear_solve_sends_the_step_to_nlgs(solver):
    """A conjugate gradient held to one iteration (below what the tolerance needs) is not the
    step's solution: the steps go to NLGS, are counted, and give NLGS's answer; the columns of
    A^-1 refuse the same way and cache nothing."""
    from asphalt_nscd.nscd.linear import LinearSolveError
    from asphalt_nscd.nscd.linear.solver import reached

    assert reached(10, 1e-12, 1e-10, 10) and reached(3, 1e-9, 1e-10, 10)  # met, or stopped early
    assert not reached(10, 1e-9, 1e-10, 10)
    n_steps = 8
    sim_g, df_g = _run(False, n_steps=n_steps)
    s, plates, bonds = random_bonded_network(n=40, law=LAW_15C)
    params = NSCDParameters(
        dt=5e-5,
        friction=0.7,
        tolerance=1e-11,
        max_iterations=50000,
        gravity=(0, 0, 0),
        linear_solver=solver,
        linear_tolerance=1e-13,
        bond_kinematics="contact",
        bonded_contact="after_break",
    )
    sim = Simulation(s, plates, bonds, params)
    assert sim.step().solver == "linear" and sim.linear_unconverged == 0
    ls = sim._linear
    ls.max_iterations = 1
    kinds = [sim.step().solver for _ in range(n_steps - 1)]
    assert kinds == ["nlgs"] * (n_steps - 1) and sim.linear_unconverged == n_steps - 1
    assert not ls.last_converged and ls.last_iterations == 1 and ls.last_residual > ls.tolerance
    scale = np.abs(sim_g.bonds.force).max()
    np.testing.assert_allclose(sim.bonds.force, sim_g.bonds.force, atol=1e-8 * scale)
    with pytest.raises(LinearSolveError, match="block 0, axis 0: relative residual"):
        ls.response(0)
    assert 0 not in ls._columns
    ls.max_iterations = 10000
    assert ls.response(0).shape == (ls.ndof, 3) and 0 in ls._columns
