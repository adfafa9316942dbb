"""Quality without ground truth: how far to trust a distance map of camera C, from the images and poses alone.

The measures, all from C's predicted distance ``d`` and the frame's images and *told* poses:

- **photometric residual** (per pixel, grey levels): each C pixel's point ``C + d * bearing`` is projected into U
  and R, their grey images (sRGB luminance, 0..255) are sampled there and -- after a least-squares gain and
  offset that cancels exposure and white-balance differences -- compared with C's; the absolute difference is
  averaged over a ``window`` x ``window`` box.  The per-pixel value is the *smaller* of the U and R residuals
  (a point occluded in one camera is usually seen by the other).  About 0 at the true distance on an exact frame.
- **distance residual** (per pixel, metres): the photometric residual divided by how fast the reprojected grey
  level changes with C's distance -- the distance change that would explain it (:func:`distance_residual`).
- **residual uncertainty** (per pixel): the geometric mean of the two residuals.
- **geometric uncertainty** (per pixel, metres per radian): how much C's distance moves for a small error of
  angle, ``d^2 / sqrt(sum_k (|b_k| sin g_k)^2)`` over the baselines ``b_k`` (C-U, C-R) and the angles ``g_k``
  between the bearing and each baseline -- triangulation gets worse with the square of the distance and along a
  baseline (:func:`geometric_uncertainty`).
- **disagreement** (per pixel, unitless; only where the method hands back a *reference*, an independent distance
  it computed on the way, such as ``fused``'s flow distance): ``|log(d / d_ref)|`` smoothed over a few pixels
  (:func:`disagreement`).  Where two different estimators disagree, at least one of them is wrong.
- **uncertainty** (per pixel, the map to rank pixels by): the product of the factors of
  :data:`UNCERTAINTY_FACTORS` that the prediction has (:func:`uncertainty_factors`, :func:`combine`): the
  geometric uncertainty, the method's ambiguity ``1 - confidence``, the disagreement plus
  :data:`DISAGREEMENT_FLOOR` and the square root of the residual uncertainty.  Which factors enter was chosen on
  the suite's dev split by ``python -m tools.research.validate_quality`` (it ranks every subset;
  docs/real-captures.md).
- **pair agreement** (per pixel, unitless): no built-in method hands back its C-U and C-R distances separately,
  so this is a reprojection proxy: along each C ray, the distance in ``d * (1 + s)``, ``s`` in
  :data:`SEARCH_STEPS`, that minimises the residual of U alone and that of R alone are found; the measure is
  ``|log(d_U / d_R)|`` (0 = both pairs agree; large = the two baselines see different surfaces there).
- **calibration score** (per frame, degrees): a small pose search that estimates how far the told rotations of U
  and R are off.  Each told rotation is turned by +-:data:`CALIBRATION_STEP_DEG` about each of the three axes and
  the mean residual over textured pixels is taken at the told rotation and both turns; a parabola through the
  three gives, per axis, the offset of the residual valley's bottom from the told rotation
  (``step * (r- - r+) / (2 (r+ + r- - 2 r0))``, clipped to two steps; a step when there is no valley).  The
  score is the largest, over U and R, of the norm of the three offsets.  An exact rig sits at the bottom of the
  valley (score ~0); a rig whose told rotation is off does not.  The method's distance was computed with the
  told poses and absorbs part of the error, so the score underestimates it; :data:`CALIBRATION_THRESHOLD` flags
  a frame.
"""

from __future__ import annotations

import cv2
import numpy as np

from reconstruction.camera.equirect import bearing_grid, project, project_with_derivative
from reconstruction.camera.image_ops import (
    axis_angle_matrix,
    grey,
    periodic_box_filter,
    periodic_gaussian_blur,
    sobel_gradient,
)
from reconstruction.camera.resample import sample_equirect

__all__ = ["SEARCH_STEPS", "CALIBRATION_STEP_DEG", "CALIBRATION_THRESHOLD", "FACTORS", "UNCERTAINTY_FACTORS",
           "DISAGREEMENT_FLOOR", "warped_grey", "photometric_residual", "distance_residual", "pair_agreement",
           "residual_uncertainty", "geometric_uncertainty", "disagreement", "uncertainty_factors", "combine",
           "valley_offset", "calibration_score", "assess"]

SEARCH_STEPS = (-0.08, -0.04, -0.02, -0.01, 0.0, 0.01, 0.02, 0.04, 0.08)
"""Relative distance steps of the pair-agreement search along each ray."""
CALIBRATION_STEP_DEG = 0.25
"""Rotation step of the calibration check's pose search, degrees."""
CALIBRATION_THRESHOLD = 0.098
"""A calibration score (degrees) above this flags the frame's told poses as off: the threshold that
``tools.research.validate_quality`` finds on the suite's dev split with ``fused-adaptive`` and 0.5 deg of rotation
error (0.0982, the middle of the gap between the highest exact and the lowest perturbed score;
docs/real-captures.md)."""
FACTORS = ("geometric", "ambiguity", "disagreement", "residual")
"""The factors the per-pixel ``uncertainty`` can be made of (:func:`uncertainty_factors`)."""
UNCERTAINTY_FACTORS = ("geometric", "ambiguity", "disagreement", "residual")
"""The factors of the ``uncertainty`` map (those a prediction has; chosen on the suite's dev split by
``tools.research.validate_quality``, docs/real-captures.md)."""
DISAGREEMENT_FLOOR = 0.02
"""Added to the disagreement factor (unitless, a relative distance difference of 2 %): two estimators that agree
to better than that do not make a pixel more trustworthy than the other factors say."""
DISAGREEMENT_SIGMA_PX = 3.0
"""Gaussian smoothing of the disagreement, pixels (wrapping in longitude): wrong regions, not single pixels."""
WINDOW = 5
_GREY = "bt601"
"""The grey images compared (:func:`reconstruction.camera.image_ops.grey`): Rec. 601 luma of the sRGB values in
float32, grey levels 0..255."""


def _points(cam_c, distance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World points (H, W, 3) of C's distance map and the (H, W) mask of valid distances."""
    d = np.asarray(distance, dtype=np.float64)
    valid = np.isfinite(d) & (d > 0)
    h, w = d.shape
    b = bearing_grid(w, h, rotation=cam_c.rotation)
    return np.asarray(cam_c.position, dtype=np.float64) + np.where(valid, d, 0.0)[..., None] * b, valid


def warped_grey(points: np.ndarray, grey_image: np.ndarray, position, rotation) -> np.ndarray:
    """Grey image of a camera at (position, rotation) sampled where ``points`` (H, W, 3) project: (H, W) float32."""
    h, w = grey_image.shape
    u, v = project(points, position, rotation, w, h)
    return sample_equirect(grey_image, u, v)


def _matched_abs_diff(gc: np.ndarray, gk: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """``|gc - (a * gk + b)|`` with the gain/offset (a, b) fitted by least squares over ``valid``."""
    x, y = gk[valid].astype(np.float64), gc[valid].astype(np.float64)
    if x.size < 2 or x.std() < 1e-6:
        a, b = 1.0, 0.0
    else:
        a = float(np.cov(x, y, bias=True)[0, 1] / x.var())
        b = float(y.mean() - a * x.mean())
    return np.abs(gc - (a * gk + b)).astype(np.float32)


def _box(x: np.ndarray, valid: np.ndarray, window: int) -> np.ndarray:
    """Mean of ``x`` over the valid pixels of each ``window`` box (wrapping across the seam); NaN where none."""
    xs = np.where(valid, x, 0).astype(np.float32)
    ws = valid.astype(np.float32)
    num = periodic_box_filter(xs, window, normalize=False, border=cv2.BORDER_REPLICATE)
    den = periodic_box_filter(ws, window, normalize=False, border=cv2.BORDER_REPLICATE)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / np.maximum(den, 1e-12), np.nan).astype(np.float32)


def _residuals(frame, distance, cameras=None, window: int = WINDOW) -> dict[str, np.ndarray]:
    """Box-averaged matched residual of U and of R (grey levels, (H, W) each, NaN where ``distance`` is invalid)."""
    cams = dict(frame.cameras) if cameras is None else cameras
    pts, valid = _points(frame.cameras["C"], distance)
    gc = grey(frame.images["C"], _GREY)
    out = {}
    for k in ("U", "R"):
        wk = warped_grey(pts, grey(frame.images[k], _GREY), cams[k].position, cams[k].rotation)
        out[k] = np.where(valid, _box(_matched_abs_diff(gc, wk, valid), valid, window), np.nan).astype(np.float32)
    return out


def distance_residual(frame, distance: np.ndarray, window: int = WINDOW) -> np.ndarray:
    """The photometric residual turned into metres: per camera k, ``box(|r_k|) / box(|dI_k/dd|)``, where
    ``dI_k/dd`` (grey levels per metre) is camera k's image gradient at the reprojected point times the
    derivative of the reprojected pixel with respect to C's distance (:func:`project_with_derivative`): the
    distance change that would explain the residual.  Textureless pixels and pixels looking along a baseline
    (no parallax) get large values, as they should.  (H, W) float32 metres, the smaller over U and R; NaN where
    ``distance`` is invalid."""
    cam_c = frame.cameras["C"]
    d = np.asarray(distance, dtype=np.float64)
    valid = np.isfinite(d) & (d > 0)
    h, w = d.shape
    b = bearing_grid(w, h, rotation=cam_c.rotation)
    dd = np.where(valid, d, 1.0)
    gc = grey(frame.images["C"], _GREY)
    best = np.full((h, w), np.inf, np.float32)
    for k in ("U", "R"):
        cam = frame.cameras[k]
        gk = grey(frame.images[k], _GREY)
        gx, gy = sobel_gradient(gk, wrap=False)
        u, v, du, dv = project_with_derivative(cam_c.position, b, dd, cam.position, cam.rotation, w, h)
        wk = sample_equirect(gk, u, v)
        slope = np.abs(sample_equirect(gx, u, v) * du + sample_equirect(gy, u, v) * dv).astype(np.float32)
        res = _box(_matched_abs_diff(gc, wk, valid), valid, window)
        sens = _box(slope, valid, window)
        with np.errstate(invalid="ignore", divide="ignore"):
            e = res / np.maximum(sens, 1e-3)
        best = np.fmin(best, np.where(np.isfinite(e), e, np.inf).astype(np.float32))
    return np.where(valid, best, np.nan).astype(np.float32)


def photometric_residual(frame, distance: np.ndarray, window: int = WINDOW) -> np.ndarray:
    """Per-pixel photometric residual of C's ``distance`` (H, W) in U and R: (H, W) float32 grey levels, the
    smaller of the two cameras' box-averaged residuals; NaN where ``distance`` is invalid (NaN, inf, <= 0)."""
    r = _residuals(frame, distance, window=window)
    return np.fmin(r["U"], r["R"])


def pair_agreement(frame, distance: np.ndarray, window: int = WINDOW) -> np.ndarray:
    """Disagreement of the C-U and C-R pairs around C's ``distance``: (H, W) float32 ``|log(d_U / d_R)|``
    (:data:`SEARCH_STEPS` along each ray), NaN where ``distance`` is invalid."""
    d = np.asarray(distance, dtype=np.float64)
    valid = np.isfinite(d) & (d > 0)
    stacks = {"U": [], "R": []}
    for s in SEARCH_STEPS:
        r = _residuals(frame, np.where(valid, d * (1.0 + s), np.nan), window=window)
        for k in stacks:
            stacks[k].append(np.where(np.isfinite(r[k]), r[k], np.inf))
    steps = np.log1p(np.asarray(SEARCH_STEPS))
    best = {k: steps[np.argmin(np.stack(v), axis=0)] for k, v in stacks.items()}
    return np.where(valid, np.abs(best["U"] - best["R"]), np.nan).astype(np.float32)


def valley_offset(r_minus: float, r0: float, r_plus: float, step: float) -> float:
    """Where a parabola through ``(-step, r_minus), (0, r0), (step, r_plus)`` has its minimum, clipped to
    ``[-2 step, 2 step]``; ``+-step`` towards the lower side when the three values make no valley (units of
    ``step``; NaN when a value is NaN)."""
    if not (np.isfinite(r_minus) and np.isfinite(r0) and np.isfinite(r_plus)):
        return float("nan")
    curvature = r_plus + r_minus - 2.0 * r0
    if curvature <= 0:
        return float(step * np.sign(r_minus - r_plus)) if r_minus != r_plus else float(step)
    return float(np.clip(step * (r_minus - r_plus) / (2.0 * curvature), -2.0 * step, 2.0 * step))


def calibration_score(frame, distance: np.ndarray, step_deg: float = CALIBRATION_STEP_DEG) -> dict:
    """The pose-search calibration check (module doc).

    Args:
        frame: frame-like (``cameras``, ``images``) with the *told* poses.
        distance: (H, W) C's predicted distance, metres.
        step_deg: rotation step, degrees.
    Returns:
        ``{"score": float, "U": {...}, "R": {...}}`` -- per camera the told residual (grey levels), the residuals
        turned by -step and +step about each axis, the valley offsets per axis (degrees) and their norm
        (``offset_deg``); ``score`` is the larger norm, degrees (NaN when no pixel is textured and valid).
    """
    pts, valid = _points(frame.cameras["C"], distance)
    gc = grey(frame.images["C"], _GREY)
    grad = np.hypot(cv2.Sobel(gc, cv2.CV_32F, 1, 0), cv2.Sobel(gc, cv2.CV_32F, 0, 1))
    textured = valid & (grad > np.median(grad[valid])) if valid.any() else valid
    out: dict = {}
    norms = []
    for k in ("U", "R"):
        cam = frame.cameras[k]
        gk = grey(frame.images[k], _GREY)

        def mean_residual(rot, cam=cam, gk=gk):
            wk = warped_grey(pts, gk, cam.position, rot)
            return float(np.mean(_matched_abs_diff(gc, wk, textured)[textured])) if textured.any() else np.nan

        told = mean_residual(cam.rotation)
        turned = [[mean_residual(axis_angle_matrix(a, sgn * np.radians(step_deg)) @ cam.rotation)
                   for sgn in (-1.0, 1.0)] for a in range(3)]
        offsets = [valley_offset(m, told, p, step_deg) for m, p in turned]
        norm = float(np.sqrt(np.sum(np.square(offsets))))
        out[k] = {"told_residual": told, "turned_residuals": turned, "offsets_deg": offsets, "offset_deg": norm}
        norms.append(norm)
    out["score"] = float(np.nanmax(norms)) if np.isfinite(norms).any() else float("nan")
    return out


def residual_uncertainty(residual: np.ndarray, distance_residual_m: np.ndarray) -> np.ndarray:
    """The geometric mean ``sqrt(photometric_residual * distance_residual_m)`` of :func:`photometric_residual`
    (grey levels) and :func:`distance_residual` (metres).  (H, W) float32, NaN where either is NaN."""
    return np.sqrt(np.asarray(residual, np.float32) * np.asarray(distance_residual_m, np.float32))


def geometric_uncertainty(frame, distance: np.ndarray) -> np.ndarray:
    """Triangulation sensitivity of C's distance to an angular error: ``d^2 / sqrt(sum_k (|b_k| sin g_k)^2)``.

    For one pair with baseline ``b`` (metres) and the angle ``g`` between C's bearing and the baseline, a bearing
    error of ``e`` radians moves the triangulated distance by about ``e * d^2 / (|b| sin g)``; the two pairs
    combine as independent measurements.

    Args:
        frame: frame-like with ``cameras`` C, U, R (told poses).
        distance: (H, W) C's distance, metres (NaN, inf, <= 0 = none).
    Returns:
        (H, W) float32 metres per radian; NaN where ``distance`` is invalid.
    """
    d = np.asarray(distance, dtype=np.float64)
    valid = np.isfinite(d) & (d > 0)
    h, w = d.shape
    cam_c = frame.cameras["C"]
    b = bearing_grid(w, h, rotation=cam_c.rotation)
    sum_sq = np.zeros((h, w))
    for k in ("U", "R"):
        base = np.asarray(frame.cameras[k].position, np.float64) - np.asarray(cam_c.position, np.float64)
        length = float(np.linalg.norm(base))
        if length == 0:
            continue
        cos_g = b @ (base / length)
        sum_sq += length ** 2 * np.maximum(1.0 - cos_g ** 2, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.where(valid, d ** 2 / np.sqrt(np.maximum(sum_sq, 1e-12)), np.nan)
    return g.astype(np.float32)


def disagreement(distance: np.ndarray, reference: np.ndarray, sigma_px: float = DISAGREEMENT_SIGMA_PX) -> np.ndarray:
    """How far C's distance is from an independent estimate: ``|log(d / d_ref)|`` smoothed by a Gaussian of
    ``sigma_px`` pixels (wrapping in longitude).

    Args:
        distance, reference: (H, W) distances, metres (NaN, inf, <= 0 = none); where the reference is invalid
            the disagreement before smoothing is 1 (a factor e apart).
    Returns:
        (H, W) float32, unitless; NaN where ``distance`` is invalid.
    """
    d = np.asarray(distance, np.float64)
    r = np.asarray(reference, np.float64)
    valid = np.isfinite(d) & (d > 0)
    ok = valid & np.isfinite(r) & (r > 0)
    x = np.ones(d.shape, np.float32)
    x[ok] = np.abs(np.log(d[ok] / r[ok]))
    x = periodic_gaussian_blur(x, sigma_px)
    return np.where(valid, x, np.nan).astype(np.float32)


def uncertainty_factors(maps: dict[str, np.ndarray], confidence: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The factors of :data:`FACTORS` that a prediction has, from its quality maps (:func:`assess`'s) and the
    method's confidence: ``geometric`` = ``geometric_m``; ``ambiguity`` = ``1 - confidence`` (when there is one);
    ``disagreement`` = ``disagreement + DISAGREEMENT_FLOOR`` (when there is a reference); ``residual`` =
    ``sqrt(residual_uncertainty)``.  Each (H, W) float32, higher = less trustworthy."""
    out = {"geometric": np.asarray(maps["geometric_m"], np.float32)}
    if confidence is not None:
        out["ambiguity"] = (1.0 - np.clip(np.asarray(confidence, np.float32), 0.0, 1.0)).astype(np.float32)
    if "disagreement" in maps:
        out["disagreement"] = (np.asarray(maps["disagreement"], np.float32) + np.float32(DISAGREEMENT_FLOOR))
    out["residual"] = np.sqrt(np.asarray(maps["residual_uncertainty"], np.float32))
    return out


def combine(factors: dict[str, np.ndarray], names) -> np.ndarray:
    """The product of the factors ``names`` that ``factors`` has (a missing one counts as 1): (H, W) float32,
    NaN where any used factor is NaN."""
    used = [factors[n] for n in names if n in factors]
    if not used:
        raise ValueError(f"none of the factors {', '.join(names)} is available")
    return np.prod(np.stack(used), axis=0).astype(np.float32)


def assess(frame, distance: np.ndarray, confidence: np.ndarray | None = None,
           reference: np.ndarray | None = None) -> tuple[dict[str, np.ndarray], dict]:
    """All measures of one prediction.

    Args:
        frame: frame-like (``cameras`` with the told poses, ``images``).
        distance: (H, W) C's distance, metres; confidence: (H, W) the method's confidence in [0, 1] or None;
        reference: (H, W) an independent distance the method computed on the way (metres) or None.
    Returns:
        ``(maps, summary)``: per-pixel maps ``photometric_residual``, ``distance_residual_m``, ``pair_agreement``,
        ``residual_uncertainty``, ``geometric_m``, ``disagreement`` (with a reference only) and ``uncertainty``
        (:data:`UNCERTAINTY_FACTORS`); per frame their medians over valid pixels, ``calibration_score``,
        ``calibration_flagged`` and the details.
    """
    maps = {"photometric_residual": photometric_residual(frame, distance),
            "distance_residual_m": distance_residual(frame, distance),
            "pair_agreement": pair_agreement(frame, distance)}
    maps["residual_uncertainty"] = residual_uncertainty(maps["photometric_residual"], maps["distance_residual_m"])
    maps["geometric_m"] = geometric_uncertainty(frame, distance)
    if reference is not None:
        maps["disagreement"] = disagreement(distance, reference)
    maps["uncertainty"] = combine(uncertainty_factors(maps, confidence), UNCERTAINTY_FACTORS)
    calib = calibration_score(frame, distance)
    summary = {f"{k}_median": (float(np.nanmedian(v)) if np.isfinite(v).any() else float("nan"))
               for k, v in maps.items()}
    summary["calibration_score"] = calib["score"]
    summary["calibration_flagged"] = bool(calib["score"] > CALIBRATION_THRESHOLD)
    summary["calibration"] = {k: calib[k] for k in ("U", "R")}
    return maps, summary
