"""Rig self-calibration (reconstruction.rig_calibration): the rotation algebra, the robust epipolar fit on exact
synthetic bearings, the match selection, and U's and R's told rotations corrected in the flow pipeline."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from reconstruction.camera.rig import CameraPose
from reconstruction.methods.flow_pipeline import FlowMethod
from reconstruction.methods.self_calibration import self_calibrate
from reconstruction.photometry import NO_CALIBRATION, PhotometricParams
from reconstruction.refine.triangulate import TriangulationLimits
from reconstruction.rig_calibration import (
    NO_RIG_CALIBRATION,
    RigParams,
    corrected_pose,
    fit_rotation,
    rotation_vector_matrix,
    usable_matches,
)
from tests.helpers import make_synthetic_frame


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle of the rotation ``a @ b.T``, degrees."""
    m = np.asarray(a) @ np.asarray(b).T
    return float(np.degrees(np.arccos(np.clip((np.trace(m) - 1.0) / 2.0, -1.0, 1.0))))


@pytest.mark.parametrize("omega", [[0.0, 0.0, 0.0], [0.01, -0.02, 0.03], [0.0, 0.0, 1.0], [0.5, 0.4, -0.3]])
def test_rotation_vector_matrix_is_rodrigues(omega):
    m = rotation_vector_matrix(np.array(omega))
    np.testing.assert_allclose(m, cv2.Rodrigues(np.array(omega, np.float64))[0], atol=1e-12)
    np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-12)


def _scene(n: int, omega_true: np.ndarray, baseline: np.ndarray, seed: int = 0):
    """C's bearings of ``n`` points 1-20 m away in all directions, and their bearings from K seen through a told
    rotation that is off by ``omega_true`` (K's true rotation is ``Rot(omega_true) @ told``)."""
    rng = np.random.default_rng(seed)
    c = rng.normal(size=(n, 3))
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    points = c * rng.uniform(1.0, 20.0, size=(n, 1))
    true_k = points - baseline
    true_k /= np.linalg.norm(true_k, axis=1, keepdims=True)
    told_k = true_k @ rotation_vector_matrix(omega_true)  # Rot^T applied to each row
    return c, told_k


@pytest.mark.parametrize("baseline", [np.array([0.0, 0.0, 0.4]), np.array([0.4, 0.0, 0.0]),
                                      np.array([0.1, -0.3, 0.25])])
def test_fit_recovers_the_rotation_from_exact_matches(baseline):
    omega = np.radians([0.15, -0.2, 0.1])
    c, k = _scene(5000, omega, baseline)
    fit = fit_rotation(c, k, baseline)
    np.testing.assert_allclose(fit["omega"], omega, atol=1e-9)
    assert fit["degrees"] == pytest.approx(np.degrees(np.linalg.norm(omega)), abs=1e-7)


def test_fit_holds_against_noise_and_outliers():
    """0.02 degrees of noise on every match and a fifth of the matches wrong by up to 5 degrees: the rotation comes
    back within 0.005 degrees."""
    baseline = np.array([0.0, 0.0, 0.4])
    omega = np.radians([0.2, 0.1, -0.15])
    c, k = _scene(20000, omega, baseline, seed=1)
    rng = np.random.default_rng(2)
    k = k + rng.normal(scale=np.radians(0.02), size=k.shape)
    bad = rng.random(k.shape[0]) < 0.2
    k[bad] += rng.uniform(-1, 1, size=(bad.sum(), 3)) * np.radians(5.0)
    k /= np.linalg.norm(k, axis=1, keepdims=True)
    fit = fit_rotation(c, k, baseline)
    assert np.degrees(np.linalg.norm(np.array(fit["omega"]) - omega)) < 0.005


def test_each_hemisphere_sees_a_told_rotation_but_not_an_effect_of_one_hemisphere():
    """With ``hemispheres``: a rotation of the whole camera is found from the matches above the horizon and from
    those below alone (each within 1e-6 degrees of the fit's), while matches turned below the horizon only (a
    scene's effect there, not the camera's; 0.1 degrees of noise on every match) give the whole fit a rotation of at
    least ``RigParams.min_degrees`` but the matches above it none (under 0.02 degrees); without it nothing is
    added."""
    baseline = np.array([0.4, 0.0, 0.0])
    omega = np.radians([0.1, -0.15, 0.2])
    c, k = _scene(20000, omega, baseline, seed=3)
    assert "hemispheres" not in fit_rotation(c, k, baseline)["evidence"]
    fit = fit_rotation(c, k, baseline, hemispheres=True)
    halves = fit["evidence"]["hemispheres"]
    assert len(halves) == 2 and all(h["blocks"] == 16 for h in halves)
    for h in halves:
        assert h["degrees"] == pytest.approx(fit["degrees"], abs=1e-6) and h["p_value"] < 1e-3
    c, exact = _scene(20000, np.zeros(3), baseline, seed=3)
    k = np.where((c[:, 2] < 0)[:, None], k, exact)
    k = k + np.random.default_rng(4).normal(scale=np.radians(0.1), size=k.shape)  # the turn within the noise
    k /= np.linalg.norm(k, axis=1, keepdims=True)
    fit = fit_rotation(c, k, baseline, hemispheres=True)
    above, lower = fit["evidence"]["hemispheres"]
    assert fit["degrees"] > 0.072 and lower["degrees"] > 0.2 and above["degrees"] < 0.02


def test_fit_skips_non_finite_matches_and_gives_up_on_too_few():
    baseline = np.array([0.4, 0.0, 0.0])
    c, k = _scene(2000, np.radians([0.1, 0.0, 0.0]), baseline)
    k[::2] = np.nan
    fit = fit_rotation(c, k, baseline)
    assert fit["matches"] <= 1000 and np.degrees(fit["omega"][0]) == pytest.approx(0.1, abs=1e-7)
    none = fit_rotation(c[:50], k[:50], baseline)
    assert none["omega"] == [0.0, 0.0, 0.0] and none["matches"] < 100


def test_corrected_pose_turns_about_world_axes_and_keeps_the_position():
    pose = CameraPose(np.array([1.0, 2.0, 3.0]), rotation_vector_matrix(np.array([0.0, 0.0, 0.7])))
    out = corrected_pose(pose, np.radians([0.0, 0.3, 0.0]))
    np.testing.assert_array_equal(out.position, pose.position)
    np.testing.assert_allclose(out.rotation, rotation_vector_matrix(np.radians([0.0, 0.3, 0.0])) @ pose.rotation,
                               atol=1e-15)


@pytest.mark.parametrize("kwargs", [{"mode": "affine"}, {"max_fb_px": 0.0}, {"texture_quantile": 1.0},
                                    {"min_sin": -0.1}, {"max_degrees": 0.0}, {"hemispheres": 2.0},
                                    {"confirm_factor": -1}, {"confirm_factor": 1.5}])
def test_rig_params_refuse_bad_values(kwargs):
    with pytest.raises(ValueError, match="rig calibration"):
        RigParams(**kwargs)


def test_usable_matches_drop_inconsistent_invalid_and_untextured_pixels():
    h, w = 40, 80
    image = np.zeros((h, w, 3), np.uint8)
    image[:, w // 2:] = np.random.default_rng(0).integers(0, 255, size=(h, w // 2, 3))  # right half textured
    bearing = np.tile(np.array([0.0, 1.0, 0.0]), (h, w, 1))
    fb = np.zeros((h, w))
    fb[0, -1] = 2.0
    valid = np.ones((h, w), bool)
    valid[1, -1] = False
    out = usable_matches(image, bearing, fb, valid, RigParams(texture_quantile=0.5)).reshape(h, w, 3)
    kept = np.isfinite(out).all(axis=-1)
    assert not kept[:, : w // 2 - 3].any()  # flat: no texture
    assert not kept[0, -1] and not kept[1, -1]
    assert kept[5:-5, w // 2 + 3: -3].mean() > 0.9


@pytest.mark.slow
@pytest.mark.parametrize("share, confirm", [(0.0, 0), (1.0, 0), (0.0, 1)])
def test_self_calibration_corrects_a_told_rotation_that_is_off(share, confirm):
    """A ray-cast frame whose told U and R rotations are off by 0.4 degrees: the pre-pass's matches bring both
    within 0.15 degrees of the truth, also when each hemisphere's matches alone must find the floor
    (``RigParams.hemispheres`` 1) and whether or not a flow pass at full resolution must find it again
    (``confirm_factor`` 1, the default, or 0); the told poses of an exact frame are left as they are."""
    frame = make_synthetic_frame(width=480)
    told = dict(frame.cameras)
    turns = {"U": np.radians([0.2, -0.3, 0.15]), "R": np.radians([-0.25, 0.1, 0.3])}
    for k, omega in turns.items():
        told[k] = corrected_pose(frame.cameras[k], omega / np.linalg.norm(omega) * np.radians(0.4))
    off = dataclasses.replace(frame, cameras=told)
    params = RigParams(hemispheres=share, confirm_factor=confirm)
    calibration = self_calibrate(off, NO_CALIBRATION, params, TriangulationLimits())
    matched, fits = calibration.frame, calibration.record["rig"]
    assert "rig" in calibration.seconds and set(fits) == {"U", "R"}
    assert calibration.applied == ["U rotation", "R rotation"]
    for k in ("U", "R"):
        assert fits[k]["applied"] and fits[k]["evidence"]["p_value"] < 1e-3
        assert len(fits[k]["evidence"].get("hemispheres", [])) == (2 if share else 0)
        assert ("confirm" in fits[k]) == bool(confirm)
        if confirm:
            confirmed = fits[k]["confirm"]
            assert confirmed["applied"] and confirmed["matches"] > fits[k]["matches"] / 2
            assert abs(confirmed["degrees"] - 0.4) < 0.15
        assert _angle_deg(matched.cameras[k].rotation, frame.cameras[k].rotation) < 0.15
        assert _angle_deg(told[k].rotation, frame.cameras[k].rotation) == pytest.approx(0.4, abs=1e-6)
        np.testing.assert_array_equal(matched.cameras[k].position, told[k].position)
    np.testing.assert_array_equal(matched.cameras["C"].rotation, frame.cameras["C"].rotation)
    exact = self_calibrate(frame, NO_CALIBRATION, params, TriangulationLimits())
    assert exact.applied == [] and exact.frame is frame  # the told poses are right: nothing is applied


@pytest.mark.slow
def test_a_rotation_the_confirming_pass_cannot_support_is_not_applied():
    """``confirm_factor`` 8 on a 480 px frame: the confirming flow pass has 60x30 pixels, too few good matches to
    support the rotation, so the rotation the pre-pass finds (0.4 degrees off) is recorded and not applied: the
    told poses are matched."""
    frame = make_synthetic_frame(width=480)
    told = dict(frame.cameras)
    told["U"] = corrected_pose(frame.cameras["U"], np.radians([0.0, 0.4, 0.0]))
    off = dataclasses.replace(frame, cameras=told)
    calibration = self_calibrate(off, NO_CALIBRATION, RigParams(confirm_factor=8), TriangulationLimits())
    fit = calibration.record["rig"]["U"]
    assert fit["evidence"]["supported"] and fit["degrees"] > 0.25  # the pre-pass's own fit would apply it
    confirmed = fit["confirm"]
    assert not fit["applied"] and not confirmed["applied"] and confirmed["matches"] < fit["matches"] / 4
    assert not (confirmed["evidence"]["supported"] and confirmed["degrees"] >= RigParams().min_degrees)
    assert "confirm" not in calibration.record["rig"]["R"]  # R's told pose is right: nothing to confirm
    np.testing.assert_array_equal(calibration.frame.cameras["U"].rotation, told["U"].rotation)


@pytest.mark.slow
def test_without_rig_calibration_the_told_poses_are_used():
    frame = make_synthetic_frame(width=160)
    calibration = self_calibrate(frame, NO_CALIBRATION, NO_RIG_CALIBRATION, TriangulationLimits())
    assert calibration.frame is frame and calibration.record == {} and calibration.seconds == {}
    calibration = self_calibrate(frame, PhotometricParams(), NO_RIG_CALIBRATION, TriangulationLimits())
    assert "rig" not in calibration.record and calibration.frame.cameras is frame.cameras


def test_flow_method_records_its_rig_calibration():
    method = FlowMethod("dis")
    assert method.config()["rig"] == dataclasses.asdict(RigParams())
    off = dataclasses.replace(method, rig=NO_RIG_CALIBRATION)
    assert off.group_key != method.group_key
