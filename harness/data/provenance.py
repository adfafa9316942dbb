"""Provenance: which tri360 produced an output (version and, when run from a git checkout, the commit)."""

from __future__ import annotations

import subprocess
from pathlib import Path

from harness import __version__

__all__ = ["tri360_version", "source_commit", "software"]

_SOURCE_ROOT = Path(__file__).resolve().parents[2]


def tri360_version() -> str:
    return __version__


def source_commit(root: Path = _SOURCE_ROOT) -> str | None:
    """The git commit of the tri360 source tree (with ``-dirty`` if it has uncommitted changes to tracked
    files), or None when tri360 does not run from a git checkout or git is unavailable."""
    if not (root / ".git").exists():
        return None
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return f"{head}-dirty" if dirty else head


def software() -> dict:
    """``{"tri360_version": ..., "commit": ...}`` for results and frames provenance."""
    return {"tri360_version": tri360_version(), "commit": source_commit()}
