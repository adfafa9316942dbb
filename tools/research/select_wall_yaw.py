"""Choose how the sweep finds the walls' yaw: the normals' vote, the yaw where the walls hold most points, or both.

Run as::

    python -m tools.research.select_wall_yaw DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split). The methods:
the reference :data:`REFERENCE` (``fused-mirror-wall-yaw-normals``: the walls' yaw from the vote of the distance
map's surface normals, as the default was before this choice), one ``fused-mirror-wall-yaw-<name>`` per candidate
of :data:`CANDIDATES` (``--candidates``: these only; :class:`reconstruction.sweep.planes.PlaneParams` ``wall_yaw``,
which serves the coarse pass's wall labels and the wall step alike, everything else the default's) and the default
``fused-mirror`` as registered (a candidate or the reference configured as the default stands for it, not run
twice). ``DIR`` becomes a results set (``tri360 evaluate``'s, without the report) plus ``selection.md`` and
``selection.json``, as ``python -m tools.research.select_fill`` writes them, with the same rule
(:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_wall_yaw")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import candidates_main, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "wall_yaw_method", "candidate_methods", "main"]

PROG = "select_wall_yaw"
#: a configuration: (``wall_yaw``,), one of :data:`reconstruction.sweep.planes.WALL_YAWS`
Config = tuple[str]
#: the reference: the default as it was before this choice
REFERENCE: Config = ("normals",)
#: the candidates
CANDIDATES: tuple[Config, ...] = (("offsets",), ("normals-or-offsets",))
TITLE = "How the walls' yaw is found"


def wall_yaw_method(wall_yaw: str) -> Method:
    """The default method whose sweep finds the walls' yaw as ``wall_yaw`` says, everything else the default's;
    labelled ``fused-mirror-wall-yaw-<wall_yaw>``."""
    base = fused_mirror()
    sweep = dataclasses.replace(base.sweep, planes=dataclasses.replace(base.sweep.planes, wall_yaw=wall_yaw))
    return dataclasses.replace(base, sweep=sweep, label=f"{base.label}-wall-yaw-{wall_yaw}")


def _name(config: Config) -> str:
    return config[0]


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`wall_yaw_method` per candidate (``names``: these only) and the
    default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(wall_yaw_method, REFERENCE, CANDIDATES, _name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<wall_yaw>", [_name(c) for c in CANDIDATES],
                           TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
