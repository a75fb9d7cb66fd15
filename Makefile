# Quick start: `make run` (the default stack on the simulated rig) and `make test`.
# Both create ./.venv and install slipstack into it on first use.
VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: run test bench mutation

# The install also compiles the numba kernels and the modules' byte-code, as pip does for an
# installed package (an editable install has none: where PYTHONDONTWRITEBYTECODE is set, every
# process would compile every module again at start-up).
$(VENV)/.installed: pyproject.toml
	python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test,foxglove,ros2]'
	$(PY) -c 'from slipstack.lib.limit_set import compile_kernels; compile_kernels(); from slipstack.lib.fusion import compile_kernels as fusion; fusion(); import slipstack.lib.protocols.crc; from slipstack.lib.rig.simulator import compile_kernels as rig; rig()'
	$(PY) -m compileall -q lib messages nodes launch analysis
	touch $@

run: $(VENV)/.installed
	$(VENV)/bin/slipstack launch

test: $(VENV)/.installed
	$(PY) -m pytest -q

bench: $(VENV)/.installed
	$(PY) -m pip install -q -e '.[test,bench]'
	@echo "benchmarks are scripts: ls tests/bench/; run e.g. $(PY) tests/bench/bench_math.py --help"

# Mutation testing of lib/ and the control-path nodes (long: not in CI). MUTATE_ARGS narrows it,
# e.g. MUTATE_ARGS="lib/weber.py --line 203"; see tests/mutation/README.md.
mutation: $(VENV)/.installed
	$(PY) tests/mutation/mutate.py --interpreted $(MUTATE_ARGS)
