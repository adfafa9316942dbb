"""The Levenberg-Marquardt refinement of the flow pipeline's distance: one variant (a :class:`RefineConfig`) on the
shared stages (:class:`reconstruction.methods.flow_stages.Prepared`).

The match checks (:func:`match_checks`), the per-pixel least-squares problem of a variant with its pair weights and
colour terms (:func:`build_problem`, :func:`variant_problem`), the replacement of outliers among unchecked pixels
(:func:`replace_outliers`) and the variant run from the ``average`` fusion or any start (:func:`refine_variant`).
The solver and the variants' registry are :mod:`reconstruction.refine.lm`.
"""

from __future__ import annotations

import cv2
import numpy as np

from reconstruction.camera.image_ops import central_differences
from reconstruction.flow.matching import PairMatch
from reconstruction.methods.flow_stages import PAIRS, Prepared
from reconstruction.refine.fill import fill_edge_aware
from reconstruction.refine.lm import (
    ColorTerm,
    RefineConfig,
    RefineProblem,
    levenberg_marquardt,
    patch_offsets,
    patch_reference,
)
from reconstruction.refine.weights import (
    angle_weight,
    epipolar_gradient,
    gradient_confidence,
    lateral_confidence,
    to_gray,
)

__all__ = ["color_texture_mask", "match_checks", "build_problem", "replace_outliers", "variant_problem",
           "refine_variant"]


def _color_terms(frame, config: RefineConfig, bearings: np.ndarray) -> list[ColorTerm]:
    """Colour-residual data of both pairs: blurred intensities (gray or RGB, in [0, 1])."""
    def prep(img):
        x = img.astype(np.float32) / 255.0 if config.color_rgb else to_gray(img)[..., None]
        if config.color_blur_px > 0:
            x = cv2.GaussianBlur(x, (0, 0), config.color_blur_px)
            x = x if x.ndim == 3 else x[..., None]
        return x.astype(np.float64)

    offsets = patch_offsets(config.color_patch) if config.color_patch > 1 else None
    ref_img = prep(frame.images["C"])
    ref = ref_img.reshape(-1, ref_img.shape[2]) if offsets is None else patch_reference(ref_img, offsets)
    origin = np.asarray(frame.cameras["C"].position, np.float64)
    terms = []
    for k in PAIRS:
        cam = frame.cameras[k]
        rot = np.asarray(cam.rotation, np.float64)
        terms.append(ColorTerm(image=prep(frame.images[k]), ref=ref,
                               start=(origin - np.asarray(cam.position, np.float64)) @ rot,
                               direction=bearings @ rot, offsets=offsets))
    return terms


def color_texture_mask(image: np.ndarray, config: RefineConfig) -> np.ndarray:
    """(H, W) bool: pixels of C whose blurred gray gradient magnitude exceeds ``config.color_min_gradient``."""
    gray = to_gray(image)
    if config.color_blur_px > 0:
        gray = cv2.GaussianBlur(gray, (0, 0), config.color_blur_px)
    gu, gv = central_differences(gray)
    return np.hypot(gu, gv) > config.color_min_gradient


def match_checks(geom, match: PairMatch, valid: np.ndarray, config: RefineConfig, height: int) -> np.ndarray:
    """(N,) bool: the pair's estimate is valid, its match lies within ``lateral_max_px`` of the epipolar
    curve and its flow is forward-backward consistent within ``fb_max_px``."""
    lateral_px = np.abs(geom.off_plane) * height / np.pi
    return valid & (lateral_px <= config.lateral_max_px) & (match.fb_error_px.reshape(-1) <= config.fb_max_px)


def build_problem(frame, matches: dict[str, PairMatch], valid: dict[str, np.ndarray], checked: dict[str, np.ndarray],
                  config: RefineConfig, bearings: np.ndarray, geoms: dict) -> RefineProblem:
    """Assemble the per-pixel least-squares problem of one variant (all of C's pixels).

    Args:
        valid: per pair, (N,) pixels where the pair's triangulation is meaningful (weight 0 elsewhere).
        checked: per pair, (N,) pixels whose match passed :func:`match_checks` (others are down-weighted
            by ``config.fallback_weight``).
    """
    weights = []
    gray = to_gray(frame.images["C"]) if config.gradient else None
    for k in PAIRS:
        w = angle_weight(geoms[k].sin_alpha, config.angle_power)
        w = w * lateral_confidence(geoms[k].off_plane, frame.height, config.lateral_px)
        if config.gradient:
            g = epipolar_gradient(gray, frame.cameras["C"].rotation, matches[k].rect_rotation, bearings)
            w = w * gradient_confidence(g, config.gradient_scale, config.gradient_floor)
        w = w * np.where(checked[k], 1.0, config.fallback_weight)
        weights.append(np.where(valid[k], w, 0.0))
    color = _color_terms(frame, config, bearings) if config.color_weight > 0 else []
    return RefineProblem(origin=np.asarray(frame.cameras["C"].position, np.float64), bearings=bearings,
                         pairs=[geoms[k] for k in PAIRS], weights=weights, height=frame.height,
                         width=frame.width, color=color, color_weight=config.color_weight,
                         color_saturation=config.color_saturation)


def replace_outliers(d: np.ndarray, checked_any: np.ndarray, guide: np.ndarray, config: RefineConfig) -> np.ndarray:
    """Where no pair passed the checks, replace results far from the edge-aware interpolation of checked
    neighbours by that interpolation (see ``RefineConfig.outlier_log_ratio``).  (H, W) arrays, metres."""
    if checked_any.all() or not checked_any.any():
        return d
    fill = fill_edge_aware(d, checked_any, guide, config.fill_lambda, config.fill_sigma_color)
    outlier = ~checked_any & (np.abs(np.log(d / fill)) > config.outlier_log_ratio)
    return np.where(outlier, fill, d)


def variant_problem(frame, prep: Prepared, config: RefineConfig):
    """The least-squares problem of one variant over all of C's pixels.

    Returns:
        ``(problem, checked)``: the :class:`RefineProblem` (with its colour terms, if any) and per pair the
        (N,) mask of pixels whose match passed :func:`match_checks`.
    """
    checked = {k: match_checks(prep.geoms[k], prep.matches[k], prep.valid[k], config, frame.height) for k in PAIRS}
    problem = build_problem(frame, prep.matches, prep.valid, checked, config, prep.bearings, prep.geoms)
    return problem, checked


def refine_variant(frame, prep: Prepared, config: RefineConfig, start: np.ndarray | None = None):
    """Run one refinement variant from ``prep.d0`` (or from ``start``: any method's distance).

    Two stages: LM on the geometric residuals to convergence, then (colour variants) ``color_iters`` LM
    iterations with the colour residuals added, on textured pixels only; finally outliers among pixels
    without a checked pair are replaced (:func:`replace_outliers`).

    Args:
        start: optional (H, W) start distances, metres (e.g. another method's output; non-finite or
            non-positive pixels start from ``prep.d0``); None = the ``average`` fusion ``prep.d0``.
    Returns:
        ``(d, iterations)``: (H, W) float64 refined distances, metres, and the LM iterations run.
    """
    h, w = frame.height, frame.width
    lim = prep.limits
    problem, checked = variant_problem(frame, prep, config)
    color, problem.color = problem.color, []  # geometric stage first
    d0 = prep.d0
    if start is not None:
        s = np.asarray(start, np.float64).reshape(-1)
        d0 = np.where(np.isfinite(s) & (s > 0), s, prep.d0)
    d, iters = levenberg_marquardt(problem, d0, lim.d_min_m, lim.d_max_m, config.max_iters, config.tol_m)
    if color:
        problem.color = color
        textured = color_texture_mask(frame.images["C"], config).reshape(-1)
        d, more = levenberg_marquardt(problem, d, lim.d_min_m, lim.d_max_m, config.color_iters, config.tol_m,
                                      only=textured)
        iters += more
    checked_any = (checked["U"] | checked["R"]).reshape(h, w)
    return replace_outliers(d.reshape(h, w), checked_any, frame.images["C"], config), iters
