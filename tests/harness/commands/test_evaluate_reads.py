"""evaluate reads each of a frame's image and distance files once per task; finding, selecting and checking the
frames before the work reads only their frame.json."""

from __future__ import annotations

import re
import shutil
from collections import Counter
from pathlib import Path

import numpy as np
import OpenEXR
import pytest

import harness.data.exr
from harness.commands.evaluate import check_frame_kinds, evaluate, evaluate_task, select_frames
from harness.data.errors import FrameError, UserError
from harness.data.frame import read_frame, read_frame_info, write_frame
from harness.runtime.context import QUIET
from reconstruction.camera.rig import CAMERA_NAMES
from reconstruction.methods.registry import flow_methods, get_methods
from tests.helpers import make_synthetic_frame

FILES = [f"{k}.png" for k in CAMERA_NAMES] + [f"{k}.distance.exr" for k in CAMERA_NAMES]


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    """A data root with two 64x32 synthetic_box frames (vp000, vp001), ground truth included."""
    r = tmp_path_factory.mktemp("reads") / "data"
    for vp in (0, 1):
        write_frame(make_synthetic_frame(64, viewpoint=vp), r)
    return r


@pytest.fixture
def reads(monkeypatch):
    """Counts, per resolved path, every read of an image or distance file through the lowest-level readers of
    ``harness.data``: ``numpy.fromfile`` (``images.read_png``'s bytes), ``exr.check_exr_structure`` (an EXR's
    headers and chunk tables) and ``OpenEXR.File`` on a path (an EXR's pixels)."""
    counts: Counter = Counter()
    fromfile, structure, exr_file = np.fromfile, harness.data.exr.check_exr_structure, OpenEXR.File

    def counting_fromfile(file, *args, **kwargs):
        counts[("bytes", Path(file).resolve())] += 1
        return fromfile(file, *args, **kwargs)

    def counting_structure(path):
        counts[("exr header", Path(path).resolve())] += 1
        return structure(path)

    def counting_exr_file(*args, **kwargs):
        if args and isinstance(args[0], str | Path):  # reading; writing passes a header dict
            counts[("exr pixels", Path(args[0]).resolve())] += 1
        return exr_file(*args, **kwargs)

    monkeypatch.setattr(np, "fromfile", counting_fromfile)
    monkeypatch.setattr(harness.data.exr, "check_exr_structure", counting_structure)
    monkeypatch.setattr(OpenEXR, "File", counting_exr_file)
    return counts


def frame_reads(counts: Counter, frame_dir: Path) -> dict[str, int]:
    """How often each of the frame's image and distance files was read, by file name (every way of reading it
    counted: a PNG's bytes, an EXR's header and its pixels each count once)."""
    out = dict.fromkeys(FILES, 0)
    for (_, path), n in counts.items():
        if path.parent == frame_dir.resolve() and path.name in out:
            out[path.name] += n
    return out


def methods():
    """A method that runs on MethodInput (dis-rect) and one handed the frame itself (the oracle)."""
    return [*get_methods(["dis-rect:average"]), *flow_methods(["oracle"], [True], ["average"])]


def test_selecting_and_checking_frames_reads_no_pixel(root, reads):
    refs = select_frames(root)
    assert [(r.scene, r.viewpoint, r.has_ground_truth) for r in refs] == [("synthetic_box", "vp000", True),
                                                                          ("synthetic_box", "vp001", True)]
    assert check_frame_kinds(refs, methods()) is True
    assert select_frames(root, ["synthetic_box"]) == refs
    info = read_frame_info(refs[0].path)
    assert (info.width, info.height, info.has_ground_truth) == (64, 32, True)
    assert not reads  # no image, no distance map: frame.json only


def test_in_process_evaluate_reads_each_file_of_a_frame_once(root, tmp_path, reads):
    table = evaluate(root, tmp_path / "res", methods(), report=False, ctx=QUIET)
    assert len(table) == 2 * 2
    for vp in ("vp000", "vp001"):
        counted = frame_reads(reads, root / "synthetic_box" / vp)
        # each PNG's bytes once; each EXR once (its header checked, then its pixels decoded: two counts)
        assert counted == {**{f"{k}.png": 1 for k in CAMERA_NAMES}, **{f"{k}.distance.exr": 2 for k in CAMERA_NAMES}}


def test_a_task_reads_its_frame_once(root, tmp_path, reads):
    """evaluate_task is what a Dask worker runs: one frame x one group of methods."""
    frame_dir = root / "synthetic_box" / "vp001"
    stage = tmp_path / "stage"
    stage.mkdir()
    result = evaluate_task(str(frame_dir), methods(), str(stage))
    assert set(result["rows"]) == {"dis-rect:average", "oracle-rect:average"}
    assert frame_reads(reads, frame_dir) == {**{f"{k}.png": 1 for k in CAMERA_NAMES},
                                             **{f"{k}.distance.exr": 2 for k in CAMERA_NAMES}}
    assert frame_reads(reads, root / "synthetic_box" / "vp000") == dict.fromkeys(FILES, 0)


def test_a_frame_without_ground_truth_is_read_once_and_no_distance_file_looked_for(root, tmp_path, reads):
    data = tmp_path / "data"
    shutil.copytree(root / "synthetic_box" / "vp000", data / "hall" / "pos1")
    for k in CAMERA_NAMES:
        (data / "hall" / "pos1" / f"{k}.distance.exr").unlink()
    table = evaluate(data, tmp_path / "res", get_methods(["dis-rect:average"]), report=False, ctx=QUIET)
    assert len(table) == 1 and (table.valid_px == 0).all()
    assert frame_reads(reads, data / "hall" / "pos1") == {**{f"{k}.png": 1 for k in CAMERA_NAMES},
                                                           **{f"{k}.distance.exr": 0 for k in CAMERA_NAMES}}


def test_missing_files_are_refused_before_any_work(root, tmp_path, monkeypatch):
    """frame.json and which files are there are checked for every frame before the first method runs."""
    def forbidden(*args, **kwargs):
        raise AssertionError("a method ran before the frames were checked")
    monkeypatch.setattr("harness.commands.evaluate.run_blind", forbidden)
    data = tmp_path / "data"
    shutil.copytree(root, data)
    vp1 = data / "synthetic_box" / "vp001"
    (vp1 / "U.distance.exr").unlink()
    with pytest.raises(FrameError, match=re.escape(f"{vp1 / 'U.distance.exr'}: file is missing")):
        evaluate(data, tmp_path / "res", methods(), report=False, ctx=QUIET)
    shutil.copy(root / "synthetic_box" / "vp001" / "U.distance.exr", vp1)
    (vp1 / "R.png").unlink()
    with pytest.raises(FrameError, match=re.escape(f"{vp1 / 'R.png'}: file is missing")):
        evaluate(data, tmp_path / "res", methods(), report=False, ctx=QUIET)
    assert not (tmp_path / "res").exists()


def test_ground_truth_without_a_finite_distance_is_refused_by_its_task(root, tmp_path, monkeypatch):
    """Only the task reads the distance maps: a frame whose C holds no finite distance is refused there, before a
    method runs on it, and no results set is written."""
    data = tmp_path / "data"
    shutil.copytree(root / "synthetic_box" / "vp000", data / "synthetic_box" / "vp000")
    frame = read_frame(root / "synthetic_box" / "vp001")
    frame.distance = {k: np.full_like(v, np.inf) for k, v in frame.distance.items()}
    write_frame(frame, data)

    def forbidden(*args, **kwargs):
        raise AssertionError("a method ran on a frame without a finite true distance")
    monkeypatch.setattr("harness.commands.evaluate.run_blind", forbidden)
    where = re.escape(str(data / "synthetic_box" / "vp001" / "C.distance.exr"))
    with pytest.raises(UserError, match=f"{where}: no pixel has a finite distance"):
        evaluate_task(str(data / "synthetic_box" / "vp001"), methods(), str(tmp_path))
    monkeypatch.undo()
    with pytest.raises(UserError, match="no pixel has a finite distance"):
        evaluate(data, tmp_path / "res", methods(), report=False, ctx=QUIET)
    assert not (tmp_path / "res").exists()
