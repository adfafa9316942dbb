"""The options that choose where a command's tasks run, shared by ``render``, ``evaluate``, ``score`` and ``study``,
and the one place the command line builds a command's :class:`~harness.runtime.context.RunContext`.

Without ``--scheduler`` or ``--workers`` everything runs in this process (no cluster needed).  See
``docs/scale-out.md`` for clusters, TLS and SLURM.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.runtime.cluster import ClusterOptions
from harness.runtime.context import RunContext

__all__ = ["add_cluster_arguments", "cluster_options", "run_context"]


def add_cluster_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("where to run (default: in this process; see docs/scale-out.md)")
    where = g.add_mutually_exclusive_group()
    where.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run the tasks on an existing Dask cluster: tcp://HOST:PORT, tls://HOST:PORT (with "
                            "--tls-*) or a scheduler file; the data root must be on a file system every worker sees")
    where.add_argument("--workers", type=int, default=None, metavar="N",
                       help="start a Dask LocalCluster of N worker processes on 127.0.0.1 only, stopped at the end")
    g.add_argument("--threads-per-worker", type=int, default=1, metavar="T",
                   help="threads (tasks at once) per --workers worker")
    g.add_argument("--tls-ca", type=Path, default=None, metavar="PEM", help="CA certificate of a tls:// scheduler")
    g.add_argument("--tls-cert", type=Path, default=None, metavar="PEM", help="this client's TLS certificate")
    g.add_argument("--tls-key", type=Path, default=None, metavar="PEM", help="this client's TLS private key")


def cluster_options(args) -> ClusterOptions | None:
    """The parsed options -> :class:`ClusterOptions`, or None to run in this process."""
    opts = ClusterOptions(scheduler=args.scheduler, workers=args.workers, threads_per_worker=args.threads_per_worker,
                          tls_ca=args.tls_ca, tls_cert=args.tls_cert, tls_key=args.tls_key)
    if not opts.distributed and not opts.tls:
        if opts.threads_per_worker < 1:
            opts.check()
        return None
    opts.check()
    return opts


def run_context(args) -> RunContext:
    """The parsed options -> the command's :class:`RunContext`: where its tasks run (:func:`cluster_options`, for a
    command with :func:`add_cluster_arguments`; else in this process), ``--quiet`` and ``--verbose``."""
    where = cluster_options(args) if hasattr(args, "scheduler") else None
    return RunContext(where, progress=not getattr(args, "quiet", False), verbose=getattr(args, "verbose", False))
