"""Output locations: what a command may write into, checked before any work; result sets swapped in whole.

**Only what tri360 wrote is ever replaced.**  Every output directory carries a marker, ``.tri360-output.json`` =
``{"format": "tri360-output/1", "kind": KIND, "entries": [top-level names tri360 wrote]}``, of one of seven kinds
(:data:`KINDS`): ``export`` (frames in a learned method's layout: ``export``; only the marker's entries and
``manifest.json`` are its own), ``data`` (a data root of frames: ``render``, ``perturb``, ``import``),
``predictions`` (a ``tri360-pred/1`` root: ``reconstruct``), ``results`` (a results set: ``evaluate``, ``score``,
``report``), ``study`` (a grid study: ``study``), ``robustness`` (a robustness study: ``study`` with a robustness
study file) and ``validation`` (``validate_quality``).  No command replaces another kind's output: a validation is not a
study, a grid study not a robustness study.  A marker written when the three shared the kind ``study`` is read by
content (``robustness.csv`` or robustness points: a robustness study; ``validation.json``/``validation.csv``: a
validation).
:func:`check_output` lets a command write into ``path`` only when it is

- absent, or an empty directory (staging leftovers of killed tri360 runs do not count), or
- a directory of the same kind that tri360 wrote: its marker says so, or -- directories written before markers
  existed -- its content does (a results set: ``results.csv`` or a ``tri360-results/1`` ``config.json``; a data
  root: ``<scene>/<viewpoint>/frame.json``; a predictions root: a ``tri360-pred/1`` ``method.json`` or
  ``<scene>/<viewpoint>/distance.exr``; a study: ``points.json``; a validation: ``validation.json`` or
  ``validation.csv``), and it holds nothing else than what tri360
  writes there (:func:`foreign_entries`: in a data root only ``<scene>/<viewpoint>/`` directories of a frame's
  files, in a predictions root only those of predictions and ``method.json``, in a results set or a study only
  the names they write);

and never when ``path`` is one of the command's inputs (data root, frame directories, predictions roots, a study
file), inside one, or a parent of one, compared by real path (symbolic links resolved).  Anything else is refused
with one line naming the path and what is in it.  :func:`mark_output` writes the marker (atomically) once the
command has written its output.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from harness.data import jsonio
from harness.data.atomic import atomic_directory, atomic_write_text, clean_stale_siblings, parse_staging_name
from harness.data.errors import UserError
from harness.data.predictions import FORMAT as PRED_FORMAT

__all__ = ["MARKER", "MARKER_FORMAT", "KINDS", "RESULTS_FORMAT", "check_output", "mark_output", "read_marker",
           "output_kind", "foreign_entries", "check_output_dir", "ensure_output_dir", "staged_directory"]

MARKER = ".tri360-output.json"
MARKER_FORMAT = "tri360-output/1"
KINDS = {"data": "data root", "predictions": "predictions root", "results": "results set",
         "study": "grid study directory", "robustness": "robustness study directory",
         "validation": "quality validation directory", "export": "export directory"}
"""The kinds of output directory -> what the messages call them."""

#: what ``evaluate``/``score`` and ``report`` write at the top of a results set (directories: not looked into)
RESULTS_FILES = frozenset({
    "results.csv", "results.json", "regions.csv", "breakdown.csv", "frames.json", "config.json", "leaderboard.csv",
    "leaderboard.md", "mae.md", "mae.csv", "fig4_mae.png", "sparsification.png", "error_vs_angle.png",
    "error_by_distance_texture.png", "report.html"})
RESULTS_DIRS = frozenset({"maps", "figures", "clouds"})
#: what a frame directory holds (``tri360-frame/1``, the render log, per-camera maps of a later format)
_FRAME_FILE_RE = re.compile(r"^(frame\.json|render_log\.json|[CUR]\.png|[CUR]\.[A-Za-z0-9_]+\.(exr|png))$")
PREDICTION_FILES = frozenset({"distance.exr", "confidence.exr", "quality.exr", "cloud.ply", "reconstruction.json"})
STUDY_FILES = frozenset({"points.json", "study.csv", "study.md"})
ROBUSTNESS_FILES = frozenset({"points.json", "robustness.csv", "robustness.md"})
STUDY_DIRS = frozenset({"data", "results"})
VALIDATION_FILES = frozenset({"validation.csv", "calibration.csv", "validation.json", "validation.md"})
OS_LITTER = frozenset({".DS_Store", "Thumbs.db", "desktop.ini"})
"""Folder-view files of macOS / Windows: nobody's data, so they neither make a directory foreign nor non-empty."""
RESULTS_FORMAT = "tri360-results/1"
EXPORT_FORMAT = "tri360-export/1"
"""The ``format`` of an export's ``manifest.json`` (:mod:`harness.data.layouts`)."""
"""The ``format`` of a results set's ``config.json``."""


# ------------------------------------------------------------------------------------------- the marker


def _entries(path: Path) -> list[str]:
    """The names in ``path``, without the marker, tri360 staging leftovers (``.x.partial-...``) and the files
    desktop systems drop into every folder they show (:data:`OS_LITTER`)."""
    try:
        names = os.listdir(path)
    except OSError:
        return []
    return sorted(n for n in names if n != MARKER and n not in OS_LITTER and parse_staging_name(n) is None)


def read_marker(path: Path) -> dict | None:
    """``path``'s marker ``{"format", "kind", "entries"}``, or None when it has none.

    Raises:
        UserError: the marker exists but is not a tri360 output marker (naming it).
    """
    m = Path(path) / MARKER
    if not os.path.lexists(m):
        return None
    try:
        raw = json.loads(m.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UserError(f"{m}: not a readable tri360 output marker ({exc}); remove it only if you know what wrote "
                        f"{path}") from None
    if (not isinstance(raw, dict) or raw.get("format") != MARKER_FORMAT or raw.get("kind") not in KINDS
            or not isinstance(raw.get("entries", []), list)):
        raise UserError(f"{m}: not a tri360 output marker (expected format {MARKER_FORMAT!r} and a kind of "
                        f"{', '.join(KINDS)})")
    return raw


def mark_output(path: Path, kind: str) -> None:
    """Write ``path``'s marker (atomically): it is a ``kind`` directory, and every entry now in it is tri360's.

    Call it once the command has written into ``path`` (which :func:`check_output` has accepted first), so the
    marker lists what was written; ``path`` is created if needed, and an identical marker is left as it is.
    """
    if kind not in KINDS:
        raise ValueError(f"unknown output kind {kind!r}")
    path = Path(path)
    text = jsonio.dumps({"format": MARKER_FORMAT, "kind": kind, "entries": _entries(path)})
    with contextlib.suppress(OSError):
        if (path / MARKER).read_text(encoding="utf-8") == text:
            return  # the same marker: leave the directory untouched
    atomic_write_text(path / MARKER, text)


# ----------------------------------------------------------------------------------- content of a directory


def _json_format(path: Path) -> str | None:
    """The ``format`` of a small JSON file, or None (missing, unreadable, not an object)."""
    try:
        if path.stat().st_size > 1 << 22:
            return None
        raw = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    return raw.get("format") if isinstance(raw, dict) else None


def _frame_foreign(d: Path, rel: str) -> list[str]:
    """Entries of frame directory ``d`` that are not a frame's files (``rel``: its path for messages).  A broken
    frame (e.g. a corrupt ``frame.json``, which ``render`` repairs) still consists of a frame's files."""
    return [f"{rel}/{n}" for n in _entries(d) if not (_FRAME_FILE_RE.match(n) and (d / n).is_file())]


def _two_level_foreign(root: Path, top: list[str], leaf) -> list[str]:
    """``root/<a>/<b>`` layouts (data and predictions roots): ``leaf(dir, rel)`` judges each ``<b>``."""
    out = []
    for a in top:
        pa = root / a
        if not pa.is_dir():
            out.append(a)
            continue
        for b in _entries(pa):
            pb = pa / b
            if not pb.is_dir():
                out.append(f"{a}/{b}")
            elif _entries(pb):
                out.extend(leaf(pb, f"{a}/{b}"))
    return out


def _pred_leaf(d: Path, rel: str) -> list[str]:
    return [f"{rel}/{n}" for n in _entries(d) if n not in PREDICTION_FILES or not (d / n).is_file()]


def foreign_entries(path: Path, kind: str, listed: Iterable[str] = ()) -> list[str]:
    """What is in ``path`` that tri360 does not write into a ``kind`` directory (paths relative to ``path``).

    ``listed``: top-level names a marker records as written by tri360 (trusted, for files that later versions
    add).  Staging leftovers of tri360 runs and the marker itself never count.
    """
    path = Path(path)
    listed = set(listed)
    top = _entries(path)
    if kind == "data":  # <scene>/<viewpoint>/ frames; nothing else
        return _two_level_foreign(path, [n for n in top if not (n in listed and (path / n).is_file())],
                                  _frame_foreign)
    if kind == "predictions":  # method.json, <scene>/<viewpoint>/{distance,confidence}.exr, reconstruction.json
        return _two_level_foreign(path, [n for n in top if not (n in listed and (path / n).is_file())
                                         and not (n == "method.json" and (path / n).is_file())], _pred_leaf)
    if kind == "results":
        return [n for n in top if n not in listed and not (n in RESULTS_FILES and (path / n).is_file())
                and not (n in RESULTS_DIRS and (path / n).is_dir())]
    if kind in ("study", "robustness"):
        files = STUDY_FILES if kind == "study" else ROBUSTNESS_FILES
        return [n for n in top if n not in listed and not ((n in files or n.endswith(".png"))
                                                           and (path / n).is_file())
                and not (n in STUDY_DIRS and (path / n).is_dir())]
    if kind == "validation":
        return [n for n in top if n not in listed and not (n in VALIDATION_FILES and (path / n).is_file())]
    if kind == "export":
        return [n for n in top if n not in listed and not (n == "manifest.json" and (path / n).is_file())]
    raise ValueError(f"unknown output kind {kind!r}")


def output_kind(path: Path) -> str | None:
    """The kind of tri360 output directory ``path`` is: its marker's, else what its content shows (directories
    written before markers existed), else None."""
    path = Path(path)
    marker = read_marker(path)
    if marker is not None:
        return _study_kind(path) if marker["kind"] == "study" else marker["kind"]
    if not path.is_dir():
        return None
    if (path / "results.csv").is_file() or _json_format(path / "config.json") == RESULTS_FORMAT:
        return "results"
    if (path / "validation.json").is_file() or (path / "validation.csv").is_file():
        return "validation"
    if (path / "points.json").is_file() and ((path / "data").is_dir() or (path / "results").is_dir()
                                             or (path / "study.csv").is_file()
                                             or (path / "robustness.csv").is_file()):
        return _study_kind(path)
    if _json_format(path / "manifest.json") == EXPORT_FORMAT:
        return "export"
    if _json_format(path / "method.json") == PRED_FORMAT:
        return "predictions"
    for a in _entries(path):
        pa = path / a
        if pa.is_dir():
            for b in _entries(pa):
                if (pa / b / "frame.json").is_file():
                    return "data"
                if (pa / b / "distance.exr").is_file():
                    return "predictions"
    return None


def _robustness_points(path: Path) -> bool:
    """True if ``path`` is a robustness study's ``points.json`` (a list of points naming a perturbation kind)."""
    try:
        if path.stat().st_size > 1 << 22:
            return False
        raw = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return False
    return isinstance(raw, list) and bool(raw) and all(isinstance(p, dict) and "kind" in p for p in raw)


def _study_kind(path: Path) -> str:
    """Which of the kinds once marked ``study`` ``path`` is, by its content: ``robustness``, ``validation`` or
    ``study`` (a grid study)."""
    if (path / "robustness.csv").is_file() or _robustness_points(path / "points.json"):
        return "robustness"
    if (path / "validation.json").is_file() or (path / "validation.csv").is_file():
        return "validation"
    return "study"


# ------------------------------------------------------------------------------------------------- the check


def _holds_files(path: Path) -> bool:
    """True if anything but directories and tri360 staging leftovers is under ``path``."""
    for _dirpath, dirnames, filenames in os.walk(path):
        if any(n != MARKER and n not in OS_LITTER and parse_staging_name(n) is None for n in filenames):
            return True
        dirnames[:] = [d for d in dirnames if parse_staging_name(d) is None]
    return False


def _real(p: Path) -> Path:
    return Path(os.path.realpath(os.path.abspath(p)))


def _check_not_input(path: Path, inputs: Iterable[Path]) -> None:
    real = _real(path)
    for inp in inputs:
        ri = _real(Path(inp))
        if real == ri:
            why = f"is an input of this command ({inp})"
        elif real.is_relative_to(ri):
            why = f"is inside an input of this command ({inp})"
        elif ri.is_relative_to(real):
            why = f"holds an input of this command ({inp})"
        else:
            continue
        raise UserError(f"{path}: output directory {why}; an output is never an input, inside one or a parent of "
                        "one: choose another output directory")


def _describe(entries: list[str]) -> str:
    n = len(entries)
    return f"{n} entr{'y' if n == 1 else 'ies'} not written by tri360, e.g. {entries[0]}"


def check_output(path: Path, kind: str, inputs: Iterable[Path] = ()) -> Path:
    """Refuse ``path`` as the output of a command that writes a ``kind`` directory unless it is absent, empty, or
    a ``kind`` directory tri360 wrote with nothing else in it; refuse it too when it is one of ``inputs``, inside
    one or a parent of one (real paths).  Also checks that it can be written (:func:`check_output_dir`).
    Nothing is created or changed.

    Args:
        path: the output directory (``--out``; for ``report`` the results set).
        kind: one of :data:`KINDS`.
        inputs: the command's inputs (data root, frame directories, predictions roots, files).
    Returns:
        ``path``.
    Raises:
        UserError: one line naming ``path`` and what is in it (or which input it is).
    """
    if kind not in KINDS:
        raise ValueError(f"unknown output kind {kind!r}")
    path = Path(path)
    _check_not_input(path, inputs)
    if os.path.lexists(path) and not path.is_dir():
        raise UserError(f"{path}: output path exists and is not a directory")
    if path.is_dir() and _entries(path):
        marker = read_marker(path)
        found = output_kind(path)
        what = KINDS[kind]
        if found is not None and found != kind:
            how = "its marker " + MARKER if marker is not None else "its content"
            raise UserError(f"{path}: is a tri360 {KINDS[found]} ({how} says so), not a {what}; tri360 writes a "
                            f"{what} only into an absent or empty directory or a {what} it wrote: choose another "
                            "output directory")
        if found is None and (path / "frame.json").is_file():
            raise UserError(f"{path}: is a frame directory (it holds frame.json), not a {what}: choose another "
                            "output directory")
        foreign = foreign_entries(path, kind, marker.get("entries", []) if marker else ())
        if found is None and not foreign and _holds_files(path):  # tri360's names, but none of its signature files
            foreign = _entries(path)
        if foreign:
            raise UserError(f"{path}: holds {_describe(foreign)} (as a {what}); tri360 writes a {what} only into an "
                            f"absent or empty directory or a {what} it wrote: choose another output directory")
    return check_output_dir(path)


def ensure_output_dir(path: Path) -> Path:
    """Create ``path`` (and parents) if needed and check that files can be created in it.

    Raises:
        UserError: one line naming the path and why it is unusable (a file is in the way, read-only file
            system, no permission, a virtual file system such as /proc, ...).
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise UserError(f"{path}: output path exists and is not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path, prefix=".tri360-write-test-"):
            pass
    except OSError as exc:
        raise UserError(f"{path}: output directory is not writable ({exc.strerror or exc})") from None
    return path


def check_output_dir(path: Path) -> Path:
    """Check, without creating anything, that ``path`` can be used as an output directory: it is a writable
    directory, or it does not exist and its nearest existing ancestor is a writable directory.

    Raises:
        UserError: one line naming the path and why it is unusable.
    """
    path = Path(path)
    probe = path
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        where = "output path" if probe == path else f"{probe} (on the output path)"
        raise UserError(f"{path}: {where} exists and is not a directory")
    try:
        with tempfile.NamedTemporaryFile(dir=probe, prefix=".tri360-write-test-"):
            pass
    except OSError as exc:
        raise UserError(f"{path}: output directory is not writable ({probe}: {exc.strerror or exc})") from None
    return path


@contextlib.contextmanager
def staged_directory(target: Path) -> Iterator[Path]:
    """Build a directory's new contents in a hidden sibling, then swap it in place of ``target``.

    The previous ``target`` is deleted as a whole: call :func:`check_output` first (it must be absent, empty or a
    directory of the same kind that tri360 wrote), and :func:`mark_output` on the staging directory at the end.

    Checks first (before the caller does any work) that ``target`` can be replaced: it is a directory or
    absent, its parent is writable, and an existing ``target`` is writable too; leftovers of killed runs
    beside it are removed.  Yields the staging directory (:func:`harness.data.atomic.atomic_directory`); on
    normal exit the previous ``target`` is replaced as a whole, on any exception (Ctrl-C included) the
    staging directory is removed and ``target`` is left as it was.

    Raises:
        UserError: one line naming ``target`` and what is wrong with it.
    """
    target = Path(target)
    if target.exists() and not target.is_dir():
        raise UserError(f"{target}: output path exists and is not a directory")
    ensure_output_dir(target.parent if str(target.parent) else Path("."))
    if target.exists():
        ensure_output_dir(target)
    clean_stale_siblings(target)
    try:
        with atomic_directory(target) as stage:
            yield stage
    except OSError as exc:
        raise UserError(f"{exc.filename or target}: cannot write the results ({exc.strerror or exc})") from None
