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
        options=plan.calibration_fit_options(config),
        model=config["calibration"]["model"],
    shell:
        "asphalt-nscd fit --measured {input} --model {params.model} {params.options} -o {output} 2> {log}"


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
        units=config["calibration"]["table3_units"],
    shell:
        "asphalt-nscd table3 {input} --units {params.units} -o {output} 2> {log}"


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
        options=plan.calibration_fit_options(config),
        frequencies=plan.spaced(config["calibration"]["refit_frequencies_Hz"]),
    shell:
        "asphalt-nscd refit-check --parameters {input} --frequencies {params.frequencies} "
        "{params.options} -o {output} 2> {log}"


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
        fmin=config["calibration"]["curves"]["fmin_Hz"],
        fmax=config["calibration"]["curves"]["fmax_Hz"],
        points=config["calibration"]["curves"]["points"],
    shell:
        "asphalt-nscd burgers-curves --parameters {input} --fmin {params.fmin} --fmax {params.fmax} "
        "--points {params.points} -o {output} 2> {log}"


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
        r_min=plan.spaced(config["calibration"]["micro"]["r_min_mm"]),
        l0=plan.spaced(config["calibration"]["micro"]["l0_mm"]),
        nu=config["calibration"]["micro"]["poisson_ratio"],
        mass=config["calibration"]["micro"]["grain_mass_kg"],
    shell:
        "asphalt-nscd micro --parameters {input} --r-min-mm {params.r_min} --l0-mm {params.l0} "
        "--nu {params.nu} --grain-mass-kg {params.mass} -o {output} 2> {log}"
