"""The L-shaped trinocular rig: camera C at the rig origin, U above it, R to its right."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from reconstruction.camera.image_ops import axis_angle_matrix

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
    return axis_angle_matrix(2, yaw_rad)


def tilt_rotation(pitch_rad: float, roll_rad: float) -> np.ndarray:
    """(3, 3) rig-frame tilt: pitch about the rig's X (right) axis, then roll about its Y (forward) axis.

    ``R = Rx(pitch) @ Ry(roll)`` (rig-from-tilted, right-handed, radians): a positive pitch raises the forward
    axis Y towards +Z (nose up), a positive roll turns the up axis Z towards +X (the rig leans right).
    The identity (bit for bit) when both are 0.
    """
    if pitch_rad == 0.0 and roll_rad == 0.0:
        return np.eye(3)
    return axis_angle_matrix(0, pitch_rad) @ axis_angle_matrix(1, roll_rad)


@dataclass(frozen=True)
class Rig:
    """An L-shaped trinocular rig.

    Attributes:
        position: (3,) world position of camera C, metres.
        yaw_rad: rotation of the whole rig about world +Z, radians (0: C looks along world +Y).
        baseline_m: distance C-U and C-R, metres (default 0.4).
        pitch_rad, roll_rad: tilt of the rig, radians (default 0: level), applied in the rig's own frame
            before the yaw (:func:`tilt_rotation`): the rig's orientation is ``yaw_rotation(yaw) @
            tilt_rotation(pitch, roll)``, and U, R stay on its (tilted) up and right axes.
    """

    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    yaw_rad: float = 0.0
    baseline_m: float = DEFAULT_BASELINE_M
    pitch_rad: float = 0.0
    roll_rad: float = 0.0

    @property
    def tilted(self) -> bool:
        """True if the rig is not level (a non-zero pitch or roll)."""
        return self.pitch_rad != 0.0 or self.roll_rad != 0.0

    def rotation(self) -> np.ndarray:
        """(3, 3) world-from-rig rotation: ``yaw_rotation(yaw) @ tilt_rotation(pitch, roll)``; columns are the
        rig's right (X), forward (Y) and up (Z) axes in world coordinates."""
        rot = yaw_rotation(self.yaw_rad)
        return rot @ tilt_rotation(self.pitch_rad, self.roll_rad) if self.tilted else rot

    def poses(self) -> dict[str, CameraPose]:
        """Poses of C, U = C + b*up, R = C + b*right (up, right: the rig's, tilted, axes; all cameras with the
        rig's orientation)."""
        rot = self.rotation()
        c = np.asarray(self.position, dtype=np.float64)
        b = float(self.baseline_m)
        return {
            "C": CameraPose(c.copy(), rot.copy()),
            "U": CameraPose(c + b * rot[:, 2], rot.copy()),
            "R": CameraPose(c + b * rot[:, 0], rot.copy()),
        }
