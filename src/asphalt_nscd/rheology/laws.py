"""Linear viscoelastic laws shared by calibration, the NSCD bond law and the harmonic solver.

One concept, one place: the macro Burger's model of the paper (Eqs. 27-29), its
generalisation (Maxwell element in series with N Kelvin-Voigt units, optional parallel
static spring), and the micro scaling of Eqs. 30-33 and 8-11 that turns a macro law (Pa,
Pa s) into a bond law (N/m, N s/m).

Conventions
-----------
=========  =============================================  ========
symbol     meaning                                        unit
=========  =============================================  ========
Em         Maxwell spring modulus                         Pa
eta_m      Maxwell dashpot viscosity                      Pa s
Ek[i]      Kelvin-Voigt spring modulus of unit i          Pa
eta_k[i]   Kelvin-Voigt dashpot viscosity of unit i       Pa s
E_inf      static spring in parallel with the chain       Pa
omega      angular frequency 2 pi f                       rad/s
E*         complex modulus E1 + i E2, phase arg(E*)       Pa, rad
=========  =============================================  ========

After :meth:`GeneralizedBurgers.scaled` by a length ``a`` (m) the same fields are bond
stiffnesses (N/m) and viscosities (N s/m); all formulas are unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Poisson's ratio of Eqs. 8-11 (paper: "set to 0.35").
POISSON_RATIO = 0.35


@dataclass(frozen=True)
class GeneralizedBurgers:
    """Maxwell (Em, eta_m) in series with Kelvin-Voigt units (Ek[i], eta_k[i]), all in
    parallel with a static spring E_inf.

    Complex modulus::

        E*(w) = E_inf + [1/Em + 1/(i w eta_m) + sum_i 1/(Ek[i] + i w eta_k[i])]^-1

    With one Kelvin-Voigt unit and E_inf = 0 this is the paper's Burger's model
    (Eqs. 27-29). ``eta_m = inf`` removes the Maxwell dashpot (a solid chain).

    Raises
    ------
    ValueError
        if a modulus or viscosity is not positive, or Ek and eta_k differ in length.
    """

    Em: float
    eta_m: float
    Ek: tuple[float, ...] = field(default_factory=tuple)
    eta_k: tuple[float, ...] = field(default_factory=tuple)
    E_inf: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "Ek", tuple(float(x) for x in np.atleast_1d(self.Ek)))
        object.__setattr__(self, "eta_k", tuple(float(x) for x in np.atleast_1d(self.eta_k)))
        if len(self.Ek) != len(self.eta_k):
            raise ValueError(f"Ek has {len(self.Ek)} units but eta_k has {len(self.eta_k)}")
        values = [self.Em, self.eta_m, *self.Ek, *self.eta_k]
        if not all(np.isfinite(v) and v > 0 or v == np.inf for v in values):
            raise ValueError(f"moduli and viscosities must be positive, got {values}")
        if not (np.isfinite(self.E_inf) and self.E_inf >= 0):
            raise ValueError(f"E_inf must be >= 0, got {self.E_inf}")

    @classmethod
    def burgers(cls, Em: float, eta_m: float, Ek: float, eta_k: float) -> "GeneralizedBurgers":
        """The paper's four-parameter Burger's model (Eqs. 27-29)."""
        return cls(Em=Em, eta_m=eta_m, Ek=(Ek,), eta_k=(eta_k,))

    @property
    def n_kelvin(self) -> int:
        return len(self.Ek)

    def complex_compliance(self, omega) -> np.ndarray | float:
        """Complex compliance D*(w) = D' - i D'' of the series chain (no E_inf), 1/Pa.

        Eqs. 28-29 for one Kelvin-Voigt unit. ``omega`` (rad/s) any shape, > 0.
        """
        w = np.asarray(omega, dtype=float)
        d = 1.0 / self.Em + (0.0 if np.isinf(self.eta_m) else 1.0 / (1j * w * self.eta_m))
        for ek, ck in zip(self.Ek, self.eta_k):
            d = d + 1.0 / (ek + 1j * w * ck)
        return d

    def complex_modulus(self, omega) -> np.ndarray | float:
        """Complex modulus E*(w) = E1 + i E2 (Pa), same shape as ``omega`` (rad/s)."""
        return self.E_inf + 1.0 / self.complex_compliance(omega)

    def norm_and_phase(self, omega) -> tuple[np.ndarray, np.ndarray]:
        """|E*| (Pa) and phase angle (degrees) at ``omega`` (rad/s) (Eq. 27, Phi)."""
        e = self.complex_modulus(omega)
        return np.abs(e), np.degrees(np.angle(e))

    def creep_compliance(self, t) -> np.ndarray | float:
        """Creep compliance J(t) (1/Pa) of the series chain, t >= 0 (s); needs E_inf = 0.

        J(t) = 1/Em + t/eta_m + sum_i (1 - exp(-Ek[i] t / eta_k[i])) / Ek[i].
        """
        if self.E_inf != 0.0:
            raise ValueError("closed-form creep compliance needs E_inf = 0")
        t = np.asarray(t, dtype=float)
        j = 1.0 / self.Em + (0.0 if np.isinf(self.eta_m) else t / self.eta_m)
        for ek, ck in zip(self.Ek, self.eta_k):
            j = j + (1.0 - np.exp(-ek * t / ck)) / ek
        return j

    def scaled(self, factor: float) -> "GeneralizedBurgers":
        """All moduli and viscosities multiplied by ``factor``.

        With factor = pi r_min^2 / l0 (m) this is the micro law of a bond (Eqs. 30-33);
        with a further 1/(2(1+nu)) the tangential law (Eqs. 8-11).
        """
        if not (np.isfinite(factor) and factor > 0):
            raise ValueError(f"scale factor must be positive, got {factor}")
        return GeneralizedBurgers(
            Em=self.Em * factor,
            eta_m=self.eta_m * factor,
            Ek=tuple(e * factor for e in self.Ek),
            eta_k=tuple(c * factor for c in self.eta_k),
            E_inf=self.E_inf * factor,
        )

    def as_dict(self) -> dict:
        return {"Em": self.Em, "eta_m": self.eta_m, "Ek": list(self.Ek), "eta_k": list(self.eta_k), "E_inf": self.E_inf}


def bond_scale(r_min, l0) -> np.ndarray:
    """Geometric factor pi r_min^2 / l0 (m) of Eqs. 30-33; arrays of shape (n_bonds,), m.

    Raises ValueError where r_min <= 0 or l0 <= 0.
    """
    r = np.asarray(r_min, dtype=float)
    l = np.asarray(l0, dtype=float)
    if np.any(r <= 0) or np.any(l <= 0):
        raise ValueError("r_min and l0 must be positive")
    return np.pi * r**2 / l


def tangential_ratio(nu: float = POISSON_RATIO) -> float:
    """Ratio tangential/normal of every micro parameter, 1/(2(1+nu)) (Eqs. 8-11)."""
    if not (-1.0 < nu < 0.5):
        raise ValueError(f"Poisson's ratio must lie in (-1, 0.5), got {nu}")
    return 1.0 / (2.0 * (1.0 + nu))
