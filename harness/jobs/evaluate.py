"""The evaluate job: reconstruct and score every frame under a data root.

Writes into RESULTS (each file atomically)::

    results.csv, results.json   one row per (scene, viewpoint, flow, rectify, variant), DESIGN.md's schema
    breakdown.csv               errors by angle to each baseline, true distance and texture
    frames.json                 where each evaluated frame lives
    maps/<scene>/<viewpoint>/<flow>-<rect|plain>/<variant>.distance.exr   the predicted distances of C

then the report (``tri360 report``) unless ``--no-report``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from harness.data.errors import UserError
from harness.data.frame import FrameError, atomic_write_text, find_frames, read_frame, write_distance_exr
from harness.jobs.reconstruct import run_with_progress
from reconstruction.methods.flow_pipeline import DEFAULT_FLOW
from reports.metrics import breakdown, summary

RESULT_COLUMNS = ["scene", "viewpoint", "width", "height", "flow", "rectify", "variant", "mae_m", "rmse_m",
                  "median_m", "absrel", "delta1", "outlier_rate", "valid_px", "seconds"]
BREAKDOWN_COLUMNS = ["scene", "viewpoint", "flow", "rectify", "variant", "kind", "bin_lo", "bin_hi", "mae_m",
                     "median_m", "n_px"]
#: configurations evaluated by default: tri360's (rectified) and the paper's set-up (plain equirect DeepFlow)
DEFAULT_CONFIGS = [(DEFAULT_FLOW, True), ("deepflow", False)]


def config_label(flow: str, rectify: bool) -> str:
    """Directory/label of a configuration, e.g. ``dis-rect`` or ``deepflow-plain``."""
    return f"{flow}-{'rect' if rectify else 'plain'}"


def configurations(flows: list[str] | None, rectify: bool) -> list[tuple[str, bool]]:
    if flows is None:
        return list(DEFAULT_CONFIGS) if rectify else [(DEFAULT_FLOW, False)]
    return [(f, rectify) for f in dict.fromkeys(flows)]


def evaluate(data_root: Path, out: Path, configs: list[tuple[str, bool]], variants: list[str],
             scenes: list[str] | None = None) -> pd.DataFrame:
    """Reconstruct and score every frame with ground truth under ``data_root``.

    Returns:
        The results table (also written to ``out``).
    Raises:
        UserError: missing or empty root, no frame with ground truth, or a malformed frame (named).
    """
    data_root = Path(data_root)
    if not data_root.is_dir():
        raise UserError(f"{data_root}: data root does not exist")
    frame_dirs = find_frames(data_root)
    if scenes:
        frame_dirs = [d for d in frame_dirs if d.relative_to(data_root).parts[0] in scenes]
    if not frame_dirs:
        raise UserError(f"{data_root}: no tri360 frames found (expected <scene>/<viewpoint>/frame.json"
                        + (f" for scenes {', '.join(scenes)}" if scenes else "") + ")")
    rows, brows, frames_index = [], [], []
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(d, c) for d in frame_dirs for c in configs]
    current_dir, frame = None, None
    for frame_path, (flow, rectify) in tqdm(jobs, desc="evaluate", unit="frame-config"):
        if frame_path != current_dir:
            try:
                frame = read_frame(frame_path)
            except FrameError as exc:
                raise UserError(str(exc)) from None
            current_dir = frame_path
            if not frame.has_ground_truth:
                raise UserError(f"{frame_path}: frame has no ground-truth distance, nothing to score "
                                "(use 'tri360 reconstruct' for captures without ground truth)")
            frames_index.append({"scene": frame.scene, "viewpoint": frame.viewpoint,
                                 "path": str(frame_path.resolve())})
        label = config_label(flow, rectify)
        result = run_with_progress(frame, flow, rectify, variants, f"{frame.scene}/{frame.viewpoint} {label}")
        shared = sum(result.seconds[k] for k in ("flow_U", "flow_R", "triangulate", "average"))
        map_dir = out / "maps" / frame.scene / frame.viewpoint / label
        gt = frame.distance["C"]
        for name in variants:
            pred = result.distance[name]
            write_distance_exr(map_dir / f"{name}.distance.exr", pred)
            seconds = shared + (result.seconds[name] if name != "average" else 0.0)
            key = {"scene": frame.scene, "viewpoint": frame.viewpoint, "flow": flow, "rectify": rectify,
                   "variant": name}
            rows.append({**key, "width": frame.width, "height": frame.height, **summary(pred, gt),
                         "seconds": round(seconds, 4)})
            brows.extend({**key, **b} for b in breakdown(frame, pred))
    table = pd.DataFrame(rows)[RESULT_COLUMNS]
    atomic_write_text(out / "results.csv", table.to_csv(index=False))
    atomic_write_text(out / "results.json", json.dumps(table.to_dict(orient="records"), indent=1) + "\n")
    atomic_write_text(out / "breakdown.csv", pd.DataFrame(brows)[BREAKDOWN_COLUMNS].to_csv(index=False))
    atomic_write_text(out / "frames.json", json.dumps(frames_index, indent=1) + "\n")
    return table


def mae_table(table: pd.DataFrame) -> str:
    """Plain-text MAE table (mean over frames): rows configuration, columns variant, metres."""
    t = table.assign(config=[config_label(f, r) for f, r in zip(table.flow, table.rectify, strict=True)])
    pivot = t.pivot_table(index=["scene", "config"], columns="variant", values="mae_m", aggfunc="mean", sort=False)
    return pivot.to_string(float_format=lambda x: f"{x:.4f}")
