# Two entry points for a fresh machine with only python3 and pip:
#   make demo   -- create .venv, install hcmt with the extras the demo uses, run the quickstart
#   make test   -- create .venv, install hcmt with the test extras, run the whole suite
#   make quick  -- the quick loop: every test not marked slow (no training, no subprocess)
#   make lint   -- ruff's linter and formatter check over src, tests, benchmarks and scripts (pyproject's [tool.ruff]), then mypy over the public API
#                  modules (pyproject's [tool.mypy] files)
PYTHON ?= python3
VENV   ?= .venv
BIN     = $(VENV)/bin
# The exact torch: this machine's local CPU wheel, installed first (pyproject only asks for a range; a range left to
# pip pulls the CUDA build and GBs of CUDA packages).
TORCH  ?= torch==2.13.0
# all: matplotlib + meshio (pictures, export), tensorboard (training scalars), tfrecord + crc32c (TFRecord datasets)
# test: what the suite needs (every extra), ruff and mypy
EXTRAS ?= all,test

.PHONY: setup demo test quick lint clean

$(BIN)/hcmt: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q '$(TORCH)'
	$(BIN)/python -m pip install -q -e '.[$(EXTRAS)]'
	touch $(BIN)/hcmt

setup: $(BIN)/hcmt

demo: setup
	$(BIN)/hcmt demo

test: setup
	$(BIN)/python -m pytest -q tests

quick: setup
	$(BIN)/python -m pytest -q -m "not slow" tests

lint: setup
	$(BIN)/ruff check src tests benchmarks scripts
	$(BIN)/ruff format --check src tests benchmarks scripts
	$(BIN)/mypy

clean:
	rm -rf $(VENV) build src/*.egg-info
