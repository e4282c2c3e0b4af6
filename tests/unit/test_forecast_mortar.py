"""The mortar's micromechanics against its limits: the Krieger-Dougherty closed form, the dilute
(Einstein, Eshelby) limit, the Hashin-Shtrikman bounds, the stone as the upper limit, air voids
softening it, and the integration against an independent stiff integrator."""

from __future__ import annotations

import numpy as np
import pytest

from asphalt_nscd.forecast import mortar
from asphalt_nscd.forecast.mortar import Constituents, Inclusion, differential_scheme, hashin_shtrikman

KS, GS = mortar.shear_bulk(55e9, 0.2)


@pytest.mark.parametrize("phi, phi_max", [(0.1, 1.0), (0.3, 1.0), (0.5, 0.64), (0.6, 0.64), (0.7, 0.8)])
def test_rigid_spheres_in_an_incompressible_matrix_follow_krieger_dougherty(phi, phi_max):
    """G / G_m = (1 - phi / phi_max)^(-2.5 phi_max) (Krieger & Dougherty 1959) for rigid spheres
    in an incompressible matrix: the scheme's closed form, to 1e-8."""
    K, G = differential_scheme(1e15, 1.0, [Inclusion(1e22, 1e22, phi)], phi_max)
    assert G.real == pytest.approx((1.0 - phi / phi_max) ** (-2.5 * phi_max), rel=1e-8)
    assert abs(G.imag) < 1e-12


@pytest.mark.parametrize("ratio", [1e-3, 0.3, 3.0, 1e3])
def test_the_dilute_limit_is_eshelbys(ratio):
    """At phi -> 0 the estimate's slope is Eshelby's dilute one (Einstein's 2.5 for rigid spheres
    in an incompressible matrix), for soft and stiff inclusions: error O(phi^2)."""
    Km, Gm = 3e9, 1e9 + 2e8j
    Ki, Gi = ratio * 3e9, ratio * 1e9
    for phi in (1e-3, 5e-4):
        K, G = differential_scheme(Km, Gm, [Inclusion(Ki, Gi, phi)], 0.7)
        Kd, Gd = mortar.dilute(Km, Gm, Ki, Gi, phi)
        assert abs(G - Gd) / abs(Gd - Gm) < 5 * phi
        assert abs(K - Kd) / abs(Kd - Km) < 5 * phi


@pytest.mark.parametrize("contrast", [1.5, 20.0, 1e3, 1e6])
def test_norris_scheme_lies_inside_the_hashin_shtrikman_bounds(contrast):
    """phi_max = 1 (Norris 1985) is a realizable composite: inside the bounds at every fraction,
    for soft and stiff inclusions (elastic phases)."""
    Kb, Gb = 3e9 / contrast, 1e9 / contrast
    for phi in np.linspace(0.02, 0.9, 12):
        K, G = differential_scheme(Kb, Gb, [Inclusion(KS, GS, phi)], 1.0)
        (Kl, Gl), (Ku, Gu) = hashin_shtrikman(np.array([Kb, KS]), np.array([Gb, GS]), np.array([1 - phi, phi]))
        assert Gl * (1 - 1e-9) <= G.real <= Gu * (1 + 1e-9)
        assert Kl * (1 - 1e-9) <= K.real <= Ku * (1 + 1e-9)


def test_hashin_shtrikman_limits():
    """Equal phases give the phase; a void phase gives a zero lower bound; the bounds bracket the
    Voigt-Reuss-free two-phase values and coincide at the pure phases."""
    (Kl, Gl), (Ku, Gu) = hashin_shtrikman(np.array([2.0, 2.0]), np.array([1.0, 1.0]), np.array([0.3, 0.7]))
    assert (Kl, Gl, Ku, Gu) == pytest.approx((2.0, 1.0, 2.0, 1.0))
    (Kl, Gl), (Ku, Gu) = hashin_shtrikman(np.array([0.0, KS]), np.array([0.0, GS]), np.array([0.2, 0.8]))
    assert Kl == 0.0 and Gl == 0.0 and 0 < Gu < GS
    (Kl, Gl), (Ku, Gu) = hashin_shtrikman(np.array([1e9, KS]), np.array([3e8, GS]), np.array([0.0, 1.0]))
    assert Gl == pytest.approx(GS) and Gu == pytest.approx(GS)


def test_the_mortar_stays_inside_the_bounds_and_below_the_stone():
    """The mortar of a mix (filler, air, fine aggregate near its packing limit), for a binder from
    glassy to fluid: its |E*| below the stone's E at every condition, and in the elastic case
    (a real binder) between the Hashin-Shtrikman bounds of its phases (the cap acts near packing)."""
    c = Constituents(fine_packing=0.72)
    vol = {"binder": 0.11, "filler": 0.05, "air": 0.07, "fine": 0.40}
    G = np.geomspace(1e2, 1.2e9, 40)
    for delta in (0.0, 30.0, 85.0):
        m = mortar.mortar_moduli(G, np.full(G.size, delta), vol, c)
        E = mortar.young(*m["mortar"])
        assert np.all(np.abs(E) <= c.E_stone_Pa * (1 + 1e-12))
        assert np.all(np.diff(np.abs(E)) > 0)
    m = mortar.mortar_moduli(G, np.zeros(G.size), vol, c)
    Kb = c.K_binder_Pa
    total = sum(vol.values())
    (Kl, Gl), (Ku, Gu) = hashin_shtrikman(
        np.array([np.full(G.size, Kb), np.zeros(G.size), np.full(G.size, KS)]),
        np.array([G, np.zeros(G.size), np.full(G.size, GS)]),
        np.array(
            [
                np.full(G.size, vol["binder"] / total),
                np.full(G.size, vol["air"] / total),
                np.full(G.size, (vol["filler"] + vol["fine"]) / total),
            ]
        ),
    )
    Gm = m["mortar"][1].real
    assert np.all(Gm >= Gl * (1 - 1e-9)) and np.all(Gm <= Gu * (1 + 1e-9))


def test_air_voids_soften_the_mortar():
    """More air (at the same binder, filler and fine aggregate) gives a softer mortar at every condition."""
    G, d = np.geomspace(1e3, 1e9, 12), np.linspace(80, 10, 12)
    E = [
        np.abs(
            mortar.young(
                *mortar.mortar_moduli(G, d, {"binder": 0.11, "filler": 0.05, "air": a, "fine": 0.35})["mortar"]
            )
        )
        for a in (0.02, 0.05, 0.09)
    ]
    assert np.all(E[0] > E[1]) and np.all(E[1] > E[2])


def test_the_integration_matches_an_independent_stiff_integrator():
    """The Runge-Kutta integration in compliances against SciPy's implicit Radau on the moduli
    themselves (voids in a nearly incompressible binder: the stiff case), to 1e-7."""
    from scipy.integrate import solve_ivp

    Kb, Gb = 3e9 + 0j, 1e4 * np.exp(1j * np.radians(80.0))
    for Ki, Gi, phi, pm in ((0.0, 0.0, 0.25, 1.0), (KS, GS, 0.6, 0.75)):
        K, G = differential_scheme(Kb, Gb, [Inclusion(Ki, Gi, phi)], pm)

        def rate(_, y):
            k, g = complex(y[0], y[1]), complex(y[2], y[3])
            z = g * (9 * k + 8 * g) / (6 * (k + 2 * g))
            dk = (Ki - k) * (k + 4 * g / 3) / (Ki + 4 * g / 3) * pm
            dg = (Gi - g) * (g + z) / (Gi + z) * pm
            return [dk.real, dk.imag, dg.real, dg.imag]

        scale = np.array([1e9, 1e9, 1e4, 1e4])
        sol = solve_ivp(
            lambda t, y: np.array(rate(t, y * scale)) / scale,
            (0, -np.log1p(-phi / pm)),
            np.array([Kb.real, Kb.imag, Gb.real, Gb.imag]) / scale,
            method="Radau",
            rtol=1e-11,
            atol=1e-14,
        )
        y = sol.y[:, -1] * scale
        assert complex(y[2], y[3]) == pytest.approx(G, rel=1e-7)
        assert complex(y[0], y[1]) == pytest.approx(K, rel=1e-6)


def test_a_fraction_at_its_packing_limit_is_refused():
    with pytest.raises(ValueError, match="packing limit"):
        differential_scheme(3e9, 1e9, [Inclusion(KS, GS, 0.7)], 0.7)
    assert Constituents().outside_ranges() == []
    assert Constituents(E_stone_Pa=4.2e9).outside_ranges() == ["E_stone_Pa"]


def test_air_in_the_mortar_is_the_dense_mortar_made_porous():
    """air_phase="mortar": without air it is the default mortar exactly (the same stages); with air it is
    the dense mortar (fine aggregate in the dense mastic, inside its Hashin-Shtrikman bounds, below the stone)
    softened by the voids at every condition, more air softer; an unknown phase is refused."""
    c = Constituents(fine_packing=0.80)
    G, d = np.geomspace(1e3, 1e9, 12), np.linspace(80, 10, 12)
    vol = {"binder": 0.11, "filler": 0.05, "air": 0.0, "fine": 0.40}
    a = mortar.mortar_moduli(G, d, vol, c, "mastic")["mortar"]
    b = mortar.mortar_moduli(G, d, vol, c, "mortar")["mortar"]
    np.testing.assert_allclose(b, a, rtol=1e-12)
    dense = mortar.young(*b)
    E = []
    for air in (0.03, 0.06):
        m = mortar.mortar_moduli(G, d, {**vol, "air": air}, c, "mortar")
        assert m["phi_air"] == pytest.approx(air / (0.56 + air)) and m["phi_fine"] == pytest.approx(0.40 / 0.56)
        np.testing.assert_allclose(m["porous_mastic"], m["mastic"], rtol=0)
        E.append(np.abs(mortar.young(*m["mortar"])))
    assert np.all(np.abs(dense) > E[0]) and np.all(E[0] > E[1]) and np.all(E[1] < c.E_stone_Pa)
    with pytest.raises(ValueError, match="air_phase"):
        mortar.mortar_moduli(G, d, vol, c, "asphalt")


@pytest.mark.parametrize("air_phase", ["mastic", "mortar", "pockets", "binder"])
def test_a_grid_of_stones_at_once_is_each_stone_alone(air_phase):
    """mortar_moduli with the stones along a first axis (stone_Pa of shape (m, 1)) gives, row by row,
    the moduli of each stone computed alone (the same operations element by element: equal to 1e-14);
    a stage with nothing to add returns its matrix unchanged."""
    G, d = np.geomspace(1e3, 1e9, 9), np.linspace(80, 10, 9)
    vol = {"binder": 0.11, "filler": 0.05, "air": 0.04, "fine": 0.38}
    E = np.array([30e9, 55e9, 90e9])
    Ks, Gs = mortar.shear_bulk(E, 0.2)
    grid = mortar.mortar_moduli(
        G[None, :], d[None, :], vol, Constituents(), air_phase, stone_Pa=(Ks[:, None], Gs[:, None])
    )
    for i, e in enumerate(E):
        alone = mortar.mortar_moduli(G, d, vol, Constituents(E_stone_Pa=float(e)), air_phase)
        for key in ("mastic", "porous_mastic", "mortar"):
            assert grid[key][0].shape == (3, 9)
            np.testing.assert_allclose(grid[key][0][i], alone[key][0], rtol=1e-14)
            np.testing.assert_allclose(grid[key][1][i], alone[key][1], rtol=1e-14)
    K, G0 = differential_scheme(np.full(4, 3e9 + 0j), np.full(4, 1e6 + 2e5j), [Inclusion(0.0, 0.0, 0.0)], 1.0)
    assert np.all(K == 3e9 + 0j) and np.all(G0 == 1e6 + 2e5j)


def test_the_confined_layer_meets_its_limits():
    """confined_modulus: a layer of vanishing shape factor is free (E); an incompressible one follows
    Gent and Lindley's E (1 + 2 S^2); a wide compressible one tends to E + K; it grows with S; a warm
    (nearly incompressible) viscoelastic layer keeps its phase angle; a negative S is refused."""
    from asphalt_nscd.forecast.mortar import confined_modulus, young

    S = np.array([0.0, 0.1, 0.5, 1.0, 2.0, 4.0])
    K, G = 1e15, 1e6  # nu -> 1/2
    np.testing.assert_allclose(confined_modulus(K, G, S).real / young(K, G), 1 + 2 * S**2, rtol=1e-5)
    Kc, Gc = 3e9, 1.2e9  # a glassy binder, nu about 0.33
    Ec = confined_modulus(Kc, Gc, S).real
    assert Ec[0] == pytest.approx(young(Kc, Gc), rel=1e-12)
    assert np.all(np.diff(Ec) > 0)
    assert confined_modulus(Kc, Gc, 1e4).real == pytest.approx(young(Kc, Gc) + Kc, rel=1e-3)
    assert Ec[-1] < young(Kc, Gc) + Kc
    # a glassy layer stiffens far less than a warm one at the same shape factor
    assert Ec[3] / young(Kc, Gc) < 2.0 < confined_modulus(3e9, 1e5, 1.0).real / young(3e9, 1e5)
    Gw = 1e5 * np.exp(1j * np.radians(70.0))
    Ew = confined_modulus(3e9, Gw, 1.5)
    assert np.degrees(np.angle(Ew)) == pytest.approx(70.0, abs=0.1)
    assert abs(Ew) == pytest.approx(abs(young(3e9, Gw)) * (1 + 2 * 1.5**2), rel=1e-3)
    with pytest.raises(ValueError, match="shape factor"):
        confined_modulus(Kc, Gc, -0.1)


def test_air_in_the_binder_is_the_mastic_without_air_and_softens_in_place_of_binder():
    """air_phase="binder": without air it is the mastic placement exactly (the same stages on the same
    fractions); every inclusion's fraction is taken over the space it shares with the air, so at a fixed
    VMA air in place of binder leaves the filler's and the fine aggregate's fractions as they were and
    softens the mortar at every condition."""
    G, d = np.geomspace(1e3, 1e9, 12), np.linspace(80, 10, 12)
    dense = {"binder": 0.11, "filler": 0.05, "air": 0.0, "fine": 0.38}
    a, b = (mortar.mortar_moduli(G, d, dense, Constituents(), phase) for phase in ("binder", "mastic"))
    for key in ("mastic", "porous_mastic", "mortar"):
        np.testing.assert_allclose(a[key][1], b[key][1], rtol=1e-12)
    swapped = [{"binder": 0.11 - x, "filler": 0.05, "air": 0.04 + x, "fine": 0.38} for x in (0.0, 0.01, 0.02)]
    E = [np.abs(mortar.young(*mortar.mortar_moduli(G, d, v, Constituents(), "binder")["mortar"])) for v in swapped]
    assert np.all(E[0] > E[1]) and np.all(E[1] > E[2])
    fractions = [mortar.mortar_moduli(G, d, v, Constituents(), "binder") for v in swapped]
    assert (
        len({round(f["phi_filler"], 12) for f in fractions}) == 1
        and len({round(f["phi_fine"], 12) for f in fractions}) == 1
    )


def test_the_fine_skeleton_is_waltons_smooth_packing():
    """granular_skeleton against Walton's (1987) own form, K = (1/6) [3 phi^2 C^2 P / (pi^4 B^2)]^(1/3) with
    B = (1/4 pi) (1/mu + 1/(mu + lambda)), and G = 3 K / 5 for smooth spheres; the pressure's cube root and the
    coordination's two thirds; none at zero pressure; real; refused outside its ranges."""
    from asphalt_nscd.forecast.mortar import granular_skeleton

    E, nu, phi, P, C = 55e9, 0.2, 0.7, 6e5, 6.0
    mu = E / (2 * (1 + nu))
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    B = (1 / mu + 1 / (mu + lam)) / (4 * np.pi)
    K_walton = (3 * phi**2 * C**2 * P / (np.pi**4 * B**2)) ** (1 / 3) / 6
    K, G = granular_skeleton(E, nu, phi, P, C)
    np.testing.assert_allclose(K, K_walton, rtol=1e-12)
    np.testing.assert_allclose(G, 0.6 * K, rtol=1e-15)
    assert 1e8 < K < 1e9  # a sand packing under hundreds of kPa: hundreds of MPa
    np.testing.assert_allclose(granular_skeleton(E, nu, phi, 8 * P, C)[0], 2 * K, rtol=1e-12)
    np.testing.assert_allclose(granular_skeleton(E, nu, phi, P, 8 * C)[0], 4 * K, rtol=1e-12)
    assert granular_skeleton(E, nu, phi, 0.0)[0] == 0.0
    Ks, _ = granular_skeleton(np.array([30e9, 90e9]), nu, np.array([0.5, 0.7]), P)
    assert Ks.shape == (2,) and np.isrealobj(Ks) and Ks[1] > Ks[0]
    for bad in ({"pressure_Pa": -1.0}, {"phi": 1.2}):
        with pytest.raises(ValueError, match="granular_skeleton"):
            granular_skeleton(**{"E_stone_Pa": E, "nu_stone": nu, "phi": phi, "pressure_Pa": P, **bad})


def test_the_contact_network_meets_its_limits_and_is_the_geometric_mean_at_twelve_neighbours():
    """mortar.contact_network: the effective-medium equation holds at its root (complex moduli too); equal
    kinds give that kind; real a > b > 0 give b < M < a, falling as the neighbours (films) grow; at 12
    neighbours (p = 1/2, c = 1) the equation reads 2 a b - 2 M^2 = 0, the geometric mean sqrt(a b) exactly
    (Lichtenecker); as b -> 0 the direct contacts sit at their threshold, M ~ sqrt(a b / c), half b's phase;
    z <= 2d refused."""
    from asphalt_nscd.forecast.mortar import contact_network

    a, b = np.array([4e9, 4e9 + 1e8j, 1e9]), np.array([1e7 + 3e7j, 2e8 + 1e8j, 1e9])
    for z in (7.0, 8.0, 12.0, 18.0, 49.0):
        M = contact_network(a, b, z)
        p, c = 6.0 / z, z / 6.0 - 1.0
        residual = p * (a - M) / (a + c * M) + (1 - p) * (b - M) / (b + c * M)
        assert np.max(np.abs(residual)) < 1e-12 and np.all(M.real > 0) and np.all(M.imag >= 0)
        np.testing.assert_allclose(M[2], 1e9, rtol=1e-12)  # equal kinds
    np.testing.assert_allclose(contact_network(a, b, 12.0), np.sqrt(a * b), rtol=1e-12)
    real = [contact_network(4e9, 1e7, z).real for z in (7.0, 8.0, 12.0, 18.0, 49.0)]
    assert all(1e7 < m < 4e9 for m in real) and np.all(np.diff(real) < 0)
    # z -> 2d: every neighbour a direct contact (p -> 1), the network the direct contacts'
    np.testing.assert_allclose(contact_network(4e9, 1e7, 6.0 + 1e-6), 4e9, rtol=1e-3)
    tiny = 1e-6 * np.exp(1j * np.radians(60.0))
    for z in (8.0, 18.0):
        M = contact_network(1.0, tiny, z)
        np.testing.assert_allclose(M, np.sqrt(tiny / (z / 6.0 - 1.0)), rtol=2e-3)
        assert np.degrees(np.angle(M)) == pytest.approx(30.0, abs=0.1)
    for z in (6.0, 3.0):
        with pytest.raises(ValueError, match="contact_network"):
            contact_network(a, b, z)
