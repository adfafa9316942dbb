"""Shared test helpers: exact synthetic frames made by the numpy ray-caster (no Blender)."""

from __future__ import annotations

from dataclasses import fields

from harness.jobs.render import render_frames
from harness.render.base import RenderSettings
from harness.render.raycast import render_frame
from scenes.model import choose_viewpoints
from scenes.registry import get_scene


def make_synthetic_frame(width: int = 160, viewpoint: int = 0, preset: str | None = None, seed: int = 0):
    """A synthetic_box frame with exact ground truth (width x width/2)."""
    entry, preset = get_scene("synthetic_box" + (f":{preset}" if preset else ""))
    spec = entry.spec(preset, seed=seed)
    rig = choose_viewpoints(spec, viewpoint + 1, seed)[viewpoint]
    return render_frame(spec, rig, width, "synthetic_box", f"vp{viewpoint:03d}")


SETTING_NAMES = frozenset(f.name for f in fields(RenderSettings))


def render_scene(scene: str, **kw):
    """``render_frames(RenderSettings(<the settings among kw>), scene, <the rest of kw>)``: lets a test vary a
    setting and a job argument the same way (``{**opts, **change}``)."""
    settings = RenderSettings(**{k: kw.pop(k) for k in list(kw) if k in SETTING_NAMES})
    return render_frames(settings, scene, **kw)
