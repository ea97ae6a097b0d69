"""``python -m agents.search``: the same as ``pneunet-grasp search``."""

import sys

from agents.search.cli import main

sys.exit(main())
