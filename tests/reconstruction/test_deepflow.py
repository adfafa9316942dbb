"""DeepFlow (variational flow with DeepMatching's matching term) against OpenCV's variational-only DeepFlow."""

from __future__ import annotations

import cv2
import numpy as np

from reconstruction.flow.backends import FlowBackend, equirect_flow, get_flow
from reconstruction.flow.deepflow import DeepFlowParams, deep_flow, match_field
from reconstruction.flow.deepmatching import DeepMatchingParams, Matches
from tests.reconstruction.test_deepmatching import texture

H, W = 64, 128
PARAMS = DeepFlowParams(matching=DeepMatchingParams(downscale=0))


def _epe(flow, du, dv, cols=slice(None)):
    ex = (flow[..., 0] - du + W / 2) % W - W / 2  # equirect: a flow that goes the other way round is the same
    return float(np.mean(np.hypot(ex, flow[..., 1] - dv)[:, cols]))


def test_beats_variational_only_deepflow_on_a_large_displacement():
    """Image 1 = image 0 moved 30 px sideways (wrapping) and 2 px down; exact flow (30, 2) except the 2 rows
    rolled in.  The faithful DeepFlow has an end-point error below 0.5 px; OpenCV's variational-only DeepFlow,
    which has no matching term, loses the large displacement (EPE above 10 px, measured 28 px)."""
    img0 = texture(H, W, 5)
    img1 = np.roll(np.roll(img0, 30, axis=1), 2, axis=0)
    flow = deep_flow(img0, img1, PARAMS)
    assert flow.shape == (H, W, 2) and flow.dtype == np.float32
    ours = _epe(flow[4:-4], 30, 2)
    gray = [cv2.cvtColor(x, cv2.COLOR_RGB2GRAY) for x in (img0, img1)]
    theirs = _epe(cv2.optflow.createOptFlow_DeepFlow().calc(gray[0], gray[1], None)[4:-4], 30, 2)
    assert ours < 0.5 and theirs > 10.0 and ours < theirs / 20


def test_non_periodic_flow_and_determinism():
    """Without wrapping: image 0 shows the scene 24 px further right than image 1 (flow +24 px); the flow is
    right within 0.5 px on the columns whose match stays inside image 1; two runs give the same flow."""
    big = texture(H, W + 32, 6)
    img0, img1 = big[:, 24:24 + W], big[:, :W]
    p = DeepFlowParams(wrap=False, matching=DeepMatchingParams(downscale=0, wrap=False))
    f1 = deep_flow(np.ascontiguousarray(img0), np.ascontiguousarray(img1), p)
    f2 = deep_flow(np.ascontiguousarray(img0), np.ascontiguousarray(img1), p)
    np.testing.assert_array_equal(f1, f2)
    inner = f1[4:-4, 8:W - 24 - 8]
    assert float(np.mean(np.hypot(inner[..., 0] - 24, inner[..., 1]))) < 0.5


def test_match_field_splats_each_match_over_its_cell_and_wraps():
    m = Matches(x0=np.array([1.0, 20.0]), y0=np.array([5.0, 5.0]), x1=np.array([-9.0, 23.0]),
                y1=np.array([6.0, 5.0]), score=np.array([2.0, 1.0]), cell=4.0)
    mu, mv, mw = match_field(m, 16, 32)
    assert mu[5, 1] == -10 and mv[5, 1] == 1 and mw[5, 1] == 1.0
    assert mu[5, 31] == -10  # the first match's cell crosses the seam (columns -1..2)
    assert mu[5, 20] == 3 and mw[5, 20] == 0.5
    assert mw[12, 10] == 0.0 and mw.sum() == 16 * 1.0 + 16 * 0.5


def test_wrapping_backends_get_unpadded_images():
    seen = []

    def fake(img0, img1):
        seen.append(img0.shape)
        return np.zeros(img0.shape[:2] + (2,), np.float32)

    img = np.zeros((8, 16, 3), np.uint8)
    equirect_flow(FlowBackend("w", fake, wraps=True), img, img, 8)
    equirect_flow(FlowBackend("p", fake), img, img, 8)
    assert seen == [(8, 16, 3), (8, 32, 3)]
    assert get_flow("deepflowdm").wraps and get_flow("epicflow").wraps and not get_flow("deepflow").wraps
