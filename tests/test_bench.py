"""The bench's comparison machinery (``harness.bench``) on a tiny frame: not speed, only that the vectorised LM
and the per-pixel scipy solve are compared on the pipeline's own problem and agree.

Tolerance: ``AGREE_TOL_M`` = 1e-4 m, the bench's own "same result" criterion.  On the geometric variants
both solvers reach the smooth per-pixel minimum to ~1e-8 m, so every pixel must agree.  The colour term's
cost is a staircase in d (cv2.remap quantises sample positions to 1/32 px), so there the two local solvers
may stop on neighbouring stairs or kinks; at 64 px wide one stair is centimetres, and 76-92 % of 50 pixels
agree within 1e-4 m (seeds 0-2), the rest within 6 mm.  So there: at least 70 % agree and none differs by more
than 2 cm (a real bug — wrong Jacobian sign, wrong pixel, wrong problem — moves them by decimetres).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import make_synthetic_frame

from harness import bench
from reconstruction.pipeline import reconstruct
from reconstruction.refine import VARIANTS
from reconstruction.spherical import sample_equirect


@pytest.fixture(scope="module")
def tiny():
    frame = make_synthetic_frame(64)
    return frame, bench.prepare(frame)


def test_replayed_problem_is_the_pipelines(tiny):
    frame, prep = tiny
    result = reconstruct(frame)
    for name, config in VARIANTS.items():
        problem, refined = bench.variant_problem(frame, prep, config)
        d, _, _ = bench.run_vectorised(problem, prep.d0, prep.limits, config)
        filled = bench.fill_invalid(d.reshape(frame.height, frame.width), refined.reshape(frame.height, frame.width))
        np.testing.assert_allclose(filled.astype(np.float32), result.distance[name], atol=1e-5, err_msg=name)


def test_subproblem_keeps_each_pixels_result(tiny):
    frame, prep = tiny
    for name, config in VARIANTS.items():
        problem, refined = bench.variant_problem(frame, prep, config)
        idx = np.flatnonzero(refined)[::7]
        d_all, _, _ = bench.run_vectorised(problem, prep.d0, prep.limits, config)
        d_sub, _, _ = bench.run_vectorised(bench.subproblem(problem, idx), prep.d0[idx], prep.limits, config)
        np.testing.assert_allclose(d_sub, d_all[idx], rtol=0, atol=1e-12, err_msg=name)


@pytest.mark.parametrize("name", list(VARIANTS))
def test_vectorised_lm_agrees_with_per_pixel_scipy(tiny, name):
    frame, prep = tiny
    config = VARIANTS[name]
    problem, refined = bench.variant_problem(frame, prep, config)
    rng = np.random.default_rng(0)
    idx = np.sort(rng.choice(np.flatnonzero(refined), size=50, replace=False))
    d_vec, _, _ = bench.run_vectorised(problem, prep.d0, prep.limits, config)
    d_sp, seconds = bench.run_scipy(problem, prep.d0, idx, prep.limits, progress=False)
    assert seconds > 0
    # the solvers really moved: otherwise agreement would be trivial
    assert np.abs(d_sp - prep.d0[idx]).max() > 1e-3
    share, worst = bench.agreement(d_vec[idx], d_sp)
    if config.color_weight > 0:
        assert share >= 0.7 and worst < 0.02, (share, worst)
    else:
        assert share == 1.0 and worst <= bench.AGREE_TOL_M, (share, worst)


def test_scipy_pixel_solves_a_known_minimum(tiny):
    frame, prep = tiny
    config = VARIANTS["angle"]
    problem, refined = bench.variant_problem(frame, prep, config)
    i = int(np.flatnonzero(refined)[len(np.flatnonzero(refined)) // 2])
    d, nfev = bench.scipy_pixel(problem, i, 1.7 * prep.d0[i], prep.limits.d_min_m, prep.limits.d_max_m)
    r, jac = problem.residuals(np.array([d]), np.array([i]))
    assert nfev >= 2 and abs(float((r * jac).sum())) < 1e-8  # stationary point of the cost


def test_bilinear_exact_matches_opencv_to_its_quantisation():
    rng = np.random.default_rng(1)
    img = rng.random((12, 24, 3)).astype(np.float32)
    u = rng.uniform(-3, 30, 200)
    v = rng.uniform(-1, 12, 200)
    ours = bench.bilinear_exact(img, u, v)
    ref = sample_equirect(img, u, v)
    assert np.abs(ours - ref).max() < 1.0 / 32 + 1e-3  # OpenCV snaps positions to 1/32 px


def test_main_prints_the_summary_line_last(tmp_path, capsys):
    assert bench.main(["--width", "32", "--subset", "5", "--frame", str(tmp_path), "--no-progress"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[-1].startswith("refine speedup vs per-pixel scipy: ") and lines[-1].endswith(" x")
    assert any("goals vs measured" in line for line in lines)
