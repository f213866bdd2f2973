"""``python -m cooprint`` = the ``cooprint`` command."""

import os
import sys

try:
    from cooprint.cli import entry
except KeyboardInterrupt:  # Ctrl-C while Python loads cooprint: the same exit as later on
    sys.stderr.write("cooprint: interrupted\n")
    os._exit(130)

entry()
