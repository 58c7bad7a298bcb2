"""``python -m forcecal``: the command-line interface of :mod:`forcecal.cli`."""

import sys

from .cli import main

sys.exit(main())
