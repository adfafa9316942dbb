"""The render command: render frames of a registered scene into a data root.

Library use::

    >>> from harness.commands.render import render_frames                                        # doctest: +SKIP
    >>> from harness.render.base import RenderSettings
    >>> dirs = render_frames(RenderSettings(width=256, samples=8), "classroom:small", viewpoints=2, out_root="data")
    >>> dirs = render_frames(RenderSettings(width=256), "box_room", out_root="data", renderer="raycast")

``settings`` (:class:`harness.render.base.RenderSettings`) says how to render, the other arguments what and where;
:func:`plan_render` checks all of it (types and ranges) and places the rigs without rendering (a study checks
every grid point with it before the first render).

Frames land in ``<out>/<scene>/vp000``, ``vp001``, ... (``<scene>`` is the family name, or
``family-preset`` for a non-default preset).  The renderer is the scene's default (``tri360 scenes``) unless
one is named.  The run is resumable: a frame directory that already reads and validates is skipped when it was
rendered with the same settings, refused (naming every difference) when it was not, and re-rendered with
``force``.  Every frame is written atomically, so an interrupted run never leaves a complete-looking frame
behind.  Blender (``bpy``) is loaded only by the Cycles worker process, never by this one.

``frame.json`` holds only what decides the frame (so two renders of the same frame are byte-identical, wherever
they ran); how long it took goes to ``render_log.json`` beside it (:data:`RENDER_LOG`: the renderer's per-stage
wall times and the host), written after the frame and ignored by every reader.

When ``ctx`` (:class:`harness.runtime.context.RunContext`) runs the tasks on a Dask cluster (``--scheduler`` /
``--workers``, or a study's open executor) each frame is one Dask task: the worker builds the scene, renders the
frame and writes it into the data root itself (which must be on a file system that every worker sees at the same
path); a frame whose worker died is simply rendered again.  Otherwise everything runs in this process with one
renderer for all frames.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import platform
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.data import jsonio
from harness.data.atomic import atomic_write_text, clean_stale_partials
from harness.data.errors import UserError
from harness.data.frame import Frame, frame_dir, is_complete, write_frame
from harness.data.names import check_name
from harness.data.outputs import check_output, ensure_output_dir, mark_output
from harness.render.base import RenderSettings, identity, recorded_identity
from harness.render.registry import get_renderer
from harness.runtime.cluster import BASE_BYTES, MEMORY_SHARE, physical_memory_bytes
from harness.runtime.context import IN_PROCESS, RunContext
from harness.runtime.options import typed_value
from harness.runtime.progress import progress_bar
from reconstruction.camera.rig import CAMERA_NAMES, DEFAULT_BASELINE_M, Rig
from reconstruction.flow.backends import builtin_flows
from reconstruction.params import type_hints
from scenes.model import SceneSpec, choose_viewpoints
from scenes.registry import get_scene

RENDER_LOG = "render_log.json"
"""Sidecar of a rendered frame: wall times per stage (``seconds``: build, C, U, R, total) and the host."""
DEFAULTS = RenderSettings()
"""The render defaults (``harness.render.base.RenderSettings``), the single source for the CLI and this command."""
DEFAULT_SCENE = "classroom"

MIN_WIDTH_BY_FLOW = {b.name: b.min_width for b in builtin_flows()}
"""Smallest even width, pixels, at which each built-in flow backend runs and gives finite output (each backend's
``min_width``, measured with ``reconstruction.flow.matching.match_pair`` (pairs C-U and C-R, forward and backward
flow) on ``tests/helpers.make_synthetic_frame(width)`` for every even width from 8 to 64, then every 4th to 160
(rlof: every even width from 60 to 400), rectified and plain alike).  At 60 and 62 px the whole ``reconstruct``
(every flow, rectified and plain, every variant) gives finite output."""
MIN_WIDTH = max(MIN_WIDTH_BY_FLOW.values())
"""Smallest width ``render`` accepts, pixels: every flow backend can process it."""

# Peak resident memory grows linearly with the pixel count W * W / 2.  Measured as the peak RSS (getrusage
# ru_maxrss) of child processes at 500, 1000 and 2000 px wide (125 k, 500 k, 2 M pixels):
# - reconstruction (``reconstruct`` of a synthetic_box frame, every variant; dis / deepflow / farneback / rlof,
#   rectified and plain): 170-176 MiB, 370-395 MiB, 1290-1304 MiB (dis, deepflow) -> 612 B/px from 500 to 1000 px
#   and 632 B/px from 500 to 2000 px (the widest flow); intercept about 100 MiB;
# - Cycles rendering (classroom, 1 sample, OIDN on): the worker 550, 861, 2120 MiB -> 878 B/px, intercept 445 MiB;
#   this process 91, 100, 137 MiB -> 26 B/px (the frame's arrays); the ray-caster renders in bounded chunks
#   (137 and 169 MiB at 500 and 1000 px: 90 B/px).
RECONSTRUCT_BYTES_PER_PIXEL = 640
"""Peak memory of reconstructing one frame, bytes per pixel of W x W/2 (measured 632, rounded up)."""
RENDER_BYTES_PER_PIXEL = 910
"""Peak memory of rendering one frame with Cycles (worker + this process), bytes per pixel (measured 878 + 26)."""
# BASE_BYTES (memory that does not grow with the width) and MEMORY_SHARE (the share of the physical memory a
# render or reconstruction may plan to use) live in harness.runtime.cluster, which bounds --workers by them too.


def max_width(memory_bytes: int | None = None) -> int:
    """The largest even width whose rendering and (separately) reconstruction fit in ``MEMORY_SHARE`` of
    ``memory_bytes`` (default: the physical memory), from the measured bytes per pixel."""
    memory = physical_memory_bytes() if memory_bytes is None else memory_bytes
    per_pixel = max(RECONSTRUCT_BYTES_PER_PIXEL, RENDER_BYTES_PER_PIXEL)
    pixels = max(0.0, MEMORY_SHARE * memory - BASE_BYTES) / per_pixel  # W * W / 2
    return int(math.sqrt(2 * pixels)) // 2 * 2


def scene_dir_name(family: str, preset: str, default_preset: str) -> str:
    """Directory name of a scene: the family, or ``family-preset`` for a non-default preset."""
    return family if preset == default_preset else f"{family}-{preset}"


def parse_overrides(items: list[str] | None, source: str = "--set") -> dict:
    """``["key=value", ...]`` -> dict; values are parsed as JSON when possible, else kept as strings.

    Raises:
        UserError: an item that is not a ``KEY=VALUE`` string (naming ``source``).
    """
    out = {}
    for item in items or []:
        key, sep, raw = item.partition("=") if isinstance(item, str) else ("", "", "")
        if not sep or not key:
            raise UserError(f"{source} expects KEY=VALUE, got {item!r}")
        try:
            out[key] = json.loads(raw)
        except json.JSONDecodeError:
            out[key] = raw
    return out


def settings_from_options(options: Mapping[str, object]) -> RenderSettings:
    """:class:`RenderSettings` from render options by name -- ``tri360 render``'s, dashes as underscores (the
    command line's parsed arguments, a study's ``[render]``): every field by its own name, and ``no_denoise``
    for ``denoise``; the fields not given keep their defaults (:data:`DEFAULTS`).  Other names are ignored."""
    kw = {f.name: options[f.name] for f in dataclasses.fields(RenderSettings) if f.name in options}
    if "no_denoise" in options:
        kw["denoise"] = not options["no_denoise"]
    return dataclasses.replace(DEFAULTS, **kw)


def check_width(width: int, memory_bytes: int | None = None) -> None:
    """Raise UserError unless ``width`` is even and within [``MIN_WIDTH``, :func:`max_width`], with the reason."""
    if width % 2:
        raise UserError(f"--width must be an even number (height = width / 2), got {width}")
    if width < MIN_WIDTH:
        needs = ", ".join(f"{k} {v}" for k, v in sorted(MIN_WIDTH_BY_FLOW.items(), key=lambda kv: -kv[1]) if v > width)
        raise UserError(f"--width must be >= {MIN_WIDTH}, got {width}: the reconstruction's flow backends fail "
                        f"on smaller images (minimum widths: {needs})")
    top = max_width(memory_bytes)
    if width > top:
        memory = physical_memory_bytes() if memory_bytes is None else memory_bytes
        per_pixel = max(RECONSTRUCT_BYTES_PER_PIXEL, RENDER_BYTES_PER_PIXEL)
        need = BASE_BYTES + per_pixel * width * (width // 2)
        raise UserError(f"--width {width} needs about {need / 2**30:.1f} GiB to render and reconstruct "
                        f"({per_pixel} bytes per pixel), more than {MEMORY_SHARE:.0%} of this machine's "
                        f"{memory / 2**30:.1f} GiB; use --width {top} or less")


def check_settings(settings: RenderSettings) -> None:
    """Raise UserError unless every field of ``settings`` has its annotated type (a bool is no integer, 128.0
    no width), the width is one the pipeline can use (:func:`check_width`), the options of ``tri360 render`` are
    in range (named as options) and :meth:`RenderSettings.check` passes."""
    hints = type_hints(RenderSettings)
    for f in dataclasses.fields(RenderSettings):
        typed_value(getattr(settings, f.name), hints[f.name], f.name)
    check_width(settings.width)
    for name, minimum in (("samples", 1), ("threads", 0), ("max_bounces", 0)):
        if getattr(settings, name) < minimum:
            raise UserError(f"--{name.replace('_', '-')} must be >= {minimum}"
                            f"{' (0 = all cores)' if name == 'threads' else ''}, got {getattr(settings, name)}")
    try:
        settings.check()  # the other fields
    except ValueError as exc:
        raise UserError(str(exc)) from None


def _check_options(viewpoints: int, baseline: float) -> None:
    if viewpoints < 1:
        raise UserError(f"--viewpoints must be >= 1, got {viewpoints}")
    if not (baseline > 0 and baseline < 100):
        raise UserError(f"--baseline must be a positive distance in metres, got {baseline}")


def _short(value) -> str:
    text = json.dumps(value) if not isinstance(value, str) else value
    return text if len(text) <= 60 else text[:57] + "..."


def differences(meta: dict, planned: dict, rig: Rig) -> list[str]:
    """What differs between a stored frame (parsed ``frame.json``) and the render planned now.

    Args:
        meta: the stored frame's metadata.
        planned: :func:`harness.render.base.identity` of the planned render.
        rig: the planned rig placement (its camera poses must equal the stored ones).
    Returns:
        One short phrase per difference, e.g. ``"samples 16 (now 12)"``; empty if it is the same render.
    """
    stored = recorded_identity(meta)
    out = []
    for key, want in planned.items():
        have = stored.get(key)
        if key == "scene params" and isinstance(have, dict) and isinstance(want, dict):
            keys = sorted(set(have) | set(want))
            out += [f"scene parameter {k} {_short(have.get(k, 'unset'))} (now {_short(want.get(k, 'unset'))})"
                    for k in keys if have.get(k, "unset") != want.get(k, "unset")]
        elif have != want:
            out.append(f"{key} {_short(have) if have is not None else 'not recorded'} (now {_short(want)})")
    if not out:
        for name, pose in rig.poses().items():
            try:
                cam = meta["cameras"][name]
                same = (np.allclose(cam["position"], pose.position, atol=1e-9)
                        and np.allclose(cam["rotation"], pose.rotation, atol=1e-9))
            except (KeyError, TypeError, ValueError):
                same = False
            if not same:
                out.append("camera poses (the viewpoint placement changed)")
                break
    return out


@dataclass(frozen=True)
class RenderPlan:
    """A checked render, before anything is drawn or written (:func:`plan_render`).

    Attributes:
        renderer: the backend name.
        spec: the scene.
        settings: the render settings.
        scene_dir: the data root's directory of the scene (:func:`scene_dir_name`).
        viewpoints: the number of viewpoints ``vp000``, ``vp001``...
        rigs: their rig placements (empty when not placed: :func:`plan_render`).
        baseline: rig baseline, metres.
        identity: :func:`harness.render.base.identity` of every frame of the plan (what decides its pixels).
    """

    renderer: str
    spec: SceneSpec
    settings: RenderSettings
    scene_dir: str
    viewpoints: int
    rigs: list[Rig]
    baseline: float
    identity: dict


def plan_render(settings: RenderSettings = DEFAULTS, scene: str = DEFAULT_SCENE, viewpoints: int = 1,
                baseline: float = DEFAULT_BASELINE_M, overrides: dict | None = None,
                renderer: str | None = None, place_rigs: bool = True) -> RenderPlan:
    """Check a render and place its rigs, without drawing or writing anything (see :func:`render_frames`).

    With ``place_rigs=False`` the rigs are not placed (``rigs`` is empty): everything else is checked, in
    milliseconds, where placing the rigs of a furnished scene takes seconds (``choose_viewpoints``' clearance
    search: about 10 s for 2 classroom viewpoints on a loaded 2-core machine).

    Raises:
        UserError: a setting of the wrong type or out of range, an unknown renderer, a scene the renderer
            cannot draw, no free viewpoints.
        SceneError: unknown scene, preset or scene parameter, or a scene file that fails.
    """
    check_settings(settings)
    _check_options(typed_value(viewpoints, int, "--viewpoints"), typed_value(baseline, float, "--baseline"))
    entry, preset = get_scene(typed_value(scene, str, "--scene"))
    spec = entry.build_spec(preset, settings.seed, overrides)
    renderer = entry.renderer if renderer is None else typed_value(renderer, str, "--renderer")
    backend = get_renderer(renderer)
    reason = backend.unsupported(spec)
    if reason:
        raise UserError(f"renderer {renderer!r} cannot draw scene {scene!r}: {reason}")
    try:
        rigs = choose_viewpoints(spec, viewpoints, settings.seed, baseline_m=baseline) if place_rigs else []
    except ValueError as exc:
        raise UserError(str(exc)) from None
    return RenderPlan(renderer=renderer, spec=spec, settings=settings,
                      scene_dir=scene_dir_name(entry.name, preset, entry.default_preset), viewpoints=viewpoints,
                      rigs=list(rigs),
                      baseline=float(baseline),
                      identity=identity(renderer, backend.pixel_settings, settings, spec, float(baseline)))


class SettingsMismatch(UserError):
    """A frame directory holds a frame rendered with other settings (attributes ``frame_dir``, ``diffs``)."""

    def __init__(self, frame_dir: Path, diffs: list[str], remedy: str):
        self.frame_dir, self.diffs = frame_dir, diffs
        super().__init__(f"{frame_dir} holds a frame rendered with other settings: {'; '.join(diffs)}; {remedy}")


def render_frames(settings: RenderSettings = DEFAULTS, scene: str = DEFAULT_SCENE, *, viewpoints: int = 1,
                  out_root: Path | str = "data", baseline: float = DEFAULT_BASELINE_M, overrides: dict | None = None,
                  renderer: str | None = None, force: bool = False, ctx: RunContext = IN_PROCESS) -> list[Path]:
    """Render ``viewpoints`` rig placements of a scene into ``out_root`` and return the frame directories.

    Args:
        settings: how to render (width, samples, seed, threads, denoise, bounces, light tree...: every field of
            :class:`harness.render.base.RenderSettings`, checked for type and range); the seed is also the scene
            layout jitter's and the viewpoint draw's.
        scene: ``family`` or ``family:preset`` (see ``tri360 scenes``).
        viewpoints: number of rig placements, named ``vp000``, ``vp001``, ... (``choose_viewpoints``).
        out_root: data root; frames go to ``<out_root>/<scene>/<viewpoint>/``.
        baseline: rig baseline C-U and C-R, metres.
        overrides: scene parameters overriding the preset's (e.g. ``{"model_path": "chair.glb"}``); each key
            must be one of the scene's parameters.
        renderer: ``"cycles"`` or ``"raycast"``; None = the scene's default.
        force: re-render frames that are already complete (whatever they were rendered with).
        ctx: where the frames render (in this process, or each frame as a Dask task: ``--scheduler`` /
            ``--workers``, or a study's open executor, left open), whether a progress bar (on stderr) advances
            per rendered camera view, and whether Blender prints its own log lines (to stderr).

    Raises:
        UserError: bad option, unwritable output, no free viewpoints, a scene the renderer cannot draw, an
            existing frame rendered with other settings (:class:`SettingsMismatch`, naming them; use ``force``),
            or a renderer failure.
        SceneError: unknown scene, preset or scene parameter, or a scene file that fails.
    """
    ctx.check()
    plan = plan_render(settings, scene, viewpoints, baseline, overrides, renderer)
    out_root = check_output(Path(out_root), "data")  # absent, empty or a data root tri360 wrote
    scene_dir = check_name(plan.scene_dir, "--scene")
    todo = []
    for i, rig in enumerate(plan.rigs):
        vp = f"vp{i:03d}"
        d = frame_dir(out_root, scene_dir, vp)
        if not force and is_complete(d):
            diff = differences(json.loads((d / "frame.json").read_text(encoding="utf-8")), plan.identity, rig)
            if diff:
                raise SettingsMismatch(d, diff, "use --force to re-render it or choose another --out")
            continue
        todo.append((vp, rig))
    dirs = [frame_dir(out_root, scene_dir, f"vp{i:03d}") for i in range(len(plan.rigs))]
    created = [p for p in (out_root / scene_dir, *(out_root / scene_dir).parents) if not p.exists()]
    ensure_output_dir(out_root / scene_dir)
    clean_stale_partials(out_root / scene_dir)  # hidden half-written frames of killed runs
    if not todo:
        mark_output(out_root, "data")
        return dirs
    if ctx.distributed:
        _render_distributed(todo, plan, out_root, created, ctx)
        mark_output(out_root, "data")
        return dirs

    items = [RenderItem(plan.renderer, plan.spec, settings, rig, scene_dir, vp) for vp, rig in todo]
    try:
        render_items(items, out_root, f"{scene_dir} ({plan.renderer})", ctx)
    except BaseException:
        _remove_if_empty(created)  # an interrupted first render leaves no empty directories behind
        raise
    mark_output(out_root, "data")
    return dirs


@dataclass(frozen=True)
class RenderItem:
    """One frame to render: with which renderer, scene, settings and rig, and where (``<scene_dir>/<viewpoint>``)."""

    renderer: str
    spec: SceneSpec
    settings: RenderSettings
    rig: Rig
    scene_dir: str
    viewpoint: str


def render_items(items: list[RenderItem], out_root: Path, desc: str, ctx: RunContext = IN_PROCESS) -> None:
    """Render frames into ``out_root`` and write each atomically as it is done (the one render loop of ``render``,
    ``render --suite`` and ``study``).

    In this process, consecutive items of one scene directory share one opened renderer (the scene is built once)
    and a progress bar advances per camera view; distributed (``ctx`` on a Dask cluster), each frame is one
    task (:func:`render_one`) and the hidden half-frames of workers lost mid-write are cleaned afterwards.
    """
    progress, verbose = ctx.progress, ctx.verbose
    if ctx.distributed:
        root = os.fspath(out_root.resolve())  # workers may run elsewhere: give them the absolute path
        tasks = {f"{it.scene_dir}/{it.viewpoint}": (it.renderer, it.spec, it.settings, it.rig, it.scene_dir,
                                                    it.viewpoint, root, verbose) for it in items}
        with ctx.executor() as ex:
            for _ in ex.run(render_one, tasks, desc="render", unit="frame", progress=progress,
                            names={k: k for k in tasks}):
                pass
        for scene in dict.fromkeys(it.scene_dir for it in items):
            clean_stale_partials(out_root / scene)
        return
    bar = progress_bar(len(items) * len(CAMERA_NAMES), desc=desc, unit="view", enabled=progress)
    try:
        start = 0
        while start < len(items):
            first = items[start]
            end = start
            while end < len(items) and items[end].scene_dir == first.scene_dir:
                end += 1
            with get_renderer(first.renderer)(first.spec, first.settings, verbose=verbose) as drawer:
                for it in items[start:end]:
                    label = f"{it.scene_dir}/{it.viewpoint}"
                    bar.set_postfix_str(label)

                    def on_camera(name, seconds, label=label):
                        bar.set_postfix_str(f"{label}/{name} {seconds:.1f}s")
                        bar.update(1)

                    write_rendered_frame(drawer.render(it.rig, scene=it.scene_dir, viewpoint=it.viewpoint,
                                                       on_camera=on_camera), out_root)
            start = end
    finally:
        bar.close()


def write_rendered_frame(frame: Frame, out_root: Path) -> Path:
    """Write a freshly rendered frame atomically, its wall times moved from ``frame.json`` to :data:`RENDER_LOG`.

    ``frame.json`` then depends only on the render's inputs: the same frame rendered twice (here, on another
    worker, after a lost worker) is byte-identical.  The sidecar is written after the frame (atomically too);
    a frame without one is still complete.  The sidecar holds the per-camera seconds, the host and process that
    rendered the frame, and when it finished (``finished_unix``, seconds since the epoch).
    """
    renderer = dict(frame.renderer)
    seconds = renderer.pop("seconds", None)
    d = write_frame(dataclasses.replace(frame, renderer=renderer), out_root)
    atomic_write_text(d / RENDER_LOG, jsonio.dumps({"seconds": seconds, "host": platform.node(), "pid": os.getpid(),
                                                    "finished_unix": round(time.time(), 3)}))
    return d


def render_one(renderer: str, spec, settings: RenderSettings, rig, scene_dir: str, viewpoint: str, out_root: str,
               verbose: bool = False) -> dict:
    """One frame, start to finish (a Dask task): build the scene, render, write the frame into ``out_root``.

    Returns:
        ``{"path": frame directory, "seconds": total render seconds}``.
    """
    backend = get_renderer(renderer)
    with backend(spec, settings, verbose=verbose) as drawer:
        frame = drawer.render(rig, scene=scene_dir, viewpoint=viewpoint)
    seconds = frame.renderer.get("seconds", {}).get("total")
    d = write_rendered_frame(frame, Path(out_root))
    return {"path": os.fspath(d), "seconds": seconds}


def _render_distributed(todo, plan: RenderPlan, out_root: Path, created: list[Path], ctx: RunContext) -> None:
    items = [RenderItem(plan.renderer, plan.spec, plan.settings, rig, plan.scene_dir, vp) for vp, rig in todo]
    try:
        render_items(items, out_root, "render", ctx)
    except BaseException:
        _remove_if_empty(created)
        raise


def _remove_if_empty(directories: list[Path]) -> None:
    """rmdir each directory (innermost first) that is still empty; stop at the first that is not."""
    for d in directories:
        try:
            d.rmdir()
        except OSError:
            return
