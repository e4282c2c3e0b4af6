# Figures and the report (src/asphalt_nscd/figures): the rheology figures of the measured mix and
# of the paper's Table 3 (isotherms, Black diagram, Cole-Cole plane; asphalt-nscd plot-rheology),
# and the report index: every output the rules flag with report() (plan.report_files) collected into
# results/report/ (asphalt-nscd collect-report); `snakemake --report` shows the same files with
# their captions.

from asphalt_nscd import plan


rule rheology_figures:
    input:
        summary=plan.MEASURED_SUMMARY,
        curves="results/calibration/burgers_parameters_curves.csv",
    output:
        isotherms_modulus=report(
            "results/calibration/figures/measured_isotherms-modulus.png",
            caption="../report/calibration_isotherms_modulus.rst",
            category="Calibration",
        ),
        isotherms_phase=report(
            "results/calibration/figures/measured_isotherms-phase.png",
            caption="../report/calibration_isotherms_phase.rst",
            category="Calibration",
        ),
        black=report(
            "results/calibration/figures/measured_black.png",
            caption="../report/calibration_black.rst",
            category="Calibration",
        ),
        cole_cole=report(
            "results/calibration/figures/measured_cole-cole.png",
            caption="../report/calibration_cole_cole.rst",
            category="Calibration",
        ),
    log:
        "logs/calibration/rheology_figures.log",
    benchmark:
        "benchmarks/calibration/rheology_figures.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        "asphalt-nscd plot-rheology --points 'measured (mean ± sd)={input.summary}' "
        '--lines "Burger\'s fit={input.curves}" '
        "--isotherms-modulus {output.isotherms_modulus} --isotherms-phase {output.isotherms_phase} "
        "--black {output.black} --cole-cole {output.cole_cole} 2> {log}"


rule paper_table3_figures:
    input:
        "results/calibration/paper_table3_curves.csv",
    output:
        modulus=report(
            "results/calibration/figures/paper_table3_isotherms-modulus.png",
            caption="../report/calibration_paper_table3.rst",
            category="Calibration",
        ),
        phase=report(
            "results/calibration/figures/paper_table3_isotherms-phase.png",
            caption="../report/calibration_paper_table3.rst",
            category="Calibration",
        ),
    log:
        "logs/calibration/paper_table3_figures.log",
    benchmark:
        "benchmarks/calibration/paper_table3_figures.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        units=config["calibration"]["table3_units"],
    shell:
        'asphalt-nscd plot-rheology --lines "paper Table 3 ({params.units} reading)={input}" '
        "--isotherms-modulus {output.modulus} --isotherms-phase {output.phase} 2> {log}"


rule master_curve_figures:
    # master curve with the measured points coloured by temperature (2S2P1D, extended law, MEPDG sigmoid),
    # shift factors, the extended law's per-cell residuals, the sigmoid's parameters beside 2S2P1D's
    input:
        search=plan.MASTER_CURVE_JSON,
        corrected=plan.CORRECTED_TABLE,
        law=plan.LAW_JSON,
    output:
        master=report(
            plan.MASTER_CURVE_FIGURES["master"],
            caption="../report/diagnosis_master_curve.rst",
            category="Diagnosis",
        ),
        shift=report(
            plan.MASTER_CURVE_FIGURES["shift"],
            caption="../report/diagnosis_master_curve.rst",
            category="Diagnosis",
        ),
        residuals=report(
            plan.MASTER_CURVE_FIGURES["residuals"],
            caption="../report/diagnosis_master_curve.rst",
            category="Diagnosis",
        ),
        residual_table=report(
            "results/diagnosis/law_residuals.csv",
            caption="../report/diagnosis_master_curve.rst",
            category="Diagnosis",
        ),
        sigmoid=report(
            plan.SIGMOID_TABLE,
            caption="../report/diagnosis_master_curve.rst",
            category="Diagnosis",
        ),
    log:
        "logs/figures/master_curve_figures.log",
    benchmark:
        "benchmarks/figures/master_curve_figures.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        "asphalt-nscd master-curve-figures --master-curve {input.search} --corrected-table {input.corrected}"
        " --law-json {input.law} --master-figure {output.master} --shift-figure {output.shift}"
        " --residual-figure {output.residuals} --residual-table {output.residual_table} --sigmoid {output.sigmoid}"
        " 2> {log}"


rule card_figures:
    # the material card against the measured means along temperature (isochrones), its E(t) and D(t), its error
    # against the number of Prony terms
    input:
        card=plan.MATERIAL_CARDS["json"],
        errors=plan.MATERIAL_CARDS["errors"],
        functions=plan.MATERIAL_CARDS["functions"],
    output:
        isochrones=report(
            plan.MATERIAL_CARD_FIGURES["isochrones"],
            caption="../report/diagnosis_card_figures.rst",
            category="Diagnosis",
        ),
        relaxation_creep=report(
            plan.MATERIAL_CARD_FIGURES["relaxation_creep"],
            caption="../report/diagnosis_card_figures.rst",
            category="Diagnosis",
        ),
        terms_curve=report(
            plan.MATERIAL_CARD_FIGURES["terms_curve"],
            caption="../report/diagnosis_card_figures.rst",
            category="Diagnosis",
        ),
    log:
        "logs/figures/card_figures.log",
    benchmark:
        "benchmarks/figures/card_figures.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        "asphalt-nscd card-figures --card {input.card} --errors {input.errors} --functions {input.functions}"
        " --isochrones {output.isochrones} --relaxation-creep {output.relaxation_creep}"
        " --terms-curve {output.terms_curve} 2> {log}"


rule report_index:
    input:
        # every output the rules flag with report(), wildcards expanded (plan.report_wildcards)
        plan.report_input(workflow, config),
    output:
        plan.REPORT_INDEX,
    log:
        "logs/report/index.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        "asphalt-nscd collect-report {input} --out-dir results/report -o {output} 2> {log}"
