"""Benchmark of the trinocular sweep: time of each stage at 1000x500 (median of 3 runs), the whole method's time,
and peak memory (RSS) at 1000x500 and 4000x2000, each size run in a child process.

    python -m harness.jobs.bench_sweep [--runs 3] [--big-width 4000] [--method sweep|fused]

Each stage is reported as wall seconds and process CPU seconds (all threads): on a shared machine the wall time
is inflated by other jobs, the CPU time much less.

The frame is the ray-cast synthetic_box (vp000) at 1000x500; the 4000x2000 run upsamples its images (same poses),
which exercises the same memory as a native 4000x2000 frame.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time

import cv2
import numpy as np

from harness.render.raycast import render_frame
from reconstruction.methods.registry import fused_method
from reconstruction.methods.sweep import SweepMethod
from scenes.model import choose_viewpoints
from scenes.registry import get_scene

BASE_WIDTH = 1000


def bench_frame(width: int):
    """The synthetic_box vp000 frame, ray-cast at 1000 wide, images resized to ``width`` (H = width / 2)."""
    entry, preset = get_scene("synthetic_box")
    spec = entry.spec(preset, seed=0)
    rig = choose_viewpoints(spec, 1, 0)[0]
    frame = render_frame(spec, rig, BASE_WIDTH, "synthetic_box", "vp000", supersample=1)
    if width != BASE_WIDTH:
        interp = cv2.INTER_CUBIC if width > BASE_WIDTH else cv2.INTER_AREA
        frame.images = {k: cv2.resize(v, (width, width // 2), interpolation=interp) for k, v in frame.images.items()}
        frame.distance = {}
        frame.width, frame.height = width, width // 2
    return frame


def child(width: int, runs: int, method_name: str = "sweep") -> None:
    """Run the method ``runs`` times on a ``width`` frame; print one JSON line with per-stage seconds per run
    (wall, and ``<stage>_cpu`` process CPU seconds)."""
    frame = bench_frame(width)
    method = fused_method() if method_name == "fused" else SweepMethod()
    out = []
    for _ in range(runs):
        t, c = time.perf_counter(), time.process_time()
        res = method.run(frame)
        wall, cpu = time.perf_counter() - t, time.process_time() - c
        stage_cpu = {f"{k}_cpu": v for k, v in res.info.get("cpu_seconds", {}).items() if k != "total"}
        out.append({**res.seconds, **stage_cpu, "wall": wall, "wall_cpu": cpu})
    print(json.dumps({"width": width, "runs": out}), flush=True)


def run_child(width: int, runs: int, method_name: str = "sweep") -> tuple[dict, float]:
    """Run :func:`child` in a fresh process; returns its JSON result and its peak RSS in GB."""
    proc = subprocess.run([sys.executable, "-m", "harness.jobs.bench_sweep", "--child", str(width),
                           "--runs", str(runs), "--method", method_name],
                          capture_output=True, text=True, check=True)
    peak_gb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024 ** 2  # ru_maxrss is KiB on Linux
    line = [x for x in proc.stdout.splitlines() if x.startswith("{")][-1]
    return json.loads(line), peak_gb


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3, help="timed runs at 1000x500 (the median is reported)")
    ap.add_argument("--big-width", type=int, default=4000, help="width of the memory run (0 = skip)")
    ap.add_argument("--method", choices=("sweep", "fused"), default="fused",
                    help="the method to time (default: fused, what `tri360 reconstruct` runs by default)")
    ap.add_argument("--child", type=int, default=0, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(args.child, args.runs, args.method)
        return 0
    # warm-up child: numba compiles (cache=True) once, so the timed child measures steady state
    run_child(320, 1, args.method)
    res, _ = run_child(BASE_WIDTH, args.runs, args.method)
    # RUSAGE_CHILDREN is the max over all children so far: the 1000-wide child is the largest yet
    peak_small = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024 ** 2
    stages = [k for k in res["runs"][0] if k not in ("total", "wall") and not k.endswith("_cpu")]

    def med(key):
        return np.median([r.get(key, np.nan) for r in res["runs"]])

    print(f"{args.method} at {BASE_WIDTH}x{BASE_WIDTH // 2}, median of {args.runs} runs (seconds, wall / CPU):")
    for k in stages:
        print(f"  {k:16s} {med(k):7.2f} / {med(k + '_cpu'):7.2f}")
    print(f"  {'method total':16s} {med('wall'):7.2f} / {med('wall_cpu'):7.2f}")
    print(f"peak RSS at {BASE_WIDTH}x{BASE_WIDTH // 2}: {peak_small:.2f} GB")
    if args.big_width:
        big, peak_big = run_child(args.big_width, 1, args.method)
        print(f"peak RSS at {args.big_width}x{args.big_width // 2}: {peak_big:.2f} GB "
              f"(one run, {big['runs'][0]['wall']:.1f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
