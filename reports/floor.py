"""The floor: the distance error of an ideal matcher, from the truth and the rig (pure numpy).

An ideal matcher finds, for every pixel of camera C, the point in camera K (U and R) that sees the same surface
point, up to an angular error ``delta`` along the epipolar curve (the one direction that moves the triangulated
distance; an error across it is explained by no distance and ignored).  ``delta = px * pi / H`` radians: ``px``
equirect pixels of pitch ``pi / H`` (:data:`FLOOR_PX` = 0.25 by default; :data:`FLOOR_PX_CHOICES`).

For C's pixel with unit bearing ``a`` (world), true distance ``d`` and the pair C-K with baseline ``t`` (world,
``K.position - C.position``, length ``B``), ``alpha`` the angle between ``a`` and ``t``, the point is
``X = C + d a`` and ``r_K = |X - K| = |d a - t|`` its range from K.  In the triangle C, K, X let ``beta`` be the
angle at K (between ``C - K`` and ``X - K``) and ``gamma = pi - alpha - beta`` the parallax, the angle at X
between the rays from C and from K.  The law of sines gives::

    d = B sin(beta) / sin(gamma) = B sin(beta) / sin(alpha + beta)
    dd/dbeta = B sin(alpha) / sin(gamma)^2 = r_K^2 / (B sin(alpha)) = r_K / sin(gamma)

(using ``r_K = B sin(alpha) / sin(gamma)``, the law of sines again).  So an error ``delta`` of the matched
bearing in K moves the distance by, to first order::

    sigma_K = delta * r_K^2 / (B sin(alpha)) = delta * |d a - t|^2 / |a x t|

which is what :func:`pair_sigma` computes.  The common approximation ``delta * d^2 / (B sin(alpha))`` (the same
with ``r_K`` replaced by ``d``; ``reconstruction.quality.geometric_uncertainty`` uses it) is what this becomes for
``B << d``: it differs from the exact derivative by the factor ``(r_K / d)^2 = 1 - 2 (B/d) cos(alpha) + (B/d)^2``.
A pixel on a pair's epipole (``sin(alpha) = 0``: its bearing along the baseline, either way) gets
``sigma_K = inf`` for that pair.  The pairs combine as independent measurements, by inverse variance::

    sigma = (1 / sigma_U^2 + 1 / sigma_R^2)^(-1/2)

(:func:`floor_sigma`: ``inf`` only where every pair is at an epipole, which an L-shaped rig never has).

The ideal matcher's angular errors are random: zero-mean Gaussian with standard deviation ``delta``, independent
between the pairs (inverse variance is the best combination of such errors).  To first order the distance error of
a pixel is then Gaussian with standard deviation ``sigma``, and its mean magnitude is ``sqrt(2 / pi) sigma``
(:data:`GAUSSIAN_MAE_FACTOR`).  The floor of a set of pixels (:func:`floor_mae`) is the MAE such a matcher makes
over them: ``sqrt(2 / pi)`` times the mean of ``sigma`` over the scored pixels (``reports.metrics.scored_pixels``:
finite positive true distance), inside a region mask when given, every pixel weighed the same, exactly as ``mae_m``
(``reports.metrics.summary``) weighs them.  Definitions and measured figures: ``docs/metrics.md``, "The floor".
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from reconstruction.camera.equirect import bearing_grid
from reports.metrics import scored_pixels

__all__ = ["FLOOR_PX", "FLOOR_PX_CHOICES", "FLOOR_PAIRS", "GAUSSIAN_MAE_FACTOR", "pixel_pitch_rad", "pair_sigma",
           "floor_sigma", "frame_floor_sigma", "floor_mae", "region_floors", "times_floor", "floor_fields"]

#: the ideal matcher's angular error per pair, equirect pixels (the floor of the results columns ``floor_m``)
FLOOR_PX = 0.25
#: the angular errors the floor is documented at, pixels (``docs/metrics.md``); any ``px > 0`` works
FLOOR_PX_CHOICES = (0.1, 0.25, 0.5)
#: the cameras paired with C
FLOOR_PAIRS = ("U", "R")
#: mean magnitude of a zero-mean Gaussian error per unit of its standard deviation, ``sqrt(2 / pi)``: the floor is
#: this times the mean of :func:`floor_sigma`
GAUSSIAN_MAE_FACTOR = math.sqrt(2.0 / math.pi)


def pixel_pitch_rad(height: int) -> float:
    """The angular pitch of an equirect image of ``height`` rows, radians per pixel: ``pi / H`` (rows span pi of
    latitude; columns span ``2 pi / W``, the same since ``W = 2 H``)."""
    if height <= 0:
        raise ValueError(f"height must be positive, got {height}")
    return math.pi / height


def pair_sigma(bearings, distance, baseline, delta_rad: float) -> np.ndarray:
    """Distance error of one pair's triangulation caused by an angular error of the match in the other camera.

    ``sigma = delta * |d a - t|^2 / |a x t|`` (the exact first-order derivative from the law of sines; module doc),
    ``inf`` where ``|a x t| = 0`` (the bearing lies along the baseline: the pair's epipoles).

    Args:
        bearings: (..., 3) unit bearings ``a`` of C's pixels, world frame.
        distance: (...) true distance ``d`` along them, metres (finite, positive).
        baseline: (3,) ``t = K.position - C.position``, world frame, metres (non-zero).
        delta_rad: the matcher's angular error along the epipolar curve, radians (>= 0).
    Returns:
        (...) float64 metres, >= 0 (``inf`` on the epipoles).
    Raises:
        ValueError: a zero or non-finite baseline, or a negative or non-finite ``delta_rad``.
    """
    a = np.asarray(bearings, dtype=np.float64)
    d = np.asarray(distance, dtype=np.float64)
    t = np.asarray(baseline, dtype=np.float64).reshape(3)
    if not (np.all(np.isfinite(t)) and np.linalg.norm(t) > 0):
        raise ValueError(f"baseline must be a finite non-zero vector, got {t.tolist()}")
    if not (math.isfinite(delta_rad) and delta_rad >= 0):
        raise ValueError(f"delta_rad must be finite and >= 0, got {delta_rad}")
    cross = np.linalg.norm(np.cross(a, t), axis=-1)  # B sin(alpha)
    r_k = d[..., None] * a - t  # X - K
    r_k2 = np.einsum("...i,...i->...", r_k, r_k)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(cross > 0, delta_rad * r_k2 / cross, np.inf)


def floor_sigma(gt, rotation, baselines: Sequence, px: float = FLOOR_PX) -> np.ndarray:
    """Per pixel of C, the ideal matcher's distance error: the pairs' :func:`pair_sigma` combined by inverse
    variance, ``(sum_k 1 / sigma_k^2)^(-1/2)``.

    Args:
        gt: (H, W) C's true distance, metres (+inf, NaN or <= 0: not scored).
        rotation: (3, 3) C's world-from-camera rotation (the bearings of its pixels in the world).
        baselines: per pair, (3,) ``K.position - C.position``, world frame, metres.
        px: the matcher's angular error per pair, equirect pixels (``delta = px * pi / H`` radians; > 0).
    Returns:
        (H, W) float64 metres at the scored pixels (``inf`` where every pair is at an epipole), NaN elsewhere.
    Raises:
        ValueError: ``gt`` not 2-D with ``W = 2 H``, ``px`` not finite and positive, no baseline, or a zero one.
    """
    gt = np.asarray(gt, dtype=np.float64)
    if gt.ndim != 2 or gt.shape[1] != 2 * gt.shape[0]:
        raise ValueError(f"gt must be an (H, 2H) equirect map, got shape {gt.shape}")
    if not (math.isfinite(px) and px > 0):
        raise ValueError(f"px must be finite and positive, got {px}")
    if len(baselines) == 0:
        raise ValueError("floor_sigma needs at least one baseline")
    h, w = gt.shape
    delta = px * pixel_pitch_rad(h)
    scored = scored_pixels(gt)
    a = bearing_grid(w, h, rotation)[scored]  # (N, 3) unit, world
    d = gt[scored]
    inv_var = np.zeros(d.shape)
    for t in baselines:
        inv_var += 1.0 / pair_sigma(a, d, t, delta) ** 2  # 0 where the pair is at an epipole (inf)
    out = np.full((h, w), np.nan)
    with np.errstate(divide="ignore"):
        out[scored] = 1.0 / np.sqrt(inv_var)
    return out


def frame_floor_sigma(frame, px: float = FLOOR_PX) -> np.ndarray:
    """:func:`floor_sigma` of a frame: its true distance of C, C's rotation and the baselines from C to each camera
    of :data:`FLOOR_PAIRS` (the frame's camera poses, as the regions use them).

    Args:
        frame: frame-like with ``distance["C"]`` ((H, W) metres) and ``cameras`` C, U, R (``position`` (3,),
            ``rotation`` (3, 3) world-from-camera).
        px: angular error per pair, pixels.
    Returns:
        (H, W) float64 metres, NaN outside the scored pixels.
    Raises:
        ValueError: the frame has no ground truth for C.
    """
    if "C" not in frame.distance:
        raise ValueError(f"frame {frame.scene}/{frame.viewpoint} has no ground truth for camera C")
    c = np.asarray(frame.cameras["C"].position, dtype=np.float64)
    baselines = [np.asarray(frame.cameras[k].position, dtype=np.float64) - c for k in FLOOR_PAIRS]
    return floor_sigma(frame.distance["C"], frame.cameras["C"].rotation, baselines, px)


def floor_mae(sigma, mask=None) -> float:
    """The floor over a set of pixels: the MAE of the ideal matcher, ``sqrt(2 / pi)`` (:data:`GAUSSIAN_MAE_FACTOR`)
    times the mean of :func:`floor_sigma` over the scored pixels (those where it is not NaN) inside ``mask``, each
    pixel weighed the same (as ``mae_m``).

    Args:
        sigma: (H, W) metres, NaN outside the scored pixels (:func:`floor_sigma`).
        mask: optional (H, W) bool region; None = every scored pixel.
    Returns:
        Metres; NaN when no scored pixel is inside ``mask``.
    Raises:
        ValueError: ``mask`` is not a bool array of ``sigma``'s shape.
    """
    s = np.asarray(sigma, dtype=np.float64)
    sel = ~np.isnan(s)
    if mask is not None:
        mask = np.asarray(mask)
        if mask.shape != s.shape or mask.dtype != bool:
            raise ValueError(f"mask must be a bool array of the shape of sigma, got {mask.dtype} {mask.shape} and "
                             f"{s.shape}")
        sel &= mask
    return float(GAUSSIAN_MAE_FACTOR * s[sel].mean()) if sel.any() else float("nan")


def region_floors(sigma, masks: Mapping[str, np.ndarray]) -> dict[str, float]:
    """:func:`floor_mae` in every region: region name -> metres (NaN for a region without scored pixels)."""
    return {name: floor_mae(sigma, mask) for name, mask in masks.items()}


def times_floor(mae, floor):
    """A MAE as a multiple of the floor: ``mae / floor`` (unitless; 1 = what the ideal matcher achieves).

    Args:
        mae, floor: metres, scalars or arrays of one shape.
    Returns:
        float (or float64 array): NaN where either is NaN or ``floor`` is not positive and finite.
    """
    m = np.asarray(mae, dtype=np.float64)
    f = np.asarray(floor, dtype=np.float64)
    ok = np.isfinite(f) & (f > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(ok, m / np.where(ok, f, 1.0), np.nan)
    return float(out) if out.ndim == 0 else out


def floor_fields(mae: float, floor: float) -> dict[str, float]:
    """The results columns ``reports.schema.FLOOR_COLUMNS`` of a row whose MAE is ``mae`` over pixels whose floor
    (:func:`floor_mae`) is ``floor``: ``{"floor_m": floor, "mae_x_floor": mae / floor}`` (metres, unitless)."""
    return {"floor_m": float(floor), "mae_x_floor": times_floor(mae, floor)}
