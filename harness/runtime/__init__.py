"""What the commands share to run, and nothing about any one command: ``startup`` (Ctrl-C and SIGTERM from the
first import to the exit), ``progress`` (a bar on a terminal, one line per item elsewhere), ``cluster`` (where
tasks run: in this process, or on Dask through ``executor``, loaded only then), ``context`` (``RunContext``: where a
command's tasks run and what it prints), ``options`` (typed option values and the method selection, shared by the
command line and study files), ``arguments`` (the argument parser of every command and tool: an argument error is
one line and status 2), ``blind`` (methods are handed their input, never the frame) and ``isolation`` (a process of
its own for an outside method).

Importing this package does nothing (``startup`` is the first module a command loads, before its heavy imports).
The runtime never imports :mod:`harness.commands` or :mod:`harness.cli` (``tests/test_architecture.py``).
"""
