# Harmonic (frequency-domain) solver of the bonded samples: exact steady-state |E*|, Phi of
# the discrete model per (T, f), for both parameter modes:
#   paper    = the paper's Table 3 (results/calibration/paper_table3.csv) x harmonic.paper_frequencies_Hz
#   measured = results/calibration/burgers_parameters.csv at the measured (T, f) of the lab summary
# plus a dense frequency sweep (isotherms, Black, Cole-Cole beside the macro law and the
# measured data), the network factor table (sample |E*| / macro |E*|), the sensitivity study
# on a finer grid, the time-domain (NSCD) check, the kinematics study (network factor per
# bond kinematics x head rotation) and a benchmark. Bond kinematics and head rotation come
# from harmonic.bond_kinematics / head_rotation (default contact + free, consistent with the
# cantilever of EN 12697-26 Eq. 3); the time-domain check uses barycentre + clamped, the
# kinematics of the NSCD core.
# Rerun one target: `snakemake --cores 1 results/harmonic/jobs/s1_paper.csv --forcerun harmonic_jobs`.

from asphalt_nscd import plan


rule harmonic_jobs:
    input:
        sample=plan.sample_file("{sample}"),
        parameters=plan.from_wildcards(plan.harmonic_parameters, config),
        summary=plan.MEASURED_SUMMARY,
    output:
        plan.harmonic_job_file("{sample}", "{mode}"),
    log:
        "logs/harmonic/jobs_{sample}_{mode}.log",
    benchmark:
        "benchmarks/harmonic/jobs_{sample}_{mode}.tsv"
    wildcard_constraints:
        mode="paper|measured",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        frequencies=plan.harmonic_frequency_option,
        settings=plan.from_wildcards(plan.harmonic_job_settings, config),
    shell:
        "asphalt-nscd harmonic --sample {input.sample} --parameters {input.parameters} {params.frequencies}"
        ' --config "$ASPHALT_NSCD_RUN_CONFIG" --mode {wildcards.mode} -o {output} 2> {log}'


rule harmonic_sweep:
    input:
        sample=plan.sample_file("{sample}"),
        parameters=plan.from_wildcards(plan.harmonic_parameters, config),
    output:
        plan.harmonic_sweep_file("{sample}", "{mode}"),
    log:
        "logs/harmonic/sweep_{sample}_{mode}.log",
    benchmark:
        "benchmarks/harmonic/sweep_{sample}_{mode}.tsv"
    wildcard_constraints:
        mode="paper|measured",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "harmonic", grid="sweep"),
    shell:
        "asphalt-nscd harmonic --sample {input.sample} --parameters {input.parameters} --grid sweep"
        ' --config "$ASPHALT_NSCD_RUN_CONFIG" --mode {wildcards.mode} -o {output} 2> {log}'


rule harmonic_figures:
    input:
        sweeps=expand(plan.harmonic_sweep_file("{sample}", "{{mode}}"), sample=plan.sample_names(config)),
        summary=plan.MEASURED_SUMMARY,
    output:
        isotherms_modulus=report(
            "results/harmonic/figures/{mode}_isotherms-modulus.png",
            caption="../report/harmonic_isotherms.rst",
            category="Harmonic solver",
            subcategory="{mode} parameters",
        ),
        isotherms_phase=report(
            "results/harmonic/figures/{mode}_isotherms-phase.png",
            caption="../report/harmonic_isotherms.rst",
            category="Harmonic solver",
            subcategory="{mode} parameters",
        ),
        black=report(
            "results/harmonic/figures/{mode}_black.png",
            caption="../report/harmonic_black.rst",
            category="Harmonic solver",
            subcategory="{mode} parameters",
        ),
        cole_cole=report(
            "results/harmonic/figures/{mode}_cole-cole.png",
            caption="../report/harmonic_cole_cole.rst",
            category="Harmonic solver",
            subcategory="{mode} parameters",
        ),
    log:
        "logs/harmonic/figures_{mode}.log",
    benchmark:
        "benchmarks/harmonic/figures_{mode}.tsv"
    wildcard_constraints:
        mode="paper|measured",
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        "asphalt-nscd harmonic-plot --harmonic {input.sweeps} --measured {input.summary} "
        "--title '{wildcards.mode} parameters' "
        "--isotherms-modulus {output.isotherms_modulus} --isotherms-phase {output.isotherms_phase} "
        "--black {output.black} --cole-cole {output.cole_cole} 2> {log}"


rule harmonic_network_factor:
    input:
        expand(plan.harmonic_job_file("{sample}", "{mode}"), sample=plan.sample_names(config), mode=plan.HARMONIC_MODES),
    output:
        table=report(
            "results/harmonic/network_factor.csv",
            caption="../report/harmonic_network_factor.rst",
            category="Harmonic solver",
        ),
        summary=report(
            "results/harmonic/network_factor_summary.csv",
            caption="../report/harmonic_network_factor.rst",
            category="Harmonic solver",
        ),
    log:
        "logs/harmonic/network_factor.log",
    benchmark:
        "benchmarks/harmonic/network_factor.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        "asphalt-nscd harmonic-network-factor {input} -o {output.table} --summary {output.summary} 2> {log}"


rule harmonic_sensitivity:
    input:
        sample=plan.sample_file(plan.sample_names(config)[0]),
        parameters=plan.HARMONIC_PARAMETERS["paper"],
    output:
        table=report(
            "results/harmonic/sensitivity.csv",
            caption="../report/harmonic_sensitivity.rst",
            category="Harmonic solver",
        ),
        figure=report(
            "results/harmonic/sensitivity.png",
            caption="../report/harmonic_sensitivity.rst",
            category="Harmonic solver",
        ),
    log:
        "logs/harmonic/sensitivity.log",
    benchmark:
        "benchmarks/harmonic/sensitivity.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "harmonic-sensitivity"),
    shell:
        "asphalt-nscd harmonic-sensitivity --sample {input.sample} --parameters {input.parameters}"
        ' --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output.table} --figure {output.figure} 2> {log}'


rule harmonic_compare:
    input:
        sample=plan.sample_file(plan.sample_names(config)[0]),
        parameters=plan.HARMONIC_PARAMETERS["paper"],
    output:
        table=report(
            "results/harmonic/compare_time_domain.csv",
            caption="../report/harmonic_compare.rst",
            category="Harmonic solver",
        ),
        figure=report(
            "results/harmonic/compare_time_domain.png",
            caption="../report/harmonic_compare.rst",
            category="Harmonic solver",
        ),
    log:
        "logs/harmonic/compare_time_domain.log",
    benchmark:
        "benchmarks/harmonic/compare_time_domain.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        # harmonic.compare, and the time-domain core's kinematics (nscd.bond_kinematics,
        # campaign.test.head_rotation) on both sides of the comparison
        settings=plan.command_settings(config, "harmonic-compare"),
    shell:
        "asphalt-nscd harmonic-compare --sample {input.sample} --parameters {input.parameters}"
        ' --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output.table} --figure {output.figure} 2> {log}'


rule harmonic_kinematics:
    input:
        sample=plan.sample_file(plan.sample_names(config)[0]),
        parameters=plan.HARMONIC_PARAMETERS["paper"],
    output:
        report(
            "results/harmonic/kinematics_study.csv",
            caption="../report/harmonic_kinematics.rst",
            category="Harmonic solver",
        ),
    log:
        "logs/harmonic/kinematics_study.log",
    benchmark:
        "benchmarks/harmonic/kinematics_study.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "harmonic-kinematics"),
    shell:
        "asphalt-nscd harmonic-kinematics --sample {input.sample} --parameters {input.parameters}"
        ' --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output} 2> {log}'


rule harmonic_transfer:
    # Network factor NF_s of a sample (no inertia; law-, T- and f-independent) under the
    # time-domain test's kinematics (nscd.bond_kinematics, campaign.test.head_rotation, nu):
    # the transfer correction of the extended campaign mode (run-2pb --network-factor-json).
    input:
        sample=plan.sample_file("{sample}"),
    output:
        plan.transfer_file("{sample}"),
    log:
        "logs/harmonic/transfer_{sample}.log",
    benchmark:
        "benchmarks/harmonic/transfer_{sample}.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "harmonic-transfer"),
    shell:
        'asphalt-nscd harmonic-transfer --sample {input.sample} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output} 2> {log}'


rule harmonic_resolution:
    # network factor against the samples' resolution (harmonic.resolution: levels x seeds), both
    # bond kinematics: does the micro-macro transfer of Eqs. 30-33 tend to 1?
    input:
        [path for _, path in plan.resolution_samples(config)],
    output:
        table="results/harmonic/resolution.csv",
        summary=report(
            "results/harmonic/resolution_summary.csv",
            caption="../report/harmonic_resolution.rst",
            category="Harmonic solver",
        ),
        fits=report(
            "results/harmonic/resolution_fits.csv",
            caption="../report/harmonic_resolution.rst",
            category="Harmonic solver",
        ),
        figure=report(
            "results/harmonic/resolution.png",
            caption="../report/harmonic_resolution.rst",
            category="Harmonic solver",
        ),
    log:
        "logs/harmonic/resolution.log",
    benchmark:
        "benchmarks/harmonic/resolution.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "harmonic-resolution"),
    shell:
        'asphalt-nscd harmonic-resolution --samples {input} --config "$ASPHALT_NSCD_RUN_CONFIG"'
        " -o {output.table} --summary {output.summary} --fits {output.fits} --figure {output.figure} 2> {log}"


rule harmonic_bench:
    output:
        report("results/harmonic/bench.json", caption="../report/harmonic_bench.rst", category="Harmonic solver"),
    log:
        "logs/harmonic/bench.log",
    benchmark:
        "benchmarks/harmonic/bench.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "harmonic-bench"),
    shell:
        'asphalt-nscd harmonic-bench --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output} 2> {log}'
