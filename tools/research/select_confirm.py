"""Choose whether the default applies a rotation its pre-pass finds only when a full-resolution fit confirms it.

Run as::

    python -m tools.research.calibration_floor DATA_ROOT --out ROWS.csv
    python -m tools.research.select_confirm DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split). A frame
whose pre-pass rotations are all confirmed (or that has none) gets the same answer from every candidate, to the
digit, so ``--frames`` may list only the scenes (every viewpoint) of the (condition, room family) cells that hold a
frame whose ``not_confirmed`` column in ``calibration_floor``'s rows is not ``none``: the rule below reads each
cell's pooled MAE, and every other cell is the same for every candidate.  The methods: the reference
:data:`REFERENCE` (``fused-mirror-confirm-0``: no confirming pass, as the default was before this choice), one
``fused-mirror-confirm-<f>`` per candidate of :data:`CANDIDATES` (``--candidates``: these only; the rig fit's
``RigParams.confirm_factor`` ``f``, everything else the default's) and the default ``fused-mirror`` as registered (a
candidate or the reference configured as the default stands for it, not run twice). ``DIR`` becomes a results set
(``tri360 evaluate``'s, without the report) plus ``selection.md`` and ``selection.json``, as ``python -m
tools.research.select_fill`` writes them, with the same rule (:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_confirm")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "confirm_method", "candidate_methods", "main"]

PROG = "select_confirm"
#: a configuration: (``RigParams.confirm_factor``: the reduction of the confirming flow pass, 0 = none)
Config = tuple[int]
#: the reference: the default as it was before this choice
REFERENCE: Config = (0,)
#: the candidates (the pre-pass itself runs at half size: confirming there would refit the same matches)
CANDIDATES: tuple[Config, ...] = ((1,),)
TITLE = "A pre-pass rotation applied only when a full-resolution fit confirms it"


def confirm_method(confirm_factor: int) -> Method:
    """The default method whose rig fit (its flow's and, if it has one, its quality flow's) applies a rotation only
    when a flow pass on images reduced by ``confirm_factor`` confirms it
    (:class:`reconstruction.rig_calibration.RigParams`), everything else the default's; labelled
    ``fused-mirror-confirm-<f>``."""
    base = fused_mirror()
    rig = dataclasses.replace(base.flow.rig, confirm_factor=confirm_factor)
    quality = base.quality_flow
    return dataclasses.replace(base, flow=dataclasses.replace(base.flow, rig=rig),
                               quality_flow=None if quality is None else dataclasses.replace(quality, rig=rig),
                               label=f"{base.label}-confirm-{config_name((confirm_factor,))}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`confirm_method` per candidate (``names``: these only, as
    ``<f>``) and the default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(confirm_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<f>", [config_name(c) for c in CANDIDATES], TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
