"""Choose whether, where no wall the sweep finds encloses a side of the room, the ceiling's edge stands for that wall.

Run as::

    python -m tools.research.select_ceiling_edge DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split). The methods:
the reference :data:`REFERENCE` (``fused-mirror-ceiling-edge-0``: only the walls found put what lies beyond them on
them, as the default was before this choice), one ``fused-mirror-ceiling-edge-<quantile>`` per candidate of
:data:`CANDIDATES` (``--candidates``: these only; the sweep's
:class:`reconstruction.refine.planes.PlaneRefineParams` ``ceiling_edge``: the share of the ceiling's area seen on a
side within which that side's wall is put, everything else the default's) and the default ``fused-mirror`` as
registered (a candidate or the reference configured as the default stands for it, not run twice). ``DIR`` becomes a
results set (``tri360 evaluate``'s, without the report) plus ``selection.md`` and ``selection.json``, as
``python -m tools.research.select_fill`` writes them, with the same rule (:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_ceiling_edge")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "ceiling_edge_method", "candidate_methods", "main"]

PROG = "select_ceiling_edge"
#: a configuration: (``ceiling_edge``,); 0: no ceiling's edge
Config = tuple[float]
#: the reference: the default as it was before this choice
REFERENCE: Config = (0.0,)
#: the candidates: the share of a side's ceiling area within which its wall is put (the one measured on dev)
CANDIDATES: tuple[Config, ...] = ((0.99,),)
TITLE = "The ceiling's edge where no wall found encloses"


def ceiling_edge_method(quantile: float) -> Method:
    """The default method whose sweep puts a side's wall at ``quantile`` of the ceiling's area where no wall found
    encloses that side (0: not), everything else the default's; labelled ``fused-mirror-ceiling-edge-<quantile>``."""
    base = fused_mirror()
    params = dataclasses.replace(base.sweep.refine_planes, ceiling_edge=quantile)
    sweep = dataclasses.replace(base.sweep, refine_planes=params)
    return dataclasses.replace(base, sweep=sweep, label=f"{base.label}-ceiling-edge-{config_name((quantile,))}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`ceiling_edge_method` per candidate (``names``: these only) and
    the default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(ceiling_edge_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<quantile>", [config_name(c) for c in CANDIDATES],
                           TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
