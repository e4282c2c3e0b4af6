"""The 2PB job on its exact periodic orbit: the linearity certificate and the orbit's record.

While no bond breaks and no unbonded pair touches, a step of the Moreau-Jean theta-method on
the bonded 2PB sample is linear and its bond frames are fixed (:mod:`asphalt_nscd.nscd`), so
the state after n steps from the periodic start of :func:`asphalt_nscd.harmonic.periodic.periodic_state`
is exactly

    y_n = y_g + n dt v_g + Re(Y z^n),   z = exp(i w dt),

the steady state under gravity (static, or steady creep at v_g for a liquid bond law) plus the
phasor Y of the step map's periodic orbit. A job whose certificate holds needs no time steps:
its record is that orbit sampled at its own steps, reduced by the same Eqs. 1-5.

* :func:`certify` -- the linearity certificate over the job's simulated steps (0 <= n <=
  n_steps): every bond's normal force and tangential force against its strength R_crit at the
  end of every step (the core's breaking rule, Eqs. 12-13), and every unbonded pair of the core's
  contact detection (sphere pairs and sphere-plate pairs not excluded by an intact bond,
  ``NSCDParameters.bonded_contact``) against a gap that closes at a step or between two. First a
  bound for any instant, max_t |a + Re(c e^{iwt})| <= |a| + e(c), with e(c) = sqrt((|c|^2 +
  |c . c|) / 2) the semi-major axis of the ellipse Re(c e^{iwt}) traces (a creep drift adds
  |v_rel| T); where the bound does not clear (a bond at or above R_crit, a gap at or below 0),
  the exact values at every step, and for gaps between steps the interpolation bound
  (w dt)^2 / 8 e(c). Weakly held spheres (zero modes of the contact kinematics: a sphere held
  by two bonds spins about the line through both) are supported against their weight along
  those modes by default, in the orbit and the time domain alike; left free
  (``mechanisms='free'``) they fall, 1/2 a T^2, which the gap bound adds. A pair already touching
  in the gravity state (gap <= 0, a closed contact whose force the bonded orbit does not carry)
  fails the certificate outright, so no closed contact is left whose opening or Coulomb cone
  would need checking; so does a steady state under gravity that could not be computed (the
  job then starts with gravity from rest, not on its orbit).
* :func:`orbit_record` -- what the core records at each step on the orbit: the head plate's
  force theta R(t_{n+1}) + (1 - theta) R(t_n) (``Simulation._plate_forces``), R the head bonds'
  reaction, and the driver force, at the mid-step times.

docs/choices.md ("Periodic start of the 2PB test", "Linearity certificate") gives the
derivation and the measured agreement with the time domain
(``reference/paper_scale/verification.csv``).
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass

import numpy as np


@dataclass
class Certificate:
    """Linearity certificate of one 2PB job (:func:`certify`).

    holds : bool -- no bond reaches its strength and no unbonded pair closes over the job.
    reason : str -- why it fails ('' when it holds).
    bond_force_ratio : largest bond force over R_crit (normal or tangential; its bound for any
        instant below 1, else its exact largest value at the steps; 0 with unbreakable bonds);
        bond_at : [i, j] of that bond (j < 0: plate -1-j).
    min_gap_m : smallest gap of an unbonded pair over the job, m (a bound above 0, else exact at
        the steps less the between-steps bound; inf: no pair in reach); gap_at : [i, j] of that
        pair (j < 0: plate -1-j); gap_start_m : its gap in the gravity state.
    n_pairs : unbonded pairs within reach (gap in the gravity state below twice the largest
        displacement amplitude plus the creep drift); n_closed_at_start : of them, touching in
        the gravity state.
    creep_m : the largest creep of a sphere under gravity over the job (steady creep of a liquid
        bond law, |v_g| T; 0 for a solid one), m; amplitude_m : the largest periodic
        displacement amplitude of a sphere, m.
    gravity_unbalanced_ratio : the force the steady state under gravity leaves unbalanced (its
        relative residual times the weights' norm) over the head force amplitude; above
        :data:`GRAVITY_UNBALANCED_MAX` the job is not certified.
    duration_s : the interval certified; seconds : wall time of the certificate.
    """

    holds: bool
    reason: str
    bond_force_ratio: float
    bond_at: list
    min_gap_m: float
    gap_at: list
    gap_start_m: float
    n_pairs: int
    n_closed_at_start: int
    creep_m: float
    amplitude_m: float
    gravity_unbalanced_ratio: float
    duration_s: float
    seconds: float

    def row(self) -> dict:
        """Columns of the job's row (``cert_*``)."""
        return {f"cert_{k}": (json_list(v) if isinstance(v, list) else v) for k, v in asdict(self).items()}


#: largest unbalanced force of the steady state under gravity, relative to the head force amplitude
GRAVITY_UNBALANCED_MAX = 1e-4


def json_list(v) -> str:
    return "[" + ", ".join(f"{x:g}" for x in v) + "]"


def ellipse_semi_major(c: np.ndarray) -> np.ndarray:
    """max over t of |Re(c e^{iwt})| for complex vectors c (..., k): sqrt((|c|^2 + |c . c|) / 2)."""
    c = np.asarray(c, complex)
    return np.sqrt(0.5 * ((np.abs(c) ** 2).sum(axis=-1) + np.abs((c * c).sum(axis=-1))))


def certify(sim, state, duration_s: float) -> Certificate:
    """The linearity certificate of the job that starts in ``state`` (a
    :class:`~asphalt_nscd.harmonic.periodic.PeriodicState` with its ``phasors``, not applied
    yet or applied at step 0) and runs ``duration_s`` seconds (module docstring).

    Raises
    ------
    ValueError if ``state`` carries no phasors (a continuous-time state).
    """
    from ..nscd.detection import bonded_exclusions, plate_pairs, sphere_pairs

    tic = time.perf_counter()
    ph = state.phasors
    if ph is None:
        raise ValueError("certify: the periodic state carries no phasors")
    g = ph["gravity_state"]
    sph, b, pls = sim.spheres, sim.bonds, sim.plates
    T = float(duration_s)
    dt = float(sim.params.dt)
    n_steps = int(round(T / dt))
    z = np.exp(1j * 2.0 * math.pi * ph["frequency_Hz"] * dt * np.arange(n_steps + 1))
    # bonds: |F_g + Re(F e^{iwt})| <= |F_g| + e(F), normal and tangential (Eqs. 12-13); exact at the
    # steps where that bound reaches R_crit
    F = ph["bond_force"]
    Fg = g.bond_force if g is not None else np.zeros(F.shape)
    amp_n = np.abs(Fg[:, 0]) + np.abs(F[:, 0])
    amp_t = np.sqrt(Fg[:, 1] ** 2 + Fg[:, 2] ** 2) + ellipse_semi_major(F[:, 1:3])
    strong = ~np.isfinite(b.r_crit) | b.broken
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(strong, 0.0, np.maximum(amp_n, amp_t) / b.r_crit)
    for kb in np.flatnonzero(ratio >= 1.0):
        Fn = Fg[kb, :, None] + np.real(F[kb, :, None] * z[None, :])  # (3, n_steps + 1)
        ratio[kb] = max(np.abs(Fn[0]).max(), np.sqrt(Fn[1] ** 2 + Fn[2] ** 2).max()) / b.r_crit[kb]
    k = int(np.argmax(ratio)) if ratio.size else -1
    bond_ratio = float(ratio[k]) if ratio.size else 0.0
    bond_at = [int(b.i[k]), int(b.j[k])] if ratio.size else []
    # unbonded pairs: positions in the gravity state, their periodic and creep motion
    X = ph["displacement"]
    x0 = state.position - np.real(X)  # the gravity state (rest + sag) at t = 0, the state's own reference
    V = g.velocity if g is not None else np.zeros_like(x0)
    mask = sim.excluded_bonds()
    exclude = bonded_exclusions(sph.n, pls.n, b.i[mask], b.j[mask]) if mask.any() else None
    # weakly held spheres left free under gravity fall along their zero modes: 1/2 a T^2 (mechanisms 'free')
    fall = (
        0.5 * T**2 * np.sqrt((g.mechanism_acceleration**2).sum(axis=1))
        if g is not None and g.mechanism_acceleration is not None
        else np.zeros(len(x0))
    )
    amp = ellipse_semi_major(X) + np.sqrt((V**2).sum(axis=1)) * T
    head = ph["head_translation"]
    reach = 2.0 * float(amp.max() if amp.size else 0.0) + ellipse_semi_major(head[None, :])[0] + 1e-12
    # a falling sphere is checked against its neighbourhood (a diameter around it): farther it cannot go unmet
    near = 2.0 * float(sph.radius[fall > 0].max()) if (fall > 0).any() else 0.0
    if near:
        reach = reach + min(2.0 * float(fall.max()), near)
    between = (2.0 * math.pi * ph["frequency_Hz"] * dt) ** 2 / 8.0  # x e(c): the gap between two steps
    t = dt * np.arange(n_steps + 1)
    i, j, gap0 = sphere_pairs(x0, sph.radius, reach, exclude)
    d = x0[i] - x0[j]
    D = X[i] - X[j]
    Vr = V[i] - V[j]
    rsum = sph.radius[i] + sph.radius[j]
    eD = ellipse_semi_major(D)
    low = np.sqrt((d**2).sum(axis=1)) - rsum - eD - np.sqrt((Vr**2).sum(axis=1)) * T - fall[i] - fall[j]
    falling = (fall[i] > 0) | (fall[j] > 0)
    for mp in np.flatnonzero((low <= 0.0) & ~falling):  # exact at every step
        path = d[mp, :, None] + np.real(D[mp, :, None] * z[None, :]) + Vr[mp, :, None] * t[None, :]
        low[mp] = float(np.sqrt((path**2).sum(axis=0)).min()) - rsum[mp] - between * eD[mp]
    pi, pk, pgap0 = plate_pairs(x0, sph.radius, pls.point, pls.normal, reach, exclude)
    moving = np.array([head if q == 1 else np.zeros(3, complex) for q in range(pls.n)]) if pls.n else np.zeros((0, 3))
    n = pls.normal[pk]
    G = (n * (X[pi] - moving[pk])).sum(axis=1)  # contacts see the plates' translation, not their rotation
    Gv = (n * V[pi]).sum(axis=1)
    plow = pgap0 - np.abs(G) - np.abs(Gv) * T - fall[pi]
    for mp in np.flatnonzero((plow <= 0.0) & ~(fall[pi] > 0)):
        plow[mp] = float((pgap0[mp] + np.real(G[mp] * z) + Gv[mp] * t).min()) - between * abs(G[mp])
    gaps = np.concatenate([low, plow])
    starts = np.concatenate([gap0, pgap0])
    pairs = np.concatenate([np.stack([i, j], 1), np.stack([pi, -1 - pk], 1)]) if gaps.size else np.zeros((0, 2), int)
    closed = int((starts <= 0.0).sum())
    if gaps.size:
        m = int(np.argmin(gaps))
        min_gap, gap_at, gap_start = float(gaps[m]), [int(v) for v in pairs[m]], float(starts[m])
    else:
        min_gap, gap_at, gap_start = math.inf, [], math.inf
    reasons = []
    if g is not None and g.failed:
        reasons.append(f"the steady state under gravity is not used ({g.failed}): the job does not start on its orbit")
    unbalanced = (
        g.residual * g.load_N / max(abs(state.head_force), 1e-300)
        if g is not None and not g.failed and np.isfinite(g.residual)
        else 0.0
    )
    if unbalanced > GRAVITY_UNBALANCED_MAX:
        reasons.append(
            f"the steady state under gravity leaves {unbalanced:.3g} of the head force unbalanced "
            f"(above {GRAVITY_UNBALANCED_MAX:g})"
        )
    falls = np.concatenate([falling, fall[pi] > 0]) if gaps.size else np.zeros(0, bool)
    if near and fall.max() > near:
        k = int(np.argmax(fall))
        reasons.append(
            f"a weakly held sphere ({k}) falls {fall[k]:.3g} m along its zero mode over the job "
            "(mechanisms 'free'), beyond its neighbourhood"
        )
    if bond_ratio >= 1.0:
        reasons.append(f"a bond's force reaches {bond_ratio:.3g} x its strength R_crit (bond {bond_at})")
    if closed:
        reasons.append(
            f"{closed} unbonded pair(s) touch in the gravity state (a closed contact carries a force "
            "the bonded orbit does not)"
        )
    elif min_gap <= 0.0:
        why = (
            " as a weakly held sphere falls along its zero mode (mechanisms 'free')"
            if falls.size and falls[int(np.argmin(gaps))]
            else ""
        )
        reasons.append(
            f"an unbonded pair closes{why}: smallest gap {min_gap:.3g} m over the job (pair {gap_at}, "
            f"{gap_start:.3g} m in the gravity state)"
        )
    return Certificate(
        holds=not reasons,
        reason="; ".join(reasons),
        bond_force_ratio=bond_ratio,
        bond_at=bond_at,
        min_gap_m=min_gap,
        gap_at=gap_at,
        gap_start_m=gap_start,
        n_pairs=int(gaps.size),
        n_closed_at_start=closed,
        creep_m=float(np.sqrt((V**2).sum(axis=1)).max() * T) if len(V) else 0.0,
        amplitude_m=float(ellipse_semi_major(X).max()) if len(X) else 0.0,
        gravity_unbalanced_ratio=float(unbalanced),
        duration_s=T,
        seconds=time.perf_counter() - tic,
    )


def orbit_record(sim, state, n_steps: int) -> dict:
    """The head plate's force signals the core would record over ``n_steps`` steps from the
    periodic start ``state`` (module docstring): ``time_s`` (n,) the mid-step times,
    ``plate_fx`` (n,) N (``StepStats.plate_force[1, 0]``) and ``driver_fx`` (n,) N
    (``StepStats.driver_force[1, 0]``), exact on the orbit.

    Raises ValueError if ``state`` carries no phasors or the simulation has no driven head."""
    ph = state.phasors
    if ph is None:
        raise ValueError("orbit_record: the periodic state carries no phasors")
    p, b, pls = sim.params, sim.bonds, sim.plates
    if pls.n < 2:
        raise ValueError("orbit_record: the simulation has no head plate (plate 1)")
    dt, th = float(p.dt), float(p.theta)
    w = 2.0 * math.pi * ph["frequency_Hz"]
    A = ph["amplitude_m"]
    top = b.j == -2
    # the head bonds' force on the plate, global x: -sum frame^T F (Simulation._plate_forces)
    Rhat = -np.einsum("bc,bc->", ph["bond_force"][top], b.frame[top][:, :, 0])
    g = ph["gravity_state"]
    Rg = -np.einsum("bc,bc->", g.bond_force[top], b.frame[top][:, :, 0]) if g is not None else 0.0
    n = np.arange(n_steps + 1)
    R = Rg + np.real(Rhat * np.exp(1j * w * dt * n))
    plate_fx = th * R[1:] + (1.0 - th) * R[:-1]
    t0, t1 = dt * n[:-1], dt * n[1:]
    acc = th * (-A * w**2 * np.sin(w * t1)) + (1.0 - th) * (-A * w**2 * np.sin(w * t0))
    driver = pls.mass[1] * (acc - p.gravity[0]) - plate_fx if np.isfinite(pls.mass[1]) else -plate_fx
    return {"time_s": t1 - 0.5 * dt, "plate_fx": plate_fx, "driver_fx": driver}
