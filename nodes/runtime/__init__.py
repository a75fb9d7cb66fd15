"""What every node runs on: the node model, host, executors, transport, run directories."""
