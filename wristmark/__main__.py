"""``python -m wristmark`` is the ``wristmark`` command."""

import sys

from wristmark.cli.main import main

if __name__ == "__main__":
    sys.exit(main())
