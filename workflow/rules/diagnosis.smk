# Diagnosis: what the simulation gets wrong. Two steps:
# 1. extend_law: the extended generalized Burger's law per temperature (Maxwell + N
#    Kelvin-Voigt units + static spring, from the 2S2P1D/WLF master curve of the
#    artifact-corrected measured data; results/diagnosis/generalized_burgers.json, Pa and Pa s),
#    from the measured table alone. The extended campaign mode (simulation.smk) runs with it.
# 2. diagnose: error budget per temperature, named causes (statistical tests on nested
#    master-curve fits; simulation causes from the NSCD campaign, the harmonic solver and the
#    time-step phase error) and the gain per temperature, NSCD before -> NSCD after and macro
#    law before -> after; plus the detection benchmark on synthetic tables with planted artifacts.
# Simulation inputs (config diagnosis.simulated, harmonic, time_integration, simulated_extended,
# transfer = the network factor JSONs of rule harmonic_transfer):
# "auto" = the workflow's own outputs on the extended mode's samples (campaign.extended.n_samples,
# the same samples before and after), null = not used, or a CSV path.
# Rerun: `snakemake --cores 1 results/diagnosis/report.json --forcerun diagnose`.

DIAG = config["diagnosis"]
DIAG_CATEGORY = "What the simulation gets wrong"


def _diag_auto(key):
    """The workflow's own output(s) for a simulation input of diagnose (``auto``)."""
    samples = mode_samples("extended")
    if key == "simulated":
        return mode_rows("measured", samples)
    if key == "simulated_extended":
        return mode_rows("extended", samples)
    if key == "harmonic":
        return [f"results/harmonic/jobs/{s}_measured.csv" for s in samples]
    if key == "time_integration":
        return ["results/campaign/measured/dt_policy_phase_error.csv"]
    if key == "transfer":
        return [transfer_file(s) for s in samples]
    raise ValueError(key)


DIAG_INPUTS = {}
for _key in ("simulated", "harmonic", "time_integration", "simulated_extended", "transfer"):
    _value = DIAG.get(_key, "auto")
    if _value == "auto":
        DIAG_INPUTS[_key] = _diag_auto(_key)
    elif _value:
        DIAG_INPUTS[_key] = [_value]


def _fit_options():
    opts = (
        f"--alpha {DIAG['alpha']} --shift {DIAG['shift']} --per-decade {DIAG['per_decade']} "
        f"--margin-decades {DIAG['margin_decades']} --prior-weight {DIAG['prior_weight']}"
    )
    if DIAG.get("T_ref_C") is not None:
        opts += f" --t-ref {DIAG['T_ref_C']}"
    if not DIAG["refine"]:
        opts += " --no-refine"
    if not DIAG.get("balance", True):
        opts += " --no-balance"
    tol = DIAG.get("balance_tolerances_pct", [3.0, 5.0])
    opts += f" --balance-tolerances-pct {tol[0]} {tol[1]}"
    return opts


def _diagnose_options():
    opts = _fit_options()
    for key, paths in DIAG_INPUTS.items():
        opts += f" --{key.replace('_', '-')} " + " ".join(paths)
    if "time_integration" in DIAG_INPUTS:
        # the campaign's Moreau-Jean theta (rows of other thetas are dropped)
        opts += f" --theta {config['campaign']['test']['theta']}"
    return opts


rule extend_law:
    input:
        measured="results/lab/measured.csv",
    output:
        laws=report(
            LAW_JSON,
            caption="../report/diagnosis_extended_law.rst",
            category=DIAG_CATEGORY,
        ),
        corrected="results/diagnosis/corrected_measured.csv",
    params:
        options=_fit_options(),
    log:
        "logs/diagnosis/extend_law.log",
    benchmark:
        "benchmarks/diagnosis/extend_law.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=15,
    shell:
        "asphalt-nscd extend-law --measured {input.measured} {params.options} -o {output.laws} "
        "--corrected {output.corrected} 2> {log}"


rule diagnose:
    input:
        measured="results/lab/measured.csv",
        macro="results/calibration/burgers_parameters.csv",
        laws=LAW_JSON,
        test="results/lab/measured.test.json",
        simulations=[p for paths in DIAG_INPUTS.values() for p in paths],
    output:
        report="results/diagnosis/report.json",
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
        tolerances=(
            f"--tolerance-network-factor {DIAG.get('cause_tolerances', {}).get('network_factor', 0.01)} "
            f"--tolerance-phase-deg {DIAG.get('cause_tolerances', {}).get('time_integration_deg', 0.1)}"
        ),
    log:
        "logs/diagnosis/diagnose.log",
    benchmark:
        "benchmarks/diagnosis/diagnose.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=15,
    shell:
        "asphalt-nscd diagnose --measured {input.measured} --test {input.test} --macro-params {input.macro} "
        "--law-json {input.laws} {params.options} {params.tolerances} -o {output.report} "
        "--budget-csv {output.budget} --effects-csv {output.effects} --gain-csv {output.gain} "
        "--figure {output.figure} --page {output.page} 2> {log}"


rule diagnose_bench:
    output:
        bench=report(
            "results/diagnosis/detection_bench.json",
            caption="../report/diagnosis_bench.rst",
            category=DIAG_CATEGORY,
        ),
        table=report(
            "results/diagnosis/detection_bench.csv",
            caption="../report/diagnosis_bench_table.rst",
            category=DIAG_CATEGORY,
        ),
    params:
        clean=DIAG["bench"]["clean"],
        planted=DIAG["bench"]["planted"],
        base_seed=DIAG["bench"]["base_seed"],
        families=",".join(DIAG["bench"]["families"]),
        alpha=DIAG["alpha"],
    log:
        "logs/diagnosis/diagnose_bench.log",
    benchmark:
        "benchmarks/diagnosis/diagnose_bench.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=120,
    shell:
        "asphalt-nscd diagnose-bench --clean {params.clean} --planted {params.planted} "
        "--base-seed {params.base_seed} --families {params.families} --alpha {params.alpha} "
        "-o {output.bench} --table {output.table} 2> {log}"


REPORT_FILES += [
    "results/diagnosis/what_the_simulation_gets_wrong.md",
    "results/diagnosis/error_budget.png",
    "results/diagnosis/error_budget.csv",
    "results/diagnosis/causes.csv",
    "results/diagnosis/gain.csv",
    "results/diagnosis/report.json",
    LAW_JSON,
    "results/diagnosis/corrected_measured.csv",
    "results/diagnosis/detection_bench.json",
    "results/diagnosis/detection_bench.csv",
]
