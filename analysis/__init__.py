"""Offline analysis: the paper's experiments re-run in lock-step and drawn as its figures."""
