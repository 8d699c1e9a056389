"""The report's figures, drawn with matplotlib's object API (Agg canvas, no display, no pyplot
state) and returned as PNG bytes for the caller to write atomically."""

from __future__ import annotations

import io

import numpy as np

__all__ = ["success_bars", "category_bars", "topdown_paths", "heatmap_topdown", "FIGURE_WIDTH_IN"]


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


FIGURE_WIDTH_IN = 7.6
"""Width (inches, at 100 dpi: 760 px) of the figures drawn to fit the HTML report's figure box
unscaled, so their labels read at the size they were drawn."""


def _wrap(text: str, width: int) -> str:
    import textwrap

    return "\n".join(textwrap.wrap(str(text), width, break_long_words=True)) or str(text)


def category_bars(groups: dict[str, dict[str, tuple[float, int]]], *, title: str, xlabel: str = "success rate") -> bytes:
    """Success per category as horizontal bars, one panel per group (side by side, sharing the
    category axis), each bar labelled with its count (``k/n`` for a rate); PNG bytes, 760 px wide,
    its height grown with the number of categories. Categories run hardest first (lowest mean
    over every group, weighted by n).

    ``groups`` maps a group label to ``{category: (mean, n)}``; a category a group lacks says
    "not run".
    """
    cats = sorted({c for v in groups.values() for c in v})
    if not cats:
        raise ValueError("category_bars: no categories to draw")
    labels = list(groups)

    def pooled(c):
        pairs = [v[c] for v in groups.values() if c in v and v[c][1] and np.isfinite(v[c][0])]
        n = sum(k for _, k in pairs)
        return (sum(m * k for m, k in pairs) / n if n else np.inf, c)

    cats.sort(key=pooled)
    top = max((m for v in groups.values() for m, _ in v.values() if np.isfinite(m)), default=0.0)
    rate = top <= 1.0
    ncols = min(len(labels), 4)
    nrows = -(-len(labels) // ncols)
    row_in = 0.24
    fig = _figure(FIGURE_WIDTH_IN, nrows * (row_in * len(cats) + 0.9) + 0.4)
    fig.set_layout_engine("constrained")
    axes = np.atleast_2d(fig.subplots(nrows, ncols, sharey=True, squeeze=False))
    y = np.arange(len(cats))
    xmax = 1.0 if rate else top * 1.05 or 1.0
    for i, ax in enumerate(axes.flat):
        if i >= len(labels):
            ax.set_visible(False)
            continue
        per = groups[labels[i]]
        means = np.array([per[c][0] if c in per else np.nan for c in cats], dtype=np.float64)
        ax.barh(y, np.nan_to_num(means), height=0.7, color="tab:blue", alpha=0.85)
        for yi, c in zip(y, cats):
            if c not in per:
                ax.text(0.02 * xmax, yi, "not run", va="center", fontsize=7.5, color="gray", style="italic")
                continue
            m, n = per[c]
            text = f"{int(round(m * n))}/{n}" if rate else f"{m:.2f} ({n})"
            ax.text(np.nan_to_num(m) + 0.03 * xmax, yi, text, va="center", fontsize=8)
        ax.set_xlim(0, xmax * 1.38)
        ax.set_xticks([0, 0.5 * xmax, xmax], [f"{v:g}" for v in (0, 0.5 * xmax, xmax)] if rate else None)
        ax.tick_params(axis="x", labelsize=8)
        ax.set_title(_wrap(labels[i], 22), fontsize=9)
        ax.grid(axis="x", alpha=0.3)
        ax.set_ylim(len(cats) - 0.5, -0.5)
        if i % ncols == 0:
            ax.set_yticks(y, [_wrap(c, 20) for c in cats], fontsize=9)
        if i // ncols == nrows - 1:
            ax.set_xlabel(xlabel, fontsize=8)
    fig.suptitle(title, fontsize=10)
    return _png(fig)


def _goal_region(ax, goal_xy, goal_box, radius: float | None, recorded: bool) -> None:
    """The success region: the goal box grown by the radius (a rounded box), else a circle."""
    from matplotlib.patches import Circle, FancyBboxPatch, Rectangle

    label = None if radius is None else f"success radius {radius:g} m" + ("" if recorded else " (default)")
    if goal_box is not None:
        (x0, y0), (x1, y1) = np.asarray(goal_box, dtype=np.float64).reshape(2, 2)
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fc="tab:red", ec="none", alpha=0.5))
        if radius:
            ax.add_patch(FancyBboxPatch((x0, y0), x1 - x0, y1 - y0, boxstyle=f"round,pad={radius}", fc="tab:red",
                                        ec="tab:red", alpha=0.12, lw=1.2, ls="--", label=label))
    elif goal_xy is not None and radius:
        ax.add_patch(Circle(tuple(np.asarray(goal_xy, dtype=float)[:2]), radius, fc="tab:red", ec="tab:red",
                            alpha=0.12, lw=1.2, ls="--", label=label))


def topdown_paths(panels: list[dict], *, title: str, ncols: int = 2) -> bytes:
    """Top-down views of episodes, ``ncols`` panels a row; PNG bytes, 760 px wide.

    Each panel: ``path_xy`` (T, 2) world metres; optional ``blocked_hw`` (H, W) bool with
    ``origin`` (2,) and ``cell`` (the grid of :func:`sim_envs.scenes.floorplan.occupancy_grid`: row i,
    column j covers ``origin + (j, i) * cell``), ``start_xy`` (2,) (default: the path's first
    point), ``end_xy`` (2,) (default: its last), ``goal_xy`` (2,), ``goal_box`` (2, 2) xy lower
    and upper corners of the goal object, ``radius`` (m) with ``radius_recorded`` (bool): the
    success region drawn around the goal box (else a circle around ``goal_xy``); ``label`` (the
    panel's first title line), ``goal`` (its second: the goal text), ``ok`` (bool: the title's
    colour, green for a success, red for a failure).
    """
    if not panels:
        raise ValueError("topdown_paths: expected at least one panel")
    from matplotlib.colors import ListedColormap
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    ncols = max(1, min(ncols, len(panels)))
    nrows = -(-len(panels) // ncols)
    aspect = 0.9
    if panels[0].get("blocked_hw") is not None:
        h, w = np.shape(panels[0]["blocked_hw"])
        aspect = min(1.5, max(0.3, h / w))
    cell_w = FIGURE_WIDTH_IN / ncols
    fig = _figure(FIGURE_WIDTH_IN, nrows * (cell_w * aspect + 0.7) + 0.8)
    fig.set_layout_engine("constrained")
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False).ravel())
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    for ax, p in zip(axes, panels):
        path = np.asarray(p["path_xy"], dtype=np.float64).reshape(-1, 2)
        if p.get("blocked_hw") is not None:
            blocked = np.asarray(p["blocked_hw"], dtype=bool)
            (x0, y0), c = p["origin"], float(p["cell"])
            h, w = blocked.shape
            ax.imshow(blocked, origin="lower", extent=(x0, x0 + w * c, y0, y0 + h * c),
                      cmap=ListedColormap(["white", "silver"]), vmin=0, vmax=1, interpolation="nearest")
        _goal_region(ax, p.get("goal_xy"), p.get("goal_box"), p.get("radius"), bool(p.get("radius_recorded")))
        if len(path):
            ax.plot(path[:, 0], path[:, 1], "-", color="tab:blue", lw=1.3)
        start = p.get("start_xy") if p.get("start_xy") is not None else (path[0] if len(path) else None)
        end = p.get("end_xy") if p.get("end_xy") is not None else (path[-1] if len(path) else None)
        if start is not None:
            ax.plot(*np.asarray(start, dtype=float)[:2], "o", color="tab:green", ms=7, mec="white")
        if end is not None:
            ax.plot(*np.asarray(end, dtype=float)[:2], "X", color="black", ms=8, mec="white")
        if p.get("goal_xy") is not None:
            ax.plot(*np.asarray(p["goal_xy"], dtype=float)[:2], "*", color="tab:red", ms=13, mec="white")
        ax.set_aspect("equal")
        ok = p.get("ok")
        colour = "black" if ok is None else ("darkgreen" if ok else "firebrick")
        lines = [_wrap(p.get("label", ""), 48)] + ([_wrap(p["goal"], 52)] if p.get("goal") else [])
        ax.set_title("\n".join(lines), fontsize=8.5, color=colour, loc="left")
        ax.tick_params(labelsize=7)
    handles = [Line2D([], [], color="tab:blue", lw=1.3, label="path"),
               Line2D([], [], ls="", marker="o", color="tab:green", ms=7, label="start"),
               Line2D([], [], ls="", marker="X", color="black", ms=8, label="end"),
               Line2D([], [], ls="", marker="*", color="tab:red", ms=12, label="goal"),
               Patch(fc="tab:red", ec="tab:red", alpha=0.2, ls="--", label="success region (goal grown by the radius)")]
    fig.legend(handles=handles, loc="outside lower center", ncols=5, fontsize=7.5, frameon=False)
    fig.suptitle(title, fontsize=10)
    return _png(fig)


def _point_spacing(points_n3: np.ndarray, sample: int = 2000) -> float:
    """Median distance from a point to its nearest neighbour (metres), over an even sample."""
    from scipy.spatial import cKDTree

    if len(points_n3) < 2:
        return 0.0
    probe = points_n3[:: max(1, len(points_n3) // sample)]
    d, _ = cKDTree(points_n3).query(probe, k=2)
    return float(np.median(d[:, 1]))


def _raster_max(points_n3: np.ndarray, values_n: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The highest value per cell of a top-down grid over xy [lo, hi] (NaN where no point falls).
    The cell is 1.6 times the points' spacing (at least 3 mm, at most 1/40 of the crop), and an
    empty cell takes the highest of its eight neighbours, so a map's gaps between points do not
    show as holes.

    Shape:
        ``points_n3`` (N, 3), ``values_n`` (N,) -> (H, W).
    """
    from scipy.ndimage import maximum_filter

    inside = np.all((points_n3[:, :2] >= lo) & (points_n3[:, :2] < hi), axis=1)
    size = float(np.clip(1.6 * _point_spacing(points_n3[inside]), 0.003, float(max(hi - lo)) / 40))
    w, h = max(1, int(np.ceil((hi[0] - lo[0]) / size))), max(1, int(np.ceil((hi[1] - lo[1]) / size)))
    ij = np.minimum(np.floor((points_n3[inside, :2] - lo) / size).astype(np.int64), [w - 1, h - 1])
    grid = np.full(h * w, -np.inf)
    np.maximum.at(grid, ij[:, 1] * w + ij[:, 0], values_n[inside])
    grid = grid.reshape(h, w)
    grid = np.where(np.isfinite(grid), grid, maximum_filter(grid, size=3, mode="constant", cval=-np.inf))
    grid[~np.isfinite(grid)] = np.nan
    return grid


def heatmap_topdown(points_n3: np.ndarray, values_n: np.ndarray, *, title: str, crop_xy: np.ndarray | None = None,
                    gt_box_xy: np.ndarray | None = None, gt_label: str = "ground truth",
                    answer_box_xy: np.ndarray | None = None, verdict: str = "", verdict_ok: bool | None = None,
                    note: str = "") -> bytes:
    """A query's relevancy seen from above: the highest value in each cell of a grid over the
    crop (:func:`_raster_max`; cells whose points all have 0, no concept vector, grey; cells
    with no point white), with the object's ground-truth box (green), the answer's region box
    (dashed), the verdict under the title (green when ``verdict_ok``, red when not) and ``note``
    in small print; PNG bytes.

    Shape:
        ``points_n3`` (N, 3) world metres, ``values_n`` (N,) (NaN counts as 0); ``crop_xy``,
        ``gt_box_xy`` and ``answer_box_xy`` (2, 2): xy lower and upper corners (``crop_xy``
        None: every point).
    """
    pts = np.asarray(points_n3, dtype=np.float64)
    vals = np.asarray(values_n, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or vals.shape != (pts.shape[0],):
        raise ValueError(f"expected points (N, 3) and values (N,), got {pts.shape} and {vals.shape}")
    if not len(pts):
        raise ValueError("heatmap_topdown: expected at least one point, got none")
    vals = np.nan_to_num(vals, nan=0.0)
    if crop_xy is None:
        lo, hi = pts[:, :2].min(axis=0), pts[:, :2].max(axis=0)
    else:
        lo, hi = np.asarray(crop_xy, dtype=np.float64).reshape(2, 2)
    hi = np.maximum(hi, lo + 1e-3)
    grid = _raster_max(pts, vals, lo, hi)
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Rectangle

    aspect = (hi[1] - lo[1]) / (hi[0] - lo[0])
    fig = _figure(6.4, min(7.0, max(2.6, 4.8 * aspect)) + 1.5)
    fig.set_layout_engine("constrained")
    ax = fig.subplots()
    extent = (lo[0], hi[0], lo[1], hi[1])
    ax.imshow(np.where(np.isfinite(grid), 1.0, np.nan), origin="lower", extent=extent,
              cmap=ListedColormap(["#d9d9d9"]), vmin=0, vmax=1, interpolation="nearest")
    hot = np.where(grid > 0, grid, np.nan)
    top = float(np.nanmax(hot)) if np.isfinite(hot).any() else 1.0
    im = ax.imshow(hot, origin="lower", extent=extent, cmap="inferno", vmin=0.0, vmax=max(top, 1e-6),
                   interpolation="nearest")
    fig.colorbar(im, ax=ax, shrink=0.85, label="relevancy (highest in the cell)")
    span = float(max(hi - lo))
    if gt_box_xy is not None:
        (x0, y0), (x1, y1) = np.asarray(gt_box_xy, dtype=np.float64).reshape(2, 2)
        pad = max(0.0, 0.012 * span - 0.5 * min(x1 - x0, y1 - y0))  # a tiny object still shows its box
        ax.add_patch(Rectangle((x0 - pad, y0 - pad), x1 - x0 + 2 * pad, y1 - y0 + 2 * pad, fill=False, ec="lime",
                               lw=2.2, label=gt_label))
    if answer_box_xy is not None:
        (x0, y0), (x1, y1) = np.asarray(answer_box_xy, dtype=np.float64).reshape(2, 2)
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="deepskyblue", lw=1.8, ls="--",
                               label="answer region"))
    if gt_box_xy is not None or answer_box_xy is not None:
        fig.legend(loc="outside lower left", ncols=2, fontsize=8, frameon=False, handlelength=1.5)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)" + (f"\n{_wrap(note, 100)}" if note else ""), fontsize=7.5)
    ax.set_ylabel("y (m)", fontsize=8)
    ax.tick_params(labelsize=7)
    fig.suptitle(_wrap(title, 64), fontsize=12, x=0.02, ha="left")
    if verdict:
        colour = "black" if verdict_ok is None else ("darkgreen" if verdict_ok else "firebrick")
        ax.set_title(_wrap(verdict, 90), fontsize=9.5, color=colour, loc="left")
    return _png(fig)
