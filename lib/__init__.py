"""Pure computation for slipstack: no sockets, no processes, no system clock.

Pad geometry, fusion, limit sets and slip tests, COR solvers, grip laws, friction
identification (docs/math.md), the simulated rig's physics and sensor models (``rig``)
and device wire-protocol codecs (``protocols``).
"""
