# Rheology: Burger's calibration of the measured mix (Eqs. 27-29), the paper's Table 3 under the
# chosen unit reading, its refit check and the micro (bond)
# parameters (Eqs. 30-33, 8-11). The rheology figures (asphalt-nscd plot-rheology) are in figures.smk.

from asphalt_nscd import plan


rule fit_burgers:
    input:
        plan.MEASURED,
    output:
        report(
            plan.BURGERS_PARAMETERS,
            caption="../report/calibration_burgers_parameters.rst",
            category="Calibration",
        ),
    log:
        "logs/calibration/fit_burgers.log",
    benchmark:
        "benchmarks/calibration/fit_burgers.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "fit"),
    shell:
        'asphalt-nscd fit --measured {input} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output} 2> {log}'


rule paper_table3:
    input:
        config["calibration"]["table3"],
    output:
        plan.PAPER_TABLE3,
    log:
        "logs/calibration/paper_table3.log",
    benchmark:
        "benchmarks/calibration/paper_table3.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "table3"),
    shell:
        'asphalt-nscd table3 {input} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output} 2> {log}'


rule table3_refit_check:
    input:
        plan.PAPER_TABLE3,
    output:
        report(
            "results/calibration/table3_refit_check.csv",
            caption="../report/calibration_table3_refit_check.rst",
            category="Calibration",
        ),
    log:
        "logs/calibration/table3_refit_check.log",
    benchmark:
        "benchmarks/calibration/table3_refit_check.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "refit-check"),
    shell:
        'asphalt-nscd refit-check --parameters {input} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output} 2> {log}'


rule burgers_curves:
    input:
        plan.CALIBRATION_TABLE,
    output:
        "results/calibration/{table}_curves.csv",
    log:
        "logs/calibration/{table}_curves.log",
    benchmark:
        "benchmarks/calibration/{table}_curves.tsv"
    wildcard_constraints:
        table="burgers_parameters|paper_table3",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "burgers-curves"),
    shell:
        'asphalt-nscd burgers-curves --parameters {input} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output} 2> {log}'


rule micro_parameters:
    input:
        plan.CALIBRATION_TABLE,
    output:
        report(
            "results/calibration/{table}_micro.csv",
            caption="../report/calibration_micro.rst",
            category="Calibration",
        ),
    log:
        "logs/calibration/{table}_micro.log",
    benchmark:
        "benchmarks/calibration/{table}_micro.tsv"
    wildcard_constraints:
        table="burgers_parameters|paper_table3",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.command_settings(config, "micro"),
    shell:
        'asphalt-nscd micro --parameters {input} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output} 2> {log}'
