"""The photometric camera model: what a real camera does to the light before its image is stored.

A rendered image is what an ideal camera records: scene-linear light encoded as sRGB.  A camera of a real rig
meters its own exposure and white balance, its lenses (two back-to-back fisheyes, stitched) darken towards their
edges, its sensor adds noise and its encoder compresses.  :class:`Photometric` records all of that for one camera;
:func:`apply` turns an ideal image into that camera's image, in linear light and in this order:

1. the lenses: the product of
   - vignetting: gain ``1 - edge_loss * (theta / 90 deg) ** 2``, ``theta`` the angle between the pixel's bearing
     and the nearer of the lens axes ``+axis`` and ``-axis`` (a camera-frame axis, ``"x"``, ``"y"`` or ``"z"``), so
     the seam between the lenses loses ``edge_loss`` of the light;
   - (optional ``falloff``) gain ``1 - edge_loss * (1 - cos(theta') ** 4)``, ``theta'`` the angle from the nearer
     of the lens axes ``+-direction`` (any unit camera-frame vector): ``cos^4`` natural fall-off, scaled so that
     the seam (``theta'`` = 90 deg) loses ``edge_loss``;
   - (optional ``chromatic`` ``(kR, kG, kB)``) both fall-offs' losses times ``k_c`` in channel ``c``
     (``1 - k_c * loss``);
   - (optional ``seam``) the lenses' own gains: ``back + (front - back) * t``, ``t = clip(phi / blend_deg + 1/2,
     0, 1)``, ``phi = asin(bearing . direction)`` in degrees (the angle above the seam plane, towards the front
     lens): each lens's gain, cross-faded linearly over a band ``blend_deg`` wide about the seam;
2. exposure: linear light times ``2 ** exposure_stops``;
3. white balance: per-channel gains ``white_balance`` (R, G, B);
4. sensor noise: Gaussian with variance ``shot * x + read`` at linear level ``x`` (Poisson-Gaussian), drawn from a
   generator seeded with ``seed``;
5. the response curve: ``"srgb"`` (IEC 61966-2-1), ``"gamma-G"`` (``x ** (1 / G)``) or ``"s-curve-K"`` (sRGB,
   then :func:`s_curve` of contrast ``K`` on the encoded value), then 8 bits;
6. compression: JPEG at ``jpeg_quality`` (4:2:0, OpenCV/libjpeg), or none (0).

The record is stored in ``frame.json`` as the camera's ``"photometric"`` object (:meth:`Photometric.to_json`);
a camera without one is ideal.  :func:`apply` is deterministic: the same image, record and seed give the same bytes.
"""

from __future__ import annotations

import cv2
import numpy as np

from harness.data.photometric import AXES, Photometric, contrast_of, gamma_of
from reconstruction.camera.equirect import bearing_grid
from reconstruction.photometry import linear_to_srgb, srgb_to_linear

__all__ = ["apply", "vignetting_gain", "falloff_gain", "seam_gain", "lens_gain", "s_curve", "encode"]


def _vignetting_shape(width: int, height: int, axis: str) -> np.ndarray:
    """(H, W) float64 ``(theta / 90 deg) ** 2``: 0 on the lens axes ``+-axis``, 1 on their seam."""
    b = bearing_grid(width, height)
    c = np.abs(b[..., AXES.index(axis)])
    theta = np.arccos(np.clip(c, 0.0, 1.0))
    return (theta / (np.pi / 2.0)) ** 2


def vignetting_gain(width: int, height: int, axis: str, edge_loss: float) -> np.ndarray:
    """(H, W) float32 gain of two back-to-back fisheyes along the camera-frame ``axis`` (module doc, step 1)."""
    return (1.0 - edge_loss * _vignetting_shape(width, height, axis)).astype(np.float32)


def _cosine(width: int, height: int, direction) -> np.ndarray:
    """(H, W) float64 ``bearing . direction`` of every pixel (``direction`` a unit camera-frame vector)."""
    return np.clip(bearing_grid(width, height) @ np.asarray(direction, np.float64), -1.0, 1.0)


def falloff_gain(width: int, height: int, direction, edge_loss) -> np.ndarray:
    """Gain of the ``cos^4`` fall-off of two back-to-back lenses along ``+-direction`` (module doc, step 1).

    Args:
        width, height: the image's size, pixels.
        direction: (3,) unit camera-frame vector, the front lens's axis.
        edge_loss: the fraction lost at the seam: a number, or (C,) one per channel.
    Returns:
        (H, W, C) float32 (C = 1 for a number).
    """
    shape = 1.0 - _cosine(width, height, direction) ** 4  # 0 on either axis, 1 on the seam
    loss = np.atleast_1d(np.asarray(edge_loss, np.float64))
    return (1.0 - shape[..., None] * loss).astype(np.float32)


def seam_gain(width: int, height: int, direction, gains, blend_deg: float) -> np.ndarray:
    """(H, W) float32 gain of two lenses with their own gains ``(front, back)``, cross-faded linearly over a band
    ``blend_deg`` degrees wide about the seam plane (perpendicular to ``direction``, module doc, step 1)."""
    phi = np.degrees(np.arcsin(_cosine(width, height, direction)))
    t = np.clip(phi / float(blend_deg) + 0.5, 0.0, 1.0)
    front, back = (float(g) for g in gains)
    return (back + (front - back) * t).astype(np.float32)


def lens_gain(width: int, height: int, camera: Photometric) -> np.ndarray | None:
    """The gain of ``camera``'s lenses (module doc, step 1), None if it has none.

    Returns:
        (H, W, 1) float32, or (H, W, 3) with ``chromatic``; with ``vignetting`` alone exactly
        ``vignetting_gain(...)[..., None]``.
    """
    k = None if camera.chromatic is None else np.asarray(camera.chromatic, np.float64)
    gain = None
    loss = camera.vignetting["edge_loss"]
    if loss > 0:
        if k is None:
            gain = vignetting_gain(width, height, camera.vignetting["axis"], loss)[..., None]
        else:
            shape = _vignetting_shape(width, height, camera.vignetting["axis"])
            gain = (1.0 - shape[..., None] * (loss * k)).astype(np.float32)
    if camera.falloff is not None and camera.falloff["edge_loss"] > 0:
        loss = camera.falloff["edge_loss"]
        g = falloff_gain(width, height, camera.falloff["direction"], loss if k is None else loss * k)
        gain = g if gain is None else gain * g
    if camera.seam is not None:
        g = seam_gain(width, height, camera.seam["direction"], camera.seam["gains"], camera.seam["blend_deg"])
        gain = g[..., None] if gain is None else gain * g[..., None]
    return gain


def s_curve(s: np.ndarray, contrast: float) -> np.ndarray:
    """The S-shaped tone curve ``s ** K / (s ** K + (1 - s) ** K)`` of contrast ``K`` >= 1 on values in [0, 1]
    (clipped first): increasing, fixed points 0, 1/2 and 1, slope ``K`` at 1/2 (1 = the identity).

    Args:
        s: any shape, encoded values in [0, 1].  contrast: ``K``.
    Returns:
        float64 of ``s``'s shape, in [0, 1].
    """
    s = np.clip(np.asarray(s, np.float64), 0.0, 1.0)
    a, b = s ** contrast, (1.0 - s) ** contrast
    return a / (a + b)  # a + b >= 2 ** (1 - K) > 0


def _srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Linear light -> sRGB in [0, 1] (IEC 61966-2-1, clipped, NaN -> 0), float64, not quantised."""
    x = np.clip(np.nan_to_num(np.asarray(linear, np.float64), nan=0.0), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def encode(linear: np.ndarray, response: str) -> np.ndarray:
    """Linear light -> uint8 through the response curve (module doc, step 5)."""
    if response == "srgb":
        return linear_to_srgb(linear)
    k = contrast_of(response)
    if k is not None:
        return np.floor(s_curve(_srgb_encode(linear), k) * 255.0 + 0.5).astype(np.uint8)
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
    gain = lens_gain(w, h, camera)
    if gain is not None:
        lin *= gain
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
