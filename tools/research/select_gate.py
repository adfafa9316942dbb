"""Choose how the flow prior's gates read C's texture and whether the frame's factor spares U's epipoles.

Whether the per-pixel gate reads C's contrast as it is, above C's noise or of C's image blurred in proportion to its
noise, and whether the frame's agreement factor spares the vertical pair's epipoles, there only where the C -> R flow
is consistent or near the room's floor or ceiling.

Run as::

    python -m tools.research.select_gate DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split, under every
camera condition: a camera's noise is what these settings are about). The methods: the reference :data:`REFERENCE`
(``fused-mirror-gate-0-0-0.5-0.7-0-0-0-0-0-3-0-0-0``, the default before this choice), one
``fused-mirror-gate-<contrast_noise>-<agreement_contrast>-<low>-<high>-<cone>-<noise_low>-<noise_high>-<blur>-``
``<blur_floor>-<max_blur>-<fb_low>-<fb_high>-<room>`` per
candidate of :data:`CANDIDATES` (``--candidates``: these only; the fields of
:class:`reconstruction.methods.prior_sweep.PriorParams` ``contrast_noise`` (the per-pixel gate reads C's contrast
above that many times its noise), ``frame_agreement_contrast`` (the frame's agreement share counts only the pixels
whose contrast above the noise is at least that many gray levels), ``frame_agreement_low``,
``frame_agreement_high``, ``epipole_cone_deg`` (within that many degrees of the C -> U baseline, up or down, the
frame's agreement factor is spared), ``epipole_cone_noise_low`` and ``epipole_cone_noise_high`` (in proportion to
the rig's noise between them, gray levels; 0-0: fully), ``contrast_blur``, ``contrast_blur_floor`` and
``contrast_max_blur_px`` (the per-pixel gate reads the contrast of C's image blurred by ``blur * (n - blur_floor)``
pixels, at most ``max_blur``, ``n`` C's noise in gray levels; ``blur`` 0: no blur), ``epipole_cone_fb_low`` and
``epipole_cone_fb_high`` (the cone's spare falls from full to none between these forward-backward inconsistencies of
the C -> R flow, pixels; 0-0: off) and ``epipole_cone_room`` (the cone's spare only where the flow lies within that
relative tolerance of the floor or the ceiling the sweep's coarse pass found; 0: off); everything else the default's)
and the default
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
#: ``frame_agreement_high``, ``epipole_cone_deg`` in degrees, ``epipole_cone_noise_low`` and ``_high`` in gray levels,
#: ``contrast_blur`` in pixels per gray level, ``contrast_blur_floor`` in gray levels, ``contrast_max_blur_px``,
#: ``epipole_cone_fb_low`` and ``_high`` in pixels, ``epipole_cone_room`` relative)
Config = tuple[float, float, float, float, float, float, float, float, float, float, float, float, float]
#: the reference: the default as it was before this choice (the contrast as it is, every pixel in the share, the
#: frame's factor everywhere, no blur)
REFERENCE: Config = (0.0, 0.0, 0.5, 0.7, 0.0, 0.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0)
_OFF = (0.0, 0.0, 3.0, 0.0, 0.0, 0.0)  # no blur, the cone's spare wherever it is on
_CONE = (20.0, 0.6, 1.2)
_ANY_FB = (0.0, 0.0, 0.0)  # the cone's spare wherever it is on
#: the candidates: the contrast above the noise, the textured share, the cone; then the blur from C's noise 0.6 gray
#: levels up (the noisiest rendering of the dev split reads 0.45, the least noisy camera twin 0.93), with and
#: without the cone, and with the contrast above the noise too; then the cone spared only where the C -> R flow
#: comes back to within 1-3 or 0.5-2 pixels of where it started, and with the contrast above the noise; then only
#: where the flow lies within 5-30 % of the room's floor or ceiling
CANDIDATES: tuple[Config, ...] = (
    (0.5, 0.0, 0.5, 0.7, 0.0, 0.0, 0.0, *_OFF), (1.0, 0.0, 0.5, 0.7, 0.0, 0.0, 0.0, *_OFF),
    (1.5, 0.0, 0.5, 0.7, 0.0, 0.0, 0.0, *_OFF), (0.0, 4.0, 0.5, 0.7, 0.0, 0.0, 0.0, *_OFF),
    (0.0, 4.0, 0.45, 0.65, 0.0, 0.0, 0.0, *_OFF), (0.0, 4.0, 0.4, 0.6, 0.0, 0.0, 0.0, *_OFF),
    (0.0, 0.0, 0.5, 0.7, 20.0, 0.0, 0.0, *_OFF), (0.0, 0.0, 0.5, 0.7, 10.0, 0.6, 1.2, *_OFF),
    (0.0, 0.0, 0.5, 0.7, *_CONE, *_OFF), (1.0, 0.0, 0.5, 0.7, 10.0, 0.6, 1.2, *_OFF),
    (1.0, 0.0, 0.5, 0.7, *_CONE, *_OFF), (1.0, 0.0, 0.5, 0.7, 30.0, 0.6, 1.2, *_OFF),
    (0.0, 0.0, 0.5, 0.7, *_CONE, 4.0, 0.6, 3.0, *_ANY_FB), (0.0, 0.0, 0.5, 0.7, *_CONE, 4.0, 0.6, 1.5, *_ANY_FB),
    (0.0, 0.0, 0.5, 0.7, *_CONE, 2.0, 0.6, 3.0, *_ANY_FB), (0.0, 0.0, 0.5, 0.7, 0.0, 0.0, 0.0, 4.0, 0.6, 3.0, *_ANY_FB),
    (1.0, 0.0, 0.5, 0.7, *_CONE, 4.0, 0.6, 1.5, *_ANY_FB), (1.0, 0.0, 0.5, 0.7, *_CONE, 4.0, 0.6, 3.0, *_ANY_FB),
    (0.0, 0.0, 0.5, 0.7, *_CONE, 0.0, 0.0, 3.0, 1.0, 3.0, 0.0),
    (0.0, 0.0, 0.5, 0.7, *_CONE, 0.0, 0.0, 3.0, 0.5, 2.0, 0.0),
    (1.0, 0.0, 0.5, 0.7, *_CONE, 0.0, 0.0, 3.0, 1.0, 3.0, 0.0),
    (0.0, 0.0, 0.5, 0.7, *_CONE, 0.0, 0.0, 3.0, 0.0, 0.0, 0.05),
    (0.0, 0.0, 0.5, 0.7, *_CONE, 0.0, 0.0, 3.0, 0.0, 0.0, 0.1),
    (0.0, 0.0, 0.5, 0.7, *_CONE, 0.0, 0.0, 3.0, 0.0, 0.0, 0.15),
    (0.0, 0.0, 0.5, 0.7, *_CONE, 0.0, 0.0, 3.0, 0.0, 0.0, 0.2),
    (0.0, 0.0, 0.5, 0.7, *_CONE, 0.0, 0.0, 3.0, 0.0, 0.0, 0.3))
TITLE = ("The flow prior's gates: C's contrast as it is, above its noise or blurred by it; the frame's factor at U's "
         "epipoles")
#: the labels' and ``--candidates``' fields
FIELDS = ("<contrast_noise>-<agreement_contrast>-<low>-<high>-<cone>-<noise_low>-<noise_high>-<blur>-<blur_floor>-"
          "<max_blur>-<fb_low>-<fb_high>-<room>")


def gate_method(contrast_noise: float, agreement_contrast: float, low: float, high: float,
                cone_deg: float = 0.0, cone_noise_low: float = 0.0, cone_noise_high: float = 0.0,
                blur: float = 0.0, blur_floor: float = 0.0, max_blur_px: float = 3.0, fb_low: float = 0.0,
                fb_high: float = 0.0, room: float = 0.0) -> Method:
    """The default method whose flow prior reads C's contrast above ``contrast_noise`` times C's noise, of C's image
    blurred by ``blur * (n - blur_floor)`` pixels (at most ``max_blur_px``; ``n`` C's noise, gray levels), in its
    per-pixel gate and counts only the pixels whose contrast above the noise is at least ``agreement_contrast`` gray
    levels (0: every pixel) in the frame's agreement share, ramped from ``low`` to ``high``, that factor spared within
    ``cone_deg`` degrees of U's epipoles in proportion to the rig's noise between ``cone_noise_low`` and
    ``cone_noise_high`` (0-0: fully) and, at each pixel, from fully at ``fb_low`` to not at all at ``fb_high``
    pixels of the C -> R flow's forward-backward inconsistency (0-0: wherever the cone is on), and only where the
    flow lies within ``room`` (relative) of the floor or the ceiling the sweep's coarse pass found (0: anywhere);
    everything else the default's; labelled ``fused-mirror-gate-`` and the thirteen values in :data:`FIELDS`' order.
    """
    base = fused_mirror()
    prior = dataclasses.replace(base.prior, contrast_noise=contrast_noise,
                                frame_agreement_contrast=agreement_contrast, frame_agreement_low=low,
                                frame_agreement_high=high, epipole_cone_deg=cone_deg,
                                epipole_cone_noise_low=cone_noise_low, epipole_cone_noise_high=cone_noise_high,
                                contrast_blur=blur, contrast_blur_floor=blur_floor, contrast_max_blur_px=max_blur_px,
                                epipole_cone_fb_low=fb_low, epipole_cone_fb_high=fb_high, epipole_cone_room=room)
    config = (contrast_noise, agreement_contrast, low, high, cone_deg, cone_noise_low, cone_noise_high, blur,
              blur_floor, max_blur_px, fb_low, fb_high, room)
    return dataclasses.replace(base, prior=prior, label=f"{base.label}-gate-{config_name(config)}")


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`gate_method` per candidate (``names``: these only, as
    :data:`FIELDS`) and the default (:func:`tools.research.select_fill.methods_to_compare`)."""
    return methods_to_compare(gate_method, REFERENCE, CANDIDATES, config_name, names)


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, FIELDS, [config_name(c) for c in CANDIDATES],
                           TITLE)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
