# fidlearn: the two commands are `make lab` (open the course) and `make test` (run every test).
# Both create a local virtual environment in .venv on first use and install everything into it.

PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.fidlearn-installed
FIRST_NOTEBOOK := $(firstword $(wildcard notebooks/00_*.ipynb) notebooks)
NOTEBOOKS := $(sort $(wildcard notebooks/[0-9][0-9]_*.ipynb))

.PHONY: lab test bench test-browser test-cv4 data env clean

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 10), "fidlearn needs Python 3.10 or newer"'
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test]"
	@touch $(STAMP)

env: $(STAMP)

lab: $(STAMP)
	$(BIN)/jupyter lab $(FIRST_NOTEBOOK)

test: $(STAMP)
	$(BIN)/python -m pytest tests $(NOTEBOOKS) --nbval --nbval-sanitize-with notebooks/sanitize.cfg

bench: $(STAMP)
	$(BIN)/python -m benchmarks

data: $(STAMP)
	$(BIN)/python tools/make_data.py

# The unit tests (not the notebooks) once more against the newest OpenCV 4.x, in a venv of its own
# (.venv-cv4) so that the two OpenCV releases never meet: no shared pytest cache, hypothesis database or bytecode.
CV4_VENV  ?= .venv-cv4
CV4_STAMP := $(CV4_VENV)/.fidlearn-installed

$(CV4_STAMP): pyproject.toml
	@test -x $(CV4_VENV)/bin/python || $(PYTHON) -m venv $(CV4_VENV)
	$(CV4_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(CV4_VENV)/bin/python -m pip install --quiet -e ".[test]" "opencv-contrib-python-headless>=4.8,<5"
	@touch $(CV4_STAMP)

test-cv4: $(CV4_STAMP)
	@$(CV4_VENV)/bin/python -c 'import cv2; assert cv2.__version__.startswith("4."), cv2.__version__; print("OpenCV", cv2.__version__)'
	HYPOTHESIS_STORAGE_DIRECTORY=$(CV4_VENV)/.hypothesis PYTHONPYCACHEPREFIX=$(CV4_VENV)/pycache \
		$(CV4_VENV)/bin/python -m pytest tests --ignore=tests/browser -p no:cacheprovider

# JupyterLab in a real (headless) browser: runs the intrinsics notebook and moves its slider.
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
	rm -rf $(VENV) $(CV4_VENV) .pytest_cache .hypothesis build *.egg-info
