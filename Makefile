# calibc developer tasks. Everything runs in a local virtual environment (.venv).
PY ?= python3
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: install test test-fast test-slow test-all test-random bench-checks lint bench clean fetch-ur10 report-screenshot

install: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e ".[dev]"
	touch $@

# test: every test in tests/ on every core (pytest-xdist, `-n auto` in pyproject.toml), the
# same pseudo-random property cases on every run (reproducible, as CI runs it), within four
# minutes on two cores; test-fast: those not marked slow (the slow marker: a whole-CLI run,
# a shipped robot solved whole, real data or a browser), the loop to run while editing,
# within a minute; test-slow: only the slow ones; test-all: another name for test;
# test-random: fresh cases each run, to look for failures the fixed ones miss. bench-checks: the checks too heavy for the suite (the
# public UR10 file at scale, campaigns of thousands of rows, whole solves of Test A and B,
# the suite's soundness properties at their full example counts), which assert and fail
# loudly.
# test-fast runs each hypothesis property on a quarter of its examples, at least one
# (--examples-share, tests/conftest.py); test runs every example. The test targets keep
# Python's bytecode caches where the environment turns them off: else each run's workers
# and `calibc` subprocesses compile calib_dsl and rewrite every test module's asserts anew
# (3.4 CPU-s of a worker's 6 s collection).
FAST_SHARE ?= 0.25
test test-fast test-slow test-random: export PYTHONDONTWRITEBYTECODE =

test: install
	$(BIN)/pytest

test-fast: install
	$(BIN)/pytest -m "not slow" --examples-share $(FAST_SHARE)

test-slow: install
	$(BIN)/pytest -m slow

test-all: test

test-random: install
	HYPOTHESIS_PROFILE=random $(BIN)/pytest

bench-checks: install
	$(BIN)/pytest bench/checks

# report-screenshot: docs/figures/report.png, the handover report of the shipped UR10 model
# as chromium shows it (the browser test keeps its screenshot in build/artefacts/)
report-screenshot: install
	$(BIN)/pytest -m slow -n 0 tests/handover/test_browser.py -k ur10
	cp build/artefacts/report-ur10.png docs/figures/report.png

lint: install
	$(BIN)/ruff check calib_dsl tests bench scripts
	$(BIN)/mypy calib_dsl

# bench: the checks too heavy for the suite (bench/checks/, as `make bench-checks`), then the
# RX90 benchmarks, then the real UR10 data against its yardstick (skipped with a
# note where the data set is absent), then the certified inner bounds, then thousands of
# configurations (RX90 and a Series-A-sized UR10 table) beside calibc as of $(BASELINE), the
# last commit before rows were compiled once; then simulated UR10 campaigns of 500-12,000 rows
# (random, grid and repeated poses) and Series B, against the yardstick and their own
# certified outer/inner; then planned campaigns against random ones (bench/plan.py).
BASELINE ?= 404e2ec
# The venv's python once `make install` made it; else $(PY) when calibc already runs there
# (no install needed); else install first.
ifneq ($(filter bench,$(MAKECMDGOALS)),)
BENCH_PY := $(shell if [ -x $(BIN)/python ]; then echo $(BIN)/python; \
	elif $(PY) -c "import calib_dsl, lark, numpy, click, scipy, highspy, pytest, hypothesis" 2>/dev/null; \
	then echo $(PY); fi)
endif

bench: $(if $(BENCH_PY),,install)
	$(or $(BENCH_PY),$(BIN)/python) -m pytest bench/checks
	$(or $(BENCH_PY),$(BIN)/python) bench/run.py
	$(or $(BENCH_PY),$(BIN)/python) bench/ur10.py
	$(or $(BENCH_PY),$(BIN)/python) bench/inner.py
	$(or $(BENCH_PY),$(BIN)/python) bench/scale.py --baseline $(BASELINE)
	$(or $(BENCH_PY),$(BIN)/python) bench/campaigns.py
	$(or $(BENCH_PY),$(BIN)/python) bench/plan.py
	$(or $(BENCH_PY),$(BIN)/python) bench/predict.py

# fetch-ur10: the public UR10 laser-tracker data set (Series B, MIT licence, Landgraf et al.,
# CASE 2021) into data/ur10/ (git ignores it: never commit it). Needs internet.
UR10_REPO ?= https://raw.githubusercontent.com/christianlandgraf/ipa-robot-accuracy/HEAD
fetch-ur10:
	mkdir -p data/ur10
	for f in measurements_joint_configurations.csv calibration_handeye.csv; do \
		curl -fsSL -o data/ur10/$$f $(UR10_REPO)/Series_B/$$f || exit 1; done
	curl -fsSL -o data/ur10/LICENSE.md $(UR10_REPO)/LICENSE.md
	@echo "data/ur10/: calibc solve models/ur10_tracker.cal --data m=data/ur10/measurements_joint_configurations.csv"

clean:
	rm -rf $(VENV) build dist *.egg-info .pytest_cache .mypy_cache .ruff_cache
