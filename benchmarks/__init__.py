"""fidlearn's benchmarks: accuracy, speed and the course's run time, measured against plain OpenCV.

Not part of the test suite. Run them all with ``make bench`` (``python -m benchmarks``) or some
by name (``python -m benchmarks speed pose``); the results go to ``docs/benchmarks.md``. Each
``bench_NAME.py`` also runs on its own (``python benchmarks/bench_NAME.py``) and prints its
tables; a line ``<!-- target: what | measured | yes/no -->`` in its output feeds the summary.
"""
