"""Choose how the default treats a match beyond its room bound: forbidden, or dearer and put on the floor.

Run as::

    python -m tools.research.select_bound DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split). The
methods: the reference :data:`REFERENCE` (``fused-mirror-bound-0-0``: every sphere label beyond the room bound
forbidden, as the default was before this choice), one ``fused-mirror-bound-<penalty>-<min_az>`` per candidate of
:data:`CANDIDATES` (``--candidates``: these only; the sweep's :class:`reconstruction.sweep.planes.PlaneParams`
``bound_penalty`` in gray levels and ``bound_penalty_min_az``, the smallest |sine of the elevation| at which the
penalty replaces the ban, everything else the default's) and the default ``fused-mirror`` as registered (a candidate
or the reference configured as the default stands for it, not run twice). ``DIR`` becomes a results set (``tri360
evaluate``'s, without the report) plus ``selection.md`` and ``selection.json``, as ``python -m
tools.research.select_fill`` writes them, with the same rule (:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_bound")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "bound_method", "candidate_methods", "main"]

PROG = "select_bound"
#: a configuration: (``bound_penalty``, gray levels, 0: forbidden; ``bound_penalty_min_az``)
Config = tuple[float, float]
#: the reference: the default as it was before this choice
REFERENCE: Config = (0.0, 0.0)
#: the candidates
CANDIDATES: tuple[Config, ...] = ((1.0, 0.0), (2.0, 0.0), (4.0, 0.0), (2.0, 0.1), (2.0, 0.2))
TITLE = "A match beyond the room bound: forbidden, or dearer and put on the floor"


def bound_method(penalty: float, min_az: float) -> Method:
    """The default method whose sweep adds ``penalty`` gray levels to a sphere label beyond the room bound and puts
    a pixel that still wins one on the floor or the ceiling found, at bearings whose |world Z| is at least
    ``min_az`` (``penalty`` 0, or a shallower bearing: those labels are forbidden), everything else the default's;
    labelled ``fused-mirror-bound-<penalty>-<min_az>``."""
    base = fused_mirror()
    planes = dataclasses.replace(base.sweep.planes, bound_penalty=penalty, bound_penalty_min_az=min_az)
    sweep = dataclasses.replace(base.sweep, planes=planes)
    return dataclasses.replace(base, sweep=sweep, label=f"{base.label}-bound-{config_name((penalty, min_az))}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`bound_method` per candidate (``names``: these only, as
    ``<penalty>-<min_az>``) and the default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(bound_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<penalty>-<min_az>",
                           [config_name(c) for c in CANDIDATES], TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
