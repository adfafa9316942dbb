"""Choose when a wall encloses: how much of what the default finds may lie well beyond it for the rest to be put on it.

Run as::

    python -m tools.research.select_walls DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split). The methods:
the reference :data:`REFERENCE` (``fused-mirror-walls-0.2-0.03``: a wall encloses when at most 3 % of the pixels
facing it lie more than 20 % beyond it, as the default was before this choice), one
``fused-mirror-walls-<margin>-<share>`` per candidate of :data:`CANDIDATES` (``--candidates``: these only; the sweep's
:class:`reconstruction.refine.planes.PlaneRefineParams` ``wall_margin`` and ``wall_max_share``, everything else the
default's) and the default ``fused-mirror`` as registered (a candidate or the reference configured as the default
stands for it, not run twice). ``DIR`` becomes a results set (``tri360 evaluate``'s, without the report) plus
``selection.md`` and ``selection.json``, as ``python -m tools.research.select_fill`` writes them, with the same rule
(:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_walls")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "walls_method", "candidate_methods", "main"]

PROG = "select_walls"
#: a configuration: (``wall_margin``, ``wall_max_share``); ``wall_margin`` 0: walls left alone
Config = tuple[float, float]
#: the reference: the default as it was before this choice
REFERENCE: Config = (0.2, 0.03)
#: the candidates: how much of a wall may lie beyond it for it to enclose
CANDIDATES: tuple[Config, ...] = ((0.2, 0.05), (0.2, 0.06), (0.2, 0.08), (0.2, 0.1))
TITLE = "What lies well beyond an enclosing wall put on it"


def walls_method(margin: float, share: float) -> Method:
    """The default method whose sweep puts the pixels more than ``margin`` (relative) beyond a wall on it when at
    most ``share`` of the pixels facing the wall lie beyond it (``margin`` 0: walls left alone), everything else the
    default's; labelled ``fused-mirror-walls-<margin>-<share>``."""
    base = fused_mirror()
    params = dataclasses.replace(base.sweep.refine_planes, wall_margin=margin, wall_max_share=share)
    sweep = dataclasses.replace(base.sweep, refine_planes=params)
    return dataclasses.replace(base, sweep=sweep, label=f"{base.label}-walls-{config_name((margin, share))}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`walls_method` per candidate (``names``: these only, as
    ``<margin>-<share>``) and the default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(walls_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<margin>-<share>",
                           [config_name(c) for c in CANDIDATES], TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
