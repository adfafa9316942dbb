"""What commands are built from but is no command of its own: ``suite`` (the ``--suite`` mode of ``render``,
``evaluate`` and ``score``), ``robustness`` (``tri360 study`` of a file with ``kind = "robustness"``),
``perturbations`` (the kinds and levels ``tri360 perturb --apply`` applies), ``captured`` (a suite's
``captured`` condition: a rendered frame as real cameras would have recorded it) and ``plugins`` (what ``methods``
and ``scenes`` say about plugins that failed to load or were refused).  They may import the command
modules (``suite`` runs ``evaluate`` and ``score``), as the command modules import them."""
