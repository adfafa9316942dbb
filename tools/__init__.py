"""tri360's tools: the benchmarks (``tools/bench/``), the research scripts that chose the defaults
(``tools/research/``) and the CI regression bounds (``tools/regression.py``).

Not installed (``pyproject.toml`` installs ``harness``, ``reconstruction``, ``reports`` and ``scenes`` only) and
never imported by those packages (``tests/test_architecture.py`` checks it): the tools import the packages, not
the other way round.  Run them from the repository root as modules, e.g. ``python -m tools.bench.pipeline`` or
``python -m tools.regression --bounds tests/regression_bounds.json`` (``make bench``, ``make regress-update``);
the root on ``sys.path`` is what makes ``tools`` importable (``python -m`` puts the working directory there, and
pytest puts the root there for ``tests``).  What several tools share -- goal lines, the bench frame, the
selection scripts' options and output -- is :mod:`tools.common`.
"""
