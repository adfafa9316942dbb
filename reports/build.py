"""``tri360 report RESULTS``: tables, figures, point clouds and one self-contained ``report.html``.

Reads only the results directory written by ``tri360 evaluate`` (``results.csv``, ``breakdown.csv``,
``frames.json``, ``maps/``) plus the frames it names, and writes into the same directory::

    RESULTS/
      mae.md  mae.csv                 # variant x scene mean MAE, % reduction vs `average`, paper reference rows
      fig4_mae.png                    # paper Fig. 4 style bars (error bars: min-max over frames)
      error_vs_angle.png              # MAE against the angle between bearing and each baseline (breakdown.csv)
      error_by_distance_texture.png   # MAE against true distance and image texture (breakdown.csv)
      figures/<scene>/<viewpoint>/<flow>-<rect|plain>.errors.png   # GT + |pred - gt| per variant
      figures/<scene>/<viewpoint>/<flow>-<rect|plain>.clouds.png   # Fig. 3 style top-down / side views
      clouds/<scene>/<viewpoint>/ground_truth.ply
      clouds/<scene>/<viewpoint>/<flow>-<rect|plain>/<variant>.ply  # binary little-endian, coloured
      report.html                     # everything above inline (images as data URIs), links to the PLYs

Every file is written atomically.  Problems that do not prevent a report (a missing map, a frame that moved)
are listed at the top of ``report.html`` and printed to stderr; a missing/empty results directory or a
malformed ``results.csv`` / ``breakdown.csv`` / ``frames.json`` is a :class:`harness.data.errors.UserError`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from harness.data.errors import UserError
from harness.data.frame import FrameError, atomic_write_bytes, atomic_write_text, read_distance_exr, read_frame
from reconstruction.camera.equirect import bearing_grid
from reports import html as H
from reports import plots
from reports.pointcloud import point_grid, write_ply
from reports.tables import (
    config_key,
    config_label,
    config_order,
    load_breakdown,
    load_frames,
    load_results,
    mae_display,
    mae_markdown,
    mae_table,
    variant_order,
)

__all__ = ["write_report", "build_report", "ReportOutcome", "PLY_CHOICES"]

PLY_CHOICES = ("all", "paper", "none")
DEFAULT_CLOUD_POINTS = 20000


@dataclass
class ReportOutcome:
    """What :func:`build_report` wrote.

    Attributes:
        html_path: ``RESULTS/report.html``.
        markdown: contents of ``mae.md``.
        problems: one line per thing that could not be shown (missing maps, unreadable frames, ...).
        files: every file written, in order.
    """

    html_path: Path
    markdown: str
    problems: list[str] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)


def write_report(results_dir, *, ply: str = "all", cloud_points: int = DEFAULT_CLOUD_POINTS) -> Path:
    """Write every report output into ``results_dir`` (see the module doc) and return ``report.html``'s path.

    Args:
        results_dir: directory written by ``tri360 evaluate``.
        ply: "all" (a PLY per frame, configuration and variant, plus ground truth), "paper" (only the
            deepflow-plain configuration, plus ground truth) or "none".
        cloud_points: points per cloud drawn in the scatter views (same seeded pixel subsample for all).
    Raises:
        harness.data.errors.UserError: missing/empty directory, malformed results.csv/breakdown.csv/frames.json.
    """
    return build_report(results_dir, ply=ply, cloud_points=cloud_points).html_path


# ------------------------------------------------------------------------------------------------ builder


def _safe_part(name: str) -> bool:
    return bool(name) and "/" not in name and "\\" not in name and name not in (".", "..")


SECTION_HALF_ANGLE_DEG = 15.0
SECTION_NOTE = (f"top-down: pixels whose bearing is within {SECTION_HALF_ANGLE_DEG:g} deg of horizontal; "
                f"side: within {SECTION_HALF_ANGLE_DEG:g} deg of the world x-z plane")


def _section_sample(frame, n_points: int):
    """Seeded pixel subsample for the cloud views: half near the horizon, half near the x-z plane.

    Returns:
        ``(idx, masks)``: (N,) flat pixel indices of camera C (scored pixels only, sorted) and one (N,) bool
        mask per view of :data:`reports.plots.CLOUD_VIEWS` (top-down, side).
    """
    import numpy as np


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


def build_report(results_dir, *, ply: str = "all", cloud_points: int = DEFAULT_CLOUD_POINTS) -> ReportOutcome:
    """Like :func:`write_report` but returns the :class:`ReportOutcome` (markdown, problems, files)."""


    if ply not in PLY_CHOICES:
        raise UserError(f"ply must be one of {', '.join(PLY_CHOICES)}, got {ply!r}")
    d = Path(results_dir)
    results = load_results(d)
    breakdown = load_breakdown(d)
    frames = load_frames(d)
    out = ReportOutcome(html_path=d / "report.html", markdown="")

    def put(rel: str, data: bytes | str) -> Path:
        path = d / rel
        if isinstance(data, str):
            atomic_write_text(path, data)
        else:
            atomic_write_bytes(path, data)
        out.files.append(path)
        return path

    # ---- tables
    table = mae_table(results)
    out.markdown = mae_markdown(table)
    put("mae.md", out.markdown)
    put("mae.csv", table.to_csv(index=False))
    body = []
    disp = mae_display(table)
    row_classes = ["paper" if s == "paper" else "" for s in table["source"]]

    # ---- summary figures
    fig4 = plots.fig4_mae(results)
    put("fig4_mae.png", fig4)
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

    # ---- per frame: error maps, cloud views, PLYs
    frame_sections = []
    frame_paths = {}
    if frames is None:
        out.problems.append(f"{d / 'frames.json'}: file is missing, so there are no error maps or point clouds")
    else:
        frame_paths = {(f["scene"], f["viewpoint"]): Path(f["path"]) for f in frames}
    keys = sorted(set(zip(results["scene"], results["viewpoint"], strict=True)))
    for scene, viewpoint in keys if frames is not None else []:
        if not (_safe_part(scene) and _safe_part(viewpoint)):
            out.problems.append(f"scene/viewpoint name {scene!r}/{viewpoint!r} cannot be used as a path; skipped")
            continue
        if (scene, viewpoint) not in frame_paths:
            out.problems.append(f"{d / 'frames.json'}: no entry for {scene}/{viewpoint}; its maps are not shown")
            continue
        try:
            frame = read_frame(frame_paths[(scene, viewpoint)])
        except FrameError as exc:
            out.problems.append(f"frame {scene}/{viewpoint} could not be read: {exc}")
            continue
        if "C" not in frame.distance:
            out.problems.append(f"frame {scene}/{viewpoint} ({frame.path}) has no ground truth; no maps shown")
            continue
        gt = frame.distance["C"]
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
        rows = results[(results["scene"] == scene) & (results["viewpoint"] == viewpoint)]
        conf_blocks = []
        for flow, rect in config_order(zip(rows["flow"], rows["rectify"], strict=True)):
            key = config_key(flow, rect)
            conf_rows = rows[(rows["flow"] == flow) & (rows["rectify"] == rect)]
            preds = {}
            for variant in variant_order(conf_rows["variant"]):
                mp = d / "maps" / scene / viewpoint / key / f"{variant}.distance.exr"
                try:
                    pred = read_distance_exr(mp)
                except FrameError as exc:
                    out.problems.append(str(exc))
                    continue
                if pred.shape != gt.shape:
                    out.problems.append(f"{mp}: shape {pred.shape} differs from the frame's {gt.shape}")
                    continue
                preds[variant] = pred
            if not preds:
                continue
            title = f"{scene} / {viewpoint} / {config_label(flow, rect)}"
            err_png = plots.error_maps(gt, preds, title)
            put(f"figures/{scene}/{viewpoint}/{key}.errors.png", err_png)
            clouds = {"ground truth": (gt_pts[idx], colors[idx])}
            conf_links = []
            write_these = ply == "all" or (ply == "paper" and flow == "deepflow" and not rect)
            for variant, pred in preds.items():
                pts = point_grid(pred, cam.position, cam.rotation).reshape(-1, 3)
                clouds[variant] = (pts[idx], colors[idx])
                if write_these:
                    rel = f"clouds/{scene}/{viewpoint}/{key}/{variant}.ply"
                    n = write_ply(d / rel, pts, colors, comment=f"tri360 {title} {variant}")
                    out.files.append(d / rel)
                    conf_links.append(H.link(rel, f"{variant} ({n} points)"))
            cloud_png = plots.cloud_views(clouds, cam.position, title, view_masks, reference="ground truth",
                                          subtitle=SECTION_NOTE)
            put(f"figures/{scene}/{viewpoint}/{key}.clouds.png", cloud_png)
            block = (H.img(err_png, f"error maps {title}",
                           "Ground truth distance and |pred - gt| per variant (shared colour scale, metres).")
                     + H.img(cloud_png, f"point clouds {title}",
                             f"Fig. 3 style sections, {idx.size} sampled pixels (the same in every column): "
                             f"{SECTION_NOTE}. Axis limits from the ground truth's 1-99 % range."))
            if conf_links:
                block += '<p class="note">PLY point clouds: ' + ", ".join(conf_links) + "</p>"
            conf_blocks.append(H.details(config_label(flow, rect), block,
                                         open_=(flow == "deepflow" and not rect) or len(conf_blocks) == 0))
        ply_note = ('<p class="note">PLY point clouds of this frame: ' + ", ".join(links) + "</p>") if links else ""
        frame_sections.append(f"<h3>{H.esc(scene)} / {H.esc(viewpoint)}</h3>"
                              f'<p class="note">frame: {H.esc(frame.path)}</p>{ply_note}' + "".join(conf_blocks))

    # ---- the HTML page
    n_frames = len(keys)
    configs = config_order(zip(results["flow"], results["rectify"], strict=True))
    body.append("<h1>tri360 report</h1>")
    body.append(f'<p class="note">results: {H.esc(d.resolve())} &middot; {n_frames} frame(s), '
                f"{len(configs)} configuration(s), variants: {H.esc(', '.join(variant_order(results['variant'])))}"
                f" &middot; generated {H.esc(time.strftime('%Y-%m-%d %H:%M:%S'))}</p>")
    if out.problems:
        body.append('<div class="problems"><strong>Problems (parts of the report are missing):</strong><ul>'
                    + "".join(f"<li>{H.esc(p)}</li>" for p in out.problems) + "</ul></div>")
    body.append("<h2>Mean absolute error</h2>")
    body.append('<p class="note">MAE of camera C\'s distance in metres, mean over frames. "vs average" = '
                "100 &times; (MAE<sub>average</sub> &minus; MAE<sub>variant</sub>) / MAE<sub>average</sub> for the "
                "same flow/rectify configuration and frames (positive = better). Pixels with no surface are not "
                "scored; an invalid prediction (NaN, inf, &le; 0) counts with error = true distance. "
                "Shaded rows: the paper's own Fig. 4 numbers, quoted, not computed here.</p>")
    body.append(H.table(disp, text_columns=2, row_classes=row_classes))
    body.append(H.img(fig4, "Fig. 4 style MAE bar chart",
                      "Bars: mean of the per-frame MAE; error bars: min-max over frames; hatched: the paper's "
                      "figures (one 1000x500 classroom frame, DeepFlow on plain equirect pairs)."))
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
    body.append("<h2>Per frame: error maps and point clouds</h2>")
    body.append("".join(frame_sections) or '<p class="note">No frames could be shown (see problems).</p>')
    body.append("<h2>All results</h2>")
    full = results.copy()
    for c in ("mae_m", "rmse_m", "median_m"):
        full[c] = full[c].map(lambda v: f"{v:.5f}")
    for c in ("absrel", "delta1", "outlier_rate"):
        full[c] = full[c].map(lambda v: f"{v:.4f}")
    full["seconds"] = full["seconds"].map(lambda v: f"{v:.2f}")
    body.append(H.table(full.astype(str), text_columns=7))
    out.files.append(out.html_path)
    atomic_write_text(out.html_path, H.page("tri360 report", "\n".join(body)))
    return out
