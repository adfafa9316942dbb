"""A framework-neutral dataset of tri360 frames for training and evaluating learned methods.

``FrameDataset(root)`` has ``__len__`` and ``__getitem__(i) -> dict`` of numpy arrays, so a PyTorch ``DataLoader``
(or any batching loop) takes it as it is; tri360 does not import torch.  One item, for frame ``i`` in sorted
``<scene>/<viewpoint>`` order:

- ``images``: (3, H, W, 3) uint8 sRGB, cameras C, U, R in that order (:data:`CAMERAS`);
- ``positions``: (3, 3) float64 metres and ``rotations``: (3, 3, 3) float64 world-from-camera, C, U, R: the told
  rig (``frame.json``); ``baseline_m``: () float64;
- ``distance``: (H, W) float32, C's Euclidean distance along each ray in metres, +inf where nothing is hit, NaN
  everywhere when the frame has no ground truth;
- ``valid``: (H, W) bool, finite positive ground truth;
- ``scene``, ``viewpoint``, ``condition``: str (``renderer.condition.name``, ``ideal`` without one).

A split of a suite is a data root of its own (``tri360 render --suite FILE --split dev --out data/dev``), so the
dataset takes no split argument; ``scenes`` keeps only those scenes.  Frames are read when asked for (nothing is
cached); a malformed frame raises :class:`harness.data.errors.FrameError` naming its file.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from harness.data.errors import UserError
from harness.data.frame import find_frames, read_frame

__all__ = ["CAMERAS", "FrameDataset"]

CAMERAS = ("C", "U", "R")


class FrameDataset:
    """The frames under ``root`` (a data root or one frame directory) as a map-style dataset (module doc)."""

    def __init__(self, root: Path, scenes: Sequence[str] | None = None):
        self.root = Path(root)
        if not self.root.is_dir():
            raise UserError(f"{self.root}: data root does not exist or is not a directory")
        dirs = find_frames(self.root)
        if scenes:
            dirs = [d for d in dirs if d.parent.name in set(scenes)]
        if not dirs:
            raise UserError(f"{self.root}: no tri360 frames found (expected <scene>/<viewpoint>/frame.json)")
        self.dirs = dirs

    def __len__(self) -> int:
        return len(self.dirs)

    def __getitem__(self, index: int) -> dict:
        if not -len(self) <= index < len(self):
            raise IndexError(f"frame index {index} out of range ({len(self)} frames)")
        f = read_frame(self.dirs[index])
        if f.has_ground_truth:
            distance = np.asarray(f.distance["C"], dtype=np.float32)
        else:
            distance = np.full((f.height, f.width), np.nan, dtype=np.float32)
        condition = f.renderer.get("condition")
        name = condition.get("name") if isinstance(condition, dict) else None
        return {
            "images": np.stack([f.images[c] for c in CAMERAS]),
            "positions": np.stack([np.asarray(f.cameras[c].position, np.float64) for c in CAMERAS]),
            "rotations": np.stack([np.asarray(f.cameras[c].rotation, np.float64) for c in CAMERAS]),
            "baseline_m": np.float64(f.baseline_m),
            "distance": distance,
            "valid": np.isfinite(distance) & (distance > 0),
            "scene": f.scene, "viewpoint": f.viewpoint, "condition": str(name or "ideal"),
        }
