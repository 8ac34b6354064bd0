"""What every test process needs before the first test runs."""

import signal

# A test run started in the background by a non-interactive shell (CI, `make test &`) inherits
# SIGINT ignored, and so would every command the tests start. The tests of Ctrl-C need it as a
# terminal gives it: Python's KeyboardInterrupt here, the default disposition in the children.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
