"""The benchmarks ``make bench`` runs, one module each (``python -m tools.bench.<name>``): ``pipeline`` (the flow
pipeline's stages, vectorised LM against per-pixel scipy), ``sweep`` (the default method's time and memory),
``render`` (the default classroom render), ``dask_speedup`` (2 Dask workers against 1), ``suite`` (a suite
frame's render time against the default frame's) and ``flow`` (DeepMatching and DeepFlow as published).  Each
prints its goals as ``[PASS]`` / ``[FAIL]`` lines (:func:`tools.common.report_goals`) and exits with status 1 when
one is missed.  ``python -m tools.bench`` (``make bench``, :mod:`tools.bench.__main__`) runs them all, whatever each
one's outcome, and ends with one table of every goal."""
