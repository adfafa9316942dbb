"""Spherical two-view triangulation along the reference camera's bearings.

For a pixel of C with unit bearing ``a`` and a pair with baseline ``t`` (C -> K, length B), the epipolar
plane is spanned by ``t`` and ``a``.  In that plane let ``alpha`` be the angle between ``a`` and ``t`` and
``beta`` the angle between ``t`` and the bearing from K to the point.  For a point at distance ``d``::

    beta(d) = atan2(d sin(alpha), d cos(alpha) - B)            (in (alpha, pi) for d in (0, inf))
    d(beta) = B sin(beta) / sin(beta - alpha)                  (law of sines; beta - alpha = parallax)

A matched bearing ``c`` is projected into the epipolar plane to read off ``beta_obs``; its component out of
the plane (flow error across the epipolar curve) cannot be explained by any distance and is ignored.
All functions take flat arrays: bearings (N, 3), results (N,); angles in radians, lengths in metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PairGeometry", "pair_geometry", "beta_of_distance", "triangulate_sines", "triangulate_midpoint",
           "TriangulationLimits"]


@dataclass(frozen=True)
class TriangulationLimits:
    """When a pair's estimate is meaningless.

    Attributes:
        min_angle_deg: a pixel closer than this to the pair's epipole (either one), degrees, is invalid
            for the pair: there the distance is unobservable.
        min_parallax_rad: smaller parallax (beta - alpha) counts as "at infinity or behind": invalid.
        d_min_m, d_max_m: estimates are clamped to this range, metres.
    """

    min_angle_deg: float = 3.0
    min_parallax_rad: float = 2e-4
    d_min_m: float = 0.05
    d_max_m: float = 100.0


@dataclass
class PairGeometry:
    """Per-pixel epipolar geometry of one pair.

    Attributes:
        baseline_m: B, metres.
        cos_alpha, sin_alpha: (N,) cos/sin of the angle between ``a`` and the baseline.
        beta_obs: (N,) observed angle between the baseline and the matched bearing, radians.
        off_plane: (N,) angle of the matched bearing out of the epipolar plane, radians (0 for a perfect
            match: flow across the epipolar curve is pure error, the paper's "lateral pixel flow").
    """

    baseline_m: float
    cos_alpha: np.ndarray
    sin_alpha: np.ndarray
    beta_obs: np.ndarray
    off_plane: np.ndarray | None = None

    @property
    def alpha(self) -> np.ndarray:
        return np.arctan2(self.sin_alpha, self.cos_alpha)


def pair_geometry(a: np.ndarray, t: np.ndarray, c: np.ndarray) -> PairGeometry:
    """Epipolar-plane angles for bearings ``a`` (N, 3) from C, baseline ``t`` (3,), matches ``c`` (N, 3)."""
    b = float(np.linalg.norm(t))
    that = np.asarray(t, dtype=np.float64) / b
    cos_a = a @ that
    n = a - cos_a[:, None] * that
    sin_a = np.linalg.norm(n, axis=1)
    nhat = n / np.where(sin_a > 1e-12, sin_a, 1.0)[:, None]
    beta = np.arctan2(np.einsum("ij,ij->i", c, nhat), c @ that)
    off = np.arcsin(np.clip(np.einsum("ij,ij->i", c, np.cross(that, nhat)), -1.0, 1.0))
    return PairGeometry(b, cos_a, sin_a, beta, off)


def beta_of_distance(g: PairGeometry, d: np.ndarray):
    """``beta(d)`` and its derivative ``d beta / d d`` (radians, radians per metre), each (N,)."""
    x = d * g.cos_alpha - g.baseline_m
    y = d * g.sin_alpha
    r2 = x * x + y * y
    return np.arctan2(y, x), -g.baseline_m * g.sin_alpha / np.maximum(r2, 1e-300)


def _validity(g: PairGeometry, parallax: np.ndarray, limits: TriangulationLimits) -> np.ndarray:
    return (g.sin_alpha >= np.sin(np.deg2rad(limits.min_angle_deg))) & (parallax > limits.min_parallax_rad)


def triangulate_sines(g: PairGeometry, limits: TriangulationLimits = TriangulationLimits()):
    """Law-of-sines distance along ``a`` for each pixel.

    Returns:
        ``(d, valid)``: (N,) distances clamped to ``[d_min_m, d_max_m]`` (finite everywhere) and (N,) bool
        validity (False at the epipoles, for non-positive parallax, or when clamping was needed).
    """
    parallax = g.beta_obs - g.alpha
    valid = _validity(g, parallax, limits)
    safe = np.maximum(parallax, limits.min_parallax_rad)
    d = g.baseline_m * np.sin(g.beta_obs) / np.sin(safe)
    d = np.where(np.isfinite(d), d, limits.d_max_m)
    valid &= (d >= limits.d_min_m) & (d <= limits.d_max_m)
    return np.clip(d, limits.d_min_m, limits.d_max_m), valid


def triangulate_midpoint(a: np.ndarray, t: np.ndarray, c: np.ndarray,
                         limits: TriangulationLimits = TriangulationLimits()):
    """Distance from C of the midpoint of the shortest segment between the rays C + s a and K + u c.

    Args:
        a: (N, 3) unit bearings from C; t: (3,) baseline C -> K; c: (N, 3) unit bearings from K.
    Returns:
        ``(d, valid)`` as :func:`triangulate_sines`.
    """
    t = np.asarray(t, dtype=np.float64)
    ac = np.einsum("ij,ij->i", a, c)
    at, ct = a @ t, c @ t
    denom = 1.0 - ac * ac
    ok = denom > 1e-12
    safe = np.where(ok, denom, 1.0)
    s = (at - ac * ct) / safe  # along a
    u = (ac * at - ct) / safe  # along c
    mid = 0.5 * ((s[:, None] * a) + (t + u[:, None] * c))
    d = np.linalg.norm(mid, axis=1) * np.sign(s)
    g = pair_geometry(a, t, c)
    valid = ok & _validity(g, g.beta_obs - g.alpha, limits) & (s > 0) & (u > 0)
    d = np.where(np.isfinite(d) & (d > 0), d, limits.d_max_m)
    valid &= (d >= limits.d_min_m) & (d <= limits.d_max_m)
    return np.clip(d, limits.d_min_m, limits.d_max_m), valid
