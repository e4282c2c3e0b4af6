"""Extended law: balanced (minimax) refinement per isotherm and the causal-fit bound."""

import numpy as np
import pytest

from asphalt_nscd.diagnosis import extend
from asphalt_nscd.rheology.laws import GeneralizedBurgers
from asphalt_nscd.rheology.models import two_s2p1d_modulus

F = np.array([25.0, 10.0, 5.0, 1.0, 0.5, 0.1])


def _mre(law, f, E, ph):
    M = law.complex_modulus(2 * np.pi * f)
    return (100 * np.mean(np.abs(np.abs(M) / E - 1)), 100 * np.mean(np.abs(np.degrees(np.angle(M)) / ph - 1)))


def _target():
    """Replicate means of a 2S2P1D isotherm (MPa, deg): causal by construction."""
    E = two_s2p1d_modulus(2 * np.pi * F, 80.0, 35e3, 2.5, 0.18, 0.55, 500.0, 0.02)
    return np.abs(E), np.degrees(np.angle(E))


def test_balance_lowers_the_minimax_objective_and_keeps_em():
    E, ph = _target()
    tau = np.logspace(-4, 1, 11)
    # a deliberately poor start: flat compliances
    law = GeneralizedBurgers(Em=35e3, eta_m=1e4, Ek=tuple(np.full(tau.size, 2e4)),
                             eta_k=tuple(2e4 * tau), E_inf=10.0)
    before = _mre(law, F, E, ph)
    out = extend.balance_to_isotherm(law, F, E, ph, prior_weight=0.0)
    after = _mre(out, F, E, ph)
    score = lambda m: max(m[0] / 3.0, m[1] / 5.0)
    assert score(after) < score(before)
    assert out.Em == law.Em and out.E_inf == law.E_inf  # kept unless static_spring=True
    free = extend.balance_to_isotherm(law, F, E, ph, prior_weight=0.0, static_spring=True)
    assert free.E_inf != law.E_inf
    assert score(_mre(free, F, E, ph)) < score(before)
    assert after[0] <= 3.0 and after[1] <= 5.0
    assert all(np.isfinite(out.Ek)) and out.E_inf >= 0


def test_balance_returns_the_law_when_it_cannot_improve():
    E, ph = _target()
    law = GeneralizedBurgers(Em=35e3, eta_m=1e4, Ek=(2e4,), eta_k=(2e4 * 0.01,))
    exact = law.complex_modulus(2 * np.pi * F)
    out = extend.balance_to_isotherm(law, F, np.abs(exact), np.degrees(np.angle(exact)))
    assert out == law  # already exact: objective 0 cannot decrease


def test_best_causal_fit_matches_a_causal_isotherm():
    E, ph = _target()
    best = extend.best_causal_fit(F, E, ph)
    assert best["objective"] < 0.1
    assert best["mre_E_norm_pct"] < 0.3 and best["mre_phase_pct"] < 0.5


def test_best_causal_fit_flags_a_kramers_kronig_inconsistent_isotherm():
    # |E*| ~ w^0.5 is a power law whose causal phase is 0.5 x 90 = 45 deg (exact); a phase of
    # 20 deg cannot go with it: no positive spectrum meets 3 % / 5 %
    f = np.logspace(-1, np.log10(25.0), 6)
    E = 1000.0 * f**0.5
    ph = np.full(f.size, 20.0)
    best = extend.best_causal_fit(f, E, ph)
    assert best["objective"] > 1.5
    # while the consistent phase is matched
    assert extend.best_causal_fit(f, E, np.full(f.size, 45.0))["objective"] < 0.2


def test_calibrate_balance_flag_changes_only_the_refinement(monkeypatch):
    calls = []
    monkeypatch.setattr(extend, "balance_to_isotherm", lambda law, *a, **k: calls.append(1) or law)
    import pandas as pd

    from asphalt_nscd.diagnosis import synthetic
    from asphalt_nscd.rheology.master_curve import fit_master_curve

    table, _ = synthetic.generate(11, [], schedule="paper_2pb", n_specimens=2)
    master = fit_master_curve(table)
    extend.calibrate(master, table, balance=False)
    assert calls == []
    laws = extend.calibrate(master, table, balance=True)
    assert len(calls) == table["temperature_C"].nunique() == len(laws)
    assert isinstance(table, pd.DataFrame)


def test_balance_tolerances_option_rejects_non_positive_values():
    import argparse

    from asphalt_nscd.diagnosis.cli import _tolerances
    from asphalt_nscd.io import InputError

    assert _tolerances(argparse.Namespace(balance_tolerances_pct=[3.0, 5.0])) == pytest.approx((0.03, 0.05))
    with pytest.raises(InputError, match="balance-tolerances-pct"):
        _tolerances(argparse.Namespace(balance_tolerances_pct=[3.0, 0.0]))
