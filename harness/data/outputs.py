"""Output locations: check them before any long computation, and swap whole result sets in atomically."""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Iterator
from pathlib import Path

from harness.data.atomic import atomic_directory, clean_stale_siblings
from harness.data.errors import UserError

__all__ = ["check_output_dir", "ensure_output_dir", "staged_directory"]


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
