"""``python -m agents.design``."""

import sys

from agents.design.cli import main

sys.exit(main())
