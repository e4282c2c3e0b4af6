"""The bench command runs at a tiny N and writes the required keys (no timing asserted)."""

import json

import pytest

from asphalt_nscd.cli import main

KEYS = {
    "case",
    "n_particles",
    "n_bonds",
    "n_contacts",
    "steps",
    "s_per_particle_step",
    "nlgs_iterations_mean",
    "peak_rss_mb",
    "solver",
    "tolerance",
    "threads",
    "compile_s",
}


@pytest.mark.parametrize("case", ["bonded", "granular"])
def test_bench_cli(tmp_path, case):
    out = tmp_path / f"{case}.json"
    assert (
        main(
            [
                "bench",
                "--case",
                case,
                "--n",
                "60",
                "--steps",
                "2",
                "--baseline-steps",
                "1",
                "--settle-steps",
                "5",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    rec = json.loads(out.read_text())
    assert KEYS <= set(rec)
    assert rec["n_particles"] == 60
    if case == "bonded":
        assert rec["n_bonds"] > 0 and rec["solver"] == "linear" and rec["speedup"] > 0
    csv = tmp_path / "summary.csv"
    assert main(["bench-summary", str(out), "-o", str(csv)]) == 0
    assert csv.read_text().startswith("case,")


def test_bench_bad_input(tmp_path):
    assert main(["bench", "--case", "bonded", "--n", "1", "-o", str(tmp_path / "x.json")]) == 2


def test_bench_granular_settles_and_reports_it(tmp_path):
    """The granular bed is timed after settling; the settling phase is reported."""
    out = tmp_path / "g.json"
    assert (
        main(
            [
                "bench",
                "--case",
                "granular",
                "--n",
                "40",
                "--steps",
                "2",
                "--settle-steps",
                "3000",
                "--settle-speed",
                "0.02",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    rec = json.loads(out.read_text())
    assert rec["settled"] and rec["settle_final_speed"] < 0.02
    assert 0 < rec["settle_steps"] <= 3000 and rec["settle_steps"] % 50 == 0
    assert rec["settle_nlgs_iterations_max"] >= rec["settle_nlgs_iterations_mean"] > 0
    assert rec["n_active_contacts"] > 0


def test_bench_threads_record(tmp_path):
    import numba

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba thread pool has a single thread")
    out = tmp_path / "t.json"
    assert (
        main(
            [
                "bench",
                "--case",
                "bonded",
                "--n",
                "60",
                "--steps",
                "2",
                "--baseline-steps",
                "1",
                "--threads",
                "2",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    rec = json.loads(out.read_text())
    assert rec["threads"] == 2 and rec["thread_speedup"] > 0
    assert rec["threads_max_force_difference"] < 1e-6
    assert main(["bench", "--case", "bonded", "--n", "60", "--threads", "0", "-o", str(tmp_path / "x.json")]) == 2


def test_bench_ssor_record_times_the_jacobi_kernel_too(tmp_path):
    """--linear-solver cg_ssor: the production run uses the SSOR conjugate gradient and the
    record holds the block-Jacobi kernel's time on the same steps, with the same forces."""
    out = tmp_path / "s.json"
    assert (
        main(
            [
                "bench",
                "--case",
                "bonded",
                "--n",
                "200",
                "--steps",
                "3",
                "--baseline-steps",
                "1",
                "--linear-solver",
                "cg_ssor",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    rec = json.loads(out.read_text())
    assert rec["linear_solver"] == "cg_ssor" and rec["solver"] == "linear"
    assert rec["speedup_vs_cg"] > 0 and rec["cg_s_per_particle_step"] > 0
    assert rec["cg_iterations_mean"] > rec["nlgs_iterations_mean"] > 0
    assert rec["cg_max_force_difference"] < 1e-5


def test_bench_summary_table_checks_the_records(tmp_path):
    from asphalt_nscd.io import InputError
    from asphalt_nscd.nscd.bench import summary_table

    good = tmp_path / "a.json"
    good.write_text(
        json.dumps(
            {
                "case": "bonded",
                "n_particles": 60,
                "s_per_particle_step": 1e-6,
                "time_breakdown": {"solve": 0.7, "detect": 0.3},
                "nested": {"x": 1},
            }
        )
    )
    table = summary_table([good])
    assert table.to_dict("records") == [
        {
            "case": "bonded",
            "n_particles": 60,
            "s_per_particle_step": 1e-6,
            "fraction_solve": 0.7,
            "fraction_detect": 0.3,
        }
    ]
    bad = tmp_path / "b.json"
    bad.write_text(json.dumps({"case": "bonded", "n_particles": 60}))
    with pytest.raises(InputError, match="b.json: key 's_per_particle_step' missing"):
        summary_table([good, bad])
