"""Equirectangular camera model (pure numpy).

Conventions (the rig and frame format follow them; verified against Blender renders):

* Camera frame: X right, Y forward, Z up.  A pose is ``position`` (3,) and ``rotation`` (3, 3),
  world-from-camera (columns are the camera axes in world coordinates).
* Image W x H with W == 2H.  Pixel coordinates ``(u, v)`` are *continuous* with the centre of pixel
  column ``i`` at ``u = i`` and of row ``j`` at ``v = j`` (the OpenCV ``remap`` convention), so
  ``lam = 2*pi*(u + 0.5)/W - pi`` and ``phi = pi/2 - pi*(v + 0.5)/H``.
* Bearing in the camera frame: ``(cos(phi)*sin(lam), cos(phi)*cos(lam), sin(phi))``.
  The image centre looks forward (+Y), ``u + 0.5 = 0.75 W`` looks right (+X), the top row looks up (+Z),
  and the left and right edges are the same (backward) meridian.

All functions broadcast over leading dimensions; angles are radians, lengths metres, pixels pixels.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "baseline_cosine",
    "pixel_to_lonlat",
    "lonlat_to_pixel",
    "lonlat_to_bearing",
    "bearing_to_lonlat",
    "pixel_to_bearing",
    "bearing_to_pixel",
    "bearing_grid",
    "project",
    "project_with_derivative",
    "project_rays_camera",
    "wrap_pixel",
]


def pixel_to_lonlat(u, v, width: int, height: int):
    """Pixel coordinates -> (longitude, latitude).

    Args:
        u, v: arrays of the same shape, continuous pixel coordinates (pixel centres at integers).
        width, height: image size in pixels.
    Returns:
        ``(lam, phi)`` in radians, same shape as ``u``; ``lam`` in [-pi, pi), ``phi`` in (-pi/2, pi/2).
    """
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    lam = 2.0 * np.pi * (u + 0.5) / width - np.pi
    phi = 0.5 * np.pi - np.pi * (v + 0.5) / height
    return lam, phi


def lonlat_to_pixel(lam, phi, width: int, height: int):
    """(longitude, latitude) in radians -> continuous pixel coordinates ``(u, v)``.

    ``u`` is not wrapped: ``lam`` in [-pi, pi) gives ``u`` in [-0.5, W - 0.5).
    """
    u = (np.asarray(lam, dtype=np.float64) + np.pi) * width / (2.0 * np.pi) - 0.5
    v = (0.5 * np.pi - np.asarray(phi, dtype=np.float64)) * height / np.pi - 0.5
    return u, v


def lonlat_to_bearing(lam, phi):
    """(longitude, latitude) -> unit bearing, shape ``lam.shape + (3,)`` (camera frame)."""
    lam = np.asarray(lam, dtype=np.float64)
    phi = np.asarray(phi, dtype=np.float64)
    cphi = np.cos(phi)
    return np.stack([cphi * np.sin(lam), cphi * np.cos(lam), np.sin(phi)], axis=-1)


def bearing_to_lonlat(b):
    """Bearing(s) ``(..., 3)`` (any positive length) -> ``(lam, phi)`` in radians, ``lam`` in [-pi, pi]."""
    b = np.asarray(b, dtype=np.float64)
    x, y, z = b[..., 0], b[..., 1], b[..., 2]
    lam = np.arctan2(x, y)
    phi = np.arctan2(z, np.hypot(x, y))
    return lam, phi


def pixel_to_bearing(u, v, width: int, height: int):
    """Continuous pixel coordinates -> unit bearing ``(..., 3)`` in the camera frame."""
    return lonlat_to_bearing(*pixel_to_lonlat(u, v, width, height))


def bearing_to_pixel(b, width: int, height: int):
    """Bearing(s) ``(..., 3)`` in the camera frame -> continuous pixel coordinates ``(u, v)``.

    ``u`` lies in [-0.5, W - 0.5]; both -0.5 and W - 0.5 are the backward meridian (the seam).
    """
    return lonlat_to_pixel(*bearing_to_lonlat(b), width, height)


def bearing_grid(width: int, height: int, rotation=None, dtype=np.float64):
    """Bearings of every pixel centre, shape ``(H, W, 3)``.

    Args:
        rotation: optional (3, 3) world-from-camera matrix; if given, bearings are in world coordinates.
    """
    # separable: longitude by column, latitude by row (the same values as pixel_to_bearing of every pixel)
    lam, _ = pixel_to_lonlat(np.arange(width), np.zeros(width), width, height)
    _, phi = pixel_to_lonlat(np.zeros(height), np.arange(height), width, height)
    cphi = np.cos(phi)[:, None]
    b = np.empty((height, width, 3))
    b[..., 0] = cphi * np.sin(lam)[None, :]
    b[..., 1] = cphi * np.cos(lam)[None, :]
    b[..., 2] = np.sin(phi)[:, None]
    if rotation is not None:
        b = b @ np.asarray(rotation, dtype=np.float64).T
    return b.astype(dtype, copy=False)


def baseline_cosine(width: int, height: int, rotation, position, other_position, other: str = "other") -> np.ndarray:
    """Cosine of the angle between each pixel's bearing of a posed camera and its baseline to another camera.

    Args:
        width, height: the camera's image size, pixels; rotation: (3, 3) its world-from-camera rotation;
        position, other_position: (3,) the two camera centres, metres (world); other: the other camera's name, for
            the error.
    Returns:
        (H, W) float64 in [-1, 1]; 1 = looking straight at the other camera (its epipole), -1 = straight away.
    Raises:
        ValueError: the two centres coincide (no baseline direction).
    """
    t = np.asarray(other_position, dtype=np.float64) - np.asarray(position, dtype=np.float64)
    norm = np.linalg.norm(t)
    if not norm > 0:
        raise ValueError(f"camera {other} coincides with camera C: no baseline direction")
    return np.clip(bearing_grid(width, height, rotation) @ (t / norm), -1.0, 1.0)


def project(points, position, rotation, width: int, height: int):
    """Project world points into a posed equirectangular camera.

    Args:
        points: (..., 3) world coordinates, metres.
        position: (3,) camera centre, metres.
        rotation: (3, 3) world-from-camera rotation.
    Returns:
        ``(u, v)`` continuous pixel coordinates, each of shape ``points.shape[:-1]``.
    """
    rel = np.asarray(points, dtype=np.float64) - np.asarray(position, dtype=np.float64)
    b_cam = rel @ np.asarray(rotation, dtype=np.float64)  # R^T (X - p), row-vector form
    return bearing_to_pixel(b_cam, width, height)


def project_with_derivative(origin, bearing, distance, position, rotation, width: int, height: int):
    """Project ``X = origin + distance * bearing`` and differentiate the pixel w.r.t. ``distance``.

    Args:
        origin: (3,) or (..., 3) world point the rays start from (the reference camera centre), metres.
        bearing: (..., 3) unit ray directions in world coordinates.
        distance: (...) distances along the rays, metres.
        position, rotation: pose of the camera projected into (world-from-camera rotation).
    Returns:
        ``u, v, du_dd, dv_dd``: pixel coordinates (pixels) and their analytic derivatives (pixels per metre),
        each of shape ``distance.shape``.  The derivative of ``u`` is that of the unwrapped longitude, so it
        is continuous across the seam; both are undefined (returned as 0) exactly at the poles.
    """
    rot = np.asarray(rotation, dtype=np.float64)
    start = (np.asarray(origin, dtype=np.float64) - np.asarray(position, dtype=np.float64)) @ rot
    return project_rays_camera(start, np.asarray(bearing, dtype=np.float64) @ rot, distance, width, height)


def project_rays_camera(start, direction, distance, width: int, height: int):
    """:func:`project_with_derivative` with the rays already in the target camera's frame.

    Args:
        start: (3,) or (..., 3) ray origins relative to the camera centre, camera frame, metres.
        direction: (..., 3) ray directions in the camera frame (d b / d distance).
        distance: (...) distances along the rays, metres.
    Returns:
        ``u, v, du_dd, dv_dd`` as :func:`project_with_derivative`.
    """
    d = np.asarray(distance, dtype=np.float64)[..., None]
    b = start + d * direction  # camera-frame vector to the point, not normalised
    x, y, z = b[..., 0], b[..., 1], b[..., 2]
    dx, dy, dz = direction[..., 0], direction[..., 1], direction[..., 2]
    rho2 = x * x + y * y
    r2 = rho2 + z * z
    rho = np.sqrt(rho2)
    pole = rho2 <= 0
    safe_rho2 = np.where(pole, 1.0, rho2)
    dlam = np.where(pole, 0.0, (y * dx - x * dy) / safe_rho2)
    dphi = np.where(pole, 0.0, (rho2 * dz - z * (x * dx + y * dy)) / (np.where(pole, 1.0, rho) * r2))
    u, v = lonlat_to_pixel(np.arctan2(x, y), np.arctan2(z, rho), width, height)
    return u, v, dlam * width / (2.0 * np.pi), -dphi * height / np.pi


def wrap_pixel(u, v, width: int, height: int):
    """Map pixel coordinates that left the image back onto the sphere.

    A point above the top edge (``v < -0.5``) has crossed the north pole: it reappears at
    ``v' = -1 - v`` on the meridian half a turn away (``u + W/2``); likewise below the bottom edge.
    Columns are then wrapped into [-0.5, W - 0.5).

    Args:
        u, v: arrays of continuous pixel coordinates (any values).
    Returns:
        ``(u, v)`` with ``u`` in [-0.5, W - 0.5) and ``v`` in [-0.5, H - 0.5].
    """
    u = np.asarray(u, dtype=np.float64).copy()
    v = np.asarray(v, dtype=np.float64).copy()
    # latitude is periodic with period 2H along a great circle through the poles
    v = np.mod(v + 0.5, 2.0 * height) - 0.5
    over = v > height - 0.5
    v = np.where(over, 2.0 * height - 1.0 - v, v)
    u = np.where(over, u + width / 2.0, u)
    u = np.mod(u + 0.5, width) - 0.5
    return u, v
