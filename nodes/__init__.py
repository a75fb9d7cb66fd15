"""Nodes: thin adapters from topics to ``slipstack.lib`` calls, and tools on the bus."""
