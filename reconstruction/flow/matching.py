"""Per-pair correspondences: for every pixel of the reference camera C, the bearing of its match in U or R.

Flow is computed in a per-pair *flow frame*.  With ``rectify=True`` (the default) both images of the pair
are resampled into the pair's rectified frame (baseline = polar axis, see :mod:`reconstruction.camera.resample`);
with ``rectify=False`` each image stays in its own camera frame (the paper's plain equirect flow).  The
flow is then read at the position of each C pixel in the flow frame and turned into a world bearing.

``oracle`` computes the exact correspondence from C's ground-truth distance instead of from images.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from reconstruction.camera.equirect import bearing_grid, bearing_to_pixel, pixel_to_bearing, wrap_pixel
from reconstruction.camera.resample import rectifying_rotation, sample_equirect, warp_equirect
from reconstruction.flow.backends import ORACLE, FlowBackend, equirect_flow, get_flow

__all__ = ["PairMatch", "match_pair", "default_pad"]


@dataclass
class PairMatch:
    """Correspondences of camera C's pixels in camera ``name``.

    Attributes:
        name: "U" or "R".
        baseline: (3,) world vector from C's centre to the other camera's centre, metres.
        bearing: (H, W, 3) unit world bearings, from the other camera, of each C pixel's match.
        rect_rotation: (3, 3) world-from-rectified rotation of this pair (used by gradient weights).
        flow_px: (H, W) magnitude of the flow in the flow frame, pixels (0 for the oracle).
        fb_error_px: (H, W) forward-backward inconsistency, pixels: |F(p) + B(p + F(p))| with B the flow from
            the other image back to C's (0 for the oracle).  Large values flag occlusions and failed matches.
        seconds: wall time of the flow computation (after the backend's once-per-process warm-up,
            :meth:`~reconstruction.flow.backends.FlowBackend.prepare`).
    """

    name: str
    baseline: np.ndarray
    bearing: np.ndarray
    rect_rotation: np.ndarray
    flow_px: np.ndarray
    fb_error_px: np.ndarray
    seconds: float


def default_pad(width: int, rectify: bool) -> int:
    """Wrap-around padding (columns per side) for flow: rectified disparity runs along columns, so a
    small margin suffices; plain equirect C-R correspondences move up to W/2 sideways near the poles."""
    return max(16, width // 16) if rectify else width // 2


def match_pair(frame, name: str, flow: str | FlowBackend, rectify: bool = True, pad: int | None = None) -> PairMatch:
    """Match every pixel of camera C in camera ``name`` ("U" or "R").

    Args:
        frame: a :class:`harness.data.frame.Frame` (only cameras, images and, for the oracle, C's distance).
        name: the other camera.
        flow: a :class:`FlowBackend`, a backend name (:func:`~reconstruction.flow.backends.discover_flows`) or
            "oracle".
        rectify: compute flow on the rectified pair (True) or the plain equirect images (False).
        pad: wrap-around columns per side for flow (default :func:`default_pad`).
    Returns:
        A :class:`PairMatch`.
    Raises:
        ValueError: for an unknown flow, or the oracle on a frame without ground truth.
    """
    w, h = frame.width, frame.height
    cam_c, cam_k = frame.cameras["C"], frame.cameras[name]
    t = np.asarray(cam_k.position, np.float64) - np.asarray(cam_c.position, np.float64)
    rect = rectifying_rotation(t, cam_c.rotation)
    rot_fc, rot_fk = (rect, rect) if rectify else (cam_c.rotation, cam_k.rotation)
    a = bearing_grid(w, h, cam_c.rotation)  # (H, W, 3) world bearings of C's pixels
    backend = None
    if not (isinstance(flow, str) and flow == ORACLE):
        backend = flow if isinstance(flow, FlowBackend) else get_flow(flow)
        backend.prepare()  # once per process: compilation is not the flow's time
    start = time.perf_counter()
    if isinstance(flow, str) and flow == ORACLE:
        truth = getattr(frame, "distance", {})  # a method's input (MethodInput) has none: only the frame has
        if "C" not in truth:
            raise ValueError("flow 'oracle' needs ground-truth distance, which this frame does not give it")
        d = truth["C"].astype(np.float64)
        finite = np.isfinite(d)
        rel = np.where(finite[..., None], cam_c.position + np.where(finite, d, 0.0)[..., None] * a - cam_k.position,
                       a)
        # the exact match, expressed as a pixel of the other camera's flow frame
        q_u, q_v = bearing_to_pixel(rel @ rot_fk, w, h)
        flow_px = np.zeros((h, w))
        fb_err = np.zeros((h, w))
    else:
        img_c = warp_equirect(frame.images["C"], rot_fc, cam_c.rotation)
        img_k = warp_equirect(frame.images[name], rot_fk, cam_k.rotation)
        npad = default_pad(w, rectify) if pad is None else pad
        field = equirect_flow(backend, img_c, img_k, npad)
        back = equirect_flow(backend, img_k, img_c, npad)
        # forward-backward check in the flow frame: follow F, then B from where F lands
        g_v, g_u = np.mgrid[0:h, 0:w].astype(np.float64)
        e_u, e_v = wrap_pixel(g_u + field[..., 0], g_v + field[..., 1], w, h)
        fb = field.astype(np.float64) + sample_equirect(back, e_u, e_v).astype(np.float64)
        fb_field = np.hypot(fb[..., 0], fb[..., 1]).astype(np.float32)
        if rectify:
            # where each C pixel sits in the rectified frame, and the flow there (bilinear, wrap-aware)
            p_u, p_v = bearing_to_pixel(a @ rot_fc, w, h)
            both = sample_equirect(np.dstack([field, fb_field]), p_u, p_v).astype(np.float64)
            f, fb_err = both[..., :2], both[..., 2]
        else:
            p_u, p_v = g_u, g_v
            f = field.astype(np.float64)
            fb_err = fb_field.astype(np.float64)
        q_u, q_v = p_u + f[..., 0], p_v + f[..., 1]
        flow_px = np.hypot(f[..., 0], f[..., 1])
    q_u, q_v = wrap_pixel(q_u, q_v, w, h)
    bearing = pixel_to_bearing(q_u, q_v, w, h) @ np.asarray(rot_fk).T
    return PairMatch(name=name, baseline=t, bearing=bearing, rect_rotation=rect, flow_px=flow_px,
                     fb_error_px=fb_err, seconds=time.perf_counter() - start)
