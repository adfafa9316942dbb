"""What each ``tri360`` command does, one module per command of :data:`harness.cli.COMMANDS`, named after it
(``import`` is ``import_``): ``render``, ``scenes``, ``methods``, ``reconstruct``, ``evaluate``, ``score``,
``report``, ``study``, ``perturb``, ``import_``, ``export``.  ``harness.cli`` parses the arguments and calls them;
they run on :mod:`harness.runtime` (where tasks run, progress, start-up, option values) and never import the CLI.

What a command is built from but is no command itself is in :mod:`harness.commands.parts`: the ``--suite`` mode of
render, evaluate and score, the robustness kind of study, the perturbations of ``perturb``, the ``captured``
condition of a suite and what the listing commands say about plugins.  ``tests/test_architecture.py`` checks that
the modules here and the CLI's commands match.
"""
