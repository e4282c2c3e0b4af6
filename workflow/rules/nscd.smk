# NSCD core (src/asphalt_nscd/nscd): verification against closed forms (creep, relaxation,
# sinusoidal steady state, rest/incline/column/impact, breakage at R_crit, dissipation,
# fast path vs NLGS) with the phase error of the time-discrete bond law vs omega dt and theta,
# and benchmarks at reduced N (bonded 2PB-like sample; frictional granular bed).

from asphalt_nscd import plan


rule nscd_verify:
    output:
        json="results/nscd/verify.json",
        csv=report(
            "results/nscd/verify.csv",
            caption="../report/nscd_verify.rst",
            category="NSCD core",
        ),
        phase=report(
            "results/nscd/phase_error.csv",
            caption="../report/nscd_phase_error_table.rst",
            category="NSCD core",
        ),
        figure=report(
            "results/nscd/phase_error.png",
            caption="../report/nscd_phase_error.rst",
            category="NSCD core",
        ),
    log:
        "logs/nscd/verify.log",
    benchmark:
        "benchmarks/nscd/verify.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        freqs=plan.comma_list(config["nscd"]["verify"]["phase_frequencies_Hz"]),
        dts=plan.comma_list(config["nscd"]["verify"]["phase_dts_s"]),
        thetas=plan.comma_list(config["nscd"]["verify"]["phase_thetas"]),
    shell:
        "asphalt-nscd verify -o {output.json} --csv {output.csv} --phase-table {output.phase} "
        "--figure {output.figure} --phase-frequencies {params.freqs} --phase-dts {params.dts} "
        "--phase-thetas {params.thetas} 2> {log}"


rule nscd_bench:
    output:
        "results/bench/nscd_{case}_n{n}.json",
    log:
        "logs/nscd/bench_{case}_n{n}.log",
    benchmark:
        "benchmarks/nscd/bench_{case}_n{n}.tsv"
    wildcard_constraints:
        case="bonded|granular",
        n=r"\d+",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        steps=config["nscd"]["bench"]["steps"],
        baseline=config["nscd"]["bench"]["baseline_steps"],
        settle=config["nscd"]["bench"]["settle_steps"],
        settle_speed=config["nscd"]["bench"].get("settle_speed_m_s", 5.0e-3),
        tol=plan.from_wildcards(plan.bench_tolerance, config),
        kinematics=plan.bond_kinematics(config),
        bonded_contact=plan.bonded_contact(config),
    shell:
        "NUMBA_NUM_THREADS={threads} asphalt-nscd bench --case {wildcards.case} --n {wildcards.n} --threads {threads} "
        "--steps {params.steps} --baseline-steps {params.baseline} --settle-steps {params.settle} "
        "--settle-speed {params.settle_speed} "
        "--tolerance {params.tol} --bond-kinematics {params.kinematics} "
        "--bonded-contact {params.bonded_contact} -o {output} 2> {log}"


rule nscd_bench_summary:
    input:
        plan.nscd_bench_files(config),
    output:
        report(
            "results/bench/nscd_bench.csv",
            caption="../report/nscd_bench.rst",
            category="NSCD core",
        ),
    log:
        "logs/nscd/bench_summary.log",
    benchmark:
        "benchmarks/nscd/bench_summary.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        "asphalt-nscd bench-summary {input} -o {output} 2> {log}"
