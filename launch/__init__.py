"""The launcher (process supervisor), the ``slipstack`` command, launch and scene files."""
