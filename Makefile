# Two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY      = $(VENV)/bin/python
STAMP   = $(VENV)/.installed

.PHONY: demo test venv detect lint clean

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

# The detection tests run MediaPipe Pose 0.10.14, the one version that ships its pose models in the wheel. Its
# declared dependencies pull jax and opencv-contrib-python (which clashes with opencv-python-headless), so it is
# installed without them, plus the four packages it needs. Where that fails the tests that need it are skipped.
DETECT_STAMP = $(VENV)/.detect-tried
$(DETECT_STAMP): $(STAMP)
	-$(PY) -m pip install -q --no-deps 'mediapipe==0.10.14' && \
		$(PY) -m pip install -q absl-py attrs flatbuffers 'protobuf>=4.25.3,<5' || \
		echo "note: MediaPipe could not be installed here; the detection tests that run it will be skipped"
	touch $(DETECT_STAMP)

detect: $(DETECT_STAMP)

test: $(STAMP) $(TORCH_STAMP) $(DETECT_STAMP)
	$(PY) -m pytest -q

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests
	$(VENV)/bin/lint-imports --no-cache

clean:
	rm -rf $(VENV) build *.egg-info src/*.egg-info
	find src -name '*.nbi' -delete -o -name '*.nbc' -delete  # numba's compiled kernels
