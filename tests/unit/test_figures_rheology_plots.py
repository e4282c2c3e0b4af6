"""Shared rheology plots: curve sets, isotherms, Black diagram, Cole-Cole plane, CLI."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

from asphalt_nscd.cli import main  # noqa: E402
from asphalt_nscd.rheology.plots import (  # noqa: E402
    CurveSet,
    as_curve_sets,
    plot_black,
    plot_cole_cole,
    plot_isotherms,
    rheology_figure,
)


@pytest.fixture
def summary():
    rows = []
    for T in (0.0, 20.0):
        for f in (1.0, 10.0):
            rows.append(
                {
                    "temperature_C": T,
                    "frequency_Hz": f,
                    "n": 2,
                    "E_norm_MPa_mean": 10000 / (1 + T) * f**0.2,
                    "E_norm_MPa_std": 100.0,
                    "phase_deg_mean": 10 + T / 2,
                    "phase_deg_std": 0.5,
                }
            )
    return pd.DataFrame(rows)


@pytest.fixture
def curves():
    f = np.logspace(-1, 2, 20)
    return pd.concat(
        [
            pd.DataFrame(
                {
                    "temperature_C": T,
                    "frequency_Hz": f,
                    "E_norm_MPa": 9000 / (1 + T) * f**0.2,
                    "phase_deg": 12 + T / 2 + 0 * f,
                }
            )
            for T in (0.0, 20.0)
        ]
    )


def teardown_function():
    plt.close("all")


def test_curve_set_accepts_summary_and_computes_e1_e2(summary):
    cs = CurveSet("measured", summary)
    assert {"E_norm_MPa", "phase_deg", "E_norm_MPa_std", "E1_MPa", "E2_MPa"} <= set(cs.data.columns)
    np.testing.assert_allclose(np.hypot(cs.data["E1_MPa"], cs.data["E2_MPa"]), cs.data["E_norm_MPa"])
    with pytest.raises(ValueError, match="phase_deg"):
        CurveSet("bad", summary.drop(columns=["phase_deg_mean"]))
    with pytest.raises(ValueError, match="kind"):
        CurveSet("bad", summary, kind="bars")


def test_dict_of_frames_picks_points_or_lines(summary, curves):
    sets = as_curve_sets({"measured": summary, "model": curves})
    assert [cs.kind for cs in sets] == ["points", "line"]


def test_isotherms_have_log_axes_and_one_artist_per_temperature_and_set(summary, curves):
    sets = [CurveSet("measured", summary), CurveSet("model", curves, kind="line")]
    ax = plot_isotherms(sets, "E_norm")
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    assert len(ax.containers) == 2  # error bars: 2 temperatures of the measured set
    model_lines = [l for l in ax.get_lines() if len(l.get_xdata()) == 20]
    assert len(model_lines) == 2
    ax = plot_isotherms(sets, "phase")
    assert ax.get_xscale() == "log" and ax.get_yscale() == "linear"
    with pytest.raises(ValueError):
        plot_isotherms(sets, "E1")


def test_black_and_cole_cole(summary, curves):
    sets = [CurveSet("measured", summary), CurveSet("model", curves, kind="line")]
    ax = plot_black(sets)
    assert ax.get_yscale() == "log" and ax.get_xlabel().startswith("phase")
    ax = plot_cole_cole(sets)
    xdata = np.concatenate([l.get_xdata() for l in ax.get_lines() if len(l.get_xdata()) == 20])
    assert xdata.min() > 0  # E1 of the model curves
    fig = rheology_figure(sets, "black", title="t")
    assert fig.axes[0].get_title() == "t"


def test_cli_plot_rheology_writes_pngs(tmp_path, summary, curves):
    s, c = tmp_path / "s.csv", tmp_path / "c.csv"
    summary.to_csv(s, index=False)
    curves.to_csv(c, index=False)
    outs = {k: tmp_path / f"{k}.png" for k in ("isotherms-modulus", "isotherms-phase", "black", "cole-cole")}
    args = ["plot-rheology", "--points", f"measured={s}", "--lines", f"fit={c}"]
    for k, p in outs.items():
        args += [f"--{k}", str(p)]
    assert main(args) == 0
    for p in outs.values():
        assert p.read_bytes()[:4] == b"\x89PNG"
    assert main(["plot-rheology", "--points", f"measured={s}"]) == 2  # no output requested
    assert main(["plot-rheology", "--points", str(s), "--black", str(tmp_path / "x.png")]) == 2  # no LABEL=
    assert not (tmp_path / "x.png").exists()


def test_collect_report_still_works(tmp_path, summary):
    src = tmp_path / "table.csv"
    summary.to_csv(src, index=False)
    index = tmp_path / "report" / "index.md"
    assert main(["collect-report", str(src), "--out-dir", str(tmp_path / "report"), "-o", str(index)]) == 0
    assert "table.csv" in index.read_text()
