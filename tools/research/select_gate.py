"""Choose how the flow prior's gates read C's texture and whether the frame's factor spares U's epipoles.

Whether the per-pixel gate reads C's contrast as it is or above C's noise, and whether the frame's agreement factor
spares the vertical pair's epipoles.

Run as::

    python -m tools.research.select_gate DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split, under every
camera condition: a camera's noise is what these settings are about). The methods: the reference :data:`REFERENCE`
(``fused-mirror-gate-0-0-0.5-0.7-0-0-0``, the default before this choice), one
``fused-mirror-gate-<contrast_noise>-<agreement_contrast>-<low>-<high>-<cone>-<noise_low>-<noise_high>`` per
candidate of :data:`CANDIDATES` (``--candidates``: these only; the fields of
:class:`reconstruction.methods.prior_sweep.PriorParams` ``contrast_noise`` (the per-pixel gate reads C's contrast
above that many times its noise), ``frame_agreement_contrast`` (the frame's agreement share counts only the pixels
whose contrast above the noise is at least that many gray levels), ``frame_agreement_low``,
``frame_agreement_high``, ``epipole_cone_deg`` (within that many degrees of the C -> U baseline, up or down, the
frame's agreement factor is spared), ``epipole_cone_noise_low`` and ``epipole_cone_noise_high`` (in proportion to
the rig's noise between them, gray levels; 0-0: fully); everything else the default's) and the default
``fused-mirror`` as registered (a candidate or the reference configured as the default stands for it, not run
twice). ``DIR`` becomes a results set (``tri360 evaluate``'s, without the report) plus ``selection.md`` and
``selection.json``, as ``python -m tools.research.select_fill`` writes them, with the same rule
(:func:`tools.research.select_fill.choose`).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_gate")

import dataclasses
import sys
from collections.abc import Sequence

from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import candidates_main, config_name, methods_to_compare

__all__ = ["PROG", "REFERENCE", "CANDIDATES", "gate_method", "candidate_methods", "main"]

PROG = "select_gate"
#: a configuration: (``contrast_noise``, ``frame_agreement_contrast`` in gray levels, ``frame_agreement_low``,
#: ``frame_agreement_high``, ``epipole_cone_deg`` in degrees, ``epipole_cone_noise_low`` and ``_high`` in gray levels)
Config = tuple[float, float, float, float, float, float, float]
#: the reference: the default as it was before this choice (the contrast as it is, every pixel in the share, the
#: frame's factor everywhere)
REFERENCE: Config = (0.0, 0.0, 0.5, 0.7, 0.0, 0.0, 0.0)
#: the candidates
CANDIDATES: tuple[Config, ...] = (
    (0.5, 0.0, 0.5, 0.7, 0.0, 0.0, 0.0), (1.0, 0.0, 0.5, 0.7, 0.0, 0.0, 0.0), (1.5, 0.0, 0.5, 0.7, 0.0, 0.0, 0.0),
    (0.0, 4.0, 0.5, 0.7, 0.0, 0.0, 0.0), (0.0, 4.0, 0.45, 0.65, 0.0, 0.0, 0.0), (0.0, 4.0, 0.4, 0.6, 0.0, 0.0, 0.0),
    (0.0, 0.0, 0.5, 0.7, 20.0, 0.0, 0.0), (0.0, 0.0, 0.5, 0.7, 10.0, 0.6, 1.2), (0.0, 0.0, 0.5, 0.7, 20.0, 0.6, 1.2),
    (1.0, 0.0, 0.5, 0.7, 10.0, 0.6, 1.2), (1.0, 0.0, 0.5, 0.7, 20.0, 0.6, 1.2), (1.0, 0.0, 0.5, 0.7, 30.0, 0.6, 1.2))
TITLE = "The flow prior's gates: C's contrast as it is or above its noise; the frame's factor at U's epipoles"


def gate_method(contrast_noise: float, agreement_contrast: float, low: float, high: float,
                cone_deg: float = 0.0, cone_noise_low: float = 0.0, cone_noise_high: float = 0.0) -> Method:
    """The default method whose flow prior reads C's contrast above ``contrast_noise`` times C's noise in its
    per-pixel gate and counts only the pixels whose contrast above the noise is at least ``agreement_contrast`` gray
    levels (0: every pixel) in the frame's agreement share, ramped from ``low`` to ``high``, that factor spared within
    ``cone_deg`` degrees of U's epipoles in proportion to the rig's noise between ``cone_noise_low`` and
    ``cone_noise_high`` (0-0: fully); everything else the default's; labelled
    ``fused-mirror-gate-<contrast_noise>-<agreement_contrast>-<low>-<high>-<cone_deg>-<cone_noise_low>-<cone_noise_high>``.
    """
    base = fused_mirror()
    prior = dataclasses.replace(base.prior, contrast_noise=contrast_noise,
                                frame_agreement_contrast=agreement_contrast, frame_agreement_low=low,
                                frame_agreement_high=high, epipole_cone_deg=cone_deg,
                                epipole_cone_noise_low=cone_noise_low, epipole_cone_noise_high=cone_noise_high)
    config = (contrast_noise, agreement_contrast, low, high, cone_deg, cone_noise_low, cone_noise_high)
    return dataclasses.replace(base, prior=prior, label=f"{base.label}-gate-{config_name(config)}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`gate_method` per candidate (``names``: these only, as
    ``<contrast_noise>-<agreement_contrast>-<low>-<high>-<cone>-<noise_low>-<noise_high>``) and the default
    (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(gate_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<contrast_noise>-<agreement_contrast>-<low>-"
                           "<high>-<cone>-<noise_low>-<noise_high>", [config_name(c) for c in CANDIDATES], TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
