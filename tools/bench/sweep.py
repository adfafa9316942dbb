"""Benchmark of the sweep-based methods: time of each stage at 1000x500 (median of 6 runs), the whole method's
time, and peak memory (RSS) at 1000x500 and 4000x2000, each run in a child process; beside it the same at
1000x500 for a comparison method, measured in the same run, and the goals.

    python -m tools.bench.sweep [--runs 6] [--big-width 4000] [--method LABEL] [--compare-with LABEL|none]

``--method`` is any registered label (default: the default method) or a fused method's label with ``-raw``
(:func:`reconstruction.methods.registry.uncalibrated`: no photometric self-calibration); ``--compare-with`` (default
``fused-mirror-raw``, the default's matching without self-calibration) is timed in the same run, one run of each
in turn, so that both see the same load.  Goals, printed as ``[PASS]`` / ``[FAIL]`` lines (exit status 1 when one
is missed):

- the method's wall time at 1000x500 at most :data:`GOAL_TIME_FACTOR` x the comparison method's in the same run:
  what the default adds to its matching (the self-calibration stage: a reduced flow pass, the rig and photometric
  fits and their tests) costs at most a tenth of it.  The runs are paired (one of each, back to back, which goes
  first alternating from pair to pair) and the goal reads the median of the pairs' ratios: a shared machine's speed
  drifts over minutes, a pair sees one speed, and the first of two back-to-back runs tends to be the slower
  (measured in docs/photometry.md).  Both are timed on the same machine in the same minutes, so no absolute time is
  needed;
- its peak RSS at 1000x500 at most :data:`GOAL_PEAK_GB`: a frame of the default size fits in the memory a
  ``--workers`` task is given (``harness.runtime.cluster.BASE_BYTES``, 1 GiB); measured 0.78-0.86 GB.  Memory does
  not depend on the machine's speed, so this stays absolute.

Each stage is reported as wall seconds and process CPU seconds (all threads): on a shared machine the wall time
is inflated by other jobs, the CPU time much less.

The frame is the ray-cast synthetic_box (vp000) at 1000x500; the 4000x2000 run upsamples its images (same poses),
which exercises the same memory as a native 4000x2000 frame.
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("bench_sweep")

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from reconstruction.methods.prior_sweep import PriorSweepMethod
from reconstruction.methods.registry import DEFAULT_METHOD, get_methods, uncalibrated
from tools.common import ArgumentParser, report_goals, synthetic_box_frame, user_error

BASE_WIDTH = 1000
GOAL_PEAK_GB = 1.0  # peak RSS of the method at 1000x500, GB
GOAL_TIME_FACTOR = 1.1  # the method's median wall time at 1000x500 over the comparison method's in the same run
DEFAULT_COMPARISON = f"{DEFAULT_METHOD}-raw"
#: the repository root, where ``python -m tools.bench.sweep`` finds ``tools``
ROOT = Path(__file__).resolve().parents[2]


def bench_method(label: str):
    """A registered method, or ``<fused label>-raw``: that method without photometric self-calibration."""
    if label.endswith("-raw"):
        base = get_methods([label[:-len("-raw")]])[0]
        if isinstance(base, PriorSweepMethod):
            return uncalibrated(base)
    return get_methods([label])[0]


def bench_frame(width: int):
    """The synthetic_box vp000 frame (:func:`tools.common.synthetic_box_frame`), ray-cast at 1000 wide without
    supersampling, images resized to ``width`` (H = width / 2)."""
    frame = synthetic_box_frame(BASE_WIDTH, "vp000", supersample=1)
    if width != BASE_WIDTH:
        interp = cv2.INTER_CUBIC if width > BASE_WIDTH else cv2.INTER_AREA
        frame.images = {k: cv2.resize(v, (width, width // 2), interpolation=interp) for k, v in frame.images.items()}
        frame.distance = {}
        frame.width, frame.height = width, width // 2
    return frame


def child(width: int, runs: int, method_name: str = DEFAULT_METHOD) -> None:
    """Run the method ``runs`` times on a ``width`` frame; print one JSON line with per-stage seconds per run
    (wall, and ``<stage>_cpu`` process CPU seconds) and the process's peak RSS (``peak_gb``)."""
    frame = bench_frame(width)
    method = bench_method(method_name)
    out = []
    for _ in range(runs):
        t, c = time.perf_counter(), time.process_time()
        res = method.run(frame)
        wall, cpu = time.perf_counter() - t, time.process_time() - c
        stage_cpu = {f"{k}_cpu": v for k, v in res.info.get("cpu_seconds", {}).items() if k != "total"}
        out.append({**res.seconds, **stage_cpu, "wall": wall, "wall_cpu": cpu})
    peak_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 ** 2  # ru_maxrss is KiB on Linux
    print(json.dumps({"width": width, "runs": out, "peak_gb": peak_gb}), flush=True)


def run_child(width: int, runs: int, method_name: str = DEFAULT_METHOD) -> tuple[dict, float]:
    """Run :func:`child` in a fresh process; returns its JSON result and its peak RSS in GB."""
    proc = subprocess.run([sys.executable, "-m", "tools.bench.sweep", "--child", str(width),
                           "--runs", str(runs), "--method", method_name],
                          capture_output=True, text=True, check=True, cwd=ROOT)
    line = [x for x in proc.stdout.splitlines() if x.startswith("{")][-1]
    res = json.loads(line)
    return res, float(res["peak_gb"])


def main(argv=None) -> int:
    ap = ArgumentParser(prog="python -m tools.bench.sweep", description=__doc__,
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=6,
                    help="timed runs (pairs, with a comparison) at 1000x500 (medians are reported)")
    ap.add_argument("--big-width", type=int, default=4000, help="width of the memory run (0 = skip)")
    ap.add_argument("--method", default=DEFAULT_METHOD,
                    help=f"the method to time, by label (default: {DEFAULT_METHOD}, what `tri360 reconstruct` runs)")
    ap.add_argument("--compare-with", default=DEFAULT_COMPARISON, metavar="LABEL",
                    help=f"method timed in the same run for the time goal (default: {DEFAULT_COMPARISON}, the default "
                         "without photometric self-calibration; 'none' = no comparison)")
    ap.add_argument("--baseline", dest="compare_with", help=argparse.SUPPRESS)  # the option's former spelling
    ap.add_argument("--child", type=int, default=0, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(args.child, args.runs, args.method)
        return 0
    try:
        for label in [args.method] + ([args.compare_with] if args.compare_with != "none" else []):
            bench_method(label)
    except ValueError as exc:
        return user_error("bench_sweep", exc)
    labels = [args.method] + ([args.compare_with] if args.compare_with not in ("none", args.method) else [])
    for label in labels:  # warm-up children: numba compiles (cache=True) once, so timed children measure steady state
        run_child(320, 1, label)
    runs: dict[str, list[dict]] = {label: [] for label in labels}
    peak: dict[str, float] = {label: 0.0 for label in labels}
    for i in range(args.runs):  # one run of each in turn, the order alternating: both see the same load and places
        for label in (labels if i % 2 == 0 else labels[::-1]):
            res, gb = run_child(BASE_WIDTH, 1, label)
            runs[label].extend(res["runs"])
            peak[label] = max(peak[label], gb)

    def med(label, key):
        return float(np.median([r.get(key, np.nan) for r in runs[label]]))

    for label in labels:
        stages = [k for k in runs[label][0] if k not in ("total", "wall") and not k.endswith("_cpu")]
        print(f"{label} at {BASE_WIDTH}x{BASE_WIDTH // 2}, median of {args.runs} runs (seconds, wall / CPU):")
        for k in stages:
            print(f"  {k:16s} {med(label, k):7.2f} / {med(label, k + '_cpu'):7.2f}")
        print(f"  {'method total':16s} {med(label, 'wall'):7.2f} / {med(label, 'wall_cpu'):7.2f}")
        print(f"peak RSS at {BASE_WIDTH}x{BASE_WIDTH // 2}: {peak[label]:.2f} GB")
    if args.big_width:
        big, peak_big = run_child(args.big_width, 1, args.method)
        print(f"{args.method}: peak RSS at {args.big_width}x{args.big_width // 2}: {peak_big:.2f} GB "
              f"(one run, {big['runs'][0]['wall']:.1f} s)")
    goals = [(peak[args.method] <= GOAL_PEAK_GB,
              f"{args.method} peak RSS at {BASE_WIDTH}x{BASE_WIDTH // 2} <= {GOAL_PEAK_GB:g} GB: "
              f"{peak[args.method]:.2f} GB")]
    if len(labels) > 1:
        t, b = med(args.method, "wall"), med(args.compare_with, "wall")
        ratios = [x["wall"] / y["wall"] for x, y in zip(runs[args.method], runs[args.compare_with], strict=True)]
        ratio = float(np.median(ratios))
        goals.append((ratio <= GOAL_TIME_FACTOR,
                      f"{args.method} at {BASE_WIDTH}x{BASE_WIDTH // 2} at most {GOAL_TIME_FACTOR:g} x "
                      f"{args.compare_with} (same run, median of {len(ratios)} paired wall ratios): {ratio:.2f} x "
                      f"(pairs {min(ratios):.2f}-{max(ratios):.2f} x; medians {t:.2f} s vs {b:.2f} s)"))
    print("goals vs measured:")
    return report_goals(goals)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "bench_sweep"))
