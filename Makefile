# cooprint — two commands set everything up on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test bench fuzz clean viewer browser

# The viewer's JavaScript (viewer/src, three.js from npm) bundled into one file that `cooprint view`
# inlines into sim/viewer.html; needs Node.js and npm (the npm registry), nothing else.
VIEWER_JS := src/cooprint/render/viewer/assets/viewer.js
VIEWER_SRC := $(wildcard viewer/src/*.js)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	# an editable install writes no bytecode, and PYTHONDONTWRITEBYTECODE=1 (set on some machines)
	# means none is ever cached: every command would compile cooprint's source again (~0.1 s)
	$(PY) -m compileall -q src
	touch $(STAMP)

$(VIEWER_JS): viewer/package.json viewer/package-lock.json $(VIEWER_SRC)
	cd viewer && npm ci --no-audit --no-fund --loglevel=error
	cd viewer && npm run --silent build

viewer: $(VIEWER_JS)

# Debian's chromium for the viewer's browser tests (tests/test_viewer_browser.py); when it cannot be
# installed (not root, no sudo, no network) those tests are skipped and say why.
browser:
	@command -v chromium >/dev/null 2>&1 || { \
	  if [ "$$(id -u)" = 0 ]; then SUDO=; elif command -v sudo >/dev/null 2>&1; then SUDO="sudo -n"; else SUDO=false; fi; \
	  { $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq chromium >/dev/null; } \
	  || echo "make: chromium could not be installed; the browser tests will be skipped"; }

demo: $(STAMP) $(VIEWER_JS)
	$(PY) -m cooprint.demo out/demo

test: $(STAMP) $(VIEWER_JS) browser
	$(PY) -m pytest -q -n 2 tests

bench: $(STAMP) $(VIEWER_JS) browser
	$(PY) benchmarks/run.py

# Not part of `make test`: 100,000 hostile inputs through every reader (mesh files, .coop,
# G-code, manifests); each must be read or refused with one line. About 5-10 min on 2 cores.
FUZZ_INPUTS ?= 100000
fuzz: $(STAMP)
	$(PY) benchmarks/fuzz.py --inputs $(FUZZ_INPUTS) --jobs 2 --failures out/fuzz

clean:
	rm -rf $(VENV) out build src/*.egg-info viewer/node_modules $(VIEWER_JS)
