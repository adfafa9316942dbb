"""Choose the default's floor and ceiling label families and its room bound, per region, family and condition.

Run as::

    python -m tools.research.select_planes DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split). The
methods: the reference :data:`REFERENCE` (``fused-mirror-planes-0-0.2-0.25``: no floor or ceiling family and the
room bound 25 % beyond the floor and ceiling, as the default was before this choice), one
``fused-mirror-planes-<room_labels>-<room_spread>-<bound_margin>`` per candidate of :data:`CANDIDATES`
(``--candidates``: these only, as ``<room_labels>-<room_spread>-<bound_margin>``; everything but the sweep's
``PlaneParams.room_labels``, ``room_spread`` and ``bound_margin`` the default's) and the default ``fused-mirror`` as
registered (a candidate configured as the default is the default, not run twice). ``DIR`` becomes a results set
(``tri360 evaluate``'s, without the report) plus ``selection.md`` and ``selection.json``, as ``python -m
tools.research.select_fill`` writes them, with the same rule (:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_planes")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "planes_method", "candidate_methods", "main"]

PROG = "select_planes"
#: a configuration: (labels of the floor's and of the ceiling's family, their relative half-width, the room bound's
#: margin)
Config = tuple[int, float, float]
#: the reference: the default as it was before this choice
REFERENCE: Config = (0, 0.2, 0.25)
#: the candidates
CANDIDATES: tuple[Config, ...] = ((9, 0.1, 0.25), (17, 0.2, 0.25), (0, 0.2, 0.05), (0, 0.2, 0.1), (0, 0.2, 0.15),
                                  (9, 0.1, 0.1))
TITLE = "The floor and ceiling label families and the room bound"


def planes_method(room_labels: int, room_spread: float, bound_margin: float) -> Method:
    """The default method whose sweep has ``room_labels`` labels for the floor and as many for the ceiling spanning
    +- ``room_spread`` (:class:`reconstruction.sweep.planes.PlaneParams`) and the room bound ``bound_margin``
    beyond them, everything else the default's; labelled
    ``fused-mirror-planes-<room_labels>-<room_spread>-<bound_margin>``."""
    base = fused_mirror()
    planes = dataclasses.replace(base.sweep.planes, room_labels=room_labels, room_spread=room_spread,
                                 bound_margin=bound_margin)
    return dataclasses.replace(base, sweep=dataclasses.replace(base.sweep, planes=planes),
                               label=f"{base.label}-planes-{config_name((room_labels, room_spread, bound_margin))}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`planes_method` per candidate (``names``: these only, as
    ``<room_labels>-<room_spread>-<bound_margin>``) and the default
    (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(planes_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<room_labels>-<room_spread>-<bound_margin>",
                           [config_name(c) for c in CANDIDATES], TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
