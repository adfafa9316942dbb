"""The L-shaped trinocular rig: camera C at the rig origin, U above it, R to its right."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

CAMERA_NAMES = ("C", "U", "R")
DEFAULT_BASELINE_M = 0.4


@dataclass(frozen=True)
class CameraPose:
    """Pose of one equirectangular camera.

    Attributes:
        position: (3,) camera centre in world coordinates, metres.
        rotation: (3, 3) world-from-camera rotation; columns are the camera X (right), Y (forward), Z (up)
            axes in world coordinates.
    """

    position: np.ndarray
    rotation: np.ndarray

    def to_json(self) -> dict:
        return {"position": [float(x) for x in self.position],
                "rotation": [[float(x) for x in row] for row in self.rotation]}


def yaw_rotation(yaw_rad: float) -> np.ndarray:
    """(3, 3) rotation about world +Z by ``yaw_rad`` radians (counter-clockwise seen from above)."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Rig:
    """An L-shaped trinocular rig.

    Attributes:
        position: (3,) world position of camera C, metres.
        yaw_rad: rotation of the whole rig about world +Z, radians (0: C looks along world +Y).
        baseline_m: distance C-U and C-R, metres (default 0.4).
    """

    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    yaw_rad: float = 0.0
    baseline_m: float = DEFAULT_BASELINE_M

    def poses(self) -> dict[str, CameraPose]:
        """Poses of C, U = C + b*up, R = C + b*right (all with the rig's orientation)."""
        rot = yaw_rotation(self.yaw_rad)
        c = np.asarray(self.position, dtype=np.float64)
        b = float(self.baseline_m)
        return {
            "C": CameraPose(c.copy(), rot.copy()),
            "U": CameraPose(c + b * rot[:, 2], rot.copy()),
            "R": CameraPose(c + b * rot[:, 0], rot.copy()),
        }
