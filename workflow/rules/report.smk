# Collects every figure and table registered in REPORT_FILES into results/report/
# with an index; `snakemake --report` shows the same files with their captions.


rule report_index:
    input:
        REPORT_FILES,
    output:
        "results/report/index.md",
    log:
        "logs/report/index.log",
    shell:
        "asphalt-nscd collect-report {input} --out-dir results/report -o {output} 2> {log}"
