"""Keep the chatter of C/C++ libraries (libpng, OpenEXR) off the user's terminal while we decode a file.

OpenEXR 3.5.3's core library prints ``<file>: (EXR_ERR_...) ...`` to file descriptor 2 for a damaged file, and
its Python binding prints ``Warning: Exception raised reading pixel data ...`` to file descriptor 1; libpng
prints ``libpng error: ...`` to descriptor 2.  None of that goes through ``sys.stderr``, so Python cannot
catch it.  A command that fails on a bad input must print exactly one line naming the file, so the decoders
in this package run inside :func:`native_output_captured`: descriptors 1 and 2 point at a temporary file for
the duration of the call, and the text is handed back so that the caller can quote the library's reason in
its own one-line message.

**Process-wide, main thread only.**  File descriptors belong to the process, so a redirection cannot be per
call or per thread.  The capture is therefore done only on the main thread (where the commands decode their
inputs and report bad ones); on any other thread (a Dask worker thread, a study's thread pool)
:func:`native_output_captured` does nothing (``Captured.active`` is False): decodes there run in parallel,
unserialised, and their library messages go to the process's real descriptors (a worker's log), while the error
raised still names the file.  While the main thread captures, output that *other* threads write to the
descriptors lands in the capture too: it is written back to the real stderr when the caller says the decode
succeeded (``Captured.release()``), and summarised in the caller's error message otherwise.  A nested capture is
a no-op.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import re
import sys
import tempfile
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field

__all__ = ["Captured", "native_output_captured", "first_library_message"]

# OpenCV's log prefix, e.g. "[ WARN:0@1.190] global grfmt_png.cpp:678 read_from_io "
_OPENCV_PREFIX = re.compile(r"^\[\s*(?:WARN|ERROR|INFO|DEBUG)[^\]]*\]\s*(?:global\s+\S+:\d+\s+\S+\s+)?")
_DEPTH = [0]  # captures open on the main thread (only the main thread captures, so no lock is needed)


def _libc_fflush() -> None:
    """Flush C stdio buffers (C++ ``std::cout`` is synced with C ``stdout`` by default)."""
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # no libc symbol table (unusual platforms): nothing to flush
        pass


@dataclass
class Captured:
    """Text that native code wrote to descriptors 1 and 2 inside :func:`native_output_captured`.

    Attributes:
        text: everything captured (decoded as UTF-8 with replacement), filled when the block exits.
        active: False when nothing was captured (not the main thread, nested capture, or descriptors
            unavailable): the library's output went to the real descriptors.
    """

    text: str = ""
    active: bool = True
    _release: bool = field(default=False, repr=False)
    _done: bool = field(default=False, repr=False)

    def release(self) -> None:
        """Hand the captured text back to the real stderr (use after a successful decode, so that warnings or
        another thread's output are not swallowed): at once if the block has exited, else when it exits."""
        if self._done:
            _write_stderr(self.text)
        else:
            self._release = True


def _write_stderr(text: str) -> None:
    if text:
        with contextlib.suppress(Exception):
            sys.stderr.write(text)
            sys.stderr.flush()


@contextlib.contextmanager
def native_output_captured() -> Iterator[Captured]:
    """Redirect file descriptors 1 and 2 to a temporary file for the duration of the block, on the main thread
    only (see the module doc: descriptors are process-wide).

    Yields:
        A :class:`Captured` whose ``text`` holds the native output once the block has exited (inactive and empty
        on other threads and when nested).
    """
    if threading.current_thread() is not threading.main_thread() or _DEPTH[0]:
        yield Captured(active=False)
        return
    _DEPTH[0] = 1
    try:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        _libc_fflush()
        try:
            saved = (os.dup(1), os.dup(2))
        except OSError:  # descriptors closed (daemonised process): decode without capturing
            yield Captured(active=False)
            return
        captured = Captured()
        with tempfile.TemporaryFile() as sink:
            try:
                os.dup2(sink.fileno(), 1)
                os.dup2(sink.fileno(), 2)
                yield captured
            finally:
                _libc_fflush()
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
                os.close(saved[0])
                os.close(saved[1])
                sink.seek(0)
                captured.text = sink.read().decode("utf-8", errors="replace")
                captured._done = True
        if captured._release:
            _write_stderr(captured.text)
    finally:
        _DEPTH[0] = 0


def first_library_message(text: str, path: str | os.PathLike | None = None, limit: int = 160) -> str:
    """The first non-empty line of captured library output, shortened to one line of at most ``limit``
    characters, without a leading ``<path>:`` (the caller's message names the file already) or OpenCV's
    ``[ WARN:...] global <file>:<line> <function>`` log prefix."""
    for line in text.splitlines():
        line = _OPENCV_PREFIX.sub("", line.strip()).strip()
        if not line:
            continue
        if path is not None:
            for prefix in (f"{os.fspath(path)}:", f"{os.path.basename(os.fspath(path))}:"):
                if line.startswith(prefix):
                    line = line[len(prefix):].strip()
        return line if len(line) <= limit else line[: limit - 3] + "..."
    return ""
