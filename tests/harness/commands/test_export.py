"""tri360 export and score --export: each layout's names, values round trip through a stand-in method, bad input."""

from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pytest

from harness.cli import main
from harness.commands.export import export
from harness.commands.score import score, score_export
from harness.data.frame import Frame, write_frame
from harness.data.layouts import (
    ENCODINGS,
    LAYOUTS,
    cassini_bearings,
    disparity_from_distance,
    distance_from_disparity,
    to_rectified,
    zenith_angle,
)
from harness.data.predictions import write_prediction
from reconstruction.camera.rig import CameraPose
from tests.helpers import make_synthetic_frame

W = 64  # frames are W x W/2


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("data")
    frame = make_synthetic_frame(W)
    write_frame(frame, root)
    return root, frame


@pytest.fixture(scope="module")
def direct_mae(data, tmp_path_factory):
    """MAE (m) of the frame's true distance written directly as tri360-pred/1 (the reference of the round trip)."""
    root, frame = data
    tmp = tmp_path_factory.mktemp("direct")
    write_prediction(tmp / "truth", frame.scene, frame.viewpoint, frame.distance["C"])
    table = score([tmp / "truth"], root, tmp / "res", ["truth"], report=False)
    return float(table.iloc[0]["mae_m"])


EXPECTED = {  # format -> the files of frame synthetic_box/vp000 (index 0), relative to --out
    "3d60": ["3d60_test.txt",
             "Center_Left_Down/synthetic_box/vp000_color_0_Left_Down_0.0.png",
             "Center_Left_Down/synthetic_box/vp000_depth_0_Left_Down_0.0.exr",
             "Right/synthetic_box/vp000_color_0_Right_0.0.png", "Right/synthetic_box/vp000_depth_0_Right_0.0.exr",
             "Up/synthetic_box/vp000_color_0_Up_0.0.png", "Up/synthetic_box/vp000_depth_0_Up_0.0.exr"],
    "helvipad": ["test/images_bottom/synthetic_box_IN/vp000.jpg", "test/images_top/synthetic_box_IN/vp000.jpg",
                 "test/depth_maps/synthetic_box_IN/vp000.png", "test/disparity_maps/synthetic_box_IN/vp000.png"],
    "360sd": ["test/image_up/00000_synthetic_box_vp000.png", "test/image_down/00000_synthetic_box_vp000.png",
              "test/disp_up/00000_synthetic_box_vp000.npy"],
    "deep360": [f"ep1_500frames/testing/{k}/00000_synthetic_box_vp000_{n}" for k, n in (
        ("rgb", "12_rgb1.png"), ("rgb", "12_rgb2.png"), ("rgb", "13_rgb1.png"), ("rgb", "13_rgb3.png"),
        ("disp", "12_disp.npz"), ("disp", "13_disp.npz"), ("depth", "depth.npz"))],
}


@pytest.mark.parametrize("fmt", sorted(LAYOUTS))
def test_layout_names_and_manifest(data, tmp_path, fmt):
    root, frame = data
    assert main([*map(str, ["export", root, "--format", fmt, "--out", tmp_path / "x"])]) == 0
    files = sorted(str(p.relative_to(tmp_path / "x")) for p in (tmp_path / "x").rglob("*") if p.is_file())
    assert files == sorted([*EXPECTED[fmt], "manifest.json", ".tri360-output.json"])
    manifest = json.loads((tmp_path / "x" / "manifest.json").read_text())
    (entry,) = manifest["frames"]
    assert (entry["scene"], entry["viewpoint"]) == (frame.scene, frame.viewpoint)
    assert sorted(f["path"] for f in entry["files"]) == sorted(p for p in EXPECTED[fmt] if not p.endswith(".txt"))
    assert {f["camera"] for f in entry["files"]} == set(LAYOUTS[fmt].cameras)
    # a rerun into its own export replaces it; an export is no data root
    assert main([*map(str, ["export", root, "--format", fmt, "--out", tmp_path / "x"])]) == 0


def test_3d60_list_and_turned_360sd(data, tmp_path):
    root, frame = data
    export(root, "3d60", tmp_path / "a")
    line = (tmp_path / "a" / "3d60_test.txt").read_text().split()
    assert line[0] == "./synthetic_box/vp000_color_0_Left_Down_0.0.png" and line[5].endswith("_Up_0.0.exr")
    export(root, "360sd", tmp_path / "b")
    up = cv2.imread(str(tmp_path / "b/test/image_up/00000_synthetic_box_vp000.png"))[:, :, ::-1]
    np.testing.assert_array_equal(up, frame.images["C"][::-1, ::-1])  # C turned 180 degrees: rows, columns reversed


def test_disparity_formula_round_trip_and_known_value():
    r = np.array([[1.0, 2.5, np.inf]], np.float32)
    alpha = np.array([[np.pi / 2]])  # a horizontal ray, the partner straight above: tan d = b / r
    d = disparity_from_distance(r, alpha, 0.4)
    assert d[0, 0] == pytest.approx(np.degrees(np.arctan(0.4)), abs=1e-5) and d[0, 2] == 0  # degrees; no surface
    back = distance_from_disparity(d, alpha, 0.4)
    np.testing.assert_allclose(back[0, :2], r[0, :2], rtol=1e-5)
    assert np.isnan(back[0, 2])
    alpha = zenith_angle(32)  # every row, near the poles too
    rr = np.full((32, 4), 3.0, np.float32)
    np.testing.assert_allclose(distance_from_disparity(disparity_from_distance(rr, alpha, 0.4), alpha, 0.4), rr,
                               rtol=1e-4)


def _stand_in(export_dir, preds, holds, suffix=None):
    """A 'method' that reads only the exported layout: it copies C's exported map of ``holds`` (``quantity`` or
    ``quantity:part-of-the-name``) into its output folder under the same name (or re-encodes it as float .npy)."""
    manifest = json.loads((export_dir / "manifest.json").read_text())
    holds, _, part = holds.partition(":")
    for entry in manifest["frames"]:
        (f,) = [f for f in entry["files"] if f["camera"] == "C" and f["holds"] == holds and part in f["path"]]
        src, dst = export_dir / f["path"], preds / f["path"]
        dst.parent.mkdir(parents=True, exist_ok=True)
        if suffix is None:
            shutil.copy(src, dst)
        else:
            np.save(dst.with_suffix(suffix), ENCODINGS[f["encoding"]].read(src))


CASES = [  # format, map copied, re-encoded as, tolerance on the MAE (m): the encoding's quantisation
    ("3d60", "distance", None, 1e-6),  # float32 EXR: exact
    ("helvipad", "distance", None, 1.0 / 512),  # 16-bit PNG, 1/256 m steps
    ("helvipad", "disparity", None, 2e-3),  # 16-bit PNG, 1/2048 degree steps
    ("helvipad", "disparity", ".npy", 2e-3),  # the same values as float degrees
    ("360sd", "disparity", None, 1e-4),  # float32 degrees, turned and back
    # Cassini pairs: C-U's Cassini grid is C's equirect grid permuted (exact); C-R's is resampled there and back
    # (bilinear twice: 0.018 m at 64 x 32, 0.0027 m at 256 x 128, larger at occlusion edges)
    ("deep360", "disparity_px:_13_", None, 1e-4),
    ("deep360", "disparity_px:_12_", None, 0.03),
    ("deep360", "disparity_px:_12_", ".npy", 0.03),
    ("deep360", "distance", None, 0.03),
]


@pytest.mark.parametrize("fmt, holds, suffix, tol", CASES)
def test_round_trip_gives_the_direct_mae(data, direct_mae, tmp_path, fmt, holds, suffix, tol):
    root, _ = data
    entries = export(root, fmt, tmp_path / "exp")
    assert sum(entries[0]["invalid_pixels"].values()) == 0  # every pixel of the box holds a value
    preds = tmp_path / "mine"
    _stand_in(tmp_path / "exp", preds, holds, suffix)
    table = score_export(preds, tmp_path / "exp", root, tmp_path / "res", report=False)
    mae = float(table.iloc[0]["mae_m"])
    assert table.iloc[0]["method"] == "mine"
    print(f"round trip {fmt} {holds} {suffix}: MAE {mae:.3g} m, direct {direct_mae:.3g} m")
    assert abs(mae - direct_mae) <= tol, (fmt, holds, mae, direct_mae)


def _one_line_exit2(capsys, argv):
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    return err


def test_bad_inputs_are_one_line(data, tmp_path, capsys):
    root, frame = data
    # a rig whose U is not straight above C
    tilted = Frame(**{**frame.__dict__, "cameras": {**frame.cameras, "U": CameraPose(
        frame.cameras["C"].position + np.array([0.02, 0, frame.baseline_m]), frame.cameras["U"].rotation)}})
    bad = tmp_path / "bad"
    write_frame(tilted, bad)
    err = _one_line_exit2(capsys, ["export", bad, "--format", "helvipad", "--out", tmp_path / "o1"])
    assert "U is not straight above C" in err and not (tmp_path / "o1").exists()
    # no ground truth
    nogt = tmp_path / "nogt"
    write_frame(Frame(**{**frame.__dict__, "distance": {}}), nogt)
    err = _one_line_exit2(capsys, ["export", nogt, "--format", "3d60", "--out", tmp_path / "o2"])
    assert "no ground truth" in err and not (tmp_path / "o2").exists()
    # an output that tri360 did not write
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    _one_line_exit2(capsys, ["export", root, "--format", "360sd", "--out", tmp_path / "busy"])
    assert sorted(p.name for p in (tmp_path / "busy").iterdir()) == ["notes.txt"]
    # predictions missing a frame, and of the wrong size
    assert main([str(a) for a in ["export", root, "--format", "360sd", "--out", tmp_path / "exp"]]) == 0
    (tmp_path / "empty").mkdir()
    err = _one_line_exit2(capsys, ["score", tmp_path / "empty", "--export", tmp_path / "exp", "--data", root,
                                   "--out", tmp_path / "r1"])
    assert "file is missing" in err and "disp_up" in err and not (tmp_path / "r1").exists()
    small = tmp_path / "small" / "test" / "disp_up"
    small.mkdir(parents=True)
    np.save(small / "00000_synthetic_box_vp000.npy", np.ones((8, 16), np.float32))
    err = _one_line_exit2(capsys, ["score", tmp_path / "small", "--export", tmp_path / "exp", "--data", root,
                                   "--out", tmp_path / "r2"])
    assert "size 16x8" in err and not (tmp_path / "r2").exists()
    err = _one_line_exit2(capsys, ["score", tmp_path / "small", "--export", tmp_path / "nothing", "--data", root,
                                   "--out", tmp_path / "r3"])
    assert "manifest.json" in err


@pytest.mark.parametrize("fmt", sorted(LAYOUTS))
def test_images_are_written_losslessly_under_the_names_the_peer_opens(data, tmp_path, fmt):
    root, frame = data
    assert main([*map(str, ["export", root, "--format", fmt, "--out", tmp_path / "x"])]) == 0
    for cam, template in LAYOUTS[fmt].images.items():
        rel = template.format(split="test", scene=frame.scene, viewpoint=frame.viewpoint,
                              id=f"00000_{frame.scene}_{frame.viewpoint}")
        img = cv2.cvtColor(cv2.imread(str(tmp_path / "x" / rel), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
        want = frame.images[cam][::-1, ::-1] if LAYOUTS[fmt].turned else frame.images[cam]
        np.testing.assert_array_equal(img, want)  # uint8: lossless means equal


def test_deep360_pairs_follow_mode_geometry(data, tmp_path):
    """The C-U Cassini image is C's equirect image permuted; the disparity is what the partner sees (the scene point
    projected into it), in MODE's ``disp2depth`` convention; MODE's lists find every episode folder."""
    root, frame = data
    export(root, "deep360", tmp_path / "x")
    rgb = tmp_path / "x/ep1_500frames/testing/rgb"
    img = cv2.cvtColor(cv2.imread(str(rgb / "00000_synthetic_box_vp000_13_rgb1.png")), cv2.COLOR_BGR2RGB)
    np.testing.assert_array_equal(img, frame.images["C"][::-1].transpose(1, 0, 2))  # W rows x H columns
    assert cv2.imread(str(rgb / "00000_synthetic_box_vp000_12_rgb2.png")).shape == (W, W // 2, 3)
    assert all((tmp_path / f"x/ep{e}_500frames/{s}/{k}").is_dir() for e in range(1, 7)
               for s in ("training", "validation", "testing") for k in ("rgb", "disp", "depth"))
    names = sorted(p.name for p in rgb.iterdir())  # MODE pairs sorted names: left 2i, right 2i + 1, disparity i
    assert [n[-8:] for n in names] == ["rgb1.png", "rgb2.png", "rgb1.png", "rgb3.png"]
    with np.load(tmp_path / "x/ep1_500frames/testing/disp/00000_synthetic_box_vp000_12_disp.npz") as z:
        disp = z["arr_0"]
    b = float(np.linalg.norm(frame.cameras["R"].position - frame.cameras["C"].position))
    r = to_rectified("distance", frame.distance["C"], "R", b)
    bearings, phi = cassini_bearings(W)
    p = bearings * r[..., None] + np.array([b, 0.0, 0.0])  # seen from the partner, which is at -x
    phi_partner = np.arcsin(p[..., 0] / np.linalg.norm(p, axis=-1))
    np.testing.assert_allclose(disp, (phi_partner - phi) * (W // 2) / np.pi, atol=1e-4)
    depth = b * np.cos(phi + disp * np.pi / (W // 2)) / np.sin(disp * np.pi / (W // 2))  # MODE's disp2depth
    np.testing.assert_allclose(depth, r, rtol=1e-4)
