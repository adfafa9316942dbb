"""The jobs behind the ``tri360`` commands, and the ``python -m harness.jobs.<job>`` scripts (benchmarks, the
selection and validation jobs).

Run as a script, a job's imports (numba, pandas, Dask: seconds) run under :func:`harness.startup.guard`, set
here before the job's module loads, so that Ctrl-C during them is one line and exit status 130; the job's
``main`` runs through :func:`harness.startup.run_main`, which puts Python's handler back.
"""

import sys

from harness import startup

if sys.argv[:1] == ["-m"]:  # set by Python while it locates the module of ``python -m``: this package's parent
    _job = next((a for a in getattr(sys, "orig_argv", [])[1:] if a.startswith("harness.jobs.")), "harness.jobs")
    startup.guard(_job.rsplit(".", 1)[-1])
