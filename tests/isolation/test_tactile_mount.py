"""The tactile driver turns a pad mounted the other way round into the pad frame.

A real DSACON32 emulator on a pty sends a 6 × 14 image with one pressed taxel and
one dead taxel (declared in the device's own indices); the driver, told how the array
is mounted, publishes the frame with both where the pad frame has them.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_driver_nodes import MS, Harness

from slipstack.lib.pad import PadGeometry
from slipstack.nodes.devices.emulators import Dsacon32Emulator
from slipstack.nodes.tactile_driver import TactileDriver, TactileDriverParams

ROWS, COLS = 6, 14


def _device_xy(r: int, c: int) -> tuple[float, float]:
    """Position (pitches) of device taxel (r, c) with the array mounted as is."""
    return c - (COLS - 1) / 2, r - (ROWS - 1) / 2


def _mounted(xy: tuple[float, float], flip_rows=False, flip_cols=False, quarter_turns=0) -> tuple[float, float]:
    """By hand: mirror y, mirror x, then (x, y) -> (-y, x) per counter-clockwise quarter turn."""
    x, y = xy
    y = -y if flip_rows else y
    x = -x if flip_cols else x
    for _ in range(quarter_turns):
        x, y = -y, x
    return x, y


@pytest.mark.parametrize("mount", [
    {}, {"quarter_turns": 1}, {"quarter_turns": 2}, {"flip_cols": True}, {"flip_rows": True, "quarter_turns": 3},
])
def test_pressed_and_dead_taxels_land_where_the_mount_puts_them(mount):
    emu = Dsacon32Emulator(rows=ROWS, cols=COLS)
    try:
        params = TactileDriverParams(url=f"dsacon32://{emu.path}?fps=100", rows=ROWS, cols=COLS, pitch_m=1e-3,
                                     dead_taxels=(0,), **mount)
        h = Harness(TactileDriver(params), emu)
        h.start()
        h.wait_for(lambda: h.node.backend.matrices and emu.acquiring)
        counts = np.zeros((ROWS, COLS), dtype=np.uint16)
        counts[1, 12] = 900
        msg = h.send(emu.send_tactile, counts, dt_ns=10 * MS)
        rows, cols = (COLS, ROWS) if mount.get("quarter_turns", 0) % 2 else (ROWS, COLS)
        assert (msg.rows, msg.cols) == (rows, cols)
        positions = PadGeometry(rows, cols, 1e-3).positions * 1e3  # in pitches
        assert tuple(positions[int(np.argmax(msg.pressure_pa))]) == pytest.approx(_mounted(_device_xy(1, 12), **mount))
        assert msg.dead.sum() == 1
        assert tuple(positions[int(np.argmax(msg.dead))]) == pytest.approx(_mounted(_device_xy(0, 0), **mount))
    finally:
        emu.close()
