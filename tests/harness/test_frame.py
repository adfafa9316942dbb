"""The tri360-frame/1 format: round trip, atomic writes, and one clear error per malformed input."""

import json
import shutil

import numpy as np
import pytest

import harness.data.frame as fr
from harness.data.frame import (
    FrameError,
    find_frames,
    is_complete,
    read_distance_exr,
    read_frame,
    write_distance_exr,
    write_frame,
)


@pytest.fixture()
def frame_dir(tmp_path, synthetic_frame):
    return write_frame(synthetic_frame, tmp_path)


def test_round_trip(frame_dir, synthetic_frame):
    got = read_frame(frame_dir)
    assert (got.width, got.height, got.scene, got.viewpoint) == (200, 100, "synthetic_box", "vp000")
    for k in "CUR":
        assert np.array_equal(got.images[k], synthetic_frame.images[k])
        assert np.array_equal(got.distance[k], synthetic_frame.distance[k])  # float32 exact, inf kept
        np.testing.assert_allclose(got.cameras[k].rotation, synthetic_frame.cameras[k].rotation, atol=1e-12)
    meta = json.loads((frame_dir / "frame.json").read_text())
    assert meta["format"] == "tri360-frame/1" and set(meta["cameras"]) == {"C", "U", "R"}
    assert find_frames(frame_dir.parent.parent) == [frame_dir]


def test_distance_exr_channel_and_no_hit(tmp_path):
    d = np.array([[1.5, np.inf], [2.0, 3.0]], np.float32)
    write_distance_exr(tmp_path / "x.exr", d)
    import OpenEXR

    assert list(OpenEXR.File(str(tmp_path / "x.exr")).channels()) == ["distance"]
    assert np.array_equal(read_distance_exr(tmp_path / "x.exr"), d)


def test_no_partial_files_left(frame_dir):
    leftovers = [p.name for p in frame_dir.parent.iterdir() if p.name.startswith(".")]
    leftovers += [p.name for p in frame_dir.iterdir() if "partial" in p.name]
    assert leftovers == []


def test_interrupted_write_leaves_no_complete_looking_frame(tmp_path, synthetic_frame, monkeypatch):

    calls = {"n": 0}
    real = fr.write_distance_exr

    def boom(path, d):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        real(path, d)

    monkeypatch.setattr(fr, "write_distance_exr", boom)
    with pytest.raises(KeyboardInterrupt):
        write_frame(synthetic_frame, tmp_path)
    scene_dir = tmp_path / "synthetic_box"
    assert not (scene_dir / "vp000").exists()
    assert list(scene_dir.iterdir()) == []  # the hidden staging directory is gone too


def _corrupt(frame_dir, what):
    meta_path = frame_dir / "frame.json"
    meta = json.loads(meta_path.read_text())
    if what == "missing_png":
        (frame_dir / "U.png").unlink()
        return "U.png", "missing"
    if what == "corrupt_png":
        (frame_dir / "R.png").write_bytes(b"not a png")
        return "R.png", "not a readable image"
    if what == "corrupt_exr":
        (frame_dir / "C.distance.exr").write_bytes(b"\x76\x2f\x31\x01garbage")
        return "C.distance.exr", "not a readable OpenEXR"
    if what == "wrong_size":
        import cv2

        img = cv2.imread(str(frame_dir / "C.png"))
        cv2.imwrite(str(frame_dir / "C.png"), img[:, :-2])
        return "C.png", "size"
    if what == "nan_exr":
        d = read_distance_exr(frame_dir / "U.distance.exr")
        d[3, 3] = np.nan
        import OpenEXR

        OpenEXR.File({"type": OpenEXR.scanlineimage}, {"distance": d}).write(str(frame_dir / "U.distance.exr"))
        return "U.distance.exr", "NaN"
    if what == "bad_json":
        meta_path.write_text("{not json")
        return "frame.json", "not valid JSON"
    if what == "not_2to1":
        meta["height"] = 120
        msg = "width == 2*height"
    elif what == "bad_rotation":
        meta["cameras"]["R"]["rotation"][0] = [2.0, 0.0, 0.0]
        msg = "orthonormal"
    elif what == "nan_position":
        meta["cameras"]["C"]["position"][1] = float("nan")
        msg = "not finite"
    elif what == "wrong_format":
        meta["format"] = "tri360-frame/0"
        msg = "format"
    elif what == "missing_camera":
        del meta["cameras"]["U"]
        msg = "cameras.U"
    meta_path.write_text(json.dumps(meta))
    return "frame.json", msg


@pytest.mark.parametrize("what", ["missing_png", "corrupt_png", "corrupt_exr", "wrong_size", "nan_exr", "bad_json",
                                  "not_2to1", "bad_rotation", "nan_position", "wrong_format", "missing_camera"])
def test_malformed_frames_name_the_file(frame_dir, what):
    name, msg = _corrupt(frame_dir, what)
    with pytest.raises(FrameError) as err:
        read_frame(frame_dir)
    assert name in str(err.value) and msg in str(err.value)
    assert not is_complete(frame_dir)


def test_frame_without_ground_truth_is_valid(frame_dir):
    for k in "CUR":
        (frame_dir / f"{k}.distance.exr").unlink()
    frame = read_frame(frame_dir)
    assert not frame.has_ground_truth


def test_partial_ground_truth_is_an_error(frame_dir):
    (frame_dir / "R.distance.exr").unlink()
    with pytest.raises(FrameError, match="R.distance.exr"):
        read_frame(frame_dir)


def test_missing_directory(tmp_path):
    with pytest.raises(FrameError, match="frame.json"):
        read_frame(tmp_path / "nope")


def test_overwrite_replaces_atomically(tmp_path, synthetic_frame):
    d = write_frame(synthetic_frame, tmp_path)
    (d / "stale.txt").write_text("old")
    d2 = write_frame(synthetic_frame, tmp_path)
    assert d2 == d and not (d / "stale.txt").exists() and is_complete(d)
    shutil.rmtree(d)
