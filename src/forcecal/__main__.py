"""``python -m forcecal``: the command-line interface of :mod:`forcecal.cli`."""

import sys

from .cli.main import main

sys.exit(main())
