"""The parts of ``report.html`` and the files that go with them, built in memory.

Pure: results DataFrames, frames and distance maps in; HTML, markdown and file contents (relative path ->
bytes or text) out.  Nothing here touches the file system: the report job (``harness.commands.report``) reads a
results set, calls these functions and writes what they return into the results directory::

    RESULTS/
      leaderboard.csv  leaderboard.md # every method x overall metrics and MAE per region, + the paper's rows
      mae.md  mae.csv                 # flow pipeline only: variant x scene mean MAE, % vs `average`, paper rows
      fig4_mae.png                    # paper Fig. 4 style bars: the paper's vs ours on the classroom; every frame
      sparsification.png              # methods with a confidence: MAE vs fraction removed, oracle, AUSE
      error_vs_angle.png              # MAE against the angle between bearing and each baseline (breakdown.csv)
      error_by_distance_texture.png   # MAE against true distance and image texture (breakdown.csv)
      figures/<scene>/<viewpoint>/errors.png          # GT + |pred - gt| of every method, a scale per method
      figures/<scene>/<viewpoint>/regions.png         # the region masks over C's image
      figures/<scene>/<viewpoint>/<group>.clouds.png  # Fig. 3 style top-down / side views per group
      clouds/<scene>/<viewpoint>/ground_truth.ply
      clouds/<scene>/<viewpoint>/<flow>-<rect|plain>/<variant>.ply  # flow pipeline (binary little-endian)
      clouds/<scene>/<viewpoint>/<method>.ply                      # other methods
      report.html                     # everything above inline (images as data URIs), links to the PLYs

Frames without ground truth (real captures: ``reports.schema.unscored_rows``, nothing scored) get instead of the
leaderboard, MAE table, breakdown and sparsification a table of their ground-truth-free quality figures
(:func:`quality_part`: ``quality.csv``, ``quality.md``), and per frame (:func:`capture_part`) no error maps,
regions or ground-truth cloud::

      figures/<scene>/<viewpoint>/maps.png            # C's image, every method's distance, confidence, quality maps
      figures/<scene>/<viewpoint>/<group>.clouds.png  # the same cloud views, without a ground-truth column
      clouds/<scene>/<viewpoint>/...ply               # every method's cloud, the same layout as above

**Leaderboard** (:func:`leaderboard_part`, :func:`reports.tables.leaderboard_table`): one row per method of the
results (flow-pipeline methods by their label, e.g. ``dis-rect:gradient``, and every other method, e.g.
``sweep`` or a scored predictions root), the columns of :data:`reports.tables.LEADERBOARD_OVERALL` (``mae_m``, the MAE
as a multiple of the floor ``mae_x_floor`` and the floor ``floor_m`` itself, ``median_m p90_m bad_5pct delta110
coverage ause``...) and the MAE of every region but ``all`` (which equals ``mae_m``), pooled over frames with each
frame weighted by its scored pixels; the paper's Fig. 4 MAEs follow as quoted rows.  Below it, the floor per region
and every method's region MAE as a multiple of it (:func:`reports.tables.floor_region_table`).  In the HTML the
leaderboard sorts by clicking a column header (best first on the first click, reversed on the next; empty cells
last), and the best value of each column among tri360's rows is highlighted (never the floor: a reference).

**Sparsification** (:func:`frame_part`, :func:`sparsification_part`): for every method with a confidence map,
per frame :func:`reports.metrics.sparsification_curves`, then their pixel-weighted mean
(:func:`reports.metrics.pooled_sparsification_curves`), so the area between the mean curve and the mean oracle
is the pixel-weighted mean of the per-frame AUSE: the leaderboard's ``ause``.

Methods that are not the flow pipeline are first-class: results with only such methods get every part but the
flow-only MAE table and Fig. 4 chart.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from reconstruction.camera.equirect import bearing_grid
from reconstruction.methods.flow_pipeline import config_label
from reconstruction.methods.registry import DEFAULT_METHOD, PAPER_CONFIG
from reports import html as H
from reports import plots
from reports.metrics import scored_pixels, sparsification_curves
from reports.pointcloud import ply_bytes, point_grid
from reports.regions import regions as frame_regions
from reports.schema import METRIC_COLUMNS, QUALITY_COLUMNS, unscored_rows
from reports.tables import (
    FLOOR_ROW,
    FLOOR_TEXT,
    LEADERBOARD_OVERALL,
    NOTHING_SCORED,
    QUALITY_HEADERS,
    config_order,
    config_title,
    floor_region_display,
    floor_region_table,
    group_columns,
    leaderboard_display,
    leaderboard_markdown,
    leaderboard_table,
    mae_display,
    mae_markdown,
    method_order,
    quality_markdown,
    quality_table,
    suite_text,
    variant_mae_table,
    variant_order,
)

__all__ = ["Part", "FramePart", "PLY_CHOICES", "DEFAULT_CLOUD_POINTS", "OTHER_KEY", "SECTION_HALF_ANGLE_DEG",
           "SECTION_NOTE", "section_sample", "leaderboard_part", "flow_mae_part", "breakdown_part",
           "sparsification_part", "frame_anchor", "frame_part", "quality_part", "capture_part", "report_html"]

#: which point clouds become PLY files: every method, only the paper set-up (deepflow-rect) or none
PLY_CHOICES = ("all", "paper", "none")
#: points per cloud drawn in the scatter views (the same seeded pixel subsample for every cloud of a frame)
DEFAULT_CLOUD_POINTS = 20000
#: figure / group name of the methods that are not the flow pipeline
OTHER_KEY = "other-methods"
SECTION_HALF_ANGLE_DEG = 15.0
SECTION_NOTE = (f"top-down: pixels whose bearing is within {SECTION_HALF_ANGLE_DEG:g} deg of horizontal; "
                f"side: within {SECTION_HALF_ANGLE_DEG:g} deg of the world x-z plane")


@dataclass
class Part:
    """One part of the report.

    Attributes:
        html: its HTML (headings included).
        files: relative path (``/``-separated, under the results directory) -> content (bytes, or text written
            as UTF-8), in the order they should be written.
        markdown: what it adds to the text ``tri360 report`` prints ("" for none).
        problems: one line per thing it could not show.
        table: the table behind it, if any (the leaderboard).
    """

    html: str = ""
    files: dict[str, bytes | str] = field(default_factory=dict)
    markdown: str = ""
    problems: list[str] = field(default_factory=list)
    table: pd.DataFrame | None = None


@dataclass
class FramePart(Part):
    """:class:`Part` of one frame, plus ``curves``: method label -> ``(fractions, curve, oracle, n_px)``, the
    frame's :func:`reports.metrics.sparsification_curves` and its scored pixels, for every method given a
    confidence (the input of :func:`reports.metrics.pooled_sparsification_curves`)."""

    curves: dict[str, tuple] = field(default_factory=dict)


def section_sample(frame, n_points: int, pixels: np.ndarray | None = None):
    """Seeded pixel subsample for the cloud views: half near the horizon, half near the x-z plane.

    Args:
        frame: a frame with ground truth for C (``distance["C"]`` (H, W) metres, ``cameras["C"]``).
        n_points: points wanted (about; each half is capped by the pixels available).
        pixels: (H, W) bool, the pixels to sample from instead of the scored ones (a frame without ground truth:
            e.g. where some method predicts a distance).
    Returns:
        ``(idx, masks)``: (N,) flat pixel indices of camera C (scored pixels only, sorted) and one (N,) bool
        mask per view of :data:`reports.plots.CLOUD_VIEWS` (top-down, side).
    """
    scored = (scored_pixels(frame.distance["C"]) if pixels is None else np.asarray(pixels, dtype=bool)).ravel()
    b = bearing_grid(frame.width, frame.height, frame.cameras["C"].rotation).reshape(-1, 3)
    s = np.sin(np.radians(SECTION_HALF_ANGLE_DEG))
    rng = np.random.default_rng(0)  # seeded: the same subsample every run
    picks = []
    for axis in (2, 1):  # top-down: |b_z| small; side: |b_y| small
        cand = np.flatnonzero(scored & (np.abs(b[:, axis]) < s))
        picks.append(rng.choice(cand, size=min(max(1, n_points // 2), cand.size), replace=False))
    idx = np.unique(np.concatenate(picks))
    masks = [np.isin(idx, p) for p in picks]
    return idx, masks


# ------------------------------------------------------------------------------------------ summary parts


def leaderboard_part(results: pd.DataFrame, regions: pd.DataFrame | None = None,
                     kinds: Mapping[str, str] | None = None) -> Part:
    """The leaderboard: ``leaderboard.csv``, ``leaderboard.md`` (also the printed markdown) and its sortable HTML
    table, then the floor and every method's MAE as a multiple of it per region
    (:func:`reports.tables.floor_region_table`, in the leaderboard's order; also in ``leaderboard.md``); ``table``
    is :func:`reports.tables.leaderboard_table`.

    Args:
        results: validated results table; regions: validated region table or None (region columns empty);
        kinds: method label -> kind (``config.json``).
    """
    board = leaderboard_table(results, regions, dict(kinds or {}))
    floors = floor_region_table(results, regions, list(board.loc[board["source"] == "tri360", "method"]))
    md = leaderboard_markdown(board, floors)
    return Part(html=_leaderboard_html(board, regions is not None) + _floor_html(floors, regions is not None),
                files={"leaderboard.csv": board.to_csv(index=False), "leaderboard.md": md}, markdown=md, table=board)


def flow_mae_part(results: pd.DataFrame) -> Part:
    """The flow pipeline's MAE by configuration and variant: ``mae.md`` (also printed), ``mae.csv``,
    ``fig4_mae.png`` and their HTML; only a note when the results hold no flow-pipeline method."""
    head = "<h2>Flow pipeline: MAE by configuration and variant</h2>"
    flow = results[results["flow"] != ""].reset_index(drop=True)
    if not len(flow):
        return Part(html=head + '\n<p class="note">These results hold no flow-pipeline method, so there is no table '
                    "by configuration and variant and no Fig. 4 chart; the paper's figures are in the "
                    "leaderboard.</p>")
    table = variant_mae_table(flow)
    md = mae_markdown(table)
    fig4 = plots.fig4_mae(results)
    html = (head + '\n<p class="note">MAE of camera C\'s distance in metres, mean over frames. "vs average" = '
            "100 &times; (MAE<sub>average</sub> &minus; MAE<sub>variant</sub>) / MAE<sub>average</sub> for "
            "the same flow/rectify configuration and frames (positive = better). Pixels with no surface are "
            "not scored; an invalid prediction (NaN, inf, &le; 0) counts with error = true distance. "
            "Shaded rows: the paper's own Fig. 4 numbers, quoted, not computed here.</p>"
            + '\n<div class="scroll">' + H.table(mae_display(table), text_columns=2, row_classes=[
                "paper" if s == "paper" else "" for s in table["source"]]) + "</div>\n"
            + H.img(fig4, "Fig. 4 style MAE bar chart",
                    "Left (when these results hold classroom frames): the paper's own Fig. 4 figures (hatched; their "
                    f"1000x500 classroom frame) beside {config_title(*PAPER_CONFIG)} and the default method "
                    f"({DEFAULT_METHOD}) on our classroom frames. Right: every frame, by configuration and variant, "
                    "and the default method; the paper's figures are not drawn beside other scenes. Bars: mean of "
                    "the per-frame MAE; error bars: min-max over frames."))
    return Part(html=html, files={"mae.md": md, "mae.csv": table.to_csv(index=False), "fig4_mae.png": fig4},
                markdown=md)


def breakdown_part(breakdown: pd.DataFrame | None) -> Part:
    """The error breakdown plots (every method): ``error_vs_angle.png``, ``error_by_distance_texture.png``;
    only a note when there is no breakdown table."""
    head = "<h2>Error breakdown</h2>"
    if breakdown is None:
        return Part(html=head + '\n<p class="note">No breakdown.csv in the results directory.</p>')
    angle = plots.breakdown_lines(breakdown, ["angle_U", "angle_R"],
                                  "Error against the angle between the pixel's bearing and each baseline")
    other = plots.breakdown_lines(breakdown, ["distance", "texture"],
                                  "Error against true distance and image texture (Sobel magnitude)")
    html = (head + "\n" + H.img(angle, "error against angle to baseline",
                         "0 degrees = looking along the baseline towards the other camera (its epipole), "
                         "where triangulation of that pair degenerates.")
            + "\n" + H.img(other, "error against distance and texture",
                    "Texture: Sobel gradient magnitude of C's grey image in grey levels per pixel (fixed bins)."))
    return Part(html=html, files={"error_vs_angle.png": angle, "error_by_distance_texture.png": other})


def sparsification_part(curves: Mapping[str, dict]) -> Part:
    """The sparsification figure ``sparsification.png`` and its HTML.

    Args:
        curves: method label -> :func:`reports.metrics.pooled_sparsification_curves`, in display order (empty:
            only a note).
    """
    head = "<h2>Sparsification (confidence)</h2>"
    if not curves:
        return Part(html=head + '\n<p class="note">No method of these results gave a confidence map, so there are no '
                    "sparsification curves.</p>")
    png = plots.sparsification_plot(dict(curves), "Sparsification curves, pooled over frames")
    html = head + "\n" + H.img(png, "sparsification curves",
                        "Per method with a confidence map: remove the least confident pixels first and plot the MAE "
                        "of the rest (solid), against the oracle that removes the largest errors first (dashed). "
                        "Curves: per-frame sparsification_curves (20 steps), pixel-weighted mean over frames; "
                        "AUSE = area between them (metres), the leaderboard's AUSE. Lower is better.")
    return Part(html=html, files={"sparsification.png": png})


# ------------------------------------------------------------------------------------------------ per frame


def _cloud_groups(rows: Mapping[str, Mapping], labels: Sequence[str]) -> list[tuple[str, str, bool, dict]]:
    """``(file key, title, paper set-up?, {name: method label})`` per cloud figure: one per flow configuration
    (its variants, in :func:`reports.tables.variant_order`), then one for every other method."""
    groups = []
    flow_rows = [rows[m] for m in labels if rows[m]["flow"]]
    for flow, rect in config_order((r["flow"], r["rectify"]) for r in flow_rows):
        members = {r["variant"]: r["method"] for r in flow_rows if r["flow"] == flow and r["rectify"] == rect}
        members = {v: members[v] for v in variant_order(members)}
        groups.append((config_label(flow, rect), config_title(flow, rect), (flow, bool(rect)) == PAPER_CONFIG,
                       members))
    others = {m: m for m in labels if not rows[m]["flow"]}
    if others:
        groups.append((OTHER_KEY, "other methods", False, others))
    return groups


def _cloud_blocks(out: FramePart, rows: Mapping[str, Mapping], preds: Mapping[str, np.ndarray], cam,
                  colors: np.ndarray, idx: np.ndarray, view_masks, ply: str, title: str, fig_dir: str,
                  cloud_dir: str, reference: tuple[str, np.ndarray] | None, limits: str) -> list[str]:
    """The point-cloud views of a frame, one group per flow configuration and one for every other method
    (:func:`_cloud_groups`), and each method's PLY as ``ply`` asks; files go into ``out.files``.

    Args:
        colors: (H*W, 3) uint8 colours of C's pixels; idx: the sampled pixel indices; view_masks: their sections.
        reference: ``(name, (len(idx), 3) points)`` drawn first in every view and setting its axis limits (the
            ground truth), or None (the first method sets them).
        limits: the caption's sentence on the axis limits.
    Returns:
        One HTML ``<details>`` block per group.
    """
    blocks = []
    groups = _cloud_groups(rows, list(preds))
    any_paper = any(g[2] for g in groups)
    for i, (key, label, paper, members) in enumerate(groups):
        clouds = {reference[0]: (reference[1], colors[idx])} if reference is not None else {}
        group_links = []
        for name, method in members.items():
            pts = point_grid(preds[method], cam.position, cam.rotation).reshape(-1, 3)
            clouds[name] = (pts[idx], colors[idx])
            if ply == "all" or (ply == "paper" and paper):
                rel = f"{cloud_dir}/{key}/{name}.ply" if key != OTHER_KEY else f"{cloud_dir}/{name}.ply"
                out.files[rel], n = ply_bytes(pts, colors, comment=f"tri360 {title} {method}")
                group_links.append(H.link(rel, f"{name} ({n} points)"))
        cloud_png = plots.cloud_views(clouds, cam.position, f"{title} / {label}", view_masks,
                                      reference=reference[0] if reference is not None else None,
                                      subtitle=SECTION_NOTE)
        out.files[f"{fig_dir}/{key}.clouds.png"] = cloud_png
        block = H.img(cloud_png, f"point clouds {title} {label}",
                      f"Fig. 3 style sections, {idx.size} sampled pixels (the same in every column): {SECTION_NOTE}. "
                      + limits)
        if group_links:
            block += '<p class="note">PLY point clouds: ' + ", ".join(group_links) + "</p>"
        blocks.append(H.details(f"point clouds: {label}", block, open_=paper or (i == 0 and not any_paper)))
    return blocks


def frame_part(frame, rows: Mapping[str, Mapping], preds: Mapping[str, np.ndarray],
               confidences: Mapping[str, np.ndarray] | None = None, *, ply: str = "all",
               cloud_points: int = DEFAULT_CLOUD_POINTS, first: bool = False) -> FramePart:
    """One frame's HTML (error maps of every method, region masks, cloud views), its figures and PLY files, and
    its sparsification curves.

    Args:
        frame: the frame (``scene``, ``viewpoint``, ``width``, ``height``, ``cameras``, ``images``, ``distance``
            with ground truth for C (and U, R for the region masks), ``path``); the scene and viewpoint names
            become parts of the file paths, so the caller checks them.
        rows: method label -> its results row (``method``, ``flow``, ``rectify``, ``variant``) for this frame.
        preds: method label -> (H, W) predicted distance, metres, in display order: the methods whose maps
            could be read (a label must be in ``rows``; other methods' labels become file names).
        confidences: method label -> (H, W) confidence (higher = more trustworthy), for methods that gave one.
        ply: one of :data:`PLY_CHOICES`.
        cloud_points: points drawn per cloud view (:func:`section_sample`).
        first: the first frame of the report (its region masks are shown unfolded).
    Returns:
        The frame's :class:`FramePart`; empty ``html`` (and a problem) when the frame has no ground truth.
    """
    if ply not in PLY_CHOICES:
        raise ValueError(f"ply must be one of {', '.join(PLY_CHOICES)}, got {ply!r}")
    scene, viewpoint = frame.scene, frame.viewpoint
    out = FramePart()
    if "C" not in frame.distance:
        out.problems.append(f"frame {scene}/{viewpoint} ({frame.path}) has no ground truth; no maps shown")
        return out
    gt = frame.distance["C"]
    n_scored = int(np.count_nonzero(scored_pixels(gt)))
    if n_scored:
        for label, conf in (confidences or {}).items():
            out.curves[label] = (*sparsification_curves(preds[label], gt, conf), n_scored)
    title = f"{scene} / {viewpoint}"
    fig_dir = f"figures/{scene}/{viewpoint}"
    cloud_dir = f"clouds/{scene}/{viewpoint}"
    blocks = []
    if preds:
        err_png = plots.error_maps(gt, dict(preds), f"{title}: every method")
        out.files[f"{fig_dir}/errors.png"] = err_png
        blocks.append(H.details("error maps: every method", H.img(
            err_png, f"error maps {title}",
            "Ground truth distance, then |pred - gt| of every method, each on its own colour scale (metres, 0 to "
            "the 99th percentile of that method's errors: read the colour bar beside each panel; the panel title "
            "gives its MAE)."), open_=True))
    try:
        masks = frame_regions(frame)
    except ValueError as exc:
        out.problems.append(f"frame {scene}/{viewpoint}: no region masks ({exc})")
    else:
        reg_png = plots.region_masks(frame.images["C"], masks, f"{title}: evaluation regions")
        out.files[f"{fig_dir}/regions.png"] = reg_png
        blocks.append(H.details("region masks", H.img(
            reg_png, f"region masks {title}",
            "The regions of regions.csv and the leaderboard (definitions: docs/metrics.md); percentages are shares "
            "of the scored pixels."), open_=first))
    # point clouds: one group per flow configuration (its variants), one for every other method
    cam = frame.cameras["C"]
    colors = frame.images["C"].reshape(-1, 3)
    gt_pts = point_grid(gt, cam.position, cam.rotation).reshape(-1, 3)
    idx, view_masks = section_sample(frame, cloud_points)
    links = []
    if ply != "none":
        rel = f"{cloud_dir}/ground_truth.ply"
        out.files[rel], n = ply_bytes(gt_pts, colors, comment=f"tri360 ground truth {scene}/{viewpoint} camera C")
        links.append(H.link(rel, f"ground truth ({n} points)"))
    blocks += _cloud_blocks(out, rows, preds, cam, colors, idx, view_masks, ply, title, fig_dir, cloud_dir,
                            reference=("ground truth", gt_pts[idx]),
                            limits="Axis limits from the ground truth's 1-99 % range.")
    ply_note = ('<p class="note">PLY point clouds of this frame: ' + ", ".join(links) + "</p>") if links else ""
    out.html = (f'<h3 id="{H.esc(frame_anchor(scene, viewpoint))}">{H.esc(scene)} / {H.esc(viewpoint)}</h3>'
                f'<p class="note">frame: {H.esc(frame.path)}</p>{ply_note}' + "".join(blocks))
    return out


def frame_anchor(scene: str, viewpoint: str) -> str:
    """The id of a frame's heading in the report (``report.html#frame-<scene>-<viewpoint>`` links to its maps)."""
    return f"frame-{scene}-{viewpoint}"


def quality_part(results: pd.DataFrame) -> Part:
    """The ground-truth-free quality figures of the frames without ground truth (:func:`reports.tables.quality_table`)
    instead of a leaderboard: ``quality.csv``, ``quality.md`` (also the printed markdown) and their HTML, clearly
    labelled as not scored; an empty part when every row was scored."""
    table = quality_table(results)
    if not len(table):
        return Part()
    view = table.copy()
    for c in QUALITY_COLUMNS:
        view[c] = view[c].map(lambda v: f"{v:.4g}" if np.isfinite(v) else "")
    view["calibration_flagged"] = view["calibration_flagged"].map(lambda v: "yes" if v else "no")
    view["seconds"] = view["seconds"].map(lambda v: f"{v:.2f}" if np.isfinite(v) else "")
    view = view.rename(columns={**QUALITY_HEADERS, "calibration_flagged": "calibration flagged"})
    md = quality_markdown(table)
    html = (f"<h2>Quality without ground truth ({H.esc(NOTHING_SCORED)})</h2>"
            f'<p class="note"><strong>{H.esc(NOTHING_SCORED)}</strong>: these frames have no ground-truth distance '
            "(real captures), so no error, MAE or leaderboard can be computed. Per frame and method: the medians "
            "over the validly predicted pixels of the quality maps that need no ground truth (reconstruction.quality: "
            "photometric residual of C's distance reprojected into U and R, the distance change that would explain "
            "it, C-U / C-R pair disagreement, and 'uncertainty', higher = less trustworthy: the product of the "
            "triangulation's sensitivity to angle, the method's ambiguity, its disagreement with the independent "
            "distance it computed on the way where it has one, and the residual) and the "
            "calibration check's score (a rig whose told poses are off scores high; flagged above the threshold). "
            "Definitions and how they were validated against true error: docs/real-captures.md. Also as "
            + H.link("quality.csv", "quality.csv") + " and " + H.link("quality.md", "quality.md") + ".</p>"
            + '<div class="scroll">' + H.table(view.astype(str), text_columns=3) + "</div>")
    return Part(html=html, files={"quality.csv": table.to_csv(index=False), "quality.md": md}, markdown=md,
                table=table)


def capture_part(frame, rows: Mapping[str, Mapping], preds: Mapping[str, np.ndarray],
                 confidences: Mapping[str, np.ndarray] | None = None,
                 quality: Mapping[str, Mapping[str, np.ndarray]] | None = None, *, ply: str = "all",
                 cloud_points: int = DEFAULT_CLOUD_POINTS) -> FramePart:
    """One frame without ground truth (a real capture; nothing scored): its maps, cloud views and PLY files.

    Args:
        frame: the frame (``scene``, ``viewpoint``, ``cameras``, ``images``, ``path``; no ``distance`` needed).
        rows, preds, confidences, ply, cloud_points: as :func:`frame_part`.
        quality: method label -> its ground-truth-free quality maps (``reconstruction.quality.assess``: name ->
            (H, W)), for the methods whose maps could be read.
    Returns:
        The frame's :class:`FramePart` (no ``curves``: nothing is scored): ``figures/<scene>/<viewpoint>/maps.png``
        (:func:`reports.plots.capture_maps`), one cloud figure per group (no ground-truth column; axis limits from
        the group's first method) and, per ``ply``, one PLY per method; empty ``html`` (and a problem) when no map
        could be read.
    """
    if ply not in PLY_CHOICES:
        raise ValueError(f"ply must be one of {', '.join(PLY_CHOICES)}, got {ply!r}")
    scene, viewpoint = frame.scene, frame.viewpoint
    out = FramePart()
    if not preds:
        out.problems.append(f"frame {scene}/{viewpoint} ({frame.path}): no distance map could be read; not shown")
        return out
    title = f"{scene} / {viewpoint}"
    fig_dir = f"figures/{scene}/{viewpoint}"
    cloud_dir = f"clouds/{scene}/{viewpoint}"
    maps = {label: {"distance": preds[label],
                    **({"confidence": confidences[label]} if label in (confidences or {}) else {}),
                    **{k: v for k, v in (quality or {}).get(label, {}).items()
                       if k in ("uncertainty", "photometric_residual")}}
            for label in preds}
    maps_png = plots.capture_maps(frame.images["C"], maps, f"{title}: every method")
    out.files[f"{fig_dir}/maps.png"] = maps_png
    blocks = [H.details("distance, confidence and quality maps: every method", H.img(
        maps_png, f"distance and quality maps {title}",
        "Camera C's image, then per method its distance, its confidence (if it gives one) and the ground-truth-free "
        "quality maps 'uncertainty' and 'photometric residual' (reconstruction.quality); each column on one shared "
        f"colour scale. {NOTHING_SCORED}."), open_=True)]
    cam = frame.cameras["C"]
    colors = frame.images["C"].reshape(-1, 3)
    predicted = np.zeros((frame.height, frame.width), dtype=bool)
    for p in preds.values():
        a = np.asarray(p, dtype=np.float64)
        predicted |= np.isfinite(a) & (a > 0)
    idx, view_masks = section_sample(frame, cloud_points, pixels=predicted)
    blocks += _cloud_blocks(out, rows, preds, cam, colors, idx, view_masks, ply, title, fig_dir, cloud_dir,
                            reference=None,
                            limits="No ground truth: axis limits from the first method's 1-99 % range.")
    out.html = (f'<h3 id="{H.esc(frame_anchor(scene, viewpoint))}">{H.esc(scene)} / {H.esc(viewpoint)}</h3>'
                f'<p class="note">frame: {H.esc(frame.path)} &middot; <strong>{H.esc(NOTHING_SCORED)}</strong> '
                "(no ground-truth distance)</p>" + "".join(blocks))
    return out


# ----------------------------------------------------------------------------------------------- the page


def report_html(results: pd.DataFrame, problems: Sequence[str], *, leaderboard: Part, sparsification: Part,
                flow: Part, breakdown: Part, frames: Sequence[Part], source: str, generated: str,
                quality: Part | None = None) -> str:
    """The complete ``report.html``.

    Args:
        results: the validated results table (the header's counts, the "All results" table).
        problems: one line per thing that could not be shown (listed at the top).
        leaderboard, sparsification, flow, breakdown: the parts of those names (:func:`leaderboard_part`, ...);
            empty parts for results that scored nothing.
        frames: the :func:`frame_part` (or :func:`capture_part`) of every frame shown, in order.
        source: what the header names as the results (e.g. the results directory).
        generated: when the report was made (shown as given).
        quality: :func:`quality_part`, for results with frames without ground truth (shown first).
    """
    order = method_order(results)
    shown = [f.html for f in frames if f.html]
    nothing_scored = bool(len(results)) and bool(unscored_rows(results).all())
    heading = ("<h2>Per frame: distance, confidence and quality maps, point clouds</h2>" if nothing_scored
               else "<h2>Per frame: error maps, regions and point clouds</h2>")
    body = [_header_html(source, generated, results, order, problems), quality.html if quality else "",
            leaderboard.html, sparsification.html, flow.html, breakdown.html, heading,
            "".join(shown) or '<p class="note">No frames could be shown (see problems).</p>',
            "<h2>All results</h2>", _all_results_html(results, nothing_scored)]
    return H.page("tri360 report", "\n".join(body))


def _header_html(source: str, generated: str, results: pd.DataFrame, order: list[str], problems: Sequence[str]) -> str:
    n_frames = len(set(zip(results["scene"], results["viewpoint"], strict=True)))
    parts = ["<h1>tri360 report</h1>",
             f'<p class="note">results: {H.esc(source)} &middot; {n_frames} frame(s), {len(order)} method(s): '
             f"{H.esc(', '.join(order))} &middot; generated {H.esc(generated)}</p>"]
    if problems:
        parts.append('<div class="problems"><strong>Problems (parts of the report are missing):</strong><ul>'
                     + "".join(f"<li>{H.esc(p)}</li>" for p in problems) + "</ul></div>")
    return "\n".join(parts)


def _leaderboard_html(board: pd.DataFrame, have_regions: bool) -> str:
    view = leaderboard_display(board)
    n_overall = len(LEADERBOARD_OVERALL)
    n_groups = len(group_columns(board))
    n_regions = len(view["columns"]) - 3 - n_overall - n_groups
    groups = [("", 3), ("overall (shares in %)", n_overall),
              *([("MAE per family and difficulty tag (m; sw = solid-angle weighted)", n_groups)] if n_groups else []),
              ("MAE per region (m)", n_regions)]
    suite = suite_text(board)
    note = ('<p class="note">Every method of these results on camera C\'s distance. Each number is pooled over the '
            "method's frames, each frame weighted by its scored pixels (per region: the region's pixels): exact over "
            "all pixels for the MAEs and shares, the pixel-weighted mean of the per-frame values for median, p90 "
            "and AUSE. Lower is better except for &delta; &lt; 1.10 and coverage; a missing or invalid prediction "
            "counts with error = true distance. Click a column header to sort (best first, click again to "
            "reverse); highlighted: the best value of the column. " + H.esc(FLOOR_TEXT) + " MAE (&times; floor) "
            "is the pooled MAE divided by the pooled floor of the same frames; floor (m) is a reference, not a "
            "merit. Shaded rows: the paper's own Fig. 4 MAEs (one "
            "1000x500 classroom frame of theirs, DeepFlow), quoted, <strong>not computed by "
            "tri360</strong>. Regions: docs/metrics.md" + ("" if have_regions else " (no regions.csv: empty)")
            + ". Also as " + H.link("leaderboard.csv", "leaderboard.csv") + " and "
            + H.link("leaderboard.md", "leaderboard.md") + ".</p>")
    return ("<h2>Leaderboard</h2>" + (f'<p class="suite">{H.esc(suite)}</p>' if suite else "") + note
            + H.sortable_table(view["display"], view["keys"], view["better"], table_id="leaderboard",
                               text_columns=2, best=view["best"], row_classes=view["row_classes"], groups=groups,
                               data_keys=view["columns"]))


def _floor_html(floors: pd.DataFrame, have_regions: bool) -> str:
    """The floor and the MAE as a multiple of it per region (:func:`reports.tables.floor_region_table`), as HTML."""
    note = ('<p class="note">First row (shaded): the floor in metres over all scored pixels and in each region. '
            + H.esc(FLOOR_TEXT) + " Then each method's MAE divided by the floor of the same pixels (1 = the ideal "
            "matcher; pooled over the method's frames as the leaderboard pools). Regions: docs/metrics.md"
            + ("" if have_regions else " (no regions.csv: empty)") + ".</p>")
    if not np.isfinite(floors.iloc[0, 1:].to_numpy(dtype=np.float64)).any():
        note = '<p class="note">These results carry no floor (their floor_m column is empty).</p>'
    view = floor_region_display(floors)
    return ("<h3>The floor and the MAE as a multiple of it, per region</h3>" + note + '<div class="scroll">'
            + H.table(view, text_columns=1,
                      row_classes=["reference" if m == FLOOR_ROW else "" for m in floors["method"]])
            + "</div>")


def _all_results_html(results: pd.DataFrame, nothing_scored: bool = False) -> str:
    if nothing_scored:  # every metric is empty: show what there is
        full = results.drop(columns=[c for c in METRIC_COLUMNS if c not in ("seconds", "valid_px")]).copy()
        for c in QUALITY_COLUMNS:
            full[c] = full[c].map(lambda v: f"{v:.4g}")
        full["seconds"] = full["seconds"].map(lambda v: f"{v:.2f}")
        return (f'<p class="note">{H.esc(NOTHING_SCORED)}: metric columns left out (all empty).</p>'
                '<div class="scroll">' + H.table(full.astype(str), text_columns=8) + "</div>")
    full = results.copy()
    for c in ("mae_m", "rmse_m", "median_m"):
        full[c] = full[c].map(lambda v: f"{v:.5f}")
    for c in ("absrel", "delta1", "outlier_rate"):
        full[c] = full[c].map(lambda v: f"{v:.4f}")
    full["floor_m"] = full["floor_m"].map(lambda v: f"{v:.5f}")
    full["mae_x_floor"] = full["mae_x_floor"].map(lambda v: f"{v:.2f}")
    full["seconds"] = full["seconds"].map(lambda v: f"{v:.2f}")
    return '<div class="scroll">' + H.table(full.astype(str), text_columns=8) + "</div>"
