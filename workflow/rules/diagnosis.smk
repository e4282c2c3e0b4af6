# Diagnosis: what the simulation gets wrong. Steps:
# 0. master_curve: artifact search (nested master-curve fits) and master curve of the measured table,
#    written once (results/diagnosis/master_curve.json) with the artifact-corrected table
#    (results/diagnosis/corrected_measured.csv); extend_law and diagnose read them.
# 1. extend_law: the temperature-aware extended generalized Burger's law (one 2S2P1D backbone and
#    Prony chain at a reference temperature + shift law; static-modulus trend, vertical shift,
#    per-isotherm refinement and spectrum density chosen by cross-validation among
#    diagnosis.law's candidates), written at the measured temperatures
#    (results/diagnosis/generalized_burgers.json, Pa and Pa s) from the corrected table of step 0,
#    with the selection's cross-validation curve. The extended campaign mode runs with it.
# 2. crossval: held-out errors (lofo: leave one frequency out; loto: leave one temperature out)
#    of the paper's Burger's law per isotherm, the extended law and the NSCD sample (harmonic
#    solution with each fold's law / NF_s on the extended mode's first sample); every fold
#    refits the whole procedure of step 1 without its held-out rows (nested selection). One lofo
#    fold (diagnosis.crossval.time_domain) also runs in the time domain (run-2pb) to show that
#    time domain and harmonic solution agree.
# 3. diagnose (reads steps 0-2, refits nothing upstream): error budget per temperature, named causes (statistical tests on nested
#    master-curve fits; simulation causes from the NSCD campaign, the harmonic solver and the
#    time-step phase error) and the gain per temperature, NSCD before -> NSCD after and macro
#    law before -> after, in-sample with the held-out MRE of step 2 beside; plus the detection
#    benchmark on synthetic tables with planted artifacts.
# Simulation inputs (config diagnosis.simulated, harmonic, time_integration, simulated_extended,
# transfer = the network factor JSONs of rule harmonic_transfer):
# "auto" = the workflow's own outputs on the extended mode's samples (campaign.extended.n_samples,
# the same samples before and after), null = not used, or a CSV path.
# Rerun: `snakemake --cores 1 results/diagnosis/report.json --forcerun diagnose`.

from asphalt_nscd import plan

DIAG_CATEGORY = "What the simulation gets wrong"
# one caption for the extended law's material cards (rule export_law)
CARDS_CAPTION = "../report/diagnosis_material_cards.rst"


rule calibrate_search:
    # the level of the artifact search calibrated on the table itself: the whole procedure rerun on
    # diagnosis.calibration.tables tables simulated from the table's fitted clean model (seeded)
    input:
        measured=plan.MEASURED,
        test=plan.MEASURED_TEST,
    output:
        report(
            plan.CALIBRATION_JSON,
            caption="../report/diagnosis_calibration.rst",
            category=DIAG_CATEGORY,
        ),
    log:
        "logs/diagnosis/calibrate_search.log",
    benchmark:
        "benchmarks/diagnosis/calibrate_search.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.diagnosis_settings(config, "search", "calibration"),
    shell:
        'asphalt-nscd calibrate-search --measured {input.measured:q} --test {input.test:q} --config "$ASPHALT_NSCD_RUN_CONFIG" '
        "--jobs {threads} -o {output:q} 2> {log}"


rule master_curve:
    input:
        measured=plan.MEASURED,
        test=plan.MEASURED_TEST,
        calibration=rules.calibrate_search.output[0],
    output:
        search=plan.MASTER_CURVE_JSON,
        corrected=report(
            plan.CORRECTED_TABLE,
            caption="../report/diagnosis_corrected.rst",
            category="Diagnosis",
        ),
    log:
        "logs/diagnosis/master_curve.log",
    benchmark:
        "benchmarks/diagnosis/master_curve.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.diagnosis_settings(config, "search"),
    shell:
        'asphalt-nscd master-curve --measured {input.measured} --test {input.test} --config "$ASPHALT_NSCD_RUN_CONFIG" '
        "--calibration {input.calibration} -o {output.search} --corrected {output.corrected} 2> {log}"


rule extend_law:
    input:
        measured=plan.MEASURED,
        search=rules.master_curve.output.search,
        corrected=rules.master_curve.output.corrected,
        calibration=rules.calibrate_search.output[0],
    output:
        laws=report(
            plan.LAW_JSON,
            caption="../report/diagnosis_extended_law.rst",
            category=DIAG_CATEGORY,
        ),
        curve=report(
            "results/diagnosis/extended_law_cv_curve.csv",
            caption="../report/diagnosis_cv_curve.rst",
            category=DIAG_CATEGORY,
        ),
        card=plan.CARD_LAW_JSON,
        without_flagged="results/diagnosis/law_without_flagged.json",
    log:
        "logs/diagnosis/extend_law.log",
    benchmark:
        "benchmarks/diagnosis/extend_law.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.diagnosis_settings(config, "search", "law"),
    shell:
        'asphalt-nscd extend-law --measured {input.measured} --config "$ASPHALT_NSCD_RUN_CONFIG" --master-curve {input.search} '
        "--corrected-table {input.corrected} --calibration {input.calibration} -o {output.laws} "
        "--cv-curve {output.curve} --card-law {output.card} --without-flagged {output.without_flagged} 2> {log}"


if plan.crossval_time_domain_cell(config):

    rule crossval_fold_law:
        # the law of the lofo fold without the time-domain cell's frequency, at its temperature (the same
        # procedure as that fold of rule crossval)
        input:
            measured=plan.MEASURED,
            calibration=rules.calibrate_search.output[0],
        output:
            f"results/diagnosis/crossval/fold_law_{plan.crossval_time_domain_case(config)}.json",
        log:
            "logs/diagnosis/crossval_fold_law.log",
        benchmark:
            "benchmarks/diagnosis/crossval_fold_law.tsv"
        conda:
            "../envs/asphalt-nscd.yaml"
        params:
            settings=plan.diagnosis_settings(config, "search", "law"),
            frequency=plan.crossval_time_domain_cell(config)["frequency_Hz"],
            temperature=plan.crossval_time_domain_cell(config)["temperature_C"],
        shell:
            'asphalt-nscd extend-law --measured {input.measured} --config "$ASPHALT_NSCD_RUN_CONFIG" --calibration {input.calibration} '
            "--exclude-frequency {params.frequency} --temperatures {params.temperature} -o {output} 2> {log}"

    rule crossval_time_domain:
        # one time-domain NSCD test of the sample with that fold's law (transfer correction on, the
        # extended mode's test settings) at the held-out cell; --verify: it steps in time whatever
        # campaign.test.method says
        input:
            sample=plan.sample_file(plan.crossval_sample(config)),
            law=rules.crossval_fold_law.output[0],
            transfer=plan.transfer_file(plan.crossval_sample(config)),
        output:
            record=f"results/diagnosis/crossval/time_domain_{plan.crossval_time_domain_case(config)}.h5",
            row=plan.crossval_time_domain_row(config),
        log:
            "logs/diagnosis/crossval_time_domain.log",
        benchmark:
            "benchmarks/diagnosis/crossval_time_domain.tsv"
        conda:
            "../envs/asphalt-nscd.yaml"
        params:
            sample=plan.crossval_sample(config),
            temperature=plan.crossval_time_domain_cell(config)["temperature_C"],
            frequency=plan.crossval_time_domain_cell(config)["frequency_Hz"],
            settings=plan.mode_settings(config, "extended"),
        shell:
            "asphalt-nscd run-2pb --sample {input.sample} --sample-name {params.sample} --mode crossval"
            " --law-json {input.law} --temperature {params.temperature} --frequency {params.frequency}"
            ' --network-factor-json {input.transfer} --config "$ASPHALT_NSCD_RUN_CONFIG" --settings-mode extended --verify'
            " -o {output.record} --row {output.row} 2> {log}"


rule export_law:
    # material cards: relaxation Prony series + WLF shift (Abaqus, LS-DYNA, JSON, CSV) of the law a card carries,
    # with what it loses against the selected law and its errors against the measured means at every cell
    input:
        card=rules.extend_law.output.card,
        law=rules.extend_law.output.laws,
        summary=plan.MEASURED_SUMMARY,
        corrected=rules.master_curve.output.corrected,
        test=plan.MEASURED_TEST,
    output:
        abaqus=report(
            plan.MATERIAL_CARDS["abaqus"],
            caption=CARDS_CAPTION,
            category="Diagnosis",
        ),
        lsdyna=report(plan.MATERIAL_CARDS["lsdyna"], caption=CARDS_CAPTION, category="Diagnosis"),
        json=report(plan.MATERIAL_CARDS["json"], caption=CARDS_CAPTION, category="Diagnosis"),
        table=report(plan.MATERIAL_CARDS["table"], caption=CARDS_CAPTION, category="Diagnosis"),
        errors=report(plan.MATERIAL_CARDS["errors"], caption=CARDS_CAPTION, category="Diagnosis"),
        functions=report(plan.MATERIAL_CARDS["functions"], caption=CARDS_CAPTION, category="Diagnosis"),
    log:
        "logs/diagnosis/export_law.log",
    benchmark:
        "benchmarks/diagnosis/export_law.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        out_dir=plan.output_directory,
        settings=plan.command_settings(config, "export-law"),
    shell:
        "asphalt-nscd export-law --law-json {input.card} --selected-law-json {input.law} --measured {input.summary}"
        ' --corrected {input.corrected} --test {input.test} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {params.out_dir} 2> {log}'


rule crossval:
    input:
        measured=plan.MEASURED,
        calibration=rules.calibrate_search.output[0],
        sample=plan.sample_file(plan.crossval_sample(config)),
        transfer=plan.transfer_file(plan.crossval_sample(config)),
        time_domain=plan.from_wildcards(plan.crossval_time_domain_input, config),
    output:
        rows=report(
            plan.crossval_file("{scheme}"),
            caption="../report/diagnosis_crossval.rst",
            category=DIAG_CATEGORY,
            subcategory="Held-out validation",
        ),
        summary=report(
            plan.crossval_file("{scheme}", "_summary.csv"),
            caption="../report/diagnosis_crossval.rst",
            category=DIAG_CATEGORY,
            subcategory="Held-out validation",
        ),
        curve=report(
            plan.crossval_file("{scheme}", "_curve.csv"),
            caption="../report/diagnosis_cv_curve.rst",
            category=DIAG_CATEGORY,
            subcategory="Held-out validation",
        ),
        figure=report(
            plan.crossval_file("{scheme}", ".png"),
            caption="../report/diagnosis_crossval_figure.rst",
            category=DIAG_CATEGORY,
            subcategory="Held-out validation",
        ),
    log:
        "logs/diagnosis/crossval_{scheme}.log",
    benchmark:
        "benchmarks/diagnosis/crossval_{scheme}.tsv"
    wildcard_constraints:
        scheme="lofo|loto|loso",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.diagnosis_settings(config, "search", "law"),
        time_domain=plan.input_options(time_domain="--time-domain"),
    shell:
        'asphalt-nscd crossval --measured {input.measured} --scheme {wildcards.scheme} --config "$ASPHALT_NSCD_RUN_CONFIG" '
        "--calibration {input.calibration} --sample {input.sample} --transfer {input.transfer} {params.time_domain} -o {output.rows} "
        "--summary {output.summary} --curve {output.curve} --figure {output.figure} 2> {log}"


rule diagnose:
    input:
        unpack(plan.diagnosis_input_function(config)),
        measured=plan.MEASURED,
        search=rules.master_curve.output.search,
        corrected=rules.master_curve.output.corrected,
        macro=plan.BURGERS_PARAMETERS,
        laws=plan.LAW_JSON,
        crossval=plan.crossval_files(config),
        test=plan.MEASURED_TEST,
        card=plan.MATERIAL_CARDS["json"],
        without_flagged=rules.extend_law.output.without_flagged,
    output:
        report=report(
            "results/diagnosis/report.json",
            caption="../report/diagnosis_what_goes_wrong.rst",
            category=DIAG_CATEGORY,
        ),
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
        page=report(plan.DIAGNOSIS_PAGE, caption="../report/diagnosis_what_goes_wrong.rst", category=DIAG_CATEGORY),
    log:
        "logs/diagnosis/diagnose.log",
    benchmark:
        "benchmarks/diagnosis/diagnose.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        simulations=plan.input_options(**plan.DIAGNOSIS_INPUT_OPTIONS),
        settings=plan.diagnosis_settings(config, "causes"),
    shell:
        "asphalt-nscd diagnose --measured {input.measured} --test {input.test} --master-curve {input.search} "
        "--corrected-table {input.corrected} --macro-params {input.macro} --law-json {input.laws} "
        '--crossval {input.crossval} --card {input.card} --law-without-flagged {input.without_flagged} {params.simulations} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output.report} '
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
    log:
        "logs/diagnosis/diagnose_bench.log",
    benchmark:
        "benchmarks/diagnosis/diagnose_bench.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.diagnosis_settings(config, "bench"),
    shell:
        'asphalt-nscd diagnose-bench --config "$ASPHALT_NSCD_RUN_CONFIG" --jobs {threads} -o {output.bench} --table {output.table} 2> {log}'


rule own_table:
    # "your own table" (README, make table TABLE=...): the law JSON, its material cards, the master-curve
    # figures, the held-out errors and the diagnosis page of measured.table, without the NSCD campaign
    # (config/table.yaml sets the diagnosis' simulation inputs to null). results/lab and results/diagnosis are
    # the working area; this rule, the last, copies the run's results into results/tables/<folder>-<table>/
    # with manifest.json (the table's SHA-256, each file's), in place only once every step has succeeded.
    input:
        measured=plan.MEASURED,
        files=[
            *rules.measured_table.output,
            *rules.calibrate_search.output,
            *rules.master_curve.output,
            *rules.extend_law.output,
            *rules.export_law.output,
            *expand(rules.crossval.output, scheme=config["diagnosis"]["crossval"]["schemes"]),
            *plan.MASTER_CURVE_FIGURES.values(),
            *plan.MATERIAL_CARD_FIGURES.values(),
            plan.SIGMOID_TABLE,
            *rules.diagnose.output,
        ],
    output:
        directory(plan.own_table_dir(config)),
    log:
        "logs/diagnosis/own_table.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        table=config["measured"]["table"],
    shell:
        "asphalt-nscd publish-table {input.files:q} --table {params.table:q} --measured {input.measured:q}"
        " -o {output:q} 2> {log}"
