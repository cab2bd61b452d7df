# Two commands on a fresh machine: `make demo` and `make test`. Both build .venv
# from requirements.lock first (exact pins), then install vmt itself without deps.
PY      ?= python3.11
VENV    := .venv
VPY     := $(VENV)/bin/python
STAMP   := $(VENV)/.installed
OUT     ?= out

.PHONY: venv demo test bench clean

venv: $(STAMP)

$(STAMP): requirements.lock pyproject.toml
	@command -v $(PY) >/dev/null 2>&1 || { echo "error: $(PY) not found (vmt needs Python 3.11)"; exit 2; }
	$(PY) -m venv $(VENV)
	$(VPY) -m pip install --quiet "pip==26.3"
	$(VPY) -m pip install --quiet -r requirements.lock
	$(VPY) -m pip install --quiet --no-deps --no-build-isolation -e .
	@touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/vmt demo --out $(OUT)

test: $(STAMP)
	OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 $(VPY) -m pytest -q -p no:cacheprovider

bench: $(STAMP)
	$(VENV)/bin/vmt bench --out bench/results.json

clean:
	rm -rf $(VENV) $(OUT) build *.egg-info
