"""Shared test settings: hypothesis profiles sized for a 2-core CI machine; the numba
kernels compiled (or loaded from their cache) once before any test, so no timed test
and no launched node pays the compile."""

from hypothesis import HealthCheck, settings

from slipstack.lib.limit_set import compile_kernels

settings.register_profile("ci", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("ci")
compile_kernels()
