"""Real cameras in the benchmark: the photometric record of frame.json, the camera model that applies it, the
``captured`` twins of a suite split (derived from the same render), and the leaderboard under both conditions.

Every suite here uses the ray-cast synthetic_box family at 64-96 px: no Blender."""

from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pytest

from harness.cli import main
from harness.commands.parts.captured import calibration_error, captured_twin
from harness.commands.parts.suite import check_suite_data, evaluate_suite, load, plan, render_suite
from harness.commands.perturb import perturb_frame, source_record
from harness.data.errors import FrameError, UserError
from harness.data.frame import read_frame, write_frame
from harness.data.images import read_png, write_png
from harness.data.photometric import CameraDistribution, Photometric, noise_parameters
from harness.data.results import read_results
from harness.render.camera import apply, vignetting_gain
from harness.runtime.context import QUIET
from reconstruction.methods.registry import get_methods
from reconstruction.photometry import srgb_to_linear
from reports.tables import leaderboard_markdown, leaderboard_table
from tests.helpers import make_synthetic_frame

SUITE = """\
format = "tri360-suite/1"
name = "mini-captured"

[render]
width = 96

[conditions.captured]
exposure_stops = 0.5
white_balance = 0.05
vignetting = [0.15, 0.35]
noise_grey_levels = [1.0, 3.0]
jpeg_quality = [85, 95]
rotation_deg = [0.1, 0.3]
translation_mm = [1.0, 2.0]

[[frames]]
family = "synthetic_box"
seed = 11
viewpoints = 2
split = "dev"
"""


# ------------------------------------------------------------------------------------------- the record


def test_record_round_trip_and_defaults_are_ideal():
    p = CameraDistribution().draw(np.random.default_rng(1))
    assert Photometric.from_json(json.loads(json.dumps(p.to_json()))) == p
    assert Photometric().is_ideal and not p.is_ideal
    assert -0.5 <= p.exposure_stops <= 0.5 and 85 <= p.jpeg_quality <= 95
    assert 0.15 <= p.vignetting["edge_loss"] <= 0.35 and p.white_balance[1] == 1.0


@pytest.mark.parametrize("raw, culprit", [
    ({"exposure_stops": "1"}, "exposure_stops"), ({"exposure_stops": float("nan")}, "exposure_stops"),
    ({"white_balance": [1, 1]}, "white_balance"), ({"vignetting": {"axis": "w", "edge_loss": 0.2}}, "vignetting"),
    ({"noise": {"shot": -1, "read": 0}}, "noise.shot"), ({"response": "gamma-9"}, "response"),
    ({"jpeg_quality": 101}, "jpeg_quality"), ({"seed": -3}, "seed"), ({"iso": 100}, "unknown key"),
    ([], "expected a table"),
])
def test_bad_records_are_one_line_naming_the_key(raw, culprit):
    with pytest.raises(ValueError, match=culprit) as info:
        Photometric.from_json(raw, "cameras.U.photometric")
    assert "\n" not in str(info.value)


def test_frame_json_carries_the_record_and_refuses_a_bad_one(tmp_path):
    f = make_synthetic_frame(64)
    f.photometric = {"U": Photometric(exposure_stops=0.3, seed=5)}
    d = write_frame(f, tmp_path)
    back = read_frame(d)
    assert back.photometric == f.photometric and "photometric" not in json.loads(
        (d / "frame.json").read_text())["cameras"]["C"]
    meta = json.loads((d / "frame.json").read_text())
    meta["cameras"]["R"]["photometric"] = {"exposure_stops": 99}
    (d / "frame.json").write_text(json.dumps(meta))
    with pytest.raises(FrameError, match=r"frame\.json: cameras\.R\.photometric: exposure_stops: expected a number"):
        read_frame(d)


# --------------------------------------------------------------------------------------- the camera model


def test_apply_ideal_is_the_identity_and_exposure_is_linear():
    img = make_synthetic_frame(64).images["C"]
    np.testing.assert_array_equal(apply(img, Photometric()), img)
    brighter = apply(img, Photometric(exposure_stops=1.0))
    lin, lin2 = srgb_to_linear(img), srgb_to_linear(brighter)
    ok = (lin > 0.02) & (lin < 0.45)  # not clipped after doubling, away from 8-bit steps in the dark
    np.testing.assert_allclose(lin2[ok] / lin[ok], 2.0, rtol=0.04)


def test_vignetting_loses_edge_loss_at_the_lenses_seam_and_nothing_on_their_axes():
    g = vignetting_gain(400, 200, "y", 0.3)
    assert g[100, 200] == pytest.approx(1.0, abs=2e-3)  # image centre: the front lens's axis (+Y)
    assert g[100, 0] == pytest.approx(1.0, abs=2e-3)  # left edge: the back lens's axis (-Y)
    assert g[100, 300] == pytest.approx(0.7, abs=5e-3)  # looking right (+X): the seam (pixel centres: 0.45 deg off)
    assert g[0, 123] == pytest.approx(0.7, abs=0.01)  # the poles lie on the seam too
    gx = vignetting_gain(400, 200, "x", 0.3)
    assert gx[100, 300] == pytest.approx(1.0, abs=5e-3) and gx[100, 200] == pytest.approx(0.7, abs=5e-3)


def test_noise_is_seeded_and_has_its_level():
    img = np.full((200, 400, 3), 128, np.uint8)
    shot, read = noise_parameters(4.0)
    cam = Photometric(noise={"shot": shot, "read": read}, seed=3)
    a, b = apply(img, cam), apply(img, cam)
    np.testing.assert_array_equal(a, b)
    assert np.std(a.astype(float)) == pytest.approx(4.0, rel=0.1)
    assert not np.array_equal(a, apply(img, dataclasses.replace(cam, seed=4)))


def test_jpeg_and_gamma_response():
    img = make_synthetic_frame(64).images["C"]
    jpg = apply(img, Photometric(jpeg_quality=50))
    assert 0 < np.abs(jpg.astype(int) - img.astype(int)).mean() < 10
    gamma = apply(img, Photometric(response="gamma-2.2"))
    assert np.abs(gamma.astype(int) - img.astype(int)).max() <= 12  # sRGB is close to gamma 2.2


# ------------------------------------------------------------------------------------------ captured twins


def test_captured_twin_is_deterministic_and_records_what_it_did():
    f = make_synthetic_frame(64)
    t1, t2 = captured_twin(f, CameraDistribution(), 7), captured_twin(f, CameraDistribution(), 7)
    for k in "CUR":
        np.testing.assert_array_equal(t1.images[k], t2.images[k])
        assert t1.photometric[k] == t2.photometric[k]
    assert not np.array_equal(captured_twin(f, CameraDistribution(), 8).images["U"], t1.images["U"])
    rec = t1.renderer["condition"]
    assert rec["name"] == "captured" and rec["seed"] == 7 and set(rec["true_cameras"]) == {"U", "R"}
    np.testing.assert_array_equal(t1.cameras["C"].rotation, f.cameras["C"].rotation)  # C is the reference
    for k in ("U", "R"):
        angle = np.degrees(np.arccos(np.clip((np.trace(t1.cameras[k].rotation.T @ f.cameras[k].rotation) - 1) / 2,
                                             -1, 1)))
        assert 0.1 - 1e-6 <= angle <= 0.3 + 1e-6
        moved_mm = 1000 * np.linalg.norm(t1.cameras[k].position - f.cameras[k].position)
        assert 1.0 - 1e-6 <= moved_mm <= 2.0 + 1e-6
    np.testing.assert_array_equal(t1.distance["C"], f.distance["C"])
    with pytest.raises(ValueError, match="already records"):
        captured_twin(t1, CameraDistribution(), 7)


def test_calibration_error_redraws_the_told_poses_and_a_twin_needs_an_ideal_source():
    f = make_synthetic_frame(64)
    twin = captured_twin(f, CameraDistribution(), 7, source={"path": "p", "sha256": "0" * 64})
    told, drawn = calibration_error(f.cameras, CameraDistribution(), 7)
    assert drawn == twin.renderer["condition"]["calibration_error"] and set(drawn) == {"U", "R"}
    assert twin.renderer["condition"]["source"] == {"path": "p", "sha256": "0" * 64}
    for k in "CUR":
        np.testing.assert_array_equal(told[k].position, twin.cameras[k].position)
        np.testing.assert_array_equal(told[k].rotation, twin.cameras[k].rotation)
    perturbed = perturb_frame(f, [("rotation", 0.5)], 1, {})
    with pytest.raises(ValueError, match="records true poses other than its told ones"):
        captured_twin(perturbed, CameraDistribution(), 7)


def test_suite_conditions_are_checked(tmp_path):
    good = tmp_path / "s.toml"
    good.write_text(SUITE)
    suite = load(good)
    assert list(suite.conditions) == ["captured"] and suite.condition_names() == ["ideal", "captured"]
    frames = suite.frames("dev")
    assert [f.scene for f in frames] == ["synthetic_box-s11"] * 2 + ["synthetic_box-s11.captured"] * 2
    assert frames[3].twin_seed == 11 * 1000 + 1 and frames[3].source == frames[1]
    for old, new, culprit in (("exposure_stops = 0.5", "exposure_stops = -1", "exposure_stops"),
                              ("vignetting = [0.15, 0.35]", "vignetting = [0.35, 0.15]", "vignetting"),
                              ("jpeg_quality = [85, 95]", "jpeg_quality = [0, 95]", "jpeg_quality"),
                              ("[conditions.captured]", "[conditions.ideal]", "ideal"),
                              ("white_balance = 0.05", "white_balance = 0.05\nflare = 1", "unknown key")):
        bad = tmp_path / "bad.toml"
        bad.write_text(SUITE.replace(old, new))
        with pytest.raises(UserError, match=culprit) as info:
            load(bad)
        assert str(bad) in str(info.value) and "\n" not in str(info.value)


@pytest.mark.slow
def test_render_suite_derives_the_twins_and_evaluate_reports_both_conditions(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SUITE)
    root = tmp_path / "data"
    dirs = render_suite(path, "dev", root, ctx=QUIET)
    assert [d.relative_to(root).as_posix() for d in dirs] == [
        "synthetic_box-s11/vp000", "synthetic_box-s11/vp001",
        "synthetic_box-s11.captured/vp000", "synthetic_box-s11.captured/vp001"]
    twin = read_frame(root / "synthetic_box-s11.captured" / "vp001")
    ideal = read_frame(root / "synthetic_box-s11" / "vp001")
    assert twin.photometric and not ideal.photometric
    assert twin.renderer["condition"]["seed"] == 11001
    expected = captured_twin(ideal, load(path).conditions["captured"], 11001)
    np.testing.assert_array_equal(twin.images["R"], expected.images["R"])
    before = (root / "synthetic_box-s11.captured" / "vp000" / "U.png").stat().st_mtime_ns
    render_suite(path, "dev", root, ctx=QUIET)  # resumable: nothing derived again
    assert (root / "synthetic_box-s11.captured" / "vp000" / "U.png").stat().st_mtime_ns == before
    assert len(check_suite_data(load(path), "dev", root)) == 4

    results = evaluate_suite(root, path, "dev", tmp_path / "res", get_methods(["dis-rect:average"]), report=False,
                             ctx=QUIET)
    assert sorted(results["condition"]) == ["captured", "captured", "ideal", "ideal"]
    back = read_results(tmp_path / "res")
    board = leaderboard_table(back)
    assert {"mae_family:all@ideal", "mae_family:all@captured", "mae_family:synthetic_box@captured"} <= set(
        board.columns)
    assert "synthetic_box@captured" in leaderboard_markdown(board)


@pytest.mark.slow
def test_a_twin_derived_otherwise_is_refused(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SUITE)
    root = tmp_path / "data"
    render_suite(path, "dev", root, ctx=QUIET)
    other = tmp_path / "other.toml"
    other.write_text(SUITE.replace("exposure_stops = 0.5", "exposure_stops = 0.25"))
    with pytest.raises(UserError, match=r"synthetic_box-s11\.captured.*condition distribution"):
        check_suite_data(load(other), "dev", root)
    with pytest.raises(UserError, match="other settings"):
        render_suite(other, "dev", root, ctx=QUIET)
    # a v1-style suite (no conditions) refuses the root: the twins are frames it does not have
    plain = tmp_path / "plain.toml"
    plain.write_text(SUITE.split("[conditions.captured]")[0] + SUITE.split("translation_mm = [1.0, 2.0]\n")[1])
    with pytest.raises(UserError, match="not in suite"):
        check_suite_data(load(plain), "dev", root)


@pytest.fixture(scope="module")
def captured_root(tmp_path_factory):
    """The mini-captured suite file and a data root holding its dev split (frames and twins)."""
    tmp = tmp_path_factory.mktemp("captured")
    path = tmp / "s.toml"
    path.write_text(SUITE)
    render_suite(path, "dev", tmp / "data", ctx=QUIET)
    return path, tmp / "data"


TWIN = "synthetic_box-s11.captured/vp001"
SOURCE = "synthetic_box-s11/vp001"


def _edit_twin(root, edit) -> None:
    meta_path = root / TWIN / "frame.json"
    meta = json.loads(meta_path.read_text())
    edit(meta)
    meta_path.write_text(json.dumps(meta))


def _reset_told_poses(root) -> None:
    def edit(meta):
        record = meta["renderer"]["condition"]
        for k in "UR":
            meta["cameras"][k].update(record["true_cameras"][k])
        meta["baseline_m"] = record["true_baseline_m"]
    _edit_twin(root, edit)


def _change_the_source(root) -> None:
    img = read_png(root / SOURCE / "C.png")
    img[0, 0] = 255 - img[0, 0]
    write_png(root / SOURCE / "C.png", img)


@pytest.mark.parametrize(("tamper", "message"), [
    (_reset_told_poses, r"the told pose of U is its true pose, but the recorded calibration error of U \(.* mm\) "
                        r"says it is off"),
    (lambda root: _edit_twin(root, lambda m: m["cameras"]["R"].pop("photometric")),
     r"cameras\.R has no photometric record \(the captured condition draws one for every camera: C, U, R\)"),
    (lambda root: _edit_twin(root, lambda m: [m["cameras"][k].pop("photometric") for k in "CUR"]),
     r"cameras\.C has no photometric record"),
    (lambda root: _edit_twin(root, lambda m: m["cameras"]["U"]["photometric"].update(exposure_stops=0.0)),
     r"cameras\.U\.photometric is not the captured condition's draw for seed 11001"),
    (_change_the_source, r"its source frame synthetic_box-s11/vp001 changed after the twin was derived"),
    (lambda root: _edit_twin(root, lambda m: m["renderer"]["condition"].pop("source")),
     r"it records no hash of its source frame synthetic_box-s11/vp001"),
])
def test_a_twin_that_does_not_match_its_derivation_is_refused_and_render_derives_it_again(captured_root, tmp_path,
                                                                                          tamper, message):
    path, rendered = captured_root
    root = tmp_path / "data"
    shutil.copytree(rendered, root)
    tamper(root)
    with pytest.raises(UserError, match=message) as info:
        check_suite_data(load(path), "dev", root)
    text = str(info.value)
    assert text.startswith(f"{root / TWIN / 'frame.json'}: twin {TWIN} does not match its derivation: ")
    assert "\n" not in text and f"`tri360 render --suite {path} --split dev --out {root}`" in text
    source = {p.name: p.read_bytes() for p in (root / SOURCE).iterdir()}
    render_suite(path, "dev", root, ctx=QUIET)  # the twin is derived again from the source as it is now
    assert len(check_suite_data(load(path), "dev", root)) == 4
    assert {p.name: p.read_bytes() for p in (root / SOURCE).iterdir()} == source
    assert read_frame(root / TWIN).renderer["condition"]["source"] == source_record(root / SOURCE)


@pytest.mark.slow
def test_evaluate_cli_on_a_captured_root(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SUITE)
    root = tmp_path / "data"
    assert main(["render", "--suite", str(path), "--split", "dev", "--out", str(root), "--quiet"]) == 0
    assert main(["evaluate", str(root), "--suite", str(path), "--split", "dev", "--method", "dis-rect:average",
                 "--out", str(tmp_path / "res"), "--quiet"]) == 0
    assert "@captured" in (tmp_path / "res" / "leaderboard.md").read_text()
    assert len(plan(load(path), "dev")) == 4
