"""reports.regions: every region mask against hand counts or an independent computation (ray casting, analytic
scenes), and the per-region summaries."""

from __future__ import annotations

import math

import numpy as np
import pytest

from harness.data.frame import Frame
from harness.render.raycast import raycast
from reconstruction.camera.equirect import bearing_grid
from reconstruction.camera.image_ops import dilate_wrapped
from reconstruction.camera.rig import CameraPose, Rig
from reports.metrics import depth_edges, summary
from reports.regions import (
    DISTANCE_BANDS_M,
    OCCLUSION_ABS_TOL_M,
    OCCLUSION_REL_TOL,
    REGION_NAMES,
    occluded_from,
    region_summaries,
    regions,
    texture_level,
)
from scenes.registry import get_scene
from tests.helpers import make_synthetic_frame

WIDTH = 320  # synthetic frames: 320 x 160, about 1 s to ray-cast


@pytest.fixture(scope="module")
def room():
    """Viewpoint 1 of the furnished synthetic_box room (seed 0): the rig stands near the texture-less board, and
    both U and R have pixels of C hidden from them.  Returns (frame, spec, regions)."""
    frame = make_synthetic_frame(WIDTH, viewpoint=1)
    entry, preset = get_scene("synthetic_box")
    spec = entry.spec(preset, seed=0)  # the spec make_synthetic_frame rendered
    return frame, spec, regions(frame)


def frame_of(gt_c, cameras=None, image=None, gt_u=None, gt_r=None) -> Frame:
    """An in-memory frame around a given ground truth of C (U and R default to C's, for masks that ignore them)."""
    h, w = gt_c.shape
    grey = np.full((h, w, 3), 128, dtype=np.uint8)
    return Frame(scene="unit", viewpoint="v0", width=w, height=h, baseline_m=0.4,
                 cameras=Rig().poses() if cameras is None else cameras,
                 images={"C": grey if image is None else image, "U": grey, "R": grey},
                 distance={"C": gt_c.astype(np.float32), "U": (gt_c if gt_u is None else gt_u).astype(np.float32),
                           "R": (gt_c if gt_r is None else gt_r).astype(np.float32)})


def rig_poses(rotation, position=(0.3, -0.2, 1.4), baseline=0.4) -> dict[str, CameraPose]:
    """Poses of an L-rig with any orientation: U = C + b * up, R = C + b * right of the rig's own axes."""
    rot = np.asarray(rotation, dtype=np.float64)
    c = np.asarray(position, dtype=np.float64)
    return {"C": CameraPose(c, rot), "U": CameraPose(c + baseline * rot[:, 2], rot),
            "R": CameraPose(c + baseline * rot[:, 0], rot)}


def yaw_tilt(yaw, tilt):
    cz, sz, cx, sx = math.cos(yaw), math.sin(yaw), math.cos(tilt), math.sin(tilt)
    rz = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]])
    return rz @ rx


def sphere_frame(w, cameras, radius=3.0) -> Frame:
    """Exact ground truth of all three cameras inside a sphere centred on C: a smooth scene without occlusion."""
    h = w // 2
    centre = cameras["C"].position
    dist = {}
    for name, pose in cameras.items():
        b = bearing_grid(w, h, pose.rotation)
        t = pose.position - centre
        tb = b @ t
        dist[name] = -tb + np.sqrt(tb * tb - t @ t + radius * radius)
    return frame_of(dist["C"], cameras, gt_u=dist["U"], gt_r=dist["R"])


# -------------------------------------------------------------------------------------------- general shape


def test_every_region_is_a_named_subset_of_the_scored_pixels():
    gt = np.full((36, 72), 3.0)
    gt[:4, :10] = np.inf  # no surface: in no region
    masks = regions(frame_of(gt))
    assert tuple(masks) == REGION_NAMES
    np.testing.assert_array_equal(masks["all"], np.isfinite(gt))
    for name, m in masks.items():
        assert m.shape == gt.shape and m.dtype == bool, name
        assert not (m & ~masks["all"]).any(), name
    assert masks["pole"][:4, :10].sum() == 0 and masks["pole"][:4, 10:].all()


def test_missing_ground_truth_is_an_error():
    frame = frame_of(np.full((4, 8), 2.0))
    del frame.distance["U"]
    with pytest.raises(ValueError, match=r"ground truth.*\['U'\]"):
        regions(frame)


# ----------------------------------------------------------------------------------------- pole and epipole


def test_pole_and_epipole_hand_counts_on_a_level_rig():
    w, h = 72, 36  # 5 degrees per pixel in both directions
    masks = regions(frame_of(np.full((h, w), 2.0)))
    # |latitude| > 60 deg: 90 - 5 (v + 0.5) > 60  <=>  v <= 5, and symmetrically at the bottom: 12 rows
    assert masks["pole"].sum() == 12 * w
    np.testing.assert_array_equal(masks["pole"].any(axis=1), [True] * 6 + [False] * 24 + [True] * 6)
    # U above C: within 15 deg of the up or down direction = colatitude 5 (v + 0.5) < 15: 3 rows at each pole
    assert masks["epipole_U"].sum() == 6 * w
    # R to the right: count the bearings within 15 deg of +X or -X one by one
    count = 0
    for v in range(h):
        for u in range(w):
            lam, phi = 2 * math.pi * (u + 0.5) / w - math.pi, math.pi / 2 - math.pi * (v + 0.5) / h
            ang = math.degrees(math.acos(max(-1.0, min(1.0, math.cos(phi) * math.sin(lam)))))
            count += ang < 15 or ang > 165
    assert masks["epipole_R"].sum() == count
    assert masks["epipole_R"][h // 2, 3 * w // 4] and masks["epipole_R"][h // 2, w // 4]  # right and left
    np.testing.assert_array_equal(masks["epipole"], masks["epipole_U"] | masks["epipole_R"])


def test_epipole_follows_the_actual_camera_positions():
    w, h = 72, 36
    level = regions(frame_of(np.full((h, w), 2.0)))
    # the whole rig yawed and tilted (positions and rotations consistently): the same pixels, since every
    # baseline keeps its direction in C's own camera frame; the pole mask is in C's image too
    turned = regions(frame_of(np.full((h, w), 2.0), rig_poses(yaw_tilt(0.7, 0.3))))
    for name in ("epipole", "epipole_U", "epipole_R", "pole"):
        np.testing.assert_array_equal(turned[name], level[name], err_msg=name)
    # U moved in front of C (rotations unchanged): its epipoles move to the image centre (forward) and the
    # seam (backward); the up direction is no longer an epipole
    cams = Rig().poses()
    cams["U"] = CameraPose(cams["C"].position + np.array([0.0, 0.4, 0.0]), cams["U"].rotation)
    moved = regions(frame_of(np.full((h, w), 2.0), cams))["epipole_U"]
    assert moved[h // 2, w // 2] and moved[h // 2, 0] and moved[h // 2, w - 1]
    assert not moved[0].any() and not moved[h // 2, w // 4]
    # the same count as the R epipoles of the level rig: both are cones about a horizontal axis
    assert moved.sum() == level["epipole_R"].sum()


# ----------------------------------------------------------------------------------------- distance bands


def test_distance_bands_partition_the_scored_pixels():
    gt = np.tile(np.array([0.5, 1.99, 2.0, 3.0, 4.999, 5.0, 7.5, np.inf]), (4, 1))
    masks = regions(frame_of(gt))
    bands = [masks[name] for name in DISTANCE_BANDS_M]
    np.testing.assert_array_equal(np.sum(bands, axis=0), np.isfinite(gt).astype(int))
    np.testing.assert_array_equal(masks["d<2m"][0], [1, 1, 0, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(masks["d2-5m"][0], [0, 0, 1, 1, 1, 0, 0, 0])
    np.testing.assert_array_equal(masks["d>=5m"][0], [0, 0, 0, 0, 0, 1, 1, 0])


# ------------------------------------------------------------------------------------------- discontinuity


def test_discontinuity_is_a_wrapped_band_about_depth_edges():
    h, w = 20, 40
    gt = np.full((h, w), 4.0)
    gt[:, :20] = 2.0  # edges between columns 19|20 and, across the seam, 39|0
    masks = regions(frame_of(gt))
    cols = np.flatnonzero(masks["discontinuity"].all(axis=0))
    # edge pixels at columns 19, 20, 39, 0, widened by 3 columns each way (wrapping around)
    np.testing.assert_array_equal(cols, [0, 1, 2, 3, 16, 17, 18, 19, 20, 21, 22, 23, 36, 37, 38, 39])
    assert masks["discontinuity"].sum() == 16 * h
    # a smooth 5 % step is no discontinuity
    gt[:, :20] = 4.0 / 1.05
    assert not regions(frame_of(gt))["discontinuity"].any()


# --------------------------------------------------------------------------------------------- textureless


def test_texture_level_on_flat_noise_and_ramp_images():
    h, w = 40, 80
    assert (texture_level(np.full((h, w, 3), 90, np.uint8)) == 0).all()
    ramp = np.repeat((20 + 3 * np.arange(h))[:, None], w, axis=1).astype(np.uint8)
    lvl = texture_level(ramp)  # a ramp of 3 grey levels per row reads 3 away from the replicated poles
    np.testing.assert_allclose(lvl[6:-6], 3.0, atol=1e-4)
    half = np.full((h, w), 100, np.uint8)
    rng = np.random.default_rng(0)
    half[:, 40:] = rng.integers(60, 140, (h, 40))
    image = np.repeat(half[:, :, None], 3, axis=2)
    masks = regions(frame_of(np.full((h, w), 2.0), image=image))
    tl = masks["textureless"]
    # the flat half is texture-less except near the noise (blur radius 3 + Sobel 1 + window 2 = 6 columns),
    # also across the seam; the noise half never is
    assert tl[:, 6:34].all() and not tl[:, 40:].any()
    assert not tl[:, 0].any() and not tl[:, 39].any()


@pytest.mark.slow
def test_textureless_finds_the_blank_board_of_the_synthetic_room(room):
    frame, spec, masks = room
    c = frame.cameras["C"]
    _, box, _, _ = raycast(spec, c.position, bearing_grid(frame.width, frame.height, c.rotation).reshape(-1, 3))
    board = np.array([spec.boxes[b].name == "board" for b in box]).reshape(masks["all"].shape)
    tl = masks["textureless"]
    assert board.mean() > 0.05  # the board fills a good part of this view
    # measured: 82 % of the board is texture-less and 85 % of the texture-less pixels are board
    assert tl[board].mean() > 0.7
    assert board[tl].mean() > 0.7
    assert tl[~board].mean() < 0.03  # the noise-textured walls, floor and furniture are not


# ------------------------------------------------------------------------------------------------ occlusion


def test_no_occlusion_inside_a_sphere_whatever_the_rig_orientation():
    # a smooth closed scene seen from inside: every surface point is visible from every camera, and the exact
    # ground truth of U and R only agrees with C's when each camera's own pose is used
    for rot in (np.eye(3), yaw_tilt(0.7, 0.3), yaw_tilt(-2.0, -1.2)):
        frame = sphere_frame(72, rig_poses(rot))
        assert not occluded_from(frame, "U").any() and not occluded_from(frame, "R").any()
    # swapping U's and R's ground truth (a pose mix-up) must show: points appear hidden
    frame = sphere_frame(72, rig_poses(yaw_tilt(0.7, 0.3)))
    frame.distance["U"], frame.distance["R"] = frame.distance["R"], frame.distance["U"]
    assert occluded_from(frame, "U").sum() > 100


@pytest.mark.slow
def test_occluded_pixels_are_really_hidden(room):
    """Every flagged pixel is confirmed by casting the ray from U or R to its surface point in the scene."""
    frame, spec, masks = room
    gt = frame.distance["C"].astype(np.float64)
    c = frame.cameras["C"]
    points = c.position + gt.reshape(-1, 1) * bearing_grid(frame.width, frame.height, c.rotation).reshape(-1, 3)
    for name in ("U", "R"):
        flagged = masks[f"occluded_{name}"].ravel()
        assert flagged.sum() >= 10, name  # both cameras have hidden pixels from this viewpoint
        pos = frame.cameras[name].position
        to_x = points[flagged] - pos
        rng = np.linalg.norm(to_x, axis=1)
        t, _, _, _ = raycast(spec, pos, to_x / rng[:, None])
        # a surface nearer than X, beyond the tolerance, blocks every flagged ray
        assert np.all(t < rng - OCCLUSION_REL_TOL * t - OCCLUSION_ABS_TOL_M), name
        # and the unflagged pixels are overwhelmingly visible (misses lie within a pixel of an occluding edge)
        to_x = points[~flagged] - pos
        rng = np.linalg.norm(to_x, axis=1)
        t, _, _, _ = raycast(spec, pos, to_x / rng[:, None])
        assert np.mean(t < rng * 0.98 - 0.01) < 0.003, name
    np.testing.assert_array_equal(masks["occluded"], masks["occluded_U"] | masks["occluded_R"])


@pytest.mark.slow
def test_occluded_share_is_small_and_beside_depth_edges(room):
    frame, _, masks = room
    occ = masks["occluded"]
    assert 0.0005 < occ.mean() < 0.02  # measured 0.22 % of the pixels
    # an occluder stands in front of every hidden point, so C sees a jump in distance right beside it; the
    # occluders here include the board, 2.5 cm proud of the wall (a 3 % jump at 1 m), hence a 5 % jump threshold
    near_edge = dilate_wrapped(depth_edges(frame.distance["C"], math.log(1.05)), 3)
    assert near_edge[occ].mean() > 0.95  # measured: all of them within 3 px of such a jump ...
    assert near_edge.mean() < 0.25  # ... in a band holding 17 % of the image


# ---------------------------------------------------------------------------------------- region summaries


@pytest.mark.slow
def test_region_summaries(room):
    frame, _, masks = room
    gt = frame.distance["C"].astype(np.float64)
    rng = np.random.default_rng(1)
    pred = gt * (1 + rng.normal(0, 0.03, gt.shape))
    pred[masks["occluded"]] *= 1.5  # a method that fails where U or R cannot see
    pred[rng.random(gt.shape) < 0.01] = np.nan
    conf = -np.abs(pred - gt)
    rows = region_summaries(frame, pred)
    assert [r["region"] for r in rows] == list(REGION_NAMES)
    whole = summary(pred, gt)
    assert rows[0]["mae_m"] == whole["mae_m"]  # exactly, not approximately
    np.testing.assert_array_equal([rows[0][k] for k in whole], list(whole.values()))
    err = np.where(np.isfinite(pred), np.abs(np.nan_to_num(pred) - gt), gt)
    by_name = {r["region"]: r for r in rows}
    for name, m in masks.items():
        assert by_name[name]["valid_px"] == m.sum(), name
        if m.any():
            assert by_name[name]["mae_m"] == pytest.approx(err[m].mean(), rel=1e-12), name
    assert by_name["occluded"]["mae_m"] > 5 * by_name["all"]["mae_m"]
    assert math.isnan(by_name["d>=5m"]["mae_m"]) == (masks["d>=5m"].sum() == 0)
    # with a confidence every row gains ause; precomputed masks give the same rows
    with_conf = region_summaries(frame, pred, conf, masks=masks)
    assert all("ause" in r for r in with_conf)
    assert with_conf[0]["ause"] == pytest.approx(summary(pred, gt, conf)["ause"], rel=1e-12)
    assert [r["mae_m"] for r in with_conf] == [r["mae_m"] for r in rows]


@pytest.mark.slow
def test_region_summaries_reject_a_wrong_shape(room):
    frame, _, masks = room
    with pytest.raises(ValueError, match=r"\(160, 319\) and \(160, 320\)"):
        region_summaries(frame, np.ones((160, 319)), masks=masks)
