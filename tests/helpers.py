"""Shared test helpers: exact synthetic frames made by the numpy ray-caster (no Blender); children that a test
sends Ctrl-C."""

from __future__ import annotations

import signal

from harness.render.raycast import render_frame
from scenes.model import choose_viewpoints
from scenes.registry import get_scene


def make_synthetic_frame(width: int = 160, viewpoint: int = 0, preset: str | None = None, seed: int = 0):
    """A synthetic_box frame with exact ground truth (width x width/2)."""
    entry, preset = get_scene("synthetic_box" + (f":{preset}" if preset else ""))
    spec = entry.spec(preset, seed=seed)
    rig = choose_viewpoints(spec, viewpoint + 1, seed)[viewpoint]
    return render_frame(spec, rig, width, "synthetic_box", f"vp{viewpoint:03d}")


def sigint_default() -> None:
    """``preexec_fn`` of a child process that a test sends SIGINT: SIGINT back to its default action.

    A process started from a background job (``cmd &``, CI runners, ``nohup``) inherits SIGINT as ignored, and
    Python then leaves it ignored (rightly: such a process is not meant to get the terminal's Ctrl-C), so
    without this a test's Ctrl-C would never arrive.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)
