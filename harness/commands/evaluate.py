"""The evaluate command: run methods on every frame under a data root, score them against ground truth, report.

Writes a results set into ``out``::

    results.csv, results.json   one row per (scene, viewpoint, method): reports.schema.RESULT_COLUMNS, with the
                                frame's floor (reports.floor) beside the MAE
    regions.csv                 the same metrics per region of each frame (reports.regions)
    breakdown.csv               errors by angle to each baseline, true distance and texture
    frames.json                 where each evaluated frame lives
    config.json                 tri360 version and commit, every method's full configuration, the frames'
                                renderer settings: everything needed to reproduce the numbers
    maps/                       predicted distance of C (and confidence, for a method that gives one) per
                                frame and method, laid out by harness.data.results.map_paths

and the report (``harness.commands.report``) unless ``report=False``.  With a Dask cluster (``ctx``) each frame x
group of methods is one task whose worker writes the maps into the staging directory (so it must be on a
file system the workers share) and returns the rows; this process writes the rest (``docs/scale-out.md``).

The whole set is built in a hidden staging directory beside ``out`` and swapped in at the end, so an interrupted
run leaves the previous results set (results and report together) untouched and never an old report beside new
results.  ``out`` must be absent, empty or a results set tri360 wrote (nothing else in it), and never the data root,
a frame, a predictions root, inside one or a parent of one (:func:`harness.data.outputs.check_output`); the set
carries the marker of a results set.  Every name that becomes part of a map's path (scene, viewpoint, method label,
flow configuration, variant) is checked (:func:`harness.data.names.check_name`), and every frame must have ground truth
(or, below, none may have it), all before the first method runs.

**Each frame is read once per task.**  Finding, selecting and checking the frames (:func:`select_frames`,
:func:`check_frame_kinds`) reads only their ``frame.json`` and looks at which files are there
(:func:`harness.data.frame.read_frame_info`): no image or distance map is opened before the tasks.  Each task
reads its frame once (:func:`harness.data.frame.read_frame`: ``frame.json``, the images and the ground truth) and
everything in it works on that one :class:`harness.data.frame.Frame`: the methods (through
:func:`harness.runtime.blind.run_blind`), the regions, the floor and the scoring (or the quality figures), the
maps it writes and its ``config.json`` entry.  So a frame whose image or distance map does not decode, or whose
ground truth holds no finite distance, is refused (named) by its task, before that task runs a method, and the
whole run stops without writing a results set.  On Dask the task's worker reads the frame, not this process.  The
report (``build_report``), drawn after every task, reads each frame once more.

**Methods never see the frame.**  Every method, built in or outside, in this process or on a Dask worker, runs on its
:class:`reconstruction.methods.base.MethodInput`: read-only copies of the images and the told rig, nothing else (no
ground truth, path, provenance or photometric record); an outside method runs in a process of its own
(:func:`harness.runtime.blind.run_blind`).  Only the scorer reads the true distance.  The one exception is the
built-in ``oracle`` flow pipeline (:func:`harness.runtime.blind.needs_ground_truth`), whose label says that it uses
it.

**Frames without ground truth** (real captures, ``tri360 import``): when *no* frame of the data root has ground
truth, the methods run and nothing is scored.  Each row has empty metrics, ``valid_px`` 0, the method's
``seconds`` and the ground-truth-free quality figures of :func:`reconstruction.quality.assess`
(``reports.schema.QUALITY_COLUMNS``); the maps are written as for scored frames, plus the quality maps
(:func:`harness.data.results.quality_map_path`); there is no ``regions.csv`` or ``breakdown.csv``.  A data root that
mixes frames with and without ground truth is refused in one line naming one frame of each kind (evaluate them
into separate results sets), and so is a method that needs ground truth (``--flow oracle``) or a suite's split
with a frame lacking it.  Frames with ground truth are scored exactly as before (no quality figures: ``tri360
reconstruct`` gives both).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from harness.commands.report import build_report
from harness.data.errors import UserError
from harness.data.exr import CONFIDENCE_CHANNEL, DISTANCE_CHANNEL, write_exr_channels, write_float_map
from harness.data.frame import find_frames, read_frame, read_frame_info
from harness.data.names import check_name
from harness.data.outputs import RESULTS_FORMAT, check_output, mark_output, staged_directory
from harness.data.provenance import software
from harness.data.results import map_paths, quality_map_path, write_results
from harness.data.suite import IDEAL
from harness.runtime.blind import run_blind
from harness.runtime.context import IN_PROCESS, RunContext
from reconstruction.methods.base import (
    Method,
    MethodInput,
    MethodOutput,
    flow_fields,
    method_groups,
    reference_distance,
    with_references,
)
from reconstruction.methods.flow_pipeline import config_label
from reconstruction.quality import assess
from reports.floor import floor_fields, frame_floor_sigma, region_floors
from reports.metrics import breakdown
from reports.regions import region_summaries, regions
from reports.schema import METRIC_COLUMNS, QUALITY_COLUMNS, breakdown_table, regions_table, results_table, unscored_rows
from reports.tables import method_summary, quality_summary
from scenes.registry import discover

__all__ = ["FrameRef", "select_frames", "evaluate", "evaluate_task", "method_groups", "summary_text",
           "results_config", "method_configs", "checked_maps"]


@dataclass(frozen=True)
class FrameRef:
    """A frame found under a data root: its directory, the scene/viewpoint its frame.json names, and whether it holds
    ground-truth distance files (:attr:`harness.data.frame.FrameInfo.has_ground_truth`; not read)."""

    path: Path
    scene: str
    viewpoint: str
    has_ground_truth: bool


def group_name(group: Sequence[Method]) -> str:
    """A method group's name for progress and errors: its one label, or the first label and how many more."""
    return group[0].label if len(group) == 1 else f"{group[0].label} +{len(group) - 1}"


def select_frames(data_root: Path, scenes: Sequence[str] | None = None) -> list[FrameRef]:
    """Every frame under ``data_root`` (which may itself be a frame directory), optionally only ``scenes``.

    A frame's scene is the one its ``frame.json`` names; a scene also matches by the name of the directory
    level the frame sits in (``<root>/<scene>/<viewpoint>``).  Reads only each frame's ``frame.json``
    (:func:`harness.data.frame.read_frame_info`): no pixel.

    Raises:
        UserError: missing root, no frames (for the scenes), a malformed frame.json, a missing image or distance
            file (:func:`~harness.data.frame.read_frame_info`), or two frame directories that name the same scene
            and viewpoint (their outputs would collide).
    """
    data_root = Path(data_root)
    if not data_root.is_dir():
        raise UserError(f"{data_root}: data root does not exist" if not data_root.exists()
                        else f"{data_root}: data root is not a directory")
    refs = []
    for d in find_frames(data_root):
        info = read_frame_info(d)
        check_name(info.scene, f"{d / 'frame.json'} (scene)")
        check_name(info.viewpoint, f"{d / 'frame.json'} (viewpoint)")
        refs.append(FrameRef(d, info.scene, info.viewpoint, info.has_ground_truth))
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


def check_method_paths(methods: Sequence[Method]) -> None:
    """Every method's maps get a path of their own, made of safe names.

    Raises:
        UserError: an unsafe label, flow or variant name (naming its source), or two methods whose maps would
            be the same file.
    """
    seen: dict[Path, str] = {}
    for m in methods:
        rel, _ = map_paths("scene", "viewpoint", m.label, source=getattr(m, "label_source", "--method"),
                           **flow_fields(m))
        if rel in seen:
            raise UserError(f"methods {seen[rel]!r} and {m.label!r} would write the same map ({rel.parent.name}/"
                            f"{rel.name}); evaluate them separately")
        seen[rel] = m.label


def scorable_frame(path: Path, scored: bool = True):
    """Read the frame at ``path`` with its ground truth (each file once, :func:`harness.data.frame.read_frame`),
    refusing one that cannot be scored.

    Args:
        scored: False = the frame is expected to have no ground truth (a real capture: nothing is scored); it is
            read and returned as is, and one that has ground truth is refused.
    Raises:
        UserError: a malformed frame, no ground-truth distance (or, with ``scored=False``, ground truth), or no
            pixel with a finite distance (named).
    """
    frame = read_frame(path)
    if not scored:
        if frame.has_ground_truth:
            raise UserError(f"{path}: frame has ground-truth distance, but the other frames of this evaluation have "
                            "none; evaluate frames with and without ground truth into separate results sets")
        return frame
    if not frame.has_ground_truth:
        raise UserError(f"{path}: frame has no ground-truth distance, nothing to score "
                        "(use 'tri360 reconstruct' for captures without ground truth)")
    if not np.isfinite(frame.distance["C"]).any():
        raise UserError(f"{Path(path) / 'C.distance.exr'}: no pixel has a finite distance, nothing to score")
    return frame


def check_frame_kinds(refs: Sequence[FrameRef], methods: Sequence[Method], suite: dict | None = None) -> bool:
    """Decide, before the first method runs, how the data root is evaluated from which files its frames hold
    (:attr:`FrameRef.has_ground_truth`; nothing is read): True = every frame has ground truth (scored), False = none
    has (methods run, nothing scored; the module doc).  Whether the files decode, and whether the ground truth holds
    a finite distance, each frame's task checks when it reads the frame (:func:`scorable_frame`).

    Raises:
        UserError: frames with and without ground truth mixed (one line naming one of each); no ground truth in a
            suite's split, or for a method that needs it (the oracle).
    """
    with_gt = [ref for ref in refs if ref.has_ground_truth]
    without = [ref for ref in refs if not ref.has_ground_truth]
    if not without:
        return True
    if suite:
        raise UserError(f"{without[0].path}: frame has no ground-truth distance, which every frame of a suite's "
                        f"split has (render the split again with `tri360 render --suite`)")
    if with_gt:
        raise UserError(f"{without[0].path}: frame has no ground-truth distance, but {with_gt[0].path} has; "
                        "evaluate does not mix scored and unscored frames in one results set: evaluate the frames "
                        "with and without ground truth into separate results sets")
    for m in methods:
        if flow_fields(m).get("flow") == "oracle":
            raise UserError(f"{without[0].path}: frame has no ground-truth distance, which method {m.label} "
                            "(flow 'oracle': exact correspondences from ground truth) needs")
    return False


def method_configs(methods: Sequence[Method]) -> dict[str, dict]:
    """``config.json``'s ``methods``: each method's full configuration (``config()``) by label (also what ``tri360
    methods --show`` prints)."""
    return {m.label: m.config() for m in methods}


def results_config(methods: Sequence[Method], frames: list, data_root: Path, started: float,
                   suite: dict | None = None) -> dict:
    """The contents of ``config.json`` (with a ``suite`` entry when a suite's split was evaluated)."""
    return {
        "format": RESULTS_FORMAT,
        "software": software(),
        "created_unix_s": round(started, 3),
        "data_root": str(Path(data_root).resolve()),
        "methods": method_configs(methods),
        "frames": frames,
        **({"suite": suite} if suite else {}),
    }


def frame_labels(frames: list[dict], suite: dict | None = None) -> dict[tuple[str, str], dict]:
    """``(scene, viewpoint) -> {family, tags, suite_id, split, condition}`` of each evaluated frame (``frames``: the
    ``config.json`` entries): the suite's record when given, else the family the frame's provenance names, that
    family's registered difficulty tags (``SceneEntry.tags``; joined by ``;``) and the condition its provenance
    records (``renderer.condition.name``; without one ``ideal`` for a rendered frame, empty for an imported or
    perturbed one)."""
    if suite:
        known = {(f["scene"], f["viewpoint"]): f for f in suite["frames"]}
        return {k: {"family": f["family"], "tags": ";".join(f["tags"]), "suite_id": suite["id"],
                    "split": suite["split"], "condition": f.get("condition", IDEAL)} for k, f in known.items()}
    entries = discover()[0]
    out = {}
    for info in frames:
        renderer = info["renderer"] if isinstance(info.get("renderer"), dict) else {}
        scene = renderer.get("scene")
        family = scene.get("family") if isinstance(scene, dict) and isinstance(scene.get("family"), str) else ""
        tags = getattr(entries[family], "tags", ()) if family in entries else ()
        record = renderer.get("condition")
        if isinstance(record, dict):
            condition = str(record.get("name", ""))
        else:  # a rendered frame without a condition record: ideal cameras; an imported capture: not known
            condition = "" if renderer.get("name") == "import" or "perturbation" in renderer else IDEAL
        out[(info["scene"], info["viewpoint"])] = {"family": family, "tags": ";".join(tags), "suite_id": "",
                                                  "split": "", "condition": condition}
    return out


def checked_maps(frame, method: Method, output: MethodOutput) -> tuple[np.ndarray, np.ndarray | None]:
    """The method's distance and confidence maps, refused (named) when they (or its reference distance) are not
    of the frame's (H, W)."""
    pred = np.asarray(output.distance)
    conf = None if output.confidence is None else np.asarray(output.confidence)
    ref = None if output.reference is None else np.asarray(output.reference)
    for what, arr in (("distance", pred), ("confidence", conf), ("reference distance", ref)):
        if arr is not None and arr.shape != (frame.height, frame.width):
            raise UserError(f"method {method.label}: returned a {arr.shape} {what} map for the "
                            f"{frame.width}x{frame.height} frame {frame.path}")
    return pred, conf


def calibrated(output: MethodOutput) -> str:
    """The results column ``calibrated``: what the method's self-calibration applied (``info["applied"]``) joined by
    ``; ``, ``none`` when it applied nothing, empty for a method that does not self-calibrate."""
    applied = output.info.get("applied") if isinstance(output.info, dict) else None
    if not isinstance(applied, list):
        return ""
    return "; ".join(str(x) for x in applied) or "none"


def _unscored_row(frame, method: Method, outputs: dict[str, MethodOutput]) -> tuple[dict, dict[str, np.ndarray]]:
    """The results row of one method on a frame without ground truth (empty metrics, ``valid_px`` 0, the
    quality figures of :func:`reconstruction.quality.assess`) and its per-pixel quality maps; ``outputs``: every
    method's output on the frame by label (the reference distance may be another's, :func:`reference_distance`)."""
    output = outputs[method.label]
    pred, conf = checked_maps(frame, method, output)
    maps, quality = assess(frame, pred, conf, reference_distance(MethodInput.of(frame), method, outputs))
    row = {"scene": frame.scene, "viewpoint": frame.viewpoint, "method": method.label, **flow_fields(method),
           "width": frame.width, "height": frame.height, **dict.fromkeys(METRIC_COLUMNS, float("nan")),
           "valid_px": 0, "seconds": round(output.total_seconds, 4), **{c: quality[c] for c in QUALITY_COLUMNS},
           "calibrated": calibrated(output)}
    return row, maps


def _score_rows(frame, method: Method, output: MethodOutput, masks: dict,
                floors: dict[str, float]) -> tuple[dict, list[dict], list[dict]]:
    """The results row, the breakdown rows and the region rows of one method on one frame; ``floors``: the frame's
    floor per region (:func:`reports.floor.region_floors` over ``masks``), which every row carries beside its MAE
    (``reports.schema.FLOOR_COLUMNS``)."""
    pred, conf = checked_maps(frame, method, output)
    key = {"scene": frame.scene, "viewpoint": frame.viewpoint, "method": method.label, **flow_fields(method)}
    region_rows = [{**key, **r, **floor_fields(r["mae_m"], floors[r["region"]])}
                   for r in region_summaries(frame, pred, conf, masks=masks)]
    overall = next(r for r in region_rows if r["region"] == "all")
    row = {**key, "width": frame.width, "height": frame.height,
           **{k: v for k, v in overall.items() if k not in key and k != "region"},
           "seconds": round(output.total_seconds, 4), "calibrated": calibrated(output)}
    return row, [{**key, **b} for b in breakdown(frame, pred)], region_rows


def evaluate_task(frame_path: str, methods: Sequence[Method], stage: str, scored: bool = True) -> dict:
    """One task of :func:`evaluate`: read one frame (each of its files once, :func:`scorable_frame`), run ``methods``
    on it, write their maps under ``stage``, score them (``scored=False``: a frame without ground truth; its rows
    carry the quality figures, and its quality maps are written too); everything works on that one frame in memory.

    Runs in this process or on a Dask worker (then ``frame_path`` and ``stage`` must be on a file system the
    worker sees at the same path).  Writing the maps is atomic and idempotent, so a task re-run after a lost
    worker changes nothing.

    Returns:
        ``{"rows": {label: (row, breakdown rows, region rows)}, "frame": the frame's config.json entry}``.
    Raises:
        UserError: the frame is malformed or has no usable ground truth (before any method runs), or a method fails
            on it (named).
    """
    path = Path(frame_path)
    frame = scorable_frame(path, scored)
    masks = regions(frame) if scored else {}
    # the floor (an ideal matcher's MAE) per region, from the truth and the rig: the same for every method
    floors = region_floors(frame_floor_sigma(frame), masks) if scored else {}
    try:
        # the methods never see ground truth (run_blind); a frame without ground truth is assessed: the quality
        # references run along (sharing their flow)
        outputs = run_blind(frame, methods if scored else with_references(methods))
    except ValueError as exc:
        raise UserError(f"{path}: {exc}") from None
    rows = {}
    for method in methods:
        output = outputs[method.label]
        if scored:
            row, brs, rrs = _score_rows(frame, method, output, masks, floors)
        else:
            (row, quality), brs, rrs = _unscored_row(frame, method, outputs), [], []
            write_exr_channels(Path(stage) / quality_map_path(frame.scene, frame.viewpoint, method.label,
                                                              **flow_fields(method)), quality)
        dist_rel, conf_rel = map_paths(frame.scene, frame.viewpoint, method.label, **flow_fields(method))
        # a prediction may hold NaN/inf/<= 0 (= no prediction): written as is, like tri360-pred/1
        write_float_map(Path(stage) / dist_rel, np.asarray(output.distance, np.float32), DISTANCE_CHANNEL)
        if output.confidence is not None:
            write_float_map(Path(stage) / conf_rel, np.asarray(output.confidence, np.float32), CONFIDENCE_CHANNEL)
        rows[method.label] = (row, brs, rrs)
    info = {"path": str(path.resolve()), "scene": frame.scene, "viewpoint": frame.viewpoint,
            "width": frame.width, "height": frame.height, "baseline_m": frame.baseline_m,
            "renderer": frame.renderer, **({} if scored else {"ground_truth": False})}
    return {"rows": rows, "frame": info}


def evaluate(data_root: Path, out: Path, methods: Sequence[Method], scenes: Sequence[str] | None = None,
             report: bool = True, ctx: RunContext = IN_PROCESS, inputs: Sequence[Path] = (),
             suite: dict | None = None) -> pd.DataFrame:
    """Run ``methods`` on every frame under ``data_root``, score them, and write a results set to ``out``.

    Before any method runs: the frames are found and their ``frame.json`` read (no pixel: each task reads its frame,
    the module doc), every name that becomes a path is checked, either every frame has ground truth (scored) or none
    has (nothing scored, quality figures instead: the module doc; :func:`check_frame_kinds`), and ``out`` must be
    absent, empty or a results set tri360 wrote, and neither an input nor inside or above one (the data root, the
    frames and ``inputs``, e.g. ``score``'s predictions roots).

    Args:
        inputs: further inputs that ``out`` must keep clear of (predictions roots).
        ctx: where it runs and whether it shows progress.  On Dask (``--scheduler`` / ``--workers``, or a
            study's open executor, left open): one task per frame x group of methods that share work (the
            variants of one flow configuration); workers write the maps into the staged results directory, this
            process gathers the rows and writes the results files.  In this process: one task per frame.  Either
            way each task reads its frame once, and holds one frame.  The rows and maps are the same either way
            (only ``seconds``, each method's wall time, differs from run to run).
        suite: the evaluated suite split (``harness.data.suite.Suite.describe``, from
            ``harness.commands.parts.suite``, which checks the data root first): recorded in ``config.json`` and
            in every row (``suite_id``, ``split``).
            Every row also names its frame's family and difficulty tags (:func:`frame_labels`).

    Returns:
        The results table (also written to ``out``).
    Raises:
        UserError: bad data root, a malformed frame.json or a missing file, frames with and without ground truth
            mixed (named), an unsafe name, an unusable output location (all checked before any long work); a frame
            whose files do not decode or whose ground truth holds no finite distance (by its task), or a method that
            fails on a frame.
    """
    started = time.time()
    ctx.check()
    refs = select_frames(data_root, scenes)
    labels = [m.label for m in methods]
    if not methods:
        raise UserError("no methods to evaluate")
    if len(set(labels)) != len(labels):
        raise UserError(f"duplicate method labels: {', '.join(sorted({x for x in labels if labels.count(x) > 1}))}")
    check_method_paths(methods)
    check_output(out, "results", [data_root, *(r.path for r in refs), *inputs])
    scored = check_frame_kinds(refs, methods, suite)  # which frames hold ground truth, before the first method runs
    distributed = ctx.distributed
    groups = method_groups(methods) if distributed else [list(methods)]
    rows, brows, rrows, frames_index, frames_config = [], [], [], [], []
    with staged_directory(out) as stage:
        stage_abs = str(Path(stage).resolve())
        tasks = {(i, g): (str(ref.path.resolve()), group, stage_abs, scored)
                 for i, ref in enumerate(refs) for g, group in enumerate(groups)}
        names = {(i, g): f"{ref.scene}/{ref.viewpoint} {group_name(group)}"
                 for i, ref in enumerate(refs) for g, group in enumerate(groups)}
        done: dict[tuple[int, int], dict] = {}
        with ctx.executor() as ex:
            for key, result in ex.run(evaluate_task, tasks, desc="evaluate", names=names,
                                      unit="frame" if len(groups) == 1 else "task", progress=ctx.progress):
                done[key] = result
        for i, _ref in enumerate(refs):
            frame_rows = {label: v for g in range(len(groups)) for label, v in done[(i, g)]["rows"].items()}
            info = done[(i, 0)]["frame"]
            for method in methods:
                row, brs, rrs = frame_rows[method.label]
                rows.append(row)
                brows.extend(brs)
                rrows.extend(rrs)
            frames_index.append({"scene": info["scene"], "viewpoint": info["viewpoint"], "path": info["path"]})
            frames_config.append(info)
        labels = frame_labels(frames_config, suite)
        rows = [{**r, **labels.get((r["scene"], r["viewpoint"]), {})} for r in rows]
        table = results_table(rows)
        write_results(stage, table, breakdown_table(brows) if scored else None,
                      regions_table(rrows) if scored else None, frames=frames_index,
                      config=results_config(methods, frames_config, data_root, started, suite))
        if report:
            build_report(stage, location=out)
        mark_output(stage, "results")
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


def summary_text(table: pd.DataFrame) -> str:
    """The results table as the plain-text summary a run prints: one row per method, best MAE first (means over
    its frames, :func:`reports.tables.method_summary`; ``x floor`` is the mean over its frames of the MAE as a multiple
    of the frame's floor, ``mae_x_floor``); a mean that is not a number (a frame without one) is ``-``.  Results of
    frames without ground truth (nothing scored) print, after a line saying so, the means of their quality figures
    instead (:func:`reports.tables.quality_summary`)."""

    def num(x: float, fmt: str) -> str:
        return format(x, fmt) if np.isfinite(x) else "-"

    if len(table) and unscored_rows(table).all():
        header = ["method", "frames", "photometric residual", "uncertainty", "calibration score", "flagged",
                  "s/frame"]
        rows = [[str(r.method), str(r.frames), num(r.photometric_residual_median, ".2f"),
                 num(r.uncertainty_median, ".3f"), num(r.calibration_score, ".3f"), str(r.flagged),
                 num(r.seconds, ".1f")] for r in quality_summary(table).itertuples(index=False)]
        return "no ground truth: nothing scored; ground-truth-free quality figures (medians), mean over frames:\n" \
            + _columns_text(header, rows)
    summary = method_summary(table)
    header = ["method", "frames", "MAE (m)", "x floor", "median (m)", "delta<1.10", "s/frame"]
    rows = [[str(r.method), str(r.frames), num(r.mae_m, ".4f"), num(r.mae_x_floor, ".2f"), num(r.median_m, ".4f"),
             num(100.0 * r.delta110, ".1f") + (" %" if np.isfinite(r.delta110) else ""), num(r.seconds, ".1f")]
            for r in summary.itertuples(index=False)]
    return _columns_text(header, rows)


def _columns_text(header: list[str], rows: list[list[str]]) -> str:
    """Plain-text columns: the first left-aligned, the others right-aligned."""
    widths = [max(len(x) for x in col) for col in zip(header, *rows, strict=True)]
    lines = ["  ".join(x.ljust(w) if i == 0 else x.rjust(w) for i, (x, w) in enumerate(zip(line, widths,
                                                                                         strict=True)))
             for line in [header, *rows]]
    return "\n".join(lines)
