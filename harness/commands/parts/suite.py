"""Suite jobs: render a suite's split, and check that a data root holds exactly it before evaluating or scoring.

``tri360 render --suite suites/tri360-v1.toml --split dev --out data/dev`` renders every frame of the split
(``harness.data.suite``: family, preset, parameters, seed, viewpoints, rig) into ``<out>/<group name>/vpNNN``,
with the machinery of every render (``harness.commands.render``): resumable (complete frames rendered with the same
settings are kept, others refused naming the difference unless ``force``), atomic frames, and on a Dask
cluster (the run context's) one Dask task per frame.

A twin under a condition (``<group>.<condition>/vpNNN``) is derived from its rendered frame after that frame is
rendered (:func:`harness.commands.parts.captured.captured_twin`) and records its source's SHA-256
(:func:`harness.commands.perturb.source_record`).  A rerun keeps a complete twin that matches its derivation
(:func:`twin_problem`) and derives again, from the frame now stored, a twin whose source is rendered in this run or
which no longer matches (a twin is a function of its source, the condition and its seed: nothing is lost); a twin
derived with other condition settings is refused like any frame rendered otherwise.

``tri360 evaluate DATA --suite FILE --split dev`` (and ``score``) first checks, reading only the ``frame.json``
files, that the data root holds exactly the split's frames rendered with the suite's settings (the same
comparison a rerun of ``render`` makes) and refuses, naming the frame, when a frame is missing, extra, or was
rendered otherwise; each twin must also match its derivation (its source's hash, every camera's photometric
record, its told poses: :func:`twin_problem`).  The results then carry the suite's id and split (``config.json``'s
``suite`` entry and the ``suite_id``/``split`` columns), and each row its family and difficulty tags, so the
leaderboard gets a column per family and per tag.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from harness.commands.evaluate import FrameRef, evaluate, select_frames
from harness.commands.parts.captured import calibration_error, captured_twin, twin_generator
from harness.commands.perturb import frame_hash, source_record
from harness.commands.render import DEFAULTS, RenderItem, check_width, differences, render_items
from harness.commands.score import score
from harness.commands.study import LIMIT_FRAMES
from harness.data.atomic import clean_stale_partials
from harness.data.errors import FrameError, UserError
from harness.data.frame import frame_dir, is_complete, parse_photometric, read_frame, write_frame
from harness.data.outputs import check_output, ensure_output_dir, mark_output
from harness.data.suite import IDEAL, Suite, SuiteFrame, load_suite
from harness.render.base import RenderSettings, identity
from harness.render.registry import get_renderer
from harness.runtime.context import IN_PROCESS, RunContext
from harness.runtime.progress import progress_bar
from reconstruction.camera.rig import CAMERA_NAMES, CameraPose, Rig
from reconstruction.methods.base import Method
from scenes.model import SceneSpec, choose_viewpoints
from scenes.registry import discover

__all__ = ["PlannedFrame", "load", "plan", "render_planned", "derive_twins",
           "render_suite", "check_suite_data", "twin_problem", "evaluate_suite",
           "score_suite"]

TWIN_TOLERANCE = 1e-9
"""Relative tolerance of a twin's recorded numbers against their derivation (float64 rounding, not a draw)."""


@dataclass(frozen=True)
class PlannedFrame:
    """A suite frame as it is to be rendered: the scene, rig, renderer, settings and the identity it records."""

    frame: SuiteFrame
    spec: SceneSpec
    rig: Rig
    renderer: str
    settings: RenderSettings
    identity: dict


def load(path: Path) -> Suite:
    """:func:`harness.data.suite.load_suite` with tri360's render defaults (``harness.commands.render.DEFAULTS``)."""
    return load_suite(Path(path), dataclasses.asdict(DEFAULTS), discover()[0])


def settings_for(suite: Suite, seed: int, threads: int = 0) -> RenderSettings:
    """The render settings of a suite frame group (the suite's, its seed, this machine's threads)."""
    try:
        settings = RenderSettings(**{**suite.render, "seed": int(seed), "threads": int(threads)})
        settings.check()
    except ValueError as exc:
        raise UserError(f"{suite.path}: [render]: {exc}") from None
    return settings


def plan(suite: Suite, split: str, threads: int = 0) -> list[PlannedFrame]:
    """Every frame of ``split``: scenes built, rigs placed (``choose_viewpoints`` with the group's baseline,
    height range and tilt), in file order.

    Raises:
        UserError: a render setting no renderer accepts, a width the reconstruction cannot use, a scene the
            renderer cannot draw, or too few free rig placements (naming the group).
        SceneError: a family that fails to build.
    """
    frames = suite.frames(split)
    check_width(int(suite.render["width"]))
    out, entries = [], []
    scenes = discover()[0]
    for f in frames:
        if f.entry not in entries:
            entries.append(f.entry)
    for e in entries:
        settings = settings_for(suite, e.seed, threads)
        scene = scenes[e.family]
        spec = scene.build_spec(e.preset, e.seed, dict(e.params))
        backend = get_renderer(e.renderer)
        reason = backend.unsupported(spec)
        if reason:
            raise UserError(f"{suite.path}: {e.name}: renderer {e.renderer!r} cannot draw {e.family}: {reason}")
        try:
            rigs = choose_viewpoints(spec, e.viewpoints, e.seed, baseline_m=e.rig.baseline_m,
                                     tilt_max_rad=e.rig.tilt_max_rad, height_range=e.rig.height_m)
        except ValueError as exc:
            raise UserError(f"{suite.path}: {e.name}: {exc}") from None
        ident = identity(e.renderer, backend.pixel_settings, settings, spec, e.rig.baseline_m)
        out += [PlannedFrame(SuiteFrame(e, i), spec, rig, e.renderer, settings, ident) for i, rig in enumerate(rigs)]
    rendered = {(p.frame.entry.name, p.frame.index): p for p in out}
    twins = [dataclasses.replace(rendered[(f.entry.name, f.index)], frame=f) for f in frames if f.condition != IDEAL]
    return out + twins


def _read_meta(d: Path) -> dict:
    try:
        return json.loads((d / "frame.json").read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"{d / 'frame.json'}: unreadable ({exc})") from None


def _stored_differences(meta: dict, p: PlannedFrame, suite: Suite) -> list[str]:
    """What differs between a stored frame (its ``frame.json``) and the planned one (a twin: also its condition
    record and the frame it came from)."""
    condition = p.frame.condition
    record = meta.get("renderer", {}).get("condition") if isinstance(meta.get("renderer"), dict) else None
    if condition == IDEAL:
        if record is not None:
            return [f"condition {record.get('name') if isinstance(record, dict) else record!r} (now ideal)"]
        return differences(meta, p.identity, p.rig)
    want = {"name": condition, "seed": p.frame.twin_seed,
            "distribution": json.loads(json.dumps(suite.conditions[condition].to_json()))}
    if not isinstance(record, dict):
        return [f"no {condition} condition recorded (now {condition})"]
    out = [f"condition {k} {record.get(k)!r} (now {v!r})" for k, v in want.items() if record.get(k) != v]
    try:  # compare the rendered frame it came from: the true poses of U and R, C's told pose
        source = {**meta, "renderer": {k: v for k, v in meta["renderer"].items() if k != "condition"},
                  "cameras": {**meta["cameras"], **record["true_cameras"]}, "baseline_m": record["true_baseline_m"]}
    except (KeyError, TypeError, AttributeError):
        return [*out, "the condition record has no true_cameras"]
    return out + differences(source, p.identity, p.rig)


def _close(a, b) -> bool:
    """Whether two JSON values are equal, floats within :data:`TWIN_TOLERANCE` (relative, at least absolute)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b, strict=True))
    numbers = [isinstance(x, int | float) and not isinstance(x, bool) for x in (a, b)]
    if all(numbers) and (isinstance(a, float) or isinstance(b, float)):
        return abs(a - b) <= TWIN_TOLERANCE * max(1.0, abs(a), abs(b))
    return a == b


def _pose(raw) -> CameraPose:
    pose = CameraPose(np.asarray(raw["position"], np.float64), np.asarray(raw["rotation"], np.float64))
    if pose.position.shape != (3,) or pose.rotation.shape != (3, 3):
        raise ValueError("not a pose")
    return pose


def _same_pose(a: CameraPose, b: CameraPose) -> bool:
    return bool(np.allclose(a.position, b.position, rtol=0.0, atol=TWIN_TOLERANCE)
                and np.allclose(a.rotation, b.rotation, rtol=0.0, atol=TWIN_TOLERANCE))


def twin_problem(meta: dict, p: PlannedFrame, suite: Suite, source_dir: Path) -> str | None:
    """What is wrong with a stored twin whose condition record and true poses match the suite
    (:func:`_stored_differences` found nothing), or None.

    Checked, against the source frame stored in ``source_dir`` and the condition's draw for the twin's seed (cheap:
    no image is derived again): the source's SHA-256 (:func:`harness.commands.perturb.frame_hash`) is the one the
    twin recorded; every camera (C, U, R) has the photometric record the condition draws; the recorded calibration
    error is the draw and U's and R's told poses are their true poses with it (so a twin whose told poses were
    reset to the true ones is refused); ``baseline_m`` is the mean of the told ``|U - C|`` and ``|R - C|``.

    Args:
        meta: the twin's parsed ``frame.json``.  p: the planned twin.  suite: its suite.
        source_dir: the directory of the rendered frame the twin is derived from.
    """
    condition, seed = p.frame.condition, p.frame.twin_seed
    dist = suite.conditions[condition]
    record = meta["renderer"]["condition"]
    source = p.frame.source.label
    recorded = record.get("source")
    if not (isinstance(recorded, dict) and isinstance(recorded.get("sha256"), str)):
        return f"it records no hash of its source frame {source} (renderer.condition.source.sha256)"
    now = frame_hash(source_dir)
    if recorded["sha256"] != now:
        return (f"its source frame {source} changed after the twin was derived (its files' sha256 is now "
                f"{now[:16]}..., the twin recorded {recorded['sha256'][:16]}...)")
    try:
        photometric = parse_photometric(meta, Path("frame.json"))
    except FrameError as exc:
        return str(exc).removeprefix("frame.json: ")
    for k in CAMERA_NAMES:
        if k not in photometric:
            return (f"cameras.{k} has no photometric record (the {condition} condition draws one for every camera: "
                    f"{', '.join(CAMERA_NAMES)})")
        if not _close(photometric[k].to_json(), dist.draw(twin_generator(seed, "photometric", k)).to_json()):
            return f"cameras.{k}.photometric is not the {condition} condition's draw for seed {seed}"
    try:
        told = {k: _pose(meta["cameras"][k]) for k in CAMERA_NAMES}
        true = {"C": told["C"], **{k: _pose(record["true_cameras"][k]) for k in ("U", "R")}}
    except (KeyError, TypeError, ValueError):
        return "its told poses or renderer.condition.true_cameras are not poses"
    want, drawn = calibration_error(true, dist, seed)
    if not _close(record.get("calibration_error"), json.loads(json.dumps(drawn))):
        return f"renderer.condition.calibration_error is not the {condition} condition's draw for seed {seed}"
    for k in ("U", "R"):
        if _same_pose(told[k], want[k]):
            continue
        error = ", ".join(f"{v['degrees']:.3g} degrees" if part == "rotation" else f"{v['mm']:.3g} mm"
                          for part, v in drawn.get(k, {}).items()) or "none"
        if _same_pose(told[k], true[k]):
            return (f"the told pose of {k} is its true pose, but the recorded calibration error of {k} ({error}) "
                    "says it is off")
        return f"the told pose of {k} is not its true pose with the recorded calibration error of {k} ({error})"
    mean = float(np.mean([np.linalg.norm(told[k].position - told["C"].position) for k in ("U", "R")]))
    if not _close(meta.get("baseline_m"), mean):
        return f"baseline_m {meta.get('baseline_m')!r} is not the mean of the told |U - C| and |R - C| ({mean:.9g})"
    return None


def render_suite(path: Path, split: str, out_root: Path, threads: int = DEFAULTS.threads, force: bool = False,
                 ctx: RunContext = IN_PROCESS, yes: bool = False) -> list[Path]:
    """Render every frame of a suite's split into ``out_root`` (resumable); return the frame directories.

    A split with more than :data:`harness.commands.study.LIMIT_FRAMES` frames still to render (not complete in
    ``out_root``; all of them with ``force``) needs ``yes``, as ``tri360 study`` does; this is checked from the
    suite file before any scene is built.

    Args:
        path: the suite file.  split: ``"dev"``, ``"test"`` or ``"train"`` (:data:`harness.data.suite.SPLITS`).
        out_root: the data root (one per split: ``evaluate --suite`` wants exactly the split's frames in it).
        threads: Cycles threads, 0 = all (a machine setting, not part of the suite).
        force: re-render complete frames whatever they were rendered with.
        ctx: where the frames render (one Dask task per frame with ``--workers`` / ``--scheduler``), progress
            and Blender's log (see :func:`harness.commands.render.render_frames`).
        yes: start a render of more than :data:`~harness.commands.study.LIMIT_FRAMES` frames.
    Raises:
        UserError: too many frames without ``yes``; see :func:`plan`; an existing frame rendered with other
            settings (naming it and the differences; use ``force``); an unwritable output; a renderer failure.
    """
    if threads < 0:
        raise UserError(f"--threads must be >= 0 (0 = all cores), got {threads}")
    ctx.check()
    suite = load(path)
    todo_count = sum(force or not is_complete(frame_dir(Path(out_root), f.scene, f.viewpoint))
                     for f in suite.frames(split))
    if todo_count > LIMIT_FRAMES and not yes:
        raise UserError(f"{suite.path}: split {split}: {todo_count} frame(s) to render into {out_root}, more than "
                        f"{LIMIT_FRAMES} frames; pass --yes to start it")
    planned = plan(suite, split, threads)
    out_root = check_output(Path(out_root), "data")  # absent, empty or a data root tri360 wrote
    todo = []
    rendering = set()  # the directories of the rendered frames this run writes: their twins are derived again
    for p in planned:
        d = frame_dir(out_root, p.frame.scene, p.frame.viewpoint)
        source = frame_dir(out_root, p.frame.source.scene, p.frame.viewpoint)
        if not force and is_complete(d):
            meta = _read_meta(d)
            diff = _stored_differences(meta, p, suite)
            if diff:
                raise UserError(f"{d} holds a frame rendered with other settings than suite {suite.name} "
                                f"({suite.id}) asks: {'; '.join(diff)}; use --force to re-render it or choose "
                                "another --out")
            if p.frame.condition == IDEAL or (
                    source not in rendering and twin_problem(meta, p, suite, source) is None):
                continue
        todo.append(p)
        if p.frame.condition == IDEAL:
            rendering.add(d)
    dirs = [frame_dir(out_root, p.frame.scene, p.frame.viewpoint) for p in planned]
    scene_dirs = [out_root / scene for scene in dict.fromkeys(p.frame.scene for p in planned)]
    created = [d for d in (*scene_dirs, out_root, *out_root.parents) if not d.exists()]
    for d in scene_dirs:
        ensure_output_dir(d)
    clean_stale_partials(out_root)  # hidden half-written frames and files of killed runs, anywhere in the root
    rendered_todo = [p for p in todo if p.frame.condition == IDEAL]
    twins_todo = [p for p in todo if p.frame.condition != IDEAL]
    if not todo:
        mark_output(out_root, "data")
        return dirs
    try:
        if rendered_todo:
            render_planned(suite, split, rendered_todo, out_root, ctx)
        mark_output(out_root, "data")
        if twins_todo:
            derive_twins(suite, split, twins_todo, out_root, ctx)
    except BaseException:
        for d in created:  # an interrupted first render leaves no empty directories behind
            try:
                d.rmdir()
            except OSError:
                pass
        raise
    return dirs


def derive_twins(suite: Suite, split: str, todo: list[PlannedFrame], out_root: Path, ctx: RunContext) -> None:
    """Write each twin (:func:`harness.commands.parts.captured.captured_twin`) of a rendered frame of ``out_root``."""
    with progress_bar(len(todo), f"{suite.name} {split}: twins", enabled=ctx.progress) as bar:
        for p in todo:
            src = frame_dir(out_root, p.frame.source.scene, p.frame.viewpoint)
            frame = read_frame(src)
            twin = captured_twin(frame, suite.conditions[p.frame.condition], p.frame.twin_seed, p.frame.condition,
                                 source=source_record(src))
            twin.scene = p.frame.scene
            write_frame(twin, out_root)
            bar.update(1)


def render_planned(suite: Suite, split: str, todo: list[PlannedFrame], out_root: Path, ctx: RunContext) -> None:
    """Render the planned ideal frames ``todo`` of ``suite``'s ``split`` into ``out_root`` (:func:`harness.commands.
    render.render_items`: where ``ctx`` says, with its progress)."""
    items = [RenderItem(p.renderer, p.spec, p.settings, p.rig, p.frame.scene, p.frame.viewpoint) for p in todo]
    render_items(items, out_root, f"{suite.name} {split}", ctx)


def check_suite_data(suite: Suite, split: str, data_root: Path) -> list[FrameRef]:
    """The frames of ``data_root`` if it holds exactly the split's frames rendered with the suite's settings.

    Raises:
        UserError: naming the first frame that is missing, extra (not in the split) or rendered with other
            settings (and how), the ``frame.json`` of the first twin that does not match its derivation (and what,
            :func:`twin_problem`), or anything :func:`harness.commands.evaluate.select_frames` refuses.
    """
    data_root = Path(data_root)
    refs = select_frames(data_root)
    by_key = {(r.scene, r.viewpoint): r for r in refs}
    frames = {(f.scene, f.viewpoint): f for f in suite.frames(split)}  # from the file: no scene built yet
    how = f"render it with `tri360 render --suite {suite.path} --split {split} --out {data_root}`"
    for key, f in frames.items():
        if key not in by_key:
            raise UserError(f"{data_root / f.scene / f.viewpoint}: frame {f.label} of suite "
                            f"{suite.name} (split {split}) is missing from the data root; {how}")
    for r in refs:
        if (r.scene, r.viewpoint) not in frames:
            raise UserError(f"{r.path}: frame {r.scene}/{r.viewpoint} is not in suite {suite.name} split {split}; "
                            "the data root must hold exactly the split's frames (render each split into a data "
                            "root of its own)")
    wanted = {(p.frame.scene, p.frame.viewpoint): p for p in plan(suite, split)}
    for key, p in wanted.items():
        d = by_key[key].path
        meta = _read_meta(d)
        diff = _stored_differences(meta, p, suite)
        if diff:
            raise UserError(f"{d}: frame {p.frame.label} was not rendered with the settings of suite "
                            f"{suite.name} ({suite.id}): {'; '.join(diff)}")
        if p.frame.condition != IDEAL:
            problem = twin_problem(meta, p, suite, by_key[(p.frame.source.scene, p.frame.viewpoint)].path)
            if problem:
                raise UserError(f"{d / 'frame.json'}: twin {p.frame.label} does not match its derivation: {problem}; "
                                f"derive it again with `tri360 render --suite {suite.path} --split {split} --out "
                                f"{data_root}`")
    return [by_key[k] for k in wanted]


def evaluate_suite(data_root: Path, path: Path, split: str, out: Path, methods: Sequence[Method],
                   report: bool = True, ctx: RunContext = IN_PROCESS) -> pd.DataFrame:
    """:func:`harness.commands.evaluate.evaluate` on a suite's split, after :func:`check_suite_data`; the results
    carry the suite id and split."""
    suite = load(path)
    check_suite_data(suite, split, data_root)
    return evaluate(data_root, out, methods, report=report, ctx=ctx,
                    suite=suite.describe(split))


def score_suite(pred_roots: Sequence[Path], data_root: Path, path: Path, split: str, out: Path,
                names: Sequence[str] | None = None, report: bool = True,
                ctx: RunContext = IN_PROCESS) -> pd.DataFrame:
    """:func:`harness.commands.score.score` on a suite's split, after :func:`check_suite_data`."""
    suite = load(path)
    check_suite_data(suite, split, data_root)
    return score(pred_roots, data_root, out, names, report=report, ctx=ctx,
                 suite=suite.describe(split))
