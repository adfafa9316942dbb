"""Multi-view matching: a trinocular sphere sweep over joint label families with semi-global matching.

Stages (each its own module, each vectorised numpy / OpenCV, numba only for the SGM recursion):

* :mod:`reconstruction.sweep.cost` -- per-pair rectified features and the uint16 cost volume of camera C over
  distance hypotheses uniform in inverse distance (each camera's own pose, any rig orientation);
* :mod:`reconstruction.sweep.planes` -- the "horizontal plane at height h" label family (gravity = world Z),
  indexing the same cost volume;
* :mod:`reconstruction.sweep.sgm` -- 8-path semi-global aggregation on the equirect grid, wrapping in longitude,
  with winner-take-all, sub-level refinement and a per-pixel confidence.
"""
