"""Shared test settings: hypothesis profiles, and the numba kernels compiled (or loaded
from their cache) once before any test, so no timed test and no launched node pays the
compile.

Hypothesis profiles (``HYPOTHESIS_PROFILE=name`` picks one; otherwise ``ci`` when the
``CI`` environment variable is set, as on the CI machine, and ``dev`` elsewhere):

More in docs/modules.md, `tests/conftest.py`.
"""

import os

from hypothesis import HealthCheck, settings

from slipstack.lib.fusion import compile_kernels as compile_fusion_kernels
from slipstack.lib.limit_set import compile_kernels
from slipstack.lib.protocols.crc import compile_kernels as compile_crc_kernels
from slipstack.lib.rig.simulator import compile_kernels as compile_rig_kernels

_COMMON = {"deadline": None, "suppress_health_check": [HealthCheck.too_slow]}
settings.register_profile("ci", derandomize=True, database=None, max_examples=100, **_COMMON)
settings.register_profile("dev", max_examples=100, **_COMMON)
settings.register_profile("thorough", max_examples=1000, **_COMMON)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE") or ("ci" if os.environ.get("CI") else "dev"))
compile_kernels()
compile_fusion_kernels()
compile_rig_kernels()
compile_crc_kernels()
