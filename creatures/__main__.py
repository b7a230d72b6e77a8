"""``python -m creatures``: the ``creatures`` command where its script is not on PATH (a venv
not activated, a checkout not installed)."""

import sys

from creatures.cli import main

sys.exit(main())
