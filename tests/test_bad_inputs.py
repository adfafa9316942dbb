"""A catalogue of bad inputs and faults, each run through the real command line, ``harness.cli.main([...])``.

Every case names a command line, how the input is broken first (``setup``) and what must happen.  A *failing*
case must:

- exit with status 2;
- print exactly one line on stderr, ``tri360 <command>: error: ...``, naming the culprit (a file, an option or a
  name); for errors argparse itself reports, its usage lines plus one ``error:`` line (argparse's documented
  behaviour);
- print no traceback, and nothing else on the terminal -- stdout/stderr are captured at the file-descriptor
  level (``capfd``), so messages printed by C libraries (libpng, OpenEXR) count too;
- write or change nothing: every file and directory under the test directory is the same before and after.

A few cases check the right behaviour of a command that must *succeed* on an unusual input (evaluate on one
frame directory, a scene filter, a re-run that must skip or repair a frame, outputs that respect the umask,
left-overs of killed runs that must be cleaned).  No case may leave hidden ``.partial``/``.old`` entries.

Frames are 64 x 32 ``synthetic_box`` frames ray-cast in numpy (no Blender); renders use the same scene.
"""

from __future__ import annotations

import json
import os
import shutil
import stat
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import OpenEXR
import pandas as pd
import pytest

import harness.commands.evaluate
import reconstruction.plugins
from harness.cli import main
from harness.data.atomic import parse_staging_name
from harness.data.frame import read_frame, write_frame
from harness.data.images import write_png
from tests.helpers import make_synthetic_frame

# ----------------------------------------------------------------------------------------------- machinery


@dataclass
class Env:
    """Paths of one case (a fresh copy of the template under ``tmp``) and clean-up callbacks."""

    tmp: Path
    cleanups: list[Callable[[], object]] = field(default_factory=list)

    @property
    def root(self) -> Path:  # a data root holding one good frame, synthetic_box/vp000
        return self.tmp / "data"

    @property
    def frame(self) -> Path:
        return self.root / "synthetic_box" / "vp000"

    @property
    def out(self) -> Path:  # does not exist unless a setup makes it
        return self.tmp / "out"

    @property
    def res(self) -> Path:  # a valid results directory (written by `tri360 evaluate --no-report`)
        return self.tmp / "results"

    @property
    def file(self) -> Path:  # an ordinary file, to be used where a directory is expected
        return self.tmp / "a_file"

    @property
    def preds(self) -> Path:  # a predictions root of the frame (written by `tri360 reconstruct`, oracle-rect:average)
        return self.tmp / "preds"

    def fmt(self, text: str) -> str:
        return text.format(tmp=self.tmp, root=self.root, frame=self.frame, out=self.out, res=self.res,
                           file=self.file, preds=self.preds)


@dataclass(frozen=True)
class Case:
    """One catalogue entry.

    Attributes:
        group: the command (render, scenes, reconstruct, evaluate, score, report, study) or "data" (data-layer
            faults, run through a command).
        name: what is wrong.
        argv: the command line; ``{tmp} {root} {frame} {out} {res} {file} {preds}`` are filled from :class:`Env`.
        culprit: substrings the single error line must contain (same placeholders).
        setup: ``setup(env, monkeypatch)`` breaks the input before the run.
        code: expected exit status; 2 = a failing case, anything else = a succeeding case checked by ``check``.
        forbid: substrings the error line must not contain.
        check: ``check(env, stdout, stderr)`` for succeeding cases.
        unchanged: also for a succeeding case, nothing under the test directory may change.
    """

    group: str
    name: str
    argv: tuple[str, ...]
    culprit: tuple[str, ...] = ()
    setup: Callable[[Env, pytest.MonkeyPatch], None] | None = None
    code: int = 2
    forbid: tuple[str, ...] = ()
    check: Callable[[Env, str, str], None] | None = None
    unchanged: bool = False


def run_cli(argv: list[str]) -> tuple[int, bool]:
    """Run ``tri360 argv`` in-process -> (exit status, True if argparse rejected the command line)."""
    try:
        return main(argv), False
    except SystemExit as exc:
        return (exc.code if isinstance(exc.code, int) else 1), True


def snapshot(root: Path) -> dict[str, tuple]:
    """Every entry under ``root``: directories by existence, files by (size, mtime)."""
    out = {}
    for p in sorted(root.rglob("*")):
        st = p.lstat()
        rel = str(p.relative_to(root))
        out[rel] = ("dir",) if stat.S_ISDIR(st.st_mode) else ("file", st.st_size, st.st_mtime_ns)
    return out


def staging_leftovers(root: Path) -> list[str]:
    return [str(p.relative_to(root)) for p in root.rglob(".*") if parse_staging_name(p.name) is not None]


def dead_pid() -> int:
    """The pid of a process that has exited (and been reaped)."""
    out = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True,
                         check=True)
    return int(out.stdout)


# ---------------------------------------------------------------------------------------- input breakers


def edit_meta(fn: Callable[[dict], object]):
    """Setup: load the frame's frame.json, let ``fn`` change it, write it back (NaN/Infinity tokens allowed)."""
    def setup(env: Env, mp) -> None:
        path = env.frame / "frame.json"
        meta = json.loads(path.read_text())
        fn(meta)
        path.write_text(json.dumps(meta))
    return setup


def write_text(rel: str, text: str):
    def setup(env: Env, mp) -> None:
        p = Path(env.fmt(rel))
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return setup


def write_bytes(rel: str, data: bytes):
    def setup(env: Env, mp) -> None:
        Path(env.fmt(rel)).write_bytes(data)
    return setup


def truncate(rel: str, fraction: float):
    """Setup: keep the first ``fraction`` of a file (header intact for 0.6 of a frame's PNG/EXR)."""
    def setup(env: Env, mp) -> None:
        p = Path(env.fmt(rel))
        data = p.read_bytes()
        p.write_bytes(data[: int(fraction * len(data))])
    return setup


def flip_bytes(rel: str, at: float, n: int = 48):
    """Setup: invert ``n`` bytes starting at fraction ``at`` of the file (inside compressed pixel data)."""
    def setup(env: Env, mp) -> None:
        p = Path(env.fmt(rel))
        data = bytearray(p.read_bytes())
        i = int(at * len(data))
        data[i:i + n] = bytes(b ^ 0xFF for b in data[i:i + n])
        p.write_bytes(bytes(data))
    return setup


def raw_exr(rel: str, fn: Callable[[np.ndarray], np.ndarray], channel: str = "distance"):
    """Setup: rewrite a distance EXR with OpenEXR directly (bypassing tri360's checks): ``fn(old) -> new``."""
    def setup(env: Env, mp) -> None:
        p = Path(env.fmt(rel))
        old = np.asarray(OpenEXR.File(str(p)).channels()["distance"].pixels, np.float32)
        OpenEXR.File({"type": OpenEXR.scanlineimage}, {channel: fn(old.copy())}).write(str(p))
    return setup


def remove(*rels: str):
    def setup(env: Env, mp) -> None:
        for rel in rels:
            Path(env.fmt(rel)).unlink()
    return setup


def dir_in_place_of(rel: str):
    def setup(env: Env, mp) -> None:
        p = Path(env.fmt(rel))
        p.unlink()
        p.mkdir()
    return setup


def png_16bit(rel: str):
    def setup(env: Env, mp) -> None:
        import cv2

        p = Path(env.fmt(rel))
        img = cv2.imread(str(p)).astype(np.uint16) * 257
        cv2.imwrite(str(p), img)
    return setup


def strip_ground_truth(env: Env, mp) -> None:
    for k in "CUR":
        (env.frame / f"{k}.distance.exr").unlink()


def make_dir(rel: str):
    def setup(env: Env, mp) -> None:
        Path(env.fmt(rel)).mkdir(parents=True)
    return setup


def read_only(rel: str):
    """Setup: make a directory read-only.  Tests run as root, which ignores permission bits, so as root this
    sets the immutable attribute (``chattr +i``); if that is impossible the case is skipped with the reason."""
    def setup(env: Env, mp) -> None:
        p = Path(env.fmt(rel))
        p.mkdir(parents=True, exist_ok=True)
        if os.geteuid() != 0:
            p.chmod(0o555)
            env.cleanups.append(lambda: p.chmod(0o755))
            return
        try:
            r = subprocess.run(["chattr", "+i", str(p)], capture_output=True, text=True)
        except FileNotFoundError:
            pytest.skip("running as root without chattr: cannot make a read-only directory")
        if r.returncode != 0:
            pytest.skip(f"running as root and `chattr +i` failed ({r.stderr.strip()}): cannot make a read-only "
                        "directory")
        env.cleanups.append(lambda: subprocess.run(["chattr", "-i", str(p)], check=True))
    return setup


def rendered(*extra: str):
    """Setup: render synthetic_box at width 64 into {out} with the CLI (plus ``extra`` options)."""
    def setup(env: Env, mp) -> None:
        code, _ = run_cli(["render", "--scene", "synthetic_box", "--width", "64", "--quiet", "--out", str(env.out),
                           *extra])
        assert code == 0, "setup render failed"
    return setup


def second_scene(env: Env, mp) -> None:
    """Setup: a copy of the frame as scene 'otherscene' (directory and frame.json)."""
    dst = env.root / "otherscene" / "vp000"
    shutil.copytree(env.frame, dst)
    meta = json.loads((dst / "frame.json").read_text())
    meta["scene"] = "otherscene"
    (dst / "frame.json").write_text(json.dumps(meta))


def second_viewpoint(env: Env, mp) -> None:
    """Setup: a second, valid frame synthetic_box/vp001 (a copy of vp000, renamed in its frame.json)."""
    dst = env.root / "synthetic_box" / "vp001"
    shutil.copytree(env.frame, dst)
    meta = json.loads((dst / "frame.json").read_text())
    meta["viewpoint"] = "vp001"
    (dst / "frame.json").write_text(json.dumps(meta))


def umask(value: int):
    def setup(env: Env, mp) -> None:
        old = os.umask(value)
        env.cleanups.append(lambda: os.umask(old))
    return setup


def combine(*setups):
    def setup(env: Env, mp) -> None:
        for s in setups:
            s(env, mp)
    return setup


class FakeEntryPoint:
    """Stands in for an ``importlib.metadata.EntryPoint`` of group ``tri360.scenes``."""

    def __init__(self, name: str, value: str, load: Callable[[], object]):
        self.name, self.value, self._load = name, value, load

    def load(self):
        return self._load()


def entry_point(name: str, load: Callable[[], object]):
    def setup(env: Env, mp) -> None:
        eps = [FakeEntryPoint(name, f"{name}_pkg:SCENES", load)]
        mp.setattr(reconstruction.plugins, "entry_points", lambda group=None: eps if group == "tri360.scenes" else [])
    return setup


def _raise_import_error():
    raise ImportError("No module named 'broken_pkg'")


def users_file(rel: str):
    """Setup: a file of the user's (tri360 never wrote it), e.g. ``{out}/notes.txt``."""
    return write_text(rel, "my notes: not written by tri360\n")


def symlink(rel: str, target: str):
    def setup(env: Env, mp) -> None:
        Path(env.fmt(rel)).symlink_to(Path(env.fmt(target)))
    return setup


def edit_json(rel: str, fn: Callable[[dict], object]):
    def setup(env: Env, mp) -> None:
        p = Path(env.fmt(rel))
        data = json.loads(p.read_text())
        fn(data)
        p.write_text(json.dumps(data))
    return setup


def no_method_may_run(env: Env, mp) -> None:
    """Setup: any method run fails loudly (not with exit 2), so a refusal proves the check came before any work."""
    def forbidden(*args, **kwargs):
        raise AssertionError("a method ran before the preconditions were checked")
    mp.setattr(harness.commands.evaluate, "run_blind", forbidden)


def vp001_without_ground_truth(env: Env, mp) -> None:
    """Setup: a second frame synthetic_box/vp001 without ground truth, and its prediction (for score)."""
    second_viewpoint(env, mp)
    for k in "CUR":
        (env.root / "synthetic_box" / "vp001" / f"{k}.distance.exr").unlink()
    shutil.copytree(env.preds / "synthetic_box" / "vp000", env.preds / "synthetic_box" / "vp001")


def prediction_exr(fn: Callable[[np.ndarray], np.ndarray]):
    """Setup: rewrite the predictions root's distance.exr with OpenEXR directly: ``fn(old float32) -> new``."""
    return raw_exr("{preds}/synthetic_box/vp000/distance.exr", fn)


def drop_markers(*rels: str):
    """Setup: remove the output markers, as in directories written by the previous release."""
    return remove(*(f"{r}/.tri360-output.json" for r in rels))


# ---------------------------------------------------------------------------------------------- checkers


def check_modes(file_mode: int, dir_mode: int, where: str = "{out}"):
    def check(env: Env, out: str, err: str) -> None:
        base = Path(env.fmt(where))
        entries = [base, *base.rglob("*")]
        assert len(entries) > 5
        bad = {str(p): oct(stat.S_IMODE(p.stat().st_mode)) for p in entries
               if stat.S_IMODE(p.stat().st_mode) != (dir_mode if p.is_dir() else file_mode)}
        assert not bad, f"modes differ from {oct(file_mode)}/{oct(dir_mode)}: {bad}"
    return check


def check_results(scenes_: set[str], n_rows: int):
    def check(env: Env, out: str, err: str) -> None:
        table = pd.read_csv(env.out / "results.csv")
        assert set(table["scene"]) == scenes_ and len(table) == n_rows
        assert err == ""
    return check


def check_frame_valid(env: Env, out: str, err: str) -> None:
    frame = read_frame(env.out / "synthetic_box" / "vp000")
    assert frame.width == 64 and frame.has_ground_truth
    assert err == ""


def check_prints_frame_dir(env: Env, out: str, err: str) -> None:
    assert err == "" and out.strip() == str(env.out / "synthetic_box" / "vp000"), out + err


def check_report_written(env: Env, out: str, err: str) -> None:
    assert (env.res / "report.html").is_file() and (env.res / "mae.md").is_file()


def check_marked(where: str, kind: str):
    def check(env: Env, out: str, err: str) -> None:
        marker = json.loads((Path(env.fmt(where)) / ".tri360-output.json").read_text())
        assert marker["format"] == "tri360-output/1" and marker["kind"] == kind, marker
    return check


def escaping_map(env: Env, mp) -> None:
    """Setup: a real map where ``maps/<scene>/<viewpoint>/oracle-rect/`` + six ``..`` + ``escape`` points, beside
    the test directory, so that a report taking the name as a path would find it and write a PLY out there."""
    src = env.res / "maps" / "synthetic_box" / "vp000" / "oracle-rect" / "average.distance.exr"
    shutil.copy(src, env.tmp.parent / "escape.distance.exr")


def check_nothing_outside_res(env: Env, out: str, err: str) -> None:
    """A report of results whose names are unsafe writes only under {res}, and says what it left out."""
    written = [p for p in env.tmp.parent.rglob("*") if "escape" in p.name and not p.name.endswith(".exr")]
    assert written == [], written
    assert "cannot be used as a path" in err


def check_scenes_warning(source: str):
    def check(env: Env, out: str, err: str) -> None:
        assert "synthetic_box" in out  # the other scenes are still listed
        lines = err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("warning: ") and source in lines[0], err
    return check


# ------------------------------------------------------------------------------------------------- cases

R = ("render", "--scene", "synthetic_box", "--width", "64", "--quiet", "--out", "{out}")
REC = ("reconstruct", "{frame}", "--out", "{out}", "--flow", "oracle", "--variant", "average", "--quiet")
EV = ("evaluate", "{root}", "--out", "{out}", "--flow", "oracle", "--variants", "average", "--no-report", "--quiet")
REP = ("report", "{res}", "--ply", "none")
SC = ("score", "{preds}", "--data", "{root}", "--out", "{out}", "--no-report", "--quiet")
ST = ("study", "{tmp}/study.toml", "--out", "{out}", "--quiet")
PROC = "/proc/tri360-no-such-dir/out"

CASES = [
    # ---- render
    Case("render", "unknown-scene", (*R, "--scene", "nosuch"), ("nosuch",)),
    Case("render", "unknown-preset", (*R, "--scene", "synthetic_box:nopreset"), ("nopreset",)),
    Case("render", "width-zero", (*R, "--width", "0"), ("--width",)),
    Case("render", "width-negative", (*R, "--width", "-64"), ("--width",)),
    Case("render", "width-odd", (*R, "--width", "65"), ("--width",)),
    Case("render", "width-tiny", (*R, "--width", "6"), ("--width",)),
    Case("render", "width-huge", (*R, "--width", "1000000"), ("--width",)),
    Case("render", "width-not-a-number", (*R, "--width", "wide"), ("--width",)),
    Case("render", "samples-zero", (*R, "--samples", "0"), ("--samples",)),
    Case("render", "samples-negative", (*R, "--samples", "-4"), ("--samples",)),
    Case("render", "viewpoints-zero", (*R, "--viewpoints", "0"), ("--viewpoints",)),
    Case("render", "viewpoints-more-than-fit", (*R, "--viewpoints", "100000"), ("100000",)),
    Case("render", "baseline-zero", (*R, "--baseline", "0"), ("--baseline",)),
    Case("render", "baseline-nan", (*R, "--baseline", "nan"), ("--baseline",)),
    Case("render", "threads-negative", (*R, "--threads", "-1"), ("--threads",)),
    Case("render", "max-bounces-negative", (*R, "--max-bounces", "-1"), ("--max-bounces",)),
    Case("render", "set-without-value", (*R, "--set", "room"), ("--set", "room")),
    Case("render", "set-unknown-key", (*R, "--set", "bogus_key=1"), ("bogus_key",)),
    Case("render", "set-bad-value", (*R, "--set", 'furniture=["sofa"]'), ("sofa",)),
    Case("render", "set-ill-typed-value", (*R, "--set", "jitter_m=big"),
         ("scene 'synthetic_box'", "jitter_m: expected a number", "'big'")),
    Case("render", "set-value-out-of-range", (*R, "--set", "room=[6, 5, -3]"), ("room: expected", "[6, 5, -3]")),
    Case("render", "unknown-renderer", (*R, "--renderer", "bogus"), ("--renderer", "bogus"),
         forbid=("unrecognized arguments",)),
    Case("render", "out-is-a-file", (*R[:-1], "{file}"), ("{file}",)),
    Case("render", "out-under-proc", (*R[:-1], PROC), ("/proc/tri360-no-such-dir",)),
    Case("render", "out-read-only", R, ("{out}",), setup=read_only("{out}")),
    Case("render", "rerun-other-width", (*R, "--width", "128"), ("{out}/synthetic_box/vp000",),
         setup=rendered()),
    Case("render", "rerun-other-seed", (*R, "--seed", "1"), ("{out}/synthetic_box/vp000",), setup=rendered()),
    Case("render", "rerun-other-baseline", (*R, "--baseline", "0.3"), ("{out}/synthetic_box/vp000",),
         setup=rendered()),
    Case("render", "rerun-same-settings-skips", R, code=0, setup=rendered(), unchanged=True,
         check=check_prints_frame_dir),
    Case("render", "rerun-repairs-corrupt-frame", R, code=0,
         setup=combine(rendered(), write_text("{out}/synthetic_box/vp000/frame.json", "{broken")),
         check=check_frame_valid),
    Case("render", "cleans-leftovers-of-killed-runs", R, code=0,
         setup=lambda env, mp: write_text(f"{{out}}/synthetic_box/.vp000.partial-{dead_pid()}-0000abcd/C.png",
                                          "half")(env, mp),
         check=check_frame_valid),
    # ---- scenes
    Case("scenes", "extra-argument", ("scenes", "bogus"), ("bogus",)),
    Case("scenes", "entry-point-fails-to-import", ("scenes",), code=0,
         setup=entry_point("broken", _raise_import_error), check=check_scenes_warning("broken")),
    Case("scenes", "entry-point-not-a-scene", ("scenes",), code=0,
         setup=entry_point("weird", lambda: 42), check=check_scenes_warning("weird")),
    Case("scenes", "render-scene-of-broken-entry-point", (*R, "--scene", "broken"), ("broken",),
         setup=entry_point("broken", _raise_import_error)),
    # ---- reconstruct
    Case("reconstruct", "frame-dir-missing", (*REC[:1], "{tmp}/nope", *REC[2:]), ("{tmp}/nope/frame.json",)),
    Case("reconstruct", "frame-json-not-json", REC, ("{frame}/frame.json", "not valid JSON"),
         setup=write_text("{frame}/frame.json", "{not json")),
    Case("reconstruct", "png-missing", REC, ("{frame}/U.png", "missing"), setup=remove("{frame}/U.png")),
    Case("reconstruct", "png-truncated", REC, ("{frame}/C.png", "truncated or corrupt"),
         setup=truncate("{frame}/C.png", 0.6)),
    Case("reconstruct", "png-garbage", REC, ("{frame}/R.png", "not a readable image"),
         setup=write_bytes("{frame}/R.png", b"GIF89a nonsense")),
    Case("reconstruct", "png-wrong-size", REC, ("{frame}/C.png", "size"),
         setup=lambda env, mp: write_png(env.frame / "C.png", np.zeros((32, 62, 3), np.uint8))),
    Case("reconstruct", "exr-truncated", REC, ("{frame}/C.distance.exr", "truncated or corrupt"),
         setup=truncate("{frame}/C.distance.exr", 0.6)),
    Case("reconstruct", "exr-pixel-bytes-overwritten", REC, ("{frame}/U.distance.exr", "truncated or corrupt"),
         setup=flip_bytes("{frame}/U.distance.exr", 0.8)),
    Case("reconstruct", "exr-nan", REC, ("{frame}/U.distance.exr", "NaN"),
         setup=raw_exr("{frame}/U.distance.exr", lambda d: np.where(d > 2.0, np.nan, d).astype(np.float32))),
    Case("reconstruct", "exr-negative", REC, ("{frame}/R.distance.exr", "positive"),
         setup=raw_exr("{frame}/R.distance.exr", lambda d: -d)),
    Case("reconstruct", "exr-minus-inf", REC, ("{frame}/C.distance.exr", "positive"),
         setup=raw_exr("{frame}/C.distance.exr", lambda d: np.where(d > 2.0, -np.inf, d).astype(np.float32))),
    Case("reconstruct", "exr-wrong-size", REC, ("{frame}/R.distance.exr", "size"),
         setup=raw_exr("{frame}/R.distance.exr", lambda d: np.ascontiguousarray(d[:, :40]))),
    Case("reconstruct", "rotation-not-orthonormal", REC, ("{frame}/frame.json", "orthonormal"),
         setup=edit_meta(lambda m: m["cameras"]["R"]["rotation"].__setitem__(0, [2.0, 0.0, 0.0]))),
    Case("reconstruct", "cameras-coincide", REC, ("{frame}/frame.json", "coincide"),
         setup=edit_meta(lambda m: m["cameras"]["U"].__setitem__("position", m["cameras"]["C"]["position"]))),
    Case("reconstruct", "baseline-contradicts-positions", REC, ("{frame}/frame.json", "baseline_m"),
         setup=edit_meta(lambda m: m.__setitem__("baseline_m", 0.8))),
    Case("reconstruct", "baseline-nan", REC, ("{frame}/frame.json", "baseline_m"),
         setup=edit_meta(lambda m: m.__setitem__("baseline_m", float("nan")))),
    Case("reconstruct", "position-infinite", REC, ("{frame}/frame.json", "not finite"),
         setup=edit_meta(lambda m: m["cameras"]["C"]["position"].__setitem__(0, float("inf")))),
    Case("reconstruct", "width-not-twice-height", REC, ("{frame}/frame.json", "2*height"),
         setup=edit_meta(lambda m: m.__setitem__("height", 40))),
    Case("reconstruct", "unknown-variant", (*REC[:-2], "bogus", "--quiet"), ("bogus",)),
    Case("reconstruct", "unknown-flow", (*REC[:4], "--flow", "bogus", "--quiet"), ("bogus",)),
    Case("reconstruct", "oracle-without-ground-truth", REC, ("{frame}",), setup=strip_ground_truth),
    Case("reconstruct", "out-is-a-file", (*REC[:2], "--out", "{file}", *REC[4:]), ("{file}",)),
    Case("reconstruct", "out-under-proc", (*REC[:2], "--out", PROC, *REC[4:]), ("/proc/tri360-no-such-dir",)),
    Case("reconstruct", "out-read-only", REC, ("{out}",), setup=read_only("{out}")),
    # ---- evaluate
    Case("evaluate", "root-missing", (EV[0], "{tmp}/nope", *EV[2:]), ("{tmp}/nope",)),
    Case("evaluate", "root-empty", (EV[0], "{tmp}/empty", *EV[2:]), ("{tmp}/empty", "no tri360 frames"),
         setup=make_dir("{tmp}/empty")),
    Case("evaluate", "root-is-a-file", (EV[0], "{file}", *EV[2:]), ("{file}",)),
    Case("evaluate", "frame-without-ground-truth", EV, ("{frame}", "ground-truth"), setup=strip_ground_truth),
    Case("evaluate", "one-bad-frame-among-good", EV, ("{root}/synthetic_box/vp001/C.png", "truncated or corrupt"),
         setup=lambda env, mp: (second_viewpoint(env, mp), truncate("{root}/synthetic_box/vp001/C.png", 0.6)(env, mp))),
    Case("evaluate", "unknown-scene", (*EV, "--scene", "nosuch"), ("nosuch",)),
    Case("evaluate", "unknown-flow", (*EV[:4], "--flow", "bogus", "--no-report", "--quiet"), ("bogus",)),
    Case("evaluate", "duplicate-scene-viewpoint", EV, ("frame.json", "vp000"),
         setup=lambda env, mp: shutil.copytree(env.frame, env.root / "copy" / "vp000")),
    Case("evaluate", "out-is-a-file", (*EV[:2], "--out", "{file}", *EV[4:]), ("{file}",)),
    Case("evaluate", "out-under-proc", (*EV[:2], "--out", PROC, *EV[4:]), ("/proc/tri360-no-such-dir",)),
    Case("evaluate", "out-parent-read-only", (*EV[:2], "--out", "{tmp}/ro/res", *EV[4:]), ("{tmp}/ro",),
         setup=read_only("{tmp}/ro")),
    Case("evaluate", "out-read-only", EV, ("{out}",), setup=read_only("{out}")),
    Case("evaluate", "single-frame-dir-as-root", (EV[0], "{frame}", *EV[2:]), code=0,
         check=check_results({"synthetic_box"}, 1)),
    Case("evaluate", "scene-filter", (*EV, "--scene", "otherscene"), code=0, setup=second_scene,
         check=check_results({"otherscene"}, 1)),
    Case("evaluate", "cleans-leftovers-of-killed-runs", EV, code=0,
         setup=lambda env, mp: write_text(f"{{tmp}}/.out.partial-{dead_pid()}-0000abcd/results.csv", "half")(
             env, mp),
         check=check_results({"synthetic_box"}, 1)),
    # ---- report
    Case("report", "results-dir-missing", (REP[0], "{tmp}/nope", *REP[2:]), ("{tmp}/nope",)),
    Case("report", "results-dir-empty", (REP[0], "{tmp}/empty", *REP[2:]), ("{tmp}/empty", "empty"),
         setup=make_dir("{tmp}/empty")),
    Case("report", "results-path-is-a-file", (REP[0], "{file}", *REP[2:]), ("{file}",)),
    Case("report", "results-csv-empty", REP, ("{res}/results.csv", "empty"), setup=write_text("{res}/results.csv", "")),
    Case("report", "results-csv-header-only", REP, ("{res}/results.csv", "no data rows"),
         setup=lambda env, mp: (env.res / "results.csv").write_text(
             (env.res / "results.csv").read_text().splitlines()[0] + "\n")),
    Case("report", "results-csv-missing-column", REP, ("{res}/results.csv", "mae_m"),
         setup=lambda env, mp: pd.read_csv(env.res / "results.csv").drop(columns=["mae_m"]).to_csv(
             env.res / "results.csv", index=False)),
    Case("report", "results-csv-non-numeric", REP, ("{res}/results.csv", "rmse_m"),
         setup=lambda env, mp: pd.read_csv(env.res / "results.csv").assign(rmse_m="lots").to_csv(
             env.res / "results.csv", index=False)),
    Case("report", "results-csv-binary-garbage", REP, ("{res}/results.csv",),
         setup=write_bytes("{res}/results.csv", bytes(range(256)) * 8)),
    Case("report", "results-csv-duplicate-rows", REP, ("{res}/results.csv", "duplicate"),
         setup=lambda env, mp: (env.res / "results.csv").write_text(
             (env.res / "results.csv").read_text() + (env.res / "results.csv").read_text().splitlines()[1] + "\n")),
    Case("report", "results-csv-is-a-directory", REP, ("{res}/results.csv",),
         setup=lambda env, mp: ((env.res / "results.csv").unlink(), (env.res / "results.csv").mkdir())),
    Case("report", "frames-json-malformed", REP, ("{res}/frames.json",), setup=write_text("{res}/frames.json", "[{")),
    Case("report", "breakdown-csv-missing-columns", REP, ("{res}/breakdown.csv",),
         setup=write_text("{res}/breakdown.csv", "a,b\n1,2\n")),
    Case("report", "cloud-points-zero", (*REP, "--cloud-points", "0"), ("--cloud-points",)),
    Case("report", "results-dir-read-only", REP, ("{res}",), setup=read_only("{res}")),
    Case("report", "cleans-leftovers-of-killed-runs", REP, code=0,
         setup=lambda env, mp: write_text(f"{{res}}/.mae.md.partial-{dead_pid()}-0000abcd", "half")(env, mp),
         check=check_report_written),
    # ---- score
    Case("score", "prediction-missing", SC, ("{preds}/synthetic_box/vp000/distance.exr", "missing"),
         setup=remove("{preds}/synthetic_box/vp000/distance.exr")),
    Case("score", "prediction-negative", SC, ("{preds}/synthetic_box/vp000/distance.exr", "negative"),
         setup=prediction_exr(lambda d: -d)),
    Case("score", "prediction-minus-inf", SC, ("{preds}/synthetic_box/vp000/distance.exr", "negative"),
         setup=prediction_exr(lambda d: np.where(d > 2.0, -np.inf, d).astype(np.float32))),
    Case("score", "prediction-uint32", SC, ("{preds}/synthetic_box/vp000/distance.exr", "uint32"),
         setup=prediction_exr(lambda d: np.nan_to_num(d, posinf=0.0).astype(np.uint32))),
    Case("score", "prediction-all-nan", SC, ("{preds}/synthetic_box/vp000/distance.exr",),
         setup=prediction_exr(lambda d: np.full_like(d, np.nan))),
    Case("score", "method-name-dotdot", (*SC, "--method", "../x"), ("--method", "../x")),
    Case("score", "method-name-absolute", (*SC, "--method", "{tmp}/abs"), ("--method",)),
    Case("score", "method-name-separator", (*SC, "--method", "a/b"), ("--method", "a/b")),
    Case("score", "method-name-hidden", (*SC, "--method", ".x"), ("--method",)),
    Case("score", "method-name-too-long", (*SC, "--method", "m" * 101), ("--method", "101 characters")),
    Case("score", "method-json-name-escapes", SC, ("{preds}/method.json",),
         setup=edit_json("{preds}/method.json", lambda m: m.__setitem__("name", "../../../escape"))),
    Case("score", "method-json-name-absolute", SC, ("{preds}/method.json",),
         setup=edit_json("{preds}/method.json", lambda m: m.__setitem__("name", "/tmp/tri360-escape"))),
    Case("score", "folder-name-unsafe", (SC[0], "{tmp}/my preds", *SC[2:]), ("{tmp}/my preds", "--method"),
         setup=lambda env, mp: (shutil.copytree(env.preds, env.tmp / "my preds"),
                                (env.tmp / "my preds" / "method.json").unlink())),
    Case("score", "frame-without-ground-truth-before-work", SC, ("{root}/synthetic_box/vp001", "ground-truth"),
         setup=combine(vp001_without_ground_truth, no_method_may_run)),
    Case("score", "out-is-the-predictions-root", (*SC[:5], "{preds}", *SC[6:]), ("{preds}", "input")),
    Case("score", "out-inside-the-predictions-root", (*SC[:5], "{preds}/res", *SC[6:]), ("{preds}/res", "input")),
    Case("score", "out-is-the-data-root", (*SC[:5], "{root}", *SC[6:]), ("{root}", "input")),
    Case("score", "out-holds-a-users-file", SC, ("{out}", "notes.txt"), setup=users_file("{out}/notes.txt")),
    # ---- outputs replace only what tri360 wrote (every writing command)
    Case("evaluate", "out-is-the-data-root", (*EV[:2], "--out", "{root}", *EV[4:]), ("{root}", "input")),
    Case("evaluate", "out-is-the-data-roots-parent", (*EV[:2], "--out", "{tmp}", *EV[4:]), ("{tmp}", "input")),
    Case("evaluate", "out-is-a-frame-dir", (*EV[:2], "--out", "{frame}", *EV[4:]), ("{frame}", "input")),
    Case("evaluate", "out-inside-the-data-root", (*EV[:2], "--out", "{root}/res", *EV[4:]), ("{root}/res",)),
    Case("evaluate", "out-is-a-link-to-the-data-root", (*EV[:2], "--out", "{tmp}/link", *EV[4:]),
         ("{tmp}/link", "input"), setup=symlink("{tmp}/link", "{root}")),
    Case("evaluate", "out-is-a-predictions-root", (*EV[:2], "--out", "{preds}", *EV[4:]),
         ("{preds}", "predictions root")),
    Case("evaluate", "out-holds-a-users-file", EV, ("{out}", "1 entry not written by tri360, e.g. notes.txt"),
         setup=users_file("{out}/notes.txt")),
    Case("evaluate", "out-is-a-results-set-with-a-users-file", (*EV[:2], "--out", "{res}", *EV[4:]),
         ("{res}", "thesis.tex"), setup=users_file("{res}/thesis.tex")),
    Case("evaluate", "out-has-a-broken-marker", (*EV[:2], "--out", "{res}", *EV[4:]), ("{res}/.tri360-output.json",),
         setup=write_text("{res}/.tri360-output.json", "{")),
    Case("evaluate", "rerun-into-its-results-set", (*EV[:2], "--out", "{res}", *EV[4:]), code=0,
         check=check_marked("{res}", "results")),
    Case("evaluate", "rerun-into-a-results-set-of-the-previous-release", (*EV[:2], "--out", "{res}", *EV[4:]),
         code=0, setup=drop_markers("{res}"), check=check_marked("{res}", "results")),
    Case("evaluate", "frame-without-ground-truth-before-work", EV, ("{root}/synthetic_box/vp001", "ground-truth"),
         setup=combine(vp001_without_ground_truth, no_method_may_run)),
    Case("evaluate", "scene-name-with-a-space", EV, ("{frame}/frame.json", "scene"),
         setup=edit_meta(lambda m: m.__setitem__("scene", "my room"))),
    Case("reconstruct", "out-is-the-data-root", (*REC[:2], "--out", "{root}", *REC[4:]), ("{root}", "input")),
    Case("reconstruct", "out-is-the-frame-dir", (*REC[:2], "--out", "{frame}", *REC[4:]), ("{frame}", "input")),
    Case("reconstruct", "out-is-the-data-roots-parent", (*REC[:2], "--out", "{tmp}", *REC[4:]), ("{tmp}", "input")),
    Case("reconstruct", "out-is-a-results-set", (*REC[:2], "--out", "{res}", *REC[4:]), ("{res}", "results set")),
    Case("reconstruct", "out-holds-a-users-file", REC, ("{out}", "notes.txt"), setup=users_file("{out}/notes.txt")),
    Case("reconstruct", "another-method-into-a-predictions-root",
         (*REC[:2], "--out", "{preds}", "--flow", "oracle", "--variant", "gradient", "--quiet"),
         ("{preds}", "'oracle-rect:average'")),
    Case("reconstruct", "predictions-root-without-method-json",
         (*REC[:2], "--out", "{preds}", "--flow", "oracle", "--variant", "gradient", "--quiet"),
         ("{preds}", "no method.json"), setup=remove("{preds}/method.json")),
    Case("reconstruct", "same-method-again-into-its-root", (*REC[:2], "--out", "{preds}", *REC[4:]), code=0,
         setup=drop_markers("{preds}"), check=check_marked("{preds}", "predictions")),
    Case("render", "out-is-the-data-roots-parent", (*R[:-1], "{tmp}"), ("{tmp}",)),
    Case("render", "out-is-a-results-set", (*R[:-1], "{res}"), ("{res}", "results set")),
    Case("render", "out-is-a-predictions-root", (*R[:-1], "{preds}"), ("{preds}", "predictions root")),
    Case("render", "out-holds-a-users-file", R, ("{out}", "notes.txt"), setup=users_file("{out}/notes.txt")),
    Case("render", "out-frame-dir-holds-a-users-file", R, ("{out}", "synthetic_box/vp000/notes.txt"),
         setup=combine(rendered(), users_file("{out}/synthetic_box/vp000/notes.txt"))),
    Case("render", "rerun-into-a-data-root-of-the-previous-release", R, code=0,
         setup=combine(rendered(), drop_markers("{out}")), check=check_marked("{out}", "data")),
    Case("report", "results-is-the-data-root", (REP[0], "{root}", *REP[2:]), ("{root}", "data root")),
    Case("report", "results-is-a-predictions-root", (REP[0], "{preds}", *REP[2:]), ("{preds}", "predictions root")),
    Case("report", "results-is-the-data-roots-parent", (REP[0], "{tmp}", *REP[2:]), ("{tmp}",)),
    Case("report", "results-holds-a-users-file", REP, ("{res}", "notes.txt"), setup=users_file("{res}/notes.txt")),
    Case("report", "results-of-the-previous-release", REP, code=0, setup=drop_markers("{res}"),
         check=check_marked("{res}", "results")),
    Case("report", "results-csv-variant-escapes", (*REP[:-1], "all"), code=0, check=check_nothing_outside_res,
         setup=combine(escaping_map, lambda env, mp: pd.read_csv(env.res / "results.csv").assign(
             variant="../../../../../../escape").to_csv(env.res / "results.csv", index=False))),
    Case("report", "results-csv-method-escapes", (*REP[:-1], "all"), code=0, check=check_nothing_outside_res,
         setup=lambda env, mp: pd.read_csv(env.res / "results.csv").assign(
             method="../../../../../../escape", flow="", rectify="", variant="").to_csv(env.res / "results.csv",
                                                                                        index=False)),
    Case("study", "out-is-the-data-root", (*ST[:3], "{root}", *ST[4:]), ("{root}", "data root")),
    Case("study", "out-is-the-data-roots-parent", (*ST[:3], "{tmp}", *ST[4:]), ("{tmp}", "input")),
    Case("study", "out-is-a-predictions-root", (*ST[:3], "{preds}", *ST[4:]), ("{preds}", "predictions root")),
    Case("study", "out-is-a-results-set", (*ST[:3], "{res}", *ST[4:]), ("{res}", "results set")),
    Case("study", "out-holds-a-users-file", ST, ("{out}", "notes.txt"), setup=users_file("{out}/notes.txt")),
    # ---- data layer, through the commands
    Case("data", "frame-json-is-a-directory", REC, ("{frame}/frame.json",),
         setup=dir_in_place_of("{frame}/frame.json")),
    Case("data", "png-is-a-directory", REC, ("{frame}/U.png",), setup=dir_in_place_of("{frame}/U.png")),
    Case("data", "png-16-bit", REC, ("{frame}/C.png", "8-bit"), setup=png_16bit("{frame}/C.png")),
    Case("data", "exr-missing-channel", REC, ("{frame}/C.distance.exr", "'distance'"),
         setup=raw_exr("{frame}/C.distance.exr", lambda d: d, channel="depth")),
    Case("data", "exr-not-an-exr", REC, ("{frame}/U.distance.exr", "not a readable OpenEXR"),
         setup=write_bytes("{frame}/U.distance.exr", b"\x89PNG\r\n\x1a\n not an exr")),
    Case("data", "partial-ground-truth", REC, ("{frame}/R.distance.exr", "missing"),
         setup=remove("{frame}/R.distance.exr")),
    Case("data", "viewpoint-name-escapes", REC, ("{frame}/frame.json", "viewpoint"),
         setup=edit_meta(lambda m: m.__setitem__("viewpoint", "../../escape"))),
    Case("data", "umask-022-render", R, code=0, setup=umask(0o022), check=check_modes(0o644, 0o755)),
    Case("data", "umask-077-render", R, code=0, setup=umask(0o077), check=check_modes(0o600, 0o700)),
    Case("data", "umask-022-evaluate-and-report", EV[:-2] + ("--quiet",), code=0, setup=umask(0o022),
         check=check_modes(0o644, 0o755)),
    Case("data", "umask-077-evaluate-and-report", EV[:-2] + ("--quiet",), code=0, setup=umask(0o077),
         check=check_modes(0o600, 0o700)),
]


# ------------------------------------------------------------------------------------------------ fixtures


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    """data/ (one 64 x 32 synthetic_box frame), results/ (evaluate --no-report on it) and a_file."""
    t = tmp_path_factory.mktemp("template")
    write_frame(make_synthetic_frame(64), t / "data")
    code, _ = run_cli(["evaluate", str(t / "data"), "--out", str(t / "results"), "--flow", "oracle", "--variants",
                       "average", "--no-report", "--quiet"])
    assert code == 0, "the template results could not be made"
    code, _ = run_cli(["reconstruct", str(t / "data" / "synthetic_box" / "vp000"), "--out", str(t / "preds"),
                       "--flow", "oracle", "--variant", "average", "--quiet"])
    assert code == 0, "the template predictions could not be made"
    (t / "a_file").write_text("I am a file, not a directory\n")
    (t / "study.toml").write_text('[render]\nscene = "synthetic_box"\nwidth = 64\n\n[evaluate]\n'
                                  'method = ["oracle-rect:average"]\n')
    return t


@pytest.fixture()
def env(tmp_path, template):
    e = Env(tmp_path / "case")
    shutil.copytree(template, e.tmp)
    yield e
    for fn in reversed(e.cleanups):
        fn()


# ------------------------------------------------------------------------------------------------ the test


def test_catalogue_size():
    groups = {}
    for c in CASES:
        groups[c.group] = groups.get(c.group, 0) + 1
    assert len(CASES) >= 40 and set(groups) == {"render", "scenes", "reconstruct", "evaluate", "score", "report",
                                                 "study", "data"}
    assert len({(c.group, c.name) for c in CASES}) == len(CASES)


#: the cases that run a whole evaluate or report, place many viewpoints or render twice: a second or more each
#: (marked ``slow``)
SLOW_CASES = {"render-viewpoints-more-than-fit", "report-cleans-leftovers-of-killed-runs",
              "report-results-of-the-previous-release", "report-results-csv-variant-escapes",
              "report-results-csv-method-escapes", "data-umask-022-evaluate-and-report",
              "data-umask-077-evaluate-and-report", "render-rerun-repairs-corrupt-frame",
              "evaluate-cleans-leftovers-of-killed-runs", "render-rerun-other-baseline", "render-rerun-other-width",
              "render-rerun-other-seed", "render-cleans-leftovers-of-killed-runs"}


def test_every_slow_case_is_in_the_catalogue():
    assert SLOW_CASES <= {f"{c.group}-{c.name}" for c in CASES}


@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.slow) if f"{c.group}-{c.name}" in SLOW_CASES else c
                                  for c in CASES], ids=[f"{c.group}-{c.name}" for c in CASES])
def test_bad_input(case: Case, env: Env, capfd, monkeypatch):
    if case.setup is not None:
        case.setup(env, monkeypatch)
    capfd.readouterr()
    before = snapshot(env.tmp)
    argv = [env.fmt(a) for a in case.argv]
    code, parser_error = run_cli(argv)
    out, err = capfd.readouterr()
    assert "Traceback" not in out + err, err
    if case.code == 2:
        assert code == 2, f"exit status {code}, expected 2; stderr: {err!r}"
        lines = [line for line in err.splitlines() if line.strip()]
        errors = [line for line in lines if ": error: " in line]
        assert len(errors) == 1, f"expected one error line, got: {lines}"
        if parser_error:  # argparse: usage lines, then its one error line
            assert all(line.startswith(("usage:", " ")) for line in lines if line != errors[0]), lines
        else:
            assert lines == errors and errors[0].startswith(f"tri360 {argv[0]}: error: "), lines
        for c in case.culprit:
            assert env.fmt(c) in errors[0], f"{env.fmt(c)!r} not named in {errors[0]!r}"
        for f in case.forbid:
            assert f not in errors[0], f"{f!r} in {errors[0]!r}"
        assert snapshot(env.tmp) == before, "a failing command wrote or changed files"
    else:
        assert code == case.code, f"exit status {code}, expected {case.code}; stderr: {err!r}"
        case.check(env, out, err)
        if case.unchanged:
            assert snapshot(env.tmp) == before, "nothing may change"
    assert staging_leftovers(env.tmp) == [], "hidden .partial/.old entries left behind"
