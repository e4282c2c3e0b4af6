# Numerical 2PB complex modulus test (paper Section 3.2.2), the campaign over samples x
# temperatures x frequencies in two modes, the time-step study, the sensitivity study and the
# Table 3 units question (Sections 3.2-4). One job per (mode, sample, T, f[, variant]):
#   results/sim/{mode}/{sample}/{T}C_{f}Hz[_dt{dt} | _{param}x{factor}].h5 (record) + .csv (row)
# Modes: paper (Table 3 under calibration.table3_units), measured (calibrated parameters),
# extended (the measured mode's schedule and settings with the generalized Burger's law of the
# diagnosis, results/diagnosis/generalized_burgers.json, on campaign.extended.n_samples
# samples; with campaign.extended.transfer_correction the bond law is divided by the sample's
# network factor NF_s, results/harmonic/transfer/{sample}.json), and the studies: dt_study, sensitivity, units_Pa, units_kPa (paper parameters).
# Start of each job (campaign.test.start, per-mode `start`): rest (n_cycles) or periodic
# (periodic_cycles from the periodic steady state, asphalt_nscd.campaign.periodic); the row's
# `start` column says which was used.
# Rerun one job: `snakemake --cores 1 results/sim/paper/s1/15C_40Hz.csv --forcerun run_2pb`.
import json
import re

CAMP = config["campaign"]
# the extended bond law per temperature (rule extend_law, diagnosis.smk) run by the extended mode
LAW_JSON = "results/diagnosis/generalized_burgers.json"
# main campaign modes with a numerical_isotherms/table4 aggregation
ISOTHERM_MODES = "paper|measured|extended"


def test_json(mode):
    """The test settings of a job mode as JSON: campaign.test with the mode's overrides of
    dt_policy, yield_stress_Pa and start (the extended mode follows the measured mode; the
    studies dt_study, sensitivity, units_* follow the paper mode; a study section's own
    start wins), and the core's bond kinematics (nscd.bond_kinematics):
    asphalt_nscd.campaign.twopb.mode_settings, shared with campaign-bench."""
    from asphalt_nscd.campaign.twopb import mode_settings

    return json.dumps(
        mode_settings(
            CAMP, mode, config["nscd"].get("bond_kinematics", "contact"), config["nscd"].get("linear_solver", "cg")
        )
    )


WINDOW_CYCLES = config["lab"]["simulation_window_cycles"]
SENS_PARAMETERS = ["Em", "eta_m", "Ek", "eta_k"]


def _num(x):
    return f"{float(x):g}"


def campaign_samples(n):
    """The first n samples of the sample list (all when n is null)."""
    return SAMPLES if n is None else SAMPLES[: int(n)]


def case_name(T, f, suffix=""):
    return f"{_num(T)}C_{_num(f)}Hz{suffix}"


def mode_samples(mode):
    """Samples of the main campaign of one mode: campaign.n_samples (paper, measured) or
    campaign.extended.n_samples (extended)."""
    return campaign_samples(CAMP["extended"]["n_samples"] if mode == "extended" else CAMP["n_samples"])


def mode_rows(mode, samples=None):
    """Reduced rows of the main campaign of one mode (paper, measured or extended; the
    extended mode runs the measured schedule), on ``samples`` (default: the mode's)."""
    sched = CAMP["measured" if mode == "extended" else mode]
    return [
        f"results/sim/{mode}/{s}/{case_name(T, f)}.csv"
        for s in (mode_samples(mode) if samples is None else samples)
        for T in sched["temperatures_C"]
        for f in sched["frequencies_Hz"]
    ]


def dt_study_files(ext):
    d = CAMP["dt_study"]
    return [
        f"results/sim/dt_study/{s}/{case_name(d['temperature_C'], d['frequency_Hz'], '_dt' + _num(dt))}.{ext}"
        for s in campaign_samples(d["n_samples"])
        for dt in d["dt_s"]
    ]


def sensitivity_rows():
    d = CAMP["sensitivity"]
    return [
        f"results/sim/sensitivity/{s}/{case_name(d['temperature_C'], f, f'_{p}x{_num(x)}')}.csv"
        for s in campaign_samples(d["n_samples"])
        for p in SENS_PARAMETERS
        for x in d["factors"]
        for f in d["frequencies_Hz"]
    ]


def sensitivity_baseline():
    d = CAMP["sensitivity"]
    return [
        f"results/sim/paper/{s}/{case_name(d['temperature_C'], f)}.csv"
        for s in campaign_samples(d["n_samples"])
        for f in d["frequencies_Hz"]
    ]


def units_rows(reading, nobreak=False):
    """Rows of the units question under one reading (nobreak: unbreakable bonds); the
    paper-mode rows serve the reading the paper mode already runs with."""
    d = CAMP["units_question"]
    mode = "paper" if reading == config["calibration"]["table3_units"] else f"units_{reading}"
    if nobreak:
        mode = f"units_{reading}_nobreak"
    return [
        f"results/sim/{mode}/{s}/{case_name(d['temperature_C'], f)}.csv"
        for s in campaign_samples(d["n_samples"])
        for f in d["frequencies_Hz"]
    ]


_CASE = re.compile(r"^(?P<T>-?[\d.]+)C_(?P<f>[\d.e+-]+)Hz(?:_dt(?P<dt>[\d.e+-]+)|_(?P<p>Em|eta_m|Ek|eta_k)x(?P<x>[\d.]+))?$")


def job_args(wc):
    """CLI options of one job from its wildcards (mode, case)."""
    m = _CASE.match(wc.case)
    if m is None:
        raise ValueError(f"bad campaign case name {wc.case!r}")
    opts = f"--temperature {m['T']} --frequency {m['f']}"
    if m["dt"]:
        opts += f" --dt {m['dt']}"
    if m["p"]:
        opts += f" --factor {m['p']}={m['x']}"
    if wc.mode == "extended" and transfer_correction():
        opts += f" --network-factor-json {transfer_file(wc.sample)}"
    if wc.mode in ("measured", "extended"):
        return opts
    units = wc.mode.split("_")[1] if wc.mode.startswith("units_") else config["calibration"]["table3_units"]
    return opts + f" --table3-units {units}"


def transfer_correction():
    """Whether the extended mode calibrates its bonds with E*(w) / NF_s (the sample's network
    factor, rule harmonic_transfer; config campaign.extended.transfer_correction, default true)."""
    return bool(CAMP["extended"].get("transfer_correction", True))


def transfer_file(sample):
    """Network factor JSON of a sample (rule harmonic_transfer, harmonic.smk)."""
    return f"results/harmonic/transfer/{sample}.json"


def job_transfer(wc):
    """The transfer JSON a job needs: the extended mode's when the correction is on, else none."""
    return [transfer_file(wc.sample)] if wc.mode == "extended" and transfer_correction() else []


def job_parameters(wc):
    return _mode_parameters(wc.mode)


def _law_option(mode):
    """CLI option of the mode's law file: --law-json (extended) or --parameters."""
    return "--law-json" if mode == "extended" else "--parameters"


rule run_2pb:
    input:
        sample=lambda wc: sample_file(wc.sample),
        parameters=job_parameters,
        transfer=job_transfer,
    output:
        record="results/sim/{mode}/{sample}/{case}.h5",
        row="results/sim/{mode}/{sample}/{case}.csv",
    wildcard_constraints:
        mode="paper|measured|extended|dt_study|sensitivity|units_Pa|units_kPa|units_Pa_nobreak|units_kPa_nobreak",
        sample=r"s\d+",
    params:
        source=lambda wc: _law_option(wc.mode),
        args=job_args,
        settings=lambda wc: test_json(wc.mode),
        window=WINDOW_CYCLES,
    log:
        "logs/sim/{mode}/{sample}/{case}.log",
    benchmark:
        "benchmarks/sim/{mode}/{sample}/{case}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=CAMP["job_runtime_min"],
    shell:
        "asphalt-nscd run-2pb --sample {input.sample} --sample-name {wildcards.sample} --mode {wildcards.mode}"
        " {params.source} {input.parameters} {params.args} --settings-json {params.settings:q}"
        " --window-cycles {params.window} -o {output.record} --row {output.row} 2> {log}"


def _mode_parameters(mode):
    """Law file of a mode: calibrated Burger's table (measured), law JSON (extended), Table 3."""
    if mode == "measured":
        return "results/calibration/burgers_parameters.csv"
    if mode == "extended":
        return LAW_JSON
    return CAL["table3"]


def _mode_options(mode):
    if mode in ("measured", "extended"):
        return "--measured-summary results/lab/measured_summary.csv"
    return f"--table3-units {CAL['table3_units']} --paper-table4 data/paper/table4_mre.csv"


rule campaign_isotherms:
    input:
        rows=lambda wc: mode_rows(wc.mode),
        parameters=lambda wc: _mode_parameters(wc.mode),
        summary=lambda wc: ["results/lab/measured_summary.csv"] if wc.mode in ("measured", "extended") else [],
    output:
        isotherms="results/campaign/{mode}/numerical_isotherms.csv",
        table4=report(
            "results/campaign/{mode}/table4_{mode}.csv",
            caption="../report/campaign_table4.rst",
            category="Campaign",
            subcategory="{mode}",
        ),
        modulus=report(
            "results/campaign/{mode}/figures/fig09_isotherms_modulus.png",
            caption="../report/campaign_isotherms.rst",
            category="Campaign",
            subcategory="{mode}",
        ),
        phase=report(
            "results/campaign/{mode}/figures/fig10_isotherms_phase.png",
            caption="../report/campaign_isotherms.rst",
            category="Campaign",
            subcategory="{mode}",
        ),
    wildcard_constraints:
        mode=ISOTHERM_MODES,
    params:
        source=lambda wc: _law_option(wc.mode),
        options=lambda wc: _mode_options(wc.mode),
        title=lambda wc: "NSCD vs " + ("Table 3 Burger's" if wc.mode == "paper" else "measured") + f" ({wc.mode} mode)",
    log:
        "logs/campaign/{mode}_isotherms.log",
    benchmark:
        "benchmarks/campaign/{mode}_isotherms.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    shell:
        "asphalt-nscd campaign-isotherms --rows {input.rows} {params.source} {input.parameters} {params.options}"
        " --isotherms {output.isotherms} --table4 {output.table4} --figure-modulus {output.modulus}"
        " --figure-phase {output.phase} --title {params.title:q} 2> {log}"


rule campaign_dt_study:
    input:
        records=dt_study_files("h5"),
        rows=dt_study_files("csv"),
        parameters=CAL["table3"],
    output:
        table=report(
            "results/campaign/paper/dt_study.csv", caption="../report/campaign_dt_study.rst", category="Campaign"
        ),
        figure=report(
            "results/campaign/paper/figures/fig06_dt_study.png",
            caption="../report/campaign_dt_study.rst",
            category="Campaign",
        ),
    params:
        units=CAL["table3_units"],
    log:
        "logs/campaign/dt_study.log",
    benchmark:
        "benchmarks/campaign/dt_study.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    shell:
        "asphalt-nscd campaign-dt-study --records {input.records} --rows {input.rows}"
        " --parameters {input.parameters} --table3-units {params.units}"
        " --table {output.table} --figure {output.figure} 2> {log}"


rule campaign_last_cycle:
    input:
        record="results/sim/paper/{}/{}.h5".format(
            SAMPLES[0], case_name(CAMP["last_cycle"]["temperature_C"], CAMP["last_cycle"]["frequency_Hz"])
        ),
    output:
        cycle=report(
            "results/campaign/paper/figures/fig07_last_cycle.png",
            caption="../report/campaign_last_cycle.rst",
            category="Campaign",
        ),
        profile=report(
            "results/campaign/paper/figures/fig08_velocity_profile.png",
            caption="../report/campaign_velocity_profile.rst",
            category="Campaign",
        ),
    log:
        "logs/campaign/last_cycle.log",
    benchmark:
        "benchmarks/campaign/last_cycle.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    shell:
        "asphalt-nscd campaign-last-cycle --record {input.record} --figure-cycle {output.cycle}"
        " --figure-profile {output.profile} 2> {log}"


SENS_FIGURES = [f"results/campaign/paper/figures/fig{11 + k}_sensitivity_{p}.png" for k, p in enumerate(SENS_PARAMETERS)]


rule campaign_sensitivity:
    input:
        rows=sensitivity_rows(),
        baseline=sensitivity_baseline(),
        parameters=CAL["table3"],
    output:
        table=report(
            "results/campaign/paper/sensitivity.csv",
            caption="../report/campaign_sensitivity.rst",
            category="Campaign",
        ),
        figures=[
            report(f, caption="../report/campaign_sensitivity.rst", category="Campaign") for f in SENS_FIGURES
        ],
    params:
        units=CAL["table3_units"],
        T=CAMP["sensitivity"]["temperature_C"],
    log:
        "logs/campaign/sensitivity.log",
    benchmark:
        "benchmarks/campaign/sensitivity.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    shell:
        "asphalt-nscd campaign-sensitivity --rows {input.rows} --baseline {input.baseline}"
        " --parameters {input.parameters} --table3-units {params.units} --temperature {params.T}"
        " --table {output.table} --figures {output.figures} 2> {log}"


rule campaign_units_question:
    input:
        rows_pa=units_rows("Pa"),
        rows_kpa=units_rows("kPa"),
        rows_kpa_nobreak=units_rows("kPa", nobreak=True),
        table3=CAL["table3"],
        sample=sample_file(SAMPLES[0]),
    output:
        report(
            "results/campaign/units_question.csv",
            caption="../report/campaign_units_question.rst",
            category="Campaign",
        ),
    params:
        T=CAMP["units_question"]["temperature_C"],
        mass=CAL["micro"]["grain_mass_kg"],
        r_min=CAL["micro"]["r_min_mm"][0],
        l0=CAL["micro"]["l0_mm"][0],
    log:
        "logs/campaign/units_question.log",
    benchmark:
        "benchmarks/campaign/units_question.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    shell:
        "asphalt-nscd campaign-units --table3 {input.table3} --rows-pa {input.rows_pa} --rows-kpa {input.rows_kpa}"
        " --rows-kpa-nobreak {input.rows_kpa_nobreak} --sample {input.sample} --temperature {params.T} --grain-mass-kg {params.mass}"
        " --r-min-mm {params.r_min} --l0-mm {params.l0} -o {output} 2> {log}"


def _policy_temperature(mode):
    temps = sorted(CAMP[mode]["temperatures_C"])
    return temps[len(temps) // 2]


rule campaign_dt_policy:
    input:
        parameters=lambda wc: _mode_parameters(wc.mode),
    output:
        report(
            "results/campaign/{mode}/dt_policy_phase_error.csv",
            caption="../report/campaign_dt_policy.rst",
            category="Campaign",
            subcategory="{mode}",
        ),
    wildcard_constraints:
        mode="paper|measured",
    params:
        units=lambda wc: "" if wc.mode == "measured" else f"--table3-units {CAL['table3_units']}",
        T=lambda wc: _policy_temperature(wc.mode),
        freqs=lambda wc: " ".join(_num(f) for f in CAMP[wc.mode]["frequencies_Hz"]),
        settings=lambda wc: test_json(wc.mode),
    log:
        "logs/campaign/{mode}_dt_policy.log",
    benchmark:
        "benchmarks/campaign/{mode}_dt_policy.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=20,
    shell:
        "asphalt-nscd campaign-dt-policy --parameters {input.parameters} {params.units} --temperature {params.T}"
        " --frequencies {params.freqs} --settings-json {params.settings:q} -o {output} 2> {log}"


for _mode in CAMP["modes"]:
    REPORT_FILES += [
        f"results/campaign/{_mode}/table4_{_mode}.csv",
        f"results/campaign/{_mode}/figures/fig09_isotherms_modulus.png",
        f"results/campaign/{_mode}/figures/fig10_isotherms_phase.png",
        f"results/campaign/{_mode}/dt_policy_phase_error.csv",
    ]
# the extended mode always runs: the diagnosis compares it with the measured mode
REPORT_FILES += [
    "results/campaign/extended/table4_extended.csv",
    "results/campaign/extended/figures/fig09_isotherms_modulus.png",
    "results/campaign/extended/figures/fig10_isotherms_phase.png",
]
if "paper" in CAMP["modes"]:
    REPORT_FILES += [
        "results/campaign/paper/dt_study.csv",
        "results/campaign/paper/figures/fig06_dt_study.png",
        "results/campaign/paper/figures/fig07_last_cycle.png",
        "results/campaign/paper/figures/fig08_velocity_profile.png",
        "results/campaign/paper/sensitivity.csv",
        *SENS_FIGURES,
        "results/campaign/units_question.csv",
    ]
