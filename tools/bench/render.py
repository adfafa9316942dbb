"""Benchmark of the default render: ``tri360 render`` of the default classroom frame, end to end, several times.

Run as ``python -m tools.bench.render`` (part of ``make bench``).  Each repeat runs the command a user runs,
``tri360 render --quiet --out TMP`` with every default (scene ``classroom``, 1000 x 500, the default samples and
Cycles settings, viewpoint ``vp000``), in a fresh process into a fresh temporary data root, and times it from
start to exit (Python start-up, Blender start-up, scene build, three cameras, writing the frame).  It prints each
wall time with the renderer's time per camera (from the frame's ``render_log.json``) and the load average before it;
the last line is ``render default frame: MIN-MAX s over N renders`` (goal: <= 60 s on 2 idle cores; exit status 1
when the slowest render misses it).  Any other
arguments are passed to ``tri360 render`` (e.g. ``--scene box_room --width 400``).  Only
meaningful on an otherwise idle machine.
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("bench_render")

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from harness.commands.render import DEFAULT_SCENE, DEFAULTS, RENDER_LOG
from tools.common import goals_status

__all__ = ["GOAL_S", "time_default_render", "main"]

GOAL_S = 60.0


def time_default_render(root: Path, extra: list[str] | None = None) -> tuple[float, dict]:
    """Run ``tri360 render --quiet --out ROOT [extra]`` in a new process; (wall seconds, its render_log.json)."""
    cmd = [sys.executable, "-m", "harness.cli", "render", "--quiet", "--out", str(root), *(extra or [])]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"error: {' '.join(cmd)} exited {proc.returncode}: {proc.stderr.strip()}")
    logs = sorted(root.rglob(RENDER_LOG))
    return wall, (json.loads(logs[0].read_text(encoding="utf-8")) if logs else {})


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.bench.render", description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="number of renders timed")
    args, extra = ap.parse_known_args(argv)
    if args.repeats < 1:
        ap.error("--repeats must be >= 1")
    what = (f"`tri360 render {' '.join(extra)}`" if extra else
            f"`tri360 render` (scene {DEFAULT_SCENE}, {DEFAULTS.width}x{DEFAULTS.height}, {DEFAULTS.samples} samples, "
            f"light tree {'on' if DEFAULTS.light_tree else 'off'})")
    print(f"render bench: {what}, {args.repeats} times, {os.cpu_count()} cores", flush=True)
    walls = []
    for i in range(args.repeats):
        load = os.getloadavg()[0]
        with tempfile.TemporaryDirectory(prefix="tri360-bench-render-") as tmp:
            wall, log = time_default_render(Path(tmp), extra)
        cams = log.get("seconds", {})
        per_cam = ", ".join(f"{c} {cams[c]:.1f}" for c in ("C", "U", "R") if c in cams)
        print(f"  render {i + 1}: {wall:.1f} s wall (renderer s per camera: {per_cam}; load average before "
              f"{load:.1f})", flush=True)
        walls.append(wall)
    ok = max(walls) <= GOAL_S
    label = "frame" if extra else "default frame"
    print(f"render {label}: {min(walls):.1f}-{max(walls):.1f} s over {len(walls)} renders "
          f"[{'ok' if ok else 'NOT MET'}: goal <= {GOAL_S:.0f} s]", flush=True)
    return goals_status([ok])


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "bench_render"))
