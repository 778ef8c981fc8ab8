# cadfeat — `make demo` and `make test` set everything up themselves (Python 3.11).
PYTHON ?= python3
VENV   ?= .venv
PY      = $(VENV)/bin/python
STAMP   = $(VENV)/.cadfeat-installed

.PHONY: setup demo test test-kernels lint docs bench clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	# one cv2: the contrib wheel only (a venv that has the base wheel loses both, then gets contrib alone)
	if $(PY) -m pip show -q opencv-python-headless 2>/dev/null; then \
	  $(PY) -m pip uninstall -q -y opencv-python-headless opencv-contrib-python-headless; fi
	$(PY) -m pip install -q -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	tools/ensure_system.sh
	$(PY) -m cadfeat.cli.demo $(DEMO_ARGS)

# The suite on every core, up to 4 (pytest-xdist), a test file per worker: a file's tests share its module
# fixtures (a study set up once) and run in order; PYTEST_PARALLEL= runs it in one process.
PYTEST_PARALLEL ?= -n auto --maxprocesses 4 --dist loadfile

test: $(STAMP)
	tools/ensure_system.sh
	CADFEAT_CHROMIUM="$$(tools/ensure_chromium.sh)" && export CADFEAT_CHROMIUM && \
	$(MAKE) --no-print-directory lint && \
	$(MAKE) --no-print-directory docs && \
	$(PY) -m pytest -q $(PYTEST_PARALLEL) && \
	$(MAKE) --no-print-directory test-kernels

# The numerical tests again under another OpenBLAS kernel family that every x86-64 CPU has (Prescott; the
# first pass runs whatever the CPU picks, e.g. SkylakeX with AVX-512): a tolerance, or a decision (a tie, a
# stopping test, a derivative-free solver's path), that holds on one kernel's round-off only shows here. The
# numerical tests: those marked `numerics`, and every test under tests/measures, tests/design, tests/vision and
# tests/cell (tests/conftest.py). In parallel like the first pass. Add KERNELS="Prescott Haswell" to try more.
KERNELS ?= Prescott
test-kernels: $(STAMP)
	for k in $(KERNELS); do \
	  echo "numerical tests under OPENBLAS_CORETYPE=$$k"; \
	  OPENBLAS_CORETYPE=$$k $(PY) -m pytest -q $(PYTEST_PARALLEL) -m numerics || exit 1; \
	done

# ruff; pyright basic on the package (pyrightconfig.json: the rules that fail on the CadQuery/OCP/numpy stubs
# are listed there, off) and strict on measures/, study/, design/, results/ and settings.py (pyright-strict.json,
# which names the modules left out and why); the two pyright runs side by side (one core each), the strict run's
# output after the basic run's.
lint: $(STAMP)
	$(PY) -m ruff check cadfeat tests benchmarks tools $(wildcard parts studies)
	log=$$(mktemp); \
	$(VENV)/bin/pyright --pythonpath $(PY) -p pyright-strict.json > $$log 2>&1 & strict=$$!; \
	$(VENV)/bin/pyright --pythonpath $(PY); basic=$$?; \
	wait $$strict; status=$$?; cat $$log; rm -f $$log; test $$basic -eq 0 && test $$status -eq 0

# The documentation (mkdocs.yml, docs/): MkDocs + mkdocstrings, --strict so that a broken link or anchor, a page
# outside the nav or an API reference to a name that no longer exists fails the build (and `make test`). No
# --quiet: it hides the warnings from the count that --strict aborts on (a broken link would pass).
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(PY) -m mkdocs build --strict --site-dir build/docs

bench: $(STAMP)
	$(PY) benchmarks/run_all.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache build *.egg-info
