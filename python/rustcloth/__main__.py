"""``python -m rustcloth COMMAND``: the command line (:mod:`rustcloth.cli`)."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
