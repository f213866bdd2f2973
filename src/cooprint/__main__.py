"""``python -m cooprint`` = the ``cooprint`` command."""

import sys

from cooprint.cli import main

sys.exit(main())
