"""Choose the degree of each camera's response curve in the default's photometric self-calibration.

Run as::

    python -m tools.research.calibration_floor DATA_ROOT --out ROWS.csv
    python -m tools.research.select_response DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split). The degree
changes every frame's fit, so even a frame on which the candidates apply the same corrections and no response can
answer differently (the kept corrections are fitted again from the full fit's values: 0.94-1.04 x on 19 such dev
frames).  A shortcut: ``--frames`` listing the frames of the (condition, room family) cells that hold a frame where,
in ``calibration_floor``'s rows of the reference and of a candidate, ``applied`` differs or names a response, since
the rule below reads each cell's pooled MAE; the other cells are then not compared.  The methods: the reference
:data:`REFERENCE` (``fused-mirror-response-1``: a power law, the default before this choice), one
``fused-mirror-response-<n>`` per candidate of :data:`CANDIDATES` (``--candidates``: these only;
``PhotometricParams.response``, the polynomial's degree in the log level, everything else the default's) and the
default ``fused-mirror`` as registered (a candidate or the reference configured as the default stands for it, not run
twice). ``DIR`` becomes a results set (``tri360 evaluate``'s, without the report)
plus ``selection.md`` and ``selection.json``, as ``python -m tools.research.select_fill`` writes them, with the same
rule (:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_response")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from reconstruction.methods.registry import with_photometric
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "response_method", "candidate_methods", "main"]

PROG = "select_response"
#: a configuration: (``PhotometricParams.response``: the degree of each camera's response polynomial, 0 = none)
Config = tuple[int]
#: the reference: the default as it was before this choice
REFERENCE: Config = (1,)
#: the candidates: a curvature (an S-shaped tone curve against a gamma one is not a power law), and a cubic
CANDIDATES: tuple[Config, ...] = ((2,), (3,))
TITLE = "The degree of each camera's response curve in the self-calibration"


def response_method(degree: int) -> Method:
    """The default method whose photometric self-calibration (its flow's, its sweep's and its quality flow's) fits
    each camera's response as a polynomial of ``degree`` in its log level
    (:class:`reconstruction.photometry.PhotometricParams`), everything else the default's; labelled
    ``fused-mirror-response-<n>``."""
    base = fused_mirror()
    photometric = dataclasses.replace(base.flow.photometric, response=degree)
    return with_photometric(base, photometric, f"{base.label}-response-{config_name((degree,))}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`response_method` per candidate (``names``: these only, as
    ``<n>``) and the default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(response_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<n>", [config_name(c) for c in CANDIDATES], TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
