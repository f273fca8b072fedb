"""``python -m wristmark`` is the ``wristmark`` command."""

import sys

from wristmark.rig.cli import main

if __name__ == "__main__":
    sys.exit(main())
