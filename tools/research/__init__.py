"""The research scripts behind tri360's defaults, rerunnable (``python -m tools.research.<name>``):
``select_matching`` (the default matching method), ``select_photometric`` (its photometric self-calibration),
both from the candidates of :mod:`tools.research.candidates`, and ``validate_quality`` (the ground-truth-free
quality measures against true error)."""
