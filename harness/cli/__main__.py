"""``python -m harness.cli``: the same as the ``tri360`` command."""

import sys

from harness.cli import main

sys.exit(main())
