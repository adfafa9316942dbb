"""Perturbations of a frame that a real rig suffers: pure numpy operations on sRGB uint8 images and on poses.

Every operation takes a level (the unit is the kind's, :data:`KINDS`) and a ``numpy.random.Generator`` and
returns the new value plus a JSON-able record of what it drew, so a perturbed frame says exactly what was done to
it.  Photometric operations work in linear light (sRGB decoded, changed, re-encoded, rounded to uint8), except
``response`` (which re-encodes the linear light through another curve than sRGB) and ``jpeg`` (which compresses
the sRGB bytes, as a camera does).

Kinds and levels:

- ``rotation`` (degrees > 0): the orientation told for U and R is off by this angle, each about its own random
  axis; the images keep the true orientation.
- ``translation`` (millimetres > 0): the position told for U and R is off by this length, each in its own random
  direction; ``baseline_m`` becomes the mean of the told ``|U - C|`` and ``|R - C|``.
- ``exposure`` (stops > 0): each camera's exposure is scaled by ``2**e``, ``e`` uniform in [-level, level].
- ``white_balance`` (relative gain > 0, e.g. 0.1): each camera's red and blue gains (green is 1) are
  ``(1 + level)**g``, ``g`` uniform in [-1, 1].
- ``noise`` (grey levels > 0): Poisson-Gaussian sensor noise in linear light whose standard deviation at sRGB
  mid-grey (128) is ``level`` grey levels; 80 % of the variance there is shot noise, 20 % read noise.
- ``response`` (spread of the tone curves, in (0, 2]): each camera's image decoded from sRGB to linear light and
  re-encoded through its own response curve instead of sRGB (:func:`harness.render.camera.encode`), then read by
  methods as sRGB again: with probability 1/2 ``gamma-G`` (``x**(1/G)``), ``G`` uniform in
  [2.2 - level/2, 2.2 + level/2], otherwise ``s-curve-K`` (sRGB, then :func:`harness.render.camera.s_curve`
  ``s**K / (s**K + (1 - s)**K)``) with ``K = 1 + level/2``; 8 bits either way.  The cameras' intensities are
  then no longer related by a gain (sRGB is not a pure gamma, so even ``G`` = 2.2 is not quite the identity).
- ``jpeg`` (quality, an integer 1..100): JPEG compression at that quality (OpenCV / libjpeg).
- ``vignetting`` (fraction in (0, 1)): light lost at the edge of the camera's two back-to-back fisheye lenses
  (looking along the camera's +Y and -Y): gain ``1 - level * (theta / 90 deg)**2``, ``theta`` the angle from the
  nearer lens axis, so the stitching meridian (left/right of the lens axes) loses ``level``.
- ``vignetting_each`` (fraction in (0, 0.999]): the same fall-off, but each camera its own: camera ``k``'s seam
  loss ``L_k`` is drawn uniform in [level / 2, level], gain ``1 - L_k * (theta / 90 deg)**2``
  (:func:`harness.render.camera.vignetting_gain` about the camera's Y axis), so the cameras differ from one another.
- ``soiling`` (an integer count > 0): that many blobs per camera, alternately water drops (a blurred,
  slightly brightened disc) and dirt (a soft dark brown stain of 40-80 % opacity), radius 1-4 % of the height.
- ``glare`` (strength > 0): veiling glare around the brightest direction seen by C (a light source, treated as
  far away so every camera sees it in the same world direction): linear light ``level * exp(-a**2 / (2 s**2))``
  with ``s`` = 8 degrees plus a uniform veil of ``level / 20``, ``a`` the angle to the source.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable

import cv2
import numpy as np

from harness.data.photometric import noise_parameters
from harness.render.camera import encode, vignetting_gain
from reconstruction.camera.equirect import bearing_grid, pixel_to_bearing
from reconstruction.camera.image_ops import axis_angle_matrix as rotation_about
from reconstruction.camera.image_ops import grey
from reconstruction.camera.rig import CameraPose
from reconstruction.photometry import linear_to_srgb, srgb_to_linear

__all__ = ["KINDS", "ORDER", "parse_level", "srgb_to_linear", "linear_to_srgb", "rotation_about",
           "perturb_pose_rotation", "perturb_pose_translation", "exposure", "white_balance", "noise", "jpeg",
           "vignetting", "vignetting_each", "response", "soiling", "glare", "generator", "noise_parameters",
           "brightest_bearing", "IMAGE_OPS"]

KINDS: dict[str, str] = {
    "rotation": "degrees", "translation": "millimetres", "exposure": "stops", "white_balance": "relative gain",
    "noise": "grey levels at mid-grey", "jpeg": "quality 1-100", "vignetting": "fraction of light lost at the lens "
    "edge, < 1", "vignetting_each": "largest fraction of light lost at the lens edge, per camera, < 1",
    "response": "spread of the cameras' tone curves", "soiling": "blobs per camera", "glare": "linear-light strength",
}
"""Every kind -> the unit of its level."""

ORDER = ("rotation", "translation", "glare", "soiling", "vignetting", "vignetting_each", "exposure", "white_balance",
         "noise", "response", "jpeg")
"""The order perturbations are applied in, whatever the command line's: poses, then light on its way through the
lens (glare, soiling, vignetting, vignetting_each), then the sensor (exposure, white balance, noise), then the
response curve that encodes the sensor's linear signal (response), then compression -- the order of
:func:`harness.render.camera.apply`."""

GLARE_SIGMA_DEG = 8.0
GLARE_VEIL = 1.0 / 20.0


def parse_level(kind: str, text: str) -> float | int:
    """Level of ``kind`` from its text; ValueError (one line, naming the kind and the allowed range) if bad."""
    if kind not in KINDS:
        raise ValueError(f"unknown perturbation kind {kind!r} (choose from {', '.join(ORDER)})")
    if kind in ("jpeg", "soiling"):
        try:
            value = int(text)
        except ValueError:
            raise ValueError(f"{kind} level must be an integer ({KINDS[kind]}), got {text!r}") from None
        lo, hi = (1, 100) if kind == "jpeg" else (1, 1000)
        if not lo <= value <= hi:
            raise ValueError(f"{kind} level must be in {lo}..{hi} ({KINDS[kind]}), got {value}")
        return value
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{kind} level must be a number ({KINDS[kind]}), got {text!r}") from None
    if not np.isfinite(value) or value <= 0:
        raise ValueError(f"{kind} level must be positive and finite ({KINDS[kind]}), got {text!r}")
    limits = {"rotation": 45.0, "translation": 1000.0, "exposure": 8.0, "white_balance": 10.0, "noise": 128.0,
              "vignetting": 0.999, "vignetting_each": 0.999, "response": 2.0, "glare": 100.0}
    if value > limits[kind]:
        raise ValueError(f"{kind} level must be at most {limits[kind]:g} ({KINDS[kind]}), got {text!r}")
    return value


def generator(seed: int, kind: str, camera: str) -> np.random.Generator:
    """The random stream of one kind on one camera: independent of the other kinds and of their order."""
    return np.random.default_rng([int(seed), zlib.crc32(kind.encode()), zlib.crc32(camera.encode())])


# ------------------------------------------------------------------------------------------------- colour


# -------------------------------------------------------------------------------------------------- poses


def _unit(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def perturb_pose_rotation(pose: CameraPose, degrees: float, rng: np.random.Generator) -> tuple[CameraPose, dict]:
    """``pose`` with its rotation turned by ``degrees`` about a random world axis (the position kept)."""
    axis = _unit(rng)
    rot = rotation_about(axis, np.radians(degrees)) @ pose.rotation
    u, _, vt = np.linalg.svd(rot)  # re-orthonormalise against rounding
    return CameraPose(pose.position.copy(), u @ vt), {"axis_world": axis.tolist(), "degrees": float(degrees)}


def perturb_pose_translation(pose: CameraPose, millimetres: float,
                             rng: np.random.Generator) -> tuple[CameraPose, dict]:
    """``pose`` with its position moved by ``millimetres`` in a random world direction (the rotation kept)."""
    direction = _unit(rng)
    pos = pose.position + direction * millimetres / 1000.0
    return CameraPose(pos, pose.rotation.copy()), {"direction_world": direction.tolist(), "mm": float(millimetres)}


# ------------------------------------------------------------------------------------------------- images


def exposure(img: np.ndarray, stops: float, rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """Scale linear light by ``2**e``, ``e`` uniform in [-stops, stops]."""
    e = float(rng.uniform(-stops, stops))
    return linear_to_srgb(srgb_to_linear(img) * 2.0 ** e), {"stops": e}


def white_balance(img: np.ndarray, level: float, rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """Red and blue gains ``(1 + level)**g``, ``g`` uniform in [-1, 1] (green 1), in linear light."""
    g = rng.uniform(-1.0, 1.0, size=2)
    gains = np.array([(1.0 + level) ** g[0], 1.0, (1.0 + level) ** g[1]])
    return linear_to_srgb(srgb_to_linear(img) * gains), {"gains_rgb": gains.tolist()}


def noise(img: np.ndarray, grey_levels: float, rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """Poisson-Gaussian noise (Gaussian approximation, variance ``a * x + b`` in linear light ``x``)."""
    a, b = noise_parameters(grey_levels)
    x = srgb_to_linear(img)
    noisy = x + np.sqrt(a * x + b) * rng.standard_normal(x.shape)
    return linear_to_srgb(noisy), {"shot_a": a, "read_b": b}


def jpeg(img: np.ndarray, quality: int, rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """JPEG-compress at ``quality`` and decode (4:2:0 chroma, as cameras do); ``rng`` is unused."""
    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(img, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError("JPEG encoding failed")
    out = cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    return out, {"bytes": int(buf.size)}


def vignetting(img: np.ndarray, level: float, rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """Radial fall-off of two back-to-back fisheyes along camera +-Y; ``rng`` is unused."""
    h, w = img.shape[:2]
    b = bearing_grid(w, h)
    theta = np.arccos(np.clip(np.abs(b[..., 1]), 0.0, 1.0))  # angle from the nearer lens axis, radians
    gain = 1.0 - level * (theta / (np.pi / 2.0)) ** 2
    return linear_to_srgb(srgb_to_linear(img) * gain[..., None]), {"edge_loss": float(level)}


def vignetting_each(img: np.ndarray, level: float, rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """:func:`vignetting` with this camera's own seam loss, drawn uniform in [level / 2, level]."""
    h, w = img.shape[:2]
    loss = float(rng.uniform(level / 2.0, level))
    gain = vignetting_gain(w, h, "y", loss)
    return linear_to_srgb(srgb_to_linear(img) * gain[..., None]), {"axis": "y", "edge_loss": loss}


RESPONSE_GAMMA = 2.2
"""The gamma about which ``response`` draws its gamma curves (sRGB's is close to ``x**(1/2.2)``)."""


def response(img: np.ndarray, level: float, rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """Re-encode the image through a drawn response curve instead of sRGB (module doc); stays 8-bit."""
    if rng.random() < 0.5:
        g = float(rng.uniform(RESPONSE_GAMMA - level / 2.0, RESPONSE_GAMMA + level / 2.0))
        curve, drawn = f"gamma-{g!r}", {"gamma": g}
    else:
        k = 1.0 + level / 2.0
        curve, drawn = f"s-curve-{k!r}", {"contrast": k}
    return encode(srgb_to_linear(img), curve), {"response": curve, **drawn}


def _disc(h: int, w: int, cu: float, cv: float, radius: float) -> np.ndarray:
    """Soft (H, W) disc weight in [0, 1] around pixel (cu, cv), wrapping across the seam."""
    v, u = np.mgrid[0:h, 0:w]
    du = np.abs(u - cu)
    du = np.minimum(du, w - du)
    r = np.hypot(du, v - cv) / radius
    return np.clip(1.5 - r, 0.0, 1.0) ** 2 * (r < 1.5)


def soiling(img: np.ndarray, count: int, rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """``count`` blobs: even ones water drops (blur + 10 % brightening), odd ones dirt (dark brown stain)."""
    h, w = img.shape[:2]
    lin = srgb_to_linear(img)
    ksize = max(3, (h // 25) | 1)
    blurred = cv2.GaussianBlur(lin, (ksize, ksize), 0)
    blobs = []
    for i in range(int(count)):
        cu, cv = float(rng.uniform(0, w)), float(rng.uniform(0, h))
        radius = float(rng.uniform(0.01, 0.04)) * h
        weight = _disc(h, w, cu, cv, radius)[..., None]
        if i % 2 == 0:
            lin = lin * (1 - weight) + np.clip(blurred * 1.1, 0, 1) * weight
            blobs.append({"type": "drop", "u": cu, "v": cv, "radius_px": radius})
        else:
            opacity = float(rng.uniform(0.4, 0.8))
            dirt = np.array([0.05, 0.035, 0.02])
            lin = lin * (1 - opacity * weight) + dirt * opacity * weight
            blobs.append({"type": "dirt", "u": cu, "v": cv, "radius_px": radius, "opacity": opacity})
    return linear_to_srgb(lin), {"blobs": blobs}


def brightest_bearing(img: np.ndarray, pose: CameraPose) -> np.ndarray:
    """World bearing (3,) of the brightest spot of an equirect image (luminance blurred over ~1 % of H)."""
    h, w = img.shape[:2]
    lum = grey(srgb_to_linear(img), "bt709")
    k = max(3, (h // 50) | 1)
    lum = cv2.GaussianBlur(lum, (k, k), 0)
    v, u = np.unravel_index(int(np.argmax(lum)), lum.shape)
    return pose.rotation @ pixel_to_bearing(float(u), float(v), w, h)


def glare(img: np.ndarray, strength: float, pose: CameraPose, source_world: np.ndarray) -> tuple[np.ndarray, dict]:
    """Veiling glare around world direction ``source_world`` (unit (3,)), seen from a camera at ``pose``."""
    h, w = img.shape[:2]
    b = bearing_grid(w, h, rotation=pose.rotation)
    angle = np.arccos(np.clip(b @ np.asarray(source_world, dtype=np.float64), -1.0, 1.0))
    s = np.radians(GLARE_SIGMA_DEG)
    add = strength * (np.exp(-angle ** 2 / (2 * s * s)) + GLARE_VEIL)
    return linear_to_srgb(srgb_to_linear(img) + add[..., None]), {"source_world": list(map(float, source_world))}


IMAGE_OPS: dict[str, Callable] = {"exposure": exposure, "white_balance": white_balance, "noise": noise,
                                  "jpeg": jpeg, "vignetting": vignetting, "vignetting_each": vignetting_each,
                                  "response": response, "soiling": soiling}
