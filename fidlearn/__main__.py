"""``python -m fidlearn``: the same as the ``fidlearn`` command."""

import sys

from ._entry import main

if __name__ == "__main__":
    sys.exit(main())
