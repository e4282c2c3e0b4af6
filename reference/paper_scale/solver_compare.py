"""Same-run CPU time per step of the 2PB test on a sample with each linear fast-path solver."""

import json, sys, time, dataclasses
import numpy as np
from asphalt_nscd import config
from asphalt_nscd.campaign import study
from asphalt_nscd.campaign.twopb import TwoPBSettings, build_simulation, start_test, mode_settings, time_step
from asphalt_nscd.sample.store import read_sample

sample_path, cfg_path, params_csv, n_steps = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
cases = [c.split(":") for c in sys.argv[5:]]
cfg = config.load([cfg_path])  # merged over config/config.yaml (run from the repository root), as Snakemake
camp = cfg["campaign"]
laws = study.JobLaws(
    table3="data/paper/table3_burgers.csv",
    table3_units=cfg["calibration"]["table3_units"],
    parameters=params_csv,
    law_json=None,
    network_factor_json=None,
    sample_name="s1",
)
sample = read_sample(sample_path)
out = []
for mode, T, f, start in cases:
    T, f = float(T), float(f)
    law = laws.law(mode, T)
    for solver in ("cg", "cg_ssor", "direct"):
        base = TwoPBSettings(
            **{
                k: v
                for k, v in mode_settings(camp, mode, "contact", solver).items()
                if k in TwoPBSettings.__dataclass_fields__
            }
        )
        s = dataclasses.replace(base, start=start, linear_solver=solver)
        dt = time_step(f, s)
        sim, _ = build_simulation(sample, law, f, dt, s)
        c0 = time.process_time()
        start_test(sim, law, f, s)
        sim.step()
        sim.step()
        setup = time.process_time() - c0
        its, lin = [], 0
        c0 = time.process_time()
        for _ in range(n_steps):
            st = sim.step()
            its.append(st.iterations)
            lin += st.solver == "linear"
        cpu = (time.process_time() - c0) / n_steps
        row = dict(
            mode=mode,
            T=T,
            f=f,
            dt=dt,
            start=start,
            solver=solver,
            s_per_step=cpu,
            s_per_sphere_step=cpu / sample.position.shape[0],
            iterations=float(np.mean(its)),
            linear_fraction=lin / n_steps,
            setup_s=setup,
            n_spheres=int(sample.position.shape[0]),
        )
        print(json.dumps(row), flush=True)
        out.append(row)
