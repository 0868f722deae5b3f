# Two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY      = $(VENV)/bin/python
STAMP   = $(VENV)/.installed

.PHONY: demo test venv lint clean

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null || { \
		echo "swarmpose needs Python >= 3.11; '$(PYTHON)' is $$($(PYTHON) --version 2>&1 || echo missing)." \
		     "Name another one: make PYTHON=python3.11 demo"; exit 1; }
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/swarmpose demo

# The torch backend's tests need PyTorch. Only a "+cpu" build is asked for (PyPI has none, so this never
# pulls CUDA packages; this machine kind's pip finds one in its local wheel folder). Where pip cannot
# find one the tests are skipped.
TORCH_STAMP = $(VENV)/.torch-tried
$(TORCH_STAMP): $(STAMP)
	-$(PY) -m pip install -q 'torch==2.13.0+cpu' 2>/dev/null || \
		echo "note: no local CPU build of torch here; the torch backend tests will be skipped"
	touch $(TORCH_STAMP)

test: $(STAMP) $(TORCH_STAMP)
	$(PY) -m pytest -q

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests
	$(VENV)/bin/lint-imports --no-cache

clean:
	rm -rf $(VENV) build *.egg-info src/*.egg-info
	find src -name '*.nbi' -delete -o -name '*.nbc' -delete  # numba's compiled kernels
