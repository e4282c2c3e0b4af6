"""Threaded kernels (NSCDParameters.threads > 1) agree with the sequential ones."""

import numba
import numpy as np
import pytest

from asphalt_nscd.nscd import NSCDParameters, Simulation
from asphalt_nscd.nscd.bench import bonded_sample
from asphalt_nscd.nscd.linear import _partition

needs_two = pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="numba thread pool has a single thread")


@needs_two
@pytest.mark.parametrize("kinematics", ["contact", "barycentre"])
def test_threaded_fast_path_matches_sequential(kinematics):
    runs = []
    for threads in (1, 2):
        s, plates, bonds = bonded_sample(300, seed=3)
        sim = Simulation(
            s,
            plates,
            bonds,
            NSCDParameters(dt=5e-5, friction=0.7, linear_tolerance=1e-12, bond_kinematics=kinematics, threads=threads),
        )
        df = sim.run(8)
        assert (df.solver == "linear").all()
        runs.append((sim, df))
    (a, da), (b, db) = runs
    if kinematics == "contact":
        assert len(b._linear.blk_g) > 0  # sphere-plate bonds: the general kernel branch
    scale = np.abs(a.bonds.force).max()
    assert scale > 0
    np.testing.assert_allclose(b.bonds.force, a.bonds.force, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(db.plate1_Fx_N, da.plate1_Fx_N, rtol=0, atol=1e-9 * np.abs(da.plate1_Fx_N).max())
    np.testing.assert_allclose(
        b.spheres.velocity, a.spheres.velocity, rtol=0, atol=1e-9 * np.abs(a.spheres.velocity).max()
    )


def test_partition_separates_the_threads():
    rng = np.random.default_rng(0)
    nblk = 200
    blk = rng.integers(-1, nblk, (1000, 4))
    blk[:, 2] = np.clip(blk[:, 0] + rng.integers(-5, 6, 1000), -1, nblk - 1)
    compact = rng.random(1000) < 0.8
    order, pc, pg = _partition(blk, compact, nblk, 3)
    assert np.array_equal(np.sort(order), np.arange(1000))
    b, c = blk[order], compact[order]
    assert c[: c.sum()].all() and not c[c.sum() :].any()  # compact bonds first
    for sub, part in ((b[c], pc), (b[~c], pg)):
        assert part[0] == 0 and part[-1] == len(sub)
        owners = []
        for t in range(3):
            used = sub[part[t] : part[t + 1]]
            used = used[used >= 0]
            owners.append(set(used.tolist()))
        for t in range(3):  # no block is written by two threads
            for u in range(t + 1, 3):
                assert not owners[t] & owners[u]
    order1, pc1, _ = _partition(blk, compact, nblk, 1)
    assert np.array_equal(order1, np.arange(1000)) and len(pc1) == 0


def test_threads_validated():
    with pytest.raises(ValueError, match="threads"):
        NSCDParameters(dt=1e-4, threads=0)
    with pytest.raises(ValueError, match="threads"):
        NSCDParameters(dt=1e-4, threads=numba.config.NUMBA_NUM_THREADS + 1)


def test_kernels_compile_without_reference_counting():
    """The loop kernels are built without numba's NRT (nscd/_jit.py); a numba version that
    rejects the flag would silently make them 5-15x slower."""
    import numpy as np

    from asphalt_nscd.nscd import _jit, linear

    assert _jit.NO_NRT
    assert linear._bonds.targetoptions.get("_nrt") is False

    @_jit.kernel
    def first(a):
        return a[0]

    assert first(np.arange(3.0) + 2.0) == 2.0  # the flag compiles
    assert first.targetoptions.get("_nrt") is False
