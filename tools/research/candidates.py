"""The candidates of the selection scripts, as data: one small typed value per candidate, its label beside the
settings it stands for (the label names the method in the results; nothing is read from it).

- :data:`MATCHING`: the fused methods ``select_matching`` tries beside the registered ones (:class:`MatchingCandidate`:
  plane families, prior weight per pixel, where the prior comes from);
- :data:`PHOTOMETRIC`: the self-calibrations of the default's matching that ``select_photometric`` tries
  (:class:`PhotometricCandidate`: photometric parameters, the sweep cost's intensity weight).

Both are ``label -> candidate`` in the order they run.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TypeVar

from reconstruction.methods.base import Method
from reconstruction.methods.prior_sweep import PriorParams, PriorSweepMethod
from reconstruction.methods.registry import with_photometric
from reconstruction.photometry import PhotometricParams
from reconstruction.rig_calibration import NO_RIG_CALIBRATION, RigParams
from reconstruction.sweep.planes import PlaneParams

__all__ = ["MatchingCandidate", "PhotometricCandidate", "by_label", "WALL_PLANES", "WALLS_COARSE3", "MATCHING",
           "PHOTOMETRIC"]


@dataclass(frozen=True)
class MatchingCandidate:
    """A fused method on ``fused``'s flow and sweep that differs in its sweep's plane families and its prior.

    Attributes:
        label: the method's label.
        prior: the prior weight per pixel (:class:`reconstruction.methods.prior_sweep.PriorParams`).
        planes: the sweep's plane families (:class:`reconstruction.sweep.planes.PlaneParams`); None = ``fused``'s
            (no walls).
        average_prior: the prior is the flow pipeline's unrefined distance (``dis-rect:average``: no LM, so
            cheaper) instead of ``fused``'s flow.
    """

    label: str
    prior: PriorParams
    planes: PlaneParams | None = None
    average_prior: bool = False

    def method(self, base: PriorSweepMethod, average: Method) -> PriorSweepMethod:
        """The candidate built on ``base`` (``fused``), ``average`` the ``dis-rect:average`` method."""
        sweep = base.sweep if self.planes is None else dataclasses.replace(base.sweep, planes=self.planes)
        return PriorSweepMethod(flow=average if self.average_prior else base.flow, sweep=sweep, prior=self.prior,
                           label=self.label)


@dataclass(frozen=True)
class PhotometricCandidate:
    """The default's matching with a photometric self-calibration and an intensity weight of the sweep cost.

    Attributes:
        label: the method's label.
        photometric: the self-calibration of its flow, sweep and quality flow
            (:class:`reconstruction.photometry.PhotometricParams`).
        intensity_weight: the sweep cost's intensity weight when the self-calibration changed the images
            (``SweepMethod.corrected_cost``; cameras that agree are matched with the sweep's own cost).
        rig: the rig self-calibration of its flow and quality flow (:class:`reconstruction.rig_calibration.
            RigParams`).
        blur_px: the Gaussian blur of the sweep's grey images when the self-calibration changed them, pixels
            (``CostParams.blur_px`` of ``corrected_cost``).
    """

    label: str
    photometric: PhotometricParams
    intensity_weight: float
    rig: RigParams = RigParams()
    blur_px: float = 0.0

    def method(self, base: PriorSweepMethod) -> PriorSweepMethod:
        """The candidate built on ``base`` (the default's matching, ``presets.fused_mirror()``)."""
        m = with_photometric(base, self.photometric, self.label)
        cost = dataclasses.replace(m.sweep.corrected_cost or m.sweep.cost, intensity_weight=self.intensity_weight,
                                   blur_px=self.blur_px)
        quality = m.quality_flow
        return dataclasses.replace(m, sweep=dataclasses.replace(m.sweep, corrected_cost=cost),
                                   flow=dataclasses.replace(m.flow, rig=self.rig),
                                   quality_flow=None if quality is None else dataclasses.replace(quality, rig=self.rig))

    def record(self) -> dict:
        """What ``selection.json`` records of the candidate: ``photometric`` and ``rig`` (as dicts),
        ``intensity_weight`` and ``blur_px``."""
        return {"photometric": self.photometric.config(), "intensity_weight": self.intensity_weight,
                "rig": dataclasses.asdict(self.rig), "blur_px": self.blur_px}


C = TypeVar("C", MatchingCandidate, PhotometricCandidate)


def by_label(*candidates: C) -> dict[str, C]:
    """``label -> candidate`` in the given order; a label given twice is an error."""
    out: dict[str, C] = {}
    for c in candidates:
        if c.label in out:
            raise ValueError(f"candidate label {c.label!r} given twice")
        out[c.label] = c
    return out


#: the sweep's horizontal planes plus 9 labels per wall found by the coarse pass: the plane families of
#: ``fused-adaptive`` and ``fused-gated`` (:mod:`reconstruction.methods.presets`)
WALL_PLANES = PlaneParams(wall_labels=9)
#: the default's wall families with the coarse room-bound pass on images 3x smaller instead of 2x (the coarse pass
#: is then about 0.6 s CPU cheaper at 1000x500, about what the wall labels cost in SGM)
WALLS_COARSE3 = dataclasses.replace(WALL_PLANES, coarse_factor=3)

#: The fused candidates of ``select_matching`` besides the registered ``fused-adaptive``
#: (:func:`reconstruction.methods.presets.fused_adaptive`: wall families, frame agreement 0.6-0.8; the first dev
#: selection chose it under the candidate label ``fused-walls-f0.6-0.8``), ``fused-gated``
#: (:func:`reconstruction.methods.presets.fused_gated`; the dev selection with the time bound chose it under the
#: candidate label ``fused-walls-k1-f0.5-0.7-avg-c0.5-2``) and the default ``fused-mirror`` (``fused-gated`` with the
#: room bound's mirror test; the third dev selection).  A first look at 10 dev frames (classroom, seminar, lab) left
#: out three more that were worse than ``sweep`` pooled: the flow confidence alone, wall families alone, and wall
#: families with the sweep-confidence power only.
MATCHING: dict[str, MatchingCandidate] = by_label(
    MatchingCandidate("fused-c0.5-2", PriorParams(contrast_low=0.5, contrast_high=2.0)),
    MatchingCandidate("fused-walls-f0.4-0.6", PriorParams(frame_agreement_low=0.4, frame_agreement_high=0.6),
                      planes=WALL_PLANES),
    MatchingCandidate("fused-walls-f0.5-0.7", PriorParams(frame_agreement_low=0.5, frame_agreement_high=0.7),
                      planes=WALL_PLANES),
    MatchingCandidate("fused-walls-k1-f0.5-0.7", PriorParams(sweep_confidence_power=1.0, frame_agreement_low=0.5,
                                                             frame_agreement_high=0.7), planes=WALL_PLANES),
    MatchingCandidate("fused-walls-k1-f0.5-0.7-avg", PriorParams(sweep_confidence_power=1.0, frame_agreement_low=0.5,
                                                                 frame_agreement_high=0.7),
                      planes=WALL_PLANES, average_prior=True),
    # the local-contrast gate of fused-c0.5-2 on the best wall candidates: no flow prior where C's image has no
    # texture for the flow to follow (a plain board or wall, where the wall labels carry the sweep); -q3: the
    # cheaper coarse pass, so that the walls cost no more time than fused
    MatchingCandidate("fused-walls-f0.6-0.8-c0.5-2", PriorParams(contrast_low=0.5, contrast_high=2.0,
                                                                 frame_agreement_low=0.6, frame_agreement_high=0.8),
                      planes=WALL_PLANES),
    MatchingCandidate("fused-walls-f0.6-0.8-c0.5-2-q3", PriorParams(contrast_low=0.5, contrast_high=2.0,
                                                                    frame_agreement_low=0.6,
                                                                    frame_agreement_high=0.8),
                      planes=WALLS_COARSE3),
)

#: The self-calibrations of the default's matching that ``select_photometric`` tries.
PHOTOMETRIC: dict[str, PhotometricCandidate] = by_label(
    PhotometricCandidate("fused-mirror-i1", PhotometricParams(), 1.0),
    PhotometricCandidate("fused-mirror-i0.5", PhotometricParams(), 0.5),
    PhotometricCandidate("fused-mirror-i0.25", PhotometricParams(), 0.25),
    PhotometricCandidate("fused-mirror-i0.5-d4", PhotometricParams(degree=4), 0.5),
    PhotometricCandidate("fused-mirror-even", PhotometricParams(even=True), 0.25),
    PhotometricCandidate("fused-mirror-told-poses", PhotometricParams(), 0.25, NO_RIG_CALIBRATION),
    PhotometricCandidate("fused-mirror-rig", PhotometricParams(), 0.25),
    PhotometricCandidate("fused-mirror-rig-b0.5", PhotometricParams(), 0.25, blur_px=0.5),
    PhotometricCandidate("fused-mirror-rig-b0.7", PhotometricParams(), 0.25, blur_px=0.7),
    PhotometricCandidate("fused-mirror-rig-b1", PhotometricParams(), 0.25, blur_px=1.0),
)
