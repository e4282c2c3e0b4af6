"""Factor and solve the 2PB step matrix of a paper-scale sample: SuperLU in symmetric mode (MMD
and METIS orderings), cholespy's sparse Cholesky, and PARDISO through pypardiso.

Usage, from the repository root after the paper-scale samples exist (``make run
CONFIG=config/paper.yaml`` or their Snakemake targets), with pypardiso installed beside the
project for the comparison (``.venv/bin/pip install pypardiso``; not a project dependency):

    OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 .venv/bin/python reference/direct_solve/bench.py \\
        results/samples/s2.h5 reference/direct_solve/s2.json

The step matrix is captured from the first step of a 2PB test (Table 3 read in kPa at 15 degC,
3 Hz, dt = 5e-5 s, the paper_kPa mode's settings); each factorisation is timed by
``time.process_time`` (factor once, 50 solves), with its largest relative residual.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np
import scipy.sparse as sp

from asphalt_nscd import config, plan
from asphalt_nscd.campaign import study, twopb
from asphalt_nscd.harmonic.ordering import expand_blocks, nested_dissection
from asphalt_nscd.nscd.linear import direct
from asphalt_nscd.nscd.linear import solver as lsolver
from asphalt_nscd.rheology.calibration import burgers_model
from asphalt_nscd.sample.store import read_sample


def step_matrix(sample_path: str) -> sp.csc_matrix:
    """The fast path's step matrix of the paper_kPa mode's 15 degC / 3 Hz job (first step)."""
    captured = {}
    factor = lsolver.factor_spd

    def capture(K, *args, **kwargs):
        captured["K"] = K.copy()
        return factor(K, *args, **kwargs)

    lsolver.factor_spd = capture
    try:
        cfg = config.load(["config/paper.yaml"])
        settings = twopb.settings_from(plan.mode_settings(cfg, "paper_kPa"))
        assert settings.linear_solver == "direct"
        table = study.parameter_table("data/paper/table3_burgers.csv", "kPa")
        law = burgers_model(study.parameters_at(table, 15.0, {}, where="Table 3"))
        sim, _ = twopb.build_simulation(read_sample(sample_path), law, 3.0, 5e-5, settings)
        sim.step()
    finally:
        lsolver.factor_spd = factor
    K = sp.csc_matrix(captured["K"])
    K.sum_duplicates()
    K.sort_indices()
    return K


def metis_permutation(K) -> np.ndarray:
    """METIS nested dissection of the 3 x 3 block graph of K, expanded to the unknowns."""
    blocks = sp.csr_matrix(K)[::3, ::3].tocoo()
    nb = K.shape[0] // 3
    return expand_blocks(nested_dissection(nb, blocks.row, blocks.col), np.arange(0, 3 * nb + 1, 3))


def timed(K, factor, solve, rhs) -> dict:
    c0 = time.process_time()
    F = factor()
    factor_cpu = time.process_time() - c0
    c0 = time.process_time()
    for b in rhs:
        solve(F, b)
    solve_cpu = (time.process_time() - c0) / len(rhs)
    residual = max(np.linalg.norm(K @ solve(F, b) - b) / np.linalg.norm(b) for b in rhs[:3])
    return {"factor_cpu_s": factor_cpu, "solve_cpu_s": solve_cpu, "residual": float(residual)}


def main(sample_path: str, out_path: str) -> None:
    K = step_matrix(sample_path)
    n = K.shape[0]
    rng = np.random.default_rng(0)
    rhs = [rng.normal(size=n) for _ in range(50)]
    out = {"sample": sample_path, "ndof": n, "nnz": int(K.nnz)}
    out["superlu_symmetric"] = timed(K, lambda: direct.splu_symmetric(K), lambda F, b: F.solve(b), rhs)
    c0 = time.process_time()
    perm = metis_permutation(K)
    out["metis_ordering_cpu_s"] = time.process_time() - c0
    out["superlu_symmetric_metis"] = timed(K, lambda: direct.splu_symmetric(K, perm), lambda F, b: F.solve(b), rhs)
    out["cholespy"] = timed(K, lambda: direct.CholeskyFactor(K), lambda F, b: F.solve(b), rhs)
    try:
        import pypardiso
    except ImportError:
        out["pypardiso"] = "not installed"
    else:
        upper = sp.triu(K, format="csr")

        def pardiso():
            solver = pypardiso.PyPardisoSolver(mtype=2)  # real symmetric positive definite
            solver.factorize(upper)
            return solver

        out["pypardiso"] = timed(K, pardiso, lambda F, b: F.solve(upper, b), rhs)
    with open(out_path, "w") as fh:
        json.dump(out, fh, indent=1)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
