"""The README's picture: one frame's input image, a method's predicted distance and its absolute error.

    python -m tools.overview RESULTS FRAME_DIR [--method LABEL] [--out docs/images/overview.png]

``RESULTS`` is a results set that ``tri360 evaluate`` wrote; ``FRAME_DIR`` (a frame directory
``<scene>/<viewpoint>``) must be the very frame it evaluated: its ``frames.json`` records where each evaluated frame
lives, and a frame directory of the same scene and viewpoint elsewhere (another data root, a copy) is refused.  The
method (default: the default method) must be a method of that results set that is not a flow-pipeline
configuration (its map is ``maps/<scene>/<viewpoint>/<label>/distance.exr``).  The figure is
:func:`reports.plots.overview_figure`.

``--out`` is the PNG to write, in an existing, writable folder that is not inside a tri360 output or input (a
results set, a data root, a frame directory, ...).  Only a file this tool wrote is ever replaced: the PNG carries a
``tEXt`` chunk ``tri360`` = :data:`PNG_MARK`, and an existing ``--out`` without it (any other file, or a directory)
is refused.  The PNG is written atomically.  Every bad input is one line on stderr and exit status 2, with nothing
written.
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("overview")

import os
import struct
import sys
import zlib
from collections.abc import Iterable
from pathlib import Path

from harness.data.atomic import atomic_write_bytes
from harness.data.errors import UserError
from harness.data.exr import read_distance_exr
from harness.data.frame import Frame, read_frame
from harness.data.outputs import KINDS, check_output_dir, output_kind
from harness.data.results import FRAMES_JSON, map_paths, read_frames
from reconstruction.methods.registry import DEFAULT_METHOD
from reports.plots import overview_figure, png_bytes
from tools.common import ArgumentParser, user_error

__all__ = ["PNG_KEYWORD", "PNG_MARK", "marked_png", "is_overview_png", "check_provenance", "check_out", "main"]

PROG = "python -m tools.overview"
PNG_KEYWORD = b"tri360"
PNG_MARK = b"tri360-overview/1"
"""The ``tEXt`` chunk (keyword ``tri360``, this text) that marks a PNG as written by this tool."""
_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_MAX_CHUNKS = 64  # chunks looked at before the image data; a marked PNG has its mark right after IHDR


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def marked_png(png: bytes) -> bytes:
    """``png`` with the ``tEXt`` chunk ``tri360`` = :data:`PNG_MARK` right after its ``IHDR``."""
    if png[:8] != _SIGNATURE or png[12:16] != b"IHDR":
        raise ValueError("not a PNG starting with IHDR")
    end = 8 + 8 + struct.unpack(">I", png[8:12])[0] + 4
    return png[:end] + _chunk(b"tEXt", PNG_KEYWORD + b"\0" + PNG_MARK) + png[end:]


def is_overview_png(path: Path) -> bool:
    """Whether ``path`` is a PNG file that carries this tool's mark (:func:`marked_png`); False for anything else,
    an unreadable file or no regular file (a FIFO is never opened) included.  Only the chunks before the image data
    are read."""
    if not Path(path).is_file():
        return False
    try:
        with open(path, "rb") as fh:
            if fh.read(8) != _SIGNATURE:
                return False
            for _ in range(_MAX_CHUNKS):
                head = fh.read(8)
                if len(head) < 8:
                    return False
                length, kind = struct.unpack(">I4s", head)
                if kind in (b"IDAT", b"IEND"):
                    return False
                if kind == b"tEXt" and length <= 1024:
                    if fh.read(length) == PNG_KEYWORD + b"\0" + PNG_MARK:
                        return True
                    fh.seek(4, os.SEEK_CUR)
                else:
                    fh.seek(length + 4, os.SEEK_CUR)
    except OSError:
        return False
    return False


def _real(p: Path) -> Path:
    return Path(os.path.realpath(os.path.abspath(p)))


def check_provenance(results: Path, frame_dir: Path, frame: Frame) -> None:
    """Refuse ``frame_dir`` unless it is the frame directory that results set ``results`` evaluated for the frame's
    scene and viewpoint (its ``frames.json``, compared by real path).

    Raises:
        UserError: one line naming the frame directory (or ``frames.json``) and where the evaluated frame lives.
    """
    index = results / FRAMES_JSON
    entries = read_frames(results)
    if entries is None:
        raise UserError(f"{index}: file is missing, so {frame_dir} cannot be checked to be the frame the results "
                        "were computed from (give a results set that tri360 evaluate wrote)")
    where = [Path(e["path"]) for e in entries if (e["scene"], e["viewpoint"]) == (frame.scene, frame.viewpoint)]
    if not where:
        raise UserError(f"{index}: no frame {frame.scene}/{frame.viewpoint}, so the results were not computed from "
                        f"{frame_dir}")
    if _real(where[0]) != _real(frame_dir):
        raise UserError(f"{frame_dir}: not the frame the results in {results} were computed from (their "
                        f"{frame.scene}/{frame.viewpoint} is {where[0]}); give that frame directory")


def _inside(path: Path, inputs: Iterable[Path]) -> str | None:
    """What tri360 directory ``path`` (a directory) is or lies in: one of ``inputs``, a frame directory or a tri360
    output (:func:`harness.data.outputs.output_kind`), else None."""
    real = _real(path)
    for inp in inputs:
        if real.is_relative_to(_real(inp)):
            return f"an input of this tool ({inp})"
    for a in (real, *real.parents):
        if a.parent == a:
            break
        if (a / "frame.json").is_file():
            return f"a frame directory ({a})"
        kind = output_kind(a)
        if kind is not None:
            return f"a tri360 {KINDS[kind]} ({a})"
    return None


def check_out(out: Path, inputs: Iterable[Path]) -> None:
    """Refuse ``out`` as the overview PNG unless it is absent or a PNG this tool wrote (:func:`is_overview_png`),
    in an existing, writable folder that is none of ``inputs`` nor inside one, nor a frame directory or a tri360
    output, nor inside one.  Nothing is created or changed.

    Raises:
        UserError: one line naming ``out`` and what is wrong.
    """
    if os.path.lexists(out):
        if out.is_dir():
            raise UserError(f"{out}: is a directory; --out is the PNG file to write")
        if not is_overview_png(out):
            raise UserError(f"{out}: exists and is not an overview PNG this tool wrote (no tri360 mark); it is never "
                            "replaced: choose another --out or remove the file yourself")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.exists():
        raise UserError(f"{out}: its folder does not exist")
    check_output_dir(parent)
    inside = _inside(parent, inputs)
    if inside is not None:
        raise UserError(f"{out}: is inside {inside}; the overview is never written into tri360's inputs or "
                        "outputs: choose another --out")


def _overview(args) -> Path:
    """Check every input, then write the PNG; the path written."""
    frame = read_frame(args.frame)
    if not frame.has_ground_truth:
        raise UserError(f"{args.frame}: the frame has no ground truth")
    check_provenance(args.results, args.frame, frame)
    distance_map, _ = map_paths(frame.scene, frame.viewpoint, args.method, source="--method")
    path = args.results / distance_map
    if not path.is_file():
        raise UserError(f"{path}: no map of method {args.method!r} for {frame.scene}/{frame.viewpoint} in "
                        f"{args.results}")
    pred = read_distance_exr(path)
    if pred.shape != frame.distance["C"].shape:
        raise UserError(f"{path}: map of {pred.shape[1]}x{pred.shape[0]} px, the frame is "
                        f"{frame.width}x{frame.height}")
    check_out(args.out, [args.results, args.frame])
    png = png_bytes(overview_figure(frame.images["C"], frame.distance["C"], pred, args.method))
    atomic_write_bytes(args.out, marked_png(png))
    return args.out


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0])
    ap.add_argument("results", type=Path, metavar="RESULTS", help="a results set of tri360 evaluate")
    ap.add_argument("frame", type=Path, metavar="FRAME_DIR",
                    help="the frame directory (<scene>/<viewpoint>) that the results set evaluated")
    ap.add_argument("--method", default=DEFAULT_METHOD, help=f"the method's label (default: {DEFAULT_METHOD})")
    ap.add_argument("--out", type=Path, default=Path("docs/images/overview.png"),
                    help="PNG to write: absent or one this tool wrote (default: %(default)s)")
    args = ap.parse_args(argv)
    try:
        written = _overview(args)
    except UserError as exc:
        return user_error(PROG, exc)
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename is not None else ""
        return user_error(PROG, f"{where}{exc.strerror or exc}")
    print(f"wrote {written}")
    return 0


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "overview"))
