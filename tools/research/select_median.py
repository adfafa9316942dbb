"""Choose the side of the median filter on the default's sweep distance.

Run as::

    python -m tools.research.select_median DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split: its ideal
frames and their camera twins; frames of other resolutions too, since the side is in pixels).  The methods: the
reference :data:`REFERENCE` (``fused-mirror-median-5``), one ``fused-mirror-median-<k>`` per candidate of
:data:`CANDIDATES` (``--candidates``: these only; ``PostParams.median_px``, everything else the default's) and the
default ``fused-mirror`` as registered (a candidate or the reference configured as the default stands for it, not run
twice). ``DIR`` becomes a results set (``tri360 evaluate``'s, without the report) plus ``selection.md`` and
``selection.json``, as ``python -m tools.research.select_fill`` writes them, with the same rule
(:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_median")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "median_method", "candidate_methods", "main"]

PROG = "select_median"
#: a configuration: (``PostParams.median_px``: the median's side, pixels)
Config = tuple[int]
#: the reference: the default's side
REFERENCE: Config = (5,)
#: the candidates: wider medians (docs/edges.md, "The median's side": 9 gave 0.970 x on the ideal dev frames)
CANDIDATES: tuple[Config, ...] = ((7,), (9,))
TITLE = "The side of the median on the sweep's distance"


def median_method(side: int) -> Method:
    """The default method whose sweep median-filters its distance with side ``side``
    (:class:`reconstruction.methods.sweep.PostParams`), everything else the default's; labelled
    ``fused-mirror-median-<k>``."""
    base = fused_mirror()
    post = dataclasses.replace(base.sweep.post, median_px=side)
    return dataclasses.replace(base, sweep=dataclasses.replace(base.sweep, post=post),
                               label=f"{base.label}-median-{config_name((side,))}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`median_method` per candidate (``names``: these only, as ``<k>``)
    and the default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(median_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<k>", [config_name(c) for c in CANDIDATES], TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
