# Numerical sample preparation (paper Section 3.2.1): one rule per sample, named s{seed}
# after config["sample"]["seeds"]. The sample section is passed to the CLI as JSON, so any
# change of it reruns the samples (params are tracked).
# Rerun one sample: `snakemake --cores 1 results/samples/s1.h5 --forcerun prepare_sample`.
import json

SAMPLES = [f"s{seed}" for seed in config["sample"]["seeds"]]
# the sample settings without the seed list: adding a seed does not rerun the other samples
SAMPLE_SETTINGS = json.dumps({k: v for k, v in config["sample"].items() if k != "seeds"})
# contact of the bonded pairs in the stabilisation: the NSCD core's setting
BONDED_CONTACT = config["nscd"].get("bonded_contact", "after_break")
# the preparation benchmark runs the first seed at the configuration's own size
PREPARE_BENCH = f"results/bench/prepare_s{config['sample']['seeds'][0]}.json"


def sample_names(cfg=None):
    """Sample names (wildcard values) of the workflow: s{seed} for each seed of the config."""
    cfg = config if cfg is None else cfg
    return [f"s{seed}" for seed in cfg["sample"]["seeds"]]


def sample_file(name):
    """Path of the HDF5 sample file of sample `name` (e.g. s1), for downstream rules."""
    return f"results/samples/{name}.h5"


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
    params:
        cfg=SAMPLE_SETTINGS,
        bonded_contact=BONDED_CONTACT,
    wildcard_constraints:
        seed=r"\d+",
    log:
        "logs/samples/s{seed}.log",
    benchmark:
        "benchmarks/samples/s{seed}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=lambda wc: 30 if config["sample"]["scale"] < 0.9 else 24 * 60,
    shell:
        "asphalt-nscd prepare-sample --config-json {params.cfg:q} --seed {wildcards.seed}"
        " --bonded-contact {params.bonded_contact}"
        " -o {output.h5} --summary {output.summary} --vtk-dir {output.vtk} --figure {output.figure} 2> {log}"


rule prepare_bench:
    output:
        report(
            "results/bench/prepare_s{seed}.json",
            caption="../report/sample_prepare_bench.rst",
            category="Numerical samples",
        ),
    params:
        cfg=SAMPLE_SETTINGS,
        bonded_contact=BONDED_CONTACT,
    wildcard_constraints:
        seed=r"\d+",
    log:
        "logs/samples/prepare_bench_s{seed}.log",
    benchmark:
        "benchmarks/samples/prepare_bench_s{seed}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=lambda wc: 30 if config["sample"]["scale"] < 0.9 else 24 * 60,
    shell:
        "NUMBA_NUM_THREADS=1 asphalt-nscd prepare-bench --config-json {params.cfg:q} --seed {wildcards.seed}"
        " --bonded-contact {params.bonded_contact} -o {output} 2> {log}"


rule sample_table:
    input:
        summaries=expand("results/samples/{sample}_summary.json", sample=SAMPLES),
    output:
        report(
            "results/samples/table2_counts.csv",
            caption="../report/sample_table2.rst",
            category="Numerical samples",
        ),
    params:
        cfg=SAMPLE_SETTINGS,
    log:
        "logs/samples/table2_counts.log",
    benchmark:
        "benchmarks/samples/table2_counts.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    shell:
        "asphalt-nscd sample-table --config-json {params.cfg:q} --summaries {input.summaries} -o {output} 2> {log}"


REPORT_FILES += ["results/samples/table2_counts.csv", PREPARE_BENCH]
REPORT_FILES += expand("results/samples/{sample}_stages.png", sample=SAMPLES)
