"""Does the micro-macro transfer of Eqs. 30-33 converge with the sample's resolution?

Eqs. 30-33 give every bond the macro law scaled by its own geometry and assume that the
sample then has the macro modulus: a network factor NF_s = 1 (:mod:`.transfer`). NF_s is a
property of the sample alone (bond kinematics, head rotation, nu), so its trend against the
sample's resolution answers whether the transfer tends to 1 as the discretisation is refined,
and how fast.

Resolution levels are samples prepared with the same protocol at several (scale, PSD cut)
pairs (config ``harmonic.resolution.levels``): a finer cut or a larger scale means more
spheres. For every sample and bond kinematics :func:`resolution_rows` computes NF_s
(:func:`.transfer.transfer_json`, one real factorisation of G); :func:`resolution_summary`
gives the mean, the standard deviation and a 95 % Student-t interval over the seeds of each
level, and fits per kinematics

    NF(N) = NF_inf + c N^(-1/3)

(weighted by the level means' standard errors; N^(-1/3) is the ratio of a sphere's size to
the specimen's, the order of a surface or boundary-layer effect in a discretised continuum),
with its chi-square against those standard errors and its p-value. A limit NF_inf (with its
standard error) is stated only where the data accept the fit (p >= :data:`FIT_ACCEPT_P`);
where they reject it (levels that are not monotone in N, or scatter about the curve far beyond
the seeds' own), no limit is claimed and ``nf_inf`` is nan. Even an accepted fit describes the
measured trend; it does not prove convergence.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..io import InputError
from ..rheology.laws import POISSON_RATIO

#: smallest chi-square p-value at which the fit NF(N) = NF_inf + c N^(-1/3) is accepted
FIT_ACCEPT_P = 0.05


def resolution_rows(
    samples, kinematics=("contact", "barycentre"), head_rotation: str = "free", nu: float = POISSON_RATIO
) -> pd.DataFrame:
    """Network factor of every sample under every bond kinematics.

    Parameters
    ----------
    samples : iterable of (level, path): the resolution level's name (:func:`asphalt_nscd.sample.settings.level_name`)
        and the sample file.
    kinematics : bond kinematics to compute ('contact', 'barycentre').
    head_rotation, nu : as :func:`.transfer.transfer_json`.

    Returns
    -------
    DataFrame, one row per (sample, kinematics): level, scale, cut_mm, sample, seed,
    n_spheres, n_bonds, bond_kinematics, head_rotation, network_factor, n_load_free.

    Raises
    ------
    InputError from the sample reader or the solver (file and option named).
    """
    from ..sample.store import read_sample
    from .transfer import transfer_json

    rows = []
    for level, path in samples:
        sample = read_sample(path)
        attrs = sample.attrs
        cfg = attrs.get("config", {})
        for kin in kinematics:
            t = transfer_json(path, nu=nu, bond_kinematics=kin, head_rotation=head_rotation)
            rows.append(
                {
                    "level": level,
                    "scale": float(attrs.get("scale", math.nan)),
                    "cut_mm": float(cfg.get("psd", {}).get("cut_mm", math.nan)),
                    "sample": str(path),
                    "seed": int(attrs.get("seed", -1)),
                    "n_spheres": int(sample.radius.size),
                    "n_bonds": int(sample.bonds["i"].size),
                    "bond_kinematics": kin,
                    "head_rotation": head_rotation,
                    "network_factor": t["network_factor"],
                    "n_load_free": t["n_load_free"],
                }
            )
    return pd.DataFrame(rows)


def resolution_summary(rows: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Per (kinematics, level): the seeds' mean and spread; per kinematics: the fit NF(N).

    Returns
    -------
    (levels, fits)
        levels: bond_kinematics, level, n_samples, n_spheres_mean, network_factor_mean,
        network_factor_sd, network_factor_ci95_low/high (Student t over the seeds; nan for
        one seed), departure_from_1_pct (100 (mean - 1)).
        fits: bond_kinematics, n_levels, exponent (-1/3), chi2 (weighted by the level means'
        standard errors), dof, p_value, accepted (p_value >= FIT_ACCEPT_P), nf_inf,
        nf_inf_se, c and the prediction at the finest level (nan where the fit is rejected
        or fewer than 3 levels), and the rejected fit's nf_inf_unaccepted (nan otherwise).

    Raises
    ------
    InputError if ``rows`` is empty.
    """
    from scipy import stats

    if rows.empty:
        raise InputError("resolution study: no sample rows")
    out = []
    for (kin, level), g in rows.groupby(["bond_kinematics", "level"], sort=False):
        nf = g["network_factor"].to_numpy(float)
        n = nf.size
        sd = float(nf.std(ddof=1)) if n > 1 else math.nan
        half = float(stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n)) if n > 1 else math.nan
        out.append(
            {
                "bond_kinematics": kin,
                "level": level,
                "n_samples": n,
                "n_spheres_mean": float(g["n_spheres"].mean()),
                "network_factor_mean": float(nf.mean()),
                "network_factor_sd": sd,
                "network_factor_ci95_low": float(nf.mean()) - half,
                "network_factor_ci95_high": float(nf.mean()) + half,
                "departure_from_1_pct": 100.0 * (float(nf.mean()) - 1.0),
            }
        )
    levels = pd.DataFrame(out).sort_values(["bond_kinematics", "n_spheres_mean"]).reset_index(drop=True)
    fits = []
    for kin, g in levels.groupby("bond_kinematics", sort=False):
        fit = {
            "bond_kinematics": kin,
            "n_levels": len(g),
            "exponent": -1.0 / 3.0,
            "chi2": math.nan,
            "dof": max(len(g) - 2, 0),
            "p_value": math.nan,
            "accepted": False,
            "nf_inf": math.nan,
            "nf_inf_se": math.nan,
            "c": math.nan,
            "n_spheres_finest": float(g["n_spheres_mean"].max()),
            "nf_finest_fit": math.nan,
            "nf_inf_unaccepted": math.nan,
        }
        if len(g) >= 3:
            x = g["n_spheres_mean"].to_numpy(float) ** (-1.0 / 3.0)
            y = g["network_factor_mean"].to_numpy(float)
            se = (g["network_factor_sd"] / np.sqrt(g["n_samples"])).to_numpy(float)
            w = np.where(np.isfinite(se) & (se > 0), 1.0 / np.where(se > 0, se, 1.0), 1.0)
            A = np.column_stack([np.ones_like(x), x]) * w[:, None]
            coef, res, *_ = np.linalg.lstsq(A, y * w, rcond=None)
            dof = len(g) - 2
            s2 = float(res[0] / dof) if len(res) and dof > 0 else 0.0
            cov = np.linalg.inv(A.T @ A) * max(s2, 1.0)  # never below the seeds' own scatter
            chi2 = float(np.sum((A @ coef - y * w) ** 2))
            p = float(stats.chi2.sf(chi2, dof)) if dof > 0 else math.nan
            accepted = bool(dof > 0 and p >= FIT_ACCEPT_P)
            fit.update({"chi2": chi2, "p_value": p, "accepted": accepted})
            if accepted:
                fit.update(
                    {
                        "nf_inf": float(coef[0]),
                        "nf_inf_se": float(math.sqrt(cov[0, 0])),
                        "c": float(coef[1]),
                        "nf_finest_fit": float(coef[0] + coef[1] * x.min()),
                    }
                )
            else:
                fit["nf_inf_unaccepted"] = float(coef[0])
        fits.append(fit)
    return levels, pd.DataFrame(fits)
