"""The photometric camera model: what a real camera does to the light before its image is stored.

A rendered image is what an ideal camera records: scene-linear light encoded as sRGB.  A camera of a real rig
meters its own exposure and white balance, its lenses (two back-to-back fisheyes, stitched) darken towards their
edges, its sensor adds noise and its encoder compresses.  :class:`Photometric` records all of that for one camera;
:func:`apply` turns an ideal image into that camera's image, in linear light and in this order:

1. vignetting: gain ``1 - edge_loss * (theta / 90 deg) ** 2``, ``theta`` the angle between the pixel's bearing and
   the nearer of the lens axes ``+axis`` and ``-axis`` (a camera-frame axis, ``"x"``, ``"y"`` or ``"z"``), so the
   seam between the lenses loses ``edge_loss`` of the light;
2. exposure: linear light times ``2 ** exposure_stops``;
3. white balance: per-channel gains ``white_balance`` (R, G, B);
4. sensor noise: Gaussian with variance ``shot * x + read`` at linear level ``x`` (Poisson-Gaussian), drawn from a
   generator seeded with ``seed``;
5. the response curve: ``"srgb"`` (IEC 61966-2-1) or ``"gamma-G"`` (``x ** (1 / G)``), then 8 bits;
6. compression: JPEG at ``jpeg_quality`` (4:2:0, OpenCV/libjpeg), or none (0).

The record is stored in ``frame.json`` as the camera's ``"photometric"`` object (:meth:`Photometric.to_json`);
a camera without one is ideal.  :func:`apply` is deterministic: the same image, record and seed give the same bytes.
"""

from __future__ import annotations

import cv2
import numpy as np

from harness.data.photometric import AXES, Photometric, gamma_of
from reconstruction.camera.equirect import bearing_grid
from reconstruction.photometry import linear_to_srgb, srgb_to_linear

__all__ = ["apply", "vignetting_gain", "encode"]

def vignetting_gain(width: int, height: int, axis: str, edge_loss: float) -> np.ndarray:
    """(H, W) float32 gain of two back-to-back fisheyes along the camera-frame ``axis`` (module doc, step 1)."""
    b = bearing_grid(width, height)
    c = np.abs(b[..., AXES.index(axis)])
    theta = np.arccos(np.clip(c, 0.0, 1.0))
    return (1.0 - edge_loss * (theta / (np.pi / 2.0)) ** 2).astype(np.float32)


def encode(linear: np.ndarray, response: str) -> np.ndarray:
    """Linear light -> uint8 through the response curve (module doc, step 5)."""
    if response == "srgb":
        return linear_to_srgb(linear)
    g = gamma_of(response)
    x = np.clip(np.nan_to_num(np.asarray(linear, np.float64), nan=0.0), 0.0, 1.0)
    return np.floor(np.power(x, 1.0 / g) * 255.0 + 0.5).astype(np.uint8)


def apply(image: np.ndarray, camera: Photometric) -> np.ndarray:
    """The image ``camera`` records of the scene an ideal camera recorded as ``image``.

    Args:
        image: (H, W, 3) uint8 sRGB, RGB order (an ideal render).
        camera: the camera's response.
    Returns:
        (H, W, 3) uint8, RGB order.
    """
    h, w = image.shape[:2]
    lin = srgb_to_linear(image).astype(np.float64)
    if camera.vignetting["edge_loss"] > 0:
        lin *= vignetting_gain(w, h, camera.vignetting["axis"], camera.vignetting["edge_loss"])[..., None]
    lin *= (2.0 ** camera.exposure_stops) * np.asarray(camera.white_balance, np.float64)
    a, b = camera.noise["shot"], camera.noise["read"]
    if a > 0 or b > 0:
        rng = np.random.default_rng(camera.seed)
        lin = lin + np.sqrt(a * np.clip(lin, 0.0, None) + b) * rng.standard_normal(lin.shape)
    out = encode(lin, camera.response)
    if camera.jpeg_quality > 0:
        ok, buf = cv2.imencode(".jpg", cv2.cvtColor(out, cv2.COLOR_RGB2BGR),
                               [cv2.IMWRITE_JPEG_QUALITY, int(camera.jpeg_quality)])
        if not ok:
            raise ValueError("JPEG encoding failed")
        out = cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    return out
