"""Broad-spectrum linear viscoelastic models of asphalt mixes and their Prony approximations.

* 2S2P1D (Olard & Di Benedetto 2003, "General 2S2P1D model and relation between the linear
  viscoelastic behaviours of bituminous binders and mixes", Road Mater. Pavement Des. 4)::

      E*(w) = E00 + (E0 - E00) / (1 + delta (i w tau)^-k + (i w tau)^-h + (i w beta tau)^-1)

  with 0 < k < h < 1. E00 is the static (long-time) modulus of the aggregate skeleton, E0
  the glassy modulus; the last term is a linear dashpot eta = (E0 - E00) beta tau.
* Huet-Sayegh (Sayegh 1965): the same without the dashpot (beta -> infinity).
* Prony series, fitted by non-negative least squares on a fixed log-spaced grid of
  characteristic times (Park & Schapery 1999 "collocation" with NNLS):

  - generalized Kelvin (compliance) chain: Maxwell spring 1/J0 and dashpot 1/phi in series
    with Kelvin-Voigt units of compliance J_i and retardation time tau_i, all in parallel
    with a static spring E_inf -- this *is* the generalized Burger's law of
    :class:`asphalt_nscd.rheology.laws.GeneralizedBurgers` (Em = 1/J0, eta_m = 1/phi,
    Ek = 1/J_i, eta_k = tau_i/J_i);
  - generalized Maxwell (relaxation) series: E*(w) = E_inf + sum_i E_i i w rho_i/(1 + i w rho_i).

Units: moduli in any consistent unit U (MPa at the edges of the diagnosis, Pa for the laws),
times in s, angular frequency in rad/s.
"""

from __future__ import annotations

import numpy as np

from .laws import GeneralizedBurgers


def two_s2p1d_modulus(omega, E00, E0, delta, k, h, beta, tau) -> np.ndarray:
    """Complex modulus of the 2S2P1D model.

    Parameters
    ----------
    omega : array, any shape
        Angular frequency, rad/s (> 0).
    E00, E0 : float or array broadcasting with ``omega``
        Static and glassy moduli (E0 > E00 >= 0), unit U.
    delta : float or array broadcasting with ``omega``
        Weight of the k parabolic element (> 0).
    k, h : float or arrays broadcasting with ``omega``
        Exponents of the parabolic elements, 0 < k < h < 1.
    beta : float or array broadcasting with ``omega``
        Dashpot parameter (> 0; ``np.inf`` gives the Huet-Sayegh model; an array is all finite
        or all infinite).
    tau : float or array broadcasting with ``omega``
        Characteristic time, s (temperature-dependent through the shift factor).

    Returns
    -------
    complex ndarray, broadcast shape, unit U.

    Raises
    ------
    ValueError
        If ``beta`` is an array with both finite and infinite values.
    """
    # (i w tau)^(-a) = (w tau)^(-a) exp(-i pi a / 2) for w tau > 0: the denominator's real and imaginary
    # parts in real arithmetic (a fit evaluates this at every residual; complex powers cost about 4 times more)
    wt = np.asarray(omega, dtype=float) * tau
    finite = np.isfinite(beta)
    if np.any(finite) and not np.all(finite):
        raise ValueError("beta must be all finite or all infinite (the Huet-Sayegh model)")
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        log_wt = np.log(wt)
        pk = delta * np.exp(-k * log_wt)
        ph = np.exp(-h * log_wt)
        re = 1.0 + pk * np.cos(0.5 * np.pi * k) + ph * np.cos(0.5 * np.pi * h)
        im = -(pk * np.sin(0.5 * np.pi * k) + ph * np.sin(0.5 * np.pi * h))
        if np.all(finite):
            im = im - 1.0 / (wt * beta)
        E = E00 + (E0 - E00) / (re + 1j * im)
    # w tau = 0, infinite or not a number: no value (as the complex power gives), not a limit
    return np.where((wt > 0) & np.isfinite(wt), E, np.nan + 1j * np.nan)[()]


def log_time_grid(
    omega_min: float, omega_max: float, per_decade: float = 1.0, margin_decades: float = 1.0
) -> np.ndarray:
    """Log-spaced characteristic times (s) covering 1/omega over the band plus a margin.

    Returns an array of shape (n,), increasing, n >= 2.
    """
    lo = np.log10(1.0 / omega_max) - margin_decades
    hi = np.log10(1.0 / omega_min) + margin_decades
    n = max(2, int(round((hi - lo) * per_decade)) + 1)
    return np.logspace(lo, hi, n)


def fit_generalized_kelvin(
    omega, E_star, tau_grid, E_inf: float = 0.0, dashpot: bool = True, weights=None, glassy_modulus: float | None = None
) -> GeneralizedBurgers:
    """Generalized Burger's law (Maxwell + N Kelvin-Voigt + static spring) by NNLS.

    The chain compliance D(w) = 1/(E*(w) - E_inf) is linear in the unknowns::

        D(w) = J0 + phi/(i w) + sum_i J_i / (1 + i w tau_i),    J0, phi, J_i >= 0

    and is fitted in relative terms (real and imaginary parts divided by |D|), which weighs
    relative errors of |E*| and errors of the phase angle (rad) alike.

    Parameters
    ----------
    omega : array, shape (m,)
        Angular frequencies, rad/s.
    E_star : complex array, shape (m,)
        Target complex modulus, unit U; must satisfy Re(E* - E_inf) > 0.
    tau_grid : array, shape (n,)
        Retardation times, s.
    E_inf : float
        Static spring in parallel, unit U (>= 0), fixed.
    dashpot : bool
        Include the Maxwell dashpot (otherwise eta_m = inf).
    weights : array, shape (m,), optional
        Extra weights of the frequencies.
    glassy_modulus : float, optional
        Fix Em (unit U) instead of fitting J0 = 1/Em (e.g. E0 - E00 of a 2S2P1D target,
        whose glassy compliance a band far below the glassy region cannot resolve).

    Returns
    -------
    GeneralizedBurgers in unit U (U s for viscosities); Kelvin-Voigt units whose NNLS weight
    is zero are dropped. A zero dashpot weight gives eta_m = inf.

    Raises
    ------
    ValueError
        if E* - E_inf has a non-positive real part or the fit has no positive glassy
        compliance.
    """
    from scipy.optimize import nnls

    w = np.asarray(omega, dtype=float).ravel()
    E = np.asarray(E_star, dtype=complex).ravel()
    tau = np.asarray(tau_grid, dtype=float).ravel()
    chain = E - E_inf
    if np.any(chain.real <= 0):
        raise ValueError("E* - E_inf must have a positive real part at every frequency")
    D = 1.0 / chain
    scale = np.abs(D) if weights is None else np.abs(D) / np.asarray(weights, dtype=float).ravel()
    fixed_J0 = glassy_modulus is not None
    if glassy_modulus is not None:
        if not glassy_modulus > 0:
            raise ValueError(f"glassy modulus must be positive, got {glassy_modulus}")
        D = D - 1.0 / glassy_modulus
    cols = [] if fixed_J0 else [np.ones_like(w, dtype=complex)]
    if dashpot:
        cols.append(1.0 / (1j * w))
    cols += [1.0 / (1.0 + 1j * w * t) for t in tau]
    A = np.column_stack(cols) / scale[:, None]
    b = D / scale
    # column scaling keeps NNLS well conditioned (unknowns of very different sizes)
    A_ri = np.vstack([A.real, A.imag])
    norms = np.linalg.norm(A_ri, axis=0)
    norms[norms == 0] = 1.0
    x, _ = nnls(A_ri / norms, np.concatenate([b.real, b.imag]), maxiter=50 * A_ri.shape[1])
    x = x / norms
    if glassy_modulus is not None:
        x = np.concatenate([[1.0 / glassy_modulus], x])
    J0 = x[0]
    if not J0 > 0:
        raise ValueError("Prony fit gave no glassy compliance (J0 = 0); give glassy_modulus or widen the grid")
    phi = x[1] if dashpot else 0.0
    J = x[2:] if dashpot else x[1:]
    keep = J > 1e-12 * J0
    eta_m = 1.0 / phi if phi > 0 else np.inf
    return GeneralizedBurgers(
        Em=1.0 / J0, eta_m=eta_m, Ek=tuple(1.0 / J[keep]), eta_k=tuple(tau[keep] / J[keep]), E_inf=float(E_inf)
    )


def fit_generalized_maxwell(omega, E_star, rho_grid, weights=None) -> dict:
    """Generalized Maxwell (relaxation Prony) series by NNLS.

    E*(w) = E_inf + sum_i E_i i w rho_i / (1 + i w rho_i), E_inf, E_i >= 0, fitted in
    relative terms like :func:`fit_generalized_kelvin`.

    Parameters
    ----------
    omega : array (m,), rad/s;  E_star : complex array (m,), unit U;
    rho_grid : array (n,), relaxation times, s;  weights : array (m,), optional.

    Returns
    -------
    dict
        ``E_inf`` (U), ``E_i`` (array (n,), U), ``rho_s`` (array (n,), s) -- zero terms kept
        so the arrays align with ``rho_grid``.
    """
    from scipy.optimize import nnls

    w = np.asarray(omega, dtype=float).ravel()
    E = np.asarray(E_star, dtype=complex).ravel()
    rho = np.asarray(rho_grid, dtype=float).ravel()
    scale = np.abs(E) if weights is None else np.abs(E) / np.asarray(weights, dtype=float).ravel()
    cols = [np.ones_like(w, dtype=complex)] + [1j * w * r / (1.0 + 1j * w * r) for r in rho]
    A = np.column_stack(cols) / scale[:, None]
    A_ri = np.vstack([A.real, A.imag])
    norms = np.linalg.norm(A_ri, axis=0)
    x, _ = nnls(A_ri / norms, np.concatenate([(E / scale).real, (E / scale).imag]), maxiter=50 * A_ri.shape[1])
    x = x / norms
    return {"E_inf": float(x[0]), "E_i": x[1:], "rho_s": rho}


def generalized_maxwell_modulus(omega, E_inf, E_i, rho_s) -> np.ndarray:
    """Complex modulus of a generalized Maxwell series; ``omega`` shape (m,) -> (m,)."""
    iw = 1j * np.asarray(omega, dtype=float)[:, None]
    return E_inf + np.sum(np.asarray(E_i) * iw * rho_s / (1.0 + iw * rho_s), axis=1)


def information_criteria(rss: float, n: int, p: int) -> dict:
    """Gaussian AIC, AICc and BIC of a least-squares fit (Burnham & Anderson 2002).

    ``rss`` residual sum of squares of ``n`` residuals, ``p`` fitted parameters.
    """
    if n <= 0 or rss <= 0:
        raise ValueError("need n > 0 residuals and rss > 0")
    ll = n * np.log(rss / n)
    aic = ll + 2 * p
    aicc = aic + (2 * p * (p + 1) / (n - p - 1) if n - p - 1 > 0 else np.inf)
    return {"aic": float(aic), "aicc": float(aicc), "bic": float(ll + p * np.log(n))}
