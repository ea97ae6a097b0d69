"""``python -m pneunet_env.cli``: the same as ``pneunet-grasp``."""

import sys

from pneunet_env.cli import main

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
