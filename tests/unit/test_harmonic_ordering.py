"""Fill-reducing ordering (METIS nested dissection), the permuted SuperLU factor and the
shifted-factor GMRES path of the harmonic solver (reuse across (T, f), refactorisation and
fallback), all checked against the direct complex LU."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from asphalt_nscd.harmonic import solver as solver_module
from asphalt_nscd.harmonic.network import network_from_sample
from asphalt_nscd.sample.lattice import lattice_sample
from asphalt_nscd.sample.store import read_sample, write_sample
from asphalt_nscd.harmonic.ordering import expand_blocks, nested_dissection
from asphalt_nscd.harmonic.solver import HarmonicSystem
from asphalt_nscd.nscd.linear import splu_symmetric
from asphalt_nscd.rheology.laws import GeneralizedBurgers

LAW = GeneralizedBurgers.burgers(Em=2.43e7, eta_m=3.71e6, Ek=4.84e7, eta_k=7.73e5)  # 15 degC


@pytest.fixture(scope="module")
def network(tmp_path_factory):
    path = tmp_path_factory.mktemp("ord") / "lattice.h5"
    write_sample(path, lattice_sample(120, seed=4))
    return network_from_sample(read_sample(path))


def test_nested_dissection_of_a_path_is_a_permutation_with_a_separator_last():
    # path 0-1-2-3-4-5-6: nested dissection numbers a middle separator vertex last
    perm = nested_dissection(7, np.arange(6), np.arange(1, 7))
    assert sorted(perm) == list(range(7))
    assert perm[-1] in (2, 3, 4)
    # duplicates, reversed edges and self-loops are accepted
    again = nested_dissection(7, np.r_[np.arange(6), np.arange(1, 7), 3], np.r_[np.arange(1, 7), np.arange(6), 3])
    assert sorted(again) == list(range(7))


def test_expand_blocks_keeps_the_unknowns_of_a_node_together():
    # nodes of 2, 2 and 1 unknowns, order (2, 0, 1)
    np.testing.assert_array_equal(expand_blocks([2, 0, 1], [0, 2, 4, 5]), [4, 0, 1, 2, 3])


def test_permuted_splu_solves_real_complex_and_multiple_rhs():
    rng = np.random.default_rng(1)
    a = sp.random(60, 60, density=0.08, random_state=2)
    a = (a + a.T + 12 * sp.eye(60)).tocsc()
    lu = splu_symmetric(a, rng.permutation(60))
    b = rng.standard_normal((60, 3)) + 1j * rng.standard_normal((60, 3))
    for rhs in (b[:, 0].real, b[:, 0], b):
        x = lu.solve(rhs)
        assert x.shape == rhs.shape
        np.testing.assert_allclose(x, spsolve(a.astype(complex), rhs.astype(complex)), rtol=1e-12, atol=1e-14)
    assert lu.L.nnz + lu.U.nnz >= a.nnz


def test_orderings_give_the_same_solution(network):
    metis = HarmonicSystem(network, ordering="metis")
    mmd = HarmonicSystem(network, ordering="mmd")
    perm = metis.permutation()
    assert sorted(perm) == list(range(metis.n_free))
    # 6-DOF blocks of a sphere stay contiguous and aligned
    body = perm[: 6 * (len(perm) // 6)].reshape(-1, 6)
    assert np.all(np.diff(body, axis=1) == 1) or metis.n_free % 6
    for inertia in ("none", "full"):
        a = metis.solve_law(LAW, 10.0, inertia=inertia, rtol=1e-13)
        b = mmd.solve_law(LAW, 10.0, inertia=inertia, rtol=1e-13)
        np.testing.assert_allclose(a.force, b.force, rtol=1e-9)
    assert metis.factor_log[0]["ordering"] == "metis" and mmd.factor_log[0]["ordering"] == "mmd"


def test_shifted_factor_is_reused_for_nearby_frequencies_and_replaced_far_away(network):
    system = HarmonicSystem(network)
    reference = HarmonicSystem(network)
    for f, new_factor in ((10.0, True), (8.0, False), (12.0, False), (2.0, False), (100.0, True)):
        n = len(system.factor_log)
        a = system.solve_law(LAW, f, inertia="full", rtol=1e-13)
        assert (len(system.factor_log) > n) == new_factor
        assert a.solver == "reuse" and a.residual < 1e-12
        assert system.last_gmres_iterations < 60
        b = reference.solve_law(LAW, f, inertia="full", solver="direct")
        np.testing.assert_allclose(a.force, b.force, rtol=1e-9)
    # the shift of a new factor is Re(w^2 / E*)
    w = 2 * np.pi * 100.0
    assert system.factor_log[-1]["shift"] == pytest.approx((w**2 / LAW.complex_modulus(w)).real, rel=1e-5)
    # both factors fit the memory budget: back at 10 Hz the first is reused, not recomputed
    assert len(system._shifted) == 2
    n = len(system.factor_log)
    a = system.solve_law(LAW, 10.0, inertia="full", rtol=1e-13)
    assert len(system.factor_log) == n and a.solver == "reuse"
    np.testing.assert_allclose(
        a.force, reference.solve_law(LAW, 10.0, inertia="full", solver="direct").force, rtol=1e-9
    )


def test_shifted_factors_beyond_the_memory_budget_are_dropped_least_recent_first(network, monkeypatch):
    probe = HarmonicSystem(network)
    probe.solve_law(LAW, 100.0, inertia="full")
    size = solver_module.FACTOR_BYTES_PER_ENTRY * probe.factor_log[-1]["stored_entries"]

    def factorisations(system, frequencies):
        n = len(system.factor_log)
        for f in frequencies:
            system.solve_law(LAW, f, inertia="full")
        return len(system.factor_log) - n

    # 100 Hz and 0.3 Hz are outside each other's reuse band: each needs its own factor
    # room for one factor and a half: the cached factor is dropped before the next is computed
    monkeypatch.setattr(solver_module, "SHIFTED_FACTOR_BUDGET_BYTES", 1.5 * size)
    one = HarmonicSystem(network)
    assert factorisations(one, [100.0, 0.3, 100.0, 0.3]) == 4 and len(one._shifted) == 1
    # room for two: both kept, the return to a shift reuses its factor
    monkeypatch.setattr(solver_module, "SHIFTED_FACTOR_BUDGET_BYTES", 2.5 * size)
    two = HarmonicSystem(network)
    assert factorisations(two, [100.0, 0.3, 100.0, 0.3]) == 2 and len(two._shifted) == 2
    w = 2 * np.pi * np.array([100.0, 0.3])
    np.testing.assert_allclose(list(two._shifted), (w**2 / LAW.complex_modulus(w)).real, rtol=1e-5)


def test_gmres_cap_refactorises_then_falls_back_to_direct(network, monkeypatch):
    system = HarmonicSystem(network)
    system.solve_law(LAW, 10.0, inertia="full")
    n = len(system.factor_log)
    monkeypatch.setattr(solver_module, "GMRES_MAX_ITERATIONS", 1)
    a = system.solve_law(LAW, 9.0, inertia="full", rtol=1e-13)
    # the reused factor failed, a factor at the exact shift failed, then the complex LU
    kinds = [r["kind"] for r in system.factor_log[n:]]
    assert kinds == ["G - sigma M", "complex K - w^2 M"]
    assert a.solver == "direct"
    b = HarmonicSystem(network).solve_law(LAW, 9.0, inertia="full", solver="direct")
    np.testing.assert_allclose(a.force, b.force, rtol=1e-10)


def test_unknown_ordering_is_rejected(network):
    with pytest.raises(ValueError, match="ordering"):
        HarmonicSystem(network, ordering="amd")
