# Every target installs what it needs into .venv first, so a fresh clone needs only `make demo` or `make test`.
# The versions installed are those of constraints.txt, the ones CI last passed with (`make constraints` renews them).
PYTHON ?= python3
VENV ?= .venv
BIN = $(VENV)/bin

.PHONY: demo test lint docs wheel-check constraints benchmark bench-compare samples golden mutants fuzz clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(VENV)/.installed: pyproject.toml constraints.txt | $(BIN)/python
	$(BIN)/python -m pip install --quiet --upgrade pip -c constraints.txt
	$(BIN)/python -m pip install --quiet -e '.[test,lint,docs]' -c constraints.txt
	touch $@

demo: $(VENV)/.installed
	$(BIN)/voxrender demo -o demo.png

test: $(VENV)/.installed
	$(BIN)/python -m pytest

# ruff, configured in pyproject.toml
lint: $(VENV)/.installed
	$(BIN)/ruff check .

# The manual into site/; a warning fails the build.
docs: $(VENV)/.installed
	$(BIN)/mkdocs build --strict

# The wheel, installed into a fresh venv outside the checkout, renders the demo in an empty folder (a minute or two).
wheel-check: $(VENV)/.installed
	$(BIN)/python tests/fresh_install.py

# Renew constraints.txt: the newest versions of everything `.[test,lint,docs]` needs, as a fresh venv installs them
# today. Run `make test` (or CI) on them before committing the new file.
constraints: | $(BIN)/python
	$(BIN)/python tests/fresh_install.py --constraints

benchmark: $(VENV)/.installed
	$(BIN)/python -m benchmarks.bench

# The key figures (whole command and its stages, ftb, raycast, encode, encode --octree, a batch of studies) of the
# working tree beside those of REF, interleaved in one run, with their ratios: make bench-compare REF=HEAD~5
REF ?= HEAD
REPEAT ?= 3
bench-compare: $(VENV)/.installed
	$(BIN)/python -m benchmarks.compare $(REF) --repeat $(REPEAT)

samples: $(VENV)/.installed
	$(BIN)/voxrender samples samples

# Rewrite the golden images after an intended change of the pictures (review them before committing).
golden: $(VENV)/.installed
	$(BIN)/python -m tests.golden

# The mutation gate: hand-written bugs, one at a time; fails if the suite misses one (the suite once, then each
# mutant until its first failing test: about 10 minutes on two cores).
mutants: $(VENV)/.installed
	$(BIN)/python tests/mutants.py

# The fuzzing gate: 84 damaged files of each format read, each rendered in a subprocess with a memory and a time limit;
# fails if any ends otherwise than in a picture or one error line, and keeps those cases under tests/fuzz_cases.
fuzz: $(VENV)/.installed
	$(BIN)/python -m tests.fuzz

clean:
	rm -rf $(VENV) samples demo.png .pytest_cache site dist build
