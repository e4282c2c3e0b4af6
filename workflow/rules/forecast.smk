# Forecast of a mix's |E*| and phase from its binder, gradation and volumetrics (asphalt_nscd.forecast), judged on
# mixes left out. `make forecast TABLE=...` runs it on a matched table; `make run` on forecast.table. The table is
# read once by the checkpoint, whose mixes name the samples; everything else follows from it.
from pathlib import Path

from asphalt_nscd import plan

# the chain's working folder: results/forecast for make run, results/forecasts/<folder>-<table>.work/forecast for
# make forecast TABLE=... (forecast.work_dir), so that a table's forecast leaves make run's chain as it is
FORECAST = plan.forecast_root(config)
MATCHED = plan.forecast_matched(config)
WHERE = plan.forecast_where(config)


checkpoint forecast_table:
    input:
        table=config["forecast"]["table"],
        sidecar=plan.forecast_sidecar(config),
    output:
        matched=MATCHED,
    log:
        "logs/forecast/table.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        mixes=plan.forecast_mixes_setting(config),
    shell:
        'asphalt-nscd matched {input.table:q} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output.matched:q} 2> {log:q}'


rule forecast_binders:
    input:
        MATCHED,
    output:
        points=report(f"{FORECAST}/binder_points.csv", caption="../report/forecast_binders.rst", category="Forecast"),
        curves=f"{FORECAST}/binder_curves.json",
    log:
        "logs/forecast/binders.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        "asphalt-nscd forecast-binders {input:q} -o {output.points:q} --curves {output.curves:q} 2> {log:q}"


rule forecast_pack:
    # the costly part of a mix's sample: its gradation above the cut deposited and vibrated (Section 3.2.1);
    # {where} is the forecast's folder for the base sample, its variants/<cut..._x...> folder for a variant
    input:
        MATCHED,
    output:
        "{where}/samples/{mix}_s{seed}.npz",
    log:
        "logs/{where}/pack_{mix}_s{seed}.log",
    benchmark:
        "benchmarks/{where}/pack_{mix}_s{seed}.tsv"
    wildcard_constraints:
        seed=r"\d+",
        where=WHERE,
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.forecast_sample_param(config),
    shell:
        'asphalt-nscd forecast-pack --config "$ASPHALT_NSCD_RUN_CONFIG" --table {input:q} --mix {wildcards.mix}'
        " --seed {wildcards.seed} --cut-mm {params.settings[dem][cut_mm]} --size-dmax {params.settings[dem][size_dmax]}"
        " -o {output:q} 2> {log:q}"


rule forecast_sample:
    input:
        matched=MATCHED,
        packing="{where}/samples/{mix}_s{seed}.npz",
    output:
        h5="{where}/samples/{mix}_s{seed}.h5",
        summary="{where}/samples/{mix}_s{seed}_summary.json",
    log:
        "logs/{where}/sample_{mix}_s{seed}.log",
    wildcard_constraints:
        seed=r"\d+",
        where=WHERE,
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.forecast_sample_param(config),
    shell:
        'asphalt-nscd forecast-sample --config "$ASPHALT_NSCD_RUN_CONFIG" --table {input.matched:q}'
        " --mix {wildcards.mix} --cut-mm {params.settings[dem][cut_mm]} --size-dmax {params.settings[dem][size_dmax]}"
        " --packing {input.packing:q} -o {output.h5:q} --summary {output.summary:q} 2> {log:q}"


rule forecast_response:
    input:
        "{where}/samples/{mix}_s{seed}.h5",
    output:
        "{where}/responses/{mix}_s{seed}.npz",
    log:
        "logs/{where}/response_{mix}_s{seed}.log",
    wildcard_constraints:
        seed=r"\d+",
        where=WHERE,
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        variant=plan.forecast_variant_param(config),
        contents=plan.FORECAST_RESPONSE_CONTENTS,
    shell:
        "asphalt-nscd forecast-response {input:q} --mix {wildcards.mix} --seed {wildcards.seed}"
        " --variant '{params.variant}' -o {output:q} 2> {log:q}"


rule forecast_crossval:
    input:
        matched=MATCHED,
        curves=rules.forecast_binders.output.curves,
        responses=plan.forecast_responses_input(config, checkpoints),
    output:
        rows=f"{FORECAST}/crossval_rows.csv",
        scores=report(f"{FORECAST}/crossval.csv", caption="../report/forecast_crossval.rst", category="Forecast"),
        constants=f"{FORECAST}/crossval_constants.json",
        split=f"{FORECAST}/error_split.csv",
        selection=f"{FORECAST}/selection_log.csv",
        learned_rows=f"{FORECAST}/learned_by_rows.csv",
    log:
        "logs/forecast/crossval.log",
    benchmark:
        "benchmarks/forecast/crossval.tsv"
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.forecast_settings(config),
    shell:
        'asphalt-nscd forecast-crossval --config "$ASPHALT_NSCD_RUN_CONFIG" --matched {input.matched:q} --curves {input.curves:q}'
        " --responses {input.responses:q} -o {output.rows:q} --scores {output.scores:q} --constants {output.constants:q}"
        " --split {output.split:q} --selection {output.selection:q} --learned-rows {output.learned_rows:q}"
        " --jobs {threads} 2> {log:q}"


rule forecast_coverage:
    # prediction intervals calibrated on the held-out residuals, and their nested coverage (asphalt_nscd.forecast.intervals)
    input:
        rules.forecast_crossval.output.rows,
    output:
        coverage=f"{FORECAST}/interval_coverage.csv",
        intervals=f"{FORECAST}/intervals.csv",
    log:
        "logs/forecast/coverage.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    shell:
        'asphalt-nscd forecast-coverage {input:q} --config "$ASPHALT_NSCD_RUN_CONFIG" -o {output.coverage:q}'
        " --intervals {output.intervals:q} 2> {log:q}"


rule forecast_predict:
    input:
        matched=MATCHED,
        curves=rules.forecast_binders.output.curves,
        scores=rules.forecast_crossval.output.scores,
        intervals=rules.forecast_coverage.output.intervals,
        responses=plan.forecast_responses_input(config, checkpoints),
    output:
        forecast=f"{FORECAST}/forecast.csv",
        level1=f"{FORECAST}/level1_tables.csv",
        sigmoid=f"{FORECAST}/sigmoid_master_curves.csv",
        constants=f"{FORECAST}/forecast_constants.json",
        state=directory(f"{FORECAST}/trained"),
    log:
        "logs/forecast/predict.log",
    conda:
        "../envs/asphalt-nscd.yaml"
    params:
        settings=plan.forecast_settings(config),
    shell:
        'asphalt-nscd forecast --config "$ASPHALT_NSCD_RUN_CONFIG" --matched {input.matched:q} --curves {input.curves:q}'
        " --responses {input.responses:q} --scores {input.scores:q} -o {output.forecast:q} --level1 {output.level1:q}"
        " --sigmoid {output.sigmoid:q} --constants {output.constants:q} --intervals {input.intervals:q}"
        " --state {output.state:q} 2> {log:q}"


rule forecast_page:
    input:
        matched=MATCHED,
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
        page=report(f"{FORECAST}/forecast.md", caption="../report/forecast_page.rst", category="Forecast"),
        predictions=report(
            f"{FORECAST}/figures/predicted_vs_measured.png",
            caption="../report/forecast_predictions.rst",
            category="Forecast",
        ),
        binders=report(
            f"{FORECAST}/figures/binder_master_curves.png",
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
        " --matched {input.matched:q} --points {input.points:q} --curves {input.curves:q} --rows {input.rows:q}"
        " --scores {input.scores:q} --constants {input.constants:q} --forecast {input.forecast:q}"
        " --forecast-constants {input.forecast_constants:q} --split {input.split:q} --selection {input.selection:q}"
        " --coverage {input.coverage:q} --learned-rows {input.learned_rows:q} -o {output.page:q} 2> {log:q}"


rule forecast_publish:
    # the last rule: the complete run copied into results/forecasts/<folder>-<table>/ (its paths relative to the parent of
    # the working folder: forecast/...) with manifest.json, in place
    # only once every step has succeeded (a failed or stopped run leaves the folder as the last complete one made it)
    input:
        table=config["forecast"]["table"],
        files=[
            MATCHED,
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
    params:
        root=plan.forecast_publish_root,
    shell:
        "asphalt-nscd forecast-publish {input.files:q} --table {input.table:q} --root {params.root:q} -o {output:q} 2> {log:q}"


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
        " -o {output:q} 2> {log:q}"
