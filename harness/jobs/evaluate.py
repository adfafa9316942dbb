"""The evaluate job: run methods on every frame under a data root, score them against ground truth, report.

Writes a results set into ``out``::

    results.csv, results.json   one row per (scene, viewpoint, method): reports.schema.RESULT_COLUMNS
    regions.csv                 the same metrics per region of each frame (reports.regions)
    breakdown.csv               errors by angle to each baseline, true distance and texture
    frames.json                 where each evaluated frame lives
    config.json                 tri360 version and commit, every method's full configuration, the frames'
                                renderer settings: everything needed to reproduce the numbers
    maps/<scene>/<viewpoint>/<flow>-<rect|plain>/<variant>.distance.exr   predicted distance of C
    maps/<scene>/<viewpoint>/<method>/distance.exr                        (methods other than the flow pipeline)
    ... confidence.exr beside each distance map of a method that gives a confidence

and the report (``reports.build``) unless ``report=False``.  With a Dask cluster (``cluster``) each frame x
group of methods is one task whose worker writes the maps into the staging directory (so it must be on a
file system the workers share) and returns the rows; this process writes the rest (``docs/scale-out.md``).

The whole set is built in a hidden staging directory beside ``out`` and swapped in at the end, so an interrupted
run leaves the previous results set (results and report together) untouched and never an old report beside new
results.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from harness.data import jsonio
from harness.data.atomic import atomic_write_text
from harness.data.errors import UserError
from harness.data.exr import CONFIDENCE_CHANNEL, DISTANCE_CHANNEL, write_float_map
from harness.data.frame import find_frames, read_frame
from harness.data.outputs import staged_directory
from harness.data.provenance import software
from harness.jobs.cluster import ClusterOptions, Executor, executor_for, is_distributed
from reconstruction.methods.base import Method, MethodOutput, flow_fields, run_methods
from reconstruction.methods.flow_pipeline import config_label
from reports.build import build_report
from reports.metrics import breakdown
from reports.regions import region_summaries, regions
from reports.schema import breakdown_table, regions_table, results_table, write_results

__all__ = ["FrameRef", "select_frames", "evaluate", "evaluate_task", "method_groups", "map_path", "mae_table",
           "results_config"]


@dataclass(frozen=True)
class FrameRef:
    """A frame found under a data root: its directory and the scene/viewpoint its frame.json names."""

    path: Path
    scene: str
    viewpoint: str


def group_name(group: Sequence[Method]) -> str:
    """A method group's name for progress and errors: its one label, or the first label and how many more."""
    return group[0].label if len(group) == 1 else f"{group[0].label} +{len(group) - 1}"


def select_frames(data_root: Path, scenes: Sequence[str] | None = None) -> list[FrameRef]:
    """Every frame under ``data_root`` (which may itself be a frame directory), optionally only ``scenes``.

    A frame's scene is the one its ``frame.json`` names; a scene also matches by the name of the directory
    level the frame sits in (``<root>/<scene>/<viewpoint>``).

    Raises:
        UserError: missing root, no frames (for the scenes), a malformed frame.json, or two frame
            directories that name the same scene and viewpoint (their outputs would collide).
    """
    data_root = Path(data_root)
    if not data_root.is_dir():
        raise UserError(f"{data_root}: data root does not exist" if not data_root.exists()
                        else f"{data_root}: data root is not a directory")
    refs = []
    for d in find_frames(data_root):
        meta = read_frame(d, load_distance=False)
        refs.append(FrameRef(d, meta.scene, meta.viewpoint))
    if scenes:
        wanted = set(scenes)
        found = sorted({r.scene for r in refs})
        refs = [r for r in refs if r.scene in wanted or r.path.parent.name in wanted]
        if not refs:
            raise UserError(f"{data_root}: no frames of scene(s) {', '.join(scenes)} "
                            f"(scenes found: {', '.join(found) or 'none'})")
    if not refs:
        raise UserError(f"{data_root}: no tri360 frames found (expected <scene>/<viewpoint>/frame.json)")
    seen: dict[tuple[str, str], Path] = {}
    for r in refs:
        key = (r.scene, r.viewpoint)
        if key in seen:
            raise UserError(f"{r.path / 'frame.json'}: names scene {r.scene!r} viewpoint {r.viewpoint!r}, as "
                            f"{seen[key] / 'frame.json'} does; their results would overwrite each other "
                            "(give each frame a unique scene/viewpoint, or evaluate them separately)")
        seen[key] = r.path
    return refs


def confidence_path(distance_path: Path) -> Path:
    """``.../gradient.distance.exr`` -> ``.../gradient.confidence.exr``; ``.../distance.exr`` -> ``confidence.exr``."""
    name = distance_path.name
    return distance_path.with_name(name[: -len("distance.exr")] + "confidence.exr")


def map_path(scene: str, viewpoint: str, method: Method) -> Path:
    """Where a method's predicted distance map goes, relative to the results directory."""
    base = Path("maps") / scene / viewpoint
    fields = flow_fields(method)
    if fields["flow"]:
        return base / config_label(fields["flow"], fields["rectify"]) / f"{fields['variant']}.distance.exr"
    return base / method.label / "distance.exr"


def results_config(methods: Sequence[Method], frames: list, data_root: Path, started: float) -> dict:
    """The contents of ``config.json``."""
    return {
        "format": "tri360-results/1",
        "software": software(),
        "created_unix_s": round(started, 3),
        "data_root": str(Path(data_root).resolve()),
        "methods": {m.label: m.config() for m in methods},
        "frames": frames,
    }


def _score_rows(frame, method: Method, output: MethodOutput, masks: dict) -> tuple[dict, list[dict], list[dict]]:
    """The results row, the breakdown rows and the region rows of one method on one frame."""
    gt = frame.distance["C"]
    pred = np.asarray(output.distance)
    conf = None if output.confidence is None else np.asarray(output.confidence)
    for what, arr in (("distance", pred), ("confidence", conf)):
        if arr is not None and arr.shape != gt.shape:
            raise UserError(f"method {method.label}: returned a {arr.shape} {what} map for the "
                            f"{gt.shape[1]}x{gt.shape[0]} frame {frame.path}")
    key = {"scene": frame.scene, "viewpoint": frame.viewpoint, "method": method.label, **flow_fields(method)}
    region_rows = [{**key, **r} for r in region_summaries(frame, pred, conf, masks=masks)]
    overall = next(r for r in region_rows if r["region"] == "all")
    row = {**key, "width": frame.width, "height": frame.height,
           **{k: v for k, v in overall.items() if k not in key and k != "region"},
           "seconds": round(output.total_seconds, 4)}
    return row, [{**key, **b} for b in breakdown(frame, pred)], region_rows


def method_groups(methods: Sequence[Method]) -> list[list[Method]]:
    """``methods`` split into the groups that share work (same ``group_key``, as ``run_methods`` runs them),
    in order of first appearance; a method without a ``group_key`` is a group of its own."""
    groups: dict = {}
    for i, m in enumerate(methods):
        key = getattr(m, "group_key", None)
        groups.setdefault(("group", key) if key is not None else ("single", i), []).append(m)
    return list(groups.values())


def evaluate_task(frame_path: str, methods: Sequence[Method], stage: str) -> dict:
    """One task of :func:`evaluate`: run ``methods`` on one frame, write their maps under ``stage``, score them.

    Runs in this process or on a Dask worker (then ``frame_path`` and ``stage`` must be on a file system the
    worker sees at the same path).  Writing the maps is atomic and idempotent, so a task re-run after a lost
    worker changes nothing.

    Returns:
        ``{"rows": {label: (row, breakdown rows, region rows)}, "frame": the frame's config.json entry}``.
    Raises:
        UserError: the frame has no usable ground truth, or a method fails on it (named).
    """
    path = Path(frame_path)
    frame = read_frame(path)
    if not frame.has_ground_truth:
        raise UserError(f"{path}: frame has no ground-truth distance, nothing to score "
                        "(use 'tri360 reconstruct' for captures without ground truth)")
    if not np.isfinite(frame.distance["C"]).any():
        raise UserError(f"{path / 'C.distance.exr'}: no pixel has a finite distance, nothing to score")
    try:
        outputs = run_methods(frame, methods)
    except ValueError as exc:
        raise UserError(f"{path}: {exc}") from None
    masks = regions(frame)
    scored = {}
    for method in methods:
        output = outputs[method.label]
        row, brs, rrs = _score_rows(frame, method, output, masks)
        dist_path = Path(stage) / map_path(frame.scene, frame.viewpoint, method)
        # a prediction may hold NaN/inf/<= 0 (= no prediction): written as is, like tri360-pred/1
        write_float_map(dist_path, np.asarray(output.distance, np.float32), DISTANCE_CHANNEL)
        if output.confidence is not None:
            write_float_map(confidence_path(dist_path), np.asarray(output.confidence, np.float32),
                            CONFIDENCE_CHANNEL)
        scored[method.label] = (row, brs, rrs)
    info = {"path": str(path.resolve()), "scene": frame.scene, "viewpoint": frame.viewpoint,
            "width": frame.width, "height": frame.height, "baseline_m": frame.baseline_m,
            "renderer": frame.renderer}
    return {"rows": scored, "frame": info}


def evaluate(data_root: Path, out: Path, methods: Sequence[Method], scenes: Sequence[str] | None = None,
             report: bool = True, progress: bool = True, cluster: ClusterOptions | None = None,
             executor: Executor | None = None) -> pd.DataFrame:
    """Run ``methods`` on every frame with ground truth under ``data_root`` and write a results set to ``out``.

    Args:
        cluster: run on Dask (``--scheduler`` / ``--workers``), one task per frame x group of methods that share
            work (the variants of one flow configuration); workers write the maps into the staged results
            directory, this process gathers the rows and writes the results files.  None = in this process, one
            task per frame.  The rows and maps are the same either way (only ``seconds``, each method's wall
            time, differs from run to run).
        executor: instead of ``cluster``, an executor that is already open (a study's); left open.

    Returns:
        The results table (also written to ``out``).
    Raises:
        UserError: bad data root, a malformed frame or one without ground truth (named), an unusable
            output location (checked before any long work), or a method that fails on a frame.
    """
    started = time.time()
    if cluster is not None:
        cluster.check()
    refs = select_frames(data_root, scenes)
    labels = [m.label for m in methods]
    if not methods:
        raise UserError("no methods to evaluate")
    if len(set(labels)) != len(labels):
        raise UserError(f"duplicate method labels: {', '.join(sorted({x for x in labels if labels.count(x) > 1}))}")
    distributed = is_distributed(cluster, executor)
    groups = method_groups(methods) if distributed else [list(methods)]
    rows, brows, rrows, frames_index, frames_config = [], [], [], [], []
    with staged_directory(out) as stage:
        stage_abs = str(Path(stage).resolve())
        tasks = {(i, g): (str(ref.path.resolve()), group, stage_abs)
                 for i, ref in enumerate(refs) for g, group in enumerate(groups)}
        names = {(i, g): f"{ref.scene}/{ref.viewpoint} {group_name(group)}"
                 for i, ref in enumerate(refs) for g, group in enumerate(groups)}
        done: dict[tuple[int, int], dict] = {}
        with executor_for(cluster, executor) as ex:
            for key, result in ex.run(evaluate_task, tasks, desc="evaluate", names=names,
                                      unit="frame" if len(groups) == 1 else "task", progress=progress):
                done[key] = result
        for i, _ref in enumerate(refs):
            scored = {label: v for g in range(len(groups)) for label, v in done[(i, g)]["rows"].items()}
            info = done[(i, 0)]["frame"]
            for method in methods:
                row, brs, rrs = scored[method.label]
                rows.append(row)
                brows.extend(brs)
                rrows.extend(rrs)
            frames_index.append({"scene": info["scene"], "viewpoint": info["viewpoint"], "path": info["path"]})
            frames_config.append(info)
        table = results_table(rows)
        write_results(stage, table, breakdown_table(brows), regions_table(rrows))
        atomic_write_text(stage / "frames.json", jsonio.dumps(frames_index))
        config = results_config(methods, frames_config, data_root, started)
        atomic_write_text(stage / "config.json", jsonio.dumps(config))
        if report:
            build_report(stage)
    return table


def config_keys(table: pd.DataFrame, other: str = "") -> tuple[list[str], list[str]]:
    """Per results row, its configuration and variant: ``("dis-rect", "gradient")`` for the flow pipeline, and
    ``(method label, other)`` for any other method (no flow: an empty or missing value, as read from a CSV)."""
    config, variant = [], []
    for f, r, v, m in zip(table["flow"], table["rectify"], table["variant"], table["method"], strict=True):
        is_flow = isinstance(f, str) and f != ""
        config.append(config_label(f, bool(r) if not isinstance(r, str) else r == "True") if is_flow else m)
        variant.append(v if is_flow else other)
    return config, variant


def mae_table(table: pd.DataFrame) -> str:
    """Plain-text MAE table (mean over frames): rows scene x configuration, columns variant, metres.

    Methods that are not the flow pipeline appear as their own configuration with variant ``-``.  A NaN
    metric of any frame makes its mean NaN (it is never silently dropped from the mean).
    """
    config, column = config_keys(table, other="-")
    t = table.assign(config=config, column=column)
    pivot = t.pivot_table(index=["scene", "config"], columns="column", values="mae_m", sort=False,
                          aggfunc=lambda s: s.mean(skipna=False), dropna=False)
    return pivot.to_string(float_format=lambda x: f"{x:.4f}")
