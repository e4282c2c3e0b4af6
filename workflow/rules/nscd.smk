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
        settings=plan.command_settings(config, "verify"),
    shell:
        "asphalt-nscd verify -o {output.json} --csv {output.csv} --phase-table {output.phase} "
        '--figure {output.figure} --config "$ASPHALT_NSCD_RUN_CONFIG" 2> {log}'


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
        settings=plan.from_wildcards(plan.bench_settings, config),
    shell:
        "NUMBA_NUM_THREADS={threads} asphalt-nscd bench --case {wildcards.case} --n {wildcards.n} --threads {threads}"
        ' --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output} 2> {log}'


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
