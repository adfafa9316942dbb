"""The trinocular cost volume of camera C over distance hypotheses uniform in inverse distance.

For a pair (C, K), K in {U, R}, both images' features are resampled into the pair's rectified frame (+Z along
the world baseline ``K - C``; each image with its *own* camera rotation, so tilted rigs and cameras rotated
against each other are handled).  In that frame a point at distance ``d`` along C's rectified bearing of
colatitude ``theta`` (angle from the baseline) is seen by K on the same meridian (same column) at colatitude
``theta' = atan2(sin(theta), cos(theta) - b/d)`` (:func:`rect_row`).  For every pixel of C (at its own
continuous rectified column and row) and every hypothesis, K's rectified features are sampled bilinearly at
that column and row ``theta'``, compared with C's, truncated, weighted by ``sin^2`` of the angle between the
pixel's bearing and the pair's baseline, summed over both pairs and quantised to uint16 (then optionally
box-filtered): one fused numba pass in C's own equirect grid.

Features (computed in the rectified frame, so both images of a pair use the same axes): an image ``T`` and its
two derivatives along the rectified columns and rows (gray levels per pixel), weighted ``intensity_weight`` and
``gradient_weight``.  ``T`` is chosen by ``CostParams.feature`` (:data:`FEATURES`; docs/cost.md):

- ``"intensity"`` (the default): the gray intensity itself (0-255).  Cameras must agree in intensity (up to what the
  photometric self-calibration's gain model corrects).
- ``"rank"``: the rank transform (Zabih & Woodfill 1994), the number of the :data:`RANK_RADIUS_PX` window's
  ``(2 r + 1)^2 - 1`` neighbours strictly darker than the pixel, times ``255 / ((2 r + 1)^2 - 1)`` (0-255).  It
  depends only on the order of the intensities, so any increasing tone curve leaves it unchanged.
- ``"normalized"``: the locally normalised intensity ``NORM_SCALE * (g - mu) / sqrt(var + NORM_EPS^2)``, ``mu``
  and ``var`` the mean and variance of the gray image ``g`` in a Gaussian window of sigma :data:`NORM_SIGMA_PX`:
  unchanged by a gain and an offset, hence nearly so by any smooth increasing tone curve (locally affine) where
  the local contrast is well above ``NORM_EPS`` (below it, the plain high-passed intensity ``NORM_SCALE / NORM_EPS
  * (g - mu)``: flat, noisy areas are not amplified).

``CostParams.normalized_weight`` mixes the normalised intensity's cost into another feature's where C shows texture
(each pair's cost a weighted mean of both truncated differences; six features sampled instead of three).

The invariance holds for the rectified gray image; the gray conversion of per-channel curves and the bilinear
resampling into the rectified frame, which a tone curve does not commute with, make it approximate.

Both gain-free features follow Hirschmueller & Scharstein (2009), "Evaluation of stereo matching costs on images
with radiometric differences" (rank and mean/LoG-filtered costs; census and mutual information do not fit a
per-pixel feature compared by L1).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numba
import numpy as np

from reconstruction.camera.equirect import bearing_grid
from reconstruction.camera.image_ops import (
    central_differences,
    grey,
    local_contrast,
    periodic_gaussian_blur,
    periodic_pad,
)
from reconstruction.camera.resample import WRAP_PAD, rectifying_rotation, rotation_maps, warp_equirect

__all__ = ["CostParams", "PairWarp", "FEATURES", "RANK_RADIUS_PX", "NORM_SIGMA_PX", "NORM_EPS", "NORM_SCALE",
           "inverse_distances", "visibility_buffer", "gray_float", "rank_transform", "local_normalize",
           "feature_image", "prepare_pair", "build_cost_volume", "source_rows", "rect_row", "image_noise",
           "noise_blur_px", "blur_for_noise", "FLAT_NOISE_SCALE", "untextured", "flatten_untextured"]

#: the per-pixel features of the cost (``CostParams.feature``; module doc)
FEATURES = ("intensity", "rank", "normalized")
#: the scale of the noise estimate behind ``CostParams.flat_contrast`` (:func:`image_noise`): 2, where the noise
#: that JPEG coding flattened at the pixel scale still shows
FLAT_NOISE_SCALE = 2
#: radius of the rank transform's square window, pixels of the rectified image (7 x 7: 48 neighbours)
RANK_RADIUS_PX = 3
#: sigma of the Gaussian window of the local normalisation, pixels of the rectified image
NORM_SIGMA_PX = 5.0
#: floor of the local standard deviation of the local normalisation, gray levels (flat, noisy areas stay small)
NORM_EPS = 8.0
#: gray levels per local standard deviation of the normalised intensity
NORM_SCALE = 16.0
_LAPLACIAN_DIFFERENCE = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)


@dataclass(frozen=True)
class CostParams:
    """Parameters of the matching cost.

    Attributes:
        d_min_m, d_max_m: nearest and farthest distance hypothesis, metres.
        levels: number of sphere hypotheses, uniform in inverse distance between ``1/d_max_m`` and ``1/d_min_m``.
        blur_px: Gaussian sigma applied to the gray images before matching, pixels (0 = none).
        gradient_weight: weight of the summed absolute gradient differences (of the feature image ``T``, module
            doc) against the difference of ``T`` itself (dimensionless; gradients are gray levels per pixel).
        intensity_weight: weight of the absolute difference of ``T`` (the intensity by default; dimensionless;
            what is left of a gain difference between the cameras after the photometric self-calibration acts on
            it, the gradients much less).
        truncate: per-pair cost truncation, gray levels (robustness to reflections and occlusions).
        box_px: side of the box filter applied to each cost slice in C's grid, pixels (1 = none).
        scale: quantisation, uint16 cost units per gray level.
        pair_power: exponent of ``sin(angle to baseline)`` in each pair's weight (2 = sin^2).
        feature: the image ``T`` compared with its derivatives (:data:`FEATURES`, module doc): ``"intensity"``
            (gray levels, 0-255), ``"rank"`` (rank transform, 0-255) or ``"normalized"`` (locally normalised
            intensity, gray-level units, typically within +-3 :data:`NORM_SCALE`).
        noise_blur, noise_floor: the blur grows with the images' noise: ``blur_px`` becomes
            ``noise_blur * (noise - noise_floor)`` where that is larger (at most ``max_noise_blur_px``), with
            ``noise`` the largest :func:`image_noise` of the frame's images at ``noise_scale``, gray levels
            (:func:`noise_blur_px`);
            ``noise_blur`` in pixels per gray level, 0 = off.
        max_noise_blur_px: the largest blur the images' noise raises ``blur_px`` to, pixels.
        noise_scale: the scale at which the noise is estimated (:func:`image_noise`'s ``scale``): 1 = the images'
            pixels; 2 = images reduced by 2, where noise that JPEG coding flattened at the pixel scale still shows.
        occlusion: visibility from the hypothesis (0 = off): given a first estimate of C's distances, a pair does not
            vote for a hypothesis whose point that estimate puts more than this fraction of its range behind a
            surface seen from the pair's other camera (:func:`visibility_buffer`); the pairs that see it stand for
            both (their weighted cost scaled to the summed weight).
        occlusion_min_share: a hypothesis keeps every pair's vote unless the pairs that see it hold at least this
            share of the summed pair weight.
        flat_contrast: less preference where C shows no texture (0 = off): C's pixels whose local contrast
            (:func:`reconstruction.camera.image_ops.local_contrast` of C's gray image, sigma ``flat_sigma_px``) is
            below ``flat_contrast`` times C's noise (:func:`image_noise` at :data:`FLAT_NOISE_SCALE`, at least
            ``flat_min_noise`` gray levels) have their sphere hypotheses' costs moved towards the mean of theirs
            (``flat_weight``; :func:`flatten_untextured`): what the pairs say there is the noise's and the cameras'
            differences, so the aggregation fills them from their textured neighbours.
        flat_weight: how far those pixels' costs move to their mean, in [0, 1]: ``(1 - w) cost + w mean`` (1 = no
            preference left, 0.5 = half of it).
        flat_sigma_px: the contrast window's sigma, pixels (> 0).
        flat_min_noise: the least noise the threshold assumes, gray levels (noise-free renders still have
            quantisation and aliasing).
        normalized_weight: the locally normalised intensity's cost mixed in where C shows texture (0 = off): at C's
            pixels whose local contrast (as for ``flat_contrast``) is at least ``normalized_contrast`` times C's
            noise, each pair's cost is ``(1 - w)`` times the truncated difference of ``feature`` and its
            derivatives plus ``w`` times that of :func:`local_normalize` and its derivatives (each truncated at
            ``truncate``; the same weights), ``w = normalized_weight``; elsewhere ``feature``'s alone.  A
            view-dependent shading or sheen moves the intensity but hardly the normalised intensity; but that
            doubles a plain floor's noise (hence only where C shows texture) and spreads a polished floor's
            reflections over its window (docs/cost.md).  Within [0, 1]; where it applies, six features are compared
            instead of three (measured at 1000x500: the cost stage about 1.4 times as long, the default method
            about 1.1 times).  The sweep's coarse room-bound pass leaves it out
            (``reconstruction.methods.sweep.room_bounds``): on images half the size the window covers twice the
            angle, and a glossy lab's walls were no longer found there.
        normalized_contrast: the local contrast, in C's noise, from which the normalised cost is mixed in (>= 0).
    """

    d_min_m: float = 0.3
    d_max_m: float = 30.0
    levels: int = 160
    blur_px: float = 0.0
    gradient_weight: float = 2.0
    intensity_weight: float = 1.0
    truncate: float = 30.0
    box_px: int = 1
    scale: float = 8.0
    pair_power: float = 2.0
    feature: str = "intensity"
    noise_blur: float = 0.0
    noise_floor: float = 1.0
    max_noise_blur_px: float = 1.5
    noise_scale: int = 1
    occlusion: float = 0.0
    occlusion_min_share: float = 0.25
    flat_contrast: float = 0.0
    flat_weight: float = 1.0
    flat_sigma_px: float = 2.0
    flat_min_noise: float = 0.5
    normalized_weight: float = 0.0
    normalized_contrast: float = 1.0

    def __post_init__(self) -> None:
        if self.feature not in FEATURES:
            raise ValueError(f"unknown cost feature {self.feature!r} (known: {', '.join(FEATURES)})")
        if not (self.noise_blur >= 0 and self.noise_floor >= 0):
            raise ValueError(f"cost noise_blur {self.noise_blur} and noise_floor {self.noise_floor} must be >= 0")
        if not self.max_noise_blur_px >= 0:
            raise ValueError(f"cost max_noise_blur_px must be >= 0, got {self.max_noise_blur_px}")
        if type(self.noise_scale) is not int or self.noise_scale < 1:
            raise ValueError(f"cost noise_scale must be an integer >= 1, got {self.noise_scale!r}")
        if not (self.occlusion >= 0 and 0 <= self.occlusion_min_share <= 1):
            raise ValueError(f"cost occlusion {self.occlusion} must be >= 0 and occlusion_min_share "
                             f"{self.occlusion_min_share} within [0, 1]")
        if not (self.flat_contrast >= 0 and self.flat_sigma_px > 0 and self.flat_min_noise >= 0
                and 0 <= self.flat_weight <= 1):
            raise ValueError(f"cost flat_contrast {self.flat_contrast} and flat_min_noise {self.flat_min_noise} must "
                             f"be >= 0, flat_sigma_px {self.flat_sigma_px} > 0 and flat_weight {self.flat_weight} "
                             f"within [0, 1]")
        if not (0 <= self.normalized_weight <= 1 and self.normalized_contrast >= 0):
            raise ValueError(f"cost normalized_weight {self.normalized_weight} must be within [0, 1] and "
                             f"normalized_contrast {self.normalized_contrast} >= 0")
        if self.normalized_weight > 0 and self.feature == "normalized":
            raise ValueError("cost normalized_weight mixes the normalised intensity into another feature's cost; "
                             "with feature 'normalized' it must be 0")

    def max_cost(self) -> int:
        """Largest possible summed cost, uint16 units (both pairs' weights sum to at most 2)."""
        return int(np.ceil(2.0 * self.truncate * self.scale)) + 1


def image_noise(image: np.ndarray, scale: int = 1) -> float:
    """The noise of an 8-bit image, gray levels (standard deviation): Immerkaer's estimate (1996), the mean absolute
    response of the 3x3 Laplacian difference times ``sqrt(pi / 2) / 6``, over the flatter half of the pixels (the
    smaller half of the Sobel gradient), so that texture and edges do not count as noise.

    Args:
        image: (H, W, 3) uint8 RGB (or (H, W) gray).
        scale: estimate on the image reduced by this factor (mean of ``scale x scale`` blocks), times ``scale``: the
            same figure for white noise, which the mean divides by ``scale``, and a larger one for noise that is
            not white, such as what JPEG coding leaves of it (its 8 x 8 blocks keep the low frequencies); at most
            the factor that leaves 5 pixels a side.
    Returns:
        The estimate for the mean of the channels, gray levels (independent noise of ``s`` per channel is
        ``s / sqrt(3)`` there).
    """
    g = np.asarray(grey(image, "mean"), np.float32)
    scale = max(1, min(int(scale), g.shape[0] // 5, g.shape[1] // 5))  # the reduced image keeps 5 pixels a side
    if scale > 1:
        h, w = (g.shape[0] // scale) * scale, (g.shape[1] // scale) * scale
        g = scale * g[:h, :w].reshape(h // scale, scale, w // scale, scale).mean(axis=(1, 3), dtype=np.float32)
    response = np.abs(cv2.filter2D(g, -1, _LAPLACIAN_DIFFERENCE))[2:-2, 2:-2]
    grad = np.hypot(cv2.Sobel(g, cv2.CV_32F, 1, 0), cv2.Sobel(g, cv2.CV_32F, 0, 1))[2:-2, 2:-2]
    flat = grad <= np.median(grad)
    return float(np.sqrt(np.pi / 2.0) / 6.0 * response[flat].mean())


def blur_for_noise(noise: float, per_level: float, floor: float, max_px: float) -> float:
    """A blur that grows with an image's noise: ``per_level * (noise - floor)`` pixels, at most ``max_px``; 0 where
    ``per_level`` is 0 or ``noise`` is not above ``floor`` (``noise``, ``floor`` in gray levels, ``per_level`` in
    pixels per gray level)."""
    if per_level <= 0 or not noise > floor:
        return 0.0
    return min(per_level * (noise - floor), max_px)


def noise_blur_px(params: CostParams, noise: float) -> float:
    """The blur (pixels) of ``params`` for images of ``noise`` gray levels (``CostParams.noise_blur``)."""
    return max(params.blur_px, blur_for_noise(noise, params.noise_blur, params.noise_floor, params.max_noise_blur_px))


def inverse_distances(params: CostParams) -> np.ndarray:
    """(levels,) float64 inverse distances of the sphere hypotheses, 1/metres, ascending (far to near)."""
    return np.linspace(1.0 / params.d_max_m, 1.0 / params.d_min_m, params.levels)


def gray_float(image: np.ndarray, blur_px: float) -> np.ndarray:
    """(H, W, 3) uint8 RGB -> (H, W) float32 gray, 0-255, optionally Gaussian-blurred (sigma ``blur_px``)."""
    g = grey(image).astype(np.float32)
    return np.ascontiguousarray(periodic_gaussian_blur(g, blur_px))


def rank_transform(gray: np.ndarray, radius: int = RANK_RADIUS_PX) -> np.ndarray:
    """The rank transform of an equirect gray image, in gray-level units.

    Args:
        gray: (H, W) float32 gray levels (any monotonic scale: only their order matters).
        radius: half side of the square window, pixels (wrapping in longitude, mirrored at the poles).
    Returns:
        (H, W) float32 in [0, 255]: the number of the window's ``(2 radius + 1)^2 - 1`` neighbours strictly
        darker than the pixel, times ``255 / ((2 radius + 1)^2 - 1)``.
    """
    h, w = gray.shape
    side = 2 * radius + 1
    padded = periodic_pad(gray, radius, radius, "reflect")
    count = np.zeros((h, w), np.uint8)
    for dy in range(side):
        for dx in range(side):
            if dy != radius or dx != radius:
                count += padded[dy:dy + h, dx:dx + w] < gray
    return count.astype(np.float32) * np.float32(255.0 / (side * side - 1))


def local_normalize(gray: np.ndarray, sigma_px: float = NORM_SIGMA_PX, eps: float = NORM_EPS,
                    scale: float = NORM_SCALE) -> np.ndarray:
    """The locally normalised intensity of an equirect gray image, in gray-level units.

    Args:
        gray: (H, W) float32 gray levels, 0-255.
        sigma_px: sigma of the Gaussian window, pixels (wrapping in longitude, mirrored at the poles).
        eps: floor of the local standard deviation, gray levels.
        scale: gray levels per local standard deviation.
    Returns:
        (H, W) float32 ``scale * (g - mu) / sqrt(var + eps^2)``, ``mu`` and ``var`` the window's Gaussian-weighted
        mean and variance of ``g``; typically within +-``3 scale``.
    """
    pad = int(np.ceil(3 * sigma_px))
    g = np.asarray(gray, np.float32)

    def blur(x):
        return periodic_gaussian_blur(x, sigma_px, cols=pad, rows=pad, row_mode="reflect")

    mu = blur(g)
    var = np.maximum(blur(g * g) - mu * mu, 0.0)
    out = (g - mu) * (np.float32(scale) / np.sqrt(var + np.float32(eps * eps)))
    return np.ascontiguousarray(out, dtype=np.float32)


def feature_image(gray_rect: np.ndarray, feature: str) -> np.ndarray:
    """(H, W) rectified gray (0-255) -> (H, W) float32 image ``T`` of ``feature`` (:data:`FEATURES`, module doc):
    the gray itself, its rank transform or its local normalisation, gray-level units."""
    if feature == "intensity":
        return gray_rect
    if feature == "rank":
        return rank_transform(gray_rect)
    if feature == "normalized":
        return local_normalize(gray_rect)
    raise ValueError(f"unknown cost feature {feature!r} (known: {', '.join(FEATURES)})")


def _features(gray_rect: np.ndarray, gradient_weight: float, intensity_weight: float = 1.0,
              feature: str = "intensity") -> np.ndarray:
    """(H, W) rectified gray -> (3, H, W) float32: the weighted feature image ``T`` (:func:`feature_image`; the
    intensity by default) and its weighted d/du (wrapping), d/dv, gray levels (per pixel)."""
    gray_rect = feature_image(gray_rect, feature)
    gu, gv = central_differences(gray_rect)
    return np.stack([intensity_weight * gray_rect, gradient_weight * gu, gradient_weight * gv]).astype(np.float32)


@dataclass
class PairWarp:
    """Everything one pair needs to produce cost slices (built once per frame; depends only on the rig).

    Attributes:
        name: the other camera's name ("U" or "R").
        baseline_m: |K - C|, metres.
        rect_rotation: (3, 3) world-from-rectified rotation (+Z along the baseline).
        ref: (F, H, W) float32 features of C in the rectified frame (F = 3, or 6 with
            ``CostParams.normalized_weight``).
        other: (F, H, W) float32 features of K in the rectified frame.
        cos_theta, sin_theta: (H,) cos / sin of each rectified row's colatitude.
        weight: (H, W) float32 pair weight in C's grid, ``sin(angle to baseline) ** pair_power``.
    """

    name: str
    baseline_m: float
    rect_rotation: np.ndarray
    ref: np.ndarray
    other: np.ndarray
    cos_theta: np.ndarray
    sin_theta: np.ndarray
    weight: np.ndarray


def _pair_features(gray_rect: np.ndarray, params: CostParams) -> np.ndarray:
    """(H, W) rectified gray -> (3, H, W) float32 weighted features of ``params.feature`` (:func:`_features`), and
    with ``params.normalized_weight`` the normalised intensity's three after them: (6, H, W)."""
    feats = _features(gray_rect, params.gradient_weight, params.intensity_weight, params.feature)
    if params.normalized_weight <= 0:
        return feats
    return np.concatenate([feats, _features(gray_rect, params.gradient_weight, params.intensity_weight, "normalized")])


def prepare_pair(frame, name: str, gray: dict, params: CostParams) -> PairWarp:
    """Rectify one pair's features and compute its rectified row colatitudes and its pair weight.

    Args:
        frame: a frame (``cameras`` with ``position``/``rotation``, ``width``, ``height``).
        name: "U" or "R".
        gray: (H, W) float32 gray image per camera name (:func:`gray_float`).
    """
    h, w = frame.height, frame.width
    cam_c, cam_k = frame.cameras["C"], frame.cameras[name]
    base = np.asarray(cam_k.position, np.float64) - np.asarray(cam_c.position, np.float64)
    b = float(np.linalg.norm(base))
    rect = rectifying_rotation(base, cam_c.rotation)
    ref, other = (_pair_features(warp_equirect(gray[k], rect, cam.rotation), params)
                  for k, cam in (("C", cam_c), (name, cam_k)))
    theta = np.pi * (np.arange(h) + 0.5) / h
    bear = bearing_grid(w, h, cam_c.rotation)
    cos_b = bear @ (base / b)
    sin2 = np.clip(1.0 - cos_b * cos_b, 0.0, 1.0)
    weight = (sin2 ** (0.5 * params.pair_power)).astype(np.float32)
    return PairWarp(name, b, rect, ref, other, np.cos(theta), np.sin(theta), weight)


def rect_row(v_rect, baseline_m: float, inv_d: float, height: int):
    """Rectified row of K that sees the point at inverse distance ``inv_d`` (1/m) along C's rectified row
    ``v_rect`` (continuous pixels; same column).  ``theta' = atan2(sin theta, cos theta - b / d)``.

    Args:
        v_rect: array of continuous rectified rows of C; baseline_m: |K - C|, metres; height: H, pixels.
    Returns:
        Continuous rectified rows of K, same shape.
    """
    theta = np.pi * (np.asarray(v_rect, np.float64) + 0.5) / height
    theta2 = np.arctan2(np.sin(theta), np.cos(theta) - baseline_m * inv_d)
    return theta2 * height / np.pi - 0.5


def source_rows(pair: PairWarp, inv_d: float, height: int) -> np.ndarray:
    """(H,) float64: the rectified row of K seen by each rectified row of C at inverse distance ``inv_d`` (1/m)."""
    theta2 = np.arctan2(pair.sin_theta, pair.cos_theta - pair.baseline_m * inv_d)
    return theta2 * height / np.pi - 0.5


def _pair_arrays(pw: PairWarp, frame):
    """Per-pixel arrays of one pair in C's grid for :func:`_sweep_costs`.

    Returns:
        ``(other_t, ref, ur, vr)``: (W, H, F) K's rectified features transposed (columns contiguous),
        (H, W, F) C's rectified features at each C pixel, (H, W) rectified column and row of each C pixel
        (float32, pixels).
    """
    h, w = frame.height, frame.width
    mu, mv = rotation_maps(w, h, frame.cameras["C"].rotation, pw.rect_rotation)
    mu = np.mod(mu + 0.5, w) - 0.5
    feats = np.ascontiguousarray(pw.ref.transpose(1, 2, 0))
    padded = periodic_pad(feats, WRAP_PAD)
    ref = cv2.remap(padded, (mu + WRAP_PAD).astype(np.float32), mv.astype(np.float32), cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE)
    other_t = np.ascontiguousarray(pw.other.transpose(2, 1, 0))
    return other_t, ref, mu.astype(np.float32), mv.astype(np.float32)


def build_cost_volume(frame, params: CostParams, extra_labels: int = 0, pairs=("U", "R"),
                      out: np.ndarray | None = None, estimate: np.ndarray | None = None):
    """The sphere-sweep cost volume of camera C.

    For every pixel of C and pair, C's rectified features at the pixel are compared with K's rectified features
    (bilinear) at the same rectified column and the row of each hypothesis (:func:`rect_row`); the truncated
    feature difference is weighted by the pair weight, summed over the pairs, quantised and box-filtered.  One
    fused numba pass over all hypotheses (no per-label Python loop).

    Args:
        frame: a frame with ``images`` (H, W, 3) uint8 and posed ``cameras`` C, U, R.
        params: cost parameters.
        extra_labels: further labels to allocate after the sphere hypotheses (filled by other families).
        pairs: which pairs to use (ablation).
        out: optional preallocated (H, W, levels + extra_labels) uint16 array.
        estimate: (H, W) a first estimate of C's distances, metres, for ``params.occlusion`` (None: every pair
            votes everywhere).
    Returns:
        ``(cost, pairs)``: (H, W, levels + extra_labels) uint16 costs (sphere labels filled, ``scale`` units per
        gray level, at most :meth:`CostParams.max_cost`) and the :class:`PairWarp` of each pair.
    """
    h, w = frame.height, frame.width
    gray = {k: gray_float(frame.images[k], params.blur_px) for k in ("C", *pairs)}
    warps = [prepare_pair(frame, k, gray, params) for k in pairs]
    n = params.levels + extra_labels
    cost = np.empty((h, w, n), np.uint16) if out is None else out
    arrays = [_pair_arrays(pw, frame) for pw in warps]
    other_t = np.stack([a[0] for a in arrays])
    ref = np.stack([a[1] for a in arrays])
    ur = np.stack([a[2] for a in arrays])
    vr = np.stack([a[3] for a in arrays])
    inv_d = inverse_distances(params)
    rows = np.stack([np.clip(np.stack([source_rows(pw, q, h) for q in inv_d], axis=1), 0.0, h - 1.0)
                     for pw in warps]).astype(np.float32)
    weight = np.stack([pw.weight * np.float32(params.scale) for pw in warps]).astype(np.float32)
    del arrays
    occlusion = params.occlusion if estimate is not None else 0.0
    zbuf = (np.stack([visibility_buffer(estimate, ur[k], vr[k], pw.baseline_m, other_t.shape[1], other_t.shape[2])
                      for k, pw in enumerate(warps)]) if occlusion > 0 else np.zeros((len(warps), 1, 1), np.float32))
    baselines = np.array([pw.baseline_m for pw in warps], np.float64)
    contrast = (_contrast_and_noise(frame.images["C"], params)
                if params.normalized_weight > 0 or params.flat_contrast > 0 else None)
    mix = (np.float32(params.normalized_weight) * ~_low_contrast(*contrast, params.normalized_contrast)
           if params.normalized_weight > 0 else np.zeros((1, 1), np.float32)).astype(np.float32)
    _sweep_costs(cost, params.levels, other_t, ref, ur, vr, rows, weight, np.float32(params.truncate), zbuf,
                 inv_d, baselines, np.float32(occlusion), np.float32(params.occlusion_min_share), mix)
    box = int(params.box_px)
    if box > 1:
        _box_lines(cost, params.levels, box // 2, True, np.float32(1.0))  # along longitude, which wraps
        _box_lines(cost.transpose(1, 0, 2), params.levels, box // 2, False, np.float32(1.0 / (box * box)))
    if params.flat_contrast > 0:
        flatten_untextured(cost, params.levels, _low_contrast(*contrast, params.flat_contrast), params.flat_weight)
    return cost, warps


def untextured(image: np.ndarray, params: CostParams) -> np.ndarray:
    """Where C shows no texture above its noise (``CostParams.flat_contrast``).

    Args:
        image: (H, W, 3) uint8 RGB of C.
        params: ``flat_contrast``, ``flat_sigma_px`` and ``flat_min_noise`` are read.
    Returns:
        (H, W) bool: local contrast below ``flat_contrast * max(noise, flat_min_noise)`` (gray levels); all False
        when ``flat_contrast`` is 0.
    """
    if params.flat_contrast <= 0:
        return np.zeros(image.shape[:2], bool)
    return _low_contrast(*_contrast_and_noise(image, params), params.flat_contrast)


def _contrast_and_noise(image: np.ndarray, params: CostParams) -> tuple[np.ndarray, float]:
    """C's local contrast ((H, W) float32, sigma ``params.flat_sigma_px``) and noise (:func:`image_noise` at
    :data:`FLAT_NOISE_SCALE`, at least ``params.flat_min_noise``), gray levels."""
    noise = max(image_noise(image, FLAT_NOISE_SCALE), params.flat_min_noise)
    return local_contrast(gray_float(image, 0.0), params.flat_sigma_px), noise


def _low_contrast(contrast: np.ndarray, noise: float, factor: float) -> np.ndarray:
    """(H, W) bool: ``contrast`` below ``factor`` times ``noise`` (:func:`_contrast_and_noise`)."""
    return contrast < factor * noise


def flatten_untextured(cost: np.ndarray, levels: int, mask: np.ndarray, weight: float = 1.0) -> None:
    """Move the first ``levels`` costs of the pixels of ``mask`` towards their mean, in place: each becomes
    ``floor((1 - weight) cost + weight mean)`` (the labels after them, planes and walls, are not touched).

    Args:
        cost: (H, W, L) uint16 cost volume, L >= ``levels``.
        levels: the number of sphere hypotheses (the first labels).
        mask: (H, W) bool.
        weight: in [0, 1]; 1 gives every hypothesis the floor of the mean (no preference left).
    """
    if mask.shape != cost.shape[:2] or not 0 < levels <= cost.shape[2]:
        raise ValueError(f"mask {mask.shape} and levels {levels} do not fit a cost volume of shape {cost.shape}")
    if not 0 <= weight <= 1:
        raise ValueError(f"weight {weight} is not within [0, 1]")
    _flatten_rows(cost, int(levels), np.ascontiguousarray(mask), float(weight))


@numba.njit(parallel=True, cache=True)
def _flatten_rows(cost, levels, mask, weight):
    h, w, _ = cost.shape
    for y in numba.prange(h):
        for x in range(w):
            if mask[y, x]:
                total = 0
                for i in range(levels):
                    total += np.int64(cost[y, x, i])
                pull = weight * (total / levels)
                for i in range(levels):
                    cost[y, x, i] = np.uint16(np.floor((1.0 - weight) * cost[y, x, i] + pull))


def visibility_buffer(estimate: np.ndarray, ur: np.ndarray, vr: np.ndarray, baseline_m: float, width: int,
                      height: int) -> np.ndarray:
    """The range from the pair's other camera K to the nearest surface of C's distance estimate along each of K's
    rectified rays: C's pixels moved to where K sees them, each covering the 2 x 2 rectified pixels around it.

    Args:
        estimate: (H, W) C's distances, metres (not finite or <= 0: left out).
        ur, vr: (H, W) rectified column and row of C's pixels, pixels.
        baseline_m: |K - C|, metres; width, height: the rectified grid's size, pixels.
    Returns:
        (width, height) float32 ranges from K, metres (columns first, as K's rectified features in
        :func:`_sweep_costs`); inf where no pixel of C lands.
    """
    zbuf = np.full((width, height), np.inf, np.float32)
    _splat_ranges(zbuf, np.asarray(estimate, np.float64), ur, vr, float(baseline_m))
    return zbuf


@numba.njit(cache=True)
def _splat_ranges(zbuf, d, ur, vr, b):
    wr, hr = zbuf.shape
    h, w = d.shape
    for y in range(h):
        for x in range(w):
            dist = d[y, x]
            if not (dist > 0.0 and dist < np.inf):
                continue
            theta = np.pi * (vr[y, x] + 0.5) / hr
            st, ct = np.sin(theta), np.cos(theta) - b / dist
            row = np.arctan2(st, ct) * hr / np.pi - 0.5
            rng = np.float32(dist * np.sqrt(st * st + ct * ct))
            c0 = int(np.floor(ur[y, x]))
            r0 = int(np.floor(row))
            for dc in range(2):
                c = (c0 + dc) % wr
                for dr in range(2):
                    r = r0 + dr
                    if 0 <= r < hr and rng < zbuf[c, r]:
                        zbuf[c, r] = rng


@numba.njit(inline="always", fastmath=True)
def _normalized_l1(other_t, p, c0, c1, j0, tv, tu, ref, y, x):
    """The summed absolute difference of features 3-5 (the normalised intensity and its derivatives) of C at
    ``(y, x)`` and of K bilinearly at columns ``c0, c1`` (weight ``tu`` on ``c1``) and rows ``j0, j0 + 1`` (weight
    ``tv`` on ``j0 + 1``)."""
    s = np.float32(0.0)
    for k in range(3, 6):
        a = other_t[p, c0, j0, k] + tv * (other_t[p, c0, j0 + 1, k] - other_t[p, c0, j0, k])
        b = other_t[p, c1, j0, k] + tv * (other_t[p, c1, j0 + 1, k] - other_t[p, c1, j0, k])
        s += abs(a + tu * (b - a) - ref[p, y, x, k])
    return s


@numba.njit(parallel=True, cache=True, fastmath=True)
def _sweep_costs(cost, n_levels, other_t, ref, ur, vr, rows, weight, truncate, zbuf, inv_d, baselines, occlusion,
                 min_share, mix):
    # cost: (H, W, >= n_levels) uint16 out; other_t: (P, W, H, F) K's rectified features, columns contiguous, F = 3
    # (a feature and its two derivatives) or 6 (then the normalised intensity's three after them); ref: (P, H, W,
    # F) C's rectified features at C's pixels; ur, vr: (P, H, W) rectified column / row of C's pixels; rows: (P, H,
    # n_levels) K's rectified row seen by each integer rectified row of C per hypothesis; weight: (P, H, W) pair
    # weight times the cost scale; zbuf: (P, W, H) visibility_buffer per pair (used when occlusion > 0); inv_d:
    # (n_levels,) 1/m; baselines: (P,) metres; mix: (H, W) weight of the second three features' truncated
    # difference against the first three's (read only when F = 6).
    h, w, _ = cost.shape
    second = other_t.shape[3] == 6
    n_pairs, wr, hr, _ = other_t.shape
    for y in numba.prange(h):
        acc = np.empty(n_levels, np.float32)
        pair = np.empty(n_levels, np.float32)
        seen = np.empty(n_levels, np.float32)
        seen_w = np.empty(n_levels, np.float32)
        for x in range(w):
            acc[:] = 0.0
            if occlusion > 0.0:
                seen[:] = 0.0
                seen_w[:] = 0.0
            total_w = np.float32(0.0)
            for p in range(n_pairs):
                wt = weight[p, y, x]
                if wt <= 0.0:
                    continue
                total_w += wt
                r0 = ref[p, y, x, 0]
                r1 = ref[p, y, x, 1]
                r2 = ref[p, y, x, 2]
                m = mix[y, x] if second else np.float32(0.0)
                u = ur[p, y, x]
                fu = np.floor(u)
                tu = np.float32(u - fu)
                c0 = int(fu) % wr
                c1 = (c0 + 1) % wr
                v = min(max(vr[p, y, x], 0.0), hr - 1.0)
                v0 = min(int(v), hr - 2)
                t = np.float32(v - v0)
                ra = rows[p, v0]
                rb = rows[p, v0 + 1]
                for i in range(n_levels):
                    row = ra[i] + t * (rb[i] - ra[i])
                    j0 = min(int(row), hr - 2)
                    tv = np.float32(row - j0)
                    a0 = other_t[p, c0, j0, 0] + tv * (other_t[p, c0, j0 + 1, 0] - other_t[p, c0, j0, 0])
                    b0 = other_t[p, c1, j0, 0] + tv * (other_t[p, c1, j0 + 1, 0] - other_t[p, c1, j0, 0])
                    a1 = other_t[p, c0, j0, 1] + tv * (other_t[p, c0, j0 + 1, 1] - other_t[p, c0, j0, 1])
                    b1 = other_t[p, c1, j0, 1] + tv * (other_t[p, c1, j0 + 1, 1] - other_t[p, c1, j0, 1])
                    a2 = other_t[p, c0, j0, 2] + tv * (other_t[p, c0, j0 + 1, 2] - other_t[p, c0, j0, 2])
                    b2 = other_t[p, c1, j0, 2] + tv * (other_t[p, c1, j0 + 1, 2] - other_t[p, c1, j0, 2])
                    s = (abs(a0 + tu * (b0 - a0) - r0) + abs(a1 + tu * (b1 - a1) - r1)
                         + abs(a2 + tu * (b2 - a2) - r2))
                    if m > 0.0:  # the normalised intensity's three features mixed in
                        s2 = _normalized_l1(other_t, p, c0, c1, j0, tv, tu, ref, y, x)
                        pair[i] = wt * ((1.0 - m) * min(s, truncate) + m * min(s2, truncate))
                    else:
                        pair[i] = wt * min(s, truncate)
                for i in range(n_levels):
                    acc[i] += pair[i]
                if occlusion > 0.0:  # the hypotheses the estimate lets K see, and this pair's vote for them
                    theta = np.pi * (v + 0.5) / hr
                    st = np.sin(theta)
                    ct = np.cos(theta)
                    b = baselines[p]
                    for i in range(n_levels):
                        q = inv_d[i]
                        dz = ct - b * q
                        rng = np.sqrt(st * st + dz * dz) / q
                        row = ra[i] + t * (rb[i] - ra[i])
                        j0 = min(int(row), hr - 2)
                        z = max(max(zbuf[p, c0, j0], zbuf[p, c0, j0 + 1]), max(zbuf[p, c1, j0], zbuf[p, c1, j0 + 1]))
                        if rng <= z * (1.0 + occlusion):
                            seen[i] += pair[i]
                            seen_w[i] += wt
            if occlusion > 0.0:
                for i in range(n_levels):
                    if seen_w[i] < total_w and seen_w[i] >= min_share * total_w:
                        acc[i] = seen[i] * total_w / seen_w[i]
            for i in range(n_levels):
                cost[y, x, i] = np.uint16(acc[i] + 0.5)


@numba.njit(parallel=True, cache=True)
def _box_lines(lines, n_levels, r, wrap, norm):
    """In place: each of the (N, L, n_levels) uint16 ``lines`` (any strides) box-filtered along its axis 1, the sum
    over the 2 r + 1 neighbours (wrapping around when ``wrap``, else clamped at both ends) times ``norm``, rounded."""
    n, length, _ = lines.shape
    for a in numba.prange(n):
        tmp = np.empty((length, n_levels), np.int32)
        for b in range(length):
            for i in range(n_levels):
                tmp[b, i] = lines[a, b, i]
        for b in range(length):
            for i in range(n_levels):
                s = np.int32(0)
                for d in range(-r, r + 1):
                    k = (b + d) % length if wrap else min(max(b + d, 0), length - 1)
                    s += tmp[k, i]
                lines[a, b, i] = np.uint16(s * norm + 0.5)
