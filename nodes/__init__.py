"""The graph's nodes: thin adapters from topics to ``slipstack.lib`` calls.

The modules directly in this package are the node types a launch file names
(``runtime/catalog.py``). Beside them, by kind (docs/architecture.md §1):

* ``runtime/``: the node model, the executors (process and in-process), transport,
  run directories — what every node runs on;
* ``devices/``: byte links, one back-end per URL scheme, and the device emulators;
* ``recording/``: MCAP recordings (file format, the recorder and the player);
* ``tools/``: the ``slipstack topic | node | bag`` verbs that attach to a running graph.
"""

from slipstack.nodes.runtime.threads import one_thread_per_library

one_thread_per_library()  # before anything below this package loads numpy
