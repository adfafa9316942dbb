"""Choose whether, and how widely, the default moves its depth edges onto C's image edges.

Run as::

    python -m tools.research.select_edges DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split). The
methods: the reference :data:`REFERENCE` (``fused-mirror-edges-0-10-5-4``: no edge snapping, as the default was
before this choice), one ``fused-mirror-edges-<r>-<c>-<s>-<reach>`` per candidate of :data:`CANDIDATES`
(``--candidates``: these only; the sweep's ``PostParams.edge_radius_px`` ``r``, ``edge_sigma_color`` ``c``,
``edge_sigma_px`` ``s`` and ``edge_reach_px`` ``reach``, everything else the default's:
:func:`reconstruction.refine.edges.snap_depth_edges`) and the default ``fused-mirror`` as registered (a candidate or
the reference configured as the default stands for it, not run twice). ``DIR`` becomes a results set (``tri360
evaluate``'s, without the report) plus ``selection.md`` and ``selection.json``, as ``python -m
tools.research.select_fill`` writes them, with the same rule (:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_edges")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "edges_method", "candidate_methods", "main"]

PROG = "select_edges"
#: a configuration: (``PostParams.edge_radius_px`` (0 = none), ``edge_sigma_color`` (C's 0-255 levels),
#: ``edge_sigma_px`` (pixels), ``edge_reach_px`` (pixels))
Config = tuple[int, float, float, int]
#: the reference: the default as it was before this choice
REFERENCE: Config = (0, 10.0, 5.0, 4)
#: the candidates
CANDIDATES: tuple[Config, ...] = ((4, 10.0, 3.0, 2), (7, 10.0, 5.0, 4), (7, 20.0, 5.0, 4), (10, 10.0, 7.0, 6))
TITLE = "Depth edges moved onto C's image edges"


def edges_method(radius_px: int, sigma_color: float, sigma_px: float, reach_px: int) -> Method:
    """The default method whose sweep moves the pixels within ``reach_px`` of a depth edge to the joint weighted
    median of their ``radius_px`` window (colour scale ``sigma_color``, spatial scale ``sigma_px``;
    :class:`reconstruction.methods.sweep.PostParams`), everything else the default's; labelled
    ``fused-mirror-edges-<r>-<c>-<s>-<reach>``."""
    base = fused_mirror()
    post = dataclasses.replace(base.sweep.post, edge_radius_px=radius_px, edge_sigma_color=sigma_color,
                               edge_sigma_px=sigma_px, edge_reach_px=reach_px)
    sweep = dataclasses.replace(base.sweep, post=post)
    return dataclasses.replace(base, sweep=sweep,
                               label=f"{base.label}-edges-{config_name((radius_px, sigma_color, sigma_px, reach_px))}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`edges_method` per candidate (``names``: these only, as
    ``<r>-<c>-<s>-<reach>``) and the default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(edges_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<r>-<c>-<s>-<reach>",
                           [config_name(c) for c in CANDIDATES], TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
