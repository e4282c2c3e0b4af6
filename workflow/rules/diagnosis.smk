# Diagnosis: what the simulation gets wrong. Steps:
# 1. extend_law: the temperature-aware extended generalized Burger's law (one 2S2P1D backbone and
#    Prony chain at a reference temperature + shift law; static-modulus trend, vertical shift,
#    per-isotherm refinement and spectrum density chosen by cross-validation among
#    diagnosis.law's candidates), written at the measured temperatures
#    (results/diagnosis/generalized_burgers.json, Pa and Pa s) from the measured table alone,
#    with the selection's cross-validation curve. The extended campaign mode runs with it.
# 2. crossval: held-out errors (lofo: leave one frequency out; loto: leave one temperature out)
#    of the paper's Burger's law per isotherm, the extended law and the NSCD sample (harmonic
#    solution with each fold's law / NF_s on the extended mode's first sample); every fold
#    refits the whole procedure of step 1 without its held-out rows (nested selection). One lofo
#    fold (diagnosis.crossval.time_domain) also runs in the time domain (run-2pb) to show that
#    time domain and harmonic solution agree.
# 3. diagnose: error budget per temperature, named causes (statistical tests on nested
#    master-curve fits; simulation causes from the NSCD campaign, the harmonic solver and the
#    time-step phase error) and the gain per temperature, NSCD before -> NSCD after and macro
#    law before -> after, in-sample with the held-out MRE of step 2 beside; plus the detection
#    benchmark on synthetic tables with planted artifacts.
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
    """Options of the artifact search and of the extended law's candidates (diagnosis.law)."""
    law = DIAG["law"]
    refines = " ".join("off" if r is None else str(r) for r in law["refines"])
    opts = (
        f"--alpha {DIAG['alpha']} --shift {DIAG['shift']} "
        f"--law-shifts {' '.join(law['shifts'])} --law-statics {' '.join(law['statics'])} "
        f"--law-verticals {' '.join('on' if v else 'off' for v in law['verticals'])} "
        f"--law-refines {refines} --law-per-decades {' '.join(str(p) for p in law['per_decades'])} "
        f"--margin-decades {law['margin_decades']} "
        f"--tolerances-pct {law['tolerances_pct'][0]} {law['tolerances_pct'][1]}"
    )
    if DIAG.get("T_ref_C") is not None:
        opts += f" --t-ref {DIAG['T_ref_C']}"
    if not law.get("one_se", True):
        opts += " --no-one-se"
    if not law.get("artifacts", True):
        opts += " --no-artifacts"
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
        curve=report(
            "results/diagnosis/extended_law_cv_curve.csv",
            caption="../report/diagnosis_cv_curve.rst",
            category=DIAG_CATEGORY,
        ),
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
        "--corrected {output.corrected} --cv-curve {output.curve} 2> {log}"


# the cross-validation: its sample (the extended mode's first), and the lofo fold run in the time domain
CV = DIAG["crossval"]
CV_SAMPLE = mode_samples("extended")[0]


def _time_domain_cell(value):
    """The (T, f) of the time-domain check: given, or ``auto``: the median tested temperature
    (the lower of the two middle ones) and its tested frequency nearest 10 Hz (read from config
    measured.table); None when null. A given cell must be measured."""
    import csv
    import math

    from snakemake.exceptions import WorkflowError

    if value is None:
        return None
    try:
        with open(config["measured"]["table"], newline="") as fh:
            cells = {(float(r["temperature_C"]), float(r["frequency_Hz"])) for r in csv.DictReader(fh)}
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise WorkflowError(f"config diagnosis.crossval.time_domain: cannot read the measured cells of "
                            f"{config['measured']['table']} ({exc!r}); set the cell or null")
    if value == "auto":
        temps = sorted({T for T, _ in cells})
        T = temps[(len(temps) - 1) // 2]
        f = min((f for t, f in cells if t == T), key=lambda f: (abs(math.log10(f) - 1.0), f))
        return {"temperature_C": T, "frequency_Hz": f}
    if (float(value["temperature_C"]), float(value["frequency_Hz"])) not in cells:
        raise WorkflowError(f"config diagnosis.crossval.time_domain: {value['temperature_C']} degC, "
                            f"{value['frequency_Hz']} Hz is not a measured cell of {config['measured']['table']}")
    return value


CV_TD = _time_domain_cell(CV["time_domain"])
CV_TD_CASE = case_name(CV_TD["temperature_C"], CV_TD["frequency_Hz"]) if CV_TD else None


if CV_TD:

    rule crossval_fold_law:
        # the law of the lofo fold without CV_TD's frequency, at CV_TD's temperature (the same
        # procedure as that fold of rule crossval)
        input:
            measured="results/lab/measured.csv",
        output:
            f"results/diagnosis/crossval/fold_law_{CV_TD_CASE}.json",
        params:
            options=_fit_options(),
            frequency=CV_TD["frequency_Hz"],
            temperature=CV_TD["temperature_C"],
        log:
            "logs/diagnosis/crossval_fold_law.log",
        benchmark:
            "benchmarks/diagnosis/crossval_fold_law.tsv"
        threads: 1
        resources:
            mem_mb=1000,
            runtime=15,
        shell:
            "asphalt-nscd extend-law --measured {input.measured} {params.options} "
            "--exclude-frequency {params.frequency} --temperatures {params.temperature} -o {output} 2> {log}"


    rule crossval_time_domain:
        # one time-domain NSCD test of the sample with that fold's law (transfer correction on, the
        # extended mode's test settings) at the held-out cell
        input:
            sample=sample_file(CV_SAMPLE),
            law=rules.crossval_fold_law.output[0],
            transfer=transfer_file(CV_SAMPLE),
        output:
            record=f"results/diagnosis/crossval/time_domain_{CV_TD_CASE}.h5",
            row=f"results/diagnosis/crossval/time_domain_{CV_TD_CASE}.csv",
        params:
            sample=CV_SAMPLE,
            temperature=CV_TD["temperature_C"],
            frequency=CV_TD["frequency_Hz"],
            settings=test_json("extended"),
            window=WINDOW_CYCLES,
        log:
            "logs/diagnosis/crossval_time_domain.log",
        benchmark:
            "benchmarks/diagnosis/crossval_time_domain.tsv"
        threads: 1
        resources:
            mem_mb=2000,
            runtime=CAMP["job_runtime_min"],
        shell:
            "asphalt-nscd run-2pb --sample {input.sample} --sample-name {params.sample} --mode crossval"
            " --law-json {input.law} --temperature {params.temperature} --frequency {params.frequency}"
            " --network-factor-json {input.transfer} --settings-json {params.settings:q}"
            " --window-cycles {params.window} -o {output.record} --row {output.row} 2> {log}"


rule crossval:
    input:
        measured="results/lab/measured.csv",
        sample=sample_file(CV_SAMPLE),
        transfer=transfer_file(CV_SAMPLE),
        time_domain=lambda wc: [rules.crossval_time_domain.output.row] if wc.scheme == "lofo" and CV_TD else [],
    output:
        rows=report(
            "results/diagnosis/crossval/{scheme}.csv",
            caption="../report/diagnosis_crossval.rst",
            category=DIAG_CATEGORY,
            subcategory="Held-out validation",
        ),
        summary=report(
            "results/diagnosis/crossval/{scheme}_summary.csv",
            caption="../report/diagnosis_crossval.rst",
            category=DIAG_CATEGORY,
            subcategory="Held-out validation",
        ),
        curve=report(
            "results/diagnosis/crossval/{scheme}_curve.csv",
            caption="../report/diagnosis_cv_curve.rst",
            category=DIAG_CATEGORY,
            subcategory="Held-out validation",
        ),
        figure=report(
            "results/diagnosis/crossval/{scheme}.png",
            caption="../report/diagnosis_crossval_figure.rst",
            category=DIAG_CATEGORY,
            subcategory="Held-out validation",
        ),
    wildcard_constraints:
        scheme="lofo|loto",
    params:
        options=_fit_options(),
        time_domain=lambda wc, input: f"--time-domain {input.time_domain}" if input.time_domain else "",
    log:
        "logs/diagnosis/crossval_{scheme}.log",
    benchmark:
        "benchmarks/diagnosis/crossval_{scheme}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=60,
    shell:
        "asphalt-nscd crossval --measured {input.measured} --scheme {wildcards.scheme} {params.options} "
        "--sample {input.sample} --transfer {input.transfer} {params.time_domain} -o {output.rows} "
        "--summary {output.summary} --curve {output.curve} --figure {output.figure} 2> {log}"


CROSSVAL_ROWS = expand("results/diagnosis/crossval/{scheme}.csv", scheme=CV["schemes"])


rule diagnose:
    input:
        measured="results/lab/measured.csv",
        macro="results/calibration/burgers_parameters.csv",
        laws=LAW_JSON,
        crossval=CROSSVAL_ROWS,
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
        "--law-json {input.laws} --crossval {input.crossval} {params.options} {params.tolerances} -o {output.report} "
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
    "results/diagnosis/extended_law_cv_curve.csv",
    "results/diagnosis/corrected_measured.csv",
    "results/diagnosis/detection_bench.json",
    "results/diagnosis/detection_bench.csv",
]
REPORT_FILES += [
    f"results/diagnosis/crossval/{scheme}{suffix}"
    for scheme in CV["schemes"]
    for suffix in (".csv", "_summary.csv", "_curve.csv", ".png")
]
