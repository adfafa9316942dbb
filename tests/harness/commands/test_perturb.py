"""tri360 perturb: every kind changes what it should (images or told poses), provenance, determinism, bad input."""

from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pytest

from harness.cli import main
from harness.commands.parts import perturbations as P
from harness.commands.parts.captured import captured_twin
from harness.commands.parts.perturbations import ORDER, noise_parameters, srgb_to_linear
from harness.commands.perturb import frame_hash, perturb_frame, perturb_root
from harness.data.frame import read_frame, write_frame
from harness.data.photometric import CameraDistribution
from harness.render.camera import encode
from reconstruction.camera.equirect import bearing_grid
from tests.helpers import make_synthetic_frame

LEVELS = {"rotation": 0.5, "translation": 2.0, "exposure": 0.5, "white_balance": 0.1, "noise": 3.0, "jpeg": 60,
          "vignetting": 0.3, "vignetting_each": 0.4, "response": 1.0, "soiling": 6, "glare": 0.5}


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    root = tmp_path_factory.mktemp("src")
    d = write_frame(make_synthetic_frame(width=120), root)
    return root, d


def _angle_deg(a, b):
    return float(np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1) / 2, -1, 1))))


@pytest.mark.parametrize("kind", ORDER)
def test_each_kind_changes_what_it_should(source, tmp_path, kind):
    root, d = source
    (out,) = perturb_root(root, tmp_path / "out", [(kind, LEVELS[kind])], seed=4)
    src, new = read_frame(d), read_frame(out)
    for n in "CUR":  # ground truth copied unchanged
        np.testing.assert_array_equal(new.distance[n], src.distance[n])
    if kind in ("rotation", "translation"):
        for n in "CUR":
            np.testing.assert_array_equal(new.images[n], src.images[n])
        np.testing.assert_array_equal(new.cameras["C"].position, src.cameras["C"].position)
        np.testing.assert_array_equal(new.cameras["C"].rotation, src.cameras["C"].rotation)
        for n in "UR":
            if kind == "rotation":
                assert _angle_deg(new.cameras[n].rotation, src.cameras[n].rotation) == pytest.approx(0.5, abs=1e-6)
                np.testing.assert_array_equal(new.cameras[n].position, src.cameras[n].position)
            else:
                moved = np.linalg.norm(new.cameras[n].position - src.cameras[n].position)
                assert moved == pytest.approx(0.002, abs=1e-9)
                np.testing.assert_allclose(new.cameras[n].rotation, src.cameras[n].rotation, atol=1e-12)
        rec = new.renderer["perturbation"]
        assert rec["true_cameras"]["U"] == src.cameras["U"].to_json()
    else:
        for n in "CUR":
            np.testing.assert_allclose(new.cameras[n].position, src.cameras[n].position, atol=0)
            np.testing.assert_allclose(new.cameras[n].rotation, src.cameras[n].rotation, atol=0)
        changed = [n for n in "CUR" if not np.array_equal(new.images[n], src.images[n])]
        assert changed == ["C", "U", "R"]


def test_provenance_names_source_and_perturbations(source, tmp_path):
    root, d = source
    (out,) = perturb_root(root, tmp_path / "out", [("noise", 2.0), ("rotation", 0.25)], seed=9)
    rec = json.loads((out / "frame.json").read_text())["renderer"]["perturbation"]
    assert rec["source"] == {"path": str(d.resolve()), "sha256": frame_hash(d)}
    assert rec["seed"] == 9
    assert [(a["kind"], a["level"], a["seed"]) for a in rec["applied"]] == [("rotation", 0.25, 9), ("noise", 2.0, 9)]


def test_rerun_with_same_seed_is_byte_identical(source, tmp_path):
    root, _ = source
    applies = [(k, LEVELS[k]) for k in ORDER]
    (a,) = perturb_root(root, tmp_path / "a", applies, seed=1)
    (b,) = perturb_root(root, tmp_path / "b", applies, seed=1)
    (c,) = perturb_root(root, tmp_path / "c", applies, seed=2)
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir())
    for n in names:
        assert (a / n).read_bytes() == (b / n).read_bytes(), n
    assert (a / "C.png").read_bytes() != (c / "C.png").read_bytes()


def test_noise_level_is_grey_levels_at_mid_grey():
    a, b = noise_parameters(4.0)
    x = float(srgb_to_linear(np.array([128], np.uint8))[0])
    rng = np.random.default_rng(0)
    lin = x + np.sqrt(a * x + b) * rng.standard_normal(200_000)
    s = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * np.abs(lin) ** (1 / 2.4) - 0.055) * 255
    assert float(np.std(s)) == pytest.approx(4.0, rel=0.03)


@pytest.mark.parametrize("apply", ["foo=1", "noise", "noise=x", "noise=-1", "jpeg=0", "jpeg=2.5", "soiling=0",
                                   "vignetting=1", "rotation=nan", "vignetting_each=1", "vignetting_each=0",
                                   "vignetting_each=x", "response=2.5", "response=0", "response=-1", "response=inf"])
def test_bad_kind_or_level_is_one_line_exit_2(source, tmp_path, capsys, apply):
    root, _ = source
    assert main(["perturb", str(root), "--out", str(tmp_path / "o"), "--apply", apply]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--apply" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("kind", ["vignetting_each", "response"])
def test_the_per_camera_photometric_kinds_are_deterministic(source, tmp_path, kind):
    root, _ = source
    (a,) = perturb_root(root, tmp_path / "a", [(kind, LEVELS[kind])], seed=5)
    (b,) = perturb_root(root, tmp_path / "b", [(kind, LEVELS[kind])], seed=5)
    (c,) = perturb_root(root, tmp_path / "c", [(kind, LEVELS[kind])], seed=6)
    for n in ("C.png", "U.png", "R.png"):
        assert (a / n).read_bytes() == (b / n).read_bytes(), n
    assert any((a / n).read_bytes() != (c / n).read_bytes() for n in ("C.png", "U.png", "R.png"))
    rec = json.loads((a / "frame.json").read_text())["renderer"]["perturbation"]
    (applied,) = rec["applied"]
    assert (applied["kind"], applied["level"], applied["seed"]) == (kind, LEVELS[kind], 5)
    assert applied["unit"] == P.KINDS[kind] and set(applied["drawn"]) == {"C", "U", "R"}


def _flat(value: int, width: int = 120):
    """A synthetic frame whose three images are flat grey ``value`` (sRGB)."""
    frame = make_synthetic_frame(width=width)
    images = {n: np.full_like(frame.images[n], value) for n in "CUR"}
    return dataclasses.replace(frame, images=images)


def _seam_loss(before: np.ndarray, after: np.ndarray) -> float:
    """The seam loss ``L`` of a fall-off ``1 - L (theta / 90 deg)**2`` about camera +-Y, fitted (least squares) to
    the linear-light ratio of two images."""
    h, w = before.shape[:2]
    theta = np.arccos(np.clip(np.abs(bearing_grid(w, h)[..., 1]), 0.0, 1.0))
    shape = (theta / (np.pi / 2.0)) ** 2
    loss = 1.0 - srgb_to_linear(after)[..., 1] / srgb_to_linear(before)[..., 1]
    return float((loss * shape).sum() / (shape * shape).sum())


def test_vignetting_each_gives_each_camera_its_own_seam_loss_within_its_range():
    level = 0.6
    frame = _flat(200)
    new = perturb_frame(frame, [("vignetting_each", level)], seed=2, source={"path": "x", "sha256": "y"})
    (applied,) = new.renderer["perturbation"]["applied"]
    drawn = {n: applied["drawn"][n]["edge_loss"] for n in "CUR"}
    measured = {n: _seam_loss(frame.images[n], new.images[n]) for n in "CUR"}
    for n in "CUR":
        assert level / 2 <= drawn[n] <= level
        assert measured[n] == pytest.approx(drawn[n], abs=0.005), n  # 8-bit rounding, averaged over the image
    for a, b in (("C", "U"), ("C", "R"), ("U", "R")):  # the cameras differ (this seed's draws: > 0.02 apart)
        assert abs(measured[a] - measured[b]) > 0.02, (a, b, measured)
        assert not np.array_equal(new.images[a], new.images[b])
    # unlike `vignetting`, alike in all three cameras
    same = perturb_frame(frame, [("vignetting", level)], seed=2, source={"path": "x", "sha256": "y"})
    assert np.array_equal(same.images["C"], same.images["U"]) and np.array_equal(same.images["C"], same.images["R"])
    assert _seam_loss(frame.images["C"], same.images["C"]) == pytest.approx(level, abs=0.005)
    # the draws over many streams stay within [level/2, level] and fill it
    img = np.full((8, 16, 3), 200, np.uint8)
    losses = [P.vignetting_each(img, level, P.generator(s, "vignetting_each", "C"))[1]["edge_loss"]
              for s in range(300)]
    assert level / 2 <= min(losses) < level / 2 + 0.02 and level - 0.02 < max(losses) <= level


def _log_ratio_spread(before: np.ndarray, after: np.ndarray) -> float:
    """Over the intensities of a grey ramp (a row), the spread (max - min) of ``log`` of the linear light read (as
    sRGB) after over before, where both are in sRGB [50, 250) (there 8-bit rounding moves it by < 0.04)."""
    a, b = before[0, :, 1], after[0, :, 1]
    ok = (a >= 50) & (b >= 50) & (b < 250)
    assert ok.sum() > 20
    return float(np.ptp(np.log(srgb_to_linear(b[ok]) / srgb_to_linear(a[ok]))))


def test_response_is_not_a_gain_and_its_draw_reproduces_the_images():
    level = 2.0
    frame = make_synthetic_frame(width=120)
    ramp = np.linspace(20, 240, frame.width).round().astype(np.uint8)  # sRGB 20..240 along each row
    ramp_img = np.repeat(np.repeat(ramp[None, :, None], frame.height, axis=0), 3, axis=2)
    frame = dataclasses.replace(frame, images={n: ramp_img.copy() for n in "CUR"})
    new = perturb_frame(frame, [("response", level)], seed=1, source={"path": "x", "sha256": "y"})
    drawn = new.renderer["perturbation"]["applied"][0]["drawn"]
    gammas = [n for n in "CUR" if "gamma" in drawn[n]]
    assert gammas, drawn  # this seed draws a gamma curve for at least one camera
    for n in "CUR":
        curve = drawn[n]["response"]
        np.testing.assert_array_equal(new.images[n], encode(srgb_to_linear(ramp_img), curve))
        if n in gammas:
            g = drawn[n]["gamma"]
            assert 2.2 - level / 2 <= g <= 2.2 + level / 2 and abs(g - 2.2) > 0.1, drawn
            assert curve == f"gamma-{g!r}"
        else:
            assert drawn[n]["contrast"] == pytest.approx(1 + level / 2, abs=0) and curve.startswith("s-curve-")
        # not a gain: the log ratio to the original varies over the intensities by far more than 8-bit rounding
        spread = _log_ratio_spread(ramp_img, new.images[n])
        assert spread > 0.15, (n, curve, spread)
    # a gain (exposure) keeps the log ratio constant to within the rounding
    gain = perturb_frame(frame, [("exposure", 0.5)], seed=1, source={"path": "x", "sha256": "y"})
    for n in "CUR":
        assert _log_ratio_spread(ramp_img, gain.images[n]) < 0.05, n
    # either curve is drawn, about half the time each
    picks = [P.response(ramp_img[:1, :8], level, P.generator(s, "response", "U"))[1] for s in range(400)]
    share = sum("gamma" in d for d in picks) / len(picks)
    assert 0.4 < share < 0.6


def test_kind_twice_and_output_into_input_refused(source, tmp_path, capsys):
    root, _ = source
    assert main(["perturb", str(root), "--out", str(tmp_path / "o"), "--apply", "noise=1", "--apply", "noise=2"]) == 2
    assert "twice" in capsys.readouterr().err
    assert main(["perturb", str(root), "--out", str(root / "x"), "--apply", "noise=1"]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_impossible_told_rig_refused_before_writing(source, tmp_path, capsys):
    root, _ = source
    assert main(["perturb", str(root), "--out", str(tmp_path / "o"), "--apply", "translation=200"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--apply translation=200" in err and "impossible rig" in err
    assert not (tmp_path / "o").exists()


@pytest.fixture(scope="module")
def twin(tmp_path_factory):
    """A data root holding one captured twin (photometric records, told poses off its true ones)."""
    root = tmp_path_factory.mktemp("twin")
    return root, write_frame(captured_twin(make_synthetic_frame(width=120), CameraDistribution(), 7), root)


@pytest.mark.slow
def test_perturbing_a_twin_keeps_its_photometric_records_and_its_true_poses(twin, tmp_path):
    root, d = twin
    src = read_frame(d)
    (once,) = perturb_root(root, tmp_path / "once", [("rotation", 0.5), ("exposure", 0.5)], seed=3)
    (twice,) = perturb_root(tmp_path / "once", tmp_path / "twice", [("translation", 0.5)], seed=4)
    for out in (once, twice):
        new = read_frame(out)
        assert new.photometric == src.photometric
        condition, perturbation = new.renderer["condition"], new.renderer["perturbation"]
        assert condition == src.renderer["condition"]
        assert perturbation["true_cameras"] == condition["true_cameras"]  # the images' poses, not the told ones
        assert perturbation["true_baseline_m"] == condition["true_baseline_m"]
    told = read_frame(once)
    for n in "UR":  # the rotation error is on top of the twin's told pose
        assert _angle_deg(told.cameras[n].rotation, src.cameras[n].rotation) == pytest.approx(0.5, abs=1e-6)


def test_a_malformed_true_pose_record_is_one_line(twin, tmp_path, capsys):
    root, d = twin
    data = tmp_path / "data"
    shutil.copytree(root, data)
    meta_path = data / d.relative_to(root) / "frame.json"
    meta = json.loads(meta_path.read_text())
    meta["renderer"]["condition"]["true_cameras"]["U"]["position"] = [0.0, 0.0]
    meta_path.write_text(json.dumps(meta))
    assert main(["perturb", str(data), "--out", str(tmp_path / "o"), "--apply", "rotation=0.5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{meta_path}: renderer.condition.true_cameras" in err[0] and "position" in err[0]
    assert not (tmp_path / "o").exists()
