# navzoo: the two README commands, plus helpers. PYTHON may point at any Python >= 3.11.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: demo test install install-test lint speed clean

$(VENV)/bin/activate:
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --upgrade pip

# CPU torch first (the wheel that is pinned for this project); an unpinned torch would pull CUDA.
# constraints.txt: the package versions the recorded figures ran with (a new installation repeats them trip for trip).
install: $(VENV)/bin/activate
	$(PY) -m pip install -c constraints.txt torch==2.13.0
	$(PY) -m pip install -c constraints.txt -e .

install-test: install
	$(PY) -m pip install -c constraints.txt -e ".[test,ray]"

demo: install
	$(VENV)/bin/navzoo demo --out runs/demo

test: install-test
	$(VENV)/bin/ruff check navzoo tests policies
	$(PY) -m pytest -n 2 --durations=15 -q

lint:
	$(VENV)/bin/ruff check navzoo tests

speed: install
	$(VENV)/bin/navzoo speed --humans 5,20,64

clean:
	rm -rf runs .pytest_cache .ruff_cache
