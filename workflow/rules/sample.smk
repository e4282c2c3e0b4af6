# Numerical sample preparation (paper Section 3.2.1): one rule per sample, named s{seed}
# after config["sample"]["seeds"]. Jobs read the run's configuration ($ASPHALT_NSCD_RUN_CONFIG, workflow/rules/common.smk);
# the settings they take from it are kept as `settings` params, so a change of them reruns the samples.
# Rerun one sample: `snakemake --cores 1 results/samples/s1.h5 --forcerun prepare_sample`.
from asphalt_nscd import plan


rule prepare_sample:
    output:
        h5="results/samples/s{seed}.h5",
        summary="results/samples/s{seed}_summary.json",
        vtk=directory("results/samples/s{seed}"),
        figure=report(
            "results/samples/s{seed}_stages.png",
            caption="../report/sample_stages.rst",
            category="Numerical samples",
            subcategory="s{seed}",
        ),
        bench=report(
            "results/bench/prepare_s{seed}.json",
            caption="../report/sample_prepare_bench.rst",
            category="Numerical samples",
            subcategory="s{seed}",
        ),
    log:
        "logs/samples/s{seed}.log",
    benchmark:
        "benchmarks/samples/s{seed}.tsv"
    wildcard_constraints:
        seed=r"\d+",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.sample_settings(config),
    shell:
        'asphalt-nscd prepare-sample --config "$ASPHALT_NSCD_RUN_CONFIG" --seed {wildcards.seed}'
        " -o {output.h5} --summary {output.summary} --vtk-dir {output.vtk} --figure {output.figure}"
        " --bench {output.bench} 2> {log}"


rule prepare_resolution_sample:
    # a sample of the network-factor resolution study (harmonic.resolution): the sample section
    # with the level's scale and PSD cut (levels equal to the campaign's reuse its samples)
    output:
        h5="results/samples/resolution/{level}/s{seed}.h5",
        summary="results/samples/resolution/{level}/s{seed}_summary.json",
    log:
        "logs/samples/resolution_{level}_s{seed}.log",
    benchmark:
        "benchmarks/samples/resolution_{level}_s{seed}.tsv"
    wildcard_constraints:
        seed=r"\d+",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.from_wildcards(plan.resolution_sample_settings, config),
    shell:
        'asphalt-nscd prepare-sample --config "$ASPHALT_NSCD_RUN_CONFIG" --level {wildcards.level} --seed {wildcards.seed}'
        " -o {output.h5} --summary {output.summary} 2> {log}"


rule sample_table:
    input:
        summaries=expand("results/samples/{sample}_summary.json", sample=plan.sample_names(config)),
    output:
        report(
            "results/samples/table2_counts.csv",
            caption="../report/sample_table2.rst",
            category="Numerical samples",
        ),
    log:
        "logs/samples/table2_counts.log",
    benchmark:
        "benchmarks/samples/table2_counts.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.sample_settings(config)["sample"],
    shell:
        'asphalt-nscd sample-table --config "$ASPHALT_NSCD_RUN_CONFIG" --summaries {input.summaries} -o {output} 2> {log}'
