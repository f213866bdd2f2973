# cooprint — two commands set everything up on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test bench fuzz clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(PY) -m cooprint.demo out/demo

test: $(STAMP)
	$(PY) -m pytest -q -n 2 tests

bench: $(STAMP)
	$(PY) benchmarks/run.py

# Not part of `make test`: 100,000 hostile inputs through every reader (mesh files, .coop,
# G-code, manifests); each must be read or refused with one line. About 5-10 min on 2 cores.
FUZZ_INPUTS ?= 100000
fuzz: $(STAMP)
	$(PY) benchmarks/fuzz.py --inputs $(FUZZ_INPUTS) --jobs 2 --failures out/fuzz

clean:
	rm -rf $(VENV) out build src/*.egg-info
