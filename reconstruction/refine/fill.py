"""Distance maps filled and fused: the pixels without a valid distance filled from their neighbours, and the two
pairs' distances of camera C fused into one.

``fill_invalid`` (normalised convolution) and ``fill_edge_aware`` (OpenCV's fast global smoother guided by an image)
fill (H, W) distance maps; ``fuse_average`` (the mean of the valid pairs: the flow pipeline's ``average``) and
``agreed_distance`` (the mean where the pairs agree) fuse per-pair (N,) distances.  Distances in metres.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

__all__ = ["FILL_SPACES", "check_fill_space", "fill_invalid", "fill_edge_aware", "fuse_average", "agreed_distance"]


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


#: the quantities :func:`fill_edge_aware` can interpolate: inverse distance (1/m) or log distance
FILL_SPACES = ("inverse", "log")


def check_fill_space(space: str) -> None:
    """Raise ValueError naming ``space`` and the known ones unless it is one of :data:`FILL_SPACES`."""
    if space not in FILL_SPACES:
        raise ValueError(f"unknown fill space {space!r} (known: {', '.join(FILL_SPACES)})")


def fill_edge_aware(d: np.ndarray, valid: np.ndarray, guide: np.ndarray, lam: float, sigma_color: float,
                    space: str = "inverse") -> np.ndarray:
    """Interpolate distances from valid pixels without crossing image edges.

    Normalised edge-aware smoothing of a function of the distance: ``f^-1(S(valid * f(d)) / S(valid))`` with ``S``
    OpenCV's fast global smoother guided by ``guide`` and ``f`` the inverse (``space="inverse"``: a plane's inverse
    distance is linear in the bearing) or the logarithm (``"log"``: a gap between a near and a far surface is
    not pulled towards the near one, as the mean of inverse distances is); pixels the smoother cannot reach fall
    back to :func:`fill_invalid`.

    Args:
        d: (H, W) distances, metres (positive); valid: (H, W) bool; guide: (H, W, 3) uint8 image.
        lam: smoothness (larger reaches farther); sigma_color: edge scale in 8-bit levels.
        space: ``"inverse"`` or ``"log"`` (:data:`FILL_SPACES`).
    Returns:
        (H, W) float64 interpolated distances (at every pixel, valid ones included), metres.
    """
    check_fill_space(space)
    fgs = cv2.ximgproc.createFastGlobalSmootherFilter(guide, lam, sigma_color)
    m = valid.astype(np.float32)
    safe = np.maximum(d, 1e-6)
    value = 1.0 / safe if space == "inverse" else np.log(safe)
    num = fgs.filter((m * value).astype(np.float32))
    den = fgs.filter(m)
    reached = den > 1e-4
    mean = num / np.where(reached, den, 1.0)
    if space == "inverse":
        out = 1.0 / np.maximum(mean, 1e-3).astype(np.float64)
    else:
        out = np.exp(mean.astype(np.float64))
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
