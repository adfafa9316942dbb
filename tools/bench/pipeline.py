"""Benchmark of the reconstruction pipeline at 1000x500: stage times, peak memory, vectorised LM vs scipy.

Run as ``python -m tools.bench.pipeline`` (``make bench``).  It

1. makes (or reuses, ``--frame DIR``) a synthetic_box frame with exact ground truth, rendered by the numpy
   ray-caster in a child process (so the renderer's memory does not count towards the peak);
2. runs :func:`reconstruction.methods.flow_pipeline.reconstruct` once for the default flow, rectified, with every
   variant (its peak memory is read right after it); then ``--rounds`` staged replays of that call (the flows and
   triangulation of :func:`~reconstruction.methods.flow_stages.prepare`, then each refinement variant), timing the
   reference computation (:func:`reference_seconds`: OpenCV's DIS optical flow, C to R and back on the plain
   images) right before ``prepare`` and before each variant, and prints every stage's median and each variant's
   median ratio to its reference; DeepFlow (the paper's flow) is timed once per pair for comparison;
3. for each refinement variant, builds exactly the per-pixel problem the pipeline builds, runs the
   vectorised :func:`reconstruction.refine.lm.levenberg_marquardt` over all pixels, and a plain per-pixel
   :func:`scipy.optimize.least_squares` loop (trf, bounds [d_min, d_max], tolerances 1e-12, Jacobian from
   the same ``problem.residuals``) over a seeded random subset of the refined pixels, extrapolated to all
   of them; reports the speedup and the agreement (share of subset pixels with |d_vec - d_scipy| <= 1e-4 m)
   and, where the two disagree, which one found the lower cost and whether more LM iterations help;
4. prints the goals as ``[PASS]`` / ``[FAIL]`` lines and, as its last line, ``refine speedup vs per-pixel scipy:
   N x``; exits with status 1 when a goal is missed (:func:`tools.common.goals_status`).

Goals, each with what it protects:

- each refinement variant at most :data:`GOAL_VARIANT_RATIO` x the reference computation timed right before it
  (median over the rounds): the refinement (the paper's optimisation) stays cheap.  It replaces "at most 1 s at
  1000x500", which ``color-patch`` met by 2-20 % on an idle 2-core machine (0.80-0.98 s) and missed on slower or
  busier ones (1.16-2.6 s; 1.23 s on a fresh Intel Xeon): the reference is timed on the same images, in the same
  process, seconds before, so the speed of the machine and most of its load cancel.  On the 2-core AMD EPYC where
  1 s was set the reference takes about 0.76 s idle, so 1 s was 1.3 x; ``color-patch``, the slowest, measured
  1.06-1.25 x there (2026-12-04, load 1.5-4 from other jobs).  1.5 x leaves a fifth for the noise of a shared
  machine, and a variant 1.3 x slower than today fails it on any machine;
- the whole staged replay with all variants at most :data:`GOAL_TOTAL_RATIO` x the reference timed between its
  stages (median over the rounds): the whole flow pipeline, its own flow included, stays cheap.  It is "reconstruct()
  at most 10 s" on that machine (10 s / 0.76 s); measured 5.1-6.0 x;
- at least :data:`GOAL_SPEEDUP` x faster than per-pixel scipy (extrapolated, same process): the LM stays
  vectorised (a ratio already);
- the same result as per-pixel scipy on at least :data:`GOAL_AGREE` of the subset pixels: the speed is not bought
  with accuracy;
- peak resident memory after ``reconstruct()`` at most :data:`GOAL_PEAK_MB` (measured 537-550 MB): memory does not
  depend on the machine's speed, and the margin is large, so this stays absolute.

Timings are wall-clock on a possibly shared machine: every stage is printed beside the reference.
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("bench")

import resource
import sys
import time
from pathlib import Path

import cv2
import numpy as np
from scipy.optimize import least_squares

from harness.runtime.progress import track
from reconstruction.camera.image_ops import grey
from reconstruction.flow.matching import match_pair
from reconstruction.methods.flow_pipeline import DEFAULT_FLOW, reconstruct
from reconstruction.methods.flow_refine import color_texture_mask, refine_variant, variant_problem
from reconstruction.methods.flow_stages import PAIRS, prepare
from reconstruction.methods.registry import PAPER_CONFIG
from reconstruction.refine.lm import RefineConfig, RefineProblem, discover_variants, levenberg_marquardt
from reconstruction.refine.triangulate import TriangulationLimits
from tools.common import ArgumentParser, load_or_render_frame, report_goals

__all__ = ["AGREE_TOL_M", "reference_seconds", "run_vectorised", "scipy_pixel", "run_scipy", "agreement", "costs",
           "compare_variant", "main"]

AGREE_TOL_M = 1e-4  # |d_vec - d_scipy| counted as "the same result", metres
GOAL_AGREE = 0.999  # share of subset pixels that must agree
GOAL_VARIANT_RATIO = 1.5  # each refinement variant's seconds over the reference's timed before it (docstring)
GOAL_SPEEDUP = 100.0  # vectorised LM vs per-pixel scipy
GOAL_TOTAL_RATIO = 13.0  # the whole staged replay's seconds over the reference's timed between its stages
GOAL_PEAK_MB = 2048.0  # peak resident memory, MB
SCIPY_TOL = 1e-12  # xtol = ftol = gtol of the per-pixel scipy solve


def reference_seconds(frame) -> float:
    """Wall seconds of the reference computation: OpenCV's DIS optical flow (preset MEDIUM, down to full resolution,
    OpenCV's other settings) from C's grey image to R's and back, on the plain equirect images, once on one thread
    and once on all: a fixed amount of CPU work on the frame's data, which no tri360 setting changes (about 0.5 + 0.26
    s at 1000x500 on an idle 2-core AMD EPYC).  Half serial and half parallel, like the LM and the flows it is set
    against, so that its time follows both the speed of a core and whether a second one is free: with a parallel
    reference alone the ratios moved by 1.6 x between an idle and a busy machine, with a serial one by 1.4 x, with
    this one by 1.2 x."""
    c, r = (grey(frame.images[k]) for k in ("C", "R"))
    threads = cv2.getNumThreads()
    total = 0.0
    try:
        for n in (1, threads):
            cv2.setNumThreads(n)
            dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
            dis.setFinestScale(0)
            start = time.perf_counter()
            dis.calc(c, r, None)
            dis.calc(r, c, None)
            total += time.perf_counter() - start
    finally:
        cv2.setNumThreads(threads)
    return total


# ------------------------------------------------------------------------------- vectorised vs scipy


def run_vectorised(problem: RefineProblem, d0: np.ndarray, limits: TriangulationLimits, max_iters: int,
                   tol: float, only: np.ndarray | None = None):
    """``(d, iterations, seconds)`` of one vectorised LM solve over all (or ``only``) pixels."""
    start = time.perf_counter()
    d, iters = levenberg_marquardt(problem, d0, limits.d_min_m, limits.d_max_m, max_iters, tol, only=only)
    return d, iters, time.perf_counter() - start


# --------------------------------------------------------------------------------------- per-pixel scipy


def scipy_pixel(problem: RefineProblem, i: int, x0: float, d_min: float, d_max: float, tol: float = SCIPY_TOL):
    """Solve pixel ``i`` alone with scipy's trust-region reflective least squares.

    Residuals and Jacobian come from ``problem.residuals(d, [i])`` (one evaluation per distinct x).
    Returns:
        ``(d, nfev)``.
    """
    ii = np.array([i])
    cache: dict = {}

    def evaluate(x):
        key = float(x[0])
        if cache.get("x") != key:
            r, jac = problem.residuals(np.array([key]), ii)
            cache.update(x=key, r=r[0], J=jac[0][:, None])
        return cache

    x0 = float(np.clip(x0, d_min, d_max))
    res = least_squares(lambda x: evaluate(x)["r"], [x0], jac=lambda x: evaluate(x)["J"], bounds=(d_min, d_max),
                        method="trf", xtol=tol, ftol=tol, gtol=tol)
    return float(res.x[0]), int(res.nfev)


def run_scipy(problem: RefineProblem, d0: np.ndarray, idx: np.ndarray, limits: TriangulationLimits,
              desc: str = "scipy", progress: bool = True):
    """Per-pixel scipy over ``idx``: ``(d (len(idx),), seconds)``, with progress on stderr."""
    out = np.empty(len(idx))
    start = time.perf_counter()
    for j, i in enumerate(track(idx, desc=desc, unit="pixel", enabled=progress, leave=False, min_interval_s=5)):
        out[j], _ = scipy_pixel(problem, int(i), d0[i], limits.d_min_m, limits.d_max_m)
    return out, time.perf_counter() - start


def agreement(d_vec: np.ndarray, d_sp: np.ndarray, tol: float = AGREE_TOL_M):
    """``(share within tol, max |difference|)``."""
    diff = np.abs(np.asarray(d_vec) - np.asarray(d_sp))
    return float(np.mean(diff <= tol)), float(diff.max()) if diff.size else 0.0


def costs(problem: RefineProblem, d: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """(len(idx),) sum of squared residuals of pixels ``idx`` at distances ``d``."""
    r, _ = problem.residuals(np.asarray(d, np.float64), idx)
    return np.einsum("ij,ij->i", r, r)


def diagnose(problem: RefineProblem, idx: np.ndarray, d_vec: np.ndarray, d_sp: np.ndarray) -> list[str]:
    """Lines explaining the subset pixels where the vectorised LM and scipy disagree: which found the lower
    cost, and how many local minima a fine scan of the cost finds between the two solutions."""
    diff = np.abs(d_vec - d_sp)
    bad = diff > AGREE_TOL_M
    if not bad.any():
        return []
    c_vec, c_sp = costs(problem, d_vec, idx), costs(problem, d_sp, idx)
    lower_sp = bad & (c_sp < c_vec * (1 - 1e-9))
    lower_vec = bad & (c_vec < c_sp * (1 - 1e-9))
    lines = [f"    disagree: {bad.sum()} px; |diff| median {np.median(diff[bad]):.3g} m; scipy cost lower at "
             f"{lower_sp.sum()}, LM cost lower at {lower_vec.sum()}, equal at {(bad & ~lower_sp & ~lower_vec).sum()}"]
    mins = []
    for j in np.flatnonzero(bad)[:200]:
        grid = np.linspace(min(d_vec[j], d_sp[j]) - 2e-3, max(d_vec[j], d_sp[j]) + 2e-3, 2001)
        c = costs(problem, grid, np.full(grid.size, idx[j]))
        mins.append(int(((c[1:-1] < c[:-2]) & (c[1:-1] < c[2:])).sum()))
    lines.append(f"    cost scanned over 2001 distances spanning both solutions +- 2 mm: local minima per pixel "
                 f"median {np.median(mins):.0f}, max {max(mins)} (the colour cost is piecewise smooth: bilinear "
                 "interpolation has kinks at pixel boundaries)")
    return lines


def compare_variant(frame, prep, config: RefineConfig, subset: int, rng, progress: bool = True) -> dict:
    """Vectorised LM vs per-pixel scipy for one variant, stage by stage, from the same starting distances.

    Geometric stage: from ``prep.d0`` over every pixel with information.  Colour stage (colour variants):
    from the geometric solution over the textured pixels, both solvers run to convergence (the pipeline
    itself stops after ``config.color_iters``).  Returns a dict of timings, speedup and agreement.
    """
    limits = prep.limits
    problem, _ = variant_problem(frame, prep, config)
    color, problem.color = problem.color, []
    d_geo, iters, t_lm = run_vectorised(problem, prep.d0, limits, config.max_iters, config.tol_m)
    informed = np.flatnonzero(sum(problem.weights) > 0)
    stages = [("geometric", problem, prep.d0, d_geo, t_lm, informed, iters)]
    if color:
        cproblem, _ = variant_problem(frame, prep, config)
        textured = color_texture_mask(frame.images["C"], config).reshape(-1)
        d_col, iters_c, t_c = run_vectorised(cproblem, d_geo, limits, 200, config.tol_m, only=textured)
        stages.append(("colour", cproblem, d_geo, d_col, t_c, np.flatnonzero(textured), iters_c))
    out = {"stages": {}, "diag": []}
    for label, prob, start, d_vec, t_vec, cand, it in stages:
        idx = np.sort(rng.choice(cand, size=min(subset, cand.size), replace=False))
        d_sp, t_sp = run_scipy(prob, start, idx, limits, desc=f"scipy {config.name} {label}", progress=progress)
        share, worst = agreement(d_vec[idx], d_sp)
        t_full = t_sp / max(idx.size, 1) * cand.size
        out["stages"][label] = dict(lm=t_vec, iters=it, sp=t_sp, sp_full=t_full, speedup=t_full / t_vec,
                                    share=share, worst=worst, m=idx.size, n=cand.size)
        if share < GOAL_AGREE:
            out["diag"].append(f"  {config.name} ({label} stage):")
            out["diag"].extend(diagnose(prob, idx, d_vec[idx], d_sp))
    return out


# ------------------------------------------------------------------------------------------------- main


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: kilobytes


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(prog="python -m tools.bench.pipeline", description=__doc__.split("\n\n")[0])
    ap.add_argument("--width", type=int, default=1000, help="frame width in pixels (height = width / 2)")
    ap.add_argument("--subset", type=int, default=2000, help="pixels solved one by one with scipy per variant")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random scipy subset")
    ap.add_argument("--frame", type=Path, default=None,
                    help="frame directory, or cache root to reuse / render into (default: a temporary dir)")
    ap.add_argument("--rounds", type=int, default=3, help="staged replays timed, each after the reference (medians)")
    ap.add_argument("--no-progress", action="store_true", help="no progress on stderr")
    args = ap.parse_args(argv)
    if args.width < 8 or args.width % 2:
        ap.error("--width must be an even number >= 8")
    if args.rounds < 1:
        ap.error("--rounds must be >= 1")

    def out(line: str = "") -> None:
        print(line, flush=True)

    variants = discover_variants()[0]
    frame, how = load_or_render_frame(args.frame, args.width)
    out(f"tri360 bench: {frame.scene}/{frame.viewpoint} {frame.width}x{frame.height} ({how}); flow "
        f"{DEFAULT_FLOW}, rectified; variants {', '.join(variants)}")
    limits = TriangulationLimits()

    # the whole pipeline first (its peak memory is read right after it)
    start = time.perf_counter()
    result = reconstruct(frame, flow=DEFAULT_FLOW, rectify=True)
    total_s = time.perf_counter() - start
    peak_reconstruct = _peak_mb()

    # rounds of a staged replay, each stage right after a timing of the reference, so that both see the same load
    ref_s, staged, ratios, replay_ratios, iters, same = [], {}, {}, [], {}, {}
    for _ in range(args.rounds):
        round_ref = [reference_seconds(frame)]
        prep = prepare(frame, DEFAULT_FLOW, True, limits)
        for k, v in prep.seconds.items():
            staged.setdefault(k, []).append(v)
        for name, config in variants.items():
            round_ref.append(reference_seconds(frame))
            start = time.perf_counter()
            d, iters[name] = refine_variant(frame, prep, config)
            staged.setdefault(name, []).append(time.perf_counter() - start)
            ratios.setdefault(name, []).append(staged[name][-1] / round_ref[-1])
            same[name] = float(np.abs(d.astype(np.float32) - result.distance[name]).max())
        ref_s.extend(round_ref)
        replay_ratios.append(sum(v[-1] for v in staged.values()) / float(np.mean(round_ref)))
    med = {k: float(np.median(v)) for k, v in staged.items()}
    stage_s = {name: med[name] for name in variants}
    ratio = {name: float(np.median(ratios[name])) for name in variants}
    ref = float(np.median(ref_s))
    replay = float(np.median([sum(v[i] for v in staged.values()) for i in range(args.rounds)]))
    replay_ratio = float(np.median(replay_ratios))
    deep = {k: match_pair(frame, k, PAPER_CONFIG[0], PAPER_CONFIG[1]).seconds for k in PAIRS}

    out("")
    out(f"stage times, seconds (staged replay, median of {args.rounds} | inside reconstruct()):")
    out(f"  reference              {ref:8.3f} |        -   (OpenCV DIS both ways at full resolution, 1 thread + all; "
        f"{min(ref_s):.3f}-{max(ref_s):.3f} s)")
    for k in PAIRS:
        out(f"  flow {DEFAULT_FLOW} {k:<14s} {med[f'flow_{k}']:8.3f} | {result.seconds[f'flow_{k}']:8.3f}")
    for k in PAIRS:
        out(f"  flow {PAPER_CONFIG[0]} {k:<9s} {deep[k]:8.3f} |        - (the paper's set-up, for comparison; once)")
    out(f"  triangulate            {med['triangulate']:8.3f} | {result.seconds['triangulate']:8.3f}")
    out(f"  average                {med['average']:8.3f} | {result.seconds['average']:8.3f}")
    for name in variants:
        out(f"  {name:<22s} {stage_s[name]:8.3f} | {result.seconds[name]:8.3f}   ({ratio[name]:.2f} x the reference; "
            f"{iters[name]} LM iterations; max |replay - reconstruct| {same[name]:.2g} m)")
    out(f"  whole pipeline         {replay:8.3f} | {total_s:8.3f}   (reconstruct() with all of: average, "
        f"{', '.join(variants)})")

    rng = np.random.default_rng(args.seed)
    rows, diag_lines = {}, []
    for name, config in variants.items():
        res = compare_variant(frame, prep, config, args.subset, rng, progress=not args.no_progress)
        diag_lines.extend(res["diag"])
        for label, r in res["stages"].items():
            rows[f"{name}/{label}"] = r
    out("")
    out(f"vectorised LM vs per-pixel scipy least_squares (trf, bounds, tol {SCIPY_TOL:g}), same start, same residuals:")
    out(f"  {'variant/stage':<20s} {'LM s':>7s} {'it':>4s} {'scipy subset':>16s} {'scipy extrap.':>14s} "
        f"{'speedup':>9s} {'agree<=1e-4m':>13s} {'max |diff| m':>13s}")
    for key, r in rows.items():
        out(f"  {key:<20s} {r['lm']:7.3f} {r['iters']:4d} {r['sp']:8.2f} s/{r['m']:<5d}px {r['sp_full']:12.1f} s "
            f"{r['speedup']:8.0f}x {100 * r['share']:12.2f}% {r['worst']:13.3g}")
    out("  (subsets drawn from the pixels each stage solves; scipy time extrapolated to all of them; the colour "
        "stage of both solvers runs to convergence here)")
    if diag_lines:
        out("")
        out("disagreement analysis:")
        for line in diag_lines:
            out(line)

    peak = _peak_mb()
    out("")
    out(f"peak memory (ru_maxrss): {peak_reconstruct:.0f} MB after reconstruct(), {peak:.0f} MB whole bench")
    out("")
    out("goals vs measured:")
    slowest = max(ratio, key=ratio.get)
    slow = min(rows, key=lambda k: rows[k]["speedup"])
    low = min(rows, key=lambda k: rows[k]["share"])
    goals = [
        (ratio[slowest] <= GOAL_VARIANT_RATIO,
         f"each refinement variant <= {GOAL_VARIANT_RATIO:g} x the reference timed before it: slowest {slowest} "
         f"{ratio[slowest]:.2f} x ({stage_s[slowest]:.3f} s; median of {args.rounds})"),
        (rows[slow]["speedup"] >= GOAL_SPEEDUP,
         f">= {GOAL_SPEEDUP:g}x faster than per-pixel scipy: smallest {rows[slow]['speedup']:.0f}x ({slow})"),
        (rows[low]["share"] >= GOAL_AGREE,
         f"same result (>= {100 * GOAL_AGREE:g} % within {AGREE_TOL_M:g} m): lowest "
         f"{100 * rows[low]['share']:.2f} % ({low})"),
        (replay_ratio <= GOAL_TOTAL_RATIO,
         f"whole pipeline with all variants <= {GOAL_TOTAL_RATIO:g} x the reference timed between its stages: "
         f"{replay_ratio:.1f} x ({replay:.2f} s; median of {args.rounds})"),
        (peak_reconstruct <= GOAL_PEAK_MB,
         f"peak memory <= {GOAL_PEAK_MB / 1024:g} GB: {peak_reconstruct:.0f} MB (reconstruct), "
         f"{peak:.0f} MB (whole bench)"),
    ]
    status = report_goals(goals, out)
    smallest = min((r["speedup"] for r in rows.values()), default=float("nan"))
    out(f"refine speedup vs per-pixel scipy: {smallest:.0f} x")
    return status


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "bench"))
