"""The rig's tilt: poses rotate with it, level rigs are unchanged, and the pipeline reconstructs tilted rigs."""

from __future__ import annotations

import numpy as np
import pytest

from harness.render.raycast import render_frame
from reconstruction.camera.rig import Rig, tilt_rotation, yaw_rotation
from reconstruction.methods.flow_pipeline import reconstruct
from scenes.model import choose_viewpoints
from scenes.registry import get_scene

TOL = 1e-12


def _is_rotation(r):
    return np.allclose(r.T @ r, np.eye(3), atol=TOL) and abs(np.linalg.det(r) - 1.0) < TOL


def test_level_rig_is_unchanged_bit_for_bit():
    """No tilt: the poses are exactly the yaw-only ones (so every existing frame keeps its bytes)."""
    pos = np.array([0.3, -0.2, 1.4])
    rig = Rig(position=pos, yaw_rad=0.7, baseline_m=0.4)
    rot = yaw_rotation(0.7)
    poses = rig.poses()
    assert not rig.tilted
    assert np.array_equal(poses["C"].rotation, rot)
    assert np.array_equal(poses["U"].position, pos + 0.4 * rot[:, 2])
    assert np.array_equal(poses["R"].position, pos + 0.4 * rot[:, 0])
    assert np.array_equal(tilt_rotation(0.0, 0.0), np.eye(3))


@pytest.mark.parametrize(("pitch", "roll", "yaw", "b"), [(0.2, 0.0, 0.0, 0.4), (0.0, -0.15, 0.0, 0.3),
                                                         (0.1, 0.12, 1.3, 0.3), (-0.3, 0.25, -2.0, 0.5)])
def test_tilted_poses_follow_the_rotated_axes(pitch, roll, yaw, b):
    """U - C = b * rig up and R - C = b * rig right, where the axes are the yaw-then-tilt rotated ones."""
    c = np.array([1.0, 2.0, 1.3])
    rig = Rig(position=c, yaw_rad=yaw, baseline_m=b, pitch_rad=pitch, roll_rad=roll)
    poses = rig.poses()
    rot = yaw_rotation(yaw) @ tilt_rotation(pitch, roll)
    assert _is_rotation(rot)
    for name in "CUR":
        assert np.allclose(poses[name].rotation, rot, atol=TOL)
    np.testing.assert_allclose(poses["U"].position - c, b * rot[:, 2], atol=TOL)
    np.testing.assert_allclose(poses["R"].position - c, b * rot[:, 0], atol=TOL)
    # the baseline stays b and the two baselines stay perpendicular
    assert np.linalg.norm(poses["U"].position - c) == pytest.approx(b, abs=TOL)
    assert np.dot(poses["U"].position - c, poses["R"].position - c) == pytest.approx(0.0, abs=TOL)


def test_tilt_directions():
    """Positive pitch raises the forward axis (nose up); positive roll leans the up axis towards the right."""
    fwd = tilt_rotation(0.3, 0.0)[:, 1]
    np.testing.assert_allclose(fwd, [0.0, np.cos(0.3), np.sin(0.3)], atol=TOL)
    up = tilt_rotation(0.0, 0.2)[:, 2]
    np.testing.assert_allclose(up, [np.sin(0.2), 0.0, np.cos(0.2)], atol=TOL)
    # the up camera's height above C is b cos(pitch) cos(roll)
    rig = Rig(position=np.zeros(3), baseline_m=0.4, pitch_rad=0.3, roll_rad=0.2)
    assert rig.poses()["U"].position[2] == pytest.approx(0.4 * np.cos(0.3) * np.cos(0.2), abs=TOL)


def test_choose_viewpoints_tilt_and_height_range():
    entry, preset = get_scene("box_room")
    spec = entry.spec(preset, seed=3)
    level = choose_viewpoints(spec, 4, 3)
    again = choose_viewpoints(spec, 4, 3, tilt_max_rad=0.0)
    for a, b in zip(level, again, strict=True):  # default and explicit 0: the very same placements
        assert np.array_equal(a.position, b.position) and a.yaw_rad == b.yaw_rad and not b.tilted
    tilted = choose_viewpoints(spec, 4, 3, tilt_max_rad=0.2)
    assert all(r.tilted and abs(r.pitch_rad) <= 0.2 and abs(r.roll_rad) <= 0.2 for r in tilted)
    assert len({round(r.pitch_rad, 9) for r in tilted}) == 4  # each rig its own tilt
    assert [r.pitch_rad for r in tilted] == [r.pitch_rad for r in choose_viewpoints(spec, 4, 3, tilt_max_rad=0.2)]
    high = choose_viewpoints(spec, 4, 3, height_range=(1.7, 1.8))
    assert all(1.7 <= r.position[2] <= 1.8 for r in high[1:]) and high[0].position[2] == pytest.approx(1.75)
    with pytest.raises(ValueError, match="tilt_max_rad"):
        choose_viewpoints(spec, 1, 3, tilt_max_rad=-0.1)
    with pytest.raises(ValueError, match="height range"):
        choose_viewpoints(spec, 1, 3, height_range=(1.5, 1.2))


def test_tilted_frame_reconstructs_exactly_with_the_oracle_flow():
    """A tilted 0.3 m rig, ray-cast: frame.json records the tilt, and the flow pipeline (rectified pairs from the
    poses) reconstructs C's distance with exact correspondences as exactly as for a level rig."""
    entry, preset = get_scene("synthetic_box")
    spec = entry.spec(preset, seed=0)
    rig = Rig(position=np.array([0.2, -0.1, 1.3]), yaw_rad=0.4, baseline_m=0.3, pitch_rad=0.15, roll_rad=-0.1)
    frame = render_frame(spec, rig, 200, "synthetic_box", "vp000")
    assert frame.renderer["rig"]["pitch_rad"] == pytest.approx(0.15)
    assert frame.renderer["rig"]["roll_rad"] == pytest.approx(-0.1)
    gt = frame.distance["C"]
    m = np.isfinite(gt)
    for rectify in (True, False):
        d = reconstruct(frame, flow="oracle", rectify=rectify, variants=["average"]).distance["average"]
        assert float(np.abs(d[m] - gt[m]).mean()) < 1e-4, rectify  # metres
