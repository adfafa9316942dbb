"""Dense optical-flow backends behind one interface.

A backend maps two equal-size 8-bit RGB images to a flow field ``(H, W, 2)`` float32 (du, dv in pixels,
from image 0 to image 1).  Equirect images wrap around: :func:`equirect_flow` pads both images with
columns copied from the opposite edge before calling the backend, so correspondences that cross the
left/right seam are found, then crops the result back to ``W`` columns.

``oracle`` is not an image backend: it is the exact correspondence from ground-truth distance and lives in
:mod:`reconstruction.flow.matching`.  Register more backends with :func:`register_flow`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["FlowBackend", "FLOWS", "register_flow", "get_flow", "available_flows", "equirect_flow"]


@dataclass(frozen=True)
class FlowBackend:
    """A dense flow method.

    Attributes:
        name: the ``--flow`` name.
        compute: ``compute(img0, img1) -> (H, W, 2) float32`` on (H, W, 3) uint8 RGB images.
        description: one line for ``--help`` and reports.
    """

    name: str
    compute: Callable[[np.ndarray, np.ndarray], np.ndarray]
    description: str = ""


def _gray(img: np.ndarray) -> np.ndarray:
    return img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)


def _deepflow(img0, img1):
    """OpenCV's DeepFlow (the variational part of Weinzaepfel et al. 2013), the paper's method."""
    return cv2.optflow.createOptFlow_DeepFlow().calc(_gray(img0), _gray(img1), None)


def _dis(img0, img1):
    """DIS flow (Kroeger et al. 2016), medium preset with a finer patch stride and variational refinement."""
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    dis.setFinestScale(0)
    dis.setPatchSize(8)
    dis.setPatchStride(3)
    dis.setGradientDescentIterations(25)
    dis.setVariationalRefinementIterations(10)
    dis.setVariationalRefinementAlpha(10.0)
    dis.setUseSpatialPropagation(True)
    return dis.calc(_gray(img0), _gray(img1), None)


def _farneback(img0, img1):
    """Farneback polynomial-expansion flow (5 levels, window 21)."""
    return cv2.calcOpticalFlowFarneback(_gray(img0), _gray(img1), None, pyr_scale=0.5, levels=5, winsize=21,
                                        iterations=5, poly_n=7, poly_sigma=1.5, flags=0)


def _rlof(img0, img1):
    """Dense RLOF (Senst et al.), robust local flow interpolated densely (needs 3-channel 8-bit)."""
    return cv2.optflow.calcOpticalFlowDenseRLOF(np.ascontiguousarray(img0), np.ascontiguousarray(img1), None)


FLOWS: dict[str, FlowBackend] = {}


def register_flow(backend: FlowBackend) -> None:
    """Add (or replace) a flow backend under ``backend.name``."""
    FLOWS[backend.name] = backend


register_flow(FlowBackend("deepflow", _deepflow, "OpenCV DeepFlow (variational), the paper's flow"))
register_flow(FlowBackend("dis", _dis, "OpenCV DIS, medium preset, stride 3, variational refinement"))
register_flow(FlowBackend("farneback", _farneback, "OpenCV Farneback polynomial expansion"))
if hasattr(cv2, "optflow") and hasattr(cv2.optflow, "calcOpticalFlowDenseRLOF"):
    register_flow(FlowBackend("rlof", _rlof, "OpenCV dense RLOF"))


def available_flows() -> list[str]:
    """Names accepted by ``--flow``: the image backends plus ``oracle``."""
    return sorted([*FLOWS, "oracle"])


def get_flow(name: str) -> FlowBackend:
    """Look up an image flow backend; raises ValueError listing the known names."""
    if name not in FLOWS:
        raise ValueError(f"unknown flow {name!r} (known: {', '.join(available_flows())})")
    return FLOWS[name]


def equirect_flow(backend: FlowBackend, img0: np.ndarray, img1: np.ndarray, pad: int) -> np.ndarray:
    """Flow between two equirect images, with ``pad`` columns of wrap-around on each side.

    Args:
        backend: the flow method.
        img0, img1: (H, W, 3) uint8 RGB.
        pad: columns copied from the opposite edge on both sides (0 <= pad <= W); the flow of a pixel
            whose match lies up to ``pad`` columns past the seam is then found directly.
    Returns:
        (H, W, 2) float32 flow of img0's pixels; targets may lie outside [0, W) (the caller wraps them).
    """
    w = img0.shape[1]
    pad = int(min(max(pad, 0), w))

    def wrap(img):
        return np.ascontiguousarray(np.concatenate([img[:, w - pad:], img, img[:, :pad]], axis=1)) if pad else img

    flow = backend.compute(wrap(img0), wrap(img1))
    flow = np.asarray(flow, dtype=np.float32)
    if not np.isfinite(flow).all():
        flow = np.nan_to_num(flow, nan=0.0, posinf=0.0, neginf=0.0)
    return np.ascontiguousarray(flow[:, pad:pad + w])
