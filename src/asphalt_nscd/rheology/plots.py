"""Shared rheology plots: isotherms of |E*| and Phi, Black diagram, Cole-Cole plane.

Every plot takes several named *curve sets* (measured points, model curves, simulation
results, ...) and colours them by temperature; the curve sets differ by marker and line
style, so one legend reads the temperatures and one the sets.

A curve set is a :class:`CurveSet` built from any table with the columns
``temperature_C, frequency_Hz`` and either ``E_norm_MPa, phase_deg`` or the replicate
summary's ``E_norm_MPa_mean, phase_deg_mean`` (then ``E_norm_MPa_std, phase_deg_std``
give error bars). ``E1_MPa, E2_MPa`` are used for the Cole-Cole plane when present,
otherwise computed from |E*| and Phi.

Example::

    from asphalt_nscd.rheology.plots import CurveSet, plot_isotherms, rheology_figure
    sets = [CurveSet("measured", summary, kind="points"),      # error bars from *_std
            CurveSet("Burger's fit", curves, kind="line")]
    fig = rheology_figure(sets, "isotherms-modulus")             # or "isotherms-phase",
                                                                 # "black", "cole-cole"
    ax = plot_isotherms(sets, quantity="phase", ax=my_axes)      # onto existing axes
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

if TYPE_CHECKING:
    from matplotlib.typing import LineStyleType

MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
LINESTYLES: tuple[LineStyleType, ...] = ("-", "--", ":", "-.")


@dataclass
class CurveSet:
    """A named set of complex-modulus values to plot.

    Parameters
    ----------
    label : str
        Legend name of the set.
    data : DataFrame, shape (n, >= 4)
        ``temperature_C`` (degC), ``frequency_Hz`` (Hz), ``E_norm_MPa`` (MPa),
        ``phase_deg`` (degrees) — or the ``*_mean`` / ``*_std`` columns of a replicate
        summary; optional ``E1_MPa, E2_MPa``.
    kind : {"points", "line"}
        Markers (with error bars when std columns exist) or lines sorted by frequency.
    marker, linestyle : str, optional
        Matplotlib style; default chosen from the set's position.
    style : dict
        Extra keyword arguments for matplotlib (e.g. ``alpha``, ``markersize``).

    Raises
    ------
    ValueError
        on an unknown kind or missing columns.
    """

    label: str
    data: pd.DataFrame
    kind: str = "points"
    marker: str | None = None
    linestyle: LineStyleType | None = None
    style: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.kind not in ("points", "line"):
            raise ValueError(f"curve set {self.label!r}: kind must be 'points' or 'line', got {self.kind!r}")
        d = self.data
        cols = {}
        for name in ("E_norm_MPa", "phase_deg"):
            if name in d.columns:
                cols[name] = d[name]
            elif f"{name}_mean" in d.columns:
                cols[name] = d[f"{name}_mean"]
            else:
                raise ValueError(f"curve set {self.label!r}: missing column {name} (or {name}_mean)")
            if f"{name}_std" in d.columns:
                cols[f"{name}_std"] = d[f"{name}_std"]
        for name in ("temperature_C", "frequency_Hz"):
            if name not in d.columns:
                raise ValueError(f"curve set {self.label!r}: missing column {name}")
            cols[name] = d[name]
        frame = pd.DataFrame(cols).astype(float)
        if "E1_MPa" in d.columns and "E2_MPa" in d.columns:
            frame["E1_MPa"], frame["E2_MPa"] = d["E1_MPa"].astype(float), d["E2_MPa"].astype(float)
        else:
            phi = np.radians(frame["phase_deg"])
            frame["E1_MPa"] = frame["E_norm_MPa"] * np.cos(phi)
            frame["E2_MPa"] = frame["E_norm_MPa"] * np.sin(phi)
        self.data = frame.sort_values(["temperature_C", "frequency_Hz"]).reset_index(drop=True)

    @property
    def temperatures(self) -> np.ndarray:
        return np.unique(self.data["temperature_C"].to_numpy())


def as_curve_sets(curve_sets) -> list[CurveSet]:
    """Normalise the argument of the plot functions to a list of CurveSet.

    Accepts a CurveSet, a list of CurveSets, or a dict ``{label: DataFrame}`` (kind
    "points" when the frame has std columns or few frequencies per temperature, else
    "line").
    """
    if isinstance(curve_sets, CurveSet):
        return [curve_sets]
    if isinstance(curve_sets, dict):
        out = []
        for label, frame in curve_sets.items():
            per_T = frame.groupby("temperature_C")["frequency_Hz"].nunique().max()
            has_std = any(c.endswith("_std") for c in frame.columns)
            out.append(CurveSet(label, frame, kind="points" if has_std or per_T <= 12 else "line"))
        return out
    return list(curve_sets)


def temperature_colors(temperatures, cmap: str = "coolwarm") -> dict:
    """Map each temperature (degC) to a colour, cold blue to hot red."""
    import matplotlib

    temps = np.unique(np.asarray(list(temperatures), dtype=float))
    colormap = matplotlib.colormaps[cmap]
    if temps.size == 1:
        return {float(temps[0]): colormap(0.0)}
    return {float(T): colormap(i / (temps.size - 1)) for i, T in enumerate(temps)}


def _style(cs: CurveSet, index: int) -> tuple[str, LineStyleType]:
    marker = cs.marker or MARKERS[index % len(MARKERS)]
    linestyle = cs.linestyle or LINESTYLES[index % len(LINESTYLES)]
    return marker, linestyle


def _draw(ax, sets, x_of, y_of, xerr_col=None, yerr_col=None, colors=None):
    """Plot every curve set per temperature; return the colour map used."""
    sets = as_curve_sets(sets)
    if colors is None:
        colors = temperature_colors(np.concatenate([cs.temperatures for cs in sets]))
    for index, cs in enumerate(sets):
        marker, linestyle = _style(cs, index)
        for T, group in cs.data.groupby("temperature_C"):
            color = colors.get(float(T), "k")
            x, y = x_of(group), y_of(group)
            if cs.kind == "line":
                ax.plot(x, y, linestyle=linestyle, color=color, **cs.style)
            else:
                xerr = group[xerr_col] if xerr_col and xerr_col in group else None
                yerr = group[yerr_col] if yerr_col and yerr_col in group else None
                ax.errorbar(
                    x,
                    y,
                    xerr=xerr,
                    yerr=yerr,
                    linestyle="none",
                    marker=marker,
                    color=color,
                    markerfacecolor="none" if index % 2 else color,
                    capsize=2,
                    **cs.style,
                )
    _legends(ax, sets, colors)
    return colors


def _legends(ax, sets, colors) -> None:
    from matplotlib.lines import Line2D

    temp_handles = [
        Line2D([], [], color=c, marker="s", linestyle="none", label=f"{T:g} °C") for T, c in sorted(colors.items())
    ]
    set_handles = []
    for index, cs in enumerate(sets):
        marker, linestyle = _style(cs, index)
        if cs.kind == "line":
            set_handles.append(Line2D([], [], color="0.3", linestyle=linestyle, label=cs.label))
        else:
            set_handles.append(
                Line2D(
                    [],
                    [],
                    color="0.3",
                    marker=marker,
                    linestyle="none",
                    label=cs.label,
                    markerfacecolor="none" if index % 2 else "0.3",
                )
            )
    first = ax.legend(
        handles=temp_handles,
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        fontsize=8,
        title="temperature",
        title_fontsize=8,
        frameon=False,
    )
    ax.add_artist(first)
    ax.legend(handles=set_handles, loc="lower left", bbox_to_anchor=(1.01, 0.0), fontsize=8, frameon=False)


def plot_isotherms(curve_sets, quantity: str = "E_norm", ax=None, colors=None):
    """Isotherms versus frequency (log axis): |E*| on a log axis or Phi (paper Figs. 9-10).

    Parameters
    ----------
    curve_sets : CurveSet, list of CurveSet, or dict {label: DataFrame}
    quantity : {"E_norm", "phase"}
        |E*| (MPa, log-log) or phase angle (degrees, semi-log).
    ax : matplotlib Axes, optional
    colors : dict {temperature_C: colour}, optional

    Returns
    -------
    matplotlib Axes
    """
    import matplotlib.pyplot as plt

    if quantity not in ("E_norm", "phase"):
        raise ValueError(f"quantity must be 'E_norm' or 'phase', got {quantity!r}")
    if ax is None:
        _, ax = plt.subplots(figsize=(6.4, 4.4))
    col = "E_norm_MPa" if quantity == "E_norm" else "phase_deg"
    _draw(ax, curve_sets, lambda g: g["frequency_Hz"], lambda g: g[col], yerr_col=f"{col}_std", colors=colors)
    ax.set_xscale("log")
    if quantity == "E_norm":
        ax.set_yscale("log")
        ax.set_ylabel("|E*| (MPa)")
    else:
        ax.set_ylabel("phase angle Φ (°)")
    ax.set_xlabel("frequency (Hz)")
    ax.grid(True, which="both", alpha=0.3)
    return ax


def plot_black(curve_sets, ax=None, colors=None):
    """Black diagram: |E*| (MPa, log axis) versus phase angle (degrees).

    Arguments and return value as :func:`plot_isotherms`.
    """
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(6.4, 4.4))
    _draw(
        ax,
        curve_sets,
        lambda g: g["phase_deg"],
        lambda g: g["E_norm_MPa"],
        xerr_col="phase_deg_std",
        yerr_col="E_norm_MPa_std",
        colors=colors,
    )
    ax.set_yscale("log")
    ax.set_xlabel("phase angle Φ (°)")
    ax.set_ylabel("|E*| (MPa)")
    ax.grid(True, which="both", alpha=0.3)
    return ax


def plot_cole_cole(curve_sets, ax=None, colors=None):
    """Cole-Cole plane: loss modulus E2 versus storage modulus E1 (MPa, linear axes).

    Arguments and return value as :func:`plot_isotherms`.
    """
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(6.4, 4.4))
    _draw(ax, curve_sets, lambda g: g["E1_MPa"], lambda g: g["E2_MPa"], colors=colors)
    ax.set_xlabel("E1 (MPa)")
    ax.set_ylabel("E2 (MPa)")
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    return ax


PLOTS = {
    "isotherms-modulus": lambda sets, ax: plot_isotherms(sets, "E_norm", ax=ax),
    "isotherms-phase": lambda sets, ax: plot_isotherms(sets, "phase", ax=ax),
    "black": lambda sets, ax: plot_black(sets, ax=ax),
    "cole-cole": lambda sets, ax: plot_cole_cole(sets, ax=ax),
}


def rheology_figure(curve_sets, plot: str, title: str | None = None):
    """A new figure with one of the plots: ``isotherms-modulus``, ``isotherms-phase``,
    ``black`` or ``cole-cole``. Returns the matplotlib Figure (close it after saving)."""
    import matplotlib.pyplot as plt

    if plot not in PLOTS:
        raise ValueError(f"unknown plot {plot!r}; expected one of {sorted(PLOTS)}")
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    PLOTS[plot](as_curve_sets(curve_sets), ax)
    if title:
        ax.set_title(title, fontsize=10)
    return fig
