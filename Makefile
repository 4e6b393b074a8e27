# Every target installs what it needs into .venv first, so a fresh clone needs only `make demo` or `make test`.
PYTHON ?= python3
VENV ?= .venv
BIN = $(VENV)/bin

.PHONY: demo test benchmark samples golden mutants clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

demo: $(VENV)/.installed
	$(BIN)/voxrender demo -o demo.png

test: $(VENV)/.installed
	$(BIN)/python -m pytest

benchmark: $(VENV)/.installed
	$(BIN)/python -m benchmarks.bench

samples: $(VENV)/.installed
	$(BIN)/voxrender samples samples

# Rewrite the golden images after an intended change of the pictures (review them before committing).
golden: $(VENV)/.installed
	$(BIN)/python -m tests.golden

# The mutation gate: hand-written bugs, one at a time; fails if the suite misses one (a few minutes).
mutants: $(VENV)/.installed
	$(BIN)/python tests/mutants.py

clean:
	rm -rf $(VENV) samples demo.png .pytest_cache
