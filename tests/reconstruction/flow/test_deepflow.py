"""DeepFlow (variational flow with DeepMatching's matching term) against OpenCV's variational-only DeepFlow."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from reconstruction.flow.backends import FlowBackend, equirect_flow, get_flow, interpolate_matches
from reconstruction.flow.deepflow import DeepFlowParams, deep_flow, deep_flow_both, match_field, match_weights
from reconstruction.flow.deepmatching import DeepMatchingParams, Matches
from tests.reconstruction.flow.test_deepmatching import texture

H, W = 64, 128
PARAMS = DeepFlowParams(matching=DeepMatchingParams(downscale=0))


def _epe(flow, du, dv, cols=slice(None)):
    ex = (flow[..., 0] - du + W / 2) % W - W / 2  # equirect: a flow that goes the other way round is the same
    return float(np.mean(np.hypot(ex, flow[..., 1] - dv)[:, cols]))


@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.slow
def test_quantised_matches_do_not_pin_the_flow():
    """256x128 pair moved by exactly (40, 3) px (wrapping); DeepMatching at its default half resolution can only
    say 2 or 4 px vertically (1 or 2 working px).  The matching term is the authors' one (each match one point;
    sparse at fine levels), so the data term recovers the sub-match precision: mean end-point error below
    0.02 px (measured 0.0006 px; with each match splatted over its whole 16 px cell, as before, 0.175 px)."""
    h, w = 128, 256
    img0 = texture(h, w, 7)
    img1 = np.roll(np.roll(img0, 40, axis=1), 3, axis=0)
    flow = deep_flow(img0, img1, DeepFlowParams())
    ex = (flow[..., 0] - 40 + w / 2) % w - w / 2
    assert float(np.mean(np.hypot(ex, flow[..., 1] - 3)[4:-4])) < 0.02


def test_match_field_splats_each_match_at_one_point_and_wraps():
    """Each match is one point, bilinearly splatted; weights add up (none lost, none duplicated), the flow is
    their weighted mean and is scaled with the level; a point between the last and the first column wraps."""
    m = Matches(x0=np.array([1.0, 1.0, 31.5]), y0=np.array([5.0, 5.0, 13.0]), x1=np.array([-9.0, -6.0, 34.5]),
                y1=np.array([6.0, 6.0, 13.0]), score=np.ones(3), cell=4.0)
    phi = np.array([2.0, 1.0, 1.0])
    mu, mv, mw = match_field(m, phi, 16, 32)
    assert mw[5, 1] == 3.0 and mu[5, 1] == -9.0 and mv[5, 1] == 1.0  # (2 * -10 + 1 * -7) / 3
    assert mw[13, 31] == 0.5 and mw[13, 0] == 0.5 and mu[13, 0] == 3.0 and mu[13, 31] == 3.0  # across the seam
    assert mw.sum() == 4.0 and np.count_nonzero(mw) == 3
    # half size: (1, 5) -> (0.25, 2.25) shared by columns 0-1 and rows 2-3, its flow halved; weights kept
    mu, mv, mw = match_field(m, phi, 16, 32, level_hw=(8, 16))
    np.testing.assert_allclose(mw.sum(), 4.0, rtol=1e-6)
    np.testing.assert_allclose(mw[2:4, 0:2], 3.0 * np.outer([0.75, 0.25], [0.75, 0.25]), rtol=1e-6)
    np.testing.assert_allclose(mu[2:4, 0:2], -4.5, rtol=1e-6)
    np.testing.assert_allclose(mv[2:4, 0:2], 0.5, rtol=1e-6)
    np.testing.assert_allclose(mu[6:8, 15], 1.5, rtol=1e-6)  # the seam match: x 15.5 -> columns 15 and 0
    np.testing.assert_allclose(mu[6:8, 0], 1.5, rtol=1e-6)


def test_match_weights_favour_textured_consistent_matches():
    """The authors' phi: a correct match in texture weighs about 1 (0.3 to 5), a match 7 px off weighs at most
    a fifth of it, and any match in a flat image weighs 0."""
    img0 = texture(H, W, 8)
    img1 = np.roll(img0, 10, axis=1)
    ys, xs = np.mgrid[12:52:8, 4:124:8]
    x0, y0 = xs.ravel().astype(float), ys.ravel().astype(float)
    good = Matches(x0=x0, y0=y0, x1=x0 + 10, y1=y0, score=np.ones(x0.size), cell=8.0)
    bad = Matches(x0=x0, y0=y0, x1=x0 + 17, y1=y0, score=np.ones(x0.size), cell=8.0)
    pg, pb = match_weights(img0, img1, good), match_weights(img0, img1, bad)
    assert 0.3 < np.median(pg) < 5.0
    assert np.mean(pb) < 0.2 * np.mean(pg)
    flat = np.full_like(img0, 128)
    assert np.all(match_weights(flat, flat, good) == 0.0)


def test_wrapping_backends_get_unpadded_images():
    seen = []

    def fake(img0, img1):
        seen.append(img0.shape)
        return np.zeros(img0.shape[:2] + (2,), np.float32)

    img = np.zeros((8, 16, 3), np.uint8)
    equirect_flow(FlowBackend("w", fake, wraps=True), img, img, 8)
    equirect_flow(FlowBackend("p", fake), img, img, 8)
    assert seen == [(8, 16, 3), (8, 32, 3)]
    assert get_flow("deepflow").wraps and get_flow("epicflow").wraps and not get_flow("deepflow-opencv").wraps


@pytest.mark.slow
def test_both_directions_at_once_equal_each_alone_and_the_backend_keeps_the_reverse():
    """deep_flow_both (two threads) gives exactly deep_flow of each direction; the deepflow backend's second call
    (the same images swapped) returns the reverse flow its first call solved, and an unrelated call recomputes."""
    from reconstruction.flow.deepmatching import deep_matching_both

    img0 = texture(H, W, 9)
    img1 = np.roll(np.roll(img0, 12, axis=1), 1, axis=0)
    m = deep_matching_both(img0, img1, PARAMS.matching)
    f01, f10 = deep_flow_both(img0, img1, PARAMS, m)
    np.testing.assert_array_equal(f01, deep_flow(img0, img1, PARAMS, matches=m[0]))
    np.testing.assert_array_equal(f10, deep_flow(img1, img0, PARAMS, matches=m[1]))
    backend = FlowBackend("deepflow-test", get_flow("deepflow").compute, params={**get_flow("deepflow").params,
                                                                                   "downscale": 0}, wraps=True)
    fwd = backend(img0, img1)
    bwd = backend(img1, img0)
    np.testing.assert_array_equal(fwd, f01)
    np.testing.assert_array_equal(bwd, f10)
    np.testing.assert_array_equal(backend(img1, img0), f10)  # recomputed: nothing pending any more


def test_a_backend_warms_up_once_per_process_before_its_first_timed_flow():
    calls = []

    def warm():
        calls.append(1)

    backend = FlowBackend("warm-test", lambda a, b: np.zeros(a.shape[:2] + (2,), np.float32), warm_up=warm)
    backend.prepare()
    backend.prepare()
    FlowBackend("warm-test-2", backend.compute, warm_up=warm).prepare()  # the same warm-up: already run
    assert calls == [1]
    assert get_flow("deepflow").warm_up is not None and get_flow("dis").warm_up is None
    FlowBackend("plain", backend.compute).prepare()  # nothing to prepare



def test_epicflow_interpolation_with_fewer_matches_than_its_neighbourhood_is_defined():
    """OpenCV's edge-aware interpolator fits each pixel from k = 128 matches; with fewer it read past its neighbour
    table (garbage or a segmentation fault, seen with 12) until k was cut to the matches' count: with 40 matches of a
    pure shift, two runs agree and the shift is interpolated everywhere (within 0.01 px)."""
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[0:48, 0:96]
    img = np.dstack([(128 + 60 * np.sin(xx / 7.0) * np.cos(yy / 5.0)).astype(np.uint8)] * 3)
    p0 = np.stack([rng.uniform(5, 90, 40), rng.uniform(5, 43, 40)], axis=1).astype(np.float32)
    p1 = p0 + np.float32([2.0, -1.0])
    first = interpolate_matches(img, img, p0, p1)
    second = interpolate_matches(img, img, p0, p1)
    assert first.shape == (48, 96, 2) and first.dtype == np.float32
    np.testing.assert_array_equal(first, second)
    np.testing.assert_allclose(first[..., 0], 2.0, atol=0.01)
    np.testing.assert_allclose(first[..., 1], -1.0, atol=0.01)
