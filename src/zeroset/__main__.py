"""``python -m zeroset``: the same command line as the ``zeroset`` script."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
