"""How a command runs: where its tasks run and what it prints, one frozen value (:class:`RunContext`).

The command line builds one from its arguments (``--scheduler``/``--workers``, ``--quiet``, ``--verbose``) and
hands it to the command, which hands it on to every part it calls::

    ctx = RunContext(ClusterOptions(workers=2), progress=False)
    with ctx.executor() as ex:                 # starts the cluster here; stopped at the end of the block
        inner = ctx.on(ex)                     # the parts it calls use this open executor and leave it open
        render_frames(settings, "classroom", out_root="data", ctx=inner)
        evaluate(Path("data"), Path("results"), methods, ctx=inner)

A command given a context whose tasks run on :class:`~harness.runtime.cluster.ClusterOptions` opens its own
executor and closes it; given one holding an open :class:`~harness.runtime.cluster.Executor` (a study's, which
serves all its renders and evaluations), it uses that executor and leaves it open.
"""

from __future__ import annotations

import contextlib
import dataclasses
from dataclasses import dataclass

from harness.runtime.cluster import ClusterOptions, Executor, open_executor

__all__ = ["RunContext", "IN_PROCESS", "QUIET"]


@dataclass(frozen=True)
class RunContext:
    """Where a command's tasks run and what it prints.

    Attributes:
        where: where the tasks run: None (in this process), :class:`ClusterOptions` (a Dask cluster that each
            :meth:`executor` block opens and closes) or an open :class:`Executor` (used, and left open).
        progress: progress bars (or lines, off a terminal) on stderr and the commands' progress messages;
            False = ``--quiet``.
        verbose: let the renderer print its own log lines (Blender's, on stderr): ``--verbose``.
    """

    where: ClusterOptions | Executor | None = None
    progress: bool = True
    verbose: bool = False

    @property
    def distributed(self) -> bool:
        """Whether the tasks run on Dask workers."""
        if isinstance(self.where, ClusterOptions):
            return self.where.distributed
        return self.where is not None and self.where.distributed

    def check(self) -> None:
        """Raise UserError naming the first cluster option that cannot work (:meth:`ClusterOptions.check`),
        before any cluster starts; nothing to check for an open executor or this process."""
        if isinstance(self.where, ClusterOptions):
            self.where.check()

    def executor(self) -> contextlib.AbstractContextManager[Executor]:
        """The executor the tasks run on: the open one (left open at the end of the block), or a new one from the
        cluster options or for this process (:func:`~harness.runtime.cluster.open_executor`: closed at the end)."""
        if self.where is None or isinstance(self.where, ClusterOptions):
            return open_executor(self.where)
        return contextlib.nullcontext(self.where)

    def on(self, executor: Executor) -> RunContext:
        """This context with its tasks on ``executor`` (open already)."""
        return dataclasses.replace(self, where=executor)

    def quiet(self) -> RunContext:
        """This context without progress output."""
        return dataclasses.replace(self, progress=False)


IN_PROCESS = RunContext()
"""In this process, showing progress: every command's default."""
QUIET = RunContext(progress=False)
"""In this process, printing no progress (tests, tools)."""
