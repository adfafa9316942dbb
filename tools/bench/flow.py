"""Benchmark of DeepMatching and DeepFlow as published at 1000x500: time and peak memory per pair and per frame.

Run as ``python -m tools.bench.flow`` (``make bench``).  On a frame (``--frame DIR``, or a synthetic_box
frame rendered by the numpy ray-caster) it runs, each in a fresh child process so that its peak RSS is its own:

1. DeepMatching of the plain equirect C-R pair, both directions with the reciprocal check
   (:func:`reconstruction.flow.deepmatching.deep_matching_both`);
2. DeepFlow's variational part for that pair, both directions at once given those matches
   (:func:`reconstruction.flow.deepflow.deep_flow_both`);
3. the whole ``deepflow`` flow stage of a frame as the paper's set-up runs it: both pairs (C-U, C-R), forward and
   backward flow, rectified (:func:`reconstruction.flow.matching.match_pair`);
4. the same flow stage with ``dis`` (tri360's own flow pipeline, ``dis-rect``);
5. the methods ``deepflow-rect:gradient`` (the paper's set-up after optimisation) and ``dis-rect:gradient`` on the
   frame, each timed as ``tri360 evaluate`` times it (its ``seconds``: flows, triangulation, LM), on a second run
   in the same child (the first compiles or loads every kernel).

It prints each figure (wall and CPU seconds: on a shared machine the CPU time over the core count is the better
estimate of the time on free cores), the goals as ``[PASS]`` / ``[FAIL]`` lines, and exits with status 1 when a goal
fails.  The first run also compiles the numba kernels (cached on disk afterwards); a warm-up on a small frame in each
child keeps compilation out of the figures.  Goals, each with what it protects:

- a frame's ``deepflow`` flow stage (3.) within ``--max-reference-ratio`` (:data:`GOAL_REFERENCE_RATIO`) x the
  reference computation timed in the same child just before and after it (the mean of the two;
  :func:`tools.bench.pipeline.reference_seconds`: OpenCV's DIS optical flow on the same frame, once on one thread and
  once on all): DeepFlow as published stays usable on a full frame.  It replaces "at most 60 s", which was met by
  8 % on an idle 2-core machine (55.6 s) and missed on a busier day (67.7 s): against a reference timed on the same
  machine in the same minute, the machine's speed and most of its load cancel.  On the 2-core AMD EPYC where 60 s
  was set the reference takes about 0.76 s idle, so the goal is 60 s / 0.76 s; today's code measured 19 x there
  (28.4 s against 1.48 s, 2026-12-04, load about 3 from other jobs);
- ``deepflow-rect:gradient``'s seconds within ``--max-ratio`` (8) x ``dis-rect:gradient``'s in the same run: the
  paper's set-up costs at most 8 x tri360's flow pipeline per frame (a ratio already);
- the ``deepflow`` flow stage's peak memory within ``--max-gb`` (4 GB; measured 1.07-1.19 GB): memory does not depend
  on the machine's speed, so this stays absolute.
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("bench_flow")

import argparse
import json
import multiprocessing as mp
import resource
import sys
import tempfile
import time
from pathlib import Path

from reconstruction.flow.deepflow import DeepFlowParams, deep_flow, deep_flow_both
from reconstruction.flow.deepmatching import DeepMatchingParams, deep_matching_both
from reconstruction.flow.matching import match_pair
from reconstruction.methods.base import run_methods
from reconstruction.methods.registry import get_methods
from tools.bench.pipeline import reference_seconds
from tools.common import ArgumentParser, load_or_render_frame, report_goals

PAIRS = ("U", "R")
METHODS = ("deepflow-rect:gradient", "dis-rect:gradient")
GOAL_REFERENCE_RATIO = 79.0  # a frame's deepflow flow stage over the reference computation (module docstring)


def _child(stage: str, frame_dir: str, width: int, queue) -> None:
    frame, _ = load_or_render_frame(Path(frame_dir), width)
    a, b = frame.images["C"], frame.images["R"]
    small = (a[::8, ::8].copy(), b[::8, ::8].copy())  # warm-up: numba compiles (or loads its cache) here
    m_small = deep_matching_both(*small, DeepMatchingParams())[0]
    deep_flow(*small, DeepFlowParams(), matches=m_small)
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 ** 2
    start, cpu = time.perf_counter(), time.process_time()
    if stage == "deepmatching":
        fwd, bwd = deep_matching_both(a, b, DeepMatchingParams())
        info = {"matches": int(fwd.x0.size), "matches_back": int(bwd.x0.size)}
    elif stage in METHODS:
        method = get_methods([stage])
        run_methods(frame, method)  # compiles or loads every kernel the method uses
        start, cpu = time.perf_counter(), time.process_time()
        out = run_methods(frame, method)[stage]
        info = {"method_seconds": out.total_seconds}
    elif stage == "deepflow":
        m = deep_matching_both(a, b, DeepMatchingParams())
        start, cpu = time.perf_counter(), time.process_time()  # the variational part alone
        deep_flow_both(a, b, DeepFlowParams(), matches=m)
        info = {}
    else:  # "frame" (deepflow) or "dis": a frame's flow stage
        if stage == "frame":  # between two timings of the reference computation
            before = reference_seconds(frame)
            start, cpu = time.perf_counter(), time.process_time()
        flow = "dis" if stage == "dis" else "deepflow"
        info = {k: match_pair(frame, k, flow, rectify=True).seconds for k in PAIRS}
    seconds, cpu_s = time.perf_counter() - start, time.process_time() - cpu
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 ** 2  # KiB on Linux -> GB
    if stage == "frame":
        info["reference_s"] = (before + reference_seconds(frame)) / 2
    queue.put({"seconds": seconds, "cpu_s": cpu_s, "peak_gb": peak, "warmup_peak_gb": base, **info})


def run_stage(stage: str, frame_dir: Path, width: int) -> dict:
    """One stage in a fresh process; returns its seconds and peak RSS (GB)."""
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    proc = ctx.Process(target=_child, args=(stage, str(frame_dir), width, q))
    proc.start()
    result = q.get()
    proc.join()
    if proc.exitcode != 0:
        raise SystemExit(f"error: bench_flow stage {stage} failed (exit {proc.exitcode})")
    return result


def main(argv=None) -> int:
    ap = ArgumentParser(prog="python -m tools.bench.flow", description=__doc__,
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frame", type=Path, default=None,
                    help="a frame directory or a cache root holding one of --width (default: render a synthetic_box "
                         "frame into a temporary directory)")
    ap.add_argument("--width", type=int, default=1000, help="frame width, pixels (default 1000)")
    ap.add_argument("--max-reference-ratio", type=float, default=GOAL_REFERENCE_RATIO,
                    help="goal: a frame's deepflow flow stage over the reference computation timed beside it "
                         "(%(default)g)")
    ap.add_argument("--max-ratio", type=float, default=8.0,
                    help=f"goal: {METHODS[0]}'s seconds per frame over {METHODS[1]}'s in the same run (8)")
    ap.add_argument("--max-gb", type=float, default=4.0, help="goal: the deepflow flow stage's peak memory, GB (4)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="tri360-bench-flow-") as tmp:
        return _run(args, Path(tmp) if args.frame is None else args.frame)


def _run(args, root: Path) -> int:
    frame, how = load_or_render_frame(root, args.width)  # renders once; the children reuse it
    frame_dir = frame.path
    print(f"tri360 bench_flow: {frame.scene}/{frame.viewpoint} {frame.width}x{frame.height} ({how})", flush=True)
    res = {}
    for stage in ("deepmatching", "deepflow", "frame", "dis", *METHODS):
        res[stage] = run_stage(stage, frame_dir, args.width)
        r = res[stage]
        extra = {k: v for k, v in r.items() if k not in ("seconds", "cpu_s", "peak_gb", "warmup_peak_gb")}
        print(f"  {stage:<22s} {r['seconds']:8.2f} s wall, {r['cpu_s']:8.2f} s CPU (all threads), peak RSS "
              f"{r['peak_gb']:.2f} GB  {json.dumps(extra)}", flush=True)
    fr, dis = res["frame"], res["dis"]
    print(f"  flow stages: deepflow / dis = {fr['seconds'] / max(dis['seconds'], 1e-9):.1f} x", flush=True)
    slow, fast = (res[m]["method_seconds"] for m in METHODS)
    ratio = slow / max(fast, 1e-9)
    ref_ratio = fr["seconds"] / fr["reference_s"]
    goals = [(ref_ratio <= args.max_reference_ratio,
              f"frame deepflow flow (2 pairs, both ways) {fr['seconds']:.1f} s / reference {fr['reference_s']:.2f} s "
              f"= {ref_ratio:.0f} x <= {args.max_reference_ratio:g} x"),
             (ratio <= args.max_ratio, f"{METHODS[0]} {slow:.1f} s / {METHODS[1]} {fast:.1f} s per frame "
                                       f"= {ratio:.1f} x <= {args.max_ratio:g} x"),
             (fr["peak_gb"] <= args.max_gb,
              f"the deepflow flow stage's peak RSS {fr['peak_gb']:.2f} GB <= {args.max_gb:g} GB")]
    return report_goals(goals)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "bench_flow"))
