"""The README's picture: one frame's input image, a method's predicted distance and its absolute error.

    python -m tools.overview RESULTS FRAME_DIR [--method LABEL] [--out docs/images/overview.png]

``RESULTS`` is a results set that ``tri360 evaluate`` wrote for a data root holding ``FRAME_DIR`` (a frame
directory ``<scene>/<viewpoint>``); the method (default: the default method) must be a method of that results set
that is not a flow-pipeline configuration (its map is ``maps/<scene>/<viewpoint>/<label>/distance.exr``).  The
figure is :func:`reports.plots.overview_figure`; the PNG is written atomically.  Exit status 2 with one line on bad
input.
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("overview")

import argparse
import sys
from pathlib import Path

from harness.data.atomic import atomic_write_bytes
from harness.data.errors import UserError
from harness.data.exr import read_distance_exr
from harness.data.frame import read_frame
from harness.data.results import map_paths
from reconstruction.methods.registry import DEFAULT_METHOD
from reports.plots import overview_figure, png_bytes
from tools.common import user_error

PROG = "python -m tools.overview"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", type=Path, metavar="RESULTS", help="a results set of tri360 evaluate")
    ap.add_argument("frame", type=Path, metavar="FRAME_DIR", help="the frame directory (<scene>/<viewpoint>)")
    ap.add_argument("--method", default=DEFAULT_METHOD, help=f"the method's label (default: {DEFAULT_METHOD})")
    ap.add_argument("--out", type=Path, default=Path("docs/images/overview.png"), help="PNG to write")
    args = ap.parse_args(argv)
    try:
        frame = read_frame(args.frame)
        if not frame.has_ground_truth:
            raise UserError(f"{args.frame}: the frame has no ground truth")
        distance_map, _ = map_paths(frame.scene, frame.viewpoint, args.method, source="--method")
        path = args.results / distance_map
        if not path.is_file():
            raise UserError(f"{path}: no map of method {args.method!r} for {frame.scene}/{frame.viewpoint} in "
                            f"{args.results}")
        pred = read_distance_exr(path)
        if pred.shape != frame.distance["C"].shape:
            raise UserError(f"{path}: map of {pred.shape[1]}x{pred.shape[0]} px, the frame is "
                            f"{frame.width}x{frame.height}")
        png = png_bytes(overview_figure(frame.images["C"], frame.distance["C"], pred, args.method))
        if not args.out.parent.is_dir():
            raise UserError(f"{args.out}: its folder does not exist")
        atomic_write_bytes(args.out, png)
    except UserError as exc:
        return user_error(PROG, exc)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "overview"))
