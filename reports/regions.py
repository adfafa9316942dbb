"""Regions of camera C's pixels (from ground truth, the rig and C's image) and the summary metrics per region.

Every mask is (H, W) bool over C's equirectangular pixels and is intersected with ``all`` (the scored pixels:
finite positive ground truth).  Definitions, thresholds and formulas: ``docs/metrics.md``.  Pure numpy + OpenCV.

Regions (in the order of :data:`REGION_NAMES`):

* ``all``: finite positive ground truth (exactly the pixels :func:`reports.metrics.summary` scores);
* ``textureless``: C's image is flat there (:func:`texture_level` below :data:`TEXTURELESS_GREY_PER_PX`);
* ``discontinuity``: within :data:`DISCONTINUITY_RADIUS_PX` pixels of a ground-truth depth edge;
* ``occluded``, ``occluded_U``, ``occluded_R``: C's surface point is hidden from camera U or R (either;
  U; R), see :func:`occluded_from`;
* ``epipole``, ``epipole_U``, ``epipole_R``: the bearing is within :data:`EPIPOLE_DEG` of a baseline direction
  (either way along it), from the actual camera positions;
* ``pole``: ``|latitude| > POLE_LAT_DEG`` in C's image;
* ``d<2m``, ``d2-5m``, ``d>=5m``: bands of the true distance (:data:`DISTANCE_BANDS_M`).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from reconstruction.camera.equirect import bearing_grid, pixel_to_lonlat, project
from reconstruction.camera.image_ops import dilate_wrapped, grey, periodic_box_filter, periodic_gaussian_blur
from reports.metrics import (
    EDGE_LOG_JUMP,
    ScoredMaps,
    angle_to_baseline_deg,
    depth_edges,
    scored_pixels,
    texture_magnitude,
)

__all__ = [
    "TEXTURE_BLUR_SIGMA_PX",
    "TEXTURE_WINDOW_PX",
    "TEXTURELESS_GREY_PER_PX",
    "DISCONTINUITY_LOG_JUMP",
    "DISCONTINUITY_RADIUS_PX",
    "OCCLUSION_REL_TOL",
    "OCCLUSION_ABS_TOL_M",
    "EPIPOLE_DEG",
    "POLE_LAT_DEG",
    "DISTANCE_BANDS_M",
    "REGION_NAMES",
    "texture_level",
    "occluded_from",
    "regions",
    "region_summaries",
]

#: sigma of the Gaussian blur applied to C's grey image before the gradient, pixels (suppresses render noise).
TEXTURE_BLUR_SIGMA_PX = 1.0
#: side of the square window over which the gradient magnitude is averaged, pixels (odd).
TEXTURE_WINDOW_PX = 5
#: a pixel is textureless when its window-averaged gradient magnitude is below this, 8-bit grey levels per pixel.
TEXTURELESS_GREY_PER_PX = 1.0
#: depth edge threshold of the ``discontinuity`` region: natural-log jump between 4-neighbours (ln 1.1).
DISCONTINUITY_LOG_JUMP = EDGE_LOG_JUMP
#: ``discontinuity`` covers pixels within this Chebyshev distance of a depth-edge pixel, pixels.
DISCONTINUITY_RADIUS_PX = 3
#: occlusion test tolerance, relative part: hidden if the range exceeds the sampled distance by more than
#: ``OCCLUSION_REL_TOL * sampled + OCCLUSION_ABS_TOL_M``.
OCCLUSION_REL_TOL = 0.02
#: occlusion test tolerance, absolute part, metres.
OCCLUSION_ABS_TOL_M = 0.01
#: half-angle of the cones about both baseline directions that make up the ``epipole`` regions, degrees.
EPIPOLE_DEG = 15.0
#: ``pole``: |latitude| of C's pixel centre above this, degrees.
POLE_LAT_DEG = 60.0
#: distance bands: name -> [lo, hi) of the true distance, metres.
DISTANCE_BANDS_M = {"d<2m": (0.0, 2.0), "d2-5m": (2.0, 5.0), "d>=5m": (5.0, math.inf)}
#: every region of :func:`regions`, in order.
REGION_NAMES = ("all", "textureless", "discontinuity", "occluded", "occluded_U", "occluded_R",
                "epipole", "epipole_U", "epipole_R", "pole", *DISTANCE_BANDS_M)


def texture_level(image) -> np.ndarray:
    """Local texture strength of an equirect image, in 8-bit grey levels per pixel.

    The grey image (OpenCV RGB->grey, 0..255) is blurred by a Gaussian of sigma :data:`TEXTURE_BLUR_SIGMA_PX`,
    its Sobel gradient magnitude is taken (:func:`reports.metrics.texture_magnitude`: a ramp of slope s reads
    s), and that magnitude is averaged over a :data:`TEXTURE_WINDOW_PX` square window (so a smooth blob's
    flat top inside a textured area is not called flat).  Columns wrap around, rows replicate.

    Args:
        image: (H, W, 3) uint8 RGB, or (H, W) grey.
    Returns:
        (H, W) float64, grey levels per pixel (>= 0).
    """
    g = grey(image).astype(np.float32)
    r = int(math.ceil(3 * TEXTURE_BLUR_SIGMA_PX))
    blurred = periodic_gaussian_blur(g, TEXTURE_BLUR_SIGMA_PX, cols=r, rows=r, row_mode="edge", ksize=2 * r + 1,
                                     border=cv2.BORDER_REFLECT_101)
    mag = texture_magnitude(blurred).astype(np.float32)
    w = TEXTURE_WINDOW_PX // 2
    mean = periodic_box_filter(mag, TEXTURE_WINDOW_PX, rows=w, row_mode="edge")
    return mean.astype(np.float64)


def occluded_from(frame, other: str, rel_tol: float = OCCLUSION_REL_TOL,
                  abs_tol_m: float = OCCLUSION_ABS_TOL_M) -> np.ndarray:
    """C's pixels whose surface point camera ``other`` cannot see (something nearer blocks its view).

    For a scored pixel of C with bearing ``a`` (world) and true distance ``d``, the surface point is
    ``X = C + d a``.  ``X`` is projected into camera ``other`` with its own pose, giving a continuous pixel
    ``(u, v)``; the ground truth ``D`` of ``other`` is read at the four pixel centres around it (columns wrap,
    rows clamp) and the pixel is occluded when ``|X - other.position| > max(D) * (1 + rel_tol) + abs_tol_m``,
    i.e. all four neighbouring rays of ``other`` stop clearly before ``X``.  Taking the maximum keeps points
    that are visible right beside an occluding edge (at sub-pixel precision) unflagged.

    Args:
        frame: a :class:`harness.data.frame.Frame` with ground truth for C and ``other``.
        other: "U" or "R" (any camera of the frame).
        rel_tol: relative tolerance (unitless); abs_tol_m: absolute tolerance, metres.
    Returns:
        (H, W) bool, False outside the scored pixels.
    """
    for name in ("C", other):
        if name not in frame.distance:
            raise ValueError(f"frame {frame.scene}/{frame.viewpoint} has no ground truth for camera {name}")
    c, k = frame.cameras["C"], frame.cameras[other]
    gt = np.asarray(frame.distance["C"], dtype=np.float64)
    dk = np.asarray(frame.distance[other], dtype=np.float64)
    h, w = gt.shape
    scored = scored_pixels(gt)
    bearings = bearing_grid(w, h, c.rotation)[scored]  # (N, 3) unit, world
    points = np.asarray(c.position, dtype=np.float64) + gt[scored][:, None] * bearings
    u, v = project(points, k.position, k.rotation, w, h)
    rng = np.linalg.norm(points - np.asarray(k.position, dtype=np.float64), axis=1)
    u0, v0 = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    cols = np.mod(np.stack([u0, u0 + 1]), w)
    rows = np.clip(np.stack([v0, v0 + 1]), 0, h - 1)
    seen = np.maximum(np.maximum(dk[rows[0], cols[0]], dk[rows[0], cols[1]]),
                      np.maximum(dk[rows[1], cols[0]], dk[rows[1], cols[1]]))
    out = np.zeros((h, w), dtype=bool)
    out[scored] = rng > seen * (1.0 + rel_tol) + abs_tol_m
    return out


def regions(frame) -> dict[str, np.ndarray]:
    """Every region of :data:`REGION_NAMES` over camera C's pixels.

    Args:
        frame: a :class:`harness.data.frame.Frame` with images and ground truth for C, U and R.
    Returns:
        name -> (H, W) bool mask, in the order of :data:`REGION_NAMES`, each a subset of ``all``.
    Raises:
        ValueError: the frame lacks ground truth for C, U or R.
    """
    missing = [n for n in ("C", "U", "R") if n not in frame.distance]
    if missing:
        raise ValueError(f"frame {frame.scene}/{frame.viewpoint} has no ground truth for camera(s) {missing}")
    gt = np.asarray(frame.distance["C"], dtype=np.float64)
    h, w = gt.shape
    valid = scored_pixels(gt)
    occ_u, occ_r = occluded_from(frame, "U"), occluded_from(frame, "R")
    epi = {}
    for name in ("U", "R"):
        ang = angle_to_baseline_deg(frame, name)
        epi[name] = (ang < EPIPOLE_DEG) | (ang > 180.0 - EPIPOLE_DEG)
    _, lat = pixel_to_lonlat(np.zeros((h, 1)), np.arange(h)[:, None], w, h)
    pole = np.broadcast_to(np.abs(np.degrees(lat)) > POLE_LAT_DEG, (h, w))
    out = {
        "all": valid,
        "textureless": texture_level(frame.images["C"]) < TEXTURELESS_GREY_PER_PX,
        "discontinuity": dilate_wrapped(depth_edges(gt, DISCONTINUITY_LOG_JUMP), DISCONTINUITY_RADIUS_PX),
        "occluded": occ_u | occ_r,
        "occluded_U": occ_u,
        "occluded_R": occ_r,
        "epipole": epi["U"] | epi["R"],
        "epipole_U": epi["U"],
        "epipole_R": epi["R"],
        "pole": pole,
    }
    with np.errstate(invalid="ignore"):
        out.update({name: (gt >= lo) & (gt < hi) for name, (lo, hi) in DISTANCE_BANDS_M.items()})
    return {name: out[name] & valid for name in REGION_NAMES}


def region_summaries(frame, pred, confidence=None, masks: dict[str, np.ndarray] | None = None) -> list[dict]:
    """Summary metrics of camera C's prediction in every region.

    Args:
        frame: a :class:`harness.data.frame.Frame` with ground truth.
        pred: (H, W) predicted distance of camera C, metres (invalid values scored as in reports.metrics).
        confidence: optional (H, W) confidence (adds ``ause``).
        masks: the frame's :func:`regions`, if already computed (e.g. once per frame for many methods).
    Returns:
        One dict per region, ``{"region": name, **summary}`` with the keys of :func:`reports.metrics.summary`,
        in region order; the ``all`` row equals ``summary(pred, gt, confidence)`` exactly.
    Raises:
        ValueError: missing ground truth, or ``pred`` / ``confidence`` not of the frame's shape.
    """
    masks = regions(frame) if masks is None else masks
    scored = ScoredMaps(pred, frame.distance["C"], confidence)
    return [{"region": name, **scored.summary(mask)} for name, mask in masks.items()]
