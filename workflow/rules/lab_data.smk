# Lab data: validation of the measured complex-modulus table (tidy table + replicate summary
# + its declared test geometry, results/lab/measured.test.json, read by the diagnosis)
# and EN 12697-26 reduction (Eqs. 1-5) of raw 2PB records listed under lab.records.
# Rerun one target: `snakemake --cores 1 results/lab/measured.csv --forcerun measured_table`.

LAB_RECORDS = {Path(p).stem: p for p in config["lab"].get("records", [])}
# the test-geometry JSON of the measured table: config measured.test, else its sidecar
_MEASURED_TABLE = Path(config["measured"]["table"])
MEASURED_TEST = config["measured"].get("test") or str(_MEASURED_TABLE.with_name(_MEASURED_TABLE.stem + ".test.json"))


rule measured_table:
    input:
        table=config["measured"]["table"],
        test=[MEASURED_TEST] if Path(MEASURED_TEST).is_file() or config["measured"].get("test") else [],
    output:
        table=report(
            "results/lab/measured.csv",
            caption="../report/lab_measured.rst",
            category="Lab data",
        ),
        summary=report(
            "results/lab/measured_summary.csv",
            caption="../report/lab_measured_summary.rst",
            category="Lab data",
        ),
        test="results/lab/measured.test.json",
    params:
        test=lambda wc, input: f"--test {input.test[0]}" if input.test else "",
    log:
        "logs/lab/measured_table.log",
    benchmark:
        "benchmarks/lab/measured_table.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    shell:
        "asphalt-nscd measured {input.table} {params.test} -o {output.table} --summary {output.summary} "
        "--test-output {output.test} 2> {log}"


rule reduce_record:
    input:
        record=lambda wc: LAB_RECORDS[wc.record],
        meta=lambda wc: str(Path(LAB_RECORDS[wc.record]).with_suffix(".json")),
    output:
        report(
            "results/lab/reduced/{record}.csv",
            caption="../report/lab_reduced.rst",
            category="Lab data",
        ),
    params:
        window_s=config["lab"]["window_s"],
    log:
        "logs/lab/reduce_{record}.log",
    benchmark:
        "benchmarks/lab/reduce_{record}.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    shell:
        "asphalt-nscd reduce {input.record} --meta {input.meta} --window-s {params.window_s} -o {output} 2> {log}"


REPORT_FILES += ["results/lab/measured.csv", "results/lab/measured_summary.csv"]
REPORT_FILES += expand("results/lab/reduced/{record}.csv", record=sorted(LAB_RECORDS))
