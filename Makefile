# Two entry points for a fresh machine with only python3 and pip:
#   make demo   -- create .venv, install hcmt, run the quickstart
#   make test   -- create .venv, install hcmt with test extras, run the whole suite
#   make quick  -- the quick loop: every test not marked slow (no training, no subprocess)
PYTHON ?= python3
VENV   ?= .venv
BIN     = $(VENV)/bin

.PHONY: setup demo test quick clean

$(BIN)/hcmt: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	# torch first, pinned: the local CPU wheel; otherwise pip pulls the CUDA build.
	$(BIN)/python -m pip install -q torch==2.13.0
	$(BIN)/python -m pip install -q -e '.[test]'
	touch $(BIN)/hcmt

setup: $(BIN)/hcmt

demo: setup
	$(BIN)/hcmt demo

test: setup
	$(BIN)/python -m pytest -q tests

quick: setup
	$(BIN)/python -m pytest -q -m "not slow" tests

clean:
	rm -rf $(VENV) build src/*.egg-info
