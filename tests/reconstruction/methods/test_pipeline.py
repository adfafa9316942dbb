"""The whole reconstruction pipeline on exact synthetic frames (no Blender)."""

import numpy as np
import pytest

from reconstruction.camera.equirect import bearing_grid, bearing_to_pixel
from reconstruction.camera.resample import rectifying_rotation, sample_equirect, warp_equirect
from reconstruction.flow.backends import FlowBackend, discover_flows, equirect_flow, get_flow
from reconstruction.flow.matching import match_pair
from reconstruction.methods.flow_pipeline import available_variants, reconstruct
from reconstruction.refine.lm import get_variant
from reconstruction.refine.triangulate import pair_geometry, triangulate_sines
from tests.helpers import make_synthetic_frame


def _mae(pred, gt):
    m = np.isfinite(gt)
    return float(np.abs(pred[m] - gt[m]).mean())


@pytest.fixture(scope="module")
def frame400():
    return make_synthetic_frame(400)


@pytest.mark.slow
@pytest.mark.parametrize("rectify", [True, False])
def test_oracle_is_exact_for_every_variant(frame400, rectify):
    """Exact correspondences: the geometric variants land on the truth to float precision; the colour term
    moves distances by the views' sub-pixel intensity differences (anti-aliasing), well under 1 mm."""
    result = reconstruct(frame400, flow="oracle", rectify=rectify)
    assert set(result.distance) == set(available_variants())
    for name, d in result.distance.items():
        assert d.shape == (frame400.height, frame400.width) and np.isfinite(d).all()
        limit = 1e-3 if get_variant(name if name != "average" else "angle").color_weight > 0 else 1e-5
        assert _mae(d, frame400.distance["C"]) < limit, name  # metres


def test_oracle_needs_ground_truth(synthetic_frame):
    import copy

    frame = copy.copy(synthetic_frame)
    frame.distance = {}
    with pytest.raises(ValueError, match="ground-truth"):
        reconstruct(frame, flow="oracle")


def test_unknown_flow_and_variant_are_rejected(synthetic_frame):
    with pytest.raises(ValueError, match="unknown flow"):
        reconstruct(synthetic_frame, flow="nope")
    with pytest.raises(ValueError, match="unknown variant"):
        reconstruct(synthetic_frame, flow="oracle", variants=["average", "nope"])


def test_the_reconstruction_keeps_each_pairs_forward_backward_inconsistency(synthetic_frame):
    """``pair_fb_px``: per pair, the flow's forward-backward inconsistency at C's pixels as :func:`match_pair` gives
    it (float32, finite, >= 0; small where the frame's texture is followed), 0 everywhere for the oracle."""
    f = synthetic_frame
    result = reconstruct(f, flow="dis", variants=["average"])
    for k in ("U", "R"):
        fb = result.pair_fb_px[k]
        assert fb.shape == (f.height, f.width) and fb.dtype == np.float32 and np.isfinite(fb).all()
        assert fb.min() >= 0.0 and np.median(fb) < 1.0  # pixels
        assert np.mean(np.abs(fb - match_pair(f, k, "dis").fb_error_px)) < 0.05  # pixels
    exact = reconstruct(f, flow="oracle", variants=["average"])
    assert all((exact.pair_fb_px[k] == 0).all() for k in ("U", "R"))


@pytest.mark.slow
def test_rectified_flow_beats_plain_and_refinement_beats_average(frame400):
    gt = frame400.distance["C"]
    rect = reconstruct(frame400, flow="dis", rectify=True)
    plain = reconstruct(frame400, flow="dis", rectify=False, variants=["average", "angle"])
    mae = {k: _mae(v, gt) for k, v in rect.distance.items()}
    # measured at 400x200 on this frame: average ~0.06 m, refined ~0.03 m, plain average > 0.3 m
    assert mae["average"] < 0.15
    assert min(mae[k] for k in mae if k != "average") < 0.8 * mae["average"]
    assert mae["average"] < _mae(plain.distance["average"], gt)
    assert _mae(plain.distance["angle"], gt) < _mae(plain.distance["average"], gt)


def test_rectifying_rotation_puts_baseline_at_the_pole():
    rot = np.array([[np.cos(0.7), -np.sin(0.7), 0], [np.sin(0.7), np.cos(0.7), 0], [0, 0, 1]])
    for t in (rot[:, 0] * 0.4, rot[:, 2] * 0.4):
        r = rectifying_rotation(t, rot)
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
        np.testing.assert_allclose(r[:, 2], t / 0.4, atol=1e-12)
    # C-U of an upright rig needs no rotation at all
    np.testing.assert_allclose(rectifying_rotation(rot[:, 2], rot), rot, atol=1e-12)


def test_warp_round_trip_preserves_the_image(synthetic_frame):
    img = synthetic_frame.images["C"]
    cam = synthetic_frame.cameras["C"]
    rect = rectifying_rotation(synthetic_frame.cameras["R"].position - cam.position, cam.rotation)
    back = warp_equirect(warp_equirect(img, rect, cam.rotation), cam.rotation, rect)
    # two bilinear resamplings blur; away from the poles the median error stays small (8-bit levels)
    band = slice(img.shape[0] // 4, 3 * img.shape[0] // 4)
    assert np.median(np.abs(back[band].astype(int) - img[band].astype(int))) <= 6


def test_sample_equirect_wraps_across_the_seam():
    img = np.tile(np.arange(8, dtype=np.float32), (4, 1))
    # halfway between the last column (7) and the first (0) across the seam
    assert sample_equirect(img, np.array([7.5]), np.array([1.0]))[0] == pytest.approx(3.5)
    assert sample_equirect(img, np.array([-0.5]), np.array([1.0]))[0] == pytest.approx(3.5)
    assert sample_equirect(img, np.array([8.0 + 2]), np.array([1.0]))[0] == pytest.approx(2.0)


def test_flow_finds_correspondences_across_the_seam():
    rng = np.random.default_rng(0)
    base = (rng.random((64, 128, 3)) * 255).astype(np.uint8)
    import cv2

    base = cv2.GaussianBlur(base, (0, 0), 1.5)
    shifted = np.roll(base, 6, axis=1)  # content moves 6 px right, wrapping at the seam
    flow = equirect_flow(get_flow("dis"), base, shifted, pad=16)
    # pixels near the right edge move across the seam: their flow is still +6, not -122
    assert np.median(flow[8:-8, -4:, 0]) == pytest.approx(6.0, abs=0.5)
    no_pad = equirect_flow(get_flow("dis"), base, shifted, pad=0)
    assert abs(np.median(no_pad[8:-8, -4:, 0]) - 6.0) > abs(np.median(flow[8:-8, -4:, 0]) - 6.0)


def test_matching_maps_flow_back_to_bearings(synthetic_frame):
    """A backend returning the oracle's flow must reproduce the oracle bearings through the same path."""
    frame = synthetic_frame
    exact = match_pair(frame, "R", "oracle", rectify=False)
    cam = frame.cameras["R"]

    u, v = bearing_to_pixel(exact.bearing @ cam.rotation, frame.width, frame.height)
    vv, uu = np.mgrid[0:frame.height, 0:frame.width]
    du = np.mod(u - uu + frame.width / 2, frame.width) - frame.width / 2
    oracle_flow = np.stack([du, v - vv], axis=-1).astype(np.float32)

    backend = FlowBackend("_test_oracle", lambda a, b: oracle_flow if a is not None else None)
    got = match_pair(frame, "R", backend, rectify=False, pad=0)
    ang = np.degrees(np.arccos(np.clip(np.einsum("...i,...i", got.bearing, exact.bearing), -1, 1)))
    assert np.percentile(ang, 99.9) < 1e-3  # degrees


def test_bearings_of_c_are_those_of_the_camera_model(synthetic_frame):
    b = bearing_grid(synthetic_frame.width, synthetic_frame.height, synthetic_frame.cameras["C"].rotation)
    np.testing.assert_allclose(np.linalg.norm(b, axis=-1), 1.0, atol=1e-12)


#: the flows that run numba DeepMatching: seconds each (and its kernels compile on a first run): marked ``slow``
DEEPMATCHING_FLOWS = {"deepflow", "epicflow"}


def test_the_slow_flows_are_registered():
    assert DEEPMATCHING_FLOWS <= set(discover_flows()[0])


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in DEEPMATCHING_FLOWS else n
                                  for n in sorted(discover_flows()[0])])
@pytest.mark.parametrize("rectify", [True, False])
def test_every_flow_backend_finds_usable_matches(synthetic_frame, name, rectify):
    """Registry smoke test: each backend runs through the full matching path and most C-U matches triangulate
    to within 25 % of the truth on the 200x100 synthetic frame (oracle: exact)."""

    frame = synthetic_frame
    m = match_pair(frame, "U", name, rectify=rectify)
    a = bearing_grid(frame.width, frame.height, frame.cameras["C"].rotation).reshape(-1, 3)
    d, valid = triangulate_sines(pair_geometry(a, m.baseline, m.bearing.reshape(-1, 3)))
    gt = frame.distance["C"].reshape(-1)
    rel = np.abs(d - gt) / gt
    assert m.fb_error_px.shape == (frame.height, frame.width) and np.isfinite(m.fb_error_px).all()
    assert np.mean(rel[valid] < 0.25) > 0.6, name
