"""Delassus blocks, NLGS convergence reporting, driver force, checkpoint/restart, the contacts' warm start."""

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
from asphalt_nscd.nscd.delassus import contact_blocks
from asphalt_nscd.nscd.detection import detect_contacts
from asphalt_nscd.nscd.verify import LAW_15C, random_bonded_network

#: every test here also runs as Python (tests/unit/test_nscd_kernels_python.py)
pytestmark = pytest.mark.kernels


def dense_delassus(
    n_spheres, ci, cj, frames, radius, inv_mass, inv_inertia, inv_mass_plate, rotation=True
) -> np.ndarray:
    """Dense global Delassus operator W = H^T M^-1 H (3C, 3C): the reference the kernel's
    diagonal blocks are checked against (small problems).

    Parameters
    ----------
    ci, cj : (C,) candidate and antagonist (plate ``-1-k``); frames : (C, 3, 3) rows n, t, s.
    rotation : include the lever arms (contacts) or not (bonds, barycentric).
    """
    c = len(ci)
    ndof = 6 * n_spheres + 3 * len(inv_mass_plate)
    H = np.zeros((ndof, 3 * c))
    minv = np.zeros(ndof)
    for s in range(n_spheres):
        minv[6 * s : 6 * s + 3] = inv_mass[s]
        minv[6 * s + 3 : 6 * s + 6] = inv_inertia[s]
    for k in range(len(inv_mass_plate)):
        minv[6 * n_spheres + 3 * k : 6 * n_spheres + 3 * k + 3] = inv_mass_plate[k]
    for a in range(c):
        F = frames[a]
        n = F[0]
        for sign, body, arm in (
            (1.0, ci[a], -radius[ci[a]] * n),
            (-1.0, cj[a], radius[cj[a]] * n if cj[a] >= 0 else None),
        ):
            if body >= 0:
                H[6 * body : 6 * body + 3, 3 * a : 3 * a + 3] = sign * F.T
                if rotation:
                    # torque of a unit impulse along each local axis: arm x e
                    H[6 * body + 3 : 6 * body + 6, 3 * a : 3 * a + 3] = sign * np.cross(arm, F).T
            else:
                k = -1 - body
                H[6 * n_spheres + 3 * k : 6 * n_spheres + 3 * k + 3, 3 * a : 3 * a + 3] = sign * F.T
    return H.T @ (minv[:, None] * H)


def test_contact_blocks_equal_dense_delassus_diagonal():
    rng = np.random.default_rng(0)
    pos = np.array([[0, 0, 0.01], [0.019, 0.002, 0.012], [0.0, 0.02, 0.011]])
    rad = np.array([0.01, 0.009, 0.011])
    s = Spheres.from_density(pos, rad, 2600.0)
    plates = Plates([Plate([0, 0, 0], [0, 0, 1], mode="free", mass=0.3)])
    ci, cj, gap, frame = detect_contacts(s.position, s.radius, plates.point, plates.normal, 0.005)
    assert len(ci) >= 4
    W = dense_delassus(s.n, ci, cj, frame, s.radius, s.inv_mass, s.inv_inertia, plates.inv_mass)
    wn, wt = np.empty(len(ci)), np.empty(len(ci))
    contact_blocks(ci, cj, s.inv_mass, s.inv_inertia, s.radius, plates.inv_mass, wn, wt)
    for a in range(len(ci)):
        blk = W[3 * a : 3 * a + 3, 3 * a : 3 * a + 3]
        np.testing.assert_allclose(blk, np.diag([wn[a], wt[a], wt[a]]), rtol=1e-12, atol=1e-12 * wt[a])
    assert rng is not None


def test_step_reports_iterations_and_residual():
    s = Spheres.from_density([[0, 0, 0.01], [0, 0, 0.03]], [0.01, 0.01], 2600.0)
    sim = Simulation(s, Plates([Plate([0, 0, 0], [0, 0, 1])]), None, NSCDParameters(dt=1e-4, tolerance=1e-9))
    df = sim.run(20)
    assert (df.iterations >= 1).all() and df.converged.all()
    assert (df.residual_quad <= 1e-9).all() and (df.residual_max <= 1e-9).all()
    assert df.n_active_contacts.iloc[-1] == 2


def test_driver_force_includes_plate_inertia():
    """Free sphere-less driven plate: the driver force is m a (minus gravity)."""
    s = Spheres.from_density([[0, 0, 1.0]], [0.01], 2600.0)  # far away
    amp, w, m = 1e-3, 2 * np.pi * 5, 0.235
    plates = Plates(
        [
            Plate(
                [0, 0, 0],
                [0, 0, 1],
                mode="driven",
                mass=m,
                displacement=lambda t: np.array([amp * np.sin(w * t), 0, 0]),
            )
        ]
    )
    sim = Simulation(s, plates, None, NSCDParameters(dt=1e-4, gravity=(0, 0, 0)))
    df = sim.run(400)
    t = df.time.to_numpy()
    # theta-average (theta = 0.5) of the exact acceleration over the step [t - dt, t]
    expected = -m * amp * w**2 * 0.5 * (np.sin(w * t) + np.sin(w * (t - 1e-4)))
    np.testing.assert_allclose(df.plate0_driver_Fx_N.to_numpy()[1:], expected[1:], atol=1e-5 * m * amp * w**2)


def _plate_bonded_to_fixed_sphere(mass, law, amp, omega, dt):
    s = Spheres(position=[[0, 0, 0.003]], radius=[0.0025], mass=[np.inf], inertia=[np.inf])
    plates = Plates(
        [
            Plate(
                [0, 0, 0.006],
                [0, 0, -1],
                mode="driven",
                mass=mass,
                displacement=lambda t: np.array([amp * np.sin(omega * t), 0, 0]),
            )
        ]
    )
    bonds = Bonds.create(s, plates, [0], [-1], law)
    return Simulation(s, plates, bonds, NSCDParameters(dt=dt, gravity=(0, 0, 0)))


def test_driver_force_of_bonded_plate_matches_closed_form():
    """Plate (0.235 kg) driven at u = A sin(wt), 40 Hz, dt = 5e-5 s, bonded to an immobile
    sphere: in steady state F = (k_t*(w) - m w^2) u, k_t* = a E*(w) / (2 (1 + nu)). The
    driver force (reported at the step midpoint) matches to 1e-4 in relative amplitude
    and 0.01 degree in phase; the former first-order inertia term was off by
    m w^2 A w dt / 2 (6e-3 N here, 3e-3 relative)."""
    from asphalt_nscd.rheology.laws import GeneralizedBurgers

    # Maxwell dashpot ~rigid, Kelvin-Voigt time 2 ms: transients gone after 0.15 s
    law = GeneralizedBurgers.burgers(Em=2.43e7, eta_m=1e14, Ek=4.84e7, eta_k=4.84e7 * 2e-3)
    f, amp, m, dt = 40.0, 63e-6, 0.235, 5e-5
    w = 2 * np.pi * f
    sim = _plate_bonded_to_fixed_sphere(m, law, amp, w, dt)
    df = sim.run(int(round(0.2 / dt)))
    t = df.time.to_numpy() - dt / 2
    sel = t > 0.2 - 2 / f
    basis = np.c_[np.sin(w * t[sel]), np.cos(w * t[sel])]
    c = np.linalg.lstsq(basis, df.plate0_driver_Fx_N.to_numpy()[sel], rcond=None)[0]
    numerical = c[0] + 1j * c[1]
    k_t = sim.bonds.Km[0, 1] / law.Em * complex(law.complex_modulus(w))
    exact = (k_t - m * w**2) * amp
    assert abs(numerical - exact) <= 1e-4 * abs(exact)
    assert abs(np.degrees(np.angle(numerical / exact))) <= 0.01


def test_driver_force_of_infinite_mass_plate_is_the_sphere_force():
    """A driven plate of infinite mass: driver force = -plate_force, no inf*0 warning."""
    sim = _plate_bonded_to_fixed_sphere(np.inf, LAW_15C, 63e-6, 2 * np.pi * 40, 5e-5)
    df = sim.run(20)
    drv = df.plate0_driver_Fx_N.to_numpy()
    assert np.all(np.isfinite(drv)) and np.abs(drv).max() > 0
    np.testing.assert_array_equal(drv, -df.plate0_Fx_N.to_numpy())


def test_checkpoint_restart_is_exact(tmp_path):
    def make():
        s, plates, bonds = random_bonded_network(n=27)
        return Simulation(s, plates, bonds, NSCDParameters(dt=5e-5))

    ref = make()
    ref.run(20)
    sim = make()
    sim.run(10)
    write_checkpoint(sim, tmp_path / "ck.h5")
    drivers = sim.plates.drivers
    back = read_checkpoint(tmp_path / "ck.h5", drivers=drivers)
    assert back.step_index == 10 and back.time == pytest.approx(sim.time)
    back.run(10)
    np.testing.assert_array_equal(back.spheres.position, ref.spheres.position)
    np.testing.assert_array_equal(back.bonds.force, ref.bonds.force)
    np.testing.assert_array_equal(back.bonds.delta_k, ref.bonds.delta_k)


def test_bonds_create_micro_parameters():
    s = Spheres(position=[[0, 0, 0], [0.005, 0, 0]], radius=[0.002, 0.0015], mass=[1, 1], inertia=[1, 1])

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


def test_warm_start_is_the_previous_impulse_in_the_new_frame_inside_the_cone():
    """The warm start of the contacts (gauss_seidel.warm_impulses): a matched contact takes the previous
    impulse as a global vector, projected on its new frame and kept in the friction cone; an unmatched one
    stays zero. Checked bit for bit against the vectorized NumPy form (einsum) it replaced, whose sums the
    chaotic deposition's trajectory depends on, and against the cone's definition."""
    import numba

    from asphalt_nscd.nscd import gauss_seidel

    rng = np.random.default_rng(7)
    m, c, mu = 400, 300, 0.4
    old_P = rng.normal(size=(m, 3)) + [2.0, 0.0, 0.0]
    old_F = np.linalg.qr(rng.normal(size=(m, 3, 3)))[0]
    src = rng.integers(-1, m, size=c)
    # frames turned a little since the previous step, as between two steps; some turned away entirely
    new_F = np.linalg.qr(old_F[np.maximum(src, 0)] + 0.1 * rng.normal(size=(c, 3, 3)))[0]
    new_F[::7] = np.linalg.qr(rng.normal(size=(len(new_F[::7]), 3, 3)))[0]
    out = np.zeros((c, 3))
    gauss_seidel.warm_impulses(src, old_P, old_F, new_F, mu, out)

    hit = src >= 0
    ref = np.zeros((c, 3))
    g = np.einsum("ac,acd->ad", old_P[src[hit]], old_F[src[hit]])
    ref[hit] = np.einsum("acd,ad->ac", new_F[hit], g)
    pn = np.maximum(ref[:, 0], 0.0)
    pt = np.hypot(ref[:, 1], ref[:, 2])
    scale = np.where(pt > mu * pn, mu * pn / np.maximum(pt, 1e-300), 1.0)
    ref = np.column_stack([pn, ref[:, 1] * scale, ref[:, 2] * scale])
    assert np.allclose(out, ref, rtol=4e-16, atol=0.0)
    if not numba.config.DISABLE_JIT:  # as Python, math.hypot is CPython's own (correctly rounded), not libm's
        assert np.array_equal(out, ref)
    assert np.all(out[~hit] == 0.0)
    assert np.all(out[:, 0] >= 0.0)
    assert np.all(np.hypot(out[:, 1], out[:, 2]) <= mu * out[:, 0] * (1 + 1e-12))
    # inside the cone the impulse is the old one turned into the new frame: its global vector is kept
    inside = hit & (scale == 1.0) & (pn > 0)
    assert inside.sum() > 50 and (hit & (scale < 1.0)).sum() > 10
    back = np.einsum("ac,acd->ad", out[inside], new_F[inside])
    assert np.allclose(back, np.einsum("ac,acd->ad", old_P[src[inside]], old_F[src[inside]]), rtol=0, atol=1e-12)
