"""Shared fixtures: exact synthetic frames made by the numpy ray-caster (no Blender)."""

from __future__ import annotations

import pytest

from harness.frame import write_frame
from harness.kit import choose_viewpoints
from harness.raycast import render_frame
from scenes import get_scene


def make_synthetic_frame(width: int = 160, viewpoint: int = 0, preset: str | None = None, seed: int = 0):
    """A synthetic_box frame with exact ground truth (width x width/2)."""
    entry, preset = get_scene("synthetic_box" + (f":{preset}" if preset else ""))
    spec = entry.spec(preset, seed=seed)
    rig = choose_viewpoints(spec, viewpoint + 1, seed)[viewpoint]
    return render_frame(spec, rig, width, "synthetic_box", f"vp{viewpoint:03d}")


@pytest.fixture(scope="session")
def synthetic_frame():
    """A 200x100 synthetic_box frame (in memory)."""
    return make_synthetic_frame(200)


@pytest.fixture(scope="session")
def synthetic_root(tmp_path_factory, synthetic_frame):
    """A data root holding two synthetic_box frames on disk."""
    root = tmp_path_factory.mktemp("data")
    write_frame(synthetic_frame, root)
    write_frame(make_synthetic_frame(200, viewpoint=1), root)
    return root
