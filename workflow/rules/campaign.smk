# Campaign (src/asphalt_nscd/campaign): the numerical 2PB complex modulus test (paper Section 3.2.2), the campaign over samples x
# temperatures x frequencies in two modes, the time-step study, the sensitivity study and the
# Table 3 units question (Sections 3.2-4). One job per (mode, sample, T, f[, variant]):
#   results/sim/{mode}/{sample}/{T}C_{f}Hz[_dt{dt} | _{param}x{factor}].h5 (record) + .csv (row)
# Modes: paper (Table 3 under calibration.table3_units), measured (calibrated parameters),
# extended (the measured mode's schedule and settings with the generalized Burger's law of the
# diagnosis, results/diagnosis/generalized_burgers.json, on campaign.extended.n_samples
# samples; with campaign.extended.transfer_correction the bond law is divided by the sample's
# network factor NF_s, results/harmonic/transfer/{sample}.json), and the studies: dt_study, sensitivity, units_Pa, units_kPa (paper parameters).
# Start of each job (campaign.test.start, per-mode `start`): rest (n_cycles) or periodic
# (periodic_cycles from the periodic steady state, asphalt_nscd.harmonic.periodic); the row's
# `start` column says which was used.
# What a sample's jobs share and no law changes (held spheres, gravity solution) is computed once (rule rig_state).
# Rerun one job: `snakemake --cores 1 results/sim/paper/s1/15C_40Hz.csv --forcerun run_2pb`.
from asphalt_nscd import plan


rule rig_state:
    # what every 2PB job of a sample shares and no law changes: the spheres the rig holds and the
    # law-free gravity solution under the test settings (one factorisation per sample, not per job)
    input:
        sample=plan.sample_file("{sample}"),
    output:
        plan.rig_state_file("{sample}"),
    log:
        "logs/campaign/rig_{sample}.log",
    benchmark:
        "benchmarks/campaign/rig_{sample}.tsv"
    wildcard_constraints:
        sample=r"s\d+",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.rig_state_settings(config),
    shell:
        'asphalt-nscd rig-state --sample {input.sample} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output} 2> {log}'


rule run_2pb:
    input:
        sample=plan.sample_file("{sample}"),
        rig=plan.rig_state_file("{sample}"),
        parameters=plan.from_wildcards(plan.mode_parameters, config),
        transfer=plan.from_wildcards(plan.job_transfer, config),
    output:
        record="results/sim/{mode}/{sample}/{case}.h5",
        row="results/sim/{mode}/{sample}/{case}.csv",
    log:
        "logs/sim/{mode}/{sample}/{case}.log",
    benchmark:
        "benchmarks/sim/{mode}/{sample}/{case}.tsv"
    wildcard_constraints:
        mode=plan.JOB_MODES,
        sample=r"s\d+",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        source=plan.from_wildcards(plan.law_option, config),
        case=plan.from_wildcards(plan.case_options, config),
        transfer=plan.input_options(transfer="--network-factor-json"),
        settings=plan.from_wildcards(plan.mode_settings, config),
        job=plan.from_wildcards(plan.job_values, config),
    shell:
        "asphalt-nscd run-2pb --sample {input.sample} --rig-state {input.rig} --sample-name {wildcards.sample} --mode {wildcards.mode}"
        ' {params.source} {input.parameters} {params.case} {params.transfer} --config "$ASPHALT_NSCD_RUN_CONFIG"'
        " -o {output.record} --row {output.row} 2> {log}"


rule campaign_isotherms:
    input:
        rows=plan.from_wildcards(plan.mode_rows, config),
        parameters=plan.from_wildcards(plan.mode_parameters, config),
        summary=plan.from_wildcards(plan.mode_summary, config),
        paper_table4=plan.from_wildcards(plan.mode_paper_table4, config),
    output:
        isotherms="results/campaign/{mode}/numerical_isotherms.csv",
        table4=report(
            "results/campaign/{mode}/table4_{mode}.csv",
            caption="../report/campaign_table4.rst",
            category="Campaign",
            subcategory="{mode}",
        ),
        modulus=report(
            "results/campaign/{mode}/figures/fig09_isotherms_modulus.png",
            caption="../report/campaign_isotherms.rst",
            category="Campaign",
            subcategory="{mode}",
        ),
        phase=report(
            "results/campaign/{mode}/figures/fig10_isotherms_phase.png",
            caption="../report/campaign_isotherms.rst",
            category="Campaign",
            subcategory="{mode}",
        ),
    log:
        "logs/campaign/{mode}_isotherms.log",
    benchmark:
        "benchmarks/campaign/{mode}_isotherms.tsv"
    wildcard_constraints:
        mode=plan.ISOTHERM_MODES,
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        source=plan.from_wildcards(plan.law_option, config),
        references=plan.input_options(summary="--measured-summary", paper_table4="--paper-table4"),
        settings=plan.from_wildcards(plan.isotherm_settings, config),
    shell:
        "asphalt-nscd campaign-isotherms --rows {input.rows} {params.source} {input.parameters} {params.references}"
        ' --mode {wildcards.mode} --config "$ASPHALT_NSCD_RUN_CONFIG" --isotherms {output.isotherms}'
        " --table4 {output.table4} --figure-modulus {output.modulus} --figure-phase {output.phase} 2> {log}"


rule campaign_dt_study:
    input:
        records=plan.dt_study_files(config, "h5"),
        rows=plan.dt_study_files(config, "csv"),
        parameters=config["calibration"]["table3"],
    output:
        table=report(
            "results/campaign/paper/dt_study.csv", caption="../report/campaign_dt_study.rst", category="Campaign"
        ),
        figure=report(
            "results/campaign/paper/figures/fig06_dt_study.png",
            caption="../report/campaign_dt_study.rst",
            category="Campaign",
        ),
    log:
        "logs/campaign/dt_study.log",
    benchmark:
        "benchmarks/campaign/dt_study.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "campaign-dt-study"),
    shell:
        "asphalt-nscd campaign-dt-study --records {input.records} --rows {input.rows}"
        ' --parameters {input.parameters} --config "$ASPHALT_NSCD_RUN_CONFIG"'
        " --table {output.table} --figure {output.figure} 2> {log}"


rule campaign_last_cycle:
    input:
        record=plan.last_cycle_record(config),
    output:
        cycle=report(
            "results/campaign/paper/figures/fig07_last_cycle.png",
            caption="../report/campaign_last_cycle.rst",
            category="Campaign",
        ),
        profile=report(
            "results/campaign/paper/figures/fig08_velocity_profile.png",
            caption="../report/campaign_velocity_profile.rst",
            category="Campaign",
        ),
    log:
        "logs/campaign/last_cycle.log",
    benchmark:
        "benchmarks/campaign/last_cycle.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        "asphalt-nscd campaign-last-cycle --record {input.record} --figure-cycle {output.cycle}"
        " --figure-profile {output.profile} 2> {log}"


rule campaign_sensitivity:
    input:
        rows=plan.sensitivity_rows(config),
        baseline=plan.sensitivity_baseline(config),
        parameters=config["calibration"]["table3"],
    output:
        table=report(
            "results/campaign/paper/sensitivity.csv",
            caption="../report/campaign_sensitivity.rst",
            category="Campaign",
        ),
        figures=report(
            plan.sensitivity_figures(),
            caption="../report/campaign_sensitivity.rst",
            category="Campaign",
        ),
    log:
        "logs/campaign/sensitivity.log",
    benchmark:
        "benchmarks/campaign/sensitivity.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "campaign-sensitivity"),
    shell:
        "asphalt-nscd campaign-sensitivity --rows {input.rows} --baseline {input.baseline}"
        ' --parameters {input.parameters} --config "$ASPHALT_NSCD_RUN_CONFIG"'
        " --table {output.table} --figures {output.figures} 2> {log}"


rule campaign_units_question:
    input:
        rows_pa=plan.units_rows(config, "Pa"),
        rows_kpa=plan.units_rows(config, "kPa"),
        rows_kpa_nobreak=plan.units_rows(config, "kPa", nobreak=True),
        table3=config["calibration"]["table3"],
        sample=plan.sample_file(plan.sample_names(config)[0]),
        summary=plan.MEASURED_SUMMARY,
    output:
        table=report(
            "results/campaign/units_question.csv",
            caption="../report/campaign_units_question.rst",
            category="Campaign",
        ),
        evidence=report(
            "results/campaign/units_evidence.csv",
            caption="../report/campaign_units_evidence.rst",
            category="Campaign",
        ),
    log:
        "logs/campaign/units_question.log",
    benchmark:
        "benchmarks/campaign/units_question.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "campaign-units"),
    shell:
        "asphalt-nscd campaign-units --table3 {input.table3} --rows-pa {input.rows_pa} --rows-kpa {input.rows_kpa}"
        ' --rows-kpa-nobreak {input.rows_kpa_nobreak} --sample {input.sample} --config "$ASPHALT_NSCD_RUN_CONFIG"'
        " -o {output.table} --evidence {output.evidence}"
        " --measured-summary {input.summary} 2> {log}"


rule campaign_dt_policy:
    input:
        parameters=plan.from_wildcards(plan.mode_parameters, config),
    output:
        report(
            "results/campaign/{mode}/dt_policy_phase_error.csv",
            caption="../report/campaign_dt_policy.rst",
            category="Campaign",
            subcategory="{mode}",
        ),
    log:
        "logs/campaign/{mode}_dt_policy.log",
    benchmark:
        "benchmarks/campaign/{mode}_dt_policy.tsv"
    wildcard_constraints:
        mode=plan.POLICY_MODES,
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.from_wildcards(plan.mode_settings, config),
        policy=plan.from_wildcards(plan.policy_settings, config),
    shell:
        "asphalt-nscd campaign-dt-policy --parameters {input.parameters}"
        ' --config "$ASPHALT_NSCD_RUN_CONFIG" --settings-mode {wildcards.mode} -o {output} 2> {log}'
