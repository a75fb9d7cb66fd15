# Quick start: `make run` (the default stack on the simulated rig) and `make test`.
# Both create ./.venv and install slipstack into it on first use. ARGS='name:=value ...'
# passes launch arguments to `make run` (e.g. ARGS=verbose:=true).
VENV ?= .venv
PY := $(VENV)/bin/python
# Every install takes the exact versions of the lock file (docs/portability.md §3); PIP_CONSTRAINT
# reaches pip's build environment too. `make upgrade` writes it anew.
LOCK := constraints.txt
PIP := PIP_CONSTRAINT=$(CURDIR)/$(LOCK) $(PY) -m pip
EXTRAS := test,foxglove,report,bench,ros2

.PHONY: run test bench mutation upgrade

# The install also compiles the numba kernels and the modules' byte-code, as pip does for an
# installed package (an editable install has none: where PYTHONDONTWRITEBYTECODE is set, every
# process would compile every module again at start-up).
$(VENV)/.installed: pyproject.toml $(LOCK)
	python3 -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q -e '.[test,foxglove,ros2]'
	$(PY) -c 'from slipstack.lib.limit_set import compile_kernels; compile_kernels(); from slipstack.lib.fusion import compile_kernels as fusion; fusion(); from slipstack.lib.protocols.crc import compile_kernels as crc; crc(); from slipstack.lib.rig.simulator import compile_kernels as rig; rig()'
	$(PY) -m compileall -q lib messages nodes launch analysis
	touch $@

run: $(VENV)/.installed
	$(VENV)/bin/slipstack launch $(ARGS)

test: $(VENV)/.installed
	$(PY) -m pytest -q

bench: $(VENV)/.installed
	$(PIP) install -q -e '.[test,bench]'
	@echo "benchmarks are scripts: ls tests/bench/; run e.g. $(PY) tests/bench/bench_math.py --help"

# Mutation testing of lib/ and the control-path nodes (long: not in CI). MUTATE_ARGS narrows it,
# e.g. MUTATE_ARGS="lib/weber.py --line 203"; see tests/mutation/README.md.
mutation: $(VENV)/.installed
	$(PY) tests/mutation/mutate.py --interpreted $(MUTATE_ARGS)

# The newest releases that pyproject.toml allows, every extra, frozen into the lock file; then
# the suite on them from a fresh venv. Commit constraints.txt with what the suite says.
upgrade:
	rm -rf $(VENV).upgrade
	python3 -m venv $(VENV).upgrade
	$(VENV).upgrade/bin/python -m pip install -q --upgrade pip
	$(VENV).upgrade/bin/python -m pip install -q -e '.[$(EXTRAS)]'
	{ echo "# exact versions of every install (make upgrade writes this file; docs/portability.md §3)"; \
	  $(VENV).upgrade/bin/python -m pip freeze --exclude-editable; } > $(LOCK)
	rm -rf $(VENV).upgrade $(VENV)
	$(MAKE) test
