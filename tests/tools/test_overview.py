"""tools.overview: the README's picture from a results set's map of one frame."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from harness.data.exr import write_distance_exr
from harness.data.frame import write_frame
from harness.data.images import read_png
from harness.data.results import map_paths
from tools.common import synthetic_box_frame
from tools.overview import PNG_MARK, is_overview_png, main, marked_png


@pytest.mark.slow
def test_overview_writes_the_picture_and_refuses_a_missing_map(tmp_path, capsys):
    frame = synthetic_box_frame(64, "vp000")
    data = tmp_path / "data"
    write_frame(frame, data)
    frame_dir = data / frame.scene / "vp000"
    results = tmp_path / "results"
    results.mkdir()
    (results / "frames.json").write_text(json.dumps([{"scene": frame.scene, "viewpoint": "vp000",
                                                      "path": str(frame_dir.resolve())}]))
    out = tmp_path / "overview.png"
    assert main([str(results), str(frame_dir), "--method", "m", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no map of method 'm'" in err[0]
    assert not out.exists()
    distance_map, _ = map_paths(frame.scene, "vp000", "m")
    (results / distance_map).parent.mkdir(parents=True)
    write_distance_exr(results / distance_map, (frame.distance["C"] * 1.01).astype(np.float32))
    assert main([str(results), str(frame_dir), "--method", "m", "--out", str(out)]) == 0
    assert read_png(out).ndim == 3 and is_overview_png(out)
    assert main([str(results), str(frame_dir), "--method", "m", "--out", str(out)]) == 0  # its own: replaced
    assert main([str(results), str(tmp_path / "nowhere"), "--method", "m", "--out", str(out)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_the_mark_is_a_text_chunk_after_ihdr_and_other_pngs_lack_it(tmp_path):
    png = cv2.imencode(".png", np.zeros((8, 16, 3), np.uint8))[1].tobytes()
    plain, marked = tmp_path / "plain.png", tmp_path / "marked.png"
    plain.write_bytes(png)
    marked.write_bytes(marked_png(png))
    assert not is_overview_png(plain) and is_overview_png(marked)
    assert PNG_MARK in marked.read_bytes()[:100]
    assert read_png(marked).shape == (8, 16, 3)  # still a valid PNG
    (tmp_path / "text.png").write_text("not a png")
    assert not is_overview_png(tmp_path / "text.png") and not is_overview_png(tmp_path / "absent.png")
