"""The data layer: the tri360-frame/1 format (round trip, validation, impossible rigs), the EXR and PNG readers on
damaged files, atomic writes (umask, concurrency, clean-up of killed runs)."""

import dataclasses
import json
import os
import shutil
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import OpenEXR
import pytest

import harness.data.atomic as atomic
import harness.data.frame as fr
from harness.data.atomic import (
    atomic_directory,
    atomic_write_bytes,
    atomic_write_text,
    atomic_write_via,
    clean_stale_partials,
    clean_stale_siblings,
    current_umask,
    parse_staging_name,
    replace_directory,
)
from harness.data.errors import FrameError
from harness.data.exr import (
    check_exr_structure,
    distance_map,
    float_channel,
    read_distance_exr,
    read_exr_channels,
    read_float_map,
    write_distance_exr,
    write_float_map,
)
from harness.data.frame import (
    MIN_CAMERA_SEPARATION_M,
    baseline_tolerance_m,
    find_frames,
    is_complete,
    read_frame,
    write_frame,
)
from harness.data.images import read_png, write_png
from harness.data.native import first_library_message, native_output_captured
from reconstruction.camera.rig import CameraPose
from tests.helpers import make_synthetic_frame

REPO = Path(__file__).resolve().parents[3]


@pytest.fixture()
def frame_dir(tmp_path, synthetic_frame):
    return write_frame(synthetic_frame, tmp_path)


@pytest.fixture(scope="module")
def small_frame():
    """A 64 x 32 synthetic_box frame (in memory)."""
    return make_synthetic_frame(64)


def hidden_entries(directory: Path) -> list[str]:
    return sorted(p.name for p in Path(directory).rglob(".*"))


# ------------------------------------------------------------------------------------------------ round trip


def test_round_trip(frame_dir, synthetic_frame):
    got = read_frame(frame_dir)
    assert (got.width, got.height, got.scene, got.viewpoint) == (200, 100, "synthetic_box", "vp000")
    for k in "CUR":
        assert np.array_equal(got.images[k], synthetic_frame.images[k])
        assert np.array_equal(got.distance[k], synthetic_frame.distance[k])  # float32 exact, inf kept
        np.testing.assert_allclose(got.cameras[k].rotation, synthetic_frame.cameras[k].rotation, rtol=0, atol=1e-12)
    meta = json.loads((frame_dir / "frame.json").read_text())
    assert meta["format"] == "tri360-frame/1" and set(meta["cameras"]) == {"C", "U", "R"}
    assert find_frames(frame_dir.parent.parent) == [frame_dir]


def test_distance_exr_channel_and_no_hit(tmp_path):
    d = np.array([[1.5, np.inf], [2.0, 3.0]], np.float32)
    write_distance_exr(tmp_path / "x.exr", d)
    assert list(OpenEXR.File(str(tmp_path / "x.exr")).channels()) == ["distance"]
    assert np.array_equal(read_distance_exr(tmp_path / "x.exr"), d)


def test_cycles_no_hit_value_becomes_inf(tmp_path):
    """Cycles writes 1e10 m for rays that hit nothing; anything above 1e9 m reads as +inf."""
    write_float_map(tmp_path / "d.exr", np.array([[1e10, 2.0]], np.float32), "distance")
    assert read_distance_exr(tmp_path / "d.exr").tolist() == [[np.inf, 2.0]]


def test_confidence_map_round_trip(tmp_path):
    c = np.linspace(0, 1, 12, dtype=np.float32).reshape(3, 4)
    write_float_map(tmp_path / "confidence.exr", c, "confidence")
    assert list(read_exr_channels(tmp_path / "confidence.exr")) == ["confidence"]
    assert np.array_equal(read_float_map(tmp_path / "confidence.exr", "confidence"), c)
    with pytest.raises(FrameError, match=r"confidence.exr: no channel named 'distance' \(found \['confidence'\]\)"):
        read_float_map(tmp_path / "confidence.exr", "distance")


def test_multi_part_exr_channels_are_merged(tmp_path):
    """Blender 5.0 writes Combined and Depth as separate parts; one reader sees every part's channels."""
    rgb = np.full((4, 8), 0.5, np.float16)
    depth = np.arange(32, dtype=np.float32).reshape(4, 8) + 1.0
    def hdr():  # a fresh dict per part: the binding stores the part name in it
        return {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}

    parts = [OpenEXR.Part(hdr(), {f"ViewLayer.Combined.{c}": rgb for c in "RGB"}, "ViewLayer.Combined"),
             OpenEXR.Part(hdr(), {"ViewLayer.Depth.Z": depth}, "ViewLayer.Depth")]
    OpenEXR.File(parts).write(str(tmp_path / "multi.exr"))
    ch = read_exr_channels(tmp_path / "multi.exr")
    assert sorted(ch) == ["ViewLayer.Combined.B", "ViewLayer.Combined.G", "ViewLayer.Combined.R", "ViewLayer.Depth.Z"]
    assert ch["ViewLayer.Combined.R"].dtype == np.float16
    assert np.array_equal(read_distance_exr(tmp_path / "multi.exr", channel="ViewLayer.Depth.Z"), depth)
    # what the Cycles backend does with one read: colour and distance from the same dict
    rgb = np.stack([float_channel(ch, tmp_path / "multi.exr", f"ViewLayer.Combined.{c}") for c in "RGB"], axis=-1)
    assert rgb.shape == (4, 8, 3) and rgb.dtype == np.float32 and np.all(rgb == 0.5)
    assert np.array_equal(distance_map(ch["ViewLayer.Depth.Z"], tmp_path / "multi.exr"), depth)
    assert [p.channels for p in check_exr_structure(tmp_path / "multi.exr")] == [
        ["ViewLayer.Combined.B", "ViewLayer.Combined.G", "ViewLayer.Combined.R"], ["ViewLayer.Depth.Z"]]


def test_channel_in_two_parts_is_an_error(tmp_path):
    d = np.ones((2, 4), np.float32)
    parts = [OpenEXR.Part({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"distance": d}, n)
             for n in "ab"]
    OpenEXR.File(parts).write(str(tmp_path / "dup.exr"))
    with pytest.raises(FrameError, match="dup.exr: channel 'distance' appears in more than one part"):
        read_exr_channels(tmp_path / "dup.exr")


# ------------------------------------------------------------------------------------------- damaged files


def _damage(path: Path, how: str) -> None:
    data = bytearray(path.read_bytes())
    if how == "truncate60":
        data = data[: int(0.6 * len(data))]
    elif how == "truncate99":
        data = data[:-3]
    elif how == "pixels":  # flip 64 bytes at 80 % of the file: inside the last compressed chunk
        i = int(0.8 * len(data))
        data[i:i + 64] = bytes(b ^ 0x5A for b in data[i:i + 64])
    elif how == "offsets":  # the chunk offset table follows the header: point the first chunk past the end
        assert check_exr_structure(path)[0].chunks >= 1
        first = _first_offset_position(bytes(data))
        data[first:first + 8] = (len(data) + 1000).to_bytes(8, "little")
    path.write_bytes(bytes(data))


def _first_offset_position(data: bytes) -> int:
    """Byte position of the first chunk offset of a single-part file: just after the header's final NUL."""
    pos = 8
    while data[pos] != 0:  # attribute: name NUL type NUL size value
        pos = data.index(b"\0", pos) + 1
        pos = data.index(b"\0", pos) + 1
        size = int.from_bytes(data[pos:pos + 4], "little")
        pos += 4 + size
    return pos + 1


@pytest.mark.parametrize("how", ["truncate60", "truncate99", "pixels", "offsets"])
def test_damaged_exr_with_intact_header_is_truncated_or_corrupt(tmp_path, capfd, how):
    """OpenEXR 3.5.3 returns *no parts* (and prints to fds 1/2) for such files; we name the file and print nothing."""
    path = tmp_path / "C.distance.exr"
    v, u = np.mgrid[0:64, 0:128]
    write_distance_exr(path, (1.0 + 0.01 * u + 0.02 * v).astype(np.float32))  # smooth, so ZIP really compresses
    # (OpenEXR stores a chunk raw when compression does not shrink it; raw chunks cannot be checked, see below)
    _damage(path, how)
    capfd.readouterr()
    with pytest.raises(FrameError) as err:
        read_distance_exr(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: truncated or corrupt OpenEXR file"), msg
    assert "\n" not in msg
    out, errout = capfd.readouterr()
    assert out == "" and errout == "", "the library's own messages must not reach the terminal"


def test_damaged_uncompressed_pixels_are_caught_by_the_value_checks(tmp_path):
    """EXR has no checksums: overwritten bytes in *uncompressed* pixel data decode to other numbers.  Only the
    distance checks can catch them (here: 0xFF bytes decode to NaN)."""
    path = tmp_path / "d.exr"
    hdr = {"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(hdr, {"distance": np.full((8, 16), 2.0, np.float32)}).write(str(path))
    data = bytearray(path.read_bytes())
    data[-16:] = b"\xff" * 16
    path.write_bytes(bytes(data))
    assert check_exr_structure(path)[0].chunks == 8  # the structure is intact
    with pytest.raises(FrameError, match="d.exr: channel 'distance' contains NaN"):
        read_distance_exr(path)


def test_not_an_exr(tmp_path):
    (tmp_path / "x.exr").write_bytes(b"hello world, not an image")
    with pytest.raises(FrameError, match=r"x.exr: not a readable OpenEXR file \(no EXR magic number\)"):
        read_exr_channels(tmp_path / "x.exr")
    (tmp_path / "d.exr").mkdir()
    with pytest.raises(FrameError, match="d.exr: is a directory"):
        read_exr_channels(tmp_path / "d.exr")


def test_truncated_png_is_one_clean_error(tmp_path, capfd):
    img = np.random.default_rng(1).integers(0, 256, (32, 64, 3), dtype=np.uint8)
    write_png(tmp_path / "C.png", img)
    assert np.array_equal(read_png(tmp_path / "C.png"), img)
    data = (tmp_path / "C.png").read_bytes()
    (tmp_path / "C.png").write_bytes(data[: int(0.6 * len(data))])
    capfd.readouterr()
    with pytest.raises(FrameError, match=r"C.png: truncated or corrupt PNG file \(.*incomplete.*\)$"):
        read_png(tmp_path / "C.png")
    assert capfd.readouterr() == ("", ""), "libpng's own message must not reach the terminal"


def test_native_output_is_captured_and_released_only_on_success(capfd):
    capfd.readouterr()
    with native_output_captured() as ok:
        os.write(2, b"lib: harmless warning\n")
    ok.release()  # the decode succeeded: hand the text back
    with native_output_captured() as bad:
        os.write(1, b"Warning: Exception raised reading pixel data\n")
        os.write(2, b"/x/y.exr: (EXR_ERR_CORRUPT_CHUNK) Unable to decompress\n")
    assert capfd.readouterr() == ("", "lib: harmless warning\n")
    assert first_library_message(bad.text) == "Warning: Exception raised reading pixel data"
    assert first_library_message("/x/y.exr: (EXR_ERR_CORRUPT_CHUNK) bad\n", "/x/y.exr") == "(EXR_ERR_CORRUPT_CHUNK) bad"
    assert first_library_message("[ WARN:0@1.2] global grfmt_png.cpp:678 read_from_io PNG input buffer is incomplete"
                                 ) == "PNG input buffer is incomplete"


# ---------------------------------------------------------------------------------------- frame validation


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
    if what == "truncated_exr":
        _damage(frame_dir / "R.distance.exr", "truncate60")
        return "R.distance.exr", "truncated or corrupt"
    if what == "wrong_size":
        import cv2

        img = cv2.imread(str(frame_dir / "C.png"))
        cv2.imwrite(str(frame_dir / "C.png"), img[:, :-2])
        return "C.png", "size"
    if what == "nan_exr":
        d = read_distance_exr(frame_dir / "U.distance.exr")
        d[3, 3] = np.nan
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
    elif what == "inf_baseline":
        meta["baseline_m"] = float("inf")
        msg = "baseline_m must be positive and finite"
    elif what == "wrong_format":
        meta["format"] = "tri360-frame/0"
        msg = "format"
    elif what == "missing_camera":
        del meta["cameras"]["U"]
        msg = "cameras.U"
    elif what == "coincident":
        meta["cameras"]["R"]["position"] = list(meta["cameras"]["U"]["position"])
        msg = "cameras U and R coincide"
    elif what == "baseline_contradiction":
        meta["baseline_m"] = 2 * meta["baseline_m"]
        msg = "contradicts baseline_m"
    elif what == "path_in_name":
        meta["viewpoint"] = "../escape"
        msg = "cannot be a directory name"
    meta_path.write_text(json.dumps(meta))  # json writes NaN/Infinity tokens, as a careless writer would
    return "frame.json", msg


@pytest.mark.parametrize("what", ["missing_png", "corrupt_png", "corrupt_exr", "truncated_exr", "wrong_size", "nan_exr",
                                  "bad_json", "not_2to1", "bad_rotation", "nan_position", "inf_baseline",
                                  "wrong_format", "missing_camera", "coincident", "baseline_contradiction",
                                  "path_in_name"])
def test_malformed_frames_name_the_file(frame_dir, what):
    name, msg = _corrupt(frame_dir, what)
    with pytest.raises(FrameError) as err:
        read_frame(frame_dir)
    assert str(frame_dir / name) in str(err.value) and msg in str(err.value), str(err.value)
    assert "\n" not in str(err.value)
    assert not is_complete(frame_dir)


def _moved(frame, name, offset):
    cams = dict(frame.cameras)
    cams[name] = CameraPose(cams[name].position + np.asarray(offset, float), cams[name].rotation)
    return dataclasses.replace(frame, cameras=cams)


def test_baseline_tolerance_is_one_percent_or_one_millimetre():
    assert baseline_tolerance_m(0.4) == pytest.approx(0.004, abs=1e-12)
    assert baseline_tolerance_m(0.05) == pytest.approx(0.001, abs=1e-12)
    assert MIN_CAMERA_SEPARATION_M == pytest.approx(0.001, abs=1e-12)


def test_rig_checks_at_their_limits(tmp_path, small_frame):
    """R moved along the baseline by 0.9 x and 1.1 x the 4 mm tolerance of a 0.4 m rig: kept, then refused."""
    assert small_frame.baseline_m == pytest.approx(0.4, abs=1e-12)
    x = small_frame.cameras["C"].rotation[:, 0]  # the rig's right axis: R = C + b x
    write_frame(_moved(small_frame, "R", 0.9 * 0.004 * x), tmp_path / "ok")
    with pytest.raises(FrameError, match=r"frame.json: impossible rig: \|R - C\| = 0.4044 m contradicts baseline_m"):
        write_frame(_moved(small_frame, "R", 1.1 * 0.004 * x), tmp_path / "bad")
    assert not (tmp_path / "bad").exists()


@pytest.mark.parametrize("change, msg", [
    ("coincident", "cameras U and R coincide"),
    ("baseline", "contradicts baseline_m"),
    ("nan_position", "position is not finite"),
    ("bad_rotation", "rotation is not orthonormal"),
    ("reflection", "rotation is not proper"),
    ("partial_gt", "ground truth for C, U only"),
    ("negative_gt", "distances must be positive"),
    ("nan_gt", "distance map contains NaN"),
    ("image_size", "image must be (32, 64, 3) uint8"),
    ("hidden_viewpoint", "cannot be a directory name"),
    ("nan_provenance", "metadata is not plain JSON"),
])
def test_write_frame_refuses_what_read_frame_would_refuse_and_writes_nothing(tmp_path, small_frame, change, msg):
    f = dataclasses.replace(small_frame, cameras=dict(small_frame.cameras), images=dict(small_frame.images),
                            distance=dict(small_frame.distance), renderer=dict(small_frame.renderer))
    if change == "coincident":
        f.cameras["R"] = f.cameras["U"]
    elif change == "baseline":
        f.baseline_m = 0.3
    elif change == "nan_position":
        f.cameras["C"] = CameraPose(np.array([0.0, np.nan, 1.0]), f.cameras["C"].rotation)
    elif change == "bad_rotation":
        f.cameras["U"] = CameraPose(f.cameras["U"].position, 1.01 * f.cameras["U"].rotation)
    elif change == "reflection":
        f.cameras["U"] = CameraPose(f.cameras["U"].position, f.cameras["U"].rotation * np.array([-1.0, 1.0, 1.0]))
    elif change == "partial_gt":
        del f.distance["R"]
    elif change == "negative_gt":
        f.distance["U"] = -f.distance["U"]
    elif change == "nan_gt":
        f.distance["C"] = np.where(np.arange(64) == 5, np.nan, f.distance["C"]).astype(np.float32)
    elif change == "image_size":
        f.images["R"] = f.images["R"][:, :60]
    elif change == "hidden_viewpoint":
        f.viewpoint = ".vp000"
    elif change == "nan_provenance":
        f.renderer["seconds"] = float("nan")
    with pytest.raises(FrameError) as err:
        write_frame(f, tmp_path)
    assert msg in str(err.value) and str(tmp_path) in str(err.value), str(err.value)
    assert list(tmp_path.iterdir()) == [], "nothing may be written for an invalid frame"


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
    assert hidden_entries(tmp_path) == []
    shutil.rmtree(d)


def test_file_in_place_of_the_frame_directory(tmp_path, small_frame):
    (tmp_path / "synthetic_box").mkdir()
    (tmp_path / "synthetic_box" / "vp000").write_text("in the way")
    with pytest.raises(NotADirectoryError) as err:
        write_frame(small_frame, tmp_path)
    assert err.value.filename == str(tmp_path / "synthetic_box" / "vp000")
    assert (tmp_path / "synthetic_box" / "vp000").read_text() == "in the way"
    assert hidden_entries(tmp_path) == []


# --------------------------------------------------------------------------------------------------- umask


def _modes(root: Path) -> dict[str, int]:
    return {str(p.relative_to(root)): stat.S_IMODE(p.stat().st_mode) for p in [root, *root.rglob("*")]}


@pytest.mark.parametrize("umask, file_mode, dir_mode", [(0o022, 0o644, 0o755), (0o077, 0o600, 0o700),
                                                         (0o002, 0o664, 0o775)])
def test_outputs_respect_the_umask(tmp_path, small_frame, umask, file_mode, dir_mode):
    old = os.umask(umask)
    try:
        assert current_umask() == umask
        root = tmp_path / "root"
        write_frame(small_frame, root)
        write_frame(small_frame, root)  # the replacing path too
        atomic_write_text(root / "notes" / "a.txt", "x")
        atomic_write_via(root / "notes" / "b.exr", lambda p: Path(p).write_bytes(b"x"))
        with atomic_directory(root / "notes" / "d") as d:
            (d / "f").write_text("x")
    finally:
        os.umask(old)
    modes = _modes(root)
    assert len(modes) == 15  # root, scene, frame, its 7 files, notes, a.txt, b.exr, d, d/f: nothing else
    for rel, mode in modes.items():
        want = dir_mode if (root / rel).is_dir() else file_mode
        assert mode == want, f"{rel}: {oct(mode)} != {oct(want)}"


def test_current_umask_without_proc(monkeypatch):
    def no_proc(*a, **k):
        raise OSError("no /proc")

    old = os.umask(0o027)
    try:
        monkeypatch.setattr(atomic, "open", no_proc, raising=False)
        assert current_umask() == 0o027
        assert os.umask(0o027) == 0o027  # and it is unchanged
    finally:
        os.umask(old)


def test_atomic_write_errors_name_the_target_not_the_temporary(tmp_path):
    (tmp_path / "d").mkdir()
    with pytest.raises(IsADirectoryError) as err:
        atomic_write_bytes(tmp_path / "d", b"x")
    assert err.value.filename == str(tmp_path / "d")
    (tmp_path / "f").write_text("x")
    with pytest.raises(NotADirectoryError) as err:
        atomic_write_text(tmp_path / "f" / "g.txt", "x")
    assert err.value.filename == str(tmp_path / "f")
    with pytest.raises(OSError) as err:
        atomic_write_text(Path("/proc/tri360-test/x.txt"), "x")
    assert "/proc/tri360-test" in str(err.value.filename)
    assert hidden_entries(tmp_path) == []


def test_failing_writer_leaves_target_and_no_temporary(tmp_path):
    atomic_write_text(tmp_path / "a.txt", "old")

    def writer(p):
        Path(p).write_text("half")
        raise RuntimeError("disk on fire")

    with pytest.raises(RuntimeError, match="disk on fire"):
        atomic_write_via(tmp_path / "a.txt", writer)
    assert (tmp_path / "a.txt").read_text() == "old" and hidden_entries(tmp_path) == []


# ------------------------------------------------------------------------------------------- concurrency

WRITER = r"""
import json, os, sys, time
from pathlib import Path
import harness.data.atomic as atomic
from harness.data.frame import read_frame, write_frame

src, root, go, n, exchange = sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3]), int(sys.argv[4]), sys.argv[5] == "1"
if not exchange:
    atomic._exchange_supported = False  # force the rename-aside fallback
frame = read_frame(src)
(go.parent / f"ready-{os.getpid()}").touch()  # imported and loaded: the test gives the go once both are
deadline = time.time() + 60
while not go.exists():
    if time.time() > deadline:
        sys.exit("no go signal")
    time.sleep(0.001)
spans = []
for _ in range(n):
    t0 = time.monotonic()
    write_frame(frame, root)
    spans.append((t0, time.monotonic()))
print(json.dumps({"spans": spans, "exchange": atomic._exchange_supported}))
"""


@pytest.mark.slow
@pytest.mark.parametrize("exchange", [True, False], ids=["renameat2-exchange", "rename-aside"])
def test_concurrent_forced_writes_of_one_frame(tmp_path, small_frame, exchange):
    """Two real processes write the same frame 20 times each, at the same time: no failure, the frame validates
    and no hidden .partial/.old entries remain.  (The old rename-to-.old-<pid> scheme crashed here.)"""
    if exchange and not atomic.exchange_supported():
        pytest.skip("renameat2(RENAME_EXCHANGE) is not available on this system")
    src = write_frame(small_frame, tmp_path / "src")
    root, go = tmp_path / "root", tmp_path / "go"
    write_frame(small_frame, root)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    procs = [subprocess.Popen([sys.executable, "-c", WRITER, str(src), str(root), str(go), "20", str(int(exchange))],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=REPO)
             for _ in range(2)]
    deadline = time.monotonic() + 120  # both writers ready (however long their start-up takes), then go at once
    while len(list(tmp_path.glob("ready-*"))) < 2 and all(p.poll() is None for p in procs):
        assert time.monotonic() < deadline, "the writers did not start"
        time.sleep(0.01)
    go.touch()
    results = [p.communicate(timeout=120) for p in procs]
    for p, (_, err) in zip(procs, results, strict=True):
        assert p.returncode == 0 and err == "", err
    a, b = (json.loads(out) for out, _ in results)
    assert a["exchange"] is b["exchange"] is exchange, "the intended replacement path was not the one used"
    a, b = a["spans"], b["spans"]
    overlaps = sum(1 for s in a for t in b if s[0] < t[1] and t[0] < s[1])
    assert overlaps > 0, "the two writers never overlapped: the test did not test concurrency"
    frame = read_frame(root / "synthetic_box" / "vp000")
    assert np.array_equal(frame.distance["C"], small_frame.distance["C"])
    assert [p.name for p in (root / "synthetic_box").iterdir()] == ["vp000"]
    assert hidden_entries(root) == []


def test_replace_directory_tolerates_the_target_vanishing(tmp_path, monkeypatch):
    """Without exchange: the target is renamed aside; if another process removed it in between, try again."""
    target, staging = tmp_path / "t", tmp_path / ".t.partial-1-00000000"
    target.mkdir()
    (target / "old").write_text("old")
    staging.mkdir()
    (staging / "new").write_text("new")
    monkeypatch.setattr(atomic, "_exchange_supported", False)
    real_rename, calls = os.rename, []

    def racing_rename(src, dst):
        calls.append((Path(src).name, Path(dst).name))
        if len(calls) == 2:  # between our failed rename and our rename-aside, someone else takes the target away
            shutil.rmtree(target)
        return real_rename(src, dst)

    monkeypatch.setattr(atomic.os, "rename", racing_rename)
    replace_directory(staging, target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t"] and (target / "new").read_text() == "new"
    assert len(calls) == 3  # rename (ENOTEMPTY), rename-aside (ENOENT), rename (done)


# ------------------------------------------------------------------------------------------ stale partials


def _dead_pid() -> int:
    out = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True,
                         check=True)
    return int(out.stdout)


def test_staging_names_encode_the_pid():
    assert parse_staging_name(".vp000.partial-123-0a1b2c3d") == ("partial", 123)
    assert parse_staging_name(".C.distance.exr.partial-77-0a1b2c3d.exr") == ("partial", 77)
    assert parse_staging_name(".vp000.old-9-ffffffff") == ("old", 9)
    assert parse_staging_name(".vp000.old-4242") == ("old", 4242)  # written by tri360 before this module
    assert parse_staging_name(".vp000.partial-k2j3h4g5") == ("partial", None)
    assert parse_staging_name(".results.csv.x8y7z6w5.partial") == ("partial", None)
    assert parse_staging_name(".gitignore") is None and parse_staging_name("vp000") is None


def test_clean_stale_partials(tmp_path):
    dead, mine, now = _dead_pid(), os.getpid(), time.time()
    scene = tmp_path / "synthetic_box"
    keep = [scene / "vp000" / "frame.json", scene / f".vp001.partial-{mine}-00000001", tmp_path / ".gitignore",
            scene / ".vp002.partial-k2j3h4g5", scene / "vp003.partial-1-00000000"]
    gone = [scene / f".vp000.partial-{dead}-0000000a", scene / f".vp000.old-{dead}-0000000b",
            tmp_path / "maps" / f".average.distance.exr.partial-{dead}-0000000c.exr", scene / f".vp004.old-{dead}",
            scene / f".vp005.partial-{mine}-0000000d"]
    for p in keep + gone:
        p.parent.mkdir(parents=True, exist_ok=True)
        if "vp00" in p.name and ".exr" not in p.name:
            p.mkdir()
            (p / "C.png").write_bytes(b"x")
        else:
            p.write_bytes(b"x")
    old = now - 7200.0
    os.utime(scene / ".vp005.partial-" f"{mine}-0000000d", (old, old))  # ours, but abandoned long ago
    os.utime(scene / ".vp002.partial-k2j3h4g5", (now - 60.0, now - 60.0))  # no pid, young: kept
    removed = clean_stale_partials(tmp_path, max_age_s=3600.0, now=now)
    assert removed == sorted(gone)
    assert all(p.exists() for p in keep) and not any(p.exists() for p in gone)
    assert clean_stale_partials(tmp_path / "missing") == []


def test_clean_stale_siblings_looks_only_beside_the_target(tmp_path):
    dead = _dead_pid()
    mine = [tmp_path / f".res.partial-{dead}-0000000a", tmp_path / f".res.old-{dead}-0000000b"]
    others = [tmp_path / f".other.partial-{dead}-0000000c", tmp_path / "deeper" / f".res.partial-{dead}-0000000d"]
    for p in mine + others:
        p.mkdir(parents=True)
    assert clean_stale_siblings(tmp_path / "res") == sorted(mine)
    assert all(p.exists() for p in others) and not any(p.exists() for p in mine)


def test_find_frames_follows_directory_links_once(tmp_path, synthetic_frame):
    """Data roots assembled from symbolic links are found; a link cycle does not loop."""
    real = tmp_path / "real"
    write_frame(synthetic_frame, real)
    root = tmp_path / "root"
    (root / "synthetic_box").mkdir(parents=True)
    (root / "synthetic_box" / "vp000").symlink_to(real / "synthetic_box" / "vp000")
    (root / "loop").symlink_to(root)
    assert find_frames(root) == [root / "synthetic_box" / "vp000"]
