"""Verification of the NSCD core against closed-form solutions.

Each case returns rows ``case, quantity, numerical, analytic, relative_error, tolerance,
passed`` (+ ``unit``, ``note``). ``relative_error = |numerical - analytic| / scale`` with
the scale stated in ``note`` when the analytic value is zero; for bound checks
(``analytic`` is an upper bound) ``relative_error = max(0, numerical - analytic) / scale``.

Cases (bond law: the paper's Table 3 at 15 degC read in Pa, Em = 2.43e7, eta_m = 3.71e6,
Ek = 4.84e7, eta_k = 7.73e5; spheres of 2 mm radius, l0 = 4.5 mm):

* ``creep_normal`` / ``creep_tangential``: one sphere fixed, constant force on the other,
  delta(t) = F (1/Km + t/Cm + (1 - exp(-Kk t/Ck))/Kk) (tangential: parameters x
  1/(2(1+nu)), Eqs. 8-11); theta = 1 (L-stable, quasi-static with a light sphere); the
  loaded sphere's rotation locked (no free rolling about the bond point c).
* ``rigid_rotation``: a bonded pair (sphere-sphere and sphere-plate with a rotating plate)
  in rigid rotation (same angular velocity, consistent translations) for a few steps: no
  bond force with the 'contact' kinematics (the tangential force k_t theta x (x_i - x_j)
  of the 'barycentre' kinematics is the reference scale).
* ``relaxation``: sphere fixed, plate driven by a step of the gap; R(t) against the
  relaxation of the chain computed by the matrix exponential of its linear ODE.
* ``sinusoid``: two-sphere bond under F sin(w t), steady state against
  X = F / (K*(w) - m w²), amplitude 0.5 %, phase 0.05 deg; theta = 0.5.
* ``rest``: sphere on a plate, reaction m g and no penetration.
* ``incline_*``: non-rotating sphere on an inclined plate: sticks below atan(mu), slides
  above with a = g (sin a - mu cos a); rotating sphere rolls with a = 5/7 g sin a.
* ``column``: 5 spheres stacked on a plate: plate reaction = total weight.
* ``impact``: zero restitution (normal velocity after impact 0, penetration bounded by
  (1 - theta) h v_impact, the Moreau-Jean position update with velocity Signorini).
* ``breakage_normal`` / ``breakage_tangential``: slow force ramp; the bond breaks when the
  force crosses R_crit = sigma_y pi r_min² (within one ramp increment).
* ``dissipation``: step dissipation never negative (impact, sliding, bonded sinusoid).
* ``fast_path``: linear fast path and NLGS give the same bond forces.
* ``fast_path_contacts``: a sphere pressed against the bonded block, sticking and slipping
  (:func:`pressed_sphere_network`): the fast path with condensed contacts gives NLGS's
  impulses on every step, and keeps every step.
* ``solver_tolerance``: driver-force phase of a -10 degC, 40 Hz test, CG (residual 1e-10)
  and NLGS (tol 1e-7) against the direct solver: within 0.001 deg and 0.01 deg.

:func:`phase_error_table` measures the phase and amplitude error of the time-discrete bond
law under an imposed sinusoidal gap, as a function of omega dt and theta.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import scipy.linalg

from ..rheology.laws import POISSON_RATIO, GeneralizedBurgers, bond_scale, tangential_ratio
from .moreau_jean import Simulation
from .state import HEAD_AMPLITUDE_M, Bonds, NSCDParameters, Plate, Plates, Spheres

#: Table 3 of the paper at 15 degC read in Pa, Pa s.
LAW_15C = GeneralizedBurgers.burgers(Em=2.43e7, eta_m=3.71e6, Ek=4.84e7, eta_k=7.73e5)
R_SPHERE = 2e-3
L0 = 4.5e-3
DENSITY = 2600.0


def _row(case, quantity, numerical, analytic, tolerance, unit="", scale=None, bound=False, note=""):
    numerical = float(numerical)
    analytic = float(analytic)
    if scale is None:
        scale = abs(analytic)
    if bound:
        err = max(0.0, numerical - analytic) / scale
    else:
        err = abs(numerical - analytic) / scale
    return {
        "case": case,
        "quantity": quantity,
        "numerical": numerical,
        "analytic": analytic,
        "relative_error": err,
        "tolerance": float(tolerance),
        "passed": bool(err <= tolerance),
        "unit": unit,
        "note": note,
    }


def _pair(mass1, inertia1=None, law=LAW_15C, gap_axis=0):
    """Sphere 0 fixed at the origin, sphere 1 at L0 along ``gap_axis``, bonded."""
    pos = np.zeros((2, 3))
    pos[1, gap_axis] = L0
    inertia1 = 0.4 * mass1 * R_SPHERE**2 if inertia1 is None else inertia1
    s = Spheres(position=pos, radius=[R_SPHERE, R_SPHERE], mass=[np.inf, mass1], inertia=[np.inf, inertia1])
    b = Bonds.create(s, Plates([]), [1], [0], law)
    return s, b


def bond_law(
    law: GeneralizedBurgers,
    tangential: bool = False,
    nu: float = POISSON_RATIO,
    r_min: float = R_SPHERE,
    l0: float = L0,
) -> GeneralizedBurgers:
    """Micro law (N/m, N s/m) of a bond of the verification geometry (Eqs. 30-33, 8-11)."""
    a = float(bond_scale(r_min, l0)) * (tangential_ratio(nu) if tangential else 1.0)
    return law.scaled(a)


# ----------------------------------------------------------------------------- bonds
def case_creep(
    direction: str = "normal", dt: float = 1e-4, t_end: float = 0.5, kinematics: str = "contact"
) -> list[dict]:
    """Creep of a two-sphere bond under a constant force of R_crit/2 (normal or tangential);
    the loaded sphere does not rotate (with the 'contact' kinematics a force at its barycentre
    would also roll it about the bond point c, harmonic/solver.py; locked, delta is the
    barycentre translation under both kinematics). ``kinematics``: bond kinematics."""
    s, b = _pair(mass1=1e-6, inertia1=np.inf)
    F = 0.5 * b.r_crit[0]
    axis = b.frame[0, 0] if direction == "normal" else b.frame[0, 1]
    f = np.zeros((2, 3))
    f[1] = F * axis
    sim = Simulation(
        s, None, b, NSCDParameters(dt=dt, theta=1.0, gravity=(0, 0, 0), bond_kinematics=kinematics), external_force=f
    )
    micro = bond_law(LAW_15C, tangential=direction != "normal")
    sampled_t: list[float] = []
    sampled_delta: list[float] = []
    x0 = s.position[1].copy()
    n_steps = int(round(t_end / dt))
    for k in range(n_steps):
        sim.step()
        if (k + 1) % max(1, n_steps // 50) == 0:
            sampled_t.append(sim.time)
            sampled_delta.append((s.position[1] - x0) @ axis)
    times, num = np.array(sampled_t), np.array(sampled_delta)
    ana = F * micro.creep_compliance(times)
    worst = int(np.argmax(np.abs(num - ana) / ana))
    return [
        _row(
            f"creep_{direction}", f"delta at t = {times[worst]:.3g} s (worst of 50)", num[worst], ana[worst], 1e-2, "m"
        ),
        _row(f"creep_{direction}", f"delta at t = {times[-1]:.3g} s", num[-1], ana[-1], 1e-2, "m"),
    ]


def relaxation_response(micro: GeneralizedBurgers, gap: float, times) -> np.ndarray:
    """Bond force (N, restoring, = -stiffness x gap) at ``times`` (s) after a step ``gap`` (m)
    at t = 0, by the matrix exponential of the chain's linear ODE (exact).

    State y = (delta_c, delta_k[0..NK-1]); R_ch = -Km (gap - sum y);
    d(delta_c)/dt = -R_ch/Cm, d(delta_k)/dt = -(R_ch + Kk delta_k)/Ck.
    """
    nk = micro.n_kelvin
    n = 1 + nk
    A = np.zeros((n, n))
    c = np.zeros(n)
    inv_c = np.array([0.0 if np.isinf(micro.eta_m) else 1.0 / micro.eta_m] + [1.0 / x for x in micro.eta_k])
    kk = np.array([0.0] + list(micro.Ek))
    # R_ch = -Km gap + Km sum(y)
    for r in range(n):
        A[r, :] += -inv_c[r] * micro.Em
        c[r] = inv_c[r] * micro.Em * gap
        A[r, r] += -inv_c[r] * kk[r]
    # y' = A y + c, y(0) = 0 -> y(t) = A^-1 (expm(A t) - I) c
    out = []
    Ainv_c = np.linalg.solve(A, c)
    for t in np.atleast_1d(times):
        y = (scipy.linalg.expm(A * t) - np.eye(n)) @ Ainv_c
        out.append(-micro.Em * (gap - y.sum()) - micro.E_inf * gap)
    return np.array(out)


def case_relaxation(dt: float = 1e-4, t_end: float = 0.3, theta: float = 0.5) -> list[dict]:
    """Sphere fixed, bonded to a plate whose displacement steps by u0 during the first step."""
    s = Spheres(
        position=np.array([[0.0, 0.0, L0]]),
        radius=np.array([R_SPHERE]),
        mass=np.array([np.inf]),
        inertia=np.array([np.inf]),
    )
    u0 = 1e-6
    plates = Plates(
        [
            Plate(
                [0, 0, 0],
                [0, 0, 1],
                mode="driven",
                mass=0.1,
                displacement=(np.array([0.0, dt, 1e9]), np.array([[0, 0, 0], [0, 0, u0], [0, 0, u0]])),
            )
        ]
    )
    b = Bonds.create(s, plates, [0], [-1], LAW_15C)
    b.r_crit[:] = np.inf
    sim = Simulation(s, plates, b, NSCDParameters(dt=dt, theta=theta, gravity=(0, 0, 0)))
    n_steps = int(round(t_end / dt))
    times, num = [], []
    for k in range(n_steps):
        sim.step()
        if (k + 1) % max(1, n_steps // 30) == 0:
            times.append(sim.time - 0.5 * dt)  # the gap ramps over the first step
            num.append(b.force[0, 0])
    micro = bond_law(LAW_15C, l0=L0)
    # the plate moves +u0 along n: the gap delta_n = -u0; force R_n = +K u0 > 0 (pushes back)
    ana = relaxation_response(micro, -u0, np.array(times))
    worst = int(np.argmax(np.abs(np.array(num) - ana) / np.abs(ana)))
    return [
        _row("relaxation", f"R_n at t = {times[worst]:.3g} s (worst of 30)", num[worst], ana[worst], 1e-2, "N"),
        _row("relaxation", f"R_n at t = {times[-1]:.3g} s", num[-1], ana[-1], 1e-2, "N"),
    ]


def _fit_harmonic(t, y, omega):
    """Least-squares fit y = a sin(wt) + b cos(wt) + c + d t; returns complex a_hat with
    y ~ Im(a_hat e^{iwt}) (a_hat = a + i b)."""
    M = np.column_stack([np.sin(omega * t), np.cos(omega * t), np.ones_like(t), t - t.mean()])
    coef, *_ = np.linalg.lstsq(M, y, rcond=None)
    return coef[0] + 1j * coef[1]


def _steady_state_bond(
    micro: GeneralizedBurgers, delta_hat: complex, omega: float, k: int, bonds: Bonds, comp: int
) -> None:
    """Set bond k's internal variables (component comp) to the exact steady state of
    delta(t) = Im(delta_hat e^{iwt}) at t = 0."""
    kstar = complex(micro.complex_modulus(omega))
    r_hat = -kstar * delta_hat
    r_ch = r_hat + micro.E_inf * delta_hat
    bonds.force[k, comp] = r_hat.imag
    bonds.delta_c[k, comp] = (-r_ch / (1j * omega * micro.eta_m)).imag
    for u, (ek, ck) in enumerate(zip(micro.Ek, micro.eta_k)):
        bonds.delta_k[k, u, comp] = (-r_ch / (ek + 1j * omega * ck)).imag


def case_sinusoid(freq: float = 10.0, dt: float = 1e-5, theta: float = 0.5, n_cycles: int = 3) -> list[dict]:
    """Two-sphere bond (sphere 0 fixed, sphere 1 of 2 mm radius) under F sin(w t) along n."""
    mass = DENSITY * 4.0 / 3.0 * np.pi * R_SPHERE**3
    s, b = _pair(mass1=mass)
    omega = 2 * np.pi * freq
    F = 0.1 * b.r_crit[0]
    n = b.frame[0, 0]
    micro = bond_law(LAW_15C)
    x_hat = F / (complex(micro.complex_modulus(omega)) - mass * omega**2)
    # exact steady state at t = 0: position, velocity and internal variables
    s.position[1] += x_hat.imag * n
    s.velocity[1] = omega * x_hat.real * n
    _steady_state_bond(micro, x_hat, omega, 0, b, 0)

    def force(t):
        f = np.zeros((2, 3))
        f[1] = F * np.sin(omega * t) * n
        return f

    sim = Simulation(s, None, b, NSCDParameters(dt=dt, theta=theta, gravity=(0, 0, 0)), external_force=force)
    period = 2 * np.pi / omega
    n_steps = int(round(n_cycles * period / dt))
    t_rec, x_rec = np.empty(n_steps), np.empty(n_steps)
    x0 = L0
    for k in range(n_steps):
        sim.step()
        t_rec[k] = sim.time
        x_rec[k] = s.position[1] @ n - x0
    last = t_rec >= t_rec[-1] - 2 * period
    fit = _fit_harmonic(t_rec[last], x_rec[last], omega)
    return [
        _row("sinusoid", f"|X| at {freq:g} Hz, omega dt = {omega * dt:.2g}", abs(fit), abs(x_hat), 5e-3, "m"),
        _row(
            "sinusoid",
            f"phase of X at {freq:g} Hz",
            np.degrees(np.angle(fit)),
            np.degrees(np.angle(x_hat)),
            0.05,
            "deg",
            scale=1.0,
            note="absolute error in degrees",
        ),
    ]


def phase_error_table(
    law: GeneralizedBurgers = LAW_15C,
    omegas=(2 * np.pi * 40.0,),
    dts=(5e-5,),
    thetas=(0.5, 1.0),
    n_cycles: int = 2,
    amplitude: float = HEAD_AMPLITUDE_M,
) -> pd.DataFrame:
    """Phase and amplitude error of the time-discrete bond law (Moreau-Jean theta, internal
    variables by the theta-method) under an imposed sinusoidal gap.

    A sphere is held fixed and bonded to a plate driven along the bond normal with
    u(t) = amplitude sin(omega t); the bond starts from the exact steady state, the force
    of the last cycle is fitted by a sinusoid and compared with -K*(omega) delta, K* the
    bond's complex stiffness (micro law of ``law``, Eqs. 30-33).

    Parameters
    ----------
    law : macro law (Pa, Pa s). omegas : rad/s. dts : s. thetas : in [0.5, 1].
    n_cycles : cycles simulated (the last one is fitted). amplitude : m.

    Returns
    -------
    DataFrame with columns omega_rad_s, frequency_Hz, dt_s, theta, omega_dt, phase_deg
    (numerical), phase_exact_deg, phase_error_deg (numerical - exact), amplitude_rel_error.
    """
    rows = []
    micro = bond_law(law)
    for omega in omegas:
        kstar = complex(micro.complex_modulus(omega))
        for dt in dts:
            for theta in thetas:
                s = Spheres(
                    position=np.array([[0.0, 0.0, L0]]),
                    radius=np.array([R_SPHERE]),
                    mass=np.array([np.inf]),
                    inertia=np.array([np.inf]),
                )
                drive = lambda t, w=omega: np.array([0.0, 0.0, amplitude * np.sin(w * t)])
                plates = Plates([Plate([0, 0, 0], [0, 0, 1], mode="driven", mass=0.1, displacement=drive)])
                b = Bonds.create(s, plates, [0], [-1], law)
                b.r_crit[:] = np.inf
                # delta_n = -u(t) = Im(-amplitude e^{iwt})
                _steady_state_bond(micro, -amplitude + 0j, omega, 0, b, 0)
                sim = Simulation(s, plates, b, NSCDParameters(dt=dt, theta=theta, gravity=(0, 0, 0)))
                period = 2 * np.pi / omega
                n_steps = max(int(round(n_cycles * period / dt)), 8)
                t = np.empty(n_steps)
                r = np.empty(n_steps)
                for k in range(n_steps):
                    sim.step()
                    t[k] = sim.time
                    r[k] = b.force[0, 0]
                last = t >= t[-1] - period
                r_hat = _fit_harmonic(t[last], r[last], omega)
                k_num = -r_hat / (-amplitude)
                rows.append(
                    {
                        "omega_rad_s": omega,
                        "frequency_Hz": omega / (2 * np.pi),
                        "dt_s": dt,
                        "theta": theta,
                        "omega_dt": omega * dt,
                        "phase_deg": float(np.degrees(np.angle(k_num))),
                        "phase_exact_deg": float(np.degrees(np.angle(kstar))),
                        "phase_error_deg": float(np.degrees(np.angle(k_num / kstar))),
                        "amplitude_rel_error": float(abs(k_num) / abs(kstar) - 1.0),
                    }
                )
    return pd.DataFrame(rows)


def case_phase_table_rows(table: pd.DataFrame) -> list[dict]:
    """Rows of the verification table from the smallest omega dt at theta = 0.5."""
    sub = table[table.theta == 0.5].sort_values("omega_dt")
    if sub.empty:
        return []
    r = sub.iloc[0]
    return [
        _row(
            "phase_table",
            f"phase error at omega dt = {r.omega_dt:.2g}, theta = 0.5",
            r.phase_deg,
            r.phase_exact_deg,
            0.05,
            "deg",
            scale=1.0,
            note="imposed gap; absolute error in degrees",
        )
    ]


# ----------------------------------------------------------------------------- contacts
def _sphere_at(pos, radius=0.01, rotating=True):
    m = DENSITY * 4.0 / 3.0 * np.pi * radius**3
    inertia = 0.4 * m * radius**2 if rotating else np.inf
    return Spheres(position=[pos], radius=[radius], mass=[m], inertia=[inertia])


def case_rest(dt: float = 1e-4, n_steps: int = 200) -> list[dict]:
    s = _sphere_at([0.0, 0.0, 0.01])
    plates = Plates([Plate([0, 0, 0], [0, 0, 1])])
    sim = Simulation(s, plates, None, NSCDParameters(dt=dt, friction=0.7))
    for _ in range(n_steps):
        st = sim.step()
    w = s.mass[0] * 9.81
    return [
        _row("rest", "plate reaction F_z", -st.plate_force[0, 2], w, 1e-9, "N"),
        _row(
            "rest",
            "penetration",
            max(0.0, -(s.position[0, 2] - 0.01)),
            0.0,
            1e-9,
            "m",
            scale=0.01,
            note="scale: radius",
        ),
    ]


def _incline(alpha_deg, mu, rotating, dt=1e-4, t_end=0.2):
    a = np.radians(alpha_deg)
    normal = np.array([-np.sin(a), 0.0, np.cos(a)])
    down = np.array([-np.cos(a), 0.0, -np.sin(a)])
    r = 0.01
    s = _sphere_at(r * normal, r, rotating)
    plates = Plates([Plate([0, 0, 0], normal)])
    sim = Simulation(s, plates, None, NSCDParameters(dt=dt, friction=mu))
    n = int(round(t_end / dt))
    for _ in range(n):
        sim.step()
    return float(s.velocity[0] @ down) / sim.time


def case_incline(mu: float = 0.5) -> list[dict]:
    g = 9.81
    crit = np.degrees(np.arctan(mu))
    rows = []
    a_stick = _incline(crit - 5.0, mu, rotating=False)
    rows.append(
        _row(
            "incline_block",
            f"a at {crit - 5:.1f} deg < atan(mu) (stick)",
            a_stick,
            0.0,
            1e-9,
            "m/s2",
            scale=g,
            note="scale: g",
        )
    )
    alpha = crit + 10.0
    a_slide = _incline(alpha, mu, rotating=False)
    ana = g * (np.sin(np.radians(alpha)) - mu * np.cos(np.radians(alpha)))
    rows.append(_row("incline_block", f"a at {alpha:.1f} deg > atan(mu) (slide)", a_slide, ana, 1e-6, "m/s2"))
    alpha = 20.0
    a_roll = _incline(alpha, mu, rotating=True)
    rows.append(
        _row(
            "incline_rolling",
            f"a at {alpha:.0f} deg (rolling, tan a < 3.5 mu)",
            a_roll,
            5.0 / 7.0 * g * np.sin(np.radians(alpha)),
            1e-6,
            "m/s2",
        )
    )
    return rows


def case_column(n: int = 5, dt: float = 1e-4, n_steps: int = 300) -> list[dict]:
    r = 0.005
    pos = np.array([[0.0, 0.0, r + 2 * r * k] for k in range(n)])
    m = DENSITY * 4.0 / 3.0 * np.pi * r**3
    s = Spheres(position=pos, radius=np.asarray(r), mass=np.asarray(m), inertia=np.asarray(0.4 * m * r**2))
    plates = Plates([Plate([0, 0, 0], [0, 0, 1])])
    sim = Simulation(s, plates, None, NSCDParameters(dt=dt, friction=0.7, tolerance=1e-10))
    for _ in range(n_steps):
        st = sim.step()
    w = n * m * 9.81
    # reaction of the contact between sphere 0 and 1 = weight of the n-1 spheres above
    sel = (sim.contact_i == 0) & (sim.contact_j == 1)
    r01 = sim.contact_impulse[sel, 0].sum() / dt
    return [
        _row("column", f"plate reaction under {n} spheres", -st.plate_force[0, 2], w, 1e-8, "N"),
        _row("column", "reaction between spheres 1 and 2", r01, (n - 1) * m * 9.81, 1e-8, "N"),
    ]


def case_impact(dt: float = 1e-4, theta: float = 0.5, height: float = 0.05):
    """Sphere dropped on a plate; returns rows and the per-step dissipation."""
    r = 0.01
    s = _sphere_at([0.0, 0.0, r + height], r)
    plates = Plates([Plate([0, 0, 0], [0, 0, 1])])
    sim = Simulation(s, plates, None, NSCDParameters(dt=dt, theta=theta, friction=0.7))
    v_imp = 0.0
    diss = []
    max_pen = 0.0
    post = []
    impacted = False
    for _ in range(int(round(2 * np.sqrt(2 * height / 9.81) / dt)) + 200):
        v_before = s.velocity[0, 2]
        st = sim.step()
        diss.append(st.dissipated)
        if impacted:  # steps after the impact step (which closes the remaining gap)
            post.append(s.velocity[0, 2])
            max_pen = max(max_pen, -(s.position[0, 2] - r))
        if st.n_active_contacts and not impacted:
            impacted = True
            v_imp = -v_before
            max_pen = max(max_pen, -(s.position[0, 2] - r))
    bound = (1 - theta) * dt * v_imp
    rows = [
        _row(
            "impact",
            "normal velocity after the impact step (max |v_z|)",
            np.max(np.abs(post)),
            0.0,
            1e-9,
            "m/s",
            scale=v_imp,
            note="scale: impact velocity",
        ),
        _row(
            "impact",
            "penetration <= (1 - theta) h v_impact",
            max_pen,
            bound,
            1e-9,
            "m",
            scale=bound,
            bound=True,
            note="upper bound",
        ),
    ]
    return rows, np.array(diss), 0.5 * s.mass[0] * v_imp**2


def rigid_rotation_force(
    kinematics: str, with_plate: bool = False, omega: float = 5.0, dt: float = 1e-5, n_steps: int = 20
) -> float:
    """Largest bond force (N) over ``n_steps`` steps of a bonded pair in rigid rotation.

    Sphere-sphere: two mobile spheres at (0,0,0) and (L0,0,0), angular velocity (0, 0, omega)
    rad/s about the origin, velocities omega x x. ``with_plate``: one sphere bonded to a
    rotating plate (z = 0, driven with zero translation, free rotation), both spinning
    about (0, 0, 0) with omega about y. No gravity; theta = 0.5.
    """
    m = 4.0 / 3.0 * np.pi * R_SPHERE**3 * DENSITY
    w = np.array([0.0, 0.0, omega]) if not with_plate else np.array([0.0, omega, 0.0])
    if with_plate:
        pos = np.array([[0.0, 0.0, L0 / 2]])
        s = Spheres(
            position=pos, radius=np.array([R_SPHERE]), mass=np.array([m]), inertia=np.array([0.4 * m * R_SPHERE**2])
        )
        plates = Plates(
            [
                Plate(
                    [0, 0, 0],
                    [0, 0, 1],
                    mode="driven",
                    mass=0.1,
                    displacement=lambda t: np.zeros(3),
                    rotation=True,
                    inertia=1e-4,
                )
            ]
        )
        plates.angular_velocity[0] = w
        b = Bonds.create(s, plates, [0], [-1], LAW_15C)
    else:
        pos = np.array([[0.0, 0.0, 0.0], [L0, 0.0, 0.0]])
        s = Spheres(
            position=pos,
            radius=np.array([R_SPHERE] * 2),
            mass=np.array([m] * 2),
            inertia=np.array([0.4 * m * R_SPHERE**2] * 2),
        )
        plates = Plates([])
        b = Bonds.create(s, plates, [1], [0], LAW_15C)
    s.angular_velocity[:] = w
    s.velocity[:] = np.cross(w, s.position)
    sim = Simulation(s, plates, b, NSCDParameters(dt=dt, gravity=(0, 0, 0), bond_kinematics=kinematics))
    f_max = 0.0
    for _ in range(n_steps):
        sim.step()
        f_max = max(f_max, float(np.abs(b.force).max()))
    return f_max


def case_rigid_rotation() -> list[dict]:
    """No bond force under a rigid rotation with the 'contact' kinematics (module docstring)."""
    rows = []
    for with_plate, name in ((False, "sphere-sphere"), (True, "sphere-rotating plate")):
        ref = rigid_rotation_force("barycentre", with_plate)
        rows.append(
            _row(
                "rigid_rotation",
                f"max |bond force|, contact kinematics, {name}",
                rigid_rotation_force("contact", with_plate),
                0.0,
                1e-9,
                "N",
                scale=ref,
                note=f"scale: barycentre kinematics force {ref:.3g} N",
            )
        )
    return rows


def case_breakage(direction: str = "normal", dt: float = 1e-4) -> list[dict]:
    """Force ramp F(t) = rate t on a two-sphere bond; record the force at breakage (the loaded
    sphere does not rotate, as in :func:`case_creep`)."""
    s, b = _pair(mass1=1e-6, inertia1=np.inf)
    rc = b.r_crit[0]
    t_break = 0.2
    rate = rc / t_break
    axis = b.frame[0, 0] if direction == "normal" else b.frame[0, 1]

    def force(t):
        f = np.zeros((2, 3))
        f[1] = rate * t * axis
        return f

    sim = Simulation(s, None, b, NSCDParameters(dt=dt, theta=1.0, gravity=(0, 0, 0)), external_force=force)
    f_at_break = np.nan
    last_intact = np.nan
    for _ in range(int(1.5 * t_break / dt)):
        st = sim.step()
        if st.n_broken:
            f_at_break = rate * sim.time
            break
        last_intact = np.abs(b.force[0, 0]) if direction == "normal" else np.hypot(*b.force[0, 1:])
    return [
        _row(
            f"breakage_{direction}",
            "applied force at breakage",
            f_at_break,
            rc,
            rate * dt / rc + 1e-6,
            "N",
            note="tolerance: one ramp increment",
        ),
        _row(
            f"breakage_{direction}",
            "last intact bond force <= R_crit",
            last_intact,
            rc,
            0.0,
            "N",
            bound=True,
            note="upper bound",
        ),
    ]


def case_dissipation(impact_diss, impact_energy) -> list[dict]:
    rows = [
        _row(
            "dissipation",
            "-(min step dissipation), impact",
            -np.min(impact_diss),
            0.0,
            1e-12,
            "J",
            scale=impact_energy,
            bound=True,
            note="must be <= 0; scale: impact energy",
        )
    ]
    # sliding block
    a = np.radians(40.0)
    normal = np.array([-np.sin(a), 0.0, np.cos(a)])
    s = _sphere_at(0.01 * normal, 0.01, rotating=False)
    s.velocity[0] = 0.1 * np.array([-np.cos(a), 0, -np.sin(a)])  # v0 = 0.1 m/s down
    sim = Simulation(s, Plates([Plate([0, 0, 0], normal)]), None, NSCDParameters(dt=1e-4, friction=0.5))
    mu, v0, n_steps, dt = 0.5, 0.1, 500, 1e-4
    d = sim.run(n_steps).dissipated.to_numpy()
    e = 0.5 * s.mass[0] * (s.velocity[0] ** 2).sum()
    rows.append(
        _row(
            "dissipation",
            "-(min step dissipation), sliding",
            -d.min(),
            0.0,
            1e-12,
            "J",
            scale=e,
            bound=True,
            note="must be <= 0; scale: final kinetic energy",
        )
    )
    t = n_steps * dt
    distance = v0 * t + 0.5 * 9.81 * (np.sin(a) - mu * np.cos(a)) * t**2
    rows.append(
        _row(
            "dissipation",
            "energy dissipated by friction while sliding",
            d.sum(),
            mu * s.mass[0] * 9.81 * np.cos(a) * distance,
            1e-6,
            "J",
            note="mu m g cos(a) x distance slid",
        )
    )
    # bonded sinusoid, theta = 0.5 and 1
    for theta in (0.5, 1.0):
        mass = DENSITY * 4.0 / 3.0 * np.pi * R_SPHERE**3
        s, b = _pair(mass1=mass)
        F = 0.1 * b.r_crit[0]
        n = b.frame[0, 0]
        sim = Simulation(
            s,
            None,
            b,
            NSCDParameters(dt=5e-5, theta=theta, gravity=(0, 0, 0)),
            external_force=lambda t: np.array([[0, 0, 0], F * np.sin(2 * np.pi * 40 * t) * n]),
        )
        d = sim.run(1000).dissipated.to_numpy()
        rows.append(
            _row(
                "dissipation",
                f"-(min step dissipation), bond, theta = {theta}",
                -d.min(),
                0.0,
                1e-9,
                "J",
                scale=max(np.abs(d).max(), 1e-300),
                bound=True,
                note="must be <= 0; scale: max |step dissipation|",
            )
        )
    return rows


def random_bonded_network(n: int = 40, seed: int = 0, law: GeneralizedBurgers = LAW_15C, contacts: bool = False):
    """A small jittered bonded block for solver comparisons: spheres of radius 2-3 mm on a
    lattice of pitch 7 mm, bonded when the gap is below 2 mm, bottom plate fixed, top plate
    driven along x. ``contacts``: shrink the pitch so that some spheres touch."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(n ** (1 / 3)))
    pitch = 6.2e-3 if contacts else 7e-3
    grid = np.array([[a, b, c] for c in range(side) for b in range(side) for a in range(side)][:n], float) * pitch
    pos = grid + rng.uniform(-2e-4, 2e-4, grid.shape) + 4e-3
    rad = rng.uniform(2e-3, 3e-3, n)
    s = Spheres.from_density(pos, rad, DENSITY)
    z_top = pos[:, 2].max() + 4e-3
    plates = Plates(
        [
            Plate([0, 0, 0], [0, 0, 1]),
            Plate(
                [0, 0, z_top],
                [0, 0, -1],
                mode="driven",
                mass=0.235,
                displacement=lambda t: np.array([HEAD_AMPLITUDE_M * np.sin(2 * np.pi * 40 * t), 0, 0]),
            ),
        ]
    )
    from .detection import plate_pairs, sphere_pairs

    i, j, _ = sphere_pairs(s.position, s.radius, 2e-3)
    pi_, pk, _ = plate_pairs(s.position, s.radius, plates.point, plates.normal, 2e-3)
    bonds = Bonds.create(s, plates, np.concatenate([i, pi_]), np.concatenate([j, -1 - pk]), law)
    return s, plates, bonds


def pressed_sphere_network(push: float, law: GeneralizedBurgers = LAW_15C):
    """:func:`random_bonded_network` (40 spheres, unbreakable bonds) plus one unbonded sphere
    (radius 2.5 mm) touching the sphere of the block's +y face with the highest centre,
    level with it (horizontal contact normal, across the head's x motion), and the external
    force (N+1, 3) N pushing it against the block with ``push`` times its weight: gravity
    and the block's motion load the contact tangentially; with mu = 0.7 it sticks (rolls)
    and slips by turns for push = 2. Returns (spheres, plates, bonds, force)."""
    s, plates, bonds = random_bonded_network(n=40, law=law)
    face = np.flatnonzero(s.position[:, 1] > s.position[:, 1].max() - 1e-3)
    k = face[np.argmax(s.position[face, 2])]
    rn = 2.5e-3
    p = s.position[k] + np.array([0.0, s.radius[k] + rn + 1e-9, 0.0])
    s2 = Spheres.from_density(np.vstack([s.position, p]), np.append(s.radius, rn), DENSITY)
    b2 = Bonds.create(s2, plates, bonds.i, bonds.j, law)
    b2.r_crit[:] = np.inf
    force = np.zeros((s2.n, 3))
    force[-1, 1] = -push * s2.mass[-1] * 9.81
    return s2, plates, b2, force


def case_fast_path_contacts(n_steps: int = 40) -> list[dict]:
    """Impulses of the fast path with a closing contact solved on the condensed Delassus
    operator against NLGS (tol 1e-12), step by step (:func:`pressed_sphere_network`)."""
    sims = []
    for fast in (True, False):
        s, plates, bonds, force = pressed_sphere_network(2.0)
        sims.append(
            Simulation(
                s,
                plates,
                bonds,
                NSCDParameters(
                    dt=5e-5,
                    friction=0.7,
                    tolerance=1e-12,
                    max_iterations=100000,
                    gravity=(0, 0, -9.81),
                    fast_path=fast,
                    linear_solver="direct",
                    fast_path_contacts=16 if fast else 0,
                ),
                external_force=force,
            )
        )
    err_b = err_c = 0.0
    n_fast = n_closed = 0
    for _ in range(n_steps):
        st = sims[0].step()
        sims[1].step()
        n_fast += st.solver == "linear"
        n_closed += st.n_active_contacts > 0
        fb, gb = sims[0].bond_impulse, sims[1].bond_impulse
        err_b = max(err_b, np.abs(fb - gb).max() / np.abs(gb).max())
        if len(sims[1].contact_impulse) and np.abs(sims[1].contact_impulse).max() > 0:
            fc, gc = sims[0].contact_impulse, sims[1].contact_impulse
            err_c = max(err_c, np.abs(fc - gc).max() / np.abs(gc).max())
    note = f"{n_steps} steps, {n_closed} with a closed contact, {n_fast} on the fast path"
    return [
        _row(
            "fast_path_contacts",
            "max |P_bond,fast - P_bond,nlgs| / max |P_bond|",
            err_b,
            0.0,
            1e-8,
            "1",
            scale=1.0,
            note=note,
        ),
        _row(
            "fast_path_contacts",
            "max |P_contact,fast - P_contact,nlgs| / max |P_contact|",
            err_c,
            0.0,
            1e-8,
            "1",
            scale=1.0,
            note=note,
        ),
        _row(
            "fast_path_contacts", "steps left to NLGS", float(n_steps - n_fast), 0.0, 0.0, "steps", scale=1.0, note=note
        ),
    ]


def case_fast_path(n_steps: int = 40) -> list[dict]:
    """Bond forces after n_steps of the linear path and of NLGS (tol 1e-10)."""
    out = []
    for fast in (True, False):
        s, plates, bonds = random_bonded_network()
        sim = Simulation(
            s,
            plates,
            bonds,
            NSCDParameters(
                dt=5e-5, friction=0.7, tolerance=1e-10, max_iterations=20000, gravity=(0, 0, 0), fast_path=fast
            ),
        )
        df = sim.run(n_steps)
        out.append((bonds.force.copy(), df))
    (f_lin, d_lin), (f_gs, _) = out
    scale = np.abs(f_gs).max()
    return [
        _row(
            "fast_path",
            "max |R_linear - R_nlgs| / max |R|",
            np.abs(f_lin - f_gs).max() / scale,
            0.0,
            1e-7,
            "1",
            scale=1.0,
            note=f"{len(f_gs)} bonds, linear steps: {(d_lin.solver == 'linear').sum()}",
        )
    ]


#: Table 3 of the paper at -10 degC read in Pa, Pa s (the stiffest, smallest phase angle).
LAW_M10C = GeneralizedBurgers.burgers(Em=3.98e7, eta_m=6.28e7, Ek=9.56e8, eta_k=1.49e7)


def _driver_phase(fast, solver="cg", tol=1e-7, linear_tol=1e-10, n_cycles=2, freq=40.0, dt=5e-5):
    """Phase (deg) of the top-plate driver force against the imposed displacement of the
    small bonded network under the -10 degC law, fitted over the last cycle."""
    s, plates, bonds = random_bonded_network(n=64, law=LAW_M10C)
    sim = Simulation(
        s,
        plates,
        bonds,
        NSCDParameters(
            dt=dt,
            gravity=(0, 0, 0),
            tolerance=tol,
            max_iterations=100000,
            fast_path=fast,
            linear_solver=solver,
            linear_tolerance=linear_tol,
            convergence="both",
        ),
    )
    omega = 2 * np.pi * freq
    n = int(round(n_cycles / freq / dt))
    t = np.empty(n)
    f = np.empty(n)
    for k in range(n):
        st = sim.step()
        t[k] = sim.time
        f[k] = st.driver_force[1, 0]
    last = t >= t[-1] - 1.0 / freq
    return float(np.degrees(np.angle(_fit_harmonic(t[last], f[last], omega))))


def case_solver_tolerance_phase() -> list[dict]:
    """Phase of a -10 degC, 40 Hz test (small bonded network, top plate driven) with the
    iterative solvers at their default tolerances against the direct solver (exact)."""
    ref = _driver_phase(True, "direct")
    cg = _driver_phase(True, "cg", linear_tol=1e-10)
    gs = _driver_phase(False, tol=1e-7)
    return [
        _row(
            "solver_tolerance",
            "driver-force phase, CG (rel. residual 1e-10)",
            cg,
            ref,
            0.001,
            "deg",
            scale=1.0,
            note="vs direct solver; absolute error in degrees",
        ),
        _row(
            "solver_tolerance",
            "driver-force phase, NLGS (tol 1e-7, quad and max)",
            gs,
            ref,
            0.01,
            "deg",
            scale=1.0,
            note="vs direct solver; absolute error in degrees",
        ),
    ]


def run_all(
    phase_omegas=(2 * np.pi * 40.0,), phase_dts=(1e-5, 2e-5, 5e-5, 1e-4, 2e-4), phase_thetas=(0.5, 0.55, 1.0)
) -> tuple[list[dict], pd.DataFrame]:
    """All verification cases. Returns (rows list, phase error DataFrame)."""
    rows: list[dict] = []
    rows += case_creep("normal")
    rows += case_creep("tangential")
    rows += case_rigid_rotation()
    rows += case_relaxation()
    rows += case_sinusoid()
    table = phase_error_table(LAW_15C, phase_omegas, phase_dts, phase_thetas)
    rows += case_phase_table_rows(table)
    rows += case_rest()
    rows += case_incline()
    rows += case_column()
    imp_rows, imp_diss, imp_e = case_impact()
    rows += imp_rows
    rows += case_breakage("normal")
    rows += case_breakage("tangential")
    rows += case_dissipation(imp_diss, imp_e)
    rows += case_fast_path()
    rows += case_fast_path_contacts()
    rows += case_solver_tolerance_phase()
    return rows, table
