"""``tri360 report RESULTS``: leaderboard, tables, figures, point clouds and one self-contained ``report.html``.

Reads only the results directory written by ``tri360 evaluate`` / ``tri360 score`` (``results.csv``,
``regions.csv``, ``breakdown.csv``, ``frames.json``, ``config.json``, ``maps/``) plus the frames it names, and
writes into the same directory::

    RESULTS/
      leaderboard.csv  leaderboard.md # every method x overall metrics and MAE per region, + the paper's rows
      mae.md  mae.csv                 # flow pipeline only: variant x scene mean MAE, % vs `average`, paper rows
      fig4_mae.png                    # flow pipeline only: paper Fig. 4 style bars (min-max over frames)
      sparsification.png              # methods with a confidence: MAE vs fraction removed, oracle, AUSE
      error_vs_angle.png              # MAE against the angle between bearing and each baseline (breakdown.csv)
      error_by_distance_texture.png   # MAE against true distance and image texture (breakdown.csv)
      figures/<scene>/<viewpoint>/errors.png          # GT + |pred - gt| of every method, one shared scale
      figures/<scene>/<viewpoint>/regions.png         # the region masks over C's image
      figures/<scene>/<viewpoint>/<group>.clouds.png  # Fig. 3 style top-down / side views per group
      clouds/<scene>/<viewpoint>/ground_truth.ply
      clouds/<scene>/<viewpoint>/<flow>-<rect|plain>/<variant>.ply  # flow pipeline (binary little-endian)
      clouds/<scene>/<viewpoint>/<method>.ply                      # other methods
      report.html                     # everything above inline (images as data URIs), links to the PLYs

**Leaderboard** (:func:`reports.tables.leaderboard_table`): one row per method of ``results.csv`` (flow-pipeline
methods by their label, e.g. ``dis-rect:gradient``, and every other method, e.g. ``sweep`` or a scored
predictions root), columns ``mae_m median_m p90_m bad_5pct delta110 coverage ause`` and the MAE of every region
of ``regions.csv`` but ``all`` (which equals ``mae_m``).  Pooling over frames: each frame's value weighted by its
number of scored pixels (for a region: the region's pixels in that frame), ``sum_f v_f N_f / sum_f N_f``; that
is exact over all pixels for the MAEs and the shares, and the pixel-weighted mean of the per-frame values for
``median_m``, ``p90_m`` and ``ause``.  The paper's Fig. 4 MAEs (``reports.tables.PAPER_MAE_M``: DeepFlow on plain
pairs, their own classroom frame) follow as quoted rows, MAE only, marked as not computed by tri360.  In the HTML
the table sorts by clicking a column header (a small inline script; best first on the first click, reversed on
the next; empty cells last), and the best value of each column among tri360's rows is highlighted.

**Sparsification** (:func:`sparsification_curves`): for every method with a ``confidence.exr`` beside its
distance map, per frame :func:`reports.metrics.sparsification_curves` (frame's maps and ground truth), then the
pixel-weighted mean of the frames' curves (weights: scored pixels), so the area between the mean curve and the
mean oracle is the pixel-weighted mean of the per-frame AUSE of ``results.csv`` -- the leaderboard's ``ause``.

**Maps** (:func:`map_paths`, the rules of ``harness.jobs.evaluate``): flow-pipeline methods
``maps/<scene>/<viewpoint>/<flow>-<rect|plain>/<variant>.distance.exr`` (+ ``<variant>.confidence.exr``), others
``maps/<scene>/<viewpoint>/<method>/distance.exr`` (+ ``confidence.exr``); NaN, inf and ``<= 0`` = no prediction.

Methods that are not the flow pipeline are first-class: a results set with only such methods (e.g. one outside
method scored with ``tri360 score``) gets the full report except the flow-only MAE table and Fig. 4 chart.

Every file is written atomically.  Problems that do not prevent a report (a missing map, a frame that moved,
a missing ``regions.csv``) are listed at the top of ``report.html`` and in :attr:`ReportOutcome.problems`; a
missing/empty results directory or a malformed ``results.csv`` / ``regions.csv`` / ``breakdown.csv`` /
``frames.json`` / ``config.json`` is a :class:`harness.data.errors.UserError`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from harness.data.atomic import atomic_write_bytes, atomic_write_text, clean_stale_partials
from harness.data.errors import FrameError, UserError
from harness.data.exr import CONFIDENCE_CHANNEL, DISTANCE_CHANNEL, read_float_map
from harness.data.frame import read_frame
from harness.data.names import is_safe_name
from harness.data.outputs import ensure_output_dir
from reconstruction.camera.equirect import bearing_grid
from reports import html as H
from reports import plots
from reports.metrics import sparsification_curves as frame_sparsification
from reports.pointcloud import point_grid, write_ply
from reports.regions import regions as frame_regions
from reports.tables import (
    LEADERBOARD_OVERALL,
    config_key,
    config_label,
    config_order,
    leaderboard_display,
    leaderboard_markdown,
    leaderboard_table,
    load_breakdown,
    load_frames,
    load_method_kinds,
    load_regions,
    load_results,
    mae_display,
    mae_markdown,
    mae_table,
    method_order,
    variant_order,
)

__all__ = ["write_report", "build_report", "ReportOutcome", "PLY_CHOICES", "map_paths", "sparsification_curves"]

PLY_CHOICES = ("all", "paper", "none")
DEFAULT_CLOUD_POINTS = 20000
#: figure / group name of the methods that are not the flow pipeline
OTHER_KEY = "other-methods"


@dataclass
class ReportOutcome:
    """What :func:`build_report` wrote.

    Attributes:
        html_path: ``RESULTS/report.html``.
        markdown: what ``tri360 report`` prints: ``leaderboard.md``, then ``mae.md`` when there are
            flow-pipeline methods.
        problems: one line per thing that could not be shown (missing maps, unreadable frames, ...).
        files: every file written, in order.
        leaderboard: the leaderboard table (:func:`reports.tables.leaderboard_table`, also ``leaderboard.csv``).
        sparsification: method label -> pooled curves (:func:`sparsification_curves`).
    """

    html_path: Path
    markdown: str
    problems: list[str] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)
    leaderboard: pd.DataFrame | None = None
    sparsification: dict[str, dict] = field(default_factory=dict)


def write_report(results_dir, *, ply: str = "all", cloud_points: int = DEFAULT_CLOUD_POINTS) -> Path:
    """Write every report output into ``results_dir`` (see the module doc) and return ``report.html``'s path.

    Args:
        results_dir: directory written by ``tri360 evaluate``.
        ply: "all" (a PLY per frame and method, plus ground truth), "paper" (only the deepflow-plain
            configuration, plus ground truth) or "none".
        cloud_points: points per cloud drawn in the scatter views (same seeded pixel subsample for all).
    Raises:
        harness.data.errors.UserError: missing/empty directory, malformed results/regions/breakdown CSV,
            frames.json or config.json.
    """
    return build_report(results_dir, ply=ply, cloud_points=cloud_points).html_path


# ------------------------------------------------------------------------------------------------ helpers


def map_paths(scene: str, viewpoint: str, row) -> tuple[Path, Path]:
    """Where ``tri360 evaluate`` put a method's maps, relative to the results directory.

    Args:
        scene, viewpoint: the frame.
        row: a ``results.csv`` row (mapping with ``method``, ``flow``, ``rectify``, ``variant``).
    Returns:
        ``(distance map, confidence map)`` paths; the confidence map exists only for methods that gave one.
    """
    base = Path("maps") / scene / viewpoint
    if row["flow"]:
        key = config_key(row["flow"], row["rectify"])
        return base / key / f"{row['variant']}.distance.exr", base / key / f"{row['variant']}.confidence.exr"
    return base / row["method"] / "distance.exr", base / row["method"] / "confidence.exr"


def _read_map(path: Path, channel: str, shape: tuple[int, int]) -> np.ndarray:
    """One float32 map (NaN / inf / <= 0 kept: they mean "no prediction"); FrameError naming the file."""
    values = read_float_map(path, channel)
    if values.shape != shape:
        raise FrameError(f"{path}: shape {values.shape} differs from the frame's {shape}")
    return values


SECTION_HALF_ANGLE_DEG = 15.0
SECTION_NOTE = (f"top-down: pixels whose bearing is within {SECTION_HALF_ANGLE_DEG:g} deg of horizontal; "
                f"side: within {SECTION_HALF_ANGLE_DEG:g} deg of the world x-z plane")


def _section_sample(frame, n_points: int):
    """Seeded pixel subsample for the cloud views: half near the horizon, half near the x-z plane.

    Returns:
        ``(idx, masks)``: (N,) flat pixel indices of camera C (scored pixels only, sorted) and one (N,) bool
        mask per view of :data:`reports.plots.CLOUD_VIEWS` (top-down, side).
    """
    gt = frame.distance["C"].ravel()
    b = bearing_grid(frame.width, frame.height, frame.cameras["C"].rotation).reshape(-1, 3)
    s = np.sin(np.radians(SECTION_HALF_ANGLE_DEG))
    scored = np.isfinite(gt) & (gt > 0)
    rng = np.random.default_rng(0)  # seeded: the same subsample every run
    picks = []
    for axis in (2, 1):  # top-down: |b_z| small; side: |b_y| small
        cand = np.flatnonzero(scored & (np.abs(b[:, axis]) < s))
        picks.append(rng.choice(cand, size=min(max(1, n_points // 2), cand.size), replace=False))
    idx = np.unique(np.concatenate(picks))
    masks = [np.isin(idx, p) for p in picks]
    return idx, masks


class _CurveSum:
    """Running pixel-weighted sums of per-frame sparsification curves of one method."""

    def __init__(self):
        self.fractions = None
        self.curve = self.oracle = 0.0
        self.weight = 0
        self.frames = 0

    def add(self, fractions: np.ndarray, curve: np.ndarray, oracle: np.ndarray, n_px: int) -> None:
        self.fractions = fractions
        self.curve = self.curve + n_px * curve
        self.oracle = self.oracle + n_px * oracle
        self.weight += n_px
        self.frames += 1

    def result(self) -> dict:
        curve, oracle = self.curve / self.weight, self.oracle / self.weight
        d = curve - oracle
        ause = float(np.sum(0.5 * (d[1:] + d[:-1]) * np.diff(self.fractions)))
        return {"fractions": self.fractions, "curve": curve, "oracle": oracle, "ause": ause, "frames": self.frames,
                "pixels": self.weight}


def sparsification_curves(items) -> dict:
    """Sparsification curves of one method pooled over frames: the pixel-weighted mean of the per-frame curves.

    Args:
        items: ``(pred, gt, confidence)`` per frame, (H, W) each (metres, metres, higher = more trustworthy).
    Returns:
        ``{"fractions", "curve", "oracle"}`` ((K,) each: removal fractions, MAE of the kept pixels in metres, the
        oracle's), ``"ause"`` (trapezoid of curve - oracle, metres: the pixel-weighted mean of the frames' AUSE),
        ``"frames"`` and ``"pixels"`` (scored pixels summed).
    Raises:
        ValueError: no frame with a scored pixel.
    """
    acc = _CurveSum()
    for pred, gt, conf in items:
        g = np.asarray(gt)
        n_px = int(np.count_nonzero(np.isfinite(g) & (g > 0)))
        if n_px:
            acc.add(*frame_sparsification(pred, gt, conf), n_px)
    if not acc.weight:
        raise ValueError("sparsification_curves needs at least one frame with a scored pixel")
    return acc.result()


# ------------------------------------------------------------------------------------------------ builder


def build_report(results_dir, *, ply: str = "all", cloud_points: int = DEFAULT_CLOUD_POINTS) -> ReportOutcome:
    """Like :func:`write_report` but returns the :class:`ReportOutcome` (markdown, problems, files, leaderboard)."""
    if ply not in PLY_CHOICES:
        raise UserError(f"ply must be one of {', '.join(PLY_CHOICES)}, got {ply!r}")
    d = Path(results_dir)
    all_results = load_results(d)
    flow_results = all_results[all_results["flow"] != ""].reset_index(drop=True)
    region_table = load_regions(d)
    breakdown = load_breakdown(d)
    frames = load_frames(d)
    kinds = load_method_kinds(d) or {}
    ensure_output_dir(d)  # inputs are valid: now check that the report can be written, before drawing
    clean_stale_partials(d)  # hidden temporaries of killed report runs
    out = ReportOutcome(html_path=d / "report.html", markdown="")

    def put(rel: str, data: bytes | str) -> Path:
        path = d / rel
        if isinstance(data, str):
            atomic_write_text(path, data)
        else:
            atomic_write_bytes(path, data)
        out.files.append(path)
        return path

    # ---- leaderboard
    if region_table is None:
        out.problems.append(f"{d / 'regions.csv'}: file is missing, so the leaderboard has no per-region MAE")
    board = leaderboard_table(all_results, region_table, kinds)
    out.leaderboard = board
    board_md = leaderboard_markdown(board)
    put("leaderboard.csv", board.to_csv(index=False))
    put("leaderboard.md", board_md)
    out.markdown = board_md

    # ---- flow pipeline: MAE table by configuration x variant, Fig. 4
    fig4 = mae_html = None
    if len(flow_results):
        table = mae_table(flow_results)
        mae_md = mae_markdown(table)
        out.markdown += "\n" + mae_md
        put("mae.md", mae_md)
        put("mae.csv", table.to_csv(index=False))
        mae_html = ('<div class="scroll">' + H.table(mae_display(table), text_columns=2, row_classes=[
            "paper" if s == "paper" else "" for s in table["source"]]) + "</div>")
        fig4 = plots.fig4_mae(flow_results)
        put("fig4_mae.png", fig4)

    # ---- breakdown figures (every method)
    angle_png = other_png = None
    if breakdown is None:
        out.problems.append(f"{d / 'breakdown.csv'}: file is missing, so there are no breakdown plots")
    else:
        angle_png = plots.breakdown_lines(breakdown, ["angle_U", "angle_R"],
                                          "Error against the angle between the pixel's bearing and each baseline")
        put("error_vs_angle.png", angle_png)
        other_png = plots.breakdown_lines(breakdown, ["distance", "texture"],
                                          "Error against true distance and image texture (Sobel magnitude)")
        put("error_by_distance_texture.png", other_png)

    # ---- per frame: error maps, region masks, cloud views, PLYs; sparsification sums
    order = method_order(all_results)
    curve_sums: dict[str, _CurveSum] = {}
    conf_frames: dict[str, list[str]] = {}
    frame_sections = []
    frame_paths = {}
    if frames is None:
        out.problems.append(f"{d / 'frames.json'}: file is missing, so there are no error maps, region masks, "
                            "sparsification curves or point clouds")
    else:
        frame_paths = {(f["scene"], f["viewpoint"]): Path(f["path"]) for f in frames}
    keys = sorted(set(zip(all_results["scene"], all_results["viewpoint"], strict=True)))
    for scene, viewpoint in keys if frames is not None else []:
        section = _frame_section(d, scene, viewpoint, frame_paths, all_results, order, ply, cloud_points, out, put,
                                 curve_sums, conf_frames, first=not frame_sections)
        if section:
            frame_sections.append(section)
    for label in order:
        if label in curve_sums:
            out.sparsification[label] = curve_sums[label].result()
            missing = len(keys) - len(conf_frames[label])
            if missing:
                out.problems.append(f"method {label}: a confidence map for {len(conf_frames[label])} frame(s) but "
                                    f"not for {missing}; its sparsification curve pools only the former")
    spars_png = None
    if out.sparsification:
        spars_png = plots.sparsification_plot(out.sparsification, "Sparsification curves, pooled over frames")
        put("sparsification.png", spars_png)

    # ---- the HTML page
    body = [_header_html(d, all_results, order, out.problems)]
    body.append(_leaderboard_html(board, region_table is not None))
    body.append("<h2>Sparsification (confidence)</h2>")
    if spars_png is not None:
        body.append(H.img(spars_png, "sparsification curves",
                          "Per method with a confidence map: remove the least confident pixels first and plot the MAE "
                          "of the rest (solid), against the oracle that removes the largest errors first (dashed). "
                          "Curves: per-frame sparsification_curves (20 steps), pixel-weighted mean over frames; "
                          "AUSE = area between them (metres), the leaderboard's AUSE. Lower is better."))
    else:
        body.append('<p class="note">No method of these results gave a confidence map, so there are no '
                    "sparsification curves.</p>")
    body.append("<h2>Flow pipeline: MAE by configuration and variant</h2>")
    if mae_html is not None:
        body.append('<p class="note">MAE of camera C\'s distance in metres, mean over frames. "vs average" = '
                    "100 &times; (MAE<sub>average</sub> &minus; MAE<sub>variant</sub>) / MAE<sub>average</sub> for "
                    "the same flow/rectify configuration and frames (positive = better). Pixels with no surface are "
                    "not scored; an invalid prediction (NaN, inf, &le; 0) counts with error = true distance. "
                    "Shaded rows: the paper's own Fig. 4 numbers, quoted, not computed here.</p>")
        body.append(mae_html)
        body.append(H.img(fig4, "Fig. 4 style MAE bar chart",
                          "Bars: mean of the per-frame MAE; error bars: min-max over frames; hatched: the paper's "
                          "figures (one 1000x500 classroom frame, DeepFlow on plain equirect pairs)."))
    else:
        body.append('<p class="note">These results hold no flow-pipeline method, so there is no table by '
                    "configuration and variant and no Fig. 4 chart; the paper's figures are in the leaderboard.</p>")
    body.append("<h2>Error breakdown</h2>")
    if angle_png is not None:
        body.append(H.img(angle_png, "error against angle to baseline",
                          "0 degrees = looking along the baseline towards the other camera (its epipole), "
                          "where triangulation of that pair degenerates."))
        body.append(H.img(other_png, "error against distance and texture",
                          "Texture: Sobel gradient magnitude of C's grey image in grey levels per pixel "
                          "(fixed bins)."))
    else:
        body.append('<p class="note">No breakdown.csv in the results directory.</p>')
    body.append("<h2>Per frame: error maps, regions and point clouds</h2>")
    body.append("".join(frame_sections) or '<p class="note">No frames could be shown (see problems).</p>')
    body.append("<h2>All results</h2>")
    body.append(_all_results_html(all_results))
    out.files.append(out.html_path)
    atomic_write_text(out.html_path, H.page("tri360 report", "\n".join(body)))
    return out


def _frame_section(d: Path, scene: str, viewpoint: str, frame_paths: dict, all_results: pd.DataFrame,
                   order: list[str], ply: str, cloud_points: int, out: ReportOutcome, put, curve_sums: dict,
                   conf_frames: dict, first: bool) -> str:
    """One frame's HTML (error maps of every method, region masks, cloud views); writes its figures and PLYs,
    adds its sparsification curves to ``curve_sums``.  Returns "" when the frame cannot be shown (a problem)."""
    if not (is_safe_name(scene) and is_safe_name(viewpoint)):
        out.problems.append(f"scene/viewpoint name {scene!r}/{viewpoint!r} cannot be used as a path; skipped")
        return ""
    if (scene, viewpoint) not in frame_paths:
        out.problems.append(f"{d / 'frames.json'}: no entry for {scene}/{viewpoint}; its maps are not shown")
        return ""
    try:
        frame = read_frame(frame_paths[(scene, viewpoint)])
    except FrameError as exc:
        out.problems.append(f"frame {scene}/{viewpoint} could not be read: {exc}")
        return ""
    if "C" not in frame.distance:
        out.problems.append(f"frame {scene}/{viewpoint} ({frame.path}) has no ground truth; no maps shown")
        return ""
    gt = frame.distance["C"]
    n_scored = int(np.count_nonzero(np.isfinite(gt) & (gt > 0)))
    rows = all_results[(all_results["scene"] == scene) & (all_results["viewpoint"] == viewpoint)]
    rows = {r["method"]: r for _, r in rows.iterrows()}
    preds: dict[str, np.ndarray] = {}
    for label in (m for m in order if m in rows):
        row = rows[label]
        parts = ([config_key(row["flow"], row["rectify"]), row["variant"]] if row["flow"] else [label])
        if not all(is_safe_name(x) for x in parts):
            out.problems.append(f"method name {label!r} cannot be used as a path; its maps are not shown")
            continue
        dist_rel, conf_rel = map_paths(scene, viewpoint, row)
        try:
            preds[label] = _read_map(d / dist_rel, DISTANCE_CHANNEL, gt.shape)
            if (d / conf_rel).exists():
                conf = _read_map(d / conf_rel, CONFIDENCE_CHANNEL, gt.shape)
                if n_scored:
                    curve_sums.setdefault(label, _CurveSum()).add(*frame_sparsification(preds[label], gt, conf),
                                                                   n_scored)
                    conf_frames.setdefault(label, []).append(f"{scene}/{viewpoint}")
        except FrameError as exc:
            out.problems.append(str(exc))
    title = f"{scene} / {viewpoint}"
    blocks = []
    fig_dir = f"figures/{scene}/{viewpoint}"
    if preds:
        err_png = plots.error_maps(gt, preds, f"{title}: every method")
        put(f"{fig_dir}/errors.png", err_png)
        blocks.append(H.details("error maps: every method", H.img(
            err_png, f"error maps {title}",
            "Ground truth distance, then |pred - gt| of every method on one shared colour scale (metres, 0 to the "
            "99th percentile of all panels' errors)."), open_=True))
    try:
        masks = frame_regions(frame)
    except ValueError as exc:
        out.problems.append(f"frame {scene}/{viewpoint}: no region masks ({exc})")
    else:
        reg_png = plots.region_masks(frame.images["C"], masks, f"{title}: evaluation regions")
        put(f"{fig_dir}/regions.png", reg_png)
        blocks.append(H.details("region masks", H.img(
            reg_png, f"region masks {title}",
            "The regions of regions.csv and the leaderboard (definitions: docs/metrics.md); percentages are shares "
            "of the scored pixels."), open_=first))
    # point clouds: one group per flow configuration (its variants), one for every other method
    cam = frame.cameras["C"]
    colors = frame.images["C"].reshape(-1, 3)
    gt_pts = point_grid(gt, cam.position, cam.rotation).reshape(-1, 3)
    idx, view_masks = _section_sample(frame, cloud_points)
    links = []
    if ply != "none":
        rel = f"clouds/{scene}/{viewpoint}/ground_truth.ply"
        n = write_ply(d / rel, gt_pts, colors, comment=f"tri360 ground truth {scene}/{viewpoint} camera C")
        out.files.append(d / rel)
        links.append(H.link(rel, f"ground truth ({n} points)"))
    groups: list[tuple[str, str, bool, dict[str, str]]] = []  # (file key, label, paper set-up?, {name: method})
    flow_rows = [rows[m] for m in preds if rows[m]["flow"]]
    for flow, rect in config_order((r["flow"], r["rectify"]) for r in flow_rows):
        members = {r["variant"]: r["method"] for r in flow_rows if r["flow"] == flow and r["rectify"] == rect}
        members = {v: members[v] for v in variant_order(members)}
        groups.append((config_key(flow, rect), config_label(flow, rect), flow == "deepflow" and not rect, members))
    others = {m: m for m in preds if not rows[m]["flow"]}
    if others:
        groups.append((OTHER_KEY, "other methods", False, others))
    any_paper = any(g[2] for g in groups)
    for i, (key, label, paper, members) in enumerate(groups):
        clouds = {"ground truth": (gt_pts[idx], colors[idx])}
        group_links = []
        for name, method in members.items():
            pts = point_grid(preds[method], cam.position, cam.rotation).reshape(-1, 3)
            clouds[name] = (pts[idx], colors[idx])
            if ply == "all" or (ply == "paper" and paper):
                rel = (f"clouds/{scene}/{viewpoint}/{key}/{name}.ply" if key != OTHER_KEY
                       else f"clouds/{scene}/{viewpoint}/{name}.ply")
                n = write_ply(d / rel, pts, colors, comment=f"tri360 {title} {method}")
                out.files.append(d / rel)
                group_links.append(H.link(rel, f"{name} ({n} points)"))
        cloud_png = plots.cloud_views(clouds, cam.position, f"{title} / {label}", view_masks,
                                      reference="ground truth", subtitle=SECTION_NOTE)
        put(f"{fig_dir}/{key}.clouds.png", cloud_png)
        block = H.img(cloud_png, f"point clouds {title} {label}",
                      f"Fig. 3 style sections, {idx.size} sampled pixels (the same in every column): {SECTION_NOTE}. "
                      "Axis limits from the ground truth's 1-99 % range.")
        if group_links:
            block += '<p class="note">PLY point clouds: ' + ", ".join(group_links) + "</p>"
        blocks.append(H.details(f"point clouds: {label}", block, open_=paper or (i == 0 and not any_paper)))
    ply_note = ('<p class="note">PLY point clouds of this frame: ' + ", ".join(links) + "</p>") if links else ""
    return (f"<h3>{H.esc(scene)} / {H.esc(viewpoint)}</h3>"
            f'<p class="note">frame: {H.esc(frame.path)}</p>{ply_note}' + "".join(blocks))


def _header_html(d: Path, results: pd.DataFrame, order: list[str], problems: list[str]) -> str:
    n_frames = len(set(zip(results["scene"], results["viewpoint"], strict=True)))
    parts = ["<h1>tri360 report</h1>",
             f'<p class="note">results: {H.esc(d.resolve())} &middot; {n_frames} frame(s), {len(order)} method(s): '
             f"{H.esc(', '.join(order))} &middot; generated {H.esc(time.strftime('%Y-%m-%d %H:%M:%S'))}</p>"]
    if problems:
        parts.append('<div class="problems"><strong>Problems (parts of the report are missing):</strong><ul>'
                     + "".join(f"<li>{H.esc(p)}</li>" for p in problems) + "</ul></div>")
    return "\n".join(parts)


def _leaderboard_html(board: pd.DataFrame, have_regions: bool) -> str:
    view = leaderboard_display(board)
    n_overall = len(LEADERBOARD_OVERALL)
    n_regions = len(view["columns"]) - 3 - n_overall
    groups = [("", 3), ("overall (shares in %)", n_overall), ("MAE per region (m)", n_regions)]
    note = ('<p class="note">Every method of these results on camera C\'s distance. Each number is pooled over the '
            "method's frames, each frame weighted by its scored pixels (per region: the region's pixels): exact over "
            "all pixels for the MAEs and shares, the pixel-weighted mean of the per-frame values for median, p90 "
            "and AUSE. Lower is better except for &delta; &lt; 1.10 and coverage; a missing or invalid prediction "
            "counts with error = true distance. Click a column header to sort (best first, click again to "
            "reverse); highlighted: the best value of the column. Shaded rows: the paper's own Fig. 4 MAEs (one "
            "1000x500 classroom frame of theirs, DeepFlow on plain equirect pairs), quoted, <strong>not computed by "
            "tri360</strong>. Regions: docs/metrics.md" + ("" if have_regions else " (no regions.csv: empty)")
            + ". Also as " + H.link("leaderboard.csv", "leaderboard.csv") + " and "
            + H.link("leaderboard.md", "leaderboard.md") + ".</p>")
    return ("<h2>Leaderboard</h2>" + note
            + H.sortable_table(view["display"], view["keys"], view["better"], table_id="leaderboard",
                               text_columns=2, best=view["best"], row_classes=view["row_classes"], groups=groups,
                               data_keys=view["columns"]))


def _all_results_html(all_results: pd.DataFrame) -> str:
    full = all_results.copy()
    for c in ("mae_m", "rmse_m", "median_m"):
        full[c] = full[c].map(lambda v: f"{v:.5f}")
    for c in ("absrel", "delta1", "outlier_rate"):
        full[c] = full[c].map(lambda v: f"{v:.4f}")
    full["seconds"] = full["seconds"].map(lambda v: f"{v:.2f}")
    return '<div class="scroll">' + H.table(full.astype(str), text_columns=8) + "</div>"
