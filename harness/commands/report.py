"""The report command (``tri360 report RESULTS``): read a results set, draw the report, write it beside the results.

Reads the results directory written by ``tri360 evaluate`` / ``tri360 score`` (``harness.data.results``: the
CSVs, ``frames.json``, ``config.json``, the maps) and the frames it names; the figures, tables, point clouds
and ``report.html`` are computed in memory by ``reports.sections`` (pure) and written here, each file
atomically, into the same directory (the file tree: ``reports.sections``).  Frames without ground truth (real
captures, nothing scored: ``reports.schema.unscored_rows``) get the table of their quality figures instead of the
leaderboard, and their distance, confidence and quality maps and point clouds instead of error maps.

Problems that do not prevent a report (a missing map, a frame that moved, a missing ``regions.csv``) are listed
at the top of ``report.html`` and in :attr:`ReportOutcome.problems`; a missing/empty results directory or a
malformed ``results.csv`` / ``regions.csv`` / ``breakdown.csv`` / ``frames.json`` / ``config.json`` is a
:class:`harness.data.errors.UserError`.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from harness.data.atomic import atomic_write_bytes, atomic_write_text, clean_stale_partials
from harness.data.errors import FrameError, UserError
from harness.data.exr import CONFIDENCE_CHANNEL, DISTANCE_CHANNEL, read_exr_channels, read_float_map
from harness.data.frame import read_frame
from harness.data.names import is_safe_name
from harness.data.outputs import ensure_output_dir
from harness.data.results import ResultsSet, map_paths, quality_map_path, read_results_set
from reports.metrics import pooled_sparsification_curves
from reports.schema import unscored_rows
from reports.sections import (
    DEFAULT_CLOUD_POINTS,
    PLY_CHOICES,
    FramePart,
    Part,
    breakdown_part,
    capture_part,
    flow_mae_part,
    frame_part,
    leaderboard_part,
    quality_part,
    report_html,
    sparsification_part,
)
from reports.tables import method_order

__all__ = ["ReportOutcome", "build_report", "PLY_CHOICES", "DEFAULT_CLOUD_POINTS"]


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
        sparsification: method label -> pooled curves (:func:`reports.metrics.pooled_sparsification_curves`).
    """

    html_path: Path
    markdown: str
    problems: list[str] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)
    leaderboard: pd.DataFrame | None = None
    sparsification: dict[str, dict] = field(default_factory=dict)


def _read_map(path: Path, channel: str, shape: tuple[int, int]) -> np.ndarray:
    """One float32 map (NaN / inf / <= 0 kept: they mean "no prediction"); FrameError naming the file."""
    values = read_float_map(path, channel)
    if values.shape != shape:
        raise FrameError(f"{path}: shape {values.shape} differs from the frame's {shape}")
    return values


def read_frame_maps(rs: ResultsSet, scene: str, viewpoint: str, order: list[str], frame_paths: dict):
    """Everything the report shows of one frame, read from disk.

    Returns:
        ``(frame, rows, preds, confidences, problems)``: the frame (None when it cannot be shown), method label ->
        results row, and the distance / confidence maps that could be read (label -> (H, W) float32, in
        ``order``); ``problems`` names every map or frame that could not be read.
    """
    d = rs.directory
    problems: list[str] = []
    if not (is_safe_name(scene) and is_safe_name(viewpoint)):
        return None, {}, {}, {}, [f"scene/viewpoint name {scene!r}/{viewpoint!r} cannot be used as a path; skipped"]
    if (scene, viewpoint) not in frame_paths:
        return None, {}, {}, {}, [f"{d / 'frames.json'}: no entry for {scene}/{viewpoint}; its maps are not shown"]
    try:
        frame = read_frame(frame_paths[(scene, viewpoint)])
    except FrameError as exc:
        return None, {}, {}, {}, [f"frame {scene}/{viewpoint} could not be read: {exc}"]
    results = rs.results
    sel = results[(results["scene"] == scene) & (results["viewpoint"] == viewpoint)]
    rows = {r["method"]: r for _, r in sel.iterrows()}
    preds: dict[str, np.ndarray] = {}
    confs: dict[str, np.ndarray] = {}
    shape = (frame.height, frame.width)
    for label in (m for m in order if m in rows):
        row = rows[label]
        try:
            dist_rel, conf_rel = map_paths(scene, viewpoint, label, row["flow"], row["rectify"], row["variant"])
        except UserError:
            problems.append(f"method name {label!r} cannot be used as a path; its maps are not shown")
            continue
        try:
            preds[label] = _read_map(d / dist_rel, DISTANCE_CHANNEL, shape)
            if (d / conf_rel).exists():
                confs[label] = _read_map(d / conf_rel, CONFIDENCE_CHANNEL, shape)
        except FrameError as exc:
            problems.append(str(exc))
    return frame, rows, preds, confs, problems


def read_quality_maps(rs: ResultsSet, scene: str, viewpoint: str, rows: dict, labels,
                      shape: tuple[int, int]) -> tuple[dict, list[str]]:
    """The quality maps (``harness.data.results.quality_map_path``) of the methods ``labels`` of a frame without
    ground truth -> ``({label: {map name: (H, W) float32}}, problems)``; a missing, unreadable or wrongly sized
    file is a problem, its method is shown without quality maps."""
    maps, problems = {}, []
    for label in labels:
        row = rows[label]
        path = rs.directory / quality_map_path(scene, viewpoint, label, row["flow"], row["rectify"], row["variant"])
        try:
            channels = read_exr_channels(path)
            bad = sorted(k for k, v in channels.items() if v.shape != shape)
            if bad:
                raise FrameError(f"{path}: channel {bad[0]} has shape {channels[bad[0]].shape}, not the frame's "
                                 f"{shape}")
            maps[label] = {k: np.asarray(v, dtype=np.float32) for k, v in channels.items()}
        except FrameError as exc:
            problems.append(f"{exc}; the quality maps of {label} on {scene}/{viewpoint} are not shown")
    return maps, problems


def _frame_parts(rs: ResultsSet, order: list[str], ply: str, cloud_points: int,
                 problems: list[str]) -> Iterator[FramePart]:
    """The :class:`reports.sections.FramePart` of every frame of the results, in (scene, viewpoint) order; the
    problems of reading them go to ``problems``."""
    if rs.frames is None:
        return
    frame_paths = {(f["scene"], f["viewpoint"]): Path(f["path"]) for f in rs.frames}
    keys = sorted(set(zip(rs.results["scene"], rs.results["viewpoint"], strict=True)))
    first = True
    for scene, viewpoint in keys:
        frame, rows, preds, confs, read_problems = read_frame_maps(rs, scene, viewpoint, order, frame_paths)
        problems.extend(read_problems)
        if frame is None:
            continue
        if frame.has_ground_truth:
            part = frame_part(frame, rows, preds, confs, ply=ply, cloud_points=cloud_points, first=first)
        else:
            quality, quality_problems = read_quality_maps(rs, scene, viewpoint, rows, list(preds),
                                                         (frame.height, frame.width))
            problems.extend(quality_problems)
            part = capture_part(frame, rows, preds, confs, quality, ply=ply, cloud_points=cloud_points)
        problems.extend(part.problems)
        first = first and not part.html
        yield part


def build_report(results_dir, *, ply: str = "all", cloud_points: int = DEFAULT_CLOUD_POINTS,
                 location=None) -> ReportOutcome:
    """Write every report output into ``results_dir`` (the file tree: ``reports.sections``).

    Args:
        results_dir: directory written by ``tri360 evaluate`` / ``tri360 score``.
        location: where the results set will be read from, named at the top of ``report.html`` (default:
            ``results_dir``; ``evaluate`` builds the set in a staging directory and passes the ``--out`` it is
            swapped into).
        ply: "all" (a PLY per frame and method, plus ground truth), "paper" (only the deepflow-rect
            configuration, plus ground truth) or "none".
        cloud_points: points per cloud drawn in the scatter views (same seeded pixel subsample for all).
    Returns:
        The :class:`ReportOutcome` (html path, markdown, problems, files, leaderboard, sparsification curves).
    Raises:
        UserError: a bad ``ply``, a missing/empty directory, malformed results / regions /
            breakdown CSV, frames.json or config.json, or a directory the report cannot be written into.
    """
    if ply not in PLY_CHOICES:
        raise UserError(f"ply must be one of {', '.join(PLY_CHOICES)}, got {ply!r}")
    rs = read_results_set(results_dir)
    d = rs.directory
    ensure_output_dir(d)  # inputs are valid: now check that the report can be written, before drawing
    clean_stale_partials(d)  # hidden temporaries of killed report runs
    out = ReportOutcome(html_path=d / "report.html", markdown="", problems=list(rs.missing))

    def put(part: Part) -> Part:
        for rel, data in part.files.items():
            path = d / rel
            if isinstance(data, str):
                atomic_write_text(path, data)
            else:
                atomic_write_bytes(path, data)
            out.files.append(path)
        return part

    results = rs.results
    unscored = unscored_rows(results)  # frames without ground truth: nothing scored
    scored = results if not unscored.any() else results[~unscored].reset_index(drop=True)
    quality = put(quality_part(results)) if unscored.any() else None
    if len(scored):
        board = put(leaderboard_part(scored, rs.regions, rs.kinds))
        flow = put(flow_mae_part(scored))
        breakdown = put(breakdown_part(rs.breakdown))
    else:
        board, flow, breakdown = Part(), Part(), Part()
    out.leaderboard = board.table
    out.markdown = "\n".join(p.markdown for p in (quality, board, flow) if p is not None and p.markdown)

    order = method_order(results)
    n_frames = len(set(zip(scored["scene"], scored["viewpoint"], strict=True)))
    curves: dict[str, list[tuple]] = {}
    frames = []
    for part in _frame_parts(rs, order, ply, cloud_points, out.problems):
        frames.append(put(part))
        for label, curve in part.curves.items():
            curves.setdefault(label, []).append(curve)
        part.files.clear()  # written: keep only the HTML
    for label in order:
        if label in curves:
            out.sparsification[label] = pooled_sparsification_curves(curves[label])
            missing = n_frames - len(curves[label])
            if missing:
                out.problems.append(f"method {label}: a confidence map for {len(curves[label])} frame(s) but "
                                    f"not for {missing}; its sparsification curve pools only the former")
    spars = put(sparsification_part(out.sparsification)) if len(scored) else Part()
    page = report_html(results, out.problems, leaderboard=board, sparsification=spars, flow=flow,
                       breakdown=breakdown, frames=frames,
                       source=str(Path(location if location is not None else d).resolve()),
                       generated=time.strftime("%Y-%m-%d %H:%M:%S"), quality=quality)
    atomic_write_text(out.html_path, page)
    out.files.append(out.html_path)
    return out
