"""The reconstruction pipeline: flow -> per-pair triangulation -> ``average`` -> LM refinement variants.

>>> result = reconstruct(frame, flow="dis", rectify=True)        # doctest: +SKIP
>>> result.distance["gradient"]                                  # (H, W) float32 metres, camera C
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from reconstruction.equirect import bearing_grid
from reconstruction.matching import PairMatch, match_pair
from reconstruction.refine import (
    VARIANTS,
    ColorTerm,
    RefineConfig,
    RefineProblem,
    get_variant,
    levenberg_marquardt,
)
from reconstruction.triangulate import TriangulationLimits, pair_geometry, triangulate_sines
from reconstruction.weights import (
    angle_weight,
    epipolar_gradient,
    gradient_confidence,
    lateral_confidence,
    to_gray,
)

__all__ = ["DEFAULT_FLOW", "PAIRS", "Reconstruction", "reconstruct", "available_variants", "fuse_average",
           "fill_invalid"]

DEFAULT_FLOW = "dis"  # chosen by measurement, see docs/refinement.md
PAIRS = ("U", "R")


def available_variants() -> list[str]:
    """``average`` (no refinement) followed by the registered LM variants."""
    return ["average", *VARIANTS]


@dataclass
class Reconstruction:
    """Output of :func:`reconstruct`.

    Attributes:
        distance: (H, W) float32 distance of camera C per variant, metres (finite everywhere).
        pair_distance: (H, W) float32 per-pair triangulated distance ("U", "R"), metres.
        pair_valid: (H, W) bool per pair: False at the pair's epipoles or where its flow is unusable.
        seconds: wall time per stage (``flow_U``, ``flow_R``, ``triangulate``, ``average``, each variant).
        iterations: LM iterations per variant.
    """

    distance: dict[str, np.ndarray] = field(default_factory=dict)
    pair_distance: dict[str, np.ndarray] = field(default_factory=dict)
    pair_valid: dict[str, np.ndarray] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)
    iterations: dict[str, int] = field(default_factory=dict)


def fill_invalid(d: np.ndarray, valid: np.ndarray, max_sigma_px: float = 64.0) -> np.ndarray:
    """Fill pixels without a valid estimate from their valid neighbours (normalised convolution).

    Args:
        d: (H, W) distances, metres; valid: (H, W) bool.
        max_sigma_px: the largest Gaussian radius tried, pixels; sigma doubles from 2 until every pixel
            has support (any pixel still empty after that takes the median of the valid ones).
    Returns:
        (H, W) float64: ``d`` where valid, interpolated elsewhere.
    """
    if valid.all() or not valid.any():
        return d.astype(np.float64) if valid.all() else np.full(d.shape, 1.0)
    num_src = np.where(valid, d, 0.0).astype(np.float32)
    den_src = valid.astype(np.float32)
    out = d.astype(np.float64).copy()
    todo = ~valid
    sigma = 2.0
    while todo.any() and sigma <= max_sigma_px:
        num = cv2.GaussianBlur(num_src, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
        den = cv2.GaussianBlur(den_src, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
        ok = todo & (den > 1e-3)
        out[ok] = num[ok] / den[ok]
        todo &= ~ok
        sigma *= 2.0
    out[todo] = np.median(d[valid])
    return out


def fuse_average(d_pairs: Sequence[np.ndarray], valid: Sequence[np.ndarray], shape: tuple[int, int]) -> np.ndarray:
    """The paper's "before optimisation" distance: the mean of the pairs' distances.

    Where only one pair is valid its distance is used alone; where neither is (at both epipoles, or the
    flow failed for both), the distance is interpolated from neighbouring pixels (:func:`fill_invalid`).

    Args:
        d_pairs: per pair (N,) distances, metres; valid: per pair (N,) bool; shape: (H, W), N = H * W.
    Returns:
        (N,) fused distances, metres.
    """
    d = np.stack(d_pairs)
    v = np.stack(valid).astype(np.float64)
    n = v.sum(axis=0)
    mean_valid = (d * v).sum(axis=0) / np.maximum(n, 1.0)
    return fill_invalid(mean_valid.reshape(shape), (n > 0).reshape(shape)).reshape(-1)


def _color_terms(frame, config: RefineConfig, idx_shape) -> list[ColorTerm]:
    def prep(img):
        x = img.astype(np.float32) / 255.0 if config.color_rgb else to_gray(img)[..., None]
        if config.color_blur_px > 0:
            x = cv2.GaussianBlur(x, (0, 0), config.color_blur_px)
            x = x if x.ndim == 3 else x[..., None]
        return x

    ref = prep(frame.images["C"]).reshape(-1, 3 if config.color_rgb else 1).astype(np.float64)
    terms = []
    for k in PAIRS:
        img = prep(frame.images[k])
        du = (np.roll(img, -1, axis=1) - np.roll(img, 1, axis=1)) / 2.0  # wraps across the seam
        dv = np.zeros_like(img)
        dv[1:-1] = (img[2:] - img[:-2]) / 2.0
        cam = frame.cameras[k]
        terms.append(ColorTerm(stack=np.ascontiguousarray(np.concatenate([img, du, dv], axis=2)), ref=ref,
                               position=np.asarray(cam.position), rotation=np.asarray(cam.rotation)))
    return terms


def usable(geom, match: PairMatch, valid: np.ndarray, config: RefineConfig, height: int) -> np.ndarray:
    """(N,) bool: the pair's estimate is valid, its match lies within ``lateral_max_px`` of the epipolar
    curve and its flow is forward-backward consistent within ``fb_max_px`` (otherwise a failed match)."""
    lateral_px = np.abs(geom.off_plane) * height / np.pi
    return valid & (lateral_px <= config.lateral_max_px) & (match.fb_error_px.reshape(-1) <= config.fb_max_px)


def build_problem(frame, matches: dict[str, PairMatch], valid: dict[str, np.ndarray], config: RefineConfig,
                  bearings: np.ndarray, geoms: dict) -> RefineProblem:
    """Assemble the per-pixel least-squares problem of one variant (all of C's pixels).

    ``valid`` is per pair the (N,) mask of pixels where the pair may be used (see :func:`usable`).
    """
    weights = []
    gray = to_gray(frame.images["C"]) if config.gradient else None
    for k in PAIRS:
        w = angle_weight(geoms[k].sin_alpha, config.angle_power)
        w = w * lateral_confidence(geoms[k].off_plane, frame.height, config.lateral_px)
        if config.gradient:
            g = epipolar_gradient(gray, frame.cameras["C"].rotation, matches[k].rect_rotation, bearings)
            w = w * gradient_confidence(g, config.gradient_scale, config.gradient_floor)
        weights.append(np.where(valid[k], w, 0.0))
    color = _color_terms(frame, config, bearings.shape) if config.color_weight > 0 else []
    return RefineProblem(origin=np.asarray(frame.cameras["C"].position, np.float64), bearings=bearings,
                         pairs=[geoms[k] for k in PAIRS], weights=weights, height=frame.height,
                         width=frame.width, color=color, color_weight=config.color_weight,
                         color_saturation=config.color_saturation)


def reconstruct(frame, flow: str = DEFAULT_FLOW, rectify: bool = True, variants: Sequence[str] | None = None,
                limits: TriangulationLimits = TriangulationLimits(),
                on_stage: Callable[[str], None] | None = None) -> Reconstruction:
    """Reconstruct camera C's per-pixel distance from a frame's three images.

    Args:
        frame: a :class:`harness.frame.Frame`.
        flow: flow backend name (:func:`reconstruction.flow.available_flows`) or "oracle".
        rectify: compute each pair's flow on rectified images (default) or plain equirect ones.
        variants: which outputs to produce (default: all of :func:`available_variants`).
        limits: when a pair's estimate counts as invalid, and the distance clamp.
        on_stage: optional callback called with each stage name before it runs (progress display).
    Returns:
        A :class:`Reconstruction`.
    Raises:
        ValueError: unknown flow or variant, or the oracle without ground truth.
    """
    variants = list(available_variants() if variants is None else variants)
    configs = {v: get_variant(v) for v in variants if v != "average"}  # validate names before any work
    h, w = frame.height, frame.width
    out = Reconstruction()
    note = on_stage or (lambda _s: None)
    bearings = bearing_grid(w, h, frame.cameras["C"].rotation).reshape(-1, 3)

    matches = {}
    for k in PAIRS:
        note(f"flow_{k}")
        matches[k] = match_pair(frame, k, flow, rectify)
        out.seconds[f"flow_{k}"] = matches[k].seconds

    note("triangulate")
    start = time.perf_counter()
    geoms, d_pair, valid = {}, {}, {}
    for k in PAIRS:
        geoms[k] = pair_geometry(bearings, matches[k].baseline, matches[k].bearing.reshape(-1, 3))
        d_pair[k], valid[k] = triangulate_sines(geoms[k], limits)
        out.pair_distance[k] = d_pair[k].reshape(h, w).astype(np.float32)
        out.pair_valid[k] = valid[k].reshape(h, w)
    out.seconds["triangulate"] = time.perf_counter() - start

    start = time.perf_counter()
    d0 = fuse_average([d_pair[k] for k in PAIRS], [valid[k] for k in PAIRS], (h, w))
    out.seconds["average"] = time.perf_counter() - start
    if "average" in variants:
        out.distance["average"] = d0.reshape(h, w).astype(np.float32)

    for name, config in configs.items():
        note(name)
        start = time.perf_counter()
        ok = {k: usable(geoms[k], matches[k], valid[k], config, h) for k in PAIRS}
        problem = build_problem(frame, matches, ok, config, bearings, geoms)
        d, iters = levenberg_marquardt(problem, d0, limits.d_min_m, limits.d_max_m, config.max_iters, config.tol_m)
        any_ok = (ok["U"] | ok["R"]).reshape(h, w)
        d = fill_invalid(d.reshape(h, w), any_ok)
        out.seconds[name] = time.perf_counter() - start
        out.iterations[name] = iters
        out.distance[name] = d.reshape(h, w).astype(np.float32)
    return out
