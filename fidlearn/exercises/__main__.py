"""``python -m fidlearn.exercises grade NOTEBOOK... [--learner ID] [--csv FILE]``."""

from ._cli import _main

if __name__ == "__main__":
    raise SystemExit(_main())
