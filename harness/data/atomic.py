"""Atomic writes: a file or directory appears under its final name complete, or not at all.

Every output of tri360 goes through this module.  A file is written to a hidden sibling and renamed into
place; a directory (a frame) is assembled in a hidden sibling and swapped into place.  Hidden siblings are
named so that a later run can tell whose they are::

    .<name>.partial-<pid>-<token>[<suffix>]    being written by process <pid> (token: 8 hex digits)
    .<name>.old-<pid>-<token>                  a replaced directory, about to be deleted by process <pid>

:func:`clean_stale_partials` (everything under a directory) and :func:`clean_stale_siblings` (the entries of one
target, beside it) remove the ones whose process is gone (a killed run) or that are older than a given age.

Permissions: files are created with mode ``0o666`` and directories with ``0o777``, *through* the kernel,
which applies the process umask (and a directory's default ACL, if any) exactly as for ``open()`` or
``mkdir`` -- so outputs get ``0o666 & ~umask`` / ``0o777 & ~umask`` (0644 / 0755 under the usual umask 022).
No umask is read or changed, so there is no race between threads.  (``tempfile.mkstemp``/``mkdtemp``, used
before, force 0600 / 0700.)  :func:`current_umask` reads it without changing it, for checks and reports.

Concurrency: two processes may write the same target at once (two ``--force`` renders of one frame); each
write is complete and the last one to finish wins.  Directory replacement uses Linux ``renameat2`` with
``RENAME_EXCHANGE`` (the old and the new directory swap names in one step, so readers never see the frame
missing) and falls back to rename-aside-then-rename with a bounded retry where that is unavailable.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import re
import secrets
import shutil
import stat
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

__all__ = [
    "FILE_MODE",
    "DIR_MODE",
    "current_umask",
    "atomic_write_bytes",
    "atomic_write_text",
    "atomic_write_via",
    "atomic_directory",
    "replace_directory",
    "exchange_supported",
    "staging_path",
    "parse_staging_name",
    "clean_stale_partials",
    "clean_stale_siblings",
]

FILE_MODE = 0o666  # requested mode of new files; the kernel applies the umask
DIR_MODE = 0o777  # requested mode of new directories; the kernel applies the umask
REPLACE_ATTEMPTS = 50  # bounded retry when other processes keep replacing the same directory
DEFAULT_STALE_AGE_S = 6 * 3600.0  # staging entries of a live process older than this are considered abandoned

_STAGING_RE = re.compile(
    r"^\.(?P<name>.+)\.(?P<kind>partial|old)-(?P<pid>\d+)-(?P<token>[0-9a-f]{8})(?P<suffix>\.[^.]*)?$")
# what tri360 wrote before this module (tempfile names: 8 characters of [a-z0-9_]); the pid is only known for .old
_LEGACY_RES = (
    re.compile(r"^\.(?P<name>.+)\.partial-[a-z0-9_]{8}$"),  # mkdtemp frame staging
    re.compile(r"^\.(?P<name>.+)\.old-(?P<pid>\d+)$"),  # renamed-aside frame
    re.compile(r"^\.(?P<name>.+)\.[a-z0-9_]{8}\.partial$"),  # mkstemp file staging
    re.compile(r"^\.(?P<name>.+)\.partial\.[a-z0-9_]{8}(\.[^.]*)?$"),  # mkstemp staging with a suffix
)
_umask_lock = threading.Lock()


# ------------------------------------------------------------------------------------------------- helpers


def current_umask() -> int:
    """The process umask, read without changing it (``Umask:`` of ``/proc/self/status``, Linux >= 4.7).

    Where ``/proc`` does not say, falls back to setting and restoring it under a lock (``os.umask`` has no
    read-only form); that is only atomic with respect to other callers of this function.
    """
    try:
        with open("/proc/self/status", encoding="ascii", errors="replace") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    with _umask_lock:
        old = os.umask(0o077)
        os.umask(old)
    return old


def staging_path(path: Path, kind: str = "partial", suffix: str = "") -> Path:
    """A hidden sibling of ``path`` owned by this process: ``.<name>.<kind>-<pid>-<token><suffix>``."""
    path = Path(path)
    return path.with_name(f".{path.name}.{kind}-{os.getpid()}-{secrets.token_hex(4)}{suffix}")


def parse_staging_name(name: str) -> tuple[str, int | None] | None:
    """``(kind, pid)`` if ``name`` is a staging entry written by tri360 (pid None for old-style names without
    one), else None.  ``kind`` is ``"partial"`` or ``"old"``."""
    parsed = _parse(name)
    return None if parsed is None else parsed[1:]


def _parse(name: str) -> tuple[str, str, int | None] | None:
    """``(name of the final entry, kind, pid)`` of a staging entry, else None."""
    m = _STAGING_RE.match(name)
    if m:
        return m["name"], m["kind"], int(m["pid"])
    for rx in _LEGACY_RES:
        m = rx.match(name)
        if m:
            pid = m.groupdict().get("pid")
            return m["name"], ("old" if ".old-" in name else "partial"), (int(pid) if pid else None)
    return None


def _named_error(exc: OSError, path: Path) -> OSError:
    """The same error (same errno, so the same OSError subclass), naming ``path`` rather than a temporary."""
    return OSError(exc.errno, exc.strerror or str(exc), os.fspath(path))


def _create_file(path: Path, suffix: str = "") -> tuple[int, Path]:
    """Create a new staging file beside ``path`` (exclusive, mode 0o666 & ~umask) -> (fd, staging path)."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    for _ in range(16):
        tmp = staging_path(path, "partial", suffix)
        try:
            return os.open(tmp, flags, FILE_MODE), tmp
        except FileExistsError:  # 32-bit token collision: astronomically rare, try another
            continue
        except OSError as exc:  # read-only file system, no permission, ...: name the file we meant to write
            raise _named_error(exc, path) from None
    raise FileExistsError(errno.EEXIST, "could not create a unique temporary file", os.fspath(path))


def _make_parent(path: Path) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)  # Path.mkdir uses mode 0o777: the umask applies
    except FileExistsError as exc:  # a file is in the way of a directory
        raise NotADirectoryError(errno.ENOTDIR, "exists and is not a directory",
                                 exc.filename or os.fspath(path.parent)) from None


# --------------------------------------------------------------------------------------------------- files


def atomic_write_bytes(path: Path, data: bytes, fsync: bool = True) -> None:
    """Write ``data`` to ``path``: a hidden sibling is written (and fsync'ed) then renamed into place.

    The file gets mode ``0o666 & ~umask``.  An existing file at ``path`` is replaced; a directory at ``path``
    is an error (``IsADirectoryError`` naming ``path``).
    """
    path = Path(path)
    _make_parent(path)
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a directory, cannot write a file there", os.fspath(path))
    fd, tmp = _create_file(path)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            if fsync:
                os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError):
            raise _named_error(exc, path) from None
        raise


def atomic_write_text(path: Path, text: str, fsync: bool = True) -> None:
    """:func:`atomic_write_bytes` of ``text`` encoded as UTF-8."""
    atomic_write_bytes(path, text.encode("utf-8"), fsync=fsync)


def atomic_write_via(path: Path, writer: Callable[[str], object]) -> None:
    """For libraries that write by file name: call ``writer(tmp)`` with a hidden sibling path that ends in
    ``path``'s suffix (libraries pick the format from it), then rename ``tmp`` onto ``path``.

    The temporary is created first (mode ``0o666 & ~umask``), so a writer that truncates and rewrites it keeps
    that mode.  If ``writer`` raises, the temporary is removed and ``path`` is left as it was.
    """
    path = Path(path)
    _make_parent(path)
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a directory, cannot write a file there", os.fspath(path))
    fd, tmp = _create_file(path, suffix=path.suffix)
    os.close(fd)
    try:
        writer(os.fspath(tmp))
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) and exc.filename in (None, os.fspath(tmp)):
            raise _named_error(exc, path) from None
        raise


# --------------------------------------------------------------------------------------------- directories

_AT_FDCWD = -100
_RENAME_EXCHANGE = 2


_renameat2_fn = None
_exchange_supported: bool | None = None  # None: not looked up yet (no work at import time)


def exchange_supported() -> bool:
    """True if directories can be swapped in one step here (Linux ``renameat2`` with ``RENAME_EXCHANGE``, glibc
    >= 2.28); a file system that refuses the flag turns this False on first use."""
    global _renameat2_fn, _exchange_supported
    if _exchange_supported is None:
        try:
            fn = ctypes.CDLL(None, use_errno=True).renameat2
            fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
            fn.restype = ctypes.c_int
            _renameat2_fn, _exchange_supported = fn, True
        except (OSError, AttributeError):  # not Linux / glibc without renameat2
            _exchange_supported = False
    return bool(_exchange_supported)


def _exchange(a: Path, b: Path) -> str:
    """Swap the names of ``a`` and ``b`` in one step.  Returns ``"done"``, ``"missing"`` (one of them does
    not exist) or ``"unsupported"`` (no renameat2, or the file system cannot exchange)."""
    global _exchange_supported
    if not exchange_supported() or _renameat2_fn is None:
        return "unsupported"
    rc = _renameat2_fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    if rc == 0:
        return "done"
    err = ctypes.get_errno()
    if err == errno.ENOENT:
        return "missing"
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP):
        _exchange_supported = False
        return "unsupported"
    raise OSError(err, os.strerror(err), os.fspath(b))


def replace_directory(staging: Path, target: Path, attempts: int = REPLACE_ATTEMPTS) -> None:
    """Move the complete directory ``staging`` to ``target``, replacing a previous ``target`` if any.

    Safe when several processes replace the same ``target`` concurrently: each attempt either renames into an
    absent ``target``, or swaps with the present one (``renameat2(RENAME_EXCHANGE)``; the previous contents
    end up under ``staging`` and are deleted), or -- without exchange support -- renames the present one
    aside to ``.<name>.old-<pid>-<token>`` and tries again.  ``target`` vanishing or reappearing between
    steps just costs another attempt.

    Raises:
        NotADirectoryError: ``target`` exists and is not a directory (it is left alone).
        OSError: after ``attempts`` attempts, or any other file system error (naming ``target``).
    """
    staging, target = Path(staging), Path(target)
    olds: list[Path] = []
    try:
        for _ in range(attempts):
            try:
                os.rename(staging, target)  # succeeds if target is absent (or an empty directory)
                return
            except OSError as exc:
                if exc.errno == errno.ENOTDIR:
                    raise NotADirectoryError(errno.ENOTDIR, "exists and is not a directory",
                                             os.fspath(target)) from None
                if exc.errno not in (errno.ENOTEMPTY, errno.EEXIST):
                    raise _named_error(exc, target) from None
            # target is a non-empty directory
            how = _exchange(staging, target)
            if how == "done":
                shutil.rmtree(staging, ignore_errors=True)  # holds the previous contents now
                return
            if how == "missing":
                continue
            old = staging_path(target, "old")
            try:
                os.rename(target, old)
            except FileNotFoundError:
                continue  # someone else moved it first: try again
            olds.append(old)
        raise OSError(errno.EBUSY, f"could not replace it after {attempts} attempts (other processes keep "
                                   "replacing it)", os.fspath(target))
    finally:
        for old in olds:
            shutil.rmtree(old, ignore_errors=True)


@contextlib.contextmanager
def atomic_directory(target: Path) -> Iterator[Path]:
    """Build a directory in a hidden sibling and move it into place as a whole.

    Yields the staging directory ``.<name>.partial-<pid>-<token>`` (same parent, so the same file system;
    mode ``0o777 & ~umask``).  On normal exit it replaces ``target`` (:func:`replace_directory`); on any
    exception, Ctrl-C included, it is deleted and ``target`` is left as it was.

    Raises:
        NotADirectoryError: ``target`` or one of its parents exists and is not a directory (checked before
            the caller's block runs, and again at the end).
    """
    target = Path(target)
    _make_parent(target)
    if target.exists() and not target.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, "exists and is not a directory", os.fspath(target))
    staging = None  # ours once os.mkdir has made it: removed on any exception, one raised by a signal handler
    # between the mkdir and the next statement included (Ctrl-C, SIGTERM)
    try:
        for _ in range(16):
            staging = staging_path(target, "partial")
            try:
                os.mkdir(staging, DIR_MODE)
                break
            except FileExistsError:  # someone else's: never ours to remove
                staging = None
                continue
            except OSError as exc:
                staging = None
                raise _named_error(exc, target.parent) from None
        if staging is None:
            raise FileExistsError(errno.EEXIST, "could not create a unique staging directory", os.fspath(target))
        yield staging
        replace_directory(staging, target)
    except BaseException:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
        raise


# ----------------------------------------------------------------------------------------------- cleaning


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    except OSError:
        return True  # cannot tell: keep it
    return True


def _remove_if_stale(p: Path, pid: int | None, max_age_s: float, now: float) -> bool:
    """Remove staging entry ``p`` if its process is gone or it is older than ``max_age_s``; True if removed."""
    try:
        st = p.lstat()
    except FileNotFoundError:
        return False
    too_old = now - st.st_mtime > max_age_s
    dead = pid is not None and not _pid_alive(pid)
    if not (too_old or dead):
        return False
    if stat.S_ISDIR(st.st_mode):
        shutil.rmtree(p, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            p.unlink()
    return not os.path.lexists(p)


def clean_stale_partials(root: Path, max_age_s: float = DEFAULT_STALE_AGE_S, now: float | None = None) -> list[Path]:
    """Remove the hidden staging leftovers of killed runs anywhere under ``root`` (recursively).

    An entry (see the module doc for the names) is removed when the process that made it is no longer running,
    or when it is older than ``max_age_s`` seconds (modification time; covers pid reuse and entries made on
    another host of a shared file system).  Old-style names without a pid are removed on age alone.  Entries
    of the calling process count as running.  Everything else is untouched, and staging directories are not
    descended into.

    Args:
        root: a data root, results directory, or any directory tri360 writes into; missing is fine.
        max_age_s: age limit, seconds.
        now: the current time (``time.time()``), for tests.
    Returns:
        The removed paths, sorted.
    """
    root = Path(root)
    now = time.time() if now is None else now
    removed = []
    if not root.is_dir():
        return removed
    for dirpath, dirnames, filenames in os.walk(root):
        for name in [*dirnames, *filenames]:
            parsed = _parse(name)
            if parsed is not None and _remove_if_stale(Path(dirpath) / name, parsed[2], max_age_s, now):
                removed.append(Path(dirpath) / name)
        dirnames[:] = [d for d in dirnames if _parse(d) is None]
    return sorted(removed)


def clean_stale_siblings(target: Path, max_age_s: float = DEFAULT_STALE_AGE_S, now: float | None = None) -> list[Path]:
    """Like :func:`clean_stale_partials`, but only for the staging entries of ``target`` itself, beside it
    (``.<target name>.partial-*`` / ``.old-*`` in its parent; nothing else in the parent is looked at).

    Returns:
        The removed paths, sorted.
    """
    target = Path(target)
    now = time.time() if now is None else now
    parent = target.parent if str(target.parent) else Path(".")
    removed = []
    try:
        names = os.listdir(parent)
    except OSError:
        return removed
    for name in names:
        parsed = _parse(name)
        if parsed is not None and parsed[0] == target.name and _remove_if_stale(parent / name, parsed[2], max_age_s,
                                                                              now):
            removed.append(parent / name)
    return sorted(removed)
