# Diagnosis: what the simulation gets wrong. Error budget per temperature, named causes
# (statistical tests on nested 2S2P1D/WLF master-curve fits), the extended generalized
# Burger's law per temperature (results/diagnosis/generalized_burgers.json, Pa and Pa s, for
# the campaign and the harmonic solver) and its gain; plus the detection benchmark on
# synthetic tables with planted artifacts.
# Rerun: `snakemake --cores 1 results/diagnosis/report.json --forcerun diagnose`.

DIAG = config["diagnosis"]
DIAG_CATEGORY = "What the simulation gets wrong"
DIAG_OPTIONAL = {
    key: DIAG.get(key)
    for key in ("simulated", "harmonic", "time_integration", "simulated_extended")
    if DIAG.get(key)
}


def _diagnose_options():
    opts = (
        f"--alpha {DIAG['alpha']} --shift {DIAG['shift']} --per-decade {DIAG['per_decade']} "
        f"--margin-decades {DIAG['margin_decades']} --prior-weight {DIAG['prior_weight']}"
    )
    if DIAG.get("T_ref_C") is not None:
        opts += f" --t-ref {DIAG['T_ref_C']}"
    if not DIAG["refine"]:
        opts += " --no-refine"
    for key, path in DIAG_OPTIONAL.items():
        opts += f" --{key.replace('_', '-')} {path}"
    if "time_integration" in DIAG_OPTIONAL and "theta" in config.get("nscd", {}):
        opts += f" --theta {config['nscd']['theta']}"
    return opts


rule diagnose:
    input:
        measured="results/lab/measured.csv",
        macro="results/calibration/burgers_parameters.csv",
        optional=list(DIAG_OPTIONAL.values()),
    output:
        report="results/diagnosis/report.json",
        laws="results/diagnosis/generalized_burgers.json",
        corrected="results/diagnosis/corrected_measured.csv",
        budget=report(
            "results/diagnosis/error_budget.csv",
            caption="../report/diagnosis_error_budget.rst",
            category=DIAG_CATEGORY,
        ),
        effects=report(
            "results/diagnosis/causes.csv",
            caption="../report/diagnosis_causes.rst",
            category=DIAG_CATEGORY,
        ),
        gain=report(
            "results/diagnosis/gain.csv",
            caption="../report/diagnosis_gain.rst",
            category=DIAG_CATEGORY,
        ),
        figure=report(
            "results/diagnosis/error_budget.png",
            caption="../report/diagnosis_what_goes_wrong.rst",
            category=DIAG_CATEGORY,
        ),
        page="results/diagnosis/what_the_simulation_gets_wrong.md",
    params:
        options=_diagnose_options(),
    log:
        "logs/diagnosis/diagnose.log",
    benchmark:
        "benchmarks/diagnosis/diagnose.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=15,
    shell:
        "asphalt-nscd diagnose --measured {input.measured} --macro-params {input.macro} {params.options} "
        "-o {output.report} --laws {output.laws} --corrected {output.corrected} "
        "--budget-csv {output.budget} --effects-csv {output.effects} --gain-csv {output.gain} "
        "--figure {output.figure} --page {output.page} 2> {log}"


rule diagnose_bench:
    output:
        report(
            "results/diagnosis/detection_bench.json",
            caption="../report/diagnosis_bench.rst",
            category=DIAG_CATEGORY,
        ),
    params:
        seeds=DIAG["bench_seeds"],
        alpha=DIAG["alpha"],
    log:
        "logs/diagnosis/diagnose_bench.log",
    benchmark:
        "benchmarks/diagnosis/diagnose_bench.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=60,
    shell:
        "asphalt-nscd diagnose-bench --seeds {params.seeds} --alpha {params.alpha} -o {output} 2> {log}"


REPORT_FILES += [
    "results/diagnosis/what_the_simulation_gets_wrong.md",
    "results/diagnosis/error_budget.png",
    "results/diagnosis/error_budget.csv",
    "results/diagnosis/causes.csv",
    "results/diagnosis/gain.csv",
    "results/diagnosis/report.json",
    "results/diagnosis/generalized_burgers.json",
    "results/diagnosis/detection_bench.json",
]
