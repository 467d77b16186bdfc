# Two entry points, both self-contained on a fresh machine with Python 3.11:
#   make serve   -> creates .venv, installs dualpuma, starts the browser viewer
#   make test    -> creates .venv, installs dualpuma[test], runs the whole test suite
PYTHON ?= python3.11
VENV   ?= .venv
PY      = $(VENV)/bin/python
STAMP   = $(VENV)/.installed
RUN_STAMP = $(VENV)/.installed-run

.PHONY: serve test bench venv clean

$(PY):
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "need $(PYTHON) on PATH (or: make PYTHON=python3 ...)"; exit 1; }
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip

# the viewer needs dualpuma alone; the tests add their tools (pytest, playwright, hypothesis, dask)
$(RUN_STAMP): $(PY) pyproject.toml constraints.txt
	$(PY) -m pip install -q -c constraints.txt -e .
	@touch $(RUN_STAMP)

$(STAMP): $(PY) pyproject.toml constraints.txt
	$(PY) -m pip install -q -c constraints.txt -e '.[test]'
	@touch $(STAMP)

venv: $(STAMP)

serve: $(RUN_STAMP)
	$(VENV)/bin/dualpuma serve $(ARGS)

# The suite runs on every core (pytest-xdist), then the real-browser tests alone: headless Chromium
# renders WebGL on the CPU and its waits are sized for a machine it does not share with other tests.
# Each command selects its tests by the `browser` marker, so no test runs twice or is left out.
test: $(STAMP)
	$(PY) -m pytest -q tests -n auto --dist worksteal -m "not browser"
	$(PY) -m pytest -q tests -m browser

bench: $(STAMP)
	$(PY) -m pip install -q -c constraints.txt -e '.[test,bench]'
	$(PY) -m pytest -q benchmarks --benchmark-only --benchmark-columns=min,median,mean,ops,rounds

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .benchmarks
