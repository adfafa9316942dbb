"""The reconstruction pipeline: flow -> per-pair triangulation -> ``average`` -> LM refinement variants.

>>> result = reconstruct(frame, flow="dis", rectify=True)        # doctest: +SKIP
>>> result.distance["gradient"]                                  # (H, W) float32 metres, camera C
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from types import SimpleNamespace

import cv2
import numpy as np

from reconstruction.camera.equirect import bearing_grid
from reconstruction.camera.image_ops import central_differences, rotation_vector_matrix
from reconstruction.flow.backends import ORACLE, FlowBackend
from reconstruction.flow.matching import PairMatch, match_pair
from reconstruction.methods.base import MethodOutput
from reconstruction.photometry import (
    IDENTITY,
    NO_CALIBRATION,
    FrameView,
    PhotometricModel,
    PhotometricParams,
    align_images,
    apply_photometric,
    fit_photometric,
)
from reconstruction.refine.lm import (
    ColorTerm,
    RefineConfig,
    RefineProblem,
    discover_variants,
    get_variant,
    levenberg_marquardt,
    patch_offsets,
    patch_reference,
)
from reconstruction.refine.triangulate import PairGeometry, TriangulationLimits, pair_geometry, triangulate_sines
from reconstruction.refine.weights import (
    angle_weight,
    epipolar_gradient,
    gradient_confidence,
    lateral_confidence,
    to_gray,
)
from reconstruction.rig_calibration import (
    NO_RIG_CALIBRATION,
    RigParams,
    corrected_pose,
    fit_rotation,
    usable_matches,
)

__all__ = ["DEFAULT_FLOW", "PAIRS", "Reconstruction", "Calibration", "reconstruct", "self_calibrate",
           "available_variants", "fuse_average", "agreed_distance", "fill_invalid", "fill_edge_aware", "Prepared",
           "prepare", "variant_problem",
           "refine_variant", "FlowMethod", "config_label", "flow_confidence", "run_flow_group"]

DEFAULT_FLOW = "dis"  # chosen by measurement, see docs/refinement.md
PAIRS = ("U", "R")


def available_variants() -> list[str]:
    """``average`` (no refinement) followed by the registered LM variants."""
    return ["average", *discover_variants()[0]]


@dataclass
class Reconstruction:
    """Output of :func:`reconstruct`.

    Attributes:
        distance: (H, W) float32 distance of camera C per variant, metres (finite everywhere).
        pair_distance: (H, W) float32 per-pair triangulated distance ("U", "R"), metres.
        pair_valid: (H, W) bool per pair: False at the pair's epipoles or where its flow is unusable.
        seconds: wall time per stage (``flow_U``, ``flow_R``, ``triangulate``, ``average``, each variant).
        iterations: LM iterations per variant.
        confidence: (H, W) float32 per variant, in [0, 1] (:func:`flow_confidence`).
        calibration: the self-calibration the flow matched with (:class:`Calibration`: the corrected frame and
            the record of what was fitted and applied).
    """

    distance: dict[str, np.ndarray] = field(default_factory=dict)
    pair_distance: dict[str, np.ndarray] = field(default_factory=dict)
    pair_valid: dict[str, np.ndarray] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)
    iterations: dict[str, int] = field(default_factory=dict)
    confidence: dict[str, np.ndarray] = field(default_factory=dict)
    calibration: Calibration | None = None


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


def fill_edge_aware(d: np.ndarray, valid: np.ndarray, guide: np.ndarray, lam: float, sigma_color: float) -> np.ndarray:
    """Interpolate distances from valid pixels without crossing image edges.

    Normalised edge-aware smoothing of inverse distance: ``S(valid / d) / S(valid)`` with ``S`` OpenCV's
    fast global smoother guided by ``guide``; pixels the smoother cannot reach fall back to
    :func:`fill_invalid`.

    Args:
        d: (H, W) distances, metres (positive); valid: (H, W) bool; guide: (H, W, 3) uint8 image.
        lam: smoothness (larger reaches farther); sigma_color: edge scale in 8-bit levels.
    Returns:
        (H, W) float64 interpolated distances (at every pixel, valid ones included), metres.
    """
    fgs = cv2.ximgproc.createFastGlobalSmootherFilter(guide, lam, sigma_color)
    m = valid.astype(np.float32)
    num = fgs.filter((m / np.maximum(d, 1e-6)).astype(np.float32))
    den = fgs.filter(m)
    reached = den > 1e-4
    inv = num / np.where(reached, den, 1.0)
    out = 1.0 / np.maximum(inv, 1e-3).astype(np.float64)
    if not reached.all():
        out = np.where(reached, out, fill_invalid(d, valid))
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


def agreed_distance(d_pairs: Sequence[np.ndarray], valid: Sequence[np.ndarray], tolerance: float) -> np.ndarray:
    """The pairs' mean distance where both triangulate and agree, NaN elsewhere.

    Args:
        d_pairs: per pair (N,) distances, metres; valid: per pair (N,) bool.
        tolerance: the largest ``|ln(d_a / d_b)|`` between the pairs (dimensionless).
    Returns:
        (N,) float64 distances, metres (NaN where a pair is invalid or they disagree).
    """
    d = np.stack([np.asarray(x, np.float64) for x in d_pairs])
    ok = np.all(np.stack(valid), axis=0) & np.all(d > 0, axis=0)
    logs = np.log(np.where(ok, d, 1.0))
    ok &= logs.max(axis=0) - logs.min(axis=0) <= tolerance
    return np.where(ok, d.mean(axis=0), np.nan)


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


@dataclass
class Prepared:
    """Everything the refinement variants share: matches, per-pair geometry and the ``average`` start.

    Attributes:
        bearings: (N, 3) world bearings of C's pixels (N = H * W, row-major).
        matches: per pair, the :class:`PairMatch`.
        geoms: per pair, the :class:`~reconstruction.refine.triangulate.PairGeometry` (arrays (N,)).
        d_pair: per pair, (N,) triangulated distances, metres; valid: per pair, (N,) bool.
        d0: (N,) the ``average`` distances, metres (every variant starts from them).
        limits: the triangulation limits used.
        seconds: wall time of ``flow_U``, ``flow_R``, ``triangulate`` and ``average``.
    """

    bearings: np.ndarray
    matches: dict[str, PairMatch]
    geoms: dict[str, PairGeometry]
    d_pair: dict[str, np.ndarray]
    valid: dict[str, np.ndarray]
    d0: np.ndarray
    limits: TriangulationLimits
    seconds: dict[str, float] = field(default_factory=dict)


def prepare(frame, flow: str | FlowBackend = DEFAULT_FLOW, rectify: bool = True,
            limits: TriangulationLimits = TriangulationLimits(),
            on_stage: Callable[[str], None] | None = None) -> Prepared:
    """Flow for both pairs, triangulation and the ``average`` fusion, each timed."""
    note = on_stage or (lambda _s: None)
    h, w = frame.height, frame.width
    seconds = {}
    bearings = bearing_grid(w, h, frame.cameras["C"].rotation).reshape(-1, 3)
    matches = {}
    for k in PAIRS:
        note(f"flow_{k}")
        matches[k] = match_pair(frame, k, flow, rectify)
        seconds[f"flow_{k}"] = matches[k].seconds
    note("triangulate")
    start = time.perf_counter()
    geoms, d_pair, valid = {}, {}, {}
    for k in PAIRS:
        geoms[k] = pair_geometry(bearings, matches[k].baseline, matches[k].bearing.reshape(-1, 3))
        d_pair[k], valid[k] = triangulate_sines(geoms[k], limits)
    seconds["triangulate"] = time.perf_counter() - start
    start = time.perf_counter()
    d0 = fuse_average([d_pair[k] for k in PAIRS], [valid[k] for k in PAIRS], (h, w))
    seconds["average"] = time.perf_counter() - start
    return Prepared(bearings, matches, geoms, d_pair, valid, d0, limits, seconds)


def flow_confidence(d: np.ndarray, prep: Prepared, tolerance: float = 0.05) -> np.ndarray:
    """Per-pixel confidence of a flow-pipeline distance, in [0, 1]: the best pair's support.

    For each pair k, ``valid_k * sin(alpha_k)^2 * exp(-|ln(d_k / d)| / tolerance)``: high where a pair far from
    its epipole triangulates (alone) to the final distance; the maximum over the pairs.

    Args:
        d: (H, W) or (N,) final distances, metres; prep: the shared stages (per-pair distances and geometry).
        tolerance: relative disagreement that lowers the support by a factor e (dimensionless).
    Returns:
        float32 array of ``d``'s shape.
    """
    dd = np.maximum(np.asarray(d, np.float64).reshape(-1), 1e-9)
    conf = np.zeros(dd.shape)
    for k in PAIRS:
        ratio = np.abs(np.log(np.maximum(prep.d_pair[k], 1e-9) / dd))
        c = np.where(prep.valid[k], prep.geoms[k].sin_alpha ** 2 * np.exp(-ratio / tolerance), 0.0)
        conf = np.maximum(conf, c)
    return np.clip(conf, 0.0, 1.0).astype(np.float32).reshape(np.shape(d))


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


def reconstruct(frame, flow: str | FlowBackend = DEFAULT_FLOW, rectify: bool = True,
                variants: Sequence[str | RefineConfig] | None = None,
                limits: TriangulationLimits = TriangulationLimits(),
                on_stage: Callable[[str], None] | None = None,
                photometric: PhotometricParams = NO_CALIBRATION,
                rig: RigParams = NO_RIG_CALIBRATION) -> Reconstruction:
    """Reconstruct camera C's per-pixel distance from a frame's three images.

    Args:
        frame: a :class:`harness.data.frame.Frame`.
        flow: a flow backend or its name (:func:`reconstruction.flow.backends.available_flows`), or "oracle".
        rectify: compute each pair's flow on rectified images (default) or plain equirect ones.
        variants: which outputs to produce: "average" and refinement variants, by name or as
            :class:`RefineConfig` (default: all of :func:`available_variants`).
        limits: when a pair's estimate counts as invalid, and the distance clamp.
        on_stage: optional callback called with each stage name before it runs (progress display).
        photometric, rig: the self-calibration (:func:`self_calibrate`; not for the oracle): the flow, the
            triangulation and every variant use its frame (``Reconstruction.calibration``).
    Returns:
        A :class:`Reconstruction`.
    Raises:
        ValueError: unknown flow or variant, or the oracle without ground truth.
    """
    variants = list(available_variants() if variants is None else variants)
    # resolve names before any work (an unknown one fails fast)
    configs = {v.name: v for v in (v if isinstance(v, RefineConfig) else get_variant(v)
                                   for v in variants if v != "average")}
    h, w = frame.height, frame.width
    note = on_stage or (lambda _s: None)
    calibration = self_calibrate(frame, photometric, rig, limits, flow != ORACLE, note)
    frame = calibration.frame
    prep = prepare(frame, flow, rectify, limits, note)
    out = Reconstruction(seconds={**calibration.seconds, **prep.seconds}, calibration=calibration)
    for k in PAIRS:
        out.pair_distance[k] = prep.d_pair[k].reshape(h, w).astype(np.float32)
        out.pair_valid[k] = prep.valid[k].reshape(h, w)
    if "average" in variants:
        out.distance["average"] = prep.d0.reshape(h, w).astype(np.float32)
        out.confidence["average"] = flow_confidence(out.distance["average"], prep)
    for name, config in configs.items():
        note(name)
        start = time.perf_counter()
        d, iters = refine_variant(frame, prep, config)
        out.seconds[name] = time.perf_counter() - start
        out.iterations[name] = iters
        out.distance[name] = d.astype(np.float32)
        out.confidence[name] = flow_confidence(out.distance[name], prep)
    return out


@dataclass(frozen=True, eq=False)
class Calibration:
    """A frame self-calibrated once, for every method that matches it (:func:`self_calibrate`).

    Attributes:
        frame: what to match: the input frame seen with U's and R's corrected poses and the corrected images (the
            input itself when nothing was applied).
        model: the photometric corrections applied (:class:`reconstruction.photometry.PhotometricModel`).
        record: JSON-able: ``rig`` (per camera the :class:`~reconstruction.rig_calibration.RigFit` with
            ``applied``) and ``photometric`` (:func:`reconstruction.photometry.fit_photometric`'s record), each
            quantity with its evidence and whether it was applied; empty when nothing ran.
        seconds: the stages' wall time: ``rig`` (the fit), ``photometric`` (the pre-pass and the photometric fit).
    """

    frame: object
    model: PhotometricModel = IDENTITY
    record: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)

    @property
    def corrected_images(self) -> bool:
        """Whether any image was changed (a gain, a field or the shared fall-off applied)."""
        return not self.model.is_identity

    @property
    def applied(self) -> list[str]:
        """What was applied, e.g. ``["R rotation", "U gain", "U field", "U response", "common field"]`` (empty:
        nothing)."""
        out = []
        for k, fit in self.record.get("rig", {}).items():
            if fit.get("applied"):
                out.append(f"{k} rotation")
        photo = self.record.get("photometric", {})
        for k in PAIRS:
            for what in ("gain", "field", "response"):
                if photo.get(k, {}).get(what, {}).get("applied"):
                    out.append(f"{k} {what}")
        if photo.get("common", {}).get("field", {}).get("applied"):
            out.append("common field")
        return out


def self_calibrate(frame, photometric: PhotometricParams, rig: RigParams, limits: TriangulationLimits,
                   prepass: bool = True, note: Callable[[str], None] = lambda _s: None) -> Calibration:
    """The frame's self-calibration: U's and R's rotations and the cameras' photometric differences, each applied
    only where the frame's own evidence supports it (:mod:`reconstruction.evidence`).

    A flow pass (``photometric.prepass_flow`` on rectified images reduced by ``photometric.prepass_factor``, after each
    channel's median gain from the same pixels so that it matches across an exposure difference) gives the
    correspondences; the rig fit (:func:`reconstruction.rig_calibration.fit_rotation`) runs on its matches, the
    matches are triangulated again with the applied poses, and the photometric fit
    (:func:`reconstruction.photometry.fit_photometric`) runs on the correspondences of the pixels whose two pairs
    triangulate alike (:func:`agreed_distance` within ``photometric.agreement``).

    Args:
        frame: the frame (images and told poses).
        photometric, rig: the fits (mode ``"none"``: not fitted).
        limits: the triangulation limits of the pre-pass.
        prepass: False (the oracle): nothing is fitted.
        note: called with the stage name before it runs.
    Returns:
        A :class:`Calibration`.
    """
    if not prepass or (photometric.mode == "none" and rig.mode == "none"):
        return Calibration(frame)
    h, w = frame.height, frame.width
    note("photometric" if photometric.mode != "none" else "rig")
    start = time.perf_counter()
    seconds, record = {}, {}
    matched = frame
    if photometric.mode != "none":  # for the pre-pass only: each channel's median gain from the same pixels
        quick = dataclasses.replace(photometric, iterations=0)
        matched = FrameView(frame, images=align_images(frame.images, frame.cameras, quick)[0])
    small = reduced_frame(matched, max(photometric.prepass_factor, 1))
    prep = prepare(small, photometric.prepass_flow, True, limits)
    d_pair, valid = [prep.d_pair[k] for k in PAIRS], [prep.valid[k] for k in PAIRS]
    cameras = dict(frame.cameras)
    if rig.mode != "none":
        t_rig = time.perf_counter()
        fits = {}
        for i, k in enumerate(PAIRS):
            m = prep.matches[k]
            fit = fit_rotation(prep.bearings, usable_matches(small.images["C"], m.bearing, m.fb_error_px,
                                                             prep.valid[k], rig), m.baseline,
                               min_sin=rig.min_sin, iterations=rig.iterations, tukey_c=rig.tukey_c,
                               max_matches=rig.max_matches, alpha=rig.alpha, longitude_blocks=rig.longitude_blocks,
                               min_block_samples=rig.min_block_samples)
            fit["applied"] = bool(fit["evidence"]["supported"] and rig.min_degrees <= fit["degrees"] <= rig.max_degrees
                                  and fit["degrees"] > 0)
            fits[k] = fit
            omega = np.asarray(fit["omega"]) if fit["applied"] else np.zeros(3)
            cameras[k] = corrected_pose(frame.cameras[k], omega)
            # the pre-pass's matches seen from the applied pose, triangulated again
            g = pair_geometry(prep.bearings, m.baseline, m.bearing.reshape(-1, 3) @ rotation_vector_matrix(omega).T)
            d_pair[i], valid[i] = triangulate_sines(g, limits)
        record["rig"] = fits
        seconds["rig"] = time.perf_counter() - t_rig
    model = IDENTITY
    if photometric.mode != "none":
        # the pixels both pairs triangulate alike (a wrong match pairs C's pixel with another surface)
        d_small = agreed_distance(d_pair, valid, photometric.agreement)
        d_full = cv2.resize(d_small.reshape(small.height, small.width).astype(np.float32), (w, h),
                            interpolation=cv2.INTER_NEAREST)
        model, record["photometric"] = fit_photometric(frame.images, cameras, d_full, photometric)
    replaced = {}
    if any(fit["applied"] for fit in record.get("rig", {}).values()):
        replaced["cameras"] = cameras
    if not model.is_identity:
        replaced["images"] = apply_photometric(frame.images, model, photometric.max_log_gain)
    seconds["photometric"] = time.perf_counter() - start - seconds.get("rig", 0.0)
    return Calibration(FrameView(frame, **replaced) if replaced else frame, model, record, seconds)


# ------------------------------------------------------------------------------------------ as a Method


def reduced_frame(frame, factor: int):
    """A frame-like view of ``frame`` with images ``factor`` times smaller (area averaging; same poses)."""
    w, h = frame.width // factor, frame.height // factor
    images = {k: cv2.resize(v, (w, h), interpolation=cv2.INTER_AREA) for k, v in frame.images.items()}
    return SimpleNamespace(width=w, height=h, cameras=frame.cameras, images=images,
                           baseline_m=getattr(frame, "baseline_m", None),
                           distance={})


def config_label(flow: str, rectify: bool) -> str:
    """Label of a flow configuration, e.g. ``dis-rect`` or ``deepflow-plain``."""
    return f"{flow}-{'rect' if rectify else 'plain'}"


@dataclass(frozen=True)
class FlowMethod:
    """One configuration of the paper's flow pipeline (flow, rectification, variant) as a :class:`Method`.

    Attributes:
        flow: the flow backend, or ``"oracle"`` (exact correspondences from ground truth).
        rectify: flow on rectified pairs (True) or on the plain equirect images (False, the paper).
        refine: the refinement variant, or None for ``average`` (the paper's "before optimisation").
        limits: triangulation validity limits and distance clamp.
        photometric: photometric self-calibration of U and R against C before the flow and the colour terms
            (:class:`reconstruction.photometry.PhotometricParams`; mode ``"none"`` = the images as they are).
        rig: rig self-calibration of U's and R's rotations against C before the flow
            (:class:`reconstruction.rig_calibration.RigParams`; mode ``"none"`` = the told poses as they are).
    """

    flow: FlowBackend | str
    rectify: bool = True
    refine: RefineConfig | None = None
    limits: TriangulationLimits = TriangulationLimits()
    photometric: PhotometricParams = PhotometricParams()
    rig: RigParams = RigParams()

    @property
    def flow_name(self) -> str:
        return self.flow if isinstance(self.flow, str) else self.flow.name

    @property
    def variant(self) -> str:
        return "average" if self.refine is None else self.refine.name

    @property
    def label(self) -> str:
        return f"{config_label(self.flow_name, self.rectify)}:{self.variant}"

    @property
    def group_key(self) -> tuple:
        """Methods with equal keys share the flow, triangulation and ``average`` stages."""
        flow = self.flow if isinstance(self.flow, str) else (self.flow.name, repr(sorted(self.flow.params.items())))
        return ("flow-pipeline", flow, self.rectify, self.limits, self.photometric, self.rig)

    def config(self) -> dict:
        flow = {"name": self.flow} if isinstance(self.flow, str) else self.flow.config()
        return {"kind": "flow-pipeline", "label": self.label, "flow": flow, "rectify": self.rectify,
                "variant": self.variant, "refine": None if self.refine is None else self.refine.config(),
                "triangulation": asdict(self.limits), "photometric": asdict(self.photometric),
                "rig": asdict(self.rig)}

    def run(self, frame) -> MethodOutput:
        return self.run_group(frame, [self])[self.label]

    def run_group(self, frame, members: Sequence,
                  on_stage: Callable[[str], None] | None = None) -> dict[str, MethodOutput]:
        """Run several variants of this flow configuration at once (flow and triangulation computed once), and
        the methods built on them (:func:`run_flow_group`)."""
        return run_flow_group(frame, members, on_stage)

    def outputs(self, result: Reconstruction, members: Sequence[FlowMethod]) -> dict[str, MethodOutput]:
        """The outputs of ``members`` (variants of this configuration) from one :func:`reconstruct` result."""
        shared = {k: result.seconds[k] for k in ("rig", "photometric", "flow_U", "flow_R", "triangulate", "average")
                  if k in result.seconds}
        calibration = result.calibration
        outs = {}
        for m in members:
            own = {m.variant: result.seconds[m.variant]} if m.refine is not None else {}
            seconds = {**shared, **own}
            seconds["total"] = sum(seconds.values())
            info = {"lm_iterations": result.iterations[m.variant]} if m.refine is not None else {}
            if calibration is not None and calibration.record:
                info["calibration"] = calibration.record
                info["applied"] = calibration.applied
            outs[m.label] = MethodOutput(distance=result.distance[m.variant], confidence=result.confidence[m.variant],
                                         seconds=seconds, info=info)
        return outs


def run_flow_group(frame, members: Sequence,
                   on_stage: Callable[[str], None] | None = None) -> dict[str, MethodOutput]:
    """Run methods that share one flow configuration (one ``group_key``), the flow and triangulation once.

    ``members`` are :class:`FlowMethod` variants of the configuration and methods built on one of them (such as
    the flow-prior sweep, :class:`reconstruction.methods.prior_sweep.PriorSweepMethod`): those have ``flow``
    (their :class:`FlowMethod`), the same ``group_key`` and a
    ``run_on_flows(frame, members, flow_outputs, on_stage)`` that runs all members of their own type given the
    flow outputs by label.  The flow variants they use are computed along with the members' own, and they are
    given the flow's :class:`Calibration` (the frame they match: self-calibrated once, :func:`self_calibrate`).

    Returns:
        Outputs by member label.
    """
    own = [m for m in members if isinstance(m, FlowMethod)]
    users = [m for m in members if not isinstance(m, FlowMethod)]
    needed = {m.label: m for m in own}
    for u in users:
        needed.setdefault(u.flow.label, u.flow)
    flows = list(needed.values())
    head = flows[0]
    if any(m.group_key != head.group_key for m in [*flows, *users]):
        raise ValueError("methods of different flow configurations in one group: "
                         + ", ".join(m.label for m in members))
    wanted = [m.refine if m.refine is not None else "average" for m in flows]
    result = reconstruct(frame, head.flow, head.rectify, wanted, head.limits, on_stage, head.photometric, head.rig)
    flow_outs = head.outputs(result, flows)
    outs = {m.label: flow_outs[m.label] for m in own}
    by_type: dict[type, list] = {}
    for u in users:
        by_type.setdefault(type(u), []).append(u)
    for kind in by_type.values():  # they match the frame the flow matched: one self-calibration per frame
        outs.update(kind[0].run_on_flows(result.calibration, kind, flow_outs, on_stage))
    return {m.label: outs[m.label] for m in members}
