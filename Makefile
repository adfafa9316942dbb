# tri360 — every target sets up .venv by itself, so each works on a fresh machine with Python 3.11.
# The tools (bench, regress-update) run as `python -m tools.…` from this directory (on sys.path with -m), as in README.md.
PYTHON ?= python3.11
VENV   := .venv
PY     := $(VENV)/bin/python
TRI    := $(VENV)/bin/tri360
STAMP  := $(VENV)/.installed
DATA   ?= data
RESULTS ?= results

.PHONY: setup browser render evaluate report test test-fast bench regress-update fingerprints-update presets-update clean

$(STAMP): pyproject.toml
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "error: $(PYTHON) not found (tri360 needs Python 3.11; set PYTHON=...)" >&2; exit 1; }
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	@touch $(STAMP)

setup: $(STAMP) ## create .venv and install tri360 with its pinned dependencies

render: $(STAMP) ## render the default scene set (classroom, 3 viewpoints, 1000x500) into $(DATA)/
	$(TRI) render --scene classroom --viewpoints 3 --out $(DATA)

evaluate: $(STAMP) ## render the default scene if missing, evaluate the default methods (fused-mirror, sweep, dis-rect:*, deepflow-rect:*; tri360 methods lists them), write $(RESULTS)/ and print one row per method (MAE, median, delta<1.10, seconds; best first)
	$(TRI) render --scene classroom --viewpoints 1 --out $(DATA)
	$(TRI) evaluate $(DATA) --out $(RESULTS)

report: $(STAMP) ## rebuild the report (tables, plots, point clouds, report.html) from $(RESULTS)/
	$(TRI) report $(RESULTS)

browser: ## install Chromium for the browser test of report.html (Debian package; needs root), if missing
	@test -x /usr/bin/chromium || { \
	  if [ "$$(id -u)" = 0 ]; then \
	    DEBIAN_FRONTEND=noninteractive apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; \
	  else echo "error: /usr/bin/chromium is missing; install it: sudo apt-get install -y chromium" >&2; exit 1; fi; }

test: $(STAMP) browser ## run the whole test suite (fast and slow tests, Blender renders, the browser check, Dask clusters)
	$(PY) -m pytest -q

test-fast: $(STAMP) ## the tests that need no Blender render, browser or Dask cluster and are not marked slow (under 2 minutes on an idle 2-core machine)
	$(PY) -m pytest -q -m "not blender and not browser and not cluster and not slow"

bench: $(STAMP) ## timings and peak memory: flow pipeline stages (+ LM vs scipy), the default method (fused-mirror) at 1000x500 and 4000x2000 beside fused-mirror-raw, the default classroom render (3 times, against a reference render), Dask render speed-up, suite frame render time vs the default frame, DeepMatching/DeepFlow; every benchmark runs whatever the others' outcome, then one table lists every goal with its figure and PASS/FAIL, and the status is non-zero if any failed (python -m tools.bench)
	$(PY) -m tools.bench

regress-update: $(STAMP) ## rewrite the CI regression bounds (tests/regression_bounds.json) from a fresh run
	$(PY) -m tools.regression --bounds tests/regression_bounds.json --update

fingerprints-update: $(STAMP) ## rewrite the scene fingerprints (tests/scenes/scene_fingerprints.json) after changing a family's version (scenes/README.md)
	$(PY) -m tools.scene_fingerprints --update

presets-update: $(STAMP) ## rewrite the reviewed snapshot of every built-in method's configuration (tests/reconstruction/methods/presets_snapshot.json) after a deliberate change of a method's parameters; review its diff
	$(PY) -m tools.presets_snapshot --update

clean: ## remove the venv, caches, rendered data and results
	rm -rf $(VENV) .pytest_cache .ruff_cache $(RESULTS) build *.egg-info
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
