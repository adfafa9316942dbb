"""The sweep with the flow pipeline's distance as a prior inside SGM (``fused``): tri360's most accurate method.

The flow pipeline (DIS on rectified pairs + the ``gradient`` LM variant) matches large structures well (coarse-
to-fine flow) but blurs edges and is noisy on weak texture; the trinocular sweep is sharp and robust to glossy
reflections (room bound) but locks onto shifted periods of repeating patterns (tiled floors) where only one pair
sees texture.  ``fused`` adds the flow's evidence to the sweep's cost volume before aggregation: every sphere label
``i`` of pixel p costs ``weight * min(|i - l_flow(p)|, truncate_levels)`` more (``l_flow`` = the flow distance's
fractional label), then the plane labels, SGM, winner, confidence and median run as in ``sweep``.  Measured in
docs/matching.md.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field

import numpy as np

from reconstruction.methods.base import MethodOutput
from reconstruction.methods.flow_pipeline import FlowMethod
from reconstruction.methods.sweep import SgmParams, SweepMethod, sweep_distance
from reconstruction.sweep.cost import CostParams

__all__ = ["PriorParams", "FusedMethod", "fused_sweep"]


def fused_sweep() -> SweepMethod:
    """The sweep configuration of ``fused``: the sweep's defaults, which were chosen with the prior (over the 4
    classroom frames + synthetic_box, docs/matching.md) and also serve the plain sweep best: a strong +-1-step
    penalty (P1 120, P2 800), truncation 30 gray levels, 160 labels and pixel-wise costs (no blur, no box filter,
    gradients weighted 2)."""
    return SweepMethod(cost=CostParams(), sgm=SgmParams())


@dataclass(frozen=True)
class PriorParams:
    """How strongly the flow distance pulls the sweep's labels.

    Attributes:
        weight: cost units (see ``CostParams.scale``: 8 per gray level) per sphere label between a hypothesis and
            the flow's distance.
        truncate_levels: label distance beyond which the prior cost stops growing, labels (robust: a wrong flow
            distance costs at most ``weight * truncate_levels``).
        use_confidence: scale the weight per pixel by the flow's confidence (``flow_confidence``) instead of 1.
    """

    weight: float = 16.0
    truncate_levels: float = 16.0
    use_confidence: bool = False


@dataclass(frozen=True)
class FusedMethod:
    """Flow pipeline -> prior cost in the sweep's volume -> SGM (a :class:`Method`).

    Attributes:
        flow: the flow-pipeline method whose distance is the prior (e.g. ``dis-rect:gradient``).
        sweep: the sweep's parameters (cost, planes, SGM, post; :class:`SweepMethod`).
        prior: prior strength (:class:`PriorParams`).
        label: the method's label.
    """

    flow: FlowMethod
    sweep: SweepMethod = field(default_factory=fused_sweep)
    prior: PriorParams = field(default_factory=PriorParams)
    label: str = "fused"

    def config(self) -> dict:
        return {"kind": "fused", "label": self.label, "flow": self.flow.config(), "sweep": self.sweep.config(),
                "prior": asdict(self.prior)}

    def run(self, frame) -> MethodOutput:
        """Run the flow method, then the sweep with its distance as prior; seconds per stage of both (wall),
        ``info["cpu_seconds"]`` the process CPU time of the sweep's stages and of the flow (all threads)."""
        t, c = time.perf_counter(), time.process_time()
        flow = self.flow.run(frame)
        flow_wall, flow_cpu = time.perf_counter() - t, time.process_time() - c
        d_flow = flow.distance
        if self.prior.use_confidence and flow.confidence is not None:
            weight = self.prior.weight * flow.confidence
        else:
            weight = np.full(d_flow.shape, self.prior.weight, np.float32)
        s = self.sweep
        d, conf, seconds, info = sweep_distance(frame, s.cost, s.planes, s.sgm, s.post, s.pairs,
                                                prior=(d_flow, weight.astype(np.float32), self.prior.truncate_levels))
        seconds = {"flow": flow_wall, **{k: v for k, v in seconds.items() if k != "total"}}
        seconds["total"] = sum(seconds.values())
        cpu = dict(info.get("cpu_seconds", {}))
        cpu["flow"] = flow_cpu
        cpu["total"] = cpu.get("total", 0.0) + flow_cpu
        info = {**info, "cpu_seconds": cpu, "flow_label": self.flow.label}
        return MethodOutput(distance=d, confidence=conf, seconds=seconds, info=info)
