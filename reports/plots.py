"""Figures of the report, each returned as PNG bytes (matplotlib's object API on Agg; no pyplot state).

* :func:`fig4_mae`: paper Fig. 4 style bars: the paper's quoted classroom bars beside tri360's on the classroom, then
  every frame by configuration and variant, with the default method; min-max error bars.
* :func:`error_maps`: ground-truth distance and ``|pred - gt|`` per method, each on its own colour scale.
* :func:`breakdown_lines`: error against a breakdown quantity (angle to a baseline, distance, texture).
* :func:`cloud_views`: paper Fig. 3 style top-down and side sections of point clouds.
* :func:`sparsification_plot`: MAE against the fraction of least-confident pixels removed, with the oracle.
* :func:`region_masks`: the evaluation regions (``reports.regions``) over camera C's image.
* :func:`capture_maps`: a frame without ground truth: C's image and every method's distance, confidence and
  ground-truth-free quality maps (nothing scored).
"""

from __future__ import annotations

import io
import math
import textwrap

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.ticker import FormatStrFormatter

from reconstruction.methods.registry import DEFAULT_METHOD, PAPER_CONFIG
from reports.metrics import score_pixels, scored_pixels
from reports.tables import PAPER_MAE_M, config_order, config_title, paper_scene_rows, variant_order

__all__ = ["variant_colors", "png_bytes", "fig4_mae", "fig4_figure", "error_maps", "error_figure", "error_scale",
           "overview_figure",
           "breakdown_lines", "breakdown_groups", "cloud_views", "CLOUD_VIEWS", "sparsification_plot", "region_masks",
           "REGION_PANELS", "CAPTURE_MAPS", "capture_maps", "METHOD_BAR_COLOR"]

#: resolution of every PNG tri360 draws (report figures and study plots), dots per inch
DPI = 90
NO_SURFACE_RGBA = (0.78, 0.78, 0.78, 1.0)  # light grey: pixel with no surface (not scored)
NO_PREDICTION_RGBA = (1.0, 0.0, 1.0, 1.0)  # magenta: invalid prediction (scored with |err| = gt)


def variant_colors(variants) -> dict[str, tuple]:
    """A stable colour per variant (tab10 in :func:`variant_order`)."""
    cmap = colormaps["tab10"]
    return {v: cmap(i % 10) for i, v in enumerate(variant_order(variants))}


def png_bytes(fig: Figure) -> bytes:
    """Render a figure to PNG bytes at :data:`DPI`: the one PNG encoder of tri360's figures."""
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue()


# ------------------------------------------------------------------------------------------------ Fig. 4


#: colour of a bar of a method that is not the flow pipeline (the default method) in :func:`fig4_mae`
METHOD_BAR_COLOR = (0.3, 0.3, 0.3, 1.0)


def _bar_groups(ax, groups: list[tuple[str, dict[str, pd.Series], bool]], colors: dict) -> None:
    """Draw groups of bars: ``(x label, {bar name: per-frame MAEs (or one quoted value)}, quoted?)``; bar height =
    mean (NaN if any frame's is), error bar = min..max over frames (none for one value), quoted bars hatched."""
    width = 0.8 / max(1, max((len(bars) for _, bars, _ in groups), default=1))
    labelled = set()
    for i, (_, bars, quoted) in enumerate(groups):
        for j, name in enumerate(bars):
            v = pd.to_numeric(bars[name], errors="coerce")
            mean = float(v.mean(skipna=False))
            x = i + (j - (len(bars) - 1) / 2) * width
            err = None if len(v) < 2 else [[mean - float(v.min())], [float(v.max()) - mean]]
            ax.bar([x], [mean], width, color=colors.get(name, METHOD_BAR_COLOR), yerr=err, capsize=2,
                   hatch="//" if quoted else None, edgecolor="0.25" if quoted else None,
                   label=None if quoted or name in labelled else name,
                   error_kw={"elinewidth": 0.8, "ecolor": "0.2"})
            if not quoted:
                labelled.add(name)
            if math.isfinite(mean):
                ax.annotate(f"{mean:.3f}", (x, mean), xytext=(0, 2), textcoords="offset points", ha="center",
                            va="bottom", fontsize=6, rotation=90)
    ax.set_xticks(range(len(groups)), [g[0] for g in groups], fontsize=7.5)
    ax.set_xlim(-0.6, len(groups) - 0.4)
    ax.set_ylabel("mean absolute error of distance (m)", fontsize=8)
    ax.set_ylim(0, ax.get_ylim()[1] * 1.15)
    ax.grid(axis="y", alpha=0.3)


def fig4_figure(results: pd.DataFrame, default_method: str = DEFAULT_METHOD) -> Figure:
    """The figure of :func:`fig4_mae`."""
    flow = results[results["flow"] != ""]
    variants = variant_order([*flow["variant"], *PAPER_MAE_M])
    colors = variant_colors(variants)
    own = results[results["method"] == default_method]

    def config_groups(rows: pd.DataFrame, suffix: str) -> list:
        rows_flow = rows[rows["flow"] != ""]
        out = []
        for f, r in config_order(zip(rows_flow["flow"], rows_flow["rectify"], strict=True)):
            conf = rows_flow[(rows_flow["flow"] == f) & (rows_flow["rectify"] == r)]
            out.append((config_title(f, r).replace(" (", "\n(") + suffix,
                        {v: conf.loc[conf["variant"] == v, "mae_m"] for v in variant_order(conf["variant"])}, False))
        return out

    classroom = results[paper_scene_rows(results)]
    panels = []
    if len(classroom):
        paper = classroom[(classroom["flow"] == PAPER_CONFIG[0]) & (classroom["rectify"] == PAPER_CONFIG[1])]
        n = len(set(zip(classroom["scene"], classroom["viewpoint"], strict=True)))
        ours = f"{config_title(*PAPER_CONFIG)}".replace(" (", "\n(")
        groups = [("paper Fig. 4:\ntheir classroom (quoted)", {v: pd.Series([m]) for v, m in PAPER_MAE_M.items()},
                   True),
                  (f"{ours}\nour classroom" + ("" if len(paper) else "\n(not in these results)"),
                   {v: paper.loc[paper["variant"] == v, "mae_m"] for v in PAPER_MAE_M
                    if (paper["variant"] == v).any()}, False)]
        mine = own[paper_scene_rows(own)]
        if len(mine):
            groups.append((f"{default_method}\n(the default)\nour classroom", {default_method: mine["mae_m"]}, False))
        panels.append((f"the classroom: the paper's Fig. 4 (their frame, 1000x500) beside tri360 (our {n} "
                       f"frame{'s' if n != 1 else ''})", groups))
    n_all = len(set(zip(results["scene"], results["viewpoint"], strict=True)))
    groups = config_groups(results, "")
    if len(own):
        groups.append((f"{default_method}\n(the default)", {default_method: own["mae_m"]}, False))
    scenes = sorted(set(results["scene"]))
    panels.append((f"tri360 on every frame of these results ({n_all}; scenes: "
                   f"{', '.join(scenes[:6])}{', ...' if len(scenes) > 6 else ''})"
                   + ("" if len(classroom) else "; no classroom frame, so the paper's figures (their classroom) are "
                      "not drawn"), groups))
    widths = [max(2, len(g)) for _, g in panels]
    fig = Figure(figsize=(max(7.0, 1.9 * sum(widths) + 1.0), 5.8), layout="constrained")
    fig.suptitle("MAE per variant: bars = mean of the per-frame MAE, error bars = min-max over frames; hatched: the "
                 "paper's own figures, quoted", fontsize=9)
    axes = fig.subplots(1, len(panels), squeeze=False, width_ratios=widths).ravel()
    handles = {}
    for ax, (head, groups), w in zip(axes, panels, widths, strict=True):
        _bar_groups(ax, groups, colors)
        ax.set_title(textwrap.fill(head, max(30, int(w * 24))), fontsize=8.5)
        for h, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, h)
    handles = {k: handles[k] for k in sorted(handles, key=lambda k: (k not in colors, variants.index(k)
                                                                     if k in colors else 0))}
    if any(quoted for _, groups in panels for _, _, quoted in groups):
        handles["the paper's own figures (quoted)"] = Patch(facecolor="white", hatch="//", edgecolor="0.25")
    if handles:
        fig.legend(list(handles.values()), list(handles), loc="outside lower center", ncols=min(len(handles), 7),
                   fontsize=8)
    return fig


def fig4_mae(results: pd.DataFrame, default_method: str = DEFAULT_METHOD) -> bytes:
    """Paper Fig. 4 style bar charts.

    Args:
        results: the validated ``results.csv`` table (``harness.data.results.read_results``): flow-pipeline rows and
            any others (of those only ``default_method``'s are drawn).
        default_method: the label of the method drawn beside the flow pipeline.
    Returns:
        PNG.  When the results hold classroom frames (:func:`reports.tables.paper_scene_rows`), a first panel puts
        the paper's quoted Fig. 4 bars (their classroom frame; hatched) beside tri360's paper set-up
        (``PAPER_CONFIG``) for the same variants on our classroom frames, and ``default_method`` there.  A second
        panel shows every frame: one group per flow configuration, one bar per variant, and ``default_method``;
        the paper's figures are never drawn beside other scenes.  Bars: mean of the per-frame MAE (metres);
        error bars: min..max over frames.
    """
    return png_bytes(fig4_figure(results, default_method))


# ------------------------------------------------------------------------------------------- error maps


def _overlay(mask: np.ndarray, rgba) -> np.ndarray:
    img = np.zeros(mask.shape + (4,), dtype=np.float32)
    img[mask] = rgba
    return img


def error_scale(errors: np.ndarray) -> float:
    """The top of one error panel's colour scale: the 99th percentile of its finite errors (metres; at least 1 mm,
    1 m when there is none), so that each method's own error structure fills its scale."""
    e = np.asarray(errors, dtype=np.float64)
    e = e[np.isfinite(e)]
    return max(float(np.percentile(e, 99)), 1e-3) if e.size else 1.0


def error_figure(gt: np.ndarray, preds: dict[str, np.ndarray], title: str, ncols: int | None = None) -> Figure:
    """The figure of :func:`error_maps` (its axes: ground truth first, then one per prediction, then unused ones)."""
    gt = np.asarray(gt, dtype=np.float64)
    scored = scored_pixels(gt)
    errs, invalid, maes = {}, {}, {}
    for v, p in preds.items():
        mask, e, valid = score_pixels(p, gt)
        full = np.full(gt.shape, np.nan)
        full[mask] = np.where(valid, e, np.nan)
        errs[v] = full
        inv = np.zeros(gt.shape, dtype=bool)
        inv[mask] = ~valid
        invalid[v] = inv
        maes[v] = float(e.mean()) if e.size else float("nan")
    n = 1 + len(preds)
    if ncols is None:
        ncols = 1 if n == 1 else (2 if n <= 4 else 3)
    nrows = math.ceil(n / ncols)
    panel_w = 6.2 if ncols <= 2 else 4.8
    fig = Figure(figsize=(panel_w * ncols + 1.2 * ncols, panel_w / 2 * nrows + 0.4 * nrows + 0.6),
                 layout="constrained")
    fig.suptitle(f"{title}\neach error panel on its own colour scale (0 to its 99th percentile); light grey: no "
                 "surface (not scored); magenta: no valid prediction (scored with error = true distance)", fontsize=9)
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.set_axis_off()
    gt_cmap = colormaps["viridis"].with_extremes(bad=NO_SURFACE_RGBA)
    shown = np.where(scored, gt, np.nan)
    gmax = float(np.nanpercentile(shown, 99.5)) if scored.any() else 1.0
    im = axes[0].imshow(shown, cmap=gt_cmap, vmin=0, vmax=gmax, interpolation="nearest")
    axes[0].set_title("ground truth distance", fontsize=9)
    fig.colorbar(im, ax=axes[0], label="distance (m)", shrink=0.9, extend="max")
    err_cmap = colormaps["magma"].with_extremes(bad=NO_SURFACE_RGBA, over=colormaps["magma"](1.0))
    for ax, v in zip(axes[1:n], preds, strict=True):
        im = ax.imshow(errs[v], cmap=err_cmap, vmin=0, vmax=error_scale(errs[v]), interpolation="nearest")
        if invalid[v].any():
            ax.imshow(_overlay(invalid[v], NO_PREDICTION_RGBA), interpolation="nearest")
        ax.set_title(f"|pred - gt|: {v} (MAE {maes[v]:.4f} m)", fontsize=9)
        fig.colorbar(im, ax=ax, label="absolute error (m)", shrink=0.9, extend="max")
    for ax in axes[:n]:
        ax.set_xticks([])
        ax.set_yticks([])
    return fig


def error_maps(gt: np.ndarray, preds: dict[str, np.ndarray], title: str, ncols: int | None = None) -> bytes:
    """Ground truth and the absolute error maps of several predictions (methods or variants) of one frame.

    Args:
        gt: (H, W) true distance, metres (+inf = no surface).
        preds: label -> (H, W) predicted distance, metres (NaN / inf / <= 0 = invalid), in panel order.
        title: figure title.
        ncols: panels per row (default: 2 up to 3 predictions, else 3).
    Returns:
        PNG: first panel the ground-truth distance (viridis, own colour bar, metres); then one panel of
        ``|pred - gt|`` per prediction (magma), each on its own colour scale from 0 to :func:`error_scale` of its
        errors (the 99th percentile; its own colour bar, metres; larger errors saturate), so that a method whose
        errors are a hundredth of another's still shows where they lie.  Light grey: no surface (not scored);
        magenta: invalid prediction (scored with error = gt).  Each panel title gives its MAE.
    """
    return png_bytes(error_figure(gt, preds, title, ncols))


def overview_figure(image: np.ndarray, gt: np.ndarray, pred: np.ndarray, method: str) -> Figure:
    """One frame in three panels, one above the other: camera C's image, a method's predicted distance and its
    absolute error.

    Args:
        image: (H, W, 3) uint8 sRGB image of camera C.
        gt: (H, W) true distance, metres (+inf = no surface).
        pred: (H, W) predicted distance, metres (NaN / inf / <= 0 = invalid).
        method: the method's label (panel titles).
    Returns:
        The figure (PNG: :func:`png_bytes`): the image; the prediction (viridis, 0 to the 99.5th percentile of the
        true distance, its colour bar in metres); ``|pred - gt|`` (magma, 0 to :func:`error_scale`, larger errors
        saturate; light grey: no surface, magenta: no valid prediction), titled with the frame's MAE.
    """
    gt = np.asarray(gt, dtype=np.float64)
    pred = np.asarray(pred, dtype=np.float64)
    scored = scored_pixels(gt)
    mask, e, valid = score_pixels(pred, gt)
    err = np.full(gt.shape, np.nan)
    err[mask] = np.where(valid, e, np.nan)
    invalid = np.zeros(gt.shape, dtype=bool)
    invalid[mask] = ~valid
    mae = float(e.mean()) if e.size else float("nan")
    fig = Figure(figsize=(7.4, 10.2), layout="constrained")
    axes = fig.subplots(3, 1)
    axes[0].imshow(image, interpolation="antialiased")
    axes[0].set_title("input: camera C (equirectangular)", fontsize=9)
    dmax = float(np.nanpercentile(np.where(scored, gt, np.nan), 99.5)) if scored.any() else 1.0
    shown = np.where(np.isfinite(pred) & (pred > 0), pred, np.nan)
    im = axes[1].imshow(shown, cmap=colormaps["viridis"].with_extremes(bad=NO_PREDICTION_RGBA), vmin=0, vmax=dmax,
                        interpolation="nearest")
    axes[1].set_title(f"predicted distance: {method}", fontsize=9)
    fig.colorbar(im, ax=axes[1], label="distance (m)", shrink=0.9, extend="max")
    cmap = colormaps["magma"].with_extremes(bad=NO_SURFACE_RGBA, over=colormaps["magma"](1.0))
    im = axes[2].imshow(err, cmap=cmap, vmin=0, vmax=error_scale(err), interpolation="nearest")
    if invalid.any():
        axes[2].imshow(_overlay(invalid, NO_PREDICTION_RGBA), interpolation="nearest")
    axes[2].set_title(f"absolute error (MAE {mae:.3f} m)", fontsize=9)
    fig.colorbar(im, ax=axes[2], label="|pred - gt| (m)", shrink=0.9, extend="max")
    for ax in axes:
        ax.set_xticks([])
        ax.set_yticks([])
    return fig


# -------------------------------------------------------------------------------------------- breakdown


OTHER_GROUP = "other methods"


def breakdown_groups(bd: pd.DataFrame) -> pd.DataFrame:
    """Add ``group`` and ``line`` columns to a breakdown table: flow-pipeline rows are grouped by configuration
    (:func:`reports.tables.config_title`) with one line per variant; every other method is a line of its own
    (its label) in the group :data:`OTHER_GROUP`."""
    flow = bd["flow"] != ""
    group = [config_title(f, r) if f else OTHER_GROUP for f, r in zip(bd["flow"], bd["rectify"], strict=True)]
    return bd.assign(group=group, line=np.where(flow, bd["variant"], bd["method"]))


def _group_order(bd: pd.DataFrame) -> list[str]:
    flow_rows = bd[bd["flow"] != ""]
    out = [config_title(f, r) for f, r in config_order(zip(flow_rows["flow"], flow_rows["rectify"], strict=True))]
    return out + ([OTHER_GROUP] if (bd["flow"] == "").any() else [])


def _aggregate_breakdown(bd: pd.DataFrame) -> pd.DataFrame:
    """Pool frames: pixel-weighted MAE per (group, line, kind, bin)."""
    b = breakdown_groups(bd[bd["n_px"] > 0])
    b["err_sum"] = b["mae_m"] * b["n_px"]
    g = b.groupby(["group", "line", "kind", "bin_lo", "bin_hi"], as_index=False)[["err_sum", "n_px"]].sum()
    g["mae_m"] = g["err_sum"] / g["n_px"]
    return g


def _bin_label(lo: float, hi: float) -> str:
    def f(x):
        return f"{x:g}"
    return f"{f(lo)}+" if math.isinf(hi) else f"{f(lo)}-{f(hi)}"


KIND_AXIS = {
    "angle_U": "angle between bearing and C-U baseline (deg)",
    "angle_R": "angle between bearing and C-R baseline (deg)",
    "distance": "true distance (m)",
    "texture": "image gradient magnitude (grey levels / px)",
}


def breakdown_lines(bd: pd.DataFrame, kinds: list[str], title: str) -> bytes:
    """Error against breakdown bins, one row of panels per flow configuration (one line per variant) and one
    for the other methods (one line per method), see :func:`breakdown_groups`.

    Args:
        bd: validated ``breakdown.csv`` table.
        kinds: which ``kind`` values to plot, one panel column each (e.g. ``["angle_U", "angle_R"]``).
        title: figure title.
    Returns:
        PNG.  y: MAE (m, log scale) pooled over frames, weighting each frame's bin by its pixel count;
        x: bin centre in degrees for ``angle_*`` kinds, bin labels otherwise.
    """
    part_bd = bd[bd["kind"].isin(kinds)]
    agg = _aggregate_breakdown(part_bd)
    configs = [g for g in _group_order(part_bd[part_bd["n_px"] > 0]) if g in set(agg["group"])]
    colors = variant_colors(agg["line"])
    nrows = max(1, len(configs))
    fig = Figure(figsize=(5.2 * len(kinds) + 1.5, 2.6 * nrows + 0.8), layout="constrained")
    fig.suptitle(f"{title}\nMAE per bin pooled over frames (pixel-weighted), log scale", fontsize=10)
    axes = fig.subplots(nrows, len(kinds), squeeze=False)
    if not configs:
        for ax in axes.ravel():
            ax.text(0.5, 0.5, "no data", ha="center", va="center", transform=ax.transAxes)
            ax.set_axis_off()
        return png_bytes(fig)
    for r, group in enumerate(configs):
        conf = agg[agg["group"] == group]
        for c, kind in enumerate(kinds):
            ax = axes[r, c]
            part = conf[conf["kind"] == kind]
            bins = part[["bin_lo", "bin_hi"]].drop_duplicates().sort_values("bin_lo")
            angle = kind.startswith("angle")
            for variant in variant_order(part["line"]):
                pv = part[part["line"] == variant].sort_values("bin_lo")
                if angle:
                    x = 0.5 * (pv["bin_lo"] + pv["bin_hi"])
                else:
                    pos = {lo: i for i, lo in enumerate(bins["bin_lo"])}
                    x = pv["bin_lo"].map(pos)
                ax.plot(x, pv["mae_m"], marker="o", ms=3, lw=1.2, color=colors[variant], label=variant)
            if angle:
                ax.set_xlim(0, 180)
                ax.set_xticks(range(0, 181, 30))
            else:
                ticks = [_bin_label(lo, hi) for lo, hi in zip(bins["bin_lo"], bins["bin_hi"], strict=True)]
                ax.set_xticks(range(len(bins)), ticks, fontsize=7)
            if (part["mae_m"] > 0).any():
                ax.set_yscale("log")
                ax.yaxis.set_major_formatter(FormatStrFormatter("%.3g"))
                ax.yaxis.set_minor_formatter(FormatStrFormatter("%.3g"))
                ax.tick_params(axis="y", which="both", labelsize=7)
            ax.grid(alpha=0.3, which="both")
            ax.set_title(group, fontsize=9)
            ax.set_xlabel(KIND_AXIS.get(kind, kind), fontsize=8)
            ax.set_ylabel("MAE (m)", fontsize=8)
            if c == 0 and (r == 0 or group == OTHER_GROUP):
                ax.legend(fontsize=7)
    return png_bytes(fig)


# ---------------------------------------------------------------------------------------------- clouds


#: default views of :func:`cloud_views`: (label, (horizontal axis, vertical axis)) with 0, 1, 2 = world x, y, z
CLOUD_VIEWS = (("top-down (x, y)", (0, 1)), ("side (x, z)", (0, 2)))


def cloud_views(clouds: dict[str, tuple[np.ndarray, np.ndarray]], centre, title: str,
                view_masks: list[np.ndarray] | None = None, reference: str | None = None,
                subtitle: str = "") -> bytes:
    """Paper Fig. 3 style views of point clouds: top-down (x-y) and side (x-z), one column per cloud.

    Args:
        clouds: name -> ``(points (N, 3) metres world, colors (N, 3) uint8)``; non-finite points are skipped.
            Pass the same pixels for every cloud so the columns are comparable.
        centre: (3,) camera C position (drawn as a black cross), metres.
        title: figure title.
        view_masks: optional (N,) bool per view in :data:`CLOUD_VIEWS`: which points each view draws
            (e.g. only pixels near the horizon for the top-down view, giving a floor-plan section).
        reference: name of the cloud whose 1..99 % coordinate range sets the shared axis limits (default: the
            first); points of other clouds outside those limits are cut off by the axes.
        subtitle: second title line (what was sampled).
    Returns:
        PNG with one row per view (top-down: x right, y up; side: x right, z up), ``len(clouds)`` columns.
    """
    names = list(clouds)
    n = len(clouds[names[0]][0])
    masks = view_masks if view_masks is not None else [np.ones(n, dtype=bool)] * len(CLOUD_VIEWS)
    ref = clouds[reference or names[0]][0]
    ref = ref[np.isfinite(ref).all(axis=1)]
    if ref.size:
        lo, hi = np.percentile(ref, 1, axis=0), np.percentile(ref, 99, axis=0)
    else:
        lo, hi = np.full(3, -1.0), np.full(3, 1.0)
    pad = 0.08 * np.maximum(hi - lo, 0.5)
    lo, hi = lo - pad, hi + pad
    c = np.asarray(centre, dtype=np.float64)
    ncols = len(names)
    fig = Figure(figsize=(max(3.3 * ncols + 0.4, 7.0), 6.8), layout="constrained")  # one column: room for the title
    fig.suptitle(f"{title}\npoints X = C + d * bearing coloured by C's image; cross: camera C"
                 + (f"\n{subtitle}" if subtitle else ""), fontsize=9)
    axes = fig.subplots(len(CLOUD_VIEWS), ncols, squeeze=False)
    for i, ((lab, (a, b)), mask) in enumerate(zip(CLOUD_VIEWS, masks, strict=True)):
        size = float(np.clip(3000.0 / max(1, int(mask.sum())), 0.8, 6.0))  # marker area, pt^2
        for j, name in enumerate(names):
            pts, col = clouds[name]
            keep = mask & np.isfinite(pts).all(axis=1)
            p, cc = pts[keep], np.asarray(col)[keep].astype(np.float64) / 255.0
            ax = axes[i, j]
            ax.scatter(p[:, a], p[:, b], s=size, c=cc, marker=".", linewidths=0, rasterized=True)
            ax.plot([c[a]], [c[b]], "k+", ms=8, mew=1.5)
            ax.set_xlim(lo[a], hi[a])
            ax.set_ylim(lo[b], hi[b])
            ax.set_aspect("equal", adjustable="box")
            ax.tick_params(labelsize=7)
            ax.set_title(f"{name}: {lab}", fontsize=8)
            ax.set_facecolor("0.93")
    return png_bytes(fig)


# ------------------------------------------------------------------------------------------ sparsification


def sparsification_plot(curves: dict[str, dict], title: str) -> bytes:
    """Sparsification curves, one panel per method: MAE of the kept pixels against the fraction removed.

    Args:
        curves: method label -> ``{"fractions": (K,), "curve": (K,), "oracle": (K,), "ause": float,
            "frames": int}``: removal fractions 0..1, the method's MAE (metres) after removing its least confident
            pixels, the oracle's (largest errors removed first), the area between them (metres) and the number
            of frames pooled.
        title: figure title.
    Returns:
        PNG: per panel the method's curve (solid) and the oracle (dashed); the legend gives the AUSE.
    """
    names = list(curves)
    ncols = max(1, min(3, len(names)))
    nrows = max(1, math.ceil(len(names) / ncols))
    fig = Figure(figsize=(max(6.0, 4.6 * ncols + 0.4), 3.4 * nrows + 0.9), layout="constrained")
    fig.suptitle(f"{title}\nMAE of the pixels kept after removing a fraction of them:\nthe least confident "
                 "(method, solid) or the largest errors (oracle, dashed)", fontsize=9)
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax in axes[len(names):]:
        ax.set_axis_off()
    colors = variant_colors(names)
    for ax, name in zip(axes, names, strict=False):
        c = curves[name]
        f = np.asarray(c["fractions"], dtype=np.float64)
        ax.plot(f, c["curve"], color=colors[name], lw=1.6, marker="o", ms=2.5,
                label=f"{name} (AUSE {c['ause']:.4f} m)")
        ax.plot(f, c["oracle"], color="0.2", lw=1.2, ls="--", label="oracle")
        ax.fill_between(f, c["oracle"], c["curve"], color=colors[name], alpha=0.15, lw=0)
        ax.set_xlim(0, 1)
        ax.set_ylim(bottom=0)
        ax.set_xlabel("fraction of pixels removed", fontsize=8)
        ax.set_ylabel("MAE of kept pixels (m)", fontsize=8)
        frames = int(c.get("frames", 1))
        ax.set_title(f"{name} ({frames} frame{'s' if frames != 1 else ''})", fontsize=9)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    return png_bytes(fig)


# ------------------------------------------------------------------------------------------- region masks


#: panels of :func:`region_masks`: (title, [(region name, RGB colour), ...]); overlapping regions of one panel
#: are drawn in order (the later on top)
REGION_PANELS = (
    ("textureless", [("textureless", (1.0, 0.85, 0.0))]),
    ("discontinuity", [("discontinuity", (1.0, 0.1, 0.1))]),
    ("occluded", [("occluded_U", (1.0, 0.5, 0.0)), ("occluded_R", (0.0, 0.8, 1.0))]),
    ("epipole", [("epipole_U", (1.0, 0.5, 0.0)), ("epipole_R", (0.0, 0.8, 1.0))]),
    ("pole", [("pole", (0.3, 0.4, 1.0))]),
    ("distance bands", [("d<2m", (0.1, 0.8, 0.2)), ("d2-5m", (1.0, 0.85, 0.0)), ("d>=5m", (0.8, 0.2, 0.9))]),
)
REGION_ALPHA = 0.65


def region_masks(image: np.ndarray, masks: dict[str, np.ndarray], title: str) -> bytes:
    """The evaluation regions of one frame drawn over camera C's image, one panel per :data:`REGION_PANELS`.

    Args:
        image: (H, W, 3) uint8 RGB, camera C.
        masks: region name -> (H, W) bool (:func:`reports.regions.regions`; ``all`` = scored pixels).  Regions
            missing from ``masks`` are left out of their panel.
        title: figure title.
    Returns:
        PNG: C's image darkened and desaturated, the regions as coloured overlays (alpha 0.65); pixels that are
        not scored (no surface) hatched grey.  Panel legends give each region's share of the scored pixels.
    """
    img = np.asarray(image, dtype=np.float64) / 255.0
    grey = img.mean(axis=2, keepdims=True)
    base = np.clip(0.25 + 0.55 * (0.7 * grey + 0.3 * img), 0, 1)  # dimmed, mostly grey: overlays stand out
    scored = masks.get("all")
    n_scored = int(scored.sum()) if scored is not None else 0
    h, w = img.shape[:2]
    ncols = 3
    nrows = math.ceil(len(REGION_PANELS) / ncols)
    panel_w = 4.8
    fig = Figure(figsize=(panel_w * ncols, (panel_w / 2 + 0.75) * nrows + 0.5), layout="constrained")
    fig.suptitle(f"{title}\nregions over camera C's image (overlays; hatched grey: no surface, not scored)",
                 fontsize=9)
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax in axes[len(REGION_PANELS):]:
        ax.set_axis_off()
    for ax, (panel, parts) in zip(axes, REGION_PANELS, strict=False):
        ax.imshow(base, interpolation="nearest")
        if scored is not None and not scored.all():
            ax.imshow(_overlay(~scored, (0.78, 0.78, 0.78, 0.85)), interpolation="nearest")
        handles = []
        for name, rgb in parts:
            if name not in masks:
                continue
            m = np.asarray(masks[name], dtype=bool)
            ax.imshow(_overlay(m, (*rgb, REGION_ALPHA)), interpolation="nearest")
            share = 100.0 * m.sum() / n_scored if n_scored else float("nan")
            handles.append(Patch(color=rgb, label=f"{name}: {share:.1f} %"))
        ax.set_title(panel, fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_xlim(-0.5, w - 0.5)
        ax.set_ylim(h - 0.5, -0.5)
        if handles:
            ax.legend(handles=handles, fontsize=7.5, loc="upper center", bbox_to_anchor=(0.5, -0.01),
                      ncols=len(handles), frameon=False, handlelength=1.0, columnspacing=0.8)
    return png_bytes(fig)


# ------------------------------------------------------------------------------- frames without ground truth


#: the columns of :func:`capture_maps`: (map name, panel title, colour map, colour bar label, scale) where the scale
#: is "zero" (0 to the 99th percentile of the column's pooled finite values) or "range" (1st to 99th percentile)
CAPTURE_MAPS = (
    ("distance", "distance", "viridis", "distance (m)", "zero"),
    ("confidence", "confidence", "cividis", "confidence (higher = more trusted)", "range"),
    ("uncertainty", "uncertainty (quality)", "magma", "uncertainty (higher = less trusted)", "zero"),
    ("photometric_residual", "photometric residual", "magma", "residual (grey levels)", "zero"),
)


def capture_maps(image: np.ndarray, maps: dict[str, dict[str, np.ndarray]], title: str) -> bytes:
    """The maps of a frame without ground truth (a real capture): nothing is scored, so no error is drawn.

    Args:
        image: (H, W, 3) uint8 RGB, camera C.
        maps: method label -> {map name -> (H, W) float}, names from :data:`CAPTURE_MAPS` (``distance`` in metres,
            NaN / inf / <= 0 = no prediction; ``confidence``; the quality maps of ``reconstruction.quality``, NaN
            where the distance is invalid); a method may lack any of them.
        title: figure title.
    Returns:
        PNG: C's image, then one row per method and one column per map name that some method has; each column on
        one shared colour scale (:data:`CAPTURE_MAPS`).  Magenta: no valid prediction (distance); light grey: no
        value.
    """
    columns = [c for c in CAPTURE_MAPS if any(c[0] in m for m in maps.values())]
    ncols = max(1, len(columns))
    nrows = 1 + len(maps)
    panel_w = 4.6
    fig = Figure(figsize=(panel_w * ncols + 1.0 * ncols, (panel_w / 2 + 0.5) * nrows + 0.6), layout="constrained")
    fig.suptitle(f"{title}\nno ground truth: nothing scored; magenta: no valid prediction; light grey: no value",
                 fontsize=9)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    axes[0, 0].imshow(np.asarray(image), interpolation="nearest")
    axes[0, 0].set_title("camera C", fontsize=9)
    for ax in axes[0, 1:]:
        ax.set_axis_off()
    for j, (name, head, cmap_name, bar, scale) in enumerate(columns):
        arrays = {label: np.asarray(m[name], dtype=np.float64) for label, m in maps.items() if name in m}
        pooled = [a[np.isfinite(a) & ((a > 0) if name == "distance" else True)] for a in arrays.values()]
        pooled = np.concatenate(pooled) if pooled else np.zeros(0)
        if pooled.size:
            lo = 0.0 if scale == "zero" else float(np.percentile(pooled, 1))
            hi = float(np.percentile(pooled, 99))
        else:
            lo, hi = 0.0, 1.0
        hi = hi if hi > lo else lo + 1e-3
        cmap = colormaps[cmap_name].with_extremes(bad=NO_SURFACE_RGBA)
        im, col_axes = None, []
        for i, label in enumerate(maps, start=1):
            ax = axes[i, j]
            if label not in arrays:
                ax.set_axis_off()
                continue
            a = arrays[label]
            shown = np.where(np.isfinite(a) & ((a > 0) if name == "distance" else True), a, np.nan)
            im = ax.imshow(shown, cmap=cmap, vmin=lo, vmax=hi, interpolation="nearest")
            if name == "distance" and not (np.isfinite(a) & (a > 0)).all():
                ax.imshow(_overlay(~(np.isfinite(a) & (a > 0)), NO_PREDICTION_RGBA), interpolation="nearest")
            ax.set_title(f"{head}: {label}", fontsize=9)
            col_axes.append(ax)
        if im is not None:
            fig.colorbar(im, ax=col_axes, label=bar, shrink=0.9, extend="max" if scale == "zero" else "both")
    for ax in axes.ravel():
        ax.set_xticks([])
        ax.set_yticks([])
    return png_bytes(fig)
