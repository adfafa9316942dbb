"""Choose how much may lie beyond a wall the sweep finds when the ceiling stops at it, and how little of the ceiling.

Run as::

    python -m tools.research.select_closed_walls DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split, every viewpoint:
the library shelves that a wall step can take for walls are on its second and third viewpoints). The methods: the
reference :data:`REFERENCE` (``fused-mirror-closed-walls-0-0``: only ``wall_max_share`` decides whether a wall
encloses, as the default was before this choice), one ``fused-mirror-closed-walls-<max share>-<ceiling share>`` per
candidate of :data:`CANDIDATES` (``--candidates``: these only; the sweep's
:class:`reconstruction.refine.planes.PlaneRefineParams` ``closed_max_share`` and ``closed_ceiling_share``, everything
else the default's) and the default ``fused-mirror`` as registered (a candidate or the reference configured as the
default stands for it, not run twice). ``DIR`` becomes a results set (``tri360 evaluate``'s, without the report) plus
``selection.md`` and ``selection.json``, as ``python -m tools.research.select_fill`` writes them, with the same rule
(:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_closed_walls")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "closed_walls_method", "candidate_methods", "main"]

PROG = "select_closed_walls"
#: a configuration: (``closed_max_share``, ``closed_ceiling_share``); (0, 0): not asked
Config = tuple[float, float]
#: the reference: the default as it was before this choice
REFERENCE: Config = (0.0, 0.0)
#: the candidates: up to 10 % of a wall's facing pixels beyond it, with at most 3 % or 4 % of the ceiling's (the
#: nearest shelf taken for a wall on dev has 6.2 % of the ceiling's beyond it)
CANDIDATES: tuple[Config, ...] = ((0.10, 0.03), (0.10, 0.04))
TITLE = "A wall with more beyond it that the ceiling stops at"


def closed_walls_method(max_share: float, ceiling_share: float) -> Method:
    """The default method whose wall step also puts on a wall what lies beyond it when at most ``max_share`` of its
    facing pixels and at most ``ceiling_share`` of the ceiling's facing pixels lie beyond it (0: not asked),
    everything else the default's; labelled ``fused-mirror-closed-walls-<max share>-<ceiling share>``."""
    base = fused_mirror()
    params = dataclasses.replace(base.sweep.refine_planes, closed_max_share=max_share,
                                 closed_ceiling_share=ceiling_share)
    sweep = dataclasses.replace(base.sweep, refine_planes=params)
    return dataclasses.replace(base, sweep=sweep,
                               label=f"{base.label}-closed-walls-{config_name((max_share, ceiling_share))}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`closed_walls_method` per candidate (``names``: these only) and
    the default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(closed_walls_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<max share>-<ceiling share>",
                           [config_name(c) for c in CANDIDATES], TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
