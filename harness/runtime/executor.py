"""The Dask ``distributed`` executor: a job's tasks on an existing cluster or on a ``LocalCluster`` of our own.

Loaded only through :func:`harness.runtime.cluster.open_executor` (this is the one module of tri360 that imports
Dask).  Two ways to get workers:

- ``ClusterOptions(workers=N)``: a ``LocalCluster`` of N worker processes (``threads_per_worker`` threads each)
  started here and stopped at the end.  Scheduler, workers and nannies listen on 127.0.0.1 only and the
  dashboard is off, so nothing is reachable from another machine.
- ``ClusterOptions(scheduler=ADDRESS)``: an existing scheduler (``dask scheduler`` + ``dask worker``, or
  ``dask-jobqueue`` on SLURM), plain ``tcp://`` or ``tls://`` with certificates (Dask ``Security``:
  ``tls_ca``, ``tls_cert``, ``tls_key``; encryption required).  ADDRESS may also be a scheduler file.

Tasks are submitted with unique keys (``tri360_<job>-<run token>-<n>``, ``pure=False``; the scheduler groups
them under the task prefix ``tri360_<job>``), results are taken as they complete (``as_completed``) and
released at once.  When a worker dies, the scheduler re-runs its tasks elsewhere (up to
``distributed.scheduler.allowed-failures`` times, then ``KilledWorker``, reported as one line): the tasks write
their outputs atomically and idempotently, so a re-run costs time only; the client keeps exactly one
result per key.  The data root (and a results directory that tasks write to) must be on a file system that
every worker sees at the same path (``docs/scale-out.md``).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import multiprocessing
import multiprocessing.forkserver
import signal
import threading
import uuid
from collections.abc import Callable, Hashable, Iterator, Mapping
from pathlib import Path

import dask
from distributed import Client, LocalCluster, as_completed
from distributed.client import FutureCancelledError
from distributed.comm import connect
from distributed.scheduler import KilledWorker
from distributed.security import Security
from distributed.utils import get_mp_context

from harness.data.errors import UserError
from harness.runtime.cluster import ClusterOptions
from harness.runtime.progress import progress_bar

__all__ = ["DaskExecutor", "security_for", "probe_scheduler", "LOOPBACK"]

LOOPBACK = "127.0.0.1"


async def _identity(address: str, timeout: float, connection_args: dict):
    comm = await connect(address, timeout=timeout, **connection_args)
    try:
        await comm.write({"op": "identity", "reply": True})
        return await comm.read()
    finally:
        comm.abort()


def probe_scheduler(address: str, security: Security | None, timeout: float, source: str) -> None:
    """Ask ``address`` who it is, within ``timeout`` (+ up to 5) seconds in all (Dask's own connect waits for
    the handshake without a bound, so a port that accepts connections and never answers -- a silent listener,
    an HTTP server -- would hang the client forever).

    Raises:
        UserError: no answer in time, an answer that is not Dask's, or a Dask process that is no scheduler
            (naming ``source``, e.g. the ``--scheduler`` value).
        OSError, ValueError: nothing listens there, or the TLS handshake failed (as Dask's client raises them).
    """
    args = security.get_connection_args("client") if security is not None else {}
    bound = timeout + min(5.0, timeout)  # past Dask's own connect timeout, which says "cannot connect" itself
    try:
        reply = asyncio.run(asyncio.wait_for(_identity(address, timeout, args), bound))
    except TimeoutError:
        raise UserError(f"--scheduler {source}: no Dask answer within {bound:.0f} s (something accepts "
                        "connections there but does not speak Dask's protocol: is this the scheduler's port?)") \
            from None
    except (OSError, ValueError):  # refused, unreachable, TLS handshake: the caller says "cannot connect"
        raise
    except Exception as exc:  # e.g. msgpack's errors on a reply that is not Dask's framing
        raise UserError(f"--scheduler {source}: does not answer as a Dask scheduler ({type(exc).__name__})") \
            from None
    kind = reply.get("type") if isinstance(reply, dict) else None
    if kind != "Scheduler":
        raise UserError(f"--scheduler {source}: answers as {kind or 'something'}, not a Dask scheduler"
                        + (" (give the scheduler's address, not a worker's)" if kind == "Worker" else ""))


def security_for(options: ClusterOptions) -> Security | None:
    """Dask ``Security`` for the client from ``--tls-ca/--tls-cert/--tls-key`` (None without TLS)."""
    if not options.tls:
        return None
    return Security(tls_ca_file=str(options.tls_ca), tls_client_cert=str(options.tls_cert),
                    tls_client_key=str(options.tls_key), require_encryption=True)


def _quiet_forkserver() -> bool:
    """Have multiprocessing's fork server running, started with SIGINT ignored, so that every worker process
    forked from it -- at start-up and when a lost worker is restarted -- ignores Ctrl-C too; False where that
    cannot be done (not the main thread, no fork server on this platform).

    A terminal's Ctrl-C goes to every process of the foreground group: each LocalCluster worker printed its own
    ``KeyboardInterrupt`` traceback (dozens of lines, mid-import or mid-task) while this process was already
    stopping them.  The workers are stopped by this process (the nannies), never by the signal.  Python's fork
    server restores, in each child it forks, the SIGINT disposition it started with; SIGINT is ignored here only
    for the instant of ``ensure_running`` (which starts the server, or again if it died, and otherwise only
    checks it).  Like Python's resource tracker, the fork server lives as long as this process.
    """
    if threading.current_thread() is not threading.main_thread() or \
            "forkserver" not in multiprocessing.get_all_start_methods():
        return False
    with dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"}):
        get_mp_context()  # sets distributed's preload of the fork server
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        multiprocessing.forkserver.ensure_running()
    finally:
        signal.signal(signal.SIGINT, old)
    return True


@contextlib.contextmanager
def _ctrl_c_deferred() -> Iterator[None]:
    """Hold back Ctrl-C (in the main thread) until the block is done, then raise ``KeyboardInterrupt``: a
    ``LocalCluster`` interrupted half-built cannot be closed (its workers, mid-start, printed tracebacks and
    Dask's exit hook failed on it); complete, it is closed cleanly in a second or two."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    old = signal.signal(signal.SIGINT, lambda *_: caught.append(True))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
    if caught:
        raise KeyboardInterrupt


def _local_cluster(options: ClusterOptions) -> LocalCluster:
    """A ``LocalCluster`` on 127.0.0.1 whose worker processes never see Ctrl-C (:func:`_quiet_forkserver`)."""
    if _quiet_forkserver():
        dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"})  # restarts too: kept
    # dashboard off; the scheduler still serves HTTP (health, metrics): on a free loopback port, not Dask's default
    # 8787, which another cluster (a second tri360 job) may hold -- Dask would warn about it on stderr
    return LocalCluster(n_workers=options.workers, threads_per_worker=options.threads_per_worker,
                        processes=True, host=LOOPBACK, dashboard_address=None, silence_logs=logging.CRITICAL,
                        scheduler_kwargs={"dashboard_address": f"{LOOPBACK}:0"})


class DaskExecutor:
    """Runs tasks on Dask workers; see the module docstring.

    Attributes:
        client: the ``distributed.Client``.
        cluster: the ``LocalCluster`` started here, or None for an existing scheduler.
    """

    distributed = True

    def __init__(self, options: ClusterOptions):
        options.check()
        self.options = options
        self.cluster: LocalCluster | None = None
        try:
            if options.workers is not None:
                with _ctrl_c_deferred():
                    self.cluster = _local_cluster(options)
                    self.client = Client(self.cluster, timeout=options.connect_timeout_s)
            else:
                self.client = self._connect(options)
        except BaseException:
            self.close()
            raise

    @staticmethod
    def _connect(options: ClusterOptions) -> Client:
        security = security_for(options)
        target = options.scheduler
        try:
            if "://" not in target and Path(target).is_file():
                try:
                    address = json.loads(Path(target).read_text(encoding="utf-8"))["address"]
                except (OSError, ValueError, KeyError, TypeError) as exc:
                    raise UserError(f"{target}: not a Dask scheduler file ({exc})") from None
            else:
                address = target
            probe_scheduler(address, security, options.connect_timeout_s, target)
            return Client(address, security=security, timeout=options.connect_timeout_s)
        except UserError:
            raise
        except (OSError, TimeoutError, ValueError) as exc:
            why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise UserError(f"cannot connect to the Dask scheduler {target} ({why}); is it running, and "
                            f"{'are --tls-ca/--tls-cert/--tls-key right' if options.tls else 'does it need TLS'}?") \
                from None

    @property
    def workers(self) -> dict:
        """The scheduler's view of its workers: address -> info."""
        return self.client.scheduler_info(n_workers=-1)["workers"]

    def run(self, fn: Callable, tasks: Mapping[Hashable, tuple], desc: str = "task", unit: str = "task",
            progress: bool = True, names: Mapping[Hashable, str] | None = None) -> Iterator[tuple[Hashable, object]]:
        """Submit ``fn(*args)`` for every ``key: args`` and yield ``(key, result)`` as tasks complete.

        Each key is yielded exactly once.  A task's exception is raised here (the remaining tasks are
        cancelled); a task whose workers kept dying raises UserError.  ``names`` gives a task's name for the
        progress bar and error messages (e.g. ``classroom/vp000 fused``); the key is used otherwise.
        """
        names = names or {}
        token = uuid.uuid4().hex[:10]
        by_future_key: dict[str, Hashable] = {}
        futures = []
        for i, (key, args) in enumerate(tasks.items()):
            fut = self.client.submit(fn, *args, key=f"tri360_{desc}-{token}-{i}", pure=False)
            by_future_key[fut.key] = key
            futures.append(fut)
        done: set[Hashable] = set()
        bar = progress_bar(len(futures), desc=f"{desc} (dask)", unit=unit, enabled=progress)
        try:
            for fut in as_completed(futures):
                key = by_future_key[fut.key]
                name = names.get(key, str(key))
                try:
                    result = fut.result()
                except KilledWorker as exc:
                    raise UserError(f"{desc} task {name}: its Dask workers died repeatedly ({exc}"
                                    "; out of memory? see the worker logs); completed tasks are kept, "
                                    "rerun to resume") from None
                except FutureCancelledError:
                    raise UserError(f"{desc} task {name} was cancelled by the Dask scheduler; rerun to resume") \
                        from None
                fut.release()
                if key in done:  # as_completed yields each future once; kept as a guard
                    continue
                done.add(key)
                bar.set_postfix_str(name)
                bar.update(1)
                yield key, result
        finally:
            bar.close()
            pending = [f for f in futures if not f.done()]
            if pending:
                self.client.cancel(pending)

    def close(self) -> None:
        client, cluster = getattr(self, "client", None), self.cluster
        self.client, self.cluster = None, None
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()
