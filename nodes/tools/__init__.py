"""Command-line tools that attach to a running graph: ``slipstack topic | node | bag``."""
