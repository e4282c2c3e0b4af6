"""Bond kinematics (contact point, 6 DOF per sphere / barycentre, 3 DOF) and head rotation of
the harmonic solver: rigid rotation, axial series and parallel closed forms for every option,
a ladder cantilever against an independent dense assembly and Euler-Bernoulli, the
regularisation of the zero-stiffness modes, and the kinematics study."""

import itertools

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.harmonic.network import network_from_arrays, network_from_sample
from asphalt_nscd.sample.rig import head_inertia
from asphalt_nscd.sample.lattice import lattice_sample, sample_from_bonds
from asphalt_nscd.sample.store import read_sample, write_sample
from asphalt_nscd.harmonic.solver import HarmonicSystem
from asphalt_nscd.rheology.laws import GeneralizedBurgers, bond_scale, tangential_ratio

LAW = GeneralizedBurgers.burgers(Em=2.02e7, eta_m=1.79e6, Ek=2.72e7, eta_k=4.61e5)  # 20 degC
A = 63e-6
RT = tangential_ratio(0.35)
OPTIONS = list(itertools.product(("contact", "barycentre"), ("free", "clamped")))


def axial_network(position, radius, i, j, length, mass=None):
    """Spheres between two plates normal to x (at x = 0 and x = length): the head motion
    (A, 0, 0) loads bonds along their axis. Plate points on the x axis."""
    position = np.asarray(position, float)
    radius = np.broadcast_to(np.asarray(radius, float), (len(position),)).copy()
    i, j = np.asarray(i), np.asarray(j)
    plate_point = np.array([[0.0, 0, 0], [length, 0, 0]])
    plate_normal = np.array([[1.0, 0, 0], [-1.0, 0, 0]])
    l0 = np.empty(len(i))
    r_min = np.empty(len(i))
    for b, (a, c) in enumerate(zip(i, j)):
        if c >= 0:
            l0[b] = np.linalg.norm(position[c] - position[a])
            r_min[b] = min(radius[a], radius[c])
        else:
            l0[b] = abs(position[a, 0] - plate_point[-1 - c, 0])
            r_min[b] = radius[a]
    mass = np.full(len(position), 1e-4) if mass is None else np.asarray(mass, float)
    return network_from_arrays(
        position,
        mass,
        plate_normal,
        [np.inf, 0.235],
        i,
        j,
        l0,
        r_min,
        radius=radius,
        plate_point=plate_point,
        head_size_m=(0.02, 0.02),
    )


def k_of(r_min, l0, omega):
    return bond_scale(r_min, l0) * LAW.complex_modulus(omega)


@pytest.mark.parametrize("kinematics,head", OPTIONS)
def test_single_axial_column_with_mass(kinematics, head):
    # sphere on the head's axis bonded to both plates: (kb + kt - w^2 m) u = kt A, no rotation
    m, f = 2e-3, 400.0
    w = 2 * np.pi * f
    net = axial_network([[6e-3, 0, 0]], 1e-3, [0, 0], [-1, -2], 0.01, mass=[m])
    system = HarmonicSystem(net, bond_kinematics=kinematics, head_rotation=head)
    kb, kt = k_of(1e-3, 6e-3, w), k_of(1e-3, 4e-3, w)
    u = kt * A / (kb + kt - w**2 * m)
    sol = system.solve_law(LAW, f, inertia="full")
    assert sol.reaction[0] == pytest.approx(kt * (A - u), rel=1e-9)
    assert sol.displacement[0, 0] == pytest.approx(u, rel=1e-9)
    assert np.all(np.abs(sol.rotation) < 1e-9 * A / 1e-3)
    assert np.all(np.abs(sol.head_rotation) < 1e-9 * A / 1e-3)


@pytest.mark.parametrize("kinematics,head", OPTIONS)
def test_axial_chain_in_series(kinematics, head):
    x = np.array([1.5, 4.0, 6.5, 8.5]) * 1e-3
    r = np.array([1.0, 1.2, 0.8, 1.0]) * 1e-3
    pos = np.column_stack([x, np.zeros(4), np.zeros(4)])
    net = axial_network(pos, r, [0, 0, 1, 2, 3], [-1, 1, 2, 3, -2], 0.01)
    system = HarmonicSystem(net, bond_kinematics=kinematics, head_rotation=head)
    w = 2 * np.pi * 10.0
    r_min = [r[0], min(r[0], r[1]), min(r[1], r[2]), min(r[2], r[3]), r[3]]
    l0 = [x[0], x[1] - x[0], x[2] - x[1], x[3] - x[2], 0.01 - x[3]]
    expected = A / np.sum(1.0 / k_of(np.array(r_min), np.array(l0), w))
    for solver in ("reuse", "direct"):
        sol = system.solve_law(LAW, 10.0, inertia="none", solver=solver)
        assert sol.reaction[0] == pytest.approx(expected, rel=1e-7)
        assert abs(sol.reaction[1]) < 1e-7 * abs(expected)
        assert abs(sol.reaction[2]) < 1e-7 * abs(expected)


@pytest.mark.parametrize("kinematics,head", OPTIONS)
def test_axial_columns_in_parallel(kinematics, head):
    # two mirrored pairs of one-sphere columns: the head does not rotate, stiffnesses add up
    radii = np.array([0.8, 1.4, 0.8, 1.4]) * 1e-3
    xs = np.array([3.0, 6.0, 3.0, 6.0]) * 1e-3
    pos = np.column_stack([xs, [4e-3, 9e-3, -4e-3, -9e-3], [2e-3, -3e-3, -2e-3, 3e-3]])
    net = axial_network(pos, radii, [0, 0, 1, 1, 2, 2, 3, 3], [-1, -2] * 4, 0.01)
    system = HarmonicSystem(net, bond_kinematics=kinematics, head_rotation=head)
    w = 2 * np.pi * 6.0
    kb, kt = k_of(radii, xs, w), k_of(radii, 0.01 - xs, w)
    sol = system.solve_law(LAW, 6.0, inertia="none")
    assert sol.reaction[0] == pytest.approx(A * np.sum(1 / (1 / kb + 1 / kt)), rel=1e-7)


def pair_system(kinematics):
    pos = np.array([[0.0, 0, 5e-3], [2.2e-3, 1.1e-3, 6.0e-3]])
    radius = np.array([1.0e-3, 1.2e-3])
    path_args = dict(
        position=pos,
        radius=radius,
        mass=np.full(2, 1e-4),
        plate_point=[[0, 0, 0], [0, 0, 0.01]],
        i=[0, 0, 1],
        j=[1, -1, -2],
    )
    return pos, radius, path_args


@pytest.mark.parametrize("kinematics", ["contact", "barycentre"])
def test_rigid_rotation_of_a_bonded_pair(tmp_path, kinematics):
    pos, radius, args = pair_system(kinematics)
    write_sample(tmp_path / "pair.h5", sample_from_bonds(**args))
    system = HarmonicSystem(
        network_from_sample(read_sample(tmp_path / "pair.h5")), bond_kinematics=kinematics, head_rotation="clamped"
    )
    kn = np.array([1.0e5, 0.0, 0.0])  # only the sphere-sphere bond (plate bonds off)
    K = system.blocks(kn, kn * RT)["ff"].toarray().real
    theta = np.array([0.3, -0.7, 0.5]) * 1e-3
    d = system.dof_per_sphere
    q = np.zeros(2 * d)
    for k in range(2):
        q[d * k : d * k + 3] = np.cross(theta, pos[k])  # u = theta x x
        if d == 6:
            q[d * k + 3 : d * k + 6] = theta
    force = (K @ q).reshape(2, d)[:, :3]
    n = (pos[1] - pos[0]) / np.linalg.norm(pos[1] - pos[0])
    if kinematics == "contact":
        assert np.all(np.abs(K @ q) < 1e-12 * kn[0] * 1e-3 * np.abs(theta).max())
    else:  # the tangential spring resists the rotation: (K q)_j = k_t theta x (x_j - x_i)
        expected = RT * kn[0] * np.cross(theta, pos[1] - pos[0])
        assert abs(expected @ n) < 1e-12 * np.linalg.norm(expected)
        np.testing.assert_allclose(force[1], expected, rtol=1e-12)
        np.testing.assert_allclose(force[0], -expected, rtol=1e-12)
    # a rigid translation strains nothing with either kinematics
    t = np.zeros(2 * d)
    for k in range(2):
        t[d * k : d * k + 3] = [1e-6, -2e-6, 3e-6]
    assert np.all(np.abs(K @ t) < 1e-12 * kn[0] * 1e-6)


def skew(a):
    return np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])


def dense_reaction(position, radius, i, j, top_z, kn, kt, head, eps):
    """Independent dense assembly (loops, 6 DOF per body) of the contact kinematics;
    bottom plate at z = 0 fixed, head at (0, 0, top_z) translated by (A, 0, 0)."""
    n_sph = len(position)
    plates = {-1: (np.array([0, 0, 0.0]), np.array([0, 0, 1.0])), -2: (np.array([0, 0, top_z]), np.array([0, 0, -1.0]))}
    ndof = 6 * n_sph + 6  # + head (u, theta)
    K = np.zeros((ndof, ndof), complex)
    for b in range(len(i)):
        a, c = i[b], j[b]
        if c >= 0:
            e = position[c] - position[a]
            dist = np.linalg.norm(e)
            e /= dist
            delta0 = dist - radius[a] - radius[c]
            centre_c = position[c]
            dofs_c = list(range(6 * c, 6 * c + 6))
        else:
            point, normal = plates[c]
            e = -normal
            delta0 = abs((position[a] - point) @ normal) - radius[a]
            centre_c = point
            dofs_c = list(range(6 * n_sph, 6 * n_sph + 6)) if c == -2 else None
        cp = position[a] + (radius[a] + delta0 / 2) * e
        D = np.zeros((6, 6), complex)
        D[:3, :3] = kn[b] * np.outer(e, e) + kt[b] * (np.eye(3) - np.outer(e, e))
        D[3:, 3:] = eps * kn[b] * np.sum((cp - position[a]) ** 2) * np.eye(3)
        La = np.block([[np.eye(3), -skew(cp - position[a])], [np.zeros((3, 3)), np.eye(3)]])
        Lc = np.block([[np.eye(3), -skew(cp - centre_c)], [np.zeros((3, 3)), np.eye(3)]])
        dofs_a = list(range(6 * a, 6 * a + 6))
        K[np.ix_(dofs_a, dofs_a)] += La.T @ D @ La
        if dofs_c is not None:
            K[np.ix_(dofs_c, dofs_c)] += Lc.T @ D @ Lc
            K[np.ix_(dofs_a, dofs_c)] -= La.T @ D @ Lc
            K[np.ix_(dofs_c, dofs_a)] -= Lc.T @ D @ La
    prescribed = list(range(6 * n_sph, 6 * n_sph + 3))
    free = list(range(6 * n_sph)) + (list(range(6 * n_sph + 3, ndof)) if head == "free" else [])
    up = np.array([A, 0, 0])
    uf = np.linalg.solve(K[np.ix_(free, free)], -K[np.ix_(free, prescribed)] @ up)
    return K[np.ix_(prescribed, free)] @ uf + K[np.ix_(prescribed, prescribed)] @ up


def ladder(n_levels, spacing=3e-3, width=3e-3, r=1.2e-3):
    """Two vertical chains x = +-width/2, rungs at every level; the base level bonded to the
    bottom plate, the top level to the head (a cantilever loaded at the head)."""
    z = spacing * (np.arange(n_levels) + 0.5)
    pos = np.concatenate([np.column_stack([np.full(n_levels, s * width / 2), np.zeros(n_levels), z]) for s in (-1, 1)])
    left, right = np.arange(n_levels), n_levels + np.arange(n_levels)
    i = np.concatenate([left[:-1], right[:-1], left, [left[0], right[0], left[-1], right[-1]]])
    j = np.concatenate([left[1:], right[1:], right, [-1, -1, -2, -2]])
    return pos, np.full(2 * n_levels, r), i, j, spacing * n_levels


@pytest.mark.parametrize("head", ["free", "clamped"])
def test_ladder_cantilever_against_dense_assembly(tmp_path, head):
    pos, radius, i, j, top = ladder(5)
    write_sample(
        tmp_path / "ladder.h5", sample_from_bonds(pos, radius, np.full(len(pos), 1e-4), [[0, 0, 0], [0, 0, top]], i, j)
    )
    system = HarmonicSystem(
        network_from_sample(read_sample(tmp_path / "ladder.h5")), bond_kinematics="contact", head_rotation=head
    )
    w = 2 * np.pi * 10.0
    e = LAW.complex_modulus(w)
    kn = system.network.scale * e
    expected = dense_reaction(pos, radius, i, j, top, kn, kn * RT, head, system.regularisation)
    for solver in ("reuse", "direct"):
        sol = system.solve_law(LAW, 10.0, inertia="none", solver=solver)
        np.testing.assert_allclose(sol.reaction, expected, rtol=1e-9, atol=1e-9 * abs(expected[0]))


def test_long_ladder_follows_euler_bernoulli():
    # The tip compliance of a cantilever loaded at a free head is L^3 / (3 EI) + shear and base
    # terms linear in L. Two chains of axial stiffness k_n per spacing s at +-w/2 give
    # EI = k_n s w^2 / 2. The third difference of C(L) on equal steps isolates the L^3 term.
    spacing, width, r = 3e-3, 3e-3, 1.2e-3
    comp = []
    levels = [20, 30, 40, 50]
    for n in levels:
        pos, radius, i, j, top = ladder(n, spacing, width, r)
        l0 = np.array(
            [
                np.linalg.norm(pos[b] - pos[c]) if c >= 0 else (pos[b, 2] if c == -1 else top - pos[b, 2])
                for b, c in zip(i, j)
            ]
        )
        net = network_from_arrays(
            pos,
            np.full(len(pos), 1e-4),
            [[0, 0, 1], [0, 0, -1]],
            [np.inf, 0.235],
            i,
            j,
            l0,
            np.full(len(i), r),
            radius=radius,
            plate_point=[[0, 0, 0], [0, 0, top]],
            head_size_m=(0, 0),
        )
        system = HarmonicSystem(net, bond_kinematics="contact", head_rotation="free")
        sol = system.solve_law(LAW, 1.0, inertia="none", solver="direct")
        g = sol.reaction[0] / (A * LAW.complex_modulus(2 * np.pi))  # K = E* G: stiffness G
        comp.append(1.0 / g.real)
    L = spacing * np.array(levels)
    c3 = comp[3] - 3 * comp[2] + 3 * comp[1] - comp[0]
    l3 = L[3] ** 3 - 3 * L[2] ** 3 + 3 * L[1] ** 3 - L[0] ** 3
    EI = 1.0 * bond_scale(r, spacing) * spacing * width**2 / 2  # E = 1 Pa
    assert c3 / l3 == pytest.approx(1 / (3 * EI), rel=1e-6)  # measured 3e-10
    assert comp[-1] == pytest.approx(L[-1] ** 3 / (3 * EI), rel=0.01)  # shear + base: 0.3 %


def test_regularisation_does_not_change_the_head_force(tmp_path):
    path = tmp_path / "lattice.h5"
    write_sample(path, lattice_sample(150, seed=5))
    net = network_from_sample(read_sample(path))
    forces = []
    for eps in (1e-8, 1e-12):
        system = HarmonicSystem(net, bond_kinematics="contact", head_rotation="free", regularisation=eps)
        forces.append(system.solve_law(LAW, 10.0, inertia="none").reaction[0])
        full = system.solve_law(LAW, 10.0, inertia="full", solver="direct")
        assert full.residual < 1e-10
    assert forces[0] == pytest.approx(forces[1], rel=1e-4)  # measured 2.4e-5
    ratios = []
    for f in (0.1, 30.0):  # K(w) = E*(w) G holds with the regularising spring
        sol = HarmonicSystem(net).solve_law(LAW, f, inertia="none")
        ratios.append(sol.reaction[0] / A / LAW.complex_modulus(2 * np.pi * f))
    assert abs(ratios[0].imag) < 1e-9 * abs(ratios[0].real)
    assert ratios[0] == pytest.approx(ratios[1], rel=1e-9)


def test_rotation_lowers_the_bending_stiffness(tmp_path):
    path = tmp_path / "lattice.h5"
    write_sample(path, lattice_sample(150, seed=5))
    net = network_from_sample(read_sample(path))
    k = {
        opt: HarmonicSystem(net, bond_kinematics=opt[0], head_rotation=opt[1])
        .solve_law(LAW, 10.0, inertia="none")
        .reaction[0]
        .real
        for opt in OPTIONS
    }
    assert k[("contact", "free")] < k[("contact", "clamped")] < k[("barycentre", "clamped")]
    assert k[("barycentre", "free")] < k[("barycentre", "clamped")]


def test_head_inertia_of_a_steel_cuboid():
    inertia = head_inertia(0.235, 0.025, 0.025)
    t = 0.235 / (7850 * 0.025**2)
    assert inertia[2] == pytest.approx(0.235 * 2 * 0.025**2 / 12)
    assert inertia[0] == pytest.approx(0.235 * (0.025**2 + t**2) / 12 + 0.235 * t**2 / 4)
    assert np.all(head_inertia(np.inf, 0.025, 0.025) == 0)


def test_bad_kinematics_options(tmp_path):
    path = tmp_path / "lattice.h5"
    write_sample(path, lattice_sample(20, seed=1))
    net = network_from_sample(read_sample(path))
    with pytest.raises(ValueError, match="bond_kinematics"):
        HarmonicSystem(net, bond_kinematics="centre")
    with pytest.raises(ValueError, match="head_rotation"):
        HarmonicSystem(net, head_rotation="hinged")
    with pytest.raises(ValueError, match="regularisation"):
        HarmonicSystem(net, regularisation=-1.0)


def test_kinematics_study_cli(tmp_path):
    path = tmp_path / "lattice.h5"
    write_sample(path, lattice_sample(60, seed=4))
    params = tmp_path / "params.csv"
    pd.DataFrame(
        {
            "temperature_C": [20.0, 30.0],
            "Em_MPa": [20.2, 13.0],
            "eta_m_MPa_s": [1.79, 0.345],
            "Ek_MPa": [27.2, 9.31],
            "eta_k_MPa_s": [0.461, 0.131],
        }
    ).to_csv(params, index=False)
    out = tmp_path / "study.csv"
    assert (
        main(
            [
                "harmonic-kinematics",
                "--sample",
                str(path),
                "--parameters",
                str(params),
                "--frequency",
                "3",
                "10",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    frame = pd.read_csv(out)
    assert len(frame) == 4 * 2 * 2 * 2  # options x inertia x T x f
    quasi = frame[frame["inertia"] == "none"]
    for _, g in quasi.groupby(["bond_kinematics", "head_rotation"]):
        np.testing.assert_allclose(g["network_factor"], g["network_factor"].iloc[0], rtol=1e-9)
        assert np.all(np.abs(g["phase_difference_deg"]) < 1e-8)
    factor = quasi.groupby(["bond_kinematics", "head_rotation"])["network_factor"].first()
    assert factor["contact", "free"] < factor["barycentre", "clamped"]
    dofs = frame.groupby(["bond_kinematics", "head_rotation"])["n_free_dof"].first()
    assert dofs["contact", "free"] == 2 * dofs["barycentre", "free"] - 3
    assert (
        main(
            [
                "harmonic-kinematics",
                "--sample",
                str(path),
                "--parameters",
                str(params),
                "--frequency",
                "-3",
                "-o",
                str(out),
            ]
        )
        == 2
    )


def test_the_rig_and_the_network_share_the_head():
    """The 2PB rig (sample.rig) and the harmonic network read the same head from a sample: the
    same rotational inertia, from the sample's b_m, e_m or, without them, from the top-plate
    bonds' contact points; a rig holding only some spheres leaves the others out."""
    from asphalt_nscd.nscd import NSCDParameters
    from asphalt_nscd.rheology.laws import GeneralizedBurgers
    from asphalt_nscd.sample import rig
    from asphalt_nscd.sample.lattice import lattice_sample

    sample = lattice_sample(40, seed=3)
    assert "b_m" not in sample.attrs  # the head's footprint from the top-plate bonds' contact points
    inertia = rig.head_inertia_of(sample)
    assert np.all(inertia > 0) and np.array_equal(inertia, network_from_sample(sample).plate_inertia)
    law = GeneralizedBurgers(Em=2.6e10, eta_m=2.6e10, Ek=[7.8e9], eta_k=[1.9e8])
    still = lambda t: (0.0, 0.0, 0.0)  # noqa: E731
    sim = rig.setup(sample, law, still, NSCDParameters(dt=1e-5), "free")
    assert sim.n_mechanisms_dropped == 0 and np.array_equal(sim.plates.inertia[1], inertia)
    held = np.ones(sample.radius.size, bool)
    held[:2] = False
    sim = rig.setup(sample, law, still, NSCDParameters(dt=1e-5), "clamped", held=held)
    assert sim.n_mechanisms_dropped == 2 and sim.spheres.n == sample.radius.size - 2
    with pytest.raises(ValueError, match="held: expected a mask"):
        rig.setup(sample, law, still, NSCDParameters(dt=1e-5), held=held[:-1])
