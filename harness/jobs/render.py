"""The render job: render frames of a registered scene into a data root.

Library use::

    from harness.jobs.render import render_frames
    dirs = render_frames("classroom:small", viewpoints=2, out_root="data", width=256, samples=8)

Frames land in ``<out>/<scene>/vp000``, ``vp001``, ... (``<scene>`` is the family name, or
``family-preset`` for a non-default preset).  The run is resumable: a frame directory that already reads
and validates is skipped (unless ``force``), and every frame is written atomically, so an interrupted run
never leaves a complete-looking frame behind.  Blender (``bpy``) is imported only when a scene with the
``"blender"`` backend is actually rendered.
"""

from __future__ import annotations

import importlib
import json
import tempfile
from pathlib import Path

from tqdm import tqdm

from harness.data.errors import UserError
from harness.data.frame import frame_dir, is_complete, write_frame
from harness.render.raycast import render_frame
from reconstruction.camera.rig import CAMERA_NAMES, DEFAULT_BASELINE_M
from scenes.model import choose_viewpoints
from scenes.registry import get_scene

# Defaults chosen by the study in docs/rendering.md (16 spp + OIDN 'accurate', light tree, max bounces 4:
# every cheaper setting measured there costs reconstruction accuracy; the other Cycles settings live in
# harness.render.cycles.RenderSettings and are recorded in each frame's renderer provenance).
DEFAULT_WIDTH = 1000
DEFAULT_SAMPLES = 12
DEFAULT_MAX_BOUNCES = 4
DEFAULT_SCENE = "classroom"


def scene_dir_name(family: str, preset: str, default_preset: str) -> str:
    """Directory name of a scene: the family, or ``family-preset`` for a non-default preset."""
    return family if preset == default_preset else f"{family}-{preset}"


def parse_overrides(items: list[str] | None) -> dict:
    """``["key=value", ...]`` -> dict; values are parsed as JSON when possible, else kept as strings."""
    out = {}
    for item in items or []:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise UserError(f"--set expects KEY=VALUE, got {item!r}")
        try:
            out[key] = json.loads(raw)
        except json.JSONDecodeError:
            out[key] = raw
    return out


def _check_options(viewpoints: int, width: int, samples: int, threads: int, baseline: float,
                   max_bounces: int) -> None:
    if viewpoints < 1:
        raise UserError(f"--viewpoints must be >= 1, got {viewpoints}")
    if width < 8 or width % 2:
        raise UserError(f"--width must be an even number >= 8 (height = width / 2), got {width}")
    if samples < 1:
        raise UserError(f"--samples must be >= 1, got {samples}")
    if threads < 0:
        raise UserError(f"--threads must be >= 0 (0 = all cores), got {threads}")
    if not (baseline > 0 and baseline < 100):
        raise UserError(f"--baseline must be a positive distance in metres, got {baseline}")
    if max_bounces < 0:
        raise UserError(f"--max-bounces must be >= 0, got {max_bounces}")


def _check_writable(directory: Path) -> None:
    try:
        directory.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=directory, prefix=".tri360-write-test-"):
            pass
    except OSError as exc:
        raise UserError(f"output directory {directory} is not writable ({exc.strerror or exc})") from None


def _existing_matches(directory: Path, width: int, params: dict) -> bool:
    """True if the complete frame at ``directory`` was rendered at ``width`` from the same scene params."""
    meta = json.loads((directory / "frame.json").read_text(encoding="utf-8"))
    params = json.loads(json.dumps(params))  # tuples -> lists, as stored
    return meta.get("width") == width and meta.get("renderer", {}).get("scene_params", params) == params


def render_frames(scene_name: str = DEFAULT_SCENE, viewpoints: int = 1, out_root: Path | str = "data",
                  width: int = DEFAULT_WIDTH, samples: int = DEFAULT_SAMPLES, seed: int = 0, threads: int = 0,
                  baseline: float = DEFAULT_BASELINE_M, force: bool = False, denoise: bool = True,
                  max_bounces: int = DEFAULT_MAX_BOUNCES, overrides: dict | None = None,
                  progress: bool = True, verbose: bool = False) -> list[Path]:
    """Render ``viewpoints`` rig placements of a scene into ``out_root`` and return the frame directories.

    Args:
        scene_name: ``family`` or ``family:preset`` (see ``tri360 scenes``).
        viewpoints: number of rig placements, named ``vp000``, ``vp001``, ... (``choose_viewpoints``).
        out_root: data root; frames go to ``<out_root>/<scene>/<viewpoint>/``.
        width: panorama width, pixels (height = width / 2); even, >= 8.
        samples: Cycles samples per pixel (Blender scenes only).
        seed: one seed for the scene layout jitter, the viewpoint draw and Cycles' noise pattern.
        threads: CPU threads for Cycles, 0 = all.
        baseline: rig baseline C-U and C-R, metres.
        force: re-render frames that are already complete.
        denoise: OpenImageDenoise on the colour images (Blender only; distance is never denoised).
        max_bounces: Cycles light bounces.
        overrides: scene parameters overriding the preset's (e.g. ``{"model_path": "chair.glb"}``).
        progress: show a tqdm bar advancing per rendered camera view.
        verbose: let Blender print its own log lines.

    Raises:
        UserError: bad option, unwritable output, no free viewpoints, or an existing frame rendered with
            other settings (use ``force``).
        SceneError: unknown scene or preset, or a scene file that fails.
    """

    _check_options(viewpoints, width, samples, threads, baseline, max_bounces)
    entry, preset = get_scene(scene_name)
    spec = entry.spec(preset, seed, **(overrides or {}))
    scene_dir = scene_dir_name(entry.name, preset, entry.default_preset)
    try:
        rigs = choose_viewpoints(spec, viewpoints, seed, baseline_m=baseline)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    out_root = Path(out_root)
    _check_writable(out_root / scene_dir)

    todo = []
    for i, rig in enumerate(rigs):
        vp = f"vp{i:03d}"
        d = frame_dir(out_root, scene_dir, vp)
        if not force and is_complete(d):
            if not _existing_matches(d, width, spec.params):
                raise UserError(f"{d} holds a frame rendered with other settings (width or scene params); "
                                f"use --force to replace it or choose another --out")
            continue
        todo.append((vp, rig))

    bar = tqdm(total=len(todo) * len(CAMERA_NAMES), unit="view", disable=not progress or not todo,
               desc=scene_dir, dynamic_ncols=True)
    renderer = None
    try:
        for vp, rig in todo:
            bar.set_postfix_str(vp)
            if entry.backend == "blender":
                if renderer is None:
                    blender = importlib.import_module("harness.render.cycles")  # lazy: only here is bpy loaded
                    settings = blender.RenderSettings(width=width, samples=samples, seed=seed, threads=threads,
                                                      denoise=denoise, max_bounces=max_bounces)
                    renderer = blender.SceneRenderer(spec, settings, verbose=verbose)

                def on_camera(name, seconds, vp=vp):
                    bar.set_postfix_str(f"{vp}/{name} {seconds:.1f}s")
                    bar.update(1)

                frame = renderer.render(rig, scene=scene_dir, viewpoint=vp, on_camera=on_camera)
            else:
                frame = render_frame(spec, rig, width, scene_dir, vp)
                bar.update(len(CAMERA_NAMES))
            frame.renderer.setdefault("seed", seed)
            frame.renderer.setdefault("scene_params", spec.params)
            write_frame(frame, out_root)
    finally:
        bar.close()
    return [frame_dir(out_root, scene_dir, f"vp{i:03d}") for i in range(len(rigs))]
