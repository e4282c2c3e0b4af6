from asphalt_nscd.campaign import plan

# Collects every figure and table of plan.report_files(config) into results/report/
# with an index; `snakemake --report` shows the same files with their captions.


rule report_index:
    input:
        plan.report_files(config),
    output:
        plan.REPORT_INDEX,
    log:
        "logs/report/index.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        "asphalt-nscd collect-report {input} --out-dir results/report -o {output} 2> {log}"
