"""The bench's comparison machinery (``tools.bench.pipeline``) on a tiny frame: not speed, only that the vectorised LM
and the per-pixel scipy solve are compared on the pipeline's own problem and agree.

Tolerance: ``AGREE_TOL_M`` = 1e-4 m, the bench's own "same result" criterion.  On the geometric stage both
solvers reach the smooth per-pixel minimum to ~1e-8 m, so every pixel must agree.  The colour term's cost is a
staircase in d (cv2.remap quantises sample positions to 1/32 px), so there the two local solvers may stop on
neighbouring stairs; at 64 px wide one stair is centimetres.  So there: at least 70 % agree and none differs by
more than 2 cm (a real bug -- wrong Jacobian sign, wrong pixel, wrong problem -- moves them by decimetres).
"""

from __future__ import annotations

import numpy as np
import pytest

from reconstruction.methods.flow_pipeline import DEFAULT_FLOW
from reconstruction.methods.flow_refine import variant_problem
from reconstruction.methods.flow_stages import prepare
from reconstruction.refine.lm import discover_variants
from tests.helpers import make_synthetic_frame
from tools import common
from tools.bench import pipeline as bench
from tools.bench import render as bench_render


@pytest.fixture(scope="module")
def tiny():
    frame = make_synthetic_frame(64)
    return frame, prepare(frame, DEFAULT_FLOW)


VARIANTS = discover_variants()[0]
#: the variants with a colour term: seconds each against scipy (marked ``slow``)
COLOUR_VARIANTS = {name for name, v in VARIANTS.items() if v.color_weight > 0}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in COLOUR_VARIANTS else n
                                  for n in sorted(VARIANTS)])
def test_vectorised_lm_agrees_with_per_pixel_scipy(tiny, name):
    frame, prep = tiny
    res = bench.compare_variant(frame, prep, VARIANTS[name], subset=50, rng=np.random.default_rng(0), progress=False)
    geo = res["stages"]["geometric"]
    assert geo["m"] == 50 and geo["share"] == 1.0 and geo["worst"] < bench.AGREE_TOL_M
    if VARIANTS[name].color_weight > 0:
        col = res["stages"]["colour"]
        assert col["share"] >= 0.7 and col["worst"] < 0.02  # metres, see the module docstring


def test_scipy_pixel_solves_a_known_minimum(tiny):
    """One pixel, exact matches (oracle): scipy must land on the true distance."""
    frame, _ = tiny
    prep = prepare(frame, flow="oracle")

    problem, _ = variant_problem(frame, prep, VARIANTS["angle"])
    i = frame.width * (frame.height // 2) + 5
    d, _ = bench.scipy_pixel(problem, i, prep.d0[i] * 1.3, 0.05, 100.0)
    assert d == pytest.approx(float(frame.distance["C"].reshape(-1)[i]), abs=1e-6)  # metres


@pytest.mark.slow
def test_main_prints_the_summary_line_last(tmp_path, capsys):
    status = bench.main(["--width", "32", "--subset", "5", "--frame", str(tmp_path), "--no-progress"])
    out = capsys.readouterr().out
    lines = out.strip().splitlines()
    assert sum("[PASS]" in x or "[FAIL]" in x for x in lines) == 5
    assert status == (1 if "[FAIL]" in out else 0)  # a missed goal fails `make bench`
    assert lines[-1].startswith("refine speedup vs per-pixel scipy: ") and lines[-1].endswith(" x")
    assert any("goals vs measured" in line for line in lines)


@pytest.mark.slow
def test_render_bench_times_the_render_command_end_to_end_against_the_reference(capsys):
    """``bench_render`` runs ``tri360 render`` in new processes, the reference and the frame in turn (here both tiny
    ray-cast frames), and prints each time, the goal on the ratio of their medians and the range."""
    tiny = ["--scene", "box_room", "--renderer", "raycast", "--width", "64"]
    status = bench_render.main(["--repeats", "2", "--reference", " ".join(tiny), *tiny])
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith(f"render bench: `tri360 render {' '.join(tiny)}` against `tri360 render "
                               f"{' '.join(tiny)}`, 2 times each")
    assert [x.split(":")[0].strip() for x in lines[1:5]] == ["reference 1", "render 1", "reference 2", "render 2"]
    assert all("renderer s per camera: C " in x for x in lines[1:5])  # each frame's render_log.json was read
    (goal,) = [x for x in lines if "[PASS]" in x or "[FAIL]" in x]
    assert f"at most {bench_render.GOAL_RATIO:g} x the reference render's CPU time (medians, same run)" in goal
    assert status == (0 if "[PASS]" in goal else 1)  # a missed goal fails `make bench`
    assert lines[-1].startswith("render frame: ") and "over 2 renders (reference " in lines[-1]


def test_the_render_reference_pins_what_sets_cycles_cost():
    """The reference render's cost must not follow the render defaults: every setting that sets it is explicit."""
    args = bench_render.REFERENCE_ARGS
    assert all(option in args for option in ("--scene", "--width", "--samples", "--max-bounces", "--no-light-tree"))


def test_goals_status_fails_on_any_missed_goal():
    assert common.goals_status([True, True]) == 0
    assert common.goals_status([True, False]) == 1


def test_report_goals_prints_one_line_per_goal_and_fails_on_a_missed_one():
    lines = []
    assert common.report_goals([(True, "a <= 1"), (False, "b <= 2")], lines.append) == 1
    assert lines == ["  [PASS] a <= 1", "  [FAIL] b <= 2"]
    assert common.report_goals([(True, "a")], lines.append) == 0
