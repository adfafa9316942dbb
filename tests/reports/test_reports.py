"""The report job end to end: a tiny fake results directory (real EXR maps, a real frame on disk) -> every output
of ``harness.commands.report.build_report``; reading a malformed results set (``harness.data.results``)."""

from __future__ import annotations

import csv
import json
import re
import time
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from harness.cli import main
from harness.commands.report import build_report
from harness.data.errors import UserError
from harness.data.exr import CONFIDENCE_CHANNEL, DISTANCE_CHANNEL, write_float_map
from harness.data.frame import Frame, write_frame
from harness.data.results import map_paths, read_results, write_results
from reconstruction.camera.equirect import bearing_grid
from reconstruction.camera.rig import Rig
from reports.floor import floor_fields, frame_floor_sigma, region_floors
from reports.metrics import breakdown, summary
from reports.pointcloud import parse_ply, ply_bytes, point_grid
from reports.regions import region_summaries, regions
from reports.schema import RESULT_COLUMNS, breakdown_table, regions_table, results_table
from reports.sections import SECTION_HALF_ANGLE_DEG, section_sample
from reports.tables import variant_mae_table

W, H = 64, 32
VARIANTS = {"average": 0.08, "gradient": 0.05, "color": 0.04}  # relative noise per variant
CONFIGS = [("deepflow", True), ("dis", True)]
#: methods that are not the flow pipeline (make_results(others=True)): label -> (relative noise, with confidence?)
OTHERS = {"matcher": (0.03, True), "outside": (0.06, False)}


def box_room_distance(width, height, half=(3.0, 4.0), floor=-1.2, ceiling=1.8) -> np.ndarray:
    """Exact distance from the origin to the walls of an axis-aligned box room, (H, W) metres."""
    b = bearing_grid(width, height)
    with np.errstate(divide="ignore"):
        tx = np.where(b[..., 0] > 0, half[0], -half[0]) / b[..., 0]
        ty = np.where(b[..., 1] > 0, half[1], -half[1]) / b[..., 1]
        tz = np.where(b[..., 2] > 0, ceiling, floor) / b[..., 2]
    return np.min(np.abs(np.stack([tx, ty, tz])), axis=0)


def box_room_frame(scene: str = "room", viewpoint: str = "v0", sky_px: int = 5) -> Frame:
    """A 64x32 box-room frame in memory; its first ``sky_px`` pixels (row-major) see no surface."""
    v, u = np.mgrid[0:H, 0:W]
    checker = (((u // 4) + (v // 4)) % 2).astype(np.uint8)
    img = np.stack([60 + 150 * checker, 90 + 0 * checker, 200 - 120 * checker], axis=2).astype(np.uint8)
    gt = box_room_distance(W, H).astype(np.float32)
    gt.flat[:sky_px] = np.inf  # a little "sky": no surface, not scored
    return Frame(scene=scene, viewpoint=viewpoint, width=W, height=H, baseline_m=0.4, cameras=Rig().poses(),
                 images={"C": img, "U": img, "R": img}, distance={"C": gt, "U": gt, "R": gt})


def make_frame(root: Path, scene: str = "room", viewpoint: str = "v0", sky_px: int = 5) -> Frame:
    """:func:`box_room_frame` written under ``root``."""
    frame = box_room_frame(scene, viewpoint, sky_px)
    frame.path = write_frame(frame, root)
    return frame


def make_results(tmp_path: Path, scenes=("room",), flow: bool = True, others: bool = False) -> Path:
    """A results directory like `tri360 evaluate` writes (results with the floor, regions, breakdown, frames.json,
    config.json, maps), one frame per scene: the flow pipeline's CONFIGS x VARIANTS (``flow``) and/or the OTHERS methods
    (``others``; ``matcher`` writes a confidence that ranks its errors, ``outside`` none and a few NaN)."""
    res = tmp_path / "results"
    rows, bd_rows, region_rows, frames, kinds = [], [], [], [], {}
    rng = np.random.default_rng(1)
    for i, scene in enumerate(scenes):
        frame = make_frame(tmp_path / "data", scene, sky_px=5 + 300 * i)  # frames differ in scored pixels
        frames.append({"scene": scene, "viewpoint": "v0", "path": str(frame.path.resolve())})
        gt = frame.distance["C"]
        masks = regions(frame)
        floors = region_floors(frame_floor_sigma(frame), masks)  # as evaluate scores them
        methods = []  # (label, key fields, map path, prediction, confidence)
        for flow_name, rect in CONFIGS if flow else []:
            for variant, noise in VARIANTS.items():
                pred = np.abs(gt * (1 + noise * rng.standard_normal(gt.shape)).astype(np.float32))
                if variant == "average":
                    pred[5, 10:14] = np.inf  # a few pixels without prediction
                key = f"{flow_name}-{'rect' if rect else 'plain'}"
                methods.append((f"{key}:{variant}", {"flow": flow_name, "rectify": rect, "variant": variant},
                                f"{key}/{variant}.distance.exr", pred, None))
        for label, (noise, with_conf) in OTHERS.items() if others else []:
            z = rng.standard_normal(gt.shape)
            pred = np.abs(gt * (1 + noise * z)).astype(np.float32)
            conf = None
            if with_conf:
                conf = (-np.abs(z) + 0.3 * rng.standard_normal(gt.shape)).astype(np.float32)  # ranks the errors
            else:
                pred[6, 0:3] = np.nan  # no prediction
            methods.append((label, {"flow": "", "rectify": "", "variant": ""}, f"{label}/distance.exr", pred, conf))
        for label, fields, rel, pred, conf in methods:
            kinds[label] = "flow-pipeline" if fields["flow"] else ("sweep" if label == "matcher" else "predictions")
            path = res / "maps" / scene / "v0" / rel
            write_float_map(path, pred, DISTANCE_CHANNEL)
            if conf is not None:
                write_float_map(path.with_name(path.name.replace("distance", "confidence")), conf, CONFIDENCE_CHANNEL)
            key = {"scene": scene, "viewpoint": "v0", "method": label, **fields}
            overall = summary(pred, gt, conf)
            rows.append({**key, "width": W, "height": H, **overall, **floor_fields(overall["mae_m"], floors["all"]),
                         "seconds": 0.5})
            bd_rows.extend({**key, **b} for b in breakdown(frame, pred))
            region_rows.extend({**key, **r, **floor_fields(r["mae_m"], floors[r["region"]])}
                               for r in region_summaries(frame, pred, conf, masks=masks))
    write_results(res, results_table(rows), breakdown_table(bd_rows), regions_table(region_rows), frames=frames,
                  config={"methods": {k: {"kind": v} for k, v in kinds.items()}})
    return res


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("report")
    res = make_results(tmp)
    t0 = time.perf_counter()
    outcome = build_report(res, cloud_points=500)
    return res, outcome, time.perf_counter() - t0


class _Collect(HTMLParser):
    def __init__(self):
        super().__init__()
        self.imgs, self.links = [], []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.imgs.append(a.get("src", ""))
        if tag == "a":
            self.links.append(a.get("href", ""))


# ------------------------------------------------------------------------------------------------ outputs


@pytest.mark.slow
def test_every_output_exists(report):
    res, outcome, _ = report
    expected = ["leaderboard.csv", "leaderboard.md", "mae.md", "mae.csv", "fig4_mae.png", "error_vs_angle.png",
                "error_by_distance_texture.png", "report.html", "clouds/room/v0/ground_truth.ply",
                "figures/room/v0/errors.png", "figures/room/v0/regions.png"]
    for flow, rect in CONFIGS:
        key = f"{flow}-{'rect' if rect else 'plain'}"
        expected += [f"figures/room/v0/{key}.clouds.png"]
        expected += [f"clouds/room/v0/{key}/{v}.ply" for v in VARIANTS]
    for rel in expected:
        p = res / rel
        assert p.is_file() and p.stat().st_size > 0, rel
        if rel.endswith(".png"):
            assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", rel
    assert outcome.html_path == res / "report.html"
    assert outcome.problems == []
    assert not (res / "sparsification.png").exists()  # no method gave a confidence
    assert not list(res.rglob("*.partial*"))  # atomic writes leave no temporaries


def _read_ply(path: Path):
    return parse_ply(path.read_bytes(), str(path))


@pytest.mark.slow
def test_ply_parses_back_with_the_right_vertex_count(report):
    res, _, _ = report
    gt_pts, gt_col = _read_ply(res / "clouds/room/v0/ground_truth.ply")
    assert gt_pts.shape == (W * H - 5, 3)  # the 5 sky pixels are dropped
    assert gt_col.dtype == np.uint8
    pts, col = _read_ply(res / "clouds/room/v0/deepflow-rect/average.ply")
    assert pts.shape == (W * H - 5 - 4, 3)  # sky and the 4 pixels without prediction dropped
    # points lie inside the box room (3 x 4 m half-widths, floor -1.2, ceiling 1.8) up to float32 rounding
    assert np.all(np.abs(gt_pts[:, 0]) <= 3.0 + 1e-4) and np.all(np.abs(gt_pts[:, 1]) <= 4.0 + 1e-4)
    assert gt_pts[:, 2].min() >= -1.2 - 1e-4 and gt_pts[:, 2].max() <= 1.8 + 1e-4
    header = (res / "clouds/room/v0/ground_truth.ply").read_bytes()[:400].decode("ascii", "replace")
    assert "format binary_little_endian 1.0" in header and "property uchar red" in header


def test_ply_roundtrip_and_nonfinite_points_dropped():
    pts = np.array([[0.0, 1.0, 2.0], [np.nan, 0, 0], [1.5, -2.0, 0.25], [np.inf, 1, 1]])
    col = np.array([[255, 0, 0], [1, 2, 3], [0, 128, 255], [4, 5, 6]], dtype=np.uint8)
    raw, n = ply_bytes(pts, col)
    assert n == 2
    back, bcol = parse_ply(raw)
    np.testing.assert_array_equal(back, pts[[0, 2]].astype(np.float32))
    np.testing.assert_array_equal(bcol, col[[0, 2]])
    assert raw.startswith(b"ply\nformat binary_little_endian 1.0\n")
    assert len(raw) - raw.index(b"end_header\n") - len(b"end_header\n") == 2 * 15


def test_point_grid_recovers_distance():
    d = box_room_distance(W, H)
    pts = point_grid(d, np.array([1.0, -2.0, 0.5]), np.eye(3))
    np.testing.assert_allclose(np.linalg.norm(pts - [1.0, -2.0, 0.5], axis=-1), d, rtol=1e-12)
    assert np.isnan(point_grid(np.full((2, 4), np.inf), np.zeros(3), np.eye(3))).all()


@pytest.mark.slow
def test_variant_mae_table_reduction_against_average(report):
    res, outcome, _ = report
    results = pd.read_csv(res / "results.csv")
    table = pd.read_csv(res / "mae.csv")
    for flow, rect in CONFIGS:
        sel = results[(results["flow"] == flow) & (results["rectify"] == rect)].set_index("variant")["mae_m"]
        mine = table[(table["flow"] == flow) & (table["rectify"] == rect) & (table["source"] == "tri360")]
        mine = mine.set_index("variant")
        for v in ("gradient", "color"):
            expect = 100 * (sel["average"] - sel[v]) / sel["average"]
            assert mine.loc[v, "room reduction_pct"] == pytest.approx(expect, abs=1e-9)  # percent
            assert mine.loc[v, "all mae_m"] == pytest.approx(sel[v], abs=1e-12)  # metres
            assert expect > 10  # noise 5 % and 4 % vs 8 %: a real reduction
            # the markdown shows the same number, 2 decimals, signed
            md_row = next(ln for ln in outcome.markdown.splitlines()
                          if ln.startswith(f"| {mine.loc[v, 'configuration']} | {v} |"))
            assert f"{expect:+.2f} %" in md_row and f"{sel[v]:.5f}" in md_row
        assert np.isnan(mine.loc["average", "room reduction_pct"])
    # the CLI prints the leaderboard, then the MAE table
    assert outcome.markdown == (res / "leaderboard.md").read_text() + "\n" + (res / "mae.md").read_text()
    assert "deepflow-rect (paper set-up)" in outcome.markdown
    assert "dis-rect |" in outcome.markdown


@pytest.mark.slow
def test_paper_reference_rows(report):
    _, outcome, _ = report
    paper = [ln for ln in outcome.markdown.splitlines() if ln.startswith("| paper's figures")]
    assert len(paper) == 3
    assert "0.14337" in paper[0] and "0.10906" in paper[1] and "0.10902" in paper[2]
    assert "+23.93 %" in paper[1]  # (0.14337 - 0.10906) / 0.14337


def test_variant_mae_table_averages_frames_and_pairs_average():
    rows = []
    for vp, (a, g) in {"v0": (0.2, 0.1), "v1": (0.4, 0.3)}.items():
        for variant, mae in (("average", a), ("gradient", g)):
            rows.append({"scene": "s", "viewpoint": vp, "flow": "dis", "rectify": True, "variant": variant,
                         "mae_m": mae})
    rows.append({"scene": "t", "viewpoint": "v0", "flow": "dis", "rectify": True, "variant": "average",
                 "mae_m": 1.0})
    t = variant_mae_table(pd.DataFrame(rows)).set_index(["source", "variant"])
    assert t.loc[("tri360", "gradient"), "s mae_m"] == pytest.approx(0.2, abs=1e-12)
    assert t.loc[("tri360", "gradient"), "s reduction_pct"] == pytest.approx(100 * (0.3 - 0.2) / 0.3, abs=1e-9)
    # "all": gradient has no frame of scene t, so it is compared with average over the same two frames only
    assert t.loc[("tri360", "gradient"), "all reduction_pct"] == pytest.approx(100 * 0.1 / 0.3, abs=1e-9)
    assert t.loc[("tri360", "average"), "all mae_m"] == pytest.approx((0.2 + 0.4 + 1.0) / 3, abs=1e-12)
    assert np.isnan(t.loc[("tri360", "gradient"), "t mae_m"])


@pytest.mark.slow
def test_html_is_self_contained(report):
    res, _, _ = report
    text = (res / "report.html").read_text()
    p = _Collect()
    p.feed(text)
    # 3 summary figures + error maps (all methods), region masks and clouds per configuration
    assert len(p.imgs) == 3 + 2 + len(CONFIGS)
    assert all(src.startswith("data:image/png;base64,") for src in p.imgs)
    plys = [h for h in p.links if h.endswith(".ply")]
    assert len(plys) == 1 + len(CONFIGS) * len(VARIANTS)
    assert all((res / h).is_file() for h in plys)
    assert not re.search(r'(src|href)="(https?:)?//', text)  # nothing fetched from the network
    assert "0.14337" in text and "paper" in text
    assert text.count("<script>") == 1 and 'table class="sortable" id="leaderboard"' in text


@pytest.mark.slow
def test_ply_paper_only_and_none(tmp_path):
    res = make_results(tmp_path)
    (res / "breakdown.csv").unlink()  # not needed here; saves two plots
    build_report(res, ply="paper", cloud_points=100)
    assert sorted(p.relative_to(res).as_posix() for p in res.rglob("*.ply")) == sorted(
        ["clouds/room/v0/ground_truth.ply"] + [f"clouds/room/v0/deepflow-rect/{v}.ply" for v in VARIANTS])
    for p in res.rglob("*.ply"):
        p.unlink()
    build_report(res, ply="none", cloud_points=100)
    assert not list(res.rglob("*.ply"))


@pytest.mark.slow
def test_missing_map_and_frame_are_reported_not_fatal(tmp_path):
    res = make_results(tmp_path)
    (res / "maps/room/v0/dis-rect/color.distance.exr").unlink()
    (res / "regions.csv").unlink()
    (res / "breakdown.csv").unlink()
    out = build_report(res, ply="none", cloud_points=100)
    assert any("color.distance.exr" in p and "missing" in p for p in out.problems)
    assert any("breakdown.csv" in p for p in out.problems)
    assert any("regions.csv" in p and "per-region" in p for p in out.problems)
    assert out.leaderboard["mae_textureless"].isna().all()  # no regions.csv: empty region columns
    assert "color.distance.exr" in (res / "report.html").read_text()
    frames = json.loads((res / "frames.json").read_text())
    frames[0]["path"] = str(tmp_path / "moved")
    (res / "frames.json").write_text(json.dumps(frames))
    out = build_report(res, ply="none", cloud_points=100)
    assert any("could not be read" in p and "moved" in p for p in out.problems)
    assert (res / "mae.md").is_file()


# ------------------------------------------------------------------------------------------------- errors


def test_missing_and_empty_results_dir(tmp_path):
    with pytest.raises(UserError, match="does not exist"):
        build_report(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(UserError, match="empty"):
        build_report(tmp_path / "empty")
    (tmp_path / "file").write_text("x")
    with pytest.raises(UserError, match="not a directory"):
        build_report(tmp_path / "file")


def _write_csv(path: Path, header, rows):
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


GOOD = ["room", "v0", 64, 32, "dis-plain:average", "dis", "False", "average", 0.1, 0.2, 0.05, 0.03, 0.9, 0.1, 2000,
        1.0]


@pytest.mark.parametrize(("header", "rows", "message"), [
    (RESULT_COLUMNS, [], "no data rows"),
    ([c for c in RESULT_COLUMNS if c != "mae_m"], [GOOD[:8] + GOOD[9:]], "missing column.*mae_m"),
    (RESULT_COLUMNS, [GOOD[:8] + ["abc"] + GOOD[9:]], "'mae_m' must be numeric.*'abc'.*row 1"),
    (RESULT_COLUMNS, [GOOD[:6] + ["maybe"] + GOOD[7:]], "'rectify' must be true/false"),
    (RESULT_COLUMNS, [GOOD, GOOD], "duplicate rows"),
    (RESULT_COLUMNS, [GOOD[:14] + ["12.5"] + GOOD[15:]], "'valid_px' must hold whole numbers"),
    (RESULT_COLUMNS, [GOOD[:4] + [""] + GOOD[5:]], "'method' is empty"),
])
def test_malformed_results_csv(tmp_path, header, rows, message):
    _write_csv(tmp_path / "r" / "results.csv", header, rows)
    with pytest.raises(UserError, match=message) as info:
        build_report(tmp_path / "r")
    assert "results.csv" in str(info.value)


def test_results_csv_missing_or_empty_file(tmp_path):
    (tmp_path / "r").mkdir()
    (tmp_path / "r" / "frames.json").write_text("[]")
    with pytest.raises(UserError, match=r"results\.csv: file is missing"):
        build_report(tmp_path / "r")
    (tmp_path / "r" / "results.csv").write_text("")
    with pytest.raises(UserError, match=r"results\.csv: file is empty"):
        build_report(tmp_path / "r")


def test_names_stay_strings(tmp_path):
    row = ["007", "001"] + GOOD[2:]
    _write_csv(tmp_path / "r" / "results.csv", RESULT_COLUMNS, [row])
    df = read_results(tmp_path / "r")
    assert df.loc[0, "scene"] == "007" and df.loc[0, "viewpoint"] == "001"
    assert df.loc[0, "rectify"] is False or df.loc[0, "rectify"] == False  # noqa: E712 (numpy bool)


@pytest.mark.slow
def test_cli_prints_the_table(tmp_path, capsys):

    res = make_results(tmp_path)
    assert main(["report", str(res), "--ply", "none", "--cloud-points", "50"]) == 0
    printed = capsys.readouterr().out
    assert "| deepflow-rect (paper set-up) | gradient |" in printed
    assert "report.html" in printed
    assert main(["report", str(tmp_path / "missing")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_cloud_sections_sample_the_right_pixels(tmp_path):

    frame = make_frame(tmp_path / "data")
    idx, (top, side) = section_sample(frame, 200)
    b = bearing_grid(W, H).reshape(-1, 3)[idx]
    limit = np.sin(np.radians(SECTION_HALF_ANGLE_DEG))
    assert top.sum() == 100 and side.sum() == 100
    assert np.all(np.abs(b[top, 2]) < limit) and np.all(np.abs(b[side, 1]) < limit)
    assert np.isfinite(frame.distance["C"].ravel()[idx]).all()  # sky pixels are never drawn
    again, _ = section_sample(frame, 200)
    np.testing.assert_array_equal(idx, again)  # seeded


def test_malformed_breakdown_and_frames_json(tmp_path):
    _write_csv(tmp_path / "r" / "results.csv", RESULT_COLUMNS, [GOOD])
    (tmp_path / "r" / "frames.json").write_text('{"scene": "room"}')
    with pytest.raises(UserError, match=r"frames\.json: must be a JSON list"):
        build_report(tmp_path / "r")
    (tmp_path / "r" / "frames.json").write_text("[{")
    with pytest.raises(UserError, match=r"frames\.json: not valid JSON"):
        build_report(tmp_path / "r")
    (tmp_path / "r" / "frames.json").unlink()
    _write_csv(tmp_path / "r" / "breakdown.csv", ["scene", "kind"], [["room", "distance"]])
    with pytest.raises(UserError, match=r"breakdown\.csv: missing column"):
        build_report(tmp_path / "r")


def test_results_set_round_trip_and_maps_layout(tmp_path):
    """harness.data.results writes what it reads back (schema types), and lays out the maps of both kinds of
    method (the one layout evaluate writes and report reads)."""
    row = dict(zip(RESULT_COLUMNS, GOOD, strict=False))
    row.update({"rectify": False, "mae_m": 0.1})
    other = {**row, "method": "sweep", "flow": "", "rectify": "", "variant": ""}
    written = write_results(tmp_path / "r", results_table([row, other]), frames=[], config={"methods": {}})
    assert [p.name for p in written] == ["results.csv", "results.json", "frames.json", "config.json"]
    back = read_results(tmp_path / "r")
    assert back.loc[0, "rectify"] == False and back.loc[1, "rectify"] == ""  # noqa: E712 (numpy bool)
    assert back["valid_px"].dtype == np.int64 and np.isnan(back.loc[0, "ause"])
    assert json.loads((tmp_path / "r" / "results.json").read_text())[0]["ause"] is None  # strict JSON
    assert [p.as_posix() for p in map_paths("s", "v", "dis-plain:color", "dis", False, "color")] == [
        "maps/s/v/dis-plain/color.distance.exr", "maps/s/v/dis-plain/color.confidence.exr"]
    assert [p.as_posix() for p in map_paths("s", "v", "sweep")] == [
        "maps/s/v/sweep/distance.exr", "maps/s/v/sweep/confidence.exr"]
