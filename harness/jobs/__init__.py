"""The jobs behind the ``tri360`` commands, and the ``python -m harness.jobs.<job>`` scripts (benchmarks, the
selection and validation jobs).

Run as a script, a job's imports (numba, pandas, Dask: seconds) run under :func:`harness.jobs.startup.guard`, set
here before the job's module loads, so that Ctrl-C during them is one line and exit status 130; the job's
``main`` runs through :func:`harness.jobs.startup.run_main`, which puts Python's handler back.
"""

import sys

from harness.jobs import startup

# ``sys.argv[0]`` is "-m" while Python locates the module of ``python -m``: this package loads first as its parent.
# Only a job run that way is guarded here (``python -m harness.cli`` imports this package too, and sets its own).
_argv = list(getattr(sys, "orig_argv", []))
_run = _argv[_argv.index("-m") + 1] if "-m" in _argv[:-1] else ""
if sys.argv[:1] == ["-m"] and _run.startswith("harness.jobs."):
    startup.guard(_run.rsplit(".", 1)[-1])
