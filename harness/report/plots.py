"""The report's figures, drawn with matplotlib's object API (Agg canvas, no display, no pyplot
state) and returned as PNG bytes for the caller to write atomically."""

from __future__ import annotations

import io

import numpy as np

__all__ = ["success_bars", "category_bars", "topdown_paths", "heatmap_topdown"]


def _figure(width: float, height: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", bbox_inches="tight")
    return buf.getvalue()


def success_bars(labels: list[str], means: list[float], lows: list[float], highs: list[float], *,
                 title: str, ylabel: str = "success rate") -> bytes:
    """Bar per group (``labels``) with asymmetric interval error bars; PNG bytes.

    Shape:
        every list (G,); NaN bounds draw no error bar.
    """
    if not len(labels) == len(means) == len(lows) == len(highs):
        raise ValueError(f"expected equal lengths, got {len(labels)}, {len(means)}, {len(lows)}, {len(highs)}")
    m = np.asarray(means, dtype=np.float64)
    lo = np.nan_to_num(m - np.asarray(lows, dtype=np.float64))
    hi = np.nan_to_num(np.asarray(highs, dtype=np.float64) - m)
    fig = _figure(max(4.0, 0.9 * len(labels) + 2), 3.6)
    ax = fig.subplots()
    x = np.arange(len(labels))
    ax.bar(x, m, color="tab:blue", alpha=0.8)
    ax.errorbar(x, m, yerr=np.stack([np.clip(lo, 0, None), np.clip(hi, 0, None)]), fmt="none", ecolor="black",
                capsize=4)
    ax.set_xticks(x, labels, rotation=25, ha="right", fontsize=8)
    ax.set_ylim(0, 1.05 if np.nanmax(np.r_[m, 0.0]) <= 1 else None)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    return _png(fig)


def category_bars(groups: dict[str, dict[str, tuple[float, int]]], *, title: str, ylabel: str = "success rate") -> bytes:
    """Grouped bars: one cluster per category, one bar per group label; PNG bytes.

    ``groups`` maps a group label to ``{category: (mean, n)}``.
    """
    cats = sorted({c for v in groups.values() for c in v})
    if not cats:
        raise ValueError("category_bars: no categories to draw")
    fig = _figure(max(5.0, 0.6 * len(cats) * max(1, len(groups)) ** 0.5 + 2), 3.8)
    ax = fig.subplots()
    width = 0.8 / max(1, len(groups))
    x = np.arange(len(cats))
    for i, (label, per_cat) in enumerate(groups.items()):
        vals = [per_cat.get(c, (np.nan, 0))[0] for c in cats]
        ax.bar(x + (i - (len(groups) - 1) / 2) * width, vals, width, label=label)
    top = max((m for v in groups.values() for m, _ in v.values() if np.isfinite(m)), default=0.0)
    if top <= 1:
        ax.set_ylim(0, 1.25)  # room for the legend above the bars of a rate
    ax.set_xticks(x, cats, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7)
    ax.grid(axis="y", alpha=0.3)
    return _png(fig)


def topdown_paths(panels: list[dict], *, title: str) -> bytes:
    """Top-down views of episodes, one panel each; PNG bytes.

    Each panel: ``path_xy`` (T, 2) world metres; optional ``blocked_hw`` (H, W) bool with
    ``origin`` (2,) and ``cell`` (the grid of :func:`sim_envs.scenes.floorplan.occupancy_grid`: row i,
    column j covers ``origin + (j, i) * cell``), ``start_xy`` (2,), ``goal_xy`` (2,), ``label`` str.
    """
    if not panels:
        raise ValueError("topdown_paths: expected at least one panel")
    from matplotlib.colors import ListedColormap

    aspect = 0.9
    if panels[0].get("blocked_hw") is not None:
        h, w = np.shape(panels[0]["blocked_hw"])
        aspect = min(1.5, max(0.3, h / w))
    fig = _figure(4.2 * len(panels), 4.2 * aspect + 0.8)
    axes = np.atleast_1d(fig.subplots(1, len(panels)))
    for ax, p in zip(axes, panels):
        path = np.asarray(p["path_xy"], dtype=np.float64).reshape(-1, 2)
        if p.get("blocked_hw") is not None:
            blocked = np.asarray(p["blocked_hw"], dtype=bool)
            (x0, y0), c = p["origin"], float(p["cell"])
            h, w = blocked.shape
            ax.imshow(blocked, origin="lower", extent=(x0, x0 + w * c, y0, y0 + h * c),
                      cmap=ListedColormap(["white", "dimgray"]), vmin=0, vmax=1, interpolation="nearest")
        if len(path):
            ax.plot(path[:, 0], path[:, 1], "-", color="tab:blue", lw=1.5, label="path")
        start = p.get("start_xy")
        if start is None and len(path):
            start = path[0]
        if start is not None:
            ax.plot(*np.asarray(start, dtype=float)[:2], "o", color="tab:green", ms=8, label="start")
        if p.get("goal_xy") is not None:
            ax.plot(*np.asarray(p["goal_xy"], dtype=float)[:2], "*", color="tab:red", ms=14, label="goal")
        ax.set_aspect("equal")
        ax.set_title(p.get("label", ""), fontsize=8)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(title, fontsize=10)
    return _png(fig)


def heatmap_topdown(points_n3: np.ndarray, values_n: np.ndarray, *, title: str) -> bytes:
    """Top-down scatter of a point cloud coloured by a per-point value (highest drawn on top); PNG bytes.

    Shape:
        ``points_n3`` (N, 3) world metres, ``values_n`` (N,); NaN values are drawn grey.
    """
    pts = np.asarray(points_n3, dtype=np.float64)
    vals = np.asarray(values_n, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or vals.shape != (pts.shape[0],):
        raise ValueError(f"expected points (N, 3) and values (N,), got {pts.shape} and {vals.shape}")
    fig = _figure(5.0, 4.2)
    ax = fig.subplots()
    nan = ~np.isfinite(vals)
    ax.scatter(pts[nan, 0], pts[nan, 1], s=2, c="lightgray", linewidths=0)
    order = np.argsort(vals[~nan])
    sc = ax.scatter(pts[~nan][order, 0], pts[~nan][order, 1], s=3, c=vals[~nan][order], cmap="inferno", linewidths=0)
    fig.colorbar(sc, ax=ax, shrink=0.8)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=9)
    ax.tick_params(labelsize=7)
    return _png(fig)
