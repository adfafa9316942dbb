"""Choose whether, and how surely, the default searches its floor and ceiling again from the images.

Run as::

    python -m tools.research.select_refine_planes DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split). The
methods: the reference :data:`REFERENCE` (``fused-mirror-refine-planes-0-0-0``: no search, as the default was before
this choice), one ``fused-mirror-refine-planes-<se>-<basin>-<snap>`` per candidate of :data:`CANDIDATES`
(``--candidates``: these only; the sweep's :class:`reconstruction.refine.planes.PlaneRefineParams` ``max_se``,
``max_basin`` and ``snap``, everything else the default's) and the default ``fused-mirror`` as registered (a
candidate or the reference configured as the default stands for it, not run twice). ``DIR`` becomes a results set
(``tri360 evaluate``'s, without the report) plus ``selection.md`` and ``selection.json``, as ``python -m
tools.research.select_fill`` writes them, with the same rule (:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_refine_planes")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from reconstruction.refine.planes import PlaneRefineParams
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "refine_planes_method", "candidate_methods", "main"]

PROG = "select_refine_planes"
#: a configuration: (``max_se``, ``max_basin``, ``snap``); ``max_se`` 0: no search
Config = tuple[float, float, float]
#: the reference: the default as it was before this choice
REFERENCE: Config = (0.0, 0.0, 0.0)
#: the candidates
CANDIDATES: tuple[Config, ...] = ((0.005, 0.03, 0.06), (0.003, 0.03, 0.06), (0.005, 0.03, 0.09))
TITLE = "Floor and ceiling searched again from the images"


def refine_planes_method(max_se: float, max_basin: float, snap: float) -> Method:
    """The default method whose sweep searches the floor and the ceiling again and applies a plane whose jackknife
    standard error is at most ``max_se`` and whose basin reaches at most ``max_basin`` (natural log), putting the
    pixels within ``snap`` of it on it (``max_se`` 0: no search), everything else the default's (the other
    :class:`PlaneRefineParams` as the default has them, or their defaults when it has none); labelled
    ``fused-mirror-refine-planes-<se>-<basin>-<snap>``."""
    base = fused_mirror()
    params = None
    if max_se > 0:
        params = dataclasses.replace(base.sweep.refine_planes or PlaneRefineParams(), max_se=max_se,
                                     max_basin=max_basin, snap=snap)
    sweep = dataclasses.replace(base.sweep, refine_planes=params)
    return dataclasses.replace(base, sweep=sweep,
                               label=f"{base.label}-refine-planes-{config_name((max_se, max_basin, snap))}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`refine_planes_method` per candidate (``names``: these only, as
    ``<se>-<basin>-<snap>``) and the default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(refine_planes_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<se>-<basin>-<snap>",
                           [config_name(c) for c in CANDIDATES], TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
