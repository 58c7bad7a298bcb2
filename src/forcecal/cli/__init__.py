"""The ``forcecal`` command line (INTERFACES.md section 5): the parser, the commands and the
demo. Only this package prints to the console and turns a :class:`~forcecal.ForcecalError`
into one line on stderr and exit status 2."""

from .main import main

__all__ = ["main"]
