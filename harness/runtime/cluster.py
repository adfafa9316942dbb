"""Where a job's tasks run: in this process (the default), or on Dask ``distributed`` (``harness.runtime.executor``).

This module is deliberately light (no Dask import): the command line builds a :class:`ClusterOptions` from
``--scheduler``/``--workers``/``--tls-*`` and the jobs call :func:`open_executor`, which loads
:mod:`harness.runtime.executor` (and with it Dask) only when a cluster is asked for, the way the Cycles backend
loads ``bpy`` only in its worker.  ``import harness.cli`` therefore never imports Dask.

An executor (:class:`Executor`) runs independent tasks and yields their results as they complete::

    with open_executor(ClusterOptions(workers=2)) as ex:           # None / ClusterOptions() = in this process
        for key, result in ex.run(fn, {"vp000": (a, b), "vp001": (c, d)}, desc="render", unit="frame"):
            ...

A command gets either from its :class:`harness.runtime.context.RunContext` (``ctx.executor()``): cluster options
(it opens and closes its own executor) or an executor that is already open (e.g. the one a study opens once for
all its renders and evaluations: used and left open).

:meth:`ClusterOptions.check` refuses, before any cluster starts, what cannot work: more ``--workers`` than the
machine can run (:func:`max_workers`: cores and memory), TLS files that are missing or not PEM (naming which
of ``--tls-ca/--tls-cert/--tls-key``), a malformed ``--scheduler``.

Every task is a module-level function and its arguments (both pickled to the workers); every key appears
exactly once in the output, whatever workers were lost on the way (Dask re-runs the tasks of a lost worker).
"""

from __future__ import annotations

import contextlib
import importlib
import os
import re
import ssl
from collections.abc import Callable, Hashable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, runtime_checkable

from harness.data.errors import UserError
from harness.runtime.progress import progress_bar

__all__ = ["ClusterOptions", "Executor", "SequentialExecutor", "open_executor", "EXECUTOR_MODULE", "max_workers",
           "machine_cores", "physical_memory_bytes", "BASE_BYTES",
           "MEMORY_SHARE", "WORKERS_PER_CORE"]

EXECUTOR_MODULE = "harness.runtime.executor"
"""The Dask executor module, imported only when a cluster is asked for."""
BASE_BYTES = 1 << 30
"""Memory of one process that does not grow with the width (Python, NumPy, OpenCV, Blender: measured about
0.55 GiB), bytes: also what each task of a ``--workers`` cluster needs at the least."""
MEMORY_SHARE = 0.8
"""Share of the physical memory a render, a reconstruction or a local cluster may plan to use (the rest: the
OS, other programs)."""
WORKERS_PER_CORE = 2
"""Tasks at once per CPU core a ``--workers`` cluster may run (a render or a reconstruction keeps a core busy;
more only wait for the same cores, each costing a process and its memory)."""


def machine_cores() -> int:
    """CPU cores this process may run on (its affinity mask; ``os.cpu_count()`` where there is none)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def physical_memory_bytes() -> int:
    """Physical memory of this machine, bytes (``SC_PHYS_PAGES * SC_PAGE_SIZE``)."""
    return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def max_workers(threads_per_worker: int = 1, cores: int | None = None, memory_bytes: int | None = None) -> int:
    """The most ``--workers`` this machine runs usefully: tasks at once (workers x threads) at most
    :data:`WORKERS_PER_CORE` per core and :data:`BASE_BYTES` each within :data:`MEMORY_SHARE` of the memory
    (0 when even one worker of ``threads_per_worker`` threads does not fit)."""
    cores = machine_cores() if cores is None else cores
    memory = physical_memory_bytes() if memory_bytes is None else memory_bytes
    tasks = min(WORKERS_PER_CORE * cores, int(MEMORY_SHARE * memory // BASE_BYTES))
    return tasks // threads_per_worker


def _check_pem(path: Path, flag: str) -> None:
    """Raise UserError naming ``flag`` unless ``path`` is a readable PEM file of the kind the flag needs."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise UserError(f"{path}: {flag} file cannot be read ({exc.strerror or exc})") from None
    if flag == "--tls-key":
        if not re.search(rb"-----BEGIN (?:[A-Z]+ )?PRIVATE KEY-----", data):
            raise UserError(f"{path}: {flag} is not a PEM private key (no '-----BEGIN PRIVATE KEY-----' block)")
        return
    blocks = re.findall(rb"-----BEGIN CERTIFICATE-----.*?-----END CERTIFICATE-----", data, flags=re.S)
    if not blocks:
        raise UserError(f"{path}: {flag} is not a PEM certificate (no '-----BEGIN CERTIFICATE-----' block)")
    try:
        for block in blocks:
            ssl.PEM_cert_to_DER_cert(block.decode("ascii"))
        if flag == "--tls-ca":
            ssl.create_default_context(cafile=os.fspath(path))
    except (ValueError, UnicodeDecodeError, ssl.SSLError) as exc:
        raise UserError(f"{path}: {flag} is not a valid PEM certificate ({exc})") from None


class _Encrypted(Exception):
    pass


def _no_password():
    raise _Encrypted


def _check_key_pair(cert: Path, key: Path) -> None:
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    try:
        context.load_cert_chain(os.fspath(cert), os.fspath(key), password=_no_password)
    except _Encrypted:
        raise UserError(f"{key}: --tls-key is encrypted; give the key without a passphrase (Dask cannot ask "
                        "for one)") from None
    except ssl.SSLError as exc:
        raise UserError(f"{key}: --tls-key is not the private key of --tls-cert {cert} ({exc.reason or exc})") \
            from None


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
        if self.workers is not None:
            top = max_workers(self.threads_per_worker)
            if self.workers > top:
                cores, memory = machine_cores(), physical_memory_bytes()
                per = (f"{self.threads_per_worker} threads each, " if self.threads_per_worker > 1 else "")
                raise UserError(f"--workers {self.workers}: this machine has {cores} core{'s' * (cores != 1)} and "
                                f"{memory / 2**30:.0f} GiB; at most {top} workers ({per}{WORKERS_PER_CORE} tasks "
                                f"per core, about {BASE_BYTES / 2**30:.0f} GiB each)")
        if self.tls:
            missing = [f"--tls-{n}" for n in ("ca", "cert", "key") if getattr(self, f"tls_{n}") is None]
            if missing:
                raise UserError(f"TLS needs --tls-ca, --tls-cert and --tls-key together; missing {', '.join(missing)}")
            for n in ("ca", "cert", "key"):
                p = Path(getattr(self, f"tls_{n}"))
                if not p.is_file():
                    raise UserError(f"{p}: --tls-{n} file does not exist")
                _check_pem(p, f"--tls-{n}")
            _check_key_pair(Path(self.tls_cert), Path(self.tls_key))
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


@runtime_checkable
class Executor(Protocol):
    """Where a job's tasks run: :class:`SequentialExecutor` (here) or ``harness.runtime.executor.DaskExecutor``.

    Attributes:
        distributed: True when tasks run on other processes (Dask workers): a job then submits everything at
            once and the workers write their outputs themselves.
    """

    distributed: bool

    def run(self, fn: Callable, tasks: Mapping[Hashable, tuple], desc: str = "", unit: str = "task",
            progress: bool = True, names: Mapping[Hashable, str] | None = None) -> Iterator[tuple[Hashable, object]]:
        """Run ``fn(*args)`` for every ``key: args``; yield each ``(key, result)`` exactly once, as they finish."""
        ...

    def close(self) -> None:
        """Cancel what is pending and release the workers (a local cluster is stopped); idempotent."""
        ...


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
def open_executor(options: ClusterOptions | None) -> Iterator[Executor]:
    """The executor ``options`` ask for (closed, and a local cluster stopped, on exit); None: in this process."""
    if options is None or not options.distributed:
        yield SequentialExecutor()
        return
    options.check()
    module = importlib.import_module(EXECUTOR_MODULE)  # loads Dask, only now
    with module.DaskExecutor(options) as ex:
        yield ex

