"""Choose the default's SGM jump penalty and its preference for the plane labels, per region, family and condition.

Run as::

    python -m tools.research.select_sgm DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split). The
methods: the reference :data:`REFERENCE` (``fused-mirror-sgm-800-4``: SGM's penalty for a jump of more than one
label 800 and the plane labels preferred by 4 cost units, as the default was before this choice), one
``fused-mirror-sgm-<p2>-<bias>`` per candidate of :data:`CANDIDATES` (``--candidates``: these only, as
``<p2>-<bias>``; everything but the sweep's ``SgmParams.p2`` and ``PlaneParams.bias`` the default's) and the default
``fused-mirror`` as registered (a candidate configured as the default is the default, not run twice). ``DIR``
becomes a results set (``tri360 evaluate``'s, without the report) plus ``selection.md`` and ``selection.json``, as
``python -m tools.research.select_fill`` writes them, with the same rule
(:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_sgm")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "sgm_method", "candidate_methods", "main"]

PROG = "select_sgm"
#: a configuration: (SGM's penalty for a jump of more than one label, cost units; the plane labels' preference,
#: cost units)
Config = tuple[int, int]
#: the reference: the default as it was before this choice
REFERENCE: Config = (800, 4)
#: the candidates
CANDIDATES: tuple[Config, ...] = ((1200, 4), (1200, 8))
TITLE = "The SGM jump penalty and the plane labels' preference"


def sgm_method(p2: int, bias: int) -> Method:
    """The default method whose sweep's SGM penalises a jump of more than one label by ``p2``
    (:class:`reconstruction.methods.sweep.SgmParams`) and prefers its plane labels by ``bias``
    (:class:`reconstruction.sweep.planes.PlaneParams`), everything else the default's; labelled
    ``fused-mirror-sgm-<p2>-<bias>``."""
    base = fused_mirror()
    sweep = dataclasses.replace(base.sweep, sgm=dataclasses.replace(base.sweep.sgm, p2=p2),
                                planes=dataclasses.replace(base.sweep.planes, bias=bias))
    return dataclasses.replace(base, sweep=sweep, label=f"{base.label}-sgm-{config_name((p2, bias))}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`sgm_method` per candidate (``names``: these only, as
    ``<p2>-<bias>``) and the default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(sgm_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<p2>-<bias>",
                           [config_name(c) for c in CANDIDATES], TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
