"""Choose how far the default's sweep gives up its matching preference where C shows no texture above noise.

Run as::

    python -m tools.research.select_flat DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split). The
methods: the reference :data:`REFERENCE` (``fused-mirror-flat-0-1``: a preference everywhere, as the default was
before this choice), one ``fused-mirror-flat-<k>-<w>`` per candidate of :data:`CANDIDATES` (``--candidates``: these
only, as ``<k>-<w>``; both sweep costs' ``CostParams.flat_contrast`` set to ``k`` and ``flat_weight`` to ``w``,
everything else the default's) and the default ``fused-mirror`` as registered (a candidate or the reference
configured as the default stands for it, not run twice). ``DIR`` becomes a results set (``tri360 evaluate``'s,
without the report) plus ``selection.md`` and ``selection.json``, as ``python -m tools.research.select_fill`` writes
them, with the same rule (:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_flat")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "flat_method", "candidate_methods", "main"]

PROG = "select_flat"
#: a configuration: (``CostParams.flat_contrast``: local contrast below this many times C's noise marks a pixel
#: (0 = none); ``CostParams.flat_weight``: how far its costs move to their mean, 1 = no preference left)
Config = tuple[float, float]
#: the reference: the default as it was before this choice
REFERENCE: Config = (0.0, 1.0)
#: the candidates
CANDIDATES: tuple[Config, ...] = ((0.7, 1.0), (1.0, 1.0), (1.0, 0.5))
TITLE = "Less matching preference where C shows no texture above its noise"


def flat_method(flat_contrast: float, flat_weight: float) -> Method:
    """The default method whose sweep costs (``cost`` and ``corrected_cost``) move the costs of the pixels below
    ``flat_contrast`` times C's noise ``flat_weight`` of the way to their mean
    (:class:`reconstruction.sweep.cost.CostParams`), everything else the default's; labelled
    ``fused-mirror-flat-<k>-<w>``."""
    base = fused_mirror()
    sweep = base.sweep
    values = {"flat_contrast": flat_contrast, "flat_weight": flat_weight}
    corrected = None if sweep.corrected_cost is None else dataclasses.replace(sweep.corrected_cost, **values)
    sweep = dataclasses.replace(sweep, cost=dataclasses.replace(sweep.cost, **values), corrected_cost=corrected)
    label = f"{base.label}-flat-{config_name((flat_contrast, flat_weight))}"
    return dataclasses.replace(base, sweep=sweep, label=label)


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`flat_method` per candidate (``names``: these only, as
    ``<k>-<w>``) and the default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(flat_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<k>-<w>",
                           [config_name(c) for c in CANDIDATES], TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
