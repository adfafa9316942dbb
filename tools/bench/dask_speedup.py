"""Benchmark of the Dask executor: a 2-worker ``LocalCluster`` against a 1-worker one, rendering the same frames.

Run as ``python -m tools.bench.dask_speedup`` (part of ``make bench``).  It starts a ``LocalCluster`` of 1 worker,
then one of 2 workers (127.0.0.1 only, 1 thread each, Cycles with ``--threads`` = that one thread, so both runs
give each worker the same threads), renders ``--frames`` viewpoints of ``--scene`` on each (one Dask task per
frame, scene built by each task, as ``tri360 render --workers N`` does) into a temporary data root, and prints the
wall time of each run (cluster start-up excluded), then its goals as ``[PASS]`` / ``[FAIL]`` lines (exit status 1
when one is missed) and, last, ``dask speedup 2 vs 1 workers: N x``.  Goals:

- the frames of both runs are byte-identical: where a frame is rendered does not change it (Cycles with a fixed
  seed and one thread per render);
- 2 workers at least :data:`GOAL_SPEEDUP` x faster than 1 on 2 cores: the executor's overheads (scheduling, each
  task's scene build, writing) leave most of the second core to the renders (measured 1.86-1.93 x,
  docs/studies.md).  Both runs are timed in the same process one after the other, so the goal is a ratio that holds
  on any 2-core machine, but only an otherwise idle one: other jobs move it either way (they take the core the
  second worker needs, 1.14 x at load 4-6, or a larger share of one worker than of two, 1.93 x at load 6-7), so
  the load average before each run is printed beside it.
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("bench_dask")

import os
import sys
import tempfile
import time
from pathlib import Path

from harness.commands.render import RENDER_LOG, render_frames
from harness.render.base import RenderSettings
from harness.runtime.cluster import ClusterOptions
from harness.runtime.context import RunContext
from harness.runtime.executor import DaskExecutor
from tools.common import ArgumentParser, report_goals

__all__ = ["GOAL_SPEEDUP", "time_render", "main"]

GOAL_SPEEDUP = 1.6


def time_render(workers: int, root: Path, scene: str, frames: int, width: int, samples: int, threads: int) -> float:
    """Render ``frames`` viewpoints on a LocalCluster of ``workers`` workers; wall seconds (start-up excluded)."""
    with DaskExecutor(ClusterOptions(workers=workers, threads_per_worker=1)) as ex:
        ex.client.wait_for_workers(workers, timeout=120)
        t0 = time.perf_counter()
        render_frames(RenderSettings(width=width, samples=samples, threads=threads), scene, viewpoints=frames,
                      out_root=root, ctx=RunContext(ex, progress=False))
        return time.perf_counter() - t0


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and p.name != RENDER_LOG}


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(prog="python -m tools.bench.dask_speedup", description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="classroom", help="scene to render (Cycles by default for classroom)")
    ap.add_argument("--frames", type=int, default=4, help="viewpoints rendered by each run")
    ap.add_argument("--width", type=int, default=400, help="panorama width, pixels")
    ap.add_argument("--samples", type=int, default=4, help="Cycles samples per pixel")
    ap.add_argument("--threads", type=int, default=1, help="Cycles threads per render = threads per worker")
    args = ap.parse_args(argv)
    print(f"dask bench: {args.frames} frames of {args.scene}, {args.width}x{args.width // 2}, {args.samples} "
          f"samples, {args.threads} thread(s) per worker, {os.cpu_count()} cores", flush=True)
    with tempfile.TemporaryDirectory(prefix="tri360-bench-dask-") as tmp:
        seconds = {}
        for workers in (1, 2):
            load = os.getloadavg()[0]
            root = Path(tmp) / f"w{workers}"
            seconds[workers] = time_render(workers, root, args.scene, args.frames, args.width, args.samples,
                                           args.threads)
            print(f"  {workers} worker(s): {seconds[workers]:7.1f} s  ({seconds[workers] / args.frames:.1f} s/frame; "
                  f"load average before: {load:.2f})", flush=True)
        same = _files(Path(tmp) / "w1") == _files(Path(tmp) / "w2")
    speedup = seconds[1] / seconds[2]
    status = report_goals([(same, f"frames byte-identical between the runs: {'yes' if same else 'NO'}"),
                           (speedup >= GOAL_SPEEDUP, f"2 workers >= {GOAL_SPEEDUP:g} x faster than 1: "
                                                    f"{seconds[1]:.1f} s / {seconds[2]:.1f} s = {speedup:.2f} x")])
    print(f"dask speedup 2 vs 1 workers: {speedup:.2f} x", flush=True)
    return status


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "bench_dask"))
