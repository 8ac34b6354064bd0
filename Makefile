# fidlearn: the two commands are `make lab` (open the course) and `make test` (lint and every test but
# the slow sweeps, which `make test-slow` runs).
# Both create a local virtual environment in .venv on first use and install everything into it.

PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.fidlearn-installed
FIRST_NOTEBOOK := $(firstword $(wildcard notebooks/00_*.ipynb))
# Extra JupyterLab options, e.g. make lab LAB_ARGS="--no-browser --port 8890"
LAB_ARGS ?=
NOTEBOOKS := $(sort $(wildcard notebooks/[0-9][0-9]_*.ipynb))
# pytest-xdist workers (make test TEST_JOBS=4 on a bigger machine). loadfile keeps each test file
# and each notebook on one worker: a notebook's cells share one kernel, a file's fixtures run once.
TEST_JOBS ?= 2
XDIST := -n $(TEST_JOBS) --dist loadfile

.PHONY: lab test test-slow bench test-browser test-cv4 test-floor data env clean

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 10), "fidlearn needs Python 3.10 or newer"'
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test]"
	@touch $(STAMP)

env: $(STAMP)

# JupyterLab serves the whole checkout (notebooks, exercises, data, docs) and opens the first
# notebook; the URL it prints opens it too. Jupyter refuses to run as root unless told: in a
# container or a cloud shell (root) the option is passed, and said.
lab: $(STAMP)
	@root=; if [ "$$(id -u)" = 0 ]; then root=--allow-root; \
		echo "make lab: running as root (a container?), so JupyterLab is started with --allow-root"; fi; \
	set -x; exec $(BIN)/jupyter lab $$root --ServerApp.root_dir="$(CURDIR)" \
		--LabApp.default_url=/lab/tree/$(FIRST_NOTEBOOK) $(LAB_ARGS)

# Lint (ruff: the rules in pyproject.toml), type-check (mypy: the modules in pyproject.toml), then every unit test, every docstring example in
# fidlearn and every numbered notebook (stored outputs compared exactly), on both cores; the tests
# marked slow (long sweeps, a class graded in the sandbox) are left to make test-slow.
# Debian's bubblewrap boxes each graded notebook (tests/test_grading_sandbox.py); installed as root when missing.
BWRAP ?= /usr/bin/bwrap
$(BWRAP):
	@if [ "$$(id -u)" = 0 ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq bubblewrap; fi

test: $(STAMP) $(BWRAP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/python -m mypy
	$(BIN)/python -m pytest -m "not slow" $(XDIST) tests fidlearn $(NOTEBOOKS) --doctest-modules --nbval --nbval-sanitize-with notebooks/sanitize.cfg

# The tests marked @pytest.mark.slow: 200-learner sweeps, false-alarm rates measured over many
# seeds, a class of cheating notebooks graded in the sandbox, the full data rebuild under audit.
test-slow: $(STAMP) $(BWRAP)
	$(BIN)/python -m pytest -m slow $(XDIST) tests

bench: $(STAMP)
	$(BIN)/python -m benchmarks

data: $(STAMP)
	$(BIN)/python tools/make_data.py

# The unit tests and the notebooks (nbval-lax: their own asserts, not the last printed digit)
# once more against the newest OpenCV 4.x (the slow sweeps run once, in make test-slow), in a venv of its own
# (.venv-cv4) so that the two OpenCV releases never meet: no shared pytest cache, hypothesis database or bytecode.
# pip does not compile the installed packages (half of its time): the tests compile what they import, into the venv.
# Checked once, by make test: the README's bare pytest commands collect as written (two whole collections, 36 s).
# They are commands for an existing environment such as .venv; the other environments only repeat it.
ONCE_ONLY := --deselect tests/test_packaging.py::test_the_readme_pytest_commands_collect_as_written
CV4_VENV  ?= .venv-cv4
CV4_STAMP := $(CV4_VENV)/.fidlearn-installed

$(CV4_STAMP): pyproject.toml
	@test -x $(CV4_VENV)/bin/python || $(PYTHON) -m venv $(CV4_VENV)
	$(CV4_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(CV4_VENV)/bin/python -m pip install --quiet --no-compile -e ".[test]" "opencv-contrib-python-headless<5"
	@touch $(CV4_STAMP)

test-cv4: $(CV4_STAMP)
	@$(CV4_VENV)/bin/python -c 'import cv2; assert cv2.__version__.startswith("4."), cv2.__version__; print("OpenCV", cv2.__version__)'
	HYPOTHESIS_STORAGE_DIRECTORY=$(CV4_VENV)/.hypothesis PYTHONPYCACHEPREFIX=$(CV4_VENV)/pycache \
		$(CV4_VENV)/bin/python -m pytest -m "not slow" $(XDIST) tests $(NOTEBOOKS) --nbval-lax --ignore=tests/browser -p no:cacheprovider $(ONCE_ONLY)

# The suite but its slow sweeps on the oldest versions pyproject.toml allows (every direct dependency pinned to
# its lower bound by tools/floor_constraints.py) and the oldest Python, in .venv-floor. The
# notebooks run there with nbval-lax: their own asserts must hold, while the stored outputs are
# compared digit for digit only on the reference OpenCV (make test).
FLOOR_VENV   ?= .venv-floor
# The oldest Python fidlearn supports (requires-python), found on PATH or in pyenv's versions.
FLOOR_PYTHON ?= $(shell for p in python3.10 $$(pyenv root 2>/dev/null)/versions/3.10*/bin/python3.10; do \
	"$$p" -c "import sys; assert sys.version_info[:2] == (3, 10)" 2>/dev/null && { echo "$$p"; break; }; done)
FLOOR_STAMP  := $(FLOOR_VENV)/.fidlearn-installed

$(FLOOR_STAMP): pyproject.toml tools/floor_constraints.py
	@test -n "$(FLOOR_PYTHON)" || { echo "make test-floor: Python 3.10, the oldest fidlearn supports, is not installed"; exit 2; }
	@test -x $(FLOOR_VENV)/bin/python || $(FLOOR_PYTHON) -m venv $(FLOOR_VENV)
	$(FLOOR_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(FLOOR_VENV)/bin/python tools/floor_constraints.py > $(FLOOR_VENV)/floors.txt
	$(FLOOR_VENV)/bin/python -m pip install --quiet --no-compile -c $(FLOOR_VENV)/floors.txt -e ".[test]"
	@touch $(FLOOR_STAMP)

test-floor: $(FLOOR_STAMP)
	@$(FLOOR_VENV)/bin/python -c 'import sys, cv2, numpy, matplotlib; print("floors: Python", sys.version.split()[0], "OpenCV", cv2.__version__, "numpy", numpy.__version__, "matplotlib", matplotlib.__version__)'
	HYPOTHESIS_STORAGE_DIRECTORY=$(FLOOR_VENV)/.hypothesis PYTHONPYCACHEPREFIX=$(FLOOR_VENV)/pycache \
		$(FLOOR_VENV)/bin/python -m pytest -m "not slow" $(XDIST) tests $(NOTEBOOKS) --nbval-lax --ignore=tests/browser -p no:cacheprovider $(ONCE_ONLY)

# JupyterLab in a real (headless) browser: runs the intrinsics notebook and moves its slider, and
# notebook 12 with Chromium's fake camera playing a rendered drive (the webcam widget end to end).
# Needs Debian's chromium (/usr/bin/chromium); installed with apt-get when missing.
BROWSER_STAMP := $(VENV)/.fidlearn-browser-installed
CHROMIUM ?= /usr/bin/chromium

$(BROWSER_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e ".[test,browser]"
	@touch $(BROWSER_STAMP)

$(CHROMIUM):
	@if [ "$$(id -u)" = 0 ]; then SUDO=; else SUDO=sudo; fi; \
	$$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq chromium

test-browser: $(BROWSER_STAMP) $(CHROMIUM)
	FIDLEARN_CHROMIUM=$(CHROMIUM) $(BIN)/python -m pytest tests/browser -p no:cacheprovider

clean:
	rm -rf $(VENV) $(CV4_VENV) $(FLOOR_VENV) .pytest_cache .hypothesis build *.egg-info
