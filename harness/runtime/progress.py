"""Progress of a long job, on stderr: a tqdm bar on a terminal; elsewhere (a log file, CI, ``make bench | tee``)
one plain line per finished item and no carriage returns.

Every long job makes its bar with :func:`progress_bar` (or iterates with :func:`track`), so the rule "a bar on a
terminal, lines in a log" lives here once.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterable, Iterator
from typing import TextIO, TypeVar

from tqdm import tqdm

__all__ = ["LineProgress", "progress_bar", "track"]

T = TypeVar("T")


class LineProgress:
    """The bar's interface (``update``, ``set_postfix_str``, ``close``, a context manager) printing one line per
    finished item: ``render: 3/12 views, 41.2 s (classroom/vp000/R 12.9s)``.  Disabled, it prints nothing.

    ``min_interval_s`` > 0 thins the lines of loops over many small items (pixels): at most one line per
    ``min_interval_s`` seconds, and always the line of the last item.
    """

    def __init__(self, total: int | None, desc: str, unit: str, enabled: bool, stream: TextIO,
                 min_interval_s: float = 0.0):
        self.total, self.desc, self.unit, self.enabled, self.stream = total, desc, unit, enabled, stream
        self.min_interval_s = min_interval_s
        self.n = 0
        self.postfix = ""
        self.started = time.monotonic()
        self._last_line = -float("inf")

    def set_postfix_str(self, text: str = "", refresh: bool = True) -> None:
        """What the next finished item is (shown in its line)."""
        self.postfix = str(text)

    def update(self, n: int = 1) -> None:
        """``n`` more items finished: one line."""
        self.n += n
        now = time.monotonic()
        last = self.total is not None and self.n >= self.total
        if not self.enabled or n <= 0 or (now - self._last_line < self.min_interval_s and not last):
            return
        self._last_line = now
        count = f"{self.n}/{self.total}" if self.total is not None else f"{self.n}"
        one = (self.total if self.total is not None else self.n) == 1
        units = self.unit if one or self.unit in ("it", "") or self.unit.endswith("s") else f"{self.unit}s"
        head = f"{self.desc}: " if self.desc else ""
        tail = f" ({self.postfix})" if self.postfix else ""
        self.stream.write(f"{head}{count} {units}, {now - self.started:.1f} s{tail}\n")
        self.stream.flush()

    def close(self) -> None:
        """Nothing to clear (every line is final)."""

    def __enter__(self) -> LineProgress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def progress_bar(total: int | None, desc: str = "", unit: str = "it", enabled: bool = True, *,
                 leave: bool = True, min_interval_s: float = 0.0, stream: TextIO | None = None) -> tqdm | LineProgress:
    """A progress bar over ``total`` items (None: unknown) on ``stream`` (default stderr).

    Args:
        total: items to do, or None.
        desc: what is being done (``"render"``), the line's or bar's prefix.
        unit: one item (``"view"``, ``"frame"``).
        enabled: False = no output at all (``--quiet``).
        leave: on a terminal, keep the finished bar (True) or clear it (False).
        min_interval_s: without a terminal, at most one line per this many seconds (and the last); 0 = a line
            per item.  (On a terminal the bar refreshes as tqdm does.)
    Returns:
        A tqdm bar if ``stream`` is a terminal, else a :class:`LineProgress`; both have ``update(n=1)``,
        ``set_postfix_str(text)``, ``close()`` and work as context managers.
    """
    stream = sys.stderr if stream is None else stream
    isatty = getattr(stream, "isatty", None)
    if callable(isatty) and isatty():
        return tqdm(total=total, desc=desc, unit=unit, disable=not enabled, leave=leave, file=stream,
                    dynamic_ncols=True)
    return LineProgress(total, desc, unit, enabled, stream, min_interval_s)


def track(items: Iterable[T], total: int | None = None, desc: str = "", unit: str = "it", enabled: bool = True, *,
          leave: bool = True, min_interval_s: float = 0.0) -> Iterator[T]:
    """Iterate ``items`` with a :func:`progress_bar` that advances after each one (``total`` defaults to
    ``len(items)`` where it has one)."""
    if total is None and hasattr(items, "__len__"):
        total = len(items)  # type: ignore[arg-type]
    with progress_bar(total, desc, unit, enabled, leave=leave, min_interval_s=min_interval_s) as bar:
        for item in items:
            yield item
            bar.update(1)
