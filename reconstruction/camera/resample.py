"""Resampling equirectangular images on the sphere: wrap-aware sampling and rotation ("rectification").

A pair is *rectified* by viewing both of its images in a common frame whose +Z axis is the pair's
baseline: the epipoles move to the poles and every epipolar curve becomes a meridian (an image column),
so disparity runs along columns and nothing crosses the left/right seam (the MODE / Cassini idea).
"""

from __future__ import annotations

import cv2
import numpy as np

from reconstruction.camera.equirect import bearing_grid, bearing_to_pixel
from reconstruction.camera.image_ops import periodic_pad

__all__ = ["rectifying_rotation", "bilinear_with_gradient", "sample_equirect", "rotation_maps", "warp_equirect",
           "WRAP_PAD"]

WRAP_PAD = 4  # columns copied from the opposite edge before bilinear sampling


def rectifying_rotation(baseline, reference_rotation) -> np.ndarray:
    """World-from-rectified rotation for a pair with baseline ``baseline`` (world, any length).

    The rectified frame has +Z along the baseline (so the epipole toward the second camera is the top
    pole), +Y as close as possible to the reference camera's forward axis, and +X = Y x Z.

    Args:
        baseline: (3,) vector from the reference camera to the other camera, metres.
        reference_rotation: (3, 3) world-from-camera rotation of the reference camera.
    Returns:
        (3, 3) rotation matrix (columns: rectified X, Y, Z in world coordinates).
    """
    z = np.asarray(baseline, dtype=np.float64)
    z = z / np.linalg.norm(z)
    ref = np.asarray(reference_rotation, dtype=np.float64)
    y = ref[:, 1] - (ref[:, 1] @ z) * z
    if np.linalg.norm(y) < 1e-6:  # baseline along the forward axis: fall back to the up axis
        y = ref[:, 2] - (ref[:, 2] @ z) * z
    y = y / np.linalg.norm(y)
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=1)


def bilinear_with_gradient(image: np.ndarray, u, v):
    """Exact bilinear interpolation of an equirect image and its derivatives, wrapping across the seam.

    Unlike ``cv2.remap`` (positions quantised to 1/32 pixel) this is continuous in ``(u, v)``, and the
    derivatives are those of the interpolant itself, so a cost built on it and its Jacobian agree.

    Args:
        image: (H, W, C) float array (intensities).
        u, v: (N,) continuous pixel coordinates (centres at integers); ``u`` wraps, ``v`` is clamped to
            [0, H - 1] (where clamped, the v-derivative is 0).
    Returns:
        ``(value, d_du, d_dv)``, each (N, C) float64: samples and their derivatives per pixel.
    """
    h, w, c = image.shape
    flat = image.reshape(h * w, c)
    u = np.asarray(u, dtype=np.float64)
    v_raw = np.asarray(v, dtype=np.float64)
    v = np.clip(v_raw, 0.0, h - 1.0)
    u0 = np.floor(u)
    fu = (u - u0)[:, None]
    i0 = u0.astype(np.int64) % w
    i1 = (i0 + 1) % w
    r0 = np.minimum(np.floor(v), h - 2).astype(np.int64)
    fv = (v - r0)[:, None]
    p00, p01 = flat[r0 * w + i0], flat[r0 * w + i1]
    p10, p11 = flat[(r0 + 1) * w + i0], flat[(r0 + 1) * w + i1]
    top = p00 + fu * (p01 - p00)
    bottom = p10 + fu * (p11 - p10)
    value = top + fv * (bottom - top)
    d_du = (p01 - p00) + fv * ((p11 - p10) - (p01 - p00))
    inside = ((v_raw > 0.0) & (v_raw < h - 1.0))[:, None]
    d_dv = np.where(inside, bottom - top, 0.0)
    return value, d_du, d_dv


def sample_equirect(image: np.ndarray, u, v, interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
    """Sample an equirectangular image at continuous pixel coordinates, wrapping across the seam.

    Args:
        image: (H, W) or (H, W, C) array (uint8 or float32).
        u, v: float arrays of equal shape (any), pixel coordinates (centres at integers); ``u`` may lie
            anywhere (it is wrapped), ``v`` is clamped to the first/last row beyond the image.
        interpolation: an OpenCV interpolation flag (bilinear positions are quantised to 1/32 pixel).
    Returns:
        Samples of shape ``u.shape`` (+ (C,) for multi-channel images), dtype of ``image``.
    """
    h, w = image.shape[:2]
    padded = periodic_pad(image, WRAP_PAD)
    uu = (np.mod(np.asarray(u, dtype=np.float64) + 0.5, w) - 0.5 + WRAP_PAD).astype(np.float32)
    vv = np.asarray(v, dtype=np.float32)
    # remap wants 2-D maps narrower than 32767 columns: lay the samples out in rows of 1024
    n, cols = uu.size, 1024
    rows = max(1, -(-n // cols))
    flat_u = np.zeros(rows * cols, np.float32)
    flat_v = np.zeros(rows * cols, np.float32)
    flat_u[:n], flat_v[:n] = uu.ravel(), vv.ravel()
    out = cv2.remap(padded, flat_u.reshape(rows, cols), flat_v.reshape(rows, cols), interpolation,
                    borderMode=cv2.BORDER_REPLICATE)
    out = out.reshape((rows * cols,) + image.shape[2:])[:n]
    return out.reshape(uu.shape + image.shape[2:])


def rotation_maps(width: int, height: int, target_rotation, source_rotation):
    """Pixel maps that resample a source equirect camera into a target frame (same centre).

    Args:
        target_rotation: (3, 3) world-from-target rotation (e.g. a rectifying rotation).
        source_rotation: (3, 3) world-from-camera rotation of the image being resampled.
    Returns:
        ``(u, v)`` float64 arrays (H, W): for every target pixel, the source pixel it looks at.
    """
    rel = np.asarray(source_rotation, dtype=np.float64).T @ np.asarray(target_rotation, dtype=np.float64)
    b = bearing_grid(width, height, rotation=rel)
    return bearing_to_pixel(b, width, height)


def warp_equirect(image: np.ndarray, target_rotation, source_rotation,
                  interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
    """Resample an equirect image (camera rotation ``source_rotation``) into ``target_rotation``'s frame.

    Returns an image of the same size and dtype; the identity when the rotations are equal.
    """
    if np.allclose(target_rotation, source_rotation, atol=1e-12):
        return image.copy()
    h, w = image.shape[:2]
    u, v = rotation_maps(w, h, target_rotation, source_rotation)
    return sample_equirect(image, u, v, interpolation)
