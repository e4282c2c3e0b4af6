# Lab data (src/asphalt_nscd/lab): validation of the measured complex-modulus table (tidy table + replicate summary
# + its declared test geometry, results/lab/measured.test.json, read by the diagnosis)
# and EN 12697-26 reduction (Eqs. 1-5) of raw 2PB records listed under lab.records.
# Rerun one target: `snakemake --cores 1 results/lab/measured.csv --forcerun measured_table`.

from asphalt_nscd import plan


rule measured_table:
    input:
        table=config["measured"]["table"],
        test=plan.measured_test_input(config),
    output:
        table=report(
            plan.MEASURED,
            caption="../report/lab_measured.rst",
            category="Lab data",
        ),
        summary=report(
            plan.MEASURED_SUMMARY,
            caption="../report/lab_measured_summary.rst",
            category="Lab data",
        ),
        test=plan.MEASURED_TEST,
    log:
        "logs/lab/measured_table.log",
    benchmark:
        "benchmarks/lab/measured_table.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        test=plan.input_options(test="--test"),
    shell:
        "asphalt-nscd measured {input.table:q} {params.test} -o {output.table:q} --summary {output.summary:q} "
        "--test-output {output.test:q} 2> {log:q}"


rule reduce_record:
    input:
        record=plan.from_wildcards(plan.record_file, config),
        meta=plan.from_wildcards(plan.record_meta, config),
    output:
        report(
            "results/lab/reduced/{record}.csv",
            caption="../report/lab_reduced.rst",
            category="Lab data",
        ),
    log:
        "logs/lab/reduce_{record}.log",
    benchmark:
        "benchmarks/lab/reduce_{record}.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "reduce"),
    shell:
        'asphalt-nscd reduce {input.record} --meta {input.meta} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output} 2> {log}'
