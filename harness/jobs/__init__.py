"""The jobs behind the ``tri360`` commands, and the ``python -m harness.jobs.<job>`` scripts (benchmarks, the
selection and validation jobs).

Importing this package does nothing.  A script guards its own imports: its module, run as ``__main__``, calls
:func:`harness.jobs.startup.guard` before its heavy imports (numba, pandas, Dask: seconds), so that Ctrl-C during
them is one line and exit status 130, and runs its ``main`` through :func:`harness.jobs.startup.run_main`, which
puts Python's handler back.
"""
