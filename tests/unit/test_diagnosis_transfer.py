"""`diagnose` with transfer-corrected extended NSCD rows and `--transfer` network-factor JSONs:
the gain table and page say the extended rows include the correction and give NF_s, and the
`law_only` rows (NF_s x E*_law) separate the gain of the law from that of the correction."""

import json

import numpy as np
import pandas as pd
import pytest
from diagnosis_chain import cli_chain

from asphalt_nscd.rheology import law_file
from asphalt_nscd.cli import main
from asphalt_nscd.diagnosis.causes import burgers_predict
from asphalt_nscd.rheology.metrics import cell_means

TEMPS = [-10.0, 0.0, 10.0, 15.0, 20.0, 30.0]
MACRO = pd.DataFrame(
    {
        "temperature_C": TEMPS,
        "Em_MPa": 30e3,
        "eta_m_MPa_s": [3e5, 1e5, 3e4, 1e4, 5e3, 1e3],
        "Ek_MPa": 40e3,
        "eta_k_MPa_s": [400.0, 200.0, 100.0, 50.0, 30.0, 10.0],
    }
)
NF = {"s1": 0.90, "s2": 0.92}  # network factors of the two samples


def _mre_E(model: pd.DataFrame, data: pd.DataFrame) -> pd.Series:
    """Independent |E*| MRE (%) per temperature."""
    m = model.merge(data, on=["temperature_C", "frequency_Hz"], suffixes=("_m", "_d"))
    return (100 * (m["E_norm_MPa_m"] / m["E_norm_MPa_d"] - 1).abs()).groupby(m["temperature_C"]).mean()


def _transfer_json(path, sample, nf):
    path.write_text(
        json.dumps(
            {"network_factor": nf, "sample": sample, "bond_kinematics": "contact", "head_rotation": "free", "nu": 0.35}
        )
    )
    return str(path)


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    d = tmp_path_factory.mktemp("diag_transfer")
    m = d / "M.csv"
    assert main(["synth", "--seed", "7", "--schedule", "paper_2pb", "--specimens", "3", "-o", str(m)]) == 0
    chain = cli_chain(m, d)
    laws_path = chain["law"]
    MACRO.to_csv(d / "macro.csv", index=False)
    grid = pd.DataFrame([(T, f) for T in TEMPS for f in (3.0, 10.0, 40.0)], columns=["temperature_C", "frequency_Hz"])
    E = burgers_predict(MACRO, grid["temperature_C"], grid["frequency_Hz"])
    laws = law_file.read(laws_path)
    Ex = np.array(
        [laws[T].complex_modulus(2 * np.pi * f) * 1e-6 for T, f in zip(grid["temperature_C"], grid["frequency_Hz"])]
    )
    sims, exts, transfers = [], [], []
    for s, nf in NF.items():
        sim = grid.assign(sample=s, mode="measured", E_norm_MPa=nf * np.abs(E), phase_deg=np.degrees(np.angle(E)))
        sim.to_csv(d / f"{s}_measured.csv", index=False)
        sims.append(str(d / f"{s}_measured.csv"))
        # corrected extended run: the law itself, 0.5 % high (inertia/time integration)
        ext = grid.assign(
            sample=s,
            mode="extended",
            E_norm_MPa=1.005 * np.abs(Ex),
            phase_deg=np.degrees(np.angle(Ex)),
            transfer_network_factor=nf,
            transfer_json=f"results/harmonic/transfer/{s}.json",
        )
        ext.to_csv(d / f"{s}_extended.csv", index=False)
        exts.append(str(d / f"{s}_extended.csv"))
        transfers.append(_transfer_json(d / f"{s}_transfer.json", s, nf))
    out = {k: d / k for k in ("r.json", "gain.csv", "page.md")}
    args = [
        "diagnose",
        *chain["args"],
        "--macro-params",
        str(d / "macro.csv"),
        "--simulated",
        *sims,
        "--simulated-extended",
        *exts,
    ]
    assert (
        main(
            [
                *args,
                "--transfer",
                *transfers,
                "-o",
                str(out["r.json"]),
                "--gain-csv",
                str(out["gain.csv"]),
                "--page",
                str(out["page.md"]),
            ]
        )
        == 0
    )
    return {
        "dir": d,
        "args": args,
        "measured": m,
        "grid": grid,
        "Ex": Ex,
        "out": out,
        "exts": exts,
        "report": json.loads(out["r.json"].read_text()),
    }


def test_report_states_the_transfer_correction(setup):
    tr = setup["report"]["transfer"]
    assert tr["applied"] is True
    assert tr["network_factor_applied"] == NF and tr["network_factor_harmonic"] == NF
    assert tr["law_only_network_factor"] == pytest.approx(np.mean(list(NF.values())))
    assert "transfer correction E*/NF_s, NF_s = 0.9 (s1), 0.92 (s2)" in setup["report"]["extended"]["model"]


def test_gain_table_separates_law_and_correction(setup):
    gain = pd.read_csv(setup["out"]["gain.csv"])
    assert set(gain["source"]) == {"nscd", "macro", "law_only"} and len(gain) == 3 * len(TEMPS)
    by = {s: g.set_index("temperature_C") for s, g in gain.groupby("source")}
    assert by["nscd"]["transfer_correction"].all() and not by["law_only"]["transfer_correction"].any()
    assert np.allclose(by["nscd"]["network_factor"], 0.91) and np.allclose(by["law_only"]["network_factor"], 0.91)
    assert by["macro"]["network_factor"].isna().all() and not by["macro"]["transfer_correction"].any()
    assert by["nscd"]["after_model"].str.contains("transfer correction").all()
    corrected = cell_means(pd.read_csv(setup["dir"] / "corrected.csv"))
    grid, Ex = setup["grid"], setup["Ex"]
    law_only = _mre_E(grid.assign(E_norm_MPa=0.91 * np.abs(Ex)), corrected)
    nscd = _mre_E(grid.assign(E_norm_MPa=1.005 * np.abs(Ex)), corrected)
    for T in TEMPS:
        assert by["law_only"].loc[T, "E_norm_mre_after_pct"] == pytest.approx(law_only.loc[T], rel=1e-9)
        assert by["nscd"].loc[T, "E_norm_mre_after_pct"] == pytest.approx(nscd.loc[T], rel=1e-9)
        # same "before" (the uncorrected NSCD runs with the Burger's law)
        assert by["law_only"].loc[T, "E_norm_mre_before_pct"] == by["nscd"].loc[T, "E_norm_mre_before_pct"]
        # without the correction the 9 % network factor stays in |E*|
        assert by["law_only"].loc[T, "E_norm_mre_after_pct"] > by["nscd"].loc[T, "E_norm_mre_after_pct"] + 3


def test_page_says_the_nscd_rows_are_corrected(setup):
    page = setup["out"]["page.md"].read_text()
    assert "include the transfer correction" in page and "NF_s = 0.9 (s1), 0.92 (s2)" in page
    assert "| 10 | NSCD simulation (+ transfer correction, NF_s = 0.91) |" in page
    assert "| 10 | extended law, no correction |" in page and "| 10 | macro law |" in page


def test_without_transfer_json_the_applied_factors_stand_in(setup, tmp_path):
    out = tmp_path / "r.json"
    assert main([*setup["args"], "-o", str(out)]) == 0
    rep = json.loads(out.read_text())
    assert rep["transfer"]["network_factor_harmonic"] == NF and rep["gain_law_only"] is not None


def test_stale_transfer_json_is_rejected(setup, tmp_path, capsys):
    stale = _transfer_json(tmp_path / "s1.json", "s1", 0.95)
    assert main([*setup["args"], "--transfer", stale, "-o", str(tmp_path / "r.json")]) == 2
    assert "sample 's1' ran with network factor 0.9 but the transfer JSON gives 0.95" in capsys.readouterr().err
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"network_factor": 0.9, "sample": "s1"}))
    assert main([*setup["args"], "--transfer", str(bad), "-o", str(tmp_path / "r.json")]) == 2
    assert f"{bad}: missing key(s)" in capsys.readouterr().err
    assert not (tmp_path / "r.json").exists()


def test_uncorrected_extended_rows_are_labelled(setup, tmp_path):
    plain = []
    for p in setup["exts"]:
        f = tmp_path / p.rsplit("/", 1)[1]
        pd.read_csv(p).drop(columns=["transfer_network_factor", "transfer_json"]).to_csv(f, index=False)
        plain.append(str(f))
    args = [a for a in setup["args"][: setup["args"].index("--simulated-extended")]]
    out, page = tmp_path / "r.json", tmp_path / "p.md"
    assert main([*args, "--simulated-extended", *plain, "-o", str(out), "--page", str(page)]) == 0
    rep = json.loads(out.read_text())
    assert rep["transfer"]["applied"] is False and rep["gain_law_only"] is None
    assert "no transfer correction" in rep["extended"]["model"]
    assert "carry no transfer correction" in page.read_text()
