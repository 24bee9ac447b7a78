# calibc developer tasks. Everything runs in a local virtual environment (.venv).
PY ?= python3
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: install test test-random lint bench clean

install: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e ".[dev]"
	touch $@

# test: the same pseudo-random property cases on every run (reproducible, as CI runs it);
# test-random: fresh cases each run, to look for failures the fixed ones miss.
test: install
	$(BIN)/pytest

test-random: install
	HYPOTHESIS_PROFILE=random $(BIN)/pytest

lint: install
	$(BIN)/ruff check calib_dsl tests bench
	$(BIN)/mypy calib_dsl

# bench: the venv's python once `make install` made it; else $(PY) when calibc already runs
# there (no install needed); else install first.
ifneq ($(filter bench,$(MAKECMDGOALS)),)
BENCH_PY := $(shell if [ -x $(BIN)/python ]; then echo $(BIN)/python; \
	elif $(PY) -c "import calib_dsl, lark, numpy, click, scipy, highspy" 2>/dev/null; \
	then echo $(PY); fi)
endif

bench: $(if $(BENCH_PY),,install)
	$(or $(BENCH_PY),$(BIN)/python) bench/run.py

clean:
	rm -rf $(VENV) build dist *.egg-info .pytest_cache .mypy_cache .ruff_cache
