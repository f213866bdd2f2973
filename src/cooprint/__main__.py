"""``python -m cooprint`` = the ``cooprint`` command."""

from cooprint.cli import entry

entry()
