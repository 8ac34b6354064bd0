"""``python -m fidlearn.exercises grade NOTEBOOK... [--learner ID] [--csv FILE]``.

The command lives in :mod:`fidlearn.grading` (which builds on this package); this entry point
only starts it and is never imported by the package itself.
"""

from ..grading._selfstudy_cli import _main

if __name__ == "__main__":
    raise SystemExit(_main())
