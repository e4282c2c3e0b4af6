# Forecast of a mix's |E*| and phase from its binder, gradation and volumetrics (asphalt_nscd.forecast), judged on
# mixes left out. `make forecast TABLE=...` runs it on a matched table; `make run` on forecast.table. The table is
# read once by the checkpoint, whose mixes name the samples; everything else follows from it.
from pathlib import Path

from asphalt_nscd import plan


checkpoint forecast_table:
    input:
        table=config["forecast"]["table"],
        sidecar=plan.forecast_sidecar(config),
    output:
        matched=plan.FORECAST_MATCHED,
    log:
        "logs/forecast/table.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        mixes=plan.forecast_mixes_setting(config),
    shell:
        'asphalt-nscd matched {input.table:q} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output.matched} 2> {log}'


rule forecast_binders:
    input:
        plan.FORECAST_MATCHED,
    output:
        points=report(
            f"{plan.FORECAST}/binder_points.csv", caption="../report/forecast_binders.rst", category="Forecast"
        ),
        curves=f"{plan.FORECAST}/binder_curves.json",
    log:
        "logs/forecast/binders.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        "asphalt-nscd forecast-binders {input} -o {output.points} --curves {output.curves} 2> {log}"


rule forecast_pack:
    # the costly part of a mix's sample: its gradation above the cut deposited and vibrated (Section 3.2.1);
    # {where} is the forecast's folder for the base sample, its variants/<cut..._x...> folder for a variant
    input:
        plan.FORECAST_MATCHED,
    output:
        "{where}/samples/{mix}_s{seed}.npz",
    log:
        "logs/{where}/pack_{mix}_s{seed}.log",
    benchmark:
        "benchmarks/{where}/pack_{mix}_s{seed}.tsv"
    wildcard_constraints:
        seed=r"\d+",
        where=plan.FORECAST_WHERE,
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.forecast_sample_param(config),
    shell:
        'asphalt-nscd forecast-pack --config "$ASPHALT_NSCD_RUN_CONFIG" --table {input} --mix {wildcards.mix}'
        " --seed {wildcards.seed} --cut-mm {params.settings[dem][cut_mm]} --size-dmax {params.settings[dem][size_dmax]}"
        " -o {output} 2> {log}"


rule forecast_sample:
    input:
        matched=plan.FORECAST_MATCHED,
        packing="{where}/samples/{mix}_s{seed}.npz",
    output:
        h5="{where}/samples/{mix}_s{seed}.h5",
        summary="{where}/samples/{mix}_s{seed}_summary.json",
    log:
        "logs/{where}/sample_{mix}_s{seed}.log",
    wildcard_constraints:
        seed=r"\d+",
        where=plan.FORECAST_WHERE,
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.forecast_sample_param(config),
    shell:
        'asphalt-nscd forecast-sample --config "$ASPHALT_NSCD_RUN_CONFIG" --table {input.matched}'
        " --mix {wildcards.mix} --cut-mm {params.settings[dem][cut_mm]} --size-dmax {params.settings[dem][size_dmax]}"
        " --packing {input.packing} -o {output.h5} --summary {output.summary} 2> {log}"


rule forecast_response:
    input:
        "{where}/samples/{mix}_s{seed}.h5",
    output:
        "{where}/responses/{mix}_s{seed}.npz",
    log:
        "logs/{where}/response_{mix}_s{seed}.log",
    wildcard_constraints:
        seed=r"\d+",
        where=plan.FORECAST_WHERE,
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        variant=plan.forecast_variant_param(config),
    shell:
        "asphalt-nscd forecast-response {input} --mix {wildcards.mix} --seed {wildcards.seed}"
        " --variant '{params.variant}' -o {output} 2> {log}"


rule forecast_crossval:
    input:
        matched=plan.FORECAST_MATCHED,
        curves=rules.forecast_binders.output.curves,
        responses=plan.forecast_responses_input(config, checkpoints),
    output:
        rows=f"{plan.FORECAST}/crossval_rows.csv",
        scores=report(f"{plan.FORECAST}/crossval.csv", caption="../report/forecast_crossval.rst", category="Forecast"),
        constants=f"{plan.FORECAST}/crossval_constants.json",
        split=f"{plan.FORECAST}/error_split.csv",
        selection=f"{plan.FORECAST}/selection_log.csv",
        learned_rows=f"{plan.FORECAST}/learned_by_rows.csv",
    log:
        "logs/forecast/crossval.log",
    benchmark:
        "benchmarks/forecast/crossval.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.forecast_settings(config),
    shell:
        'asphalt-nscd forecast-crossval --config "$ASPHALT_NSCD_RUN_CONFIG" --matched {input.matched} --curves {input.curves}'
        " --responses {input.responses} -o {output.rows} --scores {output.scores} --constants {output.constants}"
        " --split {output.split} --selection {output.selection} --learned-rows {output.learned_rows}"
        " --jobs {threads} 2> {log}"


rule forecast_coverage:
    # prediction intervals calibrated on the held-out residuals, and their nested coverage (asphalt_nscd.forecast.intervals)
    input:
        rules.forecast_crossval.output.rows,
    output:
        coverage=f"{plan.FORECAST}/interval_coverage.csv",
        intervals=f"{plan.FORECAST}/intervals.csv",
    log:
        "logs/forecast/coverage.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        'asphalt-nscd forecast-coverage {input} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output.coverage}'
        " --intervals {output.intervals} 2> {log}"


rule forecast_predict:
    input:
        matched=plan.FORECAST_MATCHED,
        curves=rules.forecast_binders.output.curves,
        scores=rules.forecast_crossval.output.scores,
        intervals=rules.forecast_coverage.output.intervals,
        responses=plan.forecast_responses_input(config, checkpoints),
    output:
        forecast=f"{plan.FORECAST}/forecast.csv",
        level1=f"{plan.FORECAST}/level1_tables.csv",
        sigmoid=f"{plan.FORECAST}/sigmoid_master_curves.csv",
        constants=f"{plan.FORECAST}/forecast_constants.json",
        state=directory(f"{plan.FORECAST}/trained"),
    log:
        "logs/forecast/predict.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.forecast_settings(config),
    shell:
        'asphalt-nscd forecast --config "$ASPHALT_NSCD_RUN_CONFIG" --matched {input.matched} --curves {input.curves}'
        " --responses {input.responses} --scores {input.scores} -o {output.forecast} --level1 {output.level1}"
        " --sigmoid {output.sigmoid} --constants {output.constants} --intervals {input.intervals}"
        " --state {output.state} 2> {log}"


rule forecast_page:
    input:
        matched=plan.FORECAST_MATCHED,
        points=rules.forecast_binders.output.points,
        curves=rules.forecast_binders.output.curves,
        rows=rules.forecast_crossval.output.rows,
        scores=rules.forecast_crossval.output.scores,
        constants=rules.forecast_crossval.output.constants,
        forecast=rules.forecast_predict.output.forecast,
        forecast_constants=rules.forecast_predict.output.constants,
        split=rules.forecast_crossval.output.split,
        selection=rules.forecast_crossval.output.selection,
        coverage=rules.forecast_coverage.output.coverage,
        learned_rows=rules.forecast_crossval.output.learned_rows,
    output:
        page=report(f"{plan.FORECAST}/forecast.md", caption="../report/forecast_page.rst", category="Forecast"),
        predictions=report(
            f"{plan.FORECAST}/figures/predicted_vs_measured.png",
            caption="../report/forecast_predictions.rst",
            category="Forecast",
        ),
        binders=report(
            f"{plan.FORECAST}/figures/binder_master_curves.png",
            caption="../report/forecast_binder_curves.rst",
            category="Forecast",
        ),
    log:
        "logs/forecast/page.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.forecast_settings(config),
        name=Path(config["forecast"]["table"]).name,
    shell:
        'asphalt-nscd forecast-page --config "$ASPHALT_NSCD_RUN_CONFIG" --table-name {params.name:q}'
        " --matched {input.matched} --points {input.points} --curves {input.curves} --rows {input.rows}"
        " --scores {input.scores} --constants {input.constants} --forecast {input.forecast}"
        " --forecast-constants {input.forecast_constants} --split {input.split} --selection {input.selection}"
        " --coverage {input.coverage} --learned-rows {input.learned_rows} -o {output.page} 2> {log}"


rule forecast_publish:
    # the last rule: the complete run copied into results/forecasts/<folder>-<table>/ with manifest.json, in place
    # only once every step has succeeded (a failed or stopped run leaves the folder as the last complete one made it)
    input:
        table=config["forecast"]["table"],
        files=[
            plan.FORECAST_MATCHED,
            *rules.forecast_binders.output,
            *rules.forecast_crossval.output,
            *rules.forecast_coverage.output,
            rules.forecast_predict.output.forecast,
            rules.forecast_predict.output.level1,
            rules.forecast_predict.output.sigmoid,
            rules.forecast_predict.output.constants,
            *rules.forecast_page.output,
        ],
    output:
        directory(plan.forecast_dir(config)),
    log:
        "logs/forecast/publish.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        "asphalt-nscd forecast-publish {input.files:q} --table {input.table:q} --root results -o {output:q} 2> {log}"


rule forecast_mix:
    # new mixes from a mix file (make forecast MIX=...), forecast with the models trained on forecast.table; the folder is
    # published complete with manifest.json, the samples kept beside it in <folder>.work to resume
    input:
        mix=config["forecast"]["mix"] or [],
        state=rules.forecast_predict.output.state,
    output:
        directory(plan.mix_dir(config)) if config["forecast"]["mix"] else [],
    log:
        "logs/forecast/mix.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        'asphalt-nscd forecast-mix {input.mix:q} --state {input.state:q} --config "$ASPHALT_NSCD_RUN_CONFIG"'
        " -o {output:q} 2> {log}"
