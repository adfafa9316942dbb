"""Choose how much of the locally normalised intensity's cost the default's sweep mixes in where C shows texture.

Run as::

    python -m tools.research.select_normalized DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split: its ideal
frames and their camera twins).  The methods: the reference :data:`REFERENCE` (``fused-mirror-normalized-0``: the
intensity cost alone), one ``fused-mirror-normalized-<w>-<c>`` per candidate of :data:`CANDIDATES` (``--candidates``:
these only; ``CostParams.normalized_weight`` ``w`` and ``normalized_contrast`` ``c`` in both the sweep's costs,
everything else the default's) and the default ``fused-mirror`` as registered (a candidate or the reference
configured as the default stands for it, not run twice).  ``DIR`` becomes a results set (``tri360 evaluate``'s,
without the report) plus ``selection.md`` and ``selection.json``, as ``python -m tools.research.select_fill`` writes
them, with the same rule (:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_normalized")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "normalized_method", "candidate_methods", "main"]

PROG = "select_normalized"
#: a configuration: (``CostParams.normalized_weight``, ``CostParams.normalized_contrast``)
Config = tuple[float, float]
#: the reference: the intensity cost alone (the default's)
REFERENCE: Config = (0.0, 1.0)
#: the candidates: half or about a third of the normalised cost where C's contrast is above twice its noise
#: (docs/cost.md, "The normalised intensity mixed in where C shows texture": 0.907 x and 0.928 x on the ideal dev
#: frames)
CANDIDATES: tuple[Config, ...] = ((0.5, 2.0), (0.35, 2.0))
TITLE = "The locally normalised intensity's cost mixed into the sweep's"


def _name(config: Config) -> str:
    """``0`` for the reference (no mix: the contrast does not matter), else ``<w>-<c>``."""
    return "0" if config[0] == 0 else config_name(config)


def normalized_method(weight: float, contrast: float) -> Method:
    """The default method whose sweep mixes in ``weight`` of the normalised intensity's cost where C's local
    contrast is at least ``contrast`` times its noise, in both its costs (``cost`` and ``corrected_cost``;
    :class:`reconstruction.sweep.cost.CostParams`), everything else the default's; labelled
    ``fused-mirror-normalized-<w>-<c>`` (``-0`` without a mix)."""
    base = fused_mirror()
    sweep = base.sweep
    costs = {k: dataclasses.replace(getattr(sweep, k), normalized_weight=weight, normalized_contrast=contrast)
             for k in ("cost", "corrected_cost")}
    return dataclasses.replace(base, sweep=dataclasses.replace(sweep, **costs),
                               label=f"{base.label}-normalized-{_name((weight, contrast))}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`normalized_method` per candidate (``names``: these only, as
    ``<w>-<c>``) and the default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(normalized_method, REFERENCE, CANDIDATES, _name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<w>-<c>", [_name(c) for c in CANDIDATES], TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
