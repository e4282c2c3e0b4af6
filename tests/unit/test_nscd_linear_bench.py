"""Bench of the linear fast path: the periodic start and the same-run comparison of the
SSOR kernel with the block-Jacobi one (records only; no timing asserted)."""

import pytest

from asphalt_nscd.campaign.bench import bench_starter
from asphalt_nscd.nscd.bench import run_bench


def test_bonded_bench_periodic_start_records_both_kernels():
    rest = run_bench("bonded", 80, steps=4, baseline_steps=1, linear_solver="cg_ssor")
    per = run_bench(
        "bonded", 80, steps=4, baseline_steps=1, linear_solver="cg_ssor", start="periodic", starter=bench_starter
    )
    assert rest["start"] == "rest" and "periodic_solve_s" not in rest
    assert per["start"] == "periodic" and per["periodic_solve_s"] > 0
    assert 0 < per["periodic_force_ratio"] < 1
    for rec in (rest, per):
        assert rec["solver"] == "linear" and rec["linear_ssor_omega"] == 1.2
        assert rec["speedup_vs_cg"] > 0 and rec["cg_max_force_difference"] < 1e-5
    # in the steady state the Galerkin start leaves little to iterate; from rest it does not
    assert per["nlgs_iterations_mean"] < per["cg_iterations_mean"]
    assert per["nlgs_iterations_mean"] < rest["nlgs_iterations_mean"]


def test_bonded_bench_rejects_an_unknown_start():
    with pytest.raises(ValueError, match="start"):
        run_bench("bonded", 40, steps=1, start="steady")
