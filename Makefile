# Two commands on a fresh machine: `make demo` and `make test`. Both build .venv
# from requirements.lock first (exact pins), then install vmt itself without deps.
PY      ?= python3.11
VENV    := .venv
VPY     := $(VENV)/bin/python
STAMP   := $(VENV)/.installed
OUT     ?= out

.PHONY: venv demo test test-controllers bench bench-table clean

venv: $(STAMP)

$(STAMP): requirements.lock pyproject.toml
	@command -v $(PY) >/dev/null 2>&1 || { echo "error: $(PY) not found (vmt needs Python 3.11)"; exit 2; }
	$(PY) -m venv $(VENV)
	$(VPY) -m pip install --quiet "pip==26.3"
	$(VPY) -m pip install --quiet -r requirements.lock
	$(VPY) -m pip install --quiet --no-deps --no-build-isolation -e .
	@touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/vmt demo --out-dir $(OUT)

# two workers (pytest-xdist); each test file on one worker, files sharing a session fixture together,
# the longest first (tests/conftest.py): no costly fixture computed twice
# PYTHONDONTWRITEBYTECODE cleared: the test files' rewritten asserts (about 3.5 s of CPU) and the
# packages' byte code are kept in __pycache__ (ignored by git); on a fresh clone they are made once,
# before the workers start (tests/conftest.py pytest_sessionstart), not by each worker
# TMPDIR on /dev/shm when it is a tmpfs with 1 GiB free (a run writes about 20 MB): the tests' files
# (pytest's tmp_path, the `vmt` processes' temporaries) are written and fsynced as always, but an
# fsync there costs no disk flush (8 ms each on this machine's ext4, over 1,200 per run); elsewhere,
# or with TEST_TMPDIR= given empty, the usual TMPDIR
TEST_WORKERS ?= 2
TEST_TMPDIR ?= $(shell df -Pk /dev/shm 2>/dev/null | awk 'NR == 2 && $$4 >= 1048576 {print "/dev/shm"}' | \
                 while read d; do [ -w "$$d" ] && [ "$$(stat -f -c %T "$$d" 2>/dev/null)" = tmpfs ] && echo "$$d"; done)
test: $(STAMP)
	$(if $(TEST_TMPDIR),TMPDIR=$(TEST_TMPDIR)) PYTHONDONTWRITEBYTECODE= OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 \
	  $(VPY) -m pytest -q -p no:cacheprovider \
	  -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

# Real controllers in the loop (tests/controllers): LinuxCNC 2.9 from Debian's packages,
# installed here if missing (needs root, as in CI); it fails, never skips, when it cannot.
test-controllers: $(STAMP)
	@if ! command -v linuxcnc >/dev/null 2>&1; then \
	  echo "installing linuxcnc-uspace (Debian) ..."; t0=$$(date +%s); \
	  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
	      --no-install-recommends -o DPkg::Lock::Timeout=600 linuxcnc-uspace >/dev/null; } \
	  || { echo "error: cannot install linuxcnc-uspace: the LinuxCNC tests cannot run"; exit 2; }; \
	  echo "linuxcnc-uspace installed in $$(( $$(date +%s) - t0 )) s"; fi
	OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 $(VPY) -m pytest -q -s -p no:cacheprovider tests/controllers

# every figure with its same-run reference (bench/results.json), and README's table generated from it
bench: $(STAMP)
	$(VENV)/bin/vmt bench --json bench/results.json --readme README.md

# README's performance table again from the last bench/results.json (no benchmark run)
bench-table: $(STAMP)
	$(VENV)/bin/vmt bench --from-json bench/results.json --readme README.md

clean:
	rm -rf $(VENV) $(OUT) build *.egg-info
