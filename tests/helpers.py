"""Shared test helpers: exact synthetic frames made by the numpy ray-caster (no Blender), and the ground-truth
consistency check of a rendered frame across its cameras."""

from __future__ import annotations

import cv2
import numpy as np

from harness.render.raycast import render_frame
from reconstruction.camera.equirect import bearing_grid, project
from scenes.model import choose_viewpoints
from scenes.registry import get_scene


def make_synthetic_frame(width: int = 160, viewpoint: int = 0, preset: str | None = None, seed: int = 0):
    """A synthetic_box frame with exact ground truth (width x width/2)."""
    entry, preset = get_scene("synthetic_box" + (f":{preset}" if preset else ""))
    spec = entry.spec(preset, seed=seed)
    rig = choose_viewpoints(spec, viewpoint + 1, seed)[viewpoint]
    return render_frame(spec, rig, width, "synthetic_box", f"vp{viewpoint:03d}")


def sample_equirect(img: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear sample of an equirect image (H, W[, C]) at continuous pixel coordinates u, v (pixel centres at
    integers, as ``reconstruction.camera.equirect``), wrapping around in longitude."""
    big = np.concatenate([img[:, -1:], img, img[:, :1]], axis=1).astype(np.float32)
    return cv2.remap(big, (u + 1).astype(np.float32), v.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)


def cross_camera_consistency(frame, k: str, rel_tol: float = 0.02):
    """Ground-truth consistency of camera ``k`` (U or R) with C: project C's ground-truth points into ``k``.

    Returns ``(agree, occluded, grey_diff)``, each (H, W) over C's pixels: ``agree`` where ``k``'s own distance
    at the projection matches the point's distance from ``k`` within ``rel_tol`` (relative); ``occluded`` where a
    nearer surface within a pixel hides the point from ``k`` (0.4 m parallax around furniture), so it cannot
    agree; ``grey_diff`` the |grey level difference| (0-255) between C's pixel and ``k`` at the projection.
    """
    W, H = frame.width, frame.height
    c, pk = frame.cameras["C"], frame.cameras[k]
    X = c.position + frame.distance["C"][..., None] * bearing_grid(W, H, c.rotation)
    u, v = project(X, pk.position, pk.rotation, W, H)
    expected = np.linalg.norm(X - pk.position, axis=-1)
    agree = np.abs(sample_equirect(frame.distance[k], u, v) - expected) < rel_tol * expected
    nearest3x3 = cv2.erode(frame.distance[k].astype(np.float32), np.ones((3, 3), np.uint8),
                           borderType=cv2.BORDER_REPLICATE)
    occluded = sample_equirect(nearest3x3, u, v) < (1.0 - rel_tol) * expected
    grey = {n: cv2.cvtColor(frame.images[n], cv2.COLOR_RGB2GRAY).astype(np.float32) for n in ("C", k)}
    return agree, occluded, np.abs(sample_equirect(grey[k], u, v) - grey["C"])
