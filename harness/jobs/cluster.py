"""Where a job's tasks run: in this process (the default), or on Dask ``distributed`` (``harness.jobs.executor``).

This module is deliberately light (no Dask import): the command line builds a :class:`ClusterOptions` from
``--scheduler``/``--workers``/``--tls-*`` and the jobs call :func:`open_executor`, which loads
:mod:`harness.jobs.executor` (and with it Dask) only when a cluster is asked for, the way the Cycles backend
loads ``bpy`` only in its worker.  ``import harness.cli`` therefore never imports Dask.

An executor runs independent tasks and yields their results as they complete::

    with open_executor(ClusterOptions(workers=2)) as ex:           # None / ClusterOptions() = in this process
        for key, result in ex.run(fn, {"vp000": (a, b), "vp001": (c, d)}, desc="render", unit="frame"):
            ...

Every task is a module-level function and its arguments (both pickled to the workers); every key appears
exactly once in the output, whatever workers were lost on the way (Dask re-runs the tasks of a lost worker).
"""

from __future__ import annotations

import contextlib
import importlib
from collections.abc import Callable, Hashable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from harness.data.errors import UserError
from harness.jobs.progress import progress_bar

__all__ = ["ClusterOptions", "SequentialExecutor", "open_executor", "EXECUTOR_MODULE"]

EXECUTOR_MODULE = "harness.jobs.executor"
"""The Dask executor module, imported only when a cluster is asked for."""


@dataclass(frozen=True)
class ClusterOptions:
    """Where to run.  Neither ``scheduler`` nor ``workers``: in this process, as always.

    Attributes:
        scheduler: address of an existing Dask scheduler (``tcp://host:port`` or ``tls://host:port``), or a
            scheduler file (JSON written by ``dask scheduler --scheduler-file``).
        workers: start a ``LocalCluster`` of this many worker processes, bound to 127.0.0.1 only, and stop it
            at the end.
        threads_per_worker: threads of each ``LocalCluster`` worker (tasks run at once per worker).
        tls_ca, tls_cert, tls_key: PEM files for ``tls://`` schedulers (Dask ``Security``): the CA that signed
            the cluster's certificates, this client's certificate and its private key.
        connect_timeout_s: how long to wait for an existing scheduler, seconds.
    """

    scheduler: str | None = None
    workers: int | None = None
    threads_per_worker: int = 1
    tls_ca: Path | None = None
    tls_cert: Path | None = None
    tls_key: Path | None = None
    connect_timeout_s: float = 30.0

    @property
    def distributed(self) -> bool:
        return self.scheduler is not None or self.workers is not None

    @property
    def tls(self) -> bool:
        return any(x is not None for x in (self.tls_ca, self.tls_cert, self.tls_key))

    def check(self) -> None:
        """Raise UserError naming the first option that cannot work (before any cluster starts)."""
        if self.scheduler is not None and self.workers is not None:
            raise UserError("give either --scheduler ADDRESS (an existing cluster) or --workers N (a local one), "
                            "not both")
        if self.workers is not None and self.workers < 1:
            raise UserError(f"--workers must be >= 1, got {self.workers}")
        if self.threads_per_worker < 1:
            raise UserError(f"threads per worker must be >= 1, got {self.threads_per_worker}")
        if self.tls:
            missing = [f"--tls-{n}" for n in ("ca", "cert", "key") if getattr(self, f"tls_{n}") is None]
            if missing:
                raise UserError(f"TLS needs --tls-ca, --tls-cert and --tls-key together; missing {', '.join(missing)}")
            for n in ("ca", "cert", "key"):
                p = Path(getattr(self, f"tls_{n}"))
                if not p.is_file():
                    raise UserError(f"{p}: --tls-{n} file does not exist")
            if self.scheduler is None:
                raise UserError("--tls-ca/--tls-cert/--tls-key are for --scheduler tls://...; a --workers cluster "
                                "is reachable from this machine only (127.0.0.1) and needs no certificates")
        if self.scheduler is not None:
            s = self.scheduler
            if s.startswith("tls://") and not self.tls:
                raise UserError(f"--scheduler {s} is a TLS address: give --tls-ca, --tls-cert and --tls-key")
            if "://" not in s and not Path(s).is_file() and ":" not in s:
                raise UserError(f"--scheduler {s}: neither an address (tcp://HOST:PORT, tls://HOST:PORT) nor an "
                                "existing scheduler file")


class SequentialExecutor:
    """Runs every task here, one after the other, in the order given (what tri360 always did)."""

    distributed = False

    def run(self, fn: Callable, tasks: Mapping[Hashable, tuple], desc: str = "", unit: str = "task",
            progress: bool = True, names: Mapping[Hashable, str] | None = None) -> Iterator[tuple[Hashable, object]]:
        names = names or {}
        with progress_bar(len(tasks), desc=desc, unit=unit, enabled=progress) as bar:
            for key, args in tasks.items():
                bar.set_postfix_str(names.get(key, str(key)))
                result = fn(*args)
                bar.update(1)
                yield key, result

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@contextlib.contextmanager
def open_executor(options) -> Iterator:
    """The executor ``options`` ask for (closed, and a local cluster stopped, on exit).

    ``options`` may also be an executor that is already open (anything with ``run``, e.g. the one a study opens
    once for all its renders and evaluations): it is used as it is and left open.
    """
    if hasattr(options, "run"):
        yield options
        return
    if options is None or not options.distributed:
        yield SequentialExecutor()
        return
    options.check()
    module = importlib.import_module(EXECUTOR_MODULE)  # loads Dask, only now
    with module.DaskExecutor(options) as ex:
        yield ex
