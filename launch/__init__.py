"""The launcher (process supervisor), the ``slipstack`` command, launch and scene files."""

from slipstack.nodes.runtime.threads import one_thread_per_library

one_thread_per_library()  # `slipstack` and every node process start here, before numpy loads
