"""What the commands share to run, and nothing about any one command: ``startup`` (Ctrl-C and SIGTERM from the
first import to the exit), ``progress`` (a bar on a terminal, one line per item elsewhere), ``cluster`` (where
tasks run: in this process, or on Dask through ``executor``, loaded only then), ``options`` (typed option values
and the method selection, shared by the command line and study files).

Importing this package does nothing (``startup`` is the first module a command loads, before its heavy imports).
The runtime never imports :mod:`harness.commands` or :mod:`harness.cli` (``tests/test_architecture.py``).
"""
