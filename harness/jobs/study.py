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

Reuse: the hashes are of the settings themselves (and of the render defaults, :func:`point_ids`), so a rerun, or an
extended grid, renders only frames that are missing (``render_frames`` is resumable and checks that stored frames
were rendered with the same settings) and evaluates only points without a complete results set. With a cluster
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

from harness.data import jsonio
from harness.data.atomic import atomic_write_bytes, atomic_write_text
from harness.data.errors import UserError
from harness.data.outputs import check_output, ensure_output_dir, mark_output
from harness.jobs.cluster import ClusterOptions, open_executor
from harness.jobs.evaluate import evaluate
from harness.jobs.progress import progress_bar
from harness.jobs.render import DEFAULTS, RENDER_LOG, render_frames
from reconstruction.methods.flow_pipeline import DEFAULT_FLOW
from reconstruction.methods.registry import default_methods, flow_methods, get_methods
from reports.plots import png_bytes
from reports.schema import METRIC_COLUMNS

__all__ = ["RENDER_KEYS", "EVALUATE_KEYS", "StudySpec", "load_study", "grid_points", "run_study", "plot_metric"]

RENDER_KEYS = ("scene", "renderer", "viewpoints", "width", "samples", "seed", "threads", "baseline", "max_bounces",
               "light_tree", "no_denoise", "set")
"""Keys of ``[render]`` (``tri360 render`` options, dashes as underscores; ``set`` is a table or KEY=VALUE list)."""
EVALUATE_KEYS = ("method", "flow", "variants", "rectify", "report")
"""Keys of ``[evaluate]`` (``tri360 evaluate`` options; ``report`` defaults to false in a study)."""
DEFAULT_METRIC = "mae_m"
#: grid points rendered or evaluated at once on a cluster (threads of this process that submit their tasks)
MAX_PARALLEL_POINTS = 32


class StudySpec:
    """A parsed, checked study file: ``render`` and ``evaluate`` settings and the ``grid`` (key -> values)."""

    def __init__(self, path: Path, render: dict, evaluate: dict, grid: dict[str, list], text: str):
        self.path, self.render, self.evaluate, self.grid, self.text = path, render, evaluate, grid, text


def load_study(path: Path) -> StudySpec:
    """Read and check a study TOML.

    Raises:
        UserError: unreadable or malformed TOML, an unknown section or key (naming the allowed ones), or a
            ``[grid]`` entry that is not a non-empty list.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{path}: study file does not exist") from None
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{path}: not valid TOML ({exc})") from None
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


def point_ids(render: dict, evaluate_: dict, defaults: dict | None = None) -> tuple[str, str]:
    """``("r-<hash>", "e-<hash>")``: the names of a point's data root and results set.

    The render hash covers the point's ``[render]`` settings and the render defaults they leave to tri360
    (``harness.jobs.render.DEFAULTS``): when a default changes (e.g. the samples), a rerun renders into a new
    data root instead of failing on frames rendered the old way.
    """
    key = {"render": render, "defaults": dataclasses.asdict(DEFAULTS) if defaults is None else defaults}
    return "r-" + _digest(key), "e-" + _digest({**key, "evaluate": evaluate_})


def _overrides(value, where: str) -> dict:
    if value is None:
        return {}
    if isinstance(value, dict):
        return dict(value)
    if isinstance(value, list) and all(isinstance(v, str) and "=" in v for v in value):
        out = {}
        for item in value:
            k, _, raw = item.partition("=")
            try:
                out[k] = json.loads(raw)
            except json.JSONDecodeError:
                out[k] = raw
        return out
    raise UserError(f"{where}: 'set' must be a table of scene parameters or a list of \"KEY=VALUE\" strings")


def render_kwargs(settings: dict, where: str) -> dict:
    """``[render]`` settings -> keyword arguments of :func:`harness.jobs.render.render_frames`."""
    kw = {}
    for key, value in settings.items():
        if key == "scene":
            kw["scene_name"] = value
        elif key == "no_denoise":
            kw["denoise"] = not bool(value)
        elif key == "set":
            kw["overrides"] = _overrides(value, where)
        else:
            kw[key] = value
    return kw


def select_methods(settings: dict, where: str) -> list:
    """``[evaluate]`` settings -> methods, as ``tri360 evaluate`` selects them."""
    method, flow = settings.get("method"), settings.get("flow")
    variants, rectify = settings.get("variants"), settings.get("rectify")

    def as_list(v):
        return None if v is None else ([v] if isinstance(v, str) else list(v))

    try:
        if method is not None:
            if flow is not None or variants is not None or rectify is not None:
                raise UserError(f"{where}: 'method' selects methods by label; do not combine it with flow, "
                                "variants or rectify")
            return get_methods(as_list(method))
        if flow is None and variants is None and rectify is None:
            return default_methods()
        return flow_methods(as_list(flow) or [DEFAULT_FLOW], [True if rectify is None else bool(rectify)],
                            as_list(variants))
    except ValueError as exc:
        raise UserError(f"{where}: {exc}") from None


def _point_settings(spec: StudySpec, point: dict) -> tuple[dict, dict]:
    render = {**spec.render, **{k: v for k, v in point.items() if k in RENDER_KEYS}}
    evaluate_ = {**spec.evaluate, **{k: v for k, v in point.items() if k in EVALUATE_KEYS}}
    return render, evaluate_


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


def run_study(study_path: Path, out: Path, cluster: ClusterOptions | None = None, metric: str = DEFAULT_METRIC,
              progress: bool = True) -> pd.DataFrame:
    """Run (or resume, or extend) a study; write ``study.csv``, one plot per grid key and ``study.md`` to ``out``.

    Returns:
        The ``study.csv`` table.
    Raises:
        UserError: a malformed study file, an unknown metric, or anything ``render``/``evaluate`` refuses.
    """
    started = time.time()
    spec = load_study(study_path)
    check_output(Path(out), "study", [study_path])  # absent, empty or a study tri360 wrote; not around the file
    if metric not in METRIC_COLUMNS:
        raise UserError(f"unknown metric {metric!r}; choose one of {', '.join(METRIC_COLUMNS)}")
    points = grid_points(spec)
    plan = []
    for point in points:
        render, evaluate_ = _point_settings(spec, point)
        where = f"{spec.path} (grid point {point or 'the only one'})"
        kw = render_kwargs(render, where)
        methods = select_methods(evaluate_, where)
        rid, eid = point_ids(render, evaluate_)
        plan.append((point, kw, methods, bool(evaluate_.get("report", False)), rid, eid))
    out = ensure_output_dir(Path(out))
    atomic_write_text(out / "points.json", jsonio.dumps(
        [{"grid": p, "data": f"data/{rid}", "results": f"results/{eid}"} for p, _, _, _, rid, eid in plan]))
    with open_executor(cluster) as ex:
        steps = []  # per point: (render job or None, evaluate job or None); a job is (name, callable)
        rendered = set()
        for point, kw, methods, report, rid, eid in plan:
            data, results = out / "data" / rid, out / "results" / eid
            render = None if rid in rendered else (f"render {point or ''} -> {data}",
                                                   partial(render_frames, out_root=data, cluster=ex, **kw))
            rendered.add(rid)
            if _complete(results):
                if progress:
                    print(f"study: reuse {results}", flush=True)
                steps.append((render, None))
                continue
            steps.append((render, (f"evaluate {point or ''} -> {results}",
                                   partial(evaluate, data, results, methods, report=report, cluster=ex))))
        if getattr(ex, "distributed", False):
            _run_concurrently([r for r, _ in steps if r], ex, progress, "render")
            _run_concurrently([e for _, e in steps if e], ex, progress, "evaluate")
        else:
            for job in (j for step in steps for j in step if j):
                if progress:
                    print(f"study: {job[0]}", flush=True)
                job[1](progress=progress)
    tables = []
    colmap = {key: key for key in spec.grid}
    for point, _kw, _methods, _report, _rid, eid in plan:
        results = out / "results" / eid
        table = pd.read_csv(results / "results.csv", keep_default_na=False, na_values=[""])
        frames = {(f["scene"], f["viewpoint"]): f["path"]
                  for f in json.loads((results / "frames.json").read_text(encoding="utf-8"))}
        table = table.assign(render_s=[_render_seconds(frames.get((s, v), ""))
                                       for s, v in zip(table.scene, table.viewpoint, strict=True)])
        colmap = {key: grid_column(key, table.columns) for key in spec.grid}
        for key in reversed(list(spec.grid)):
            if colmap[key] in table.columns:  # e.g. width: the results' own column, the same value
                table = table.drop(columns=colmap[key])
            table.insert(0, colmap[key], _cell(point[key]))
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


def _complete(results: Path) -> bool:
    """A results set that a finished evaluation left (reused as it is)."""
    return (results / "results.csv").is_file() and (results / "config.json").is_file()


def _run_concurrently(jobs: list[tuple[str, Callable]], ex, progress: bool, what: str) -> None:
    """Run every ``(name, job)`` at once from threads of this process (at most ``MAX_PARALLEL_POINTS`` at a
    time), so the Dask tasks of every grid point share the cluster's workers; one bar counts finished points.

    When jobs fail, the first in plan order is raised (naming how many others failed) after the rest have
    finished, so their frames and results are kept for a rerun.  Ctrl-C closes the Dask client, which cancels
    every pending task, and returns at once.
    """
    if not jobs:
        return
    errors: dict[int, BaseException] = {}
    pool = ThreadPoolExecutor(max_workers=min(len(jobs), MAX_PARALLEL_POINTS), thread_name_prefix="study")
    try:
        with progress_bar(len(jobs), desc=f"study {what} (dask)", unit="point", enabled=progress) as bar:
            futures = {pool.submit(job, progress=False): i for i, (_, job) in enumerate(jobs)}
            for fut in as_completed(futures):
                if fut.exception() is not None:
                    errors[futures[fut]] = fut.exception()
                bar.set_postfix_str(jobs[futures[fut]][0].split(" -> ")[0])
                bar.update(1)
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        ex.close()  # cancels the submitted Dask tasks; the threads waiting on them return
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
