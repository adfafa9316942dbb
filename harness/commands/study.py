"""Parameter studies: render and evaluate every point of a grid of settings, in one command.

A study is a TOML file::

    [render]                    # tri360 render options (dashes as underscores), the same for every point
    scene = "synthetic_box"
    width = 200
    viewpoints = 1

    [evaluate]                  # tri360 evaluate options: method / flow / variants / rectify / report
    method = ["dis-rect:gradient", "dis-rect:average"]

    [grid]                      # a list of values for any key of [render] or [evaluate]; the full product runs
    baseline = [0.2, 0.4]

:func:`run_study` writes into ``out``:

- ``study.csv``: one row per grid point x frame x method: a column per grid key, then the results columns of
  ``tri360 evaluate`` (``reports.schema``), then ``render_s`` (the frame's render wall time from its
  ``render_log.json``; NaN if unknown);
- ``<key>.png`` per grid key: the metric (default ``mae_m``) against the key's values, one line per method (the
  mean over frames and over the other grid keys' values), with a band from the minimum to the maximum;
- ``study.md``: the study file, the table of means per point and method, the plots;
- ``data/r-<hash>/``: the frames of each distinct render setting (a data root), ``results/e-<hash>/``: the results
  set of each distinct (render, evaluate) setting, ``points.json``: which grid point uses which.

Before any work every key is checked against its option's type (:func:`load_study`; the types come from
``RenderSettings``, ``plan_render`` and ``MethodSelection``, not from a table here), every grid point as render
and evaluate would check it (:func:`plan_point`), and the plan's size (:data:`LIMIT_POINTS`, :data:`LIMIT_FRAMES`:
past them only with ``yes``).

A file with ``kind = "robustness"`` is a robustness study instead (:mod:`harness.commands.parts.robustness`), which
:func:`run_study` hands over whole.

Reuse: the data roots are named by what decides the frames' pixels (:func:`point_ids`), so a rerun, or an
extended grid, renders only frames that are missing (``render_frames`` is resumable and checks that stored frames
were rendered with the same settings), a threads-only change renders nothing, and only points without a complete
results set are evaluated. With a cluster
(``--scheduler`` / ``--workers``) one executor serves every render and evaluation of the study, and every grid
point's frames (then every point's evaluation) are submitted at once (up to ``MAX_PARALLEL_POINTS`` points at a
time), so the workers are busy even when a point has fewer frames than there are workers. Without one, each point is
rendered, then evaluated, in the file's order.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import time
import tomllib
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from functools import partial
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from harness.commands.evaluate import evaluate
from harness.commands.parts.robustness import is_robustness_study, run_robustness
from harness.commands.render import (
    RENDER_LOG,
    RenderPlan,
    SettingsMismatch,
    parse_overrides,
    plan_render,
    render_frames,
    settings_from_options,
)
from harness.data import jsonio
from harness.data.atomic import atomic_write_bytes, atomic_write_text
from harness.data.errors import UserError
from harness.data.frame import frame_dir, is_complete
from harness.data.outputs import check_output, ensure_output_dir, mark_output
from harness.data.results import read_frames, read_results
from harness.render.base import RenderSettings
from harness.runtime.context import IN_PROCESS, RunContext
from harness.runtime.options import MethodSelection, typed_value
from harness.runtime.progress import progress_bar
from reconstruction.params import type_hints
from reports.plots import png_bytes
from reports.schema import METRIC_COLUMNS
from scenes.registry import SceneError

__all__ = ["RENDER_KEYS", "EVALUATE_KEYS", "StudySpec", "PointPlan", "load_study", "grid_points", "plan_point",
           "point_ids", "frame_seconds", "run_study", "plot_metric"]

RENDER_KEYS = ("scene", "renderer", "viewpoints", "width", "samples", "seed", "threads", "baseline", "max_bounces",
               "light_tree", "no_denoise", "set")
"""Keys of ``[render]`` (``tri360 render`` options, dashes as underscores; ``set`` is a table or KEY=VALUE list)."""
EVALUATE_KEYS = (*(f.name for f in dataclasses.fields(MethodSelection)), "report")
"""Keys of ``[evaluate]`` (``tri360 evaluate`` options: :class:`harness.runtime.options.MethodSelection`'s fields and
``report``, which defaults to false in a study)."""
DEFAULT_METRIC = "mae_m"
#: grid points rendered or evaluated at once on a cluster (threads of this process that submit their tasks)
MAX_PARALLEL_POINTS = 32


RENDER_S_FIXED = 4.0
RENDER_S_PER_MPX_SAMPLE = 6.0
"""Estimated Cycles wall time of one frame (C, U and R), seconds: ``RENDER_S_FIXED + RENDER_S_PER_MPX_SAMPLE *
megapixels (W x W/2) * samples``, fitted to the classroom frames measured on 2 cores (``docs/studies.md``: 500 px
at 4 and 64 samples 7 and 52 s, 1000 px at 20 samples 57 s idle, 2000 px at 20 samples 228 s)."""
RAYCAST_S_PER_MPX = 140.0
"""Estimated ray-caster wall time of one frame per megapixel, seconds (synthetic_box on 2 cores shared with other
jobs: 3.2 s at 200 px, 0.02 Mpx; 11.3 s at 400 px, 0.08 Mpx)."""
NOTICE_FRAMES = 8
"""A study that renders more frames than this says so (frames, points, estimated render time) before it starts."""
LIMIT_FRAMES = 100
"""A study that renders more frames than this, or whose estimated rendering exceeds :data:`LIMIT_RENDER_S`,
starts only with ``--yes``."""
LIMIT_RENDER_S = 4 * 3600.0
"""Estimated rendering, seconds, past which a study needs ``--yes``."""
LIMIT_POINTS = 1000
"""Grid points past which a study needs ``--yes`` before it is even planned (checked from the grid's lengths)."""


def _render_hints() -> dict[str, object]:
    """The type of each ``[render]`` key: a :class:`RenderSettings` field's (``no_denoise``: ``denoise``'s), else
    the parameter of :func:`harness.commands.render.plan_render` of that name; ``set`` is a table of scene parameters
    or a list of KEY=VALUE strings."""
    settings, plan = type_hints(RenderSettings), type_hints(plan_render)
    out = {}
    for key in RENDER_KEYS:
        if key == "set":
            out[key] = dict | tuple[str, ...]
        elif key == "no_denoise":
            out[key] = settings["denoise"]
        else:
            out[key] = settings[key] if key in settings else plan[key]
    return out


def _evaluate_hints() -> dict[str, object]:
    """The type of each ``[evaluate]`` key: a :class:`MethodSelection` field's, and ``report``: the evaluate
    job's parameter."""
    return {**type_hints(MethodSelection), "report": type_hints(evaluate)["report"]}


class StudySpec:
    """A parsed, checked study file: ``render`` and ``evaluate`` settings and the ``grid`` (key -> values), as
    the file gives them (each value checked against its key's type)."""

    def __init__(self, path: Path, render: dict, evaluate: dict, grid: dict[str, list], text: str):
        self.path, self.render, self.evaluate, self.grid, self.text = path, render, evaluate, grid, text

    @property
    def size(self) -> int:
        """Number of grid points (the product of the grid's lengths), without listing them."""
        return math.prod(len(v) for v in self.grid.values())


def _check_value(key: str, value, source: str):
    """A ``[render]`` or ``[evaluate]`` value checked against its key's type (``source`` names it in errors);
    ``set`` as a dict of scene parameters."""
    hints = _render_hints() if key in RENDER_KEYS else _evaluate_hints()
    value = typed_value(value, hints[key], source)
    if key == "set":
        value = parse_overrides(list(value), source) if isinstance(value, tuple) else value
    return value


def load_study(path: Path) -> StudySpec:
    """Read and check a study TOML: every key of ``[render]`` and ``[evaluate]``, and every value of every
    ``[grid]`` list, against the type of its option (:func:`harness.runtime.options.typed_value`).

    Raises:
        UserError: unreadable or malformed TOML, an unknown section or key (naming the allowed ones), a value
            of the wrong type (naming the key), or a ``[grid]`` entry that is not a non-empty list.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{path}: study file does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: study file cannot be read ({exc})") from None
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{path}: not valid TOML ({exc})") from None
    if "kind" in raw:
        raise UserError(f"{path}: kind = {raw['kind']!r}: the only kind of study file is 'robustness' "
                        "(docs/robustness.md); a grid study has no kind key")
    unknown = sorted(set(raw) - {"render", "evaluate", "grid"})
    if unknown:
        raise UserError(f"{path}: unknown section(s) [{'], ['.join(unknown)}]; a study has [render], [evaluate] "
                        "and [grid]")
    sections = {}
    for name, allowed in (("render", RENDER_KEYS), ("evaluate", EVALUATE_KEYS)):
        table = raw.get(name, {})
        if not isinstance(table, dict):
            raise UserError(f"{path}: [{name}] must be a table")
        bad = sorted(set(table) - set(allowed))
        if bad:
            raise UserError(f"{path}: [{name}] has unknown key(s) {', '.join(bad)}; allowed: {', '.join(allowed)}")
        for key, value in table.items():
            _check_value(key, value, f"{path}: [{name}] {key}")
        sections[name] = dict(table)
    grid = raw.get("grid", {})
    if not isinstance(grid, dict):
        raise UserError(f"{path}: [grid] must be a table")
    for key, values in grid.items():
        if key not in RENDER_KEYS and key not in EVALUATE_KEYS:
            raise UserError(f"{path}: [grid] key {key!r} is no render or evaluate option; allowed: "
                            f"{', '.join(RENDER_KEYS + EVALUATE_KEYS)}")
        if not isinstance(values, list) or not values:
            raise UserError(f"{path}: [grid] {key} must be a non-empty list of values, got {values!r}")
        for i, value in enumerate(values):
            _check_value(key, value, f"{path}: [grid] {key}[{i}]")
        if len({json.dumps(v, sort_keys=True) for v in values}) != len(values):
            raise UserError(f"{path}: [grid] {key} lists a value twice")
    return StudySpec(path, sections["render"], sections["evaluate"], dict(grid), text)


def grid_points(spec: StudySpec) -> list[dict]:
    """The full product of the grid, in the file's order: ``[{key: value, ...}, ...]`` (one empty point if
    there is no grid)."""
    keys = list(spec.grid)
    return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*(spec.grid[k] for k in keys))]


def _digest(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:12]


def point_ids(plan: RenderPlan, methods: Sequence, report: bool) -> tuple[str, str]:
    """``("r-<hash>", "e-<hash>")``: the names of a point's data root and results set.

    The render hash covers what decides the frames' pixels -- the planned frames' identity
    (:func:`harness.render.base.identity`: renderer, width, baseline, the renderer's pixel settings, scene
    parameters and code version), the scene directory and the number of viewpoints -- so a change of a setting
    that changes no pixel (``threads``) reuses the frames, and a change of the render defaults (e.g. the samples)
    renders into a new data root instead of failing on frames rendered the old way.  The results hash adds the
    methods' labels and ``report``.
    """
    key = {"identity": plan.identity, "scene_dir": plan.scene_dir, "viewpoints": plan.viewpoints}
    return "r-" + _digest(key), "e-" + _digest({**key, "methods": [m.label for m in methods], "report": report})


@dataclasses.dataclass(frozen=True)
class PointPlan:
    """One grid point, checked: its render (:class:`harness.commands.render.RenderPlan`, rigs not yet placed, and
    the :func:`harness.commands.render.render_frames` keywords), its methods, and its data root and results set."""

    point: dict
    render: RenderPlan
    render_kw: dict
    methods: list
    report: bool
    rid: str
    eid: str


def plan_point(spec: StudySpec, point: dict) -> PointPlan:
    """Check one grid point as ``render`` and ``evaluate`` would (types, ranges, scene and its parameters,
    renderer, methods), without rendering.

    Raises:
        UserError, SceneError: naming the study file and the point.
    """
    where = f"{spec.path} (grid point {point or 'the only one'})"
    render = {k: _check_value(k, v, f"{where}: {k}") for k, v in {**spec.render, **point}.items()
              if k in RENDER_KEYS}
    evaluate_ = {k: v for k, v in {**spec.evaluate, **point}.items() if k in EVALUATE_KEYS}
    report = _check_value("report", evaluate_.get("report", False), f"{where}: report")
    kw = {k: render[k] for k in ("scene", "viewpoints", "baseline", "renderer") if k in render}
    kw["overrides"] = render.get("set")
    try:
        plan = plan_render(settings_from_options(render), place_rigs=False, **kw)
        methods = MethodSelection.from_mapping(evaluate_, where).methods()
    except UserError as exc:
        raise UserError(f"{where}: {exc}" if not str(exc).startswith(where) else str(exc)) from None
    except SceneError as exc:
        raise SceneError(f"{where}: {exc}") from None
    rid, eid = point_ids(plan, methods, report)
    return PointPlan(point, plan, kw, methods, report, rid, eid)


def frame_seconds(plan: RenderPlan) -> float:
    """Estimated wall time of rendering one frame of ``plan``, seconds (:data:`RENDER_S_PER_MPX_SAMPLE`,
    :data:`RAYCAST_S_PER_MPX`; a rough guide on 2 cores, not a promise)."""
    mpx = plan.settings.width * plan.settings.height / 1e6
    if plan.renderer == "raycast":
        return RAYCAST_S_PER_MPX * mpx
    return RENDER_S_FIXED + RENDER_S_PER_MPX_SAMPLE * mpx * plan.settings.samples


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else (f"{seconds / 60:.0f} min" if seconds < 7200 else
                                                      f"{seconds / 3600:.1f} h")


def _render_seconds(frame_path: str) -> float:
    try:
        log = json.loads((Path(frame_path) / RENDER_LOG).read_text(encoding="utf-8"))
        return float(log["seconds"]["total"])
    except (OSError, ValueError, KeyError, TypeError):
        return float("nan")


GRID_COLUMN_SAME = ("width", "viewpoints")
"""Grid keys whose value the results table already holds under the same name (or not at all): their study.csv
column is the key itself.  Any other grid key that collides with a results column (``method``) gets ``grid_``
in front."""


def grid_column(key: str, columns) -> str:
    """The study.csv column of grid key ``key``, given the results table's ``columns`` (:data:`GRID_COLUMN_SAME`)."""
    return key if key in GRID_COLUMN_SAME or key not in columns else f"grid_{key}"


def _cell(value):
    """A grid value as a study.csv cell (scalars as they are, anything else as JSON)."""
    return value if isinstance(value, bool | int | float | str) else json.dumps(value, sort_keys=True)


def run_study(study_path: Path, out: Path, ctx: RunContext = IN_PROCESS, metric: str = DEFAULT_METRIC,
              yes: bool = False) -> pd.DataFrame:
    """Run (or resume, or extend) a study; write ``study.csv``, one plot per grid key and ``study.md`` to ``out``.

    Before any work: the study file is checked (:func:`load_study`), its size from the grid's lengths (more than
    :data:`LIMIT_POINTS` points need ``yes``), then every grid point (:func:`plan_point`); a study that renders
    more than :data:`NOTICE_FRAMES` frames prints how many and about how long, and past :data:`LIMIT_FRAMES`
    frames or :data:`LIMIT_RENDER_S` of estimated rendering it needs ``yes``.

    Returns:
        The ``study.csv`` table.
    Raises:
        UserError: a malformed study file, an unknown metric, a plan too large without ``yes``, or anything
            ``render``/``evaluate`` refuses.
    """
    if is_robustness_study(study_path):  # kind = "robustness": harness.commands.parts.robustness
        if metric != DEFAULT_METRIC:
            raise UserError(f"--metric {metric}: a robustness study ({study_path}) tabulates {DEFAULT_METRIC} only")
        return run_robustness(study_path, out, ctx)
    started = time.time()
    ctx.check()
    spec = load_study(study_path)
    check_output(Path(out), "study", [study_path])  # absent, empty or a study tri360 wrote; not around the file
    if metric not in METRIC_COLUMNS:
        raise UserError(f"unknown metric {metric!r}; choose one of {', '.join(METRIC_COLUMNS)}")
    if spec.size > LIMIT_POINTS and not yes:
        lengths = " x ".join(f"{len(v)} {k}" for k, v in spec.grid.items())
        raise UserError(f"{spec.path}: {spec.size} grid points ({lengths}), more than {LIMIT_POINTS}; check the "
                        "grid, or pass --yes to plan and run them all")
    plan = [plan_point(spec, point) for point in grid_points(spec)]
    out = Path(out)
    _check_size(spec, plan, out, yes)
    out = ensure_output_dir(out)
    atomic_write_text(out / "points.json", jsonio.dumps(
        [{"grid": p.point, "data": f"data/{p.rid}", "results": f"results/{p.eid}"} for p in plan]))
    with ctx.executor() as ex:
        run = ctx.on(ex)  # one executor for every render and evaluation of the study
        steps = []  # per point: (render job or None, evaluate job or None); a job is (name, callable of ctx=)
        rendered = set()
        for p in plan:
            data, results = out / "data" / p.rid, out / "results" / p.eid
            render = None if p.rid in rendered else (f"render {p.point or ''} -> {data}",
                                                     partial(_render_point, p, data))
            rendered.add(p.rid)
            if _complete(results):
                if ctx.progress:
                    print(f"study: reuse {results}", flush=True)
                steps.append((render, None))
                continue
            steps.append((render, (f"evaluate {p.point or ''} -> {results}",
                                   partial(evaluate, data, results, p.methods, report=p.report))))
        if ex.distributed:
            _run_concurrently([r for r, _ in steps if r], run, "render")
            _run_concurrently([e for _, e in steps if e], run, "evaluate")
        else:
            for job in (j for step in steps for j in step if j):
                if ctx.progress:
                    print(f"study: {job[0]}", flush=True)
                job[1](ctx=run)
    tables = []
    colmap = {key: key for key in spec.grid}
    for p in plan:
        results = out / "results" / p.eid
        table = read_results(results)
        frames = {(f["scene"], f["viewpoint"]): f["path"] for f in read_frames(results) or []}
        table = table.assign(render_s=[_render_seconds(frames.get((s, v), ""))
                                       for s, v in zip(table.scene, table.viewpoint, strict=True)])
        colmap = {key: grid_column(key, table.columns) for key in spec.grid}
        for key in reversed(list(spec.grid)):
            if colmap[key] in table.columns:  # e.g. width: the results' own column, the same value
                table = table.drop(columns=colmap[key])
            table.insert(0, colmap[key], _cell(p.point[key]))
        tables.append(table)
    study = pd.concat(tables, ignore_index=True)
    csv = study.to_csv(index=False)
    atomic_write_text(out / "study.csv", csv)
    plots = {}
    for key in spec.grid:
        name = f"{key}.png"
        atomic_write_bytes(out / name, plot_metric(study, colmap[key], metric))
        plots[key] = name
    atomic_write_text(out / "study.md", study_markdown(spec, study, metric, plots, time.time() - started,
                                                       [colmap[k] for k in spec.grid]))
    mark_output(out, "study")
    return study


def _check_size(spec: StudySpec, plan: list[PointPlan], out: Path, yes: bool) -> None:
    """Count the frames still to render (distinct data roots, frames not complete on disk) and estimate their
    rendering; say so past :data:`NOTICE_FRAMES`, refuse past the limits without ``yes``."""
    todo, seconds, roots = 0, 0.0, {}
    for p in plan:
        roots.setdefault(p.rid, p.render)
    for rid, render in roots.items():
        missing = sum(not is_complete(frame_dir(out / "data" / rid, render.scene_dir, f"vp{i:03d}"))
                      for i in range(render.viewpoints))
        todo += missing
        seconds += missing * frame_seconds(render)
    evaluations = sum(not _complete(out / "results" / p.eid) for p in plan)
    what = (f"{spec.path}: {len(plan)} grid point(s), {todo} frame(s) to render (about {_duration(seconds)} "
            f"on 2 cores), {evaluations} evaluation(s)")
    if (todo > LIMIT_FRAMES or seconds > LIMIT_RENDER_S) and not yes:
        raise UserError(f"{what}: more than {LIMIT_FRAMES} frames or {_duration(LIMIT_RENDER_S)} of rendering; "
                        "pass --yes to start it")
    if todo > NOTICE_FRAMES:
        print(f"study: {what.split(': ', 1)[1]}", flush=True)


def _render_point(p: PointPlan, data: Path, ctx: RunContext) -> list[Path]:
    """Render one point's frames into its data root (a study's data roots are named by what decides the frames,
    so frames there rendered otherwise come from another version of tri360: say what to do, not ``--force``)."""
    try:
        return render_frames(p.render.settings, **p.render_kw, out_root=data, ctx=ctx)
    except SettingsMismatch as exc:
        raise UserError(f"{exc.frame_dir} holds a frame rendered with other settings: {'; '.join(exc.diffs)}; "
                        f"the study's data root {data} was rendered by another version of tri360: remove that "
                        "directory (tri360 wrote it) to render it again, or choose another --out") from None


def _complete(results: Path) -> bool:
    """A results set that a finished evaluation left (reused as it is)."""
    return (results / "results.csv").is_file() and (results / "config.json").is_file()


def _run_concurrently(jobs: list[tuple[str, Callable]], ctx: RunContext, what: str) -> None:
    """Run every ``(name, job)`` at once from threads of this process (at most ``MAX_PARALLEL_POINTS`` at a
    time), each job as ``job(ctx=...)`` on ``ctx``'s open Dask executor without progress of its own, so the Dask
    tasks of every grid point share the cluster's workers; one bar counts finished points.

    When jobs fail, the first in plan order is raised (naming how many others failed) after the rest have
    finished, so their frames and results are kept for a rerun.  Ctrl-C closes the Dask client, which cancels
    every pending task, and returns at once.
    """
    if not jobs:
        return
    errors: dict[int, BaseException] = {}
    pool = ThreadPoolExecutor(max_workers=min(len(jobs), MAX_PARALLEL_POINTS), thread_name_prefix="study")
    try:
        with progress_bar(len(jobs), desc=f"study {what} (dask)", unit="point", enabled=ctx.progress) as bar:
            futures = {pool.submit(job, ctx=ctx.quiet()): i for i, (_, job) in enumerate(jobs)}
            for fut in as_completed(futures):
                if fut.exception() is not None:
                    errors[futures[fut]] = fut.exception()
                bar.set_postfix_str(jobs[futures[fut]][0].split(" -> ")[0])
                bar.update(1)
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        ctx.where.close()  # cancels the submitted Dask tasks; the threads waiting on them return
        raise
    pool.shutdown(wait=True)
    if errors:
        first = min(errors)
        exc = errors[first]
        if len(errors) > 1 and isinstance(exc, UserError):
            raise UserError(f"{exc} (and {len(errors) - 1} more grid point(s) failed)") from exc
        raise exc


def _x_values(values: Sequence) -> tuple[list, bool]:
    numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)
    return list(values), numeric


def plot_metric(study: pd.DataFrame, key: str, metric: str = DEFAULT_METRIC) -> bytes:
    """PNG: ``metric`` against ``key``, one line per method (mean over frames and other grid keys), min-max band."""
    fig = Figure(figsize=(6.4, 4.2))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    order = list(dict.fromkeys(study[key].tolist()))
    values, numeric = _x_values(order)
    xs = values if numeric else list(range(len(values)))
    for method, sub in study.groupby("method", sort=False):
        stats = sub.groupby(key, sort=False)[metric].agg(["mean", "min", "max"]).reindex(order)
        line = ax.plot(xs, stats["mean"].to_numpy(float), marker="o", label=method)[0]
        ax.fill_between(xs, stats["min"].to_numpy(float), stats["max"].to_numpy(float), color=line.get_color(),
                        alpha=0.15, linewidth=0)
    if not numeric:
        ax.set_xticks(xs, [str(v) for v in values])
    elif min(values) > 0 and max(values) / min(values) > 10:  # e.g. samples 4..64: a log axis, ticks at the values
        ax.set_xscale("log", base=2)
        ax.set_xticks(values, [f"{v:g}" for v in values])
        ax.minorticks_off()
    ax.set_xlabel(key)
    ax.set_ylabel(f"{metric} (m)" if metric.endswith("_m") else metric)
    n_frames = study.groupby(["scene", "viewpoint"]).ngroups
    ax.set_title(f"{metric} vs {key} (mean over {n_frames} frame(s); band: min-max)", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return png_bytes(fig)


def _fmt(x) -> str:
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else (f"{x:.4f}" if isinstance(x, float) else
                                                                              str(x))


def study_markdown(spec: StudySpec, study: pd.DataFrame, metric: str, plots: dict[str, str], seconds: float,
                   keys: list[str]) -> str:
    """The text of ``study.md``; ``keys``: the study.csv columns of the grid keys."""
    group = [*keys, "method"]
    agg = study.groupby(group, sort=False).agg(mean=(metric, "mean"), lo=(metric, "min"), hi=(metric, "max"),
                                               frames=(metric, "size"), render_s=("render_s", "mean"))
    lines = [f"# Study `{spec.path.name}`", "",
             f"{len(study)} rows (grid points x frames x methods) in `study.csv`; metric `{metric}` (mean over "
             f"frames, min-max in brackets); `render_s`: mean render wall time per frame, seconds (from each "
             f"frame's `{RENDER_LOG}`). Written in {seconds:.0f} s (reused frames and results included).", "",
             "```toml", spec.text.strip(), "```", "",
             "| " + " | ".join([*group, metric, "min-max", "frames", "render_s"]) + " |",
             "|" + "---|" * (len(group) + 4)]
    for idx, r in agg.iterrows():
        idx = idx if isinstance(idx, tuple) else (idx,)
        lines.append("| " + " | ".join([*(str(v) for v in idx), _fmt(r["mean"]),
                                         f"{_fmt(r['lo'])}-{_fmt(r['hi'])}", str(int(r["frames"])),
                                         _fmt(float(r["render_s"])) if np.isfinite(r["render_s"]) else ""]) + " |")
    for key, name in plots.items():
        lines += ["", f"## {metric} vs {key}", "", f"![{metric} vs {key}]({name})"]
    return "\n".join(lines) + "\n"
