"""The bench command runs at a tiny N and writes the required keys (no timing asserted)."""

import json

import pytest

from asphalt_nscd.cli import main

KEYS = {"case", "n_particles", "n_bonds", "n_contacts", "steps", "s_per_particle_step",
        "nlgs_iterations_mean", "peak_rss_mb", "solver", "tolerance", "threads", "compile_s"}


@pytest.mark.parametrize("case", ["bonded", "granular"])
def test_bench_cli(tmp_path, case):
    out = tmp_path / f"{case}.json"
    assert main(["bench", "--case", case, "--n", "60", "--steps", "2", "--baseline-steps", "1",
                 "--settle-steps", "5", "-o", str(out)]) == 0
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
