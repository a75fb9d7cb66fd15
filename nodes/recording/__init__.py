"""Recordings: the MCAP file of slipstack frames, the recorder and the player."""
