"""Fig. 5-like picture of the preparation stages: side views with spheres drawn to scale."""

from __future__ import annotations

import numpy as np


def _draw_spheres(ax, x, z, radius, norm, cmap):
    from matplotlib.collections import EllipseCollection

    d = 2e3 * np.asarray(radius)
    coll = EllipseCollection(
        d,
        d,
        np.zeros_like(d),
        units="xy",
        offsets=np.column_stack([x, z]) * 1e3,
        offset_transform=ax.transData,
        cmap=cmap,
        norm=norm,
        edgecolors="k",
        linewidths=0.2,
    )
    coll.set_array(d)
    ax.add_collection(coll)
    ax.set_aspect("equal")
    return coll


def stages_figure(stages: list[dict], trapezoid=None):
    """Figure with one side view per stage.

    Parameters
    ----------
    stages
        dicts with ``title``, ``position`` (N, 3, m), ``radius`` (N, m) and ``frame``:
        ``deposition`` (view x-z, gravity down) or ``specimen`` (view x-z, z up along h).
    trapezoid
        :class:`~asphalt_nscd.sample.geometry.Trapezoid` outlined on specimen-frame panels.

    Returns
    -------
    matplotlib Figure
    """
    import matplotlib.pyplot as plt
    from matplotlib.colors import Normalize

    all_d = np.concatenate([2e3 * np.asarray(s["radius"]) for s in stages])
    norm = Normalize(all_d.min(), all_d.max() if all_d.max() > all_d.min() else all_d.min() + 1)
    cmap = plt.get_cmap("viridis")
    dep = [s for s in stages if s["frame"] == "deposition"]
    fig = plt.figure(figsize=(10, 7), layout="constrained")
    grid = fig.add_gridspec(max(len(dep), 1), 2, width_ratios=[3, 1])
    coll = None
    labels = "abcdefgh"
    for k, stage in enumerate(stages):
        if stage["frame"] == "deposition":
            ax = fig.add_subplot(grid[dep.index(stage), 0])
            p = np.asarray(stage["position"])
            coll = _draw_spheres(ax, p[:, 0], p[:, 2], stage["radius"], norm, cmap)
            top = (p[:, 2] + np.asarray(stage["radius"])).max() * 1e3 if len(p) else 1.0
            ax.set_xlim(0, stage.get("length", p[:, 0].max()) * 1e3)
            ax.set_ylim(0, top * 1.05)
            ax.set_xlabel("x (mm)")
            ax.set_ylabel("z (mm)")
        else:
            ax = fig.add_subplot(grid[:, 1])
            p = np.asarray(stage["position"])
            coll = _draw_spheres(ax, p[:, 0], p[:, 2], stage["radius"], norm, cmap)
            if trapezoid is not None:
                xs = 0.5e3 * np.array([-trapezoid.B, trapezoid.B, trapezoid.b, -trapezoid.b, -trapezoid.B])
                zs = 1e3 * np.array([0, 0, trapezoid.h, trapezoid.h, 0])
                ax.plot(xs, zs, "r-", lw=0.8)
            ax.autoscale_view()
            ax.set_xlabel("x (mm)")
            ax.set_ylabel("z (mm)")
        ax.set_title(f"({labels[k]}) {stage['title']}", fontsize=9)
    if coll is not None:
        fig.colorbar(coll, ax=fig.axes, label="diameter (mm)", shrink=0.6)
    return fig
