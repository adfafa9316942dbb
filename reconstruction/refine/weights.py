"""Per-pixel confidence weights of each stereo pair.

* angle weight (Yin et al. 2019): ``sin(alpha)^p`` where alpha is the angle between the pixel's bearing
  and the pair's baseline; a pair cannot measure distance along its baseline (its epipoles).
* gradient confidence (paper section 3.2, eq. 1): the image gradient of C *along the pair's epipolar
  direction*; flow is reliable where texture crosses the epipolar curve (the aperture problem).  In the
  pair's rectified frame epipolar curves are image columns, so this is |dI/dv| there.
"""

from __future__ import annotations

import cv2
import numpy as np

from reconstruction.camera.equirect import bearing_to_pixel
from reconstruction.camera.image_ops import grey
from reconstruction.camera.resample import sample_equirect, warp_equirect

__all__ = ["angle_weight", "epipolar_gradient", "gradient_confidence", "lateral_confidence", "to_gray"]


def to_gray(image: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 RGB -> (H, W) float32 intensity in [0, 1]: OpenCV's 8-bit grey
    (:func:`reconstruction.camera.image_ops.grey`) over 255."""
    return grey(image).astype(np.float32) / 255.0


def angle_weight(sin_alpha: np.ndarray, power: float) -> np.ndarray:
    """``sin(alpha)**power`` (dimensionless, (N,)); ``power = 0`` gives ones."""
    return np.power(np.clip(sin_alpha, 0.0, 1.0), power)


def epipolar_gradient(gray: np.ndarray, camera_rotation, rect_rotation, bearings: np.ndarray,
                      blur_px: float = 1.0) -> np.ndarray:
    """Magnitude of C's image gradient along a pair's epipolar direction at each pixel.

    Args:
        gray: (H, W) float32 intensity of C in [0, 1].
        camera_rotation: (3, 3) world-from-camera rotation of C.
        rect_rotation: (3, 3) world-from-rectified rotation of the pair.
        bearings: (N, 3) world bearings of the pixels to evaluate (normally all of C's pixels).
        blur_px: Gaussian sigma applied before differentiating, pixels.
    Returns:
        (N,) |dI/dv| in the rectified frame, intensity per pixel.
    """
    rect = warp_equirect(gray, rect_rotation, camera_rotation)
    if blur_px > 0:
        rect = cv2.GaussianBlur(rect, (0, 0), blur_px)
    gv = np.abs(cv2.Sobel(rect, cv2.CV_32F, 0, 1, ksize=3, borderType=cv2.BORDER_REPLICATE)) / 8.0
    u, v = bearing_to_pixel(bearings @ np.asarray(rect_rotation), gray.shape[1], gray.shape[0])
    return sample_equirect(gv, u, v).astype(np.float64)


def gradient_confidence(grad: np.ndarray, scale: float, floor: float) -> np.ndarray:
    """Saturating confidence ``floor + (1 - floor) * g^2 / (g^2 + scale^2)`` in [floor, 1], (N,)."""
    g2 = np.square(grad)
    return floor + (1.0 - floor) * g2 / (g2 + scale * scale)


def lateral_confidence(off_plane_rad: np.ndarray, height: int, sigma_px: float) -> np.ndarray:
    """Confidence ``1 / (1 + (e / sigma)^2)`` from the match's angle out of the epipolar plane.

    Args:
        off_plane_rad: (N,) angle of the match out of the epipolar plane, radians.
        height: image height H; ``e = |angle| * H / pi`` in pixel equivalents.
        sigma_px: the error, pixel equivalents, at which confidence halves (<= 0: all ones).
    """
    if sigma_px <= 0:
        return np.ones_like(off_plane_rad)
    e = np.abs(off_plane_rad) * height / np.pi
    return 1.0 / (1.0 + np.square(e / sigma_px))
