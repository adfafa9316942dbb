"""The research scripts behind tri360's defaults, rerunnable (``python -m tools.research.<name>``):

- ``select_matching``: the default matching method; ``select_photometric``: its photometric self-calibration; both
  from the candidates of :mod:`tools.research.candidates`;
- ``select_cost``: the default method with each per-pixel feature of the sweep cost, per camera condition;
- ``validate_quality``: the ground-truth-free quality measures against true error;
- ``render_subset``: the first viewpoints of every group of a suite split, with their twins (the subset the
  selections take with ``--partial``);
- ``calibration_floor``: what the default's self-calibration fits on each frame of a data root, and whether it
  applies it;
- ``check_calibration``: the self-calibration's bounds on a results set (no harm on cameras that agree, holding on
  every camera family).
"""
