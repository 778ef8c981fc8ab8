# cadfeat — `make demo` and `make test` set everything up themselves (Python 3.11).
PYTHON ?= python3
VENV   ?= .venv
PY      = $(VENV)/bin/python
STAMP   = $(VENV)/.cadfeat-installed

.PHONY: setup demo test lint bench clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	tools/ensure_system.sh
	$(PY) -m cadfeat.cli.demo $(DEMO_ARGS)

test: $(STAMP)
	tools/ensure_system.sh
	CADFEAT_CHROMIUM="$$(tools/ensure_chromium.sh)" && export CADFEAT_CHROMIUM && \
	$(MAKE) lint && \
	$(PY) -m pytest -q

# ruff; pyright basic on the package (pyrightconfig.json: the rules that fail on the CadQuery/OCP/numpy stubs
# are listed there, off) and strict on measures/ and the study settings models (pyright-strict.json).
lint: $(STAMP)
	$(PY) -m ruff check cadfeat tests benchmarks tools $(wildcard parts studies)
	$(VENV)/bin/pyright --pythonpath $(PY)
	$(VENV)/bin/pyright --pythonpath $(PY) -p pyright-strict.json

bench: $(STAMP)
	$(PY) benchmarks/run_all.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache build *.egg-info
