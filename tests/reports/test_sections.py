"""reports.sections: every part of the report built in memory, from DataFrames, frames and maps (no results
directory, no file written)."""

from __future__ import annotations

import numpy as np
import pytest

from reports.floor import frame_floor_sigma, region_floors
from reports.metrics import breakdown, pooled_sparsification_curves, summary
from reports.pointcloud import parse_ply
from reports.regions import region_summaries, regions
from reports.schema import breakdown_table, regions_table, results_table
from reports.sections import (
    OTHER_KEY,
    Part,
    breakdown_part,
    flow_mae_part,
    frame_part,
    leaderboard_part,
    report_html,
    sparsification_part,
)
from tests.reports.test_reports import H, W, box_room_frame

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def frame():
    return box_room_frame(sky_px=5)


def _methods(frame):
    """Two flow-pipeline variants of one configuration and one other method with a confidence map, on
    ``frame``: ``(rows by label, preds, confidences)`` with rows as in results.csv."""
    rng = np.random.default_rng(2)
    gt = frame.distance["C"]
    rows, preds, confs = {}, {}, {}
    for label, noise, fields in (("dis-rect:average", 0.08, ("dis", True, "average")),
                                 ("dis-rect:gradient", 0.04, ("dis", True, "gradient")),
                                 ("matcher", 0.03, ("", "", ""))):
        z = rng.standard_normal(gt.shape)
        preds[label] = np.abs(gt * (1 + noise * z)).astype(np.float32)
        rows[label] = {"scene": frame.scene, "viewpoint": frame.viewpoint, "method": label,
                       **dict(zip(("flow", "rectify", "variant"), fields, strict=True))}
        if label == "matcher":
            confs[label] = (-np.abs(z)).astype(np.float32)
    return rows, preds, confs


def _results(frame, rows, preds, confs):
    out, regs, bd = [], [], []
    masks = regions(frame)
    for label, row in rows.items():
        conf = confs.get(label)
        out.append({**row, "width": W, "height": H, **summary(preds[label], frame.distance["C"], conf),
                    "seconds": 0.1})
        regs.extend({**row, **r} for r in region_summaries(frame, preds[label], conf, masks=masks))
        bd.extend({**row, **b} for b in breakdown(frame, preds[label]))
    return results_table(out), regions_table(regs), breakdown_table(bd)


@pytest.mark.slow
def test_frame_part_holds_every_figure_and_cloud(frame):
    rows, preds, confs = _methods(frame)
    part = frame_part(frame, rows, preds, confs, ply="all", cloud_points=200, first=True)
    assert part.problems == []
    fig, clouds = "figures/room/v0", "clouds/room/v0"
    assert sorted(part.files) == sorted([f"{fig}/errors.png", f"{fig}/regions.png", f"{fig}/dis-rect.clouds.png",
                                         f"{fig}/{OTHER_KEY}.clouds.png", f"{clouds}/ground_truth.ply",
                                         f"{clouds}/dis-rect/average.ply", f"{clouds}/dis-rect/gradient.ply",
                                         f"{clouds}/matcher.ply"])
    assert all(part.files[k][:8] == PNG for k in part.files if k.endswith(".png"))
    pts, col = parse_ply(part.files[f"{clouds}/ground_truth.ply"])
    assert pts.shape == (W * H - 5, 3) and col.dtype == np.uint8  # the sky pixels are no points
    assert part.html.startswith('<h3 id="frame-room-v0">room / v0</h3>') and part.html.count("<img ") == 4
    assert 'href="clouds/room/v0/dis-rect/gradient.ply"' in part.html
    # the sparsification curve of the method with a confidence, weighted by the frame's scored pixels
    assert sorted(part.curves) == ["matcher"]
    fractions, curve, oracle, n_px = part.curves["matcher"]
    assert n_px == W * H - 5 and fractions.shape == curve.shape == oracle.shape == (21,)
    assert curve[0] == pytest.approx(summary(preds["matcher"], frame.distance["C"])["mae_m"], abs=1e-9)


@pytest.mark.slow
def test_frame_part_ply_choices_and_problems(frame):
    rows, preds, _ = _methods(frame)
    none = frame_part(frame, rows, preds, ply="none", cloud_points=100)
    assert not [k for k in none.files if k.endswith(".ply")] and "PLY point clouds" not in none.html  # not base64
    paper = frame_part(frame, rows, preds, ply="paper", cloud_points=100)  # no deepflow-rect here
    assert [k for k in paper.files if k.endswith(".ply")] == ["clouds/room/v0/ground_truth.ply"]
    with pytest.raises(ValueError, match="ply must be one of"):
        frame_part(frame, rows, preds, ply="some")
    no_gt = box_room_frame()
    no_gt.distance = {}
    empty = frame_part(no_gt, rows, preds)
    assert empty.html == "" and empty.files == {} and "has no ground truth" in empty.problems[0]
    no_masks = box_room_frame()
    del no_masks.distance["U"]  # region masks need U and R
    part = frame_part(no_masks, rows, preds, ply="none", cloud_points=100)
    assert "no region masks" in part.problems[0] and "figures/room/v0/regions.png" not in part.files
    assert "figures/room/v0/errors.png" in part.files  # the rest is still drawn


@pytest.mark.slow
def test_summary_parts_from_dataframes(frame):
    rows, preds, confs = _methods(frame)
    results, region_table, bd = _results(frame, rows, preds, confs)
    board = leaderboard_part(results, region_table, {"matcher": "sweep"})
    assert list(board.files) == ["leaderboard.csv", "leaderboard.md"]
    assert board.markdown == board.files["leaderboard.md"]
    assert board.table.set_index("method").loc["matcher", "kind"] == "sweep"
    assert 'id="leaderboard"' in board.html and "no regions.csv" not in board.html
    assert "no regions.csv: empty" in leaderboard_part(results).html
    flow = flow_mae_part(results)
    assert list(flow.files) == ["mae.md", "mae.csv", "fig4_mae.png"] and flow.files["fig4_mae.png"][:8] == PNG
    assert "| dis-rect | gradient |" in flow.markdown
    only_other = flow_mae_part(results[results["flow"] == ""])
    assert only_other.files == {} and only_other.markdown == "" and "no flow-pipeline method" in only_other.html
    plots = breakdown_part(bd)
    assert list(plots.files) == ["error_vs_angle.png", "error_by_distance_texture.png"]
    assert breakdown_part(None).files == {} and "No breakdown.csv" in breakdown_part(None).html
    assert sparsification_part({}).files == {}


@pytest.mark.slow
def test_leaderboard_part_shows_the_floor_or_says_there_is_none(frame):
    rows, preds, confs = _methods(frame)
    results, region_table, _ = _results(frame, rows, preds, confs)  # no floor columns: an older results set
    older = leaderboard_part(results, region_table)
    assert "These results carry no floor" in older.html and older.table["floor_m"].isna().all()
    floors = region_floors(frame_floor_sigma(frame), regions(frame))
    results["floor_m"] = floors["all"]
    results["mae_x_floor"] = results["mae_m"] / floors["all"]
    region_table["floor_m"] = region_table["region"].map(floors)
    part = leaderboard_part(results, region_table)
    assert "These results carry no floor" not in part.html
    assert f'<td class="text">floor (m)</td><td class="">{floors["all"]:.5f}</td>' in part.html
    board = part.table.set_index("method")
    assert board.loc["matcher", "floor_m"] == pytest.approx(floors["all"], rel=1e-12)  # one frame: its floor
    ratio = board.loc["matcher", "mae_m"] / floors["all"]
    assert board.loc["matcher", "mae_x_floor"] == pytest.approx(ratio, rel=1e-12)
    assert f"| matcher | — | 1 | {board.loc['matcher', 'mae_m']:.5f} | {ratio:.2f} |" in part.markdown
    curves = {"matcher": pooled_sparsification_curves([frame_part(frame, rows, preds, confs, ply="none",
                                                                   cloud_points=50).curves["matcher"]])}
    spars = sparsification_part(curves)
    assert list(spars.files) == ["sparsification.png"] and spars.files["sparsification.png"][:8] == PNG
    # the AUSE of the pooled curve (one frame) is the results' ause
    assert curves["matcher"]["ause"] == pytest.approx(float(results.set_index("method").loc["matcher", "ause"]),
                                                      abs=1e-9)


def test_report_html_puts_the_parts_in_order(frame):
    rows, preds, confs = _methods(frame)
    results, _, _ = _results(frame, rows, preds, confs)
    parts = {name: Part(html=f"<h2>{name}</h2>") for name in ("leaderboard", "sparsification", "flow", "breakdown")}
    page = report_html(results, ["a problem <here>"], **parts, frames=[Part(html="<h3>f1</h3>"), Part()],
                       source="RESULTS", generated="2026-01-01 00:00:00")
    order = [page.index(x) for x in ("a problem &lt;here&gt;", "<h2>leaderboard", "<h2>sparsification", "<h2>flow",
                                     "<h2>breakdown", "<h3>f1</h3>", "<h2>All results</h2>")]
    assert order == sorted(order)
    assert "results: RESULTS" in page and "generated 2026-01-01 00:00:00" in page
    assert "1 frame(s), 3 method(s): dis-rect:average, dis-rect:gradient, matcher" in page
    empty = report_html(results, [], **parts, frames=[Part()], source="R", generated="now")
    assert "No frames could be shown" in empty and "Problems" not in empty
