"""tactile_driver: a tactile matrix (URL-chosen back-end) → ``tactile/frame``.

Each frame of raw counts (rows × cols, row = y, col = x) is calibrated with
:class:`slipstack.lib.calibration.Calibration` into pressure (Pa, float32,
row-major), a saturation mask (raw count ≥ the saturation level) and a dead mask
(the calibration's dead taxels plus ``dead_taxels``; they read 0 Pa).

More in docs/modules.md, `nodes/tactile_driver.py`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from slipstack.lib.calibration import Calibration, load_calibration
from slipstack.lib.errors import ConfigError
from slipstack.lib.pad import PadMount
from slipstack.lib.samples import TactileSample
from slipstack.messages import TactileFrame
from slipstack.nodes.device_driver import DeviceDriver
from slipstack.nodes.devices.backends import Dsacon32Backend, FramedBackend
from slipstack.nodes.runtime.node import Context, Output

__all__ = ["TactileDriver", "TactileDriverParams", "DEFAULT_PA_PER_COUNT"]

DEFAULT_PA_PER_COUNT = 10.0
_FULL_SCALE = {"u8": 255, "u12": 4095, "u16": 65535}


@dataclass(frozen=True)
class TactileDriverParams:
    url: str = field(metadata={"help": "device URL, e.g. dsacon32:///dev/ttyUSB0?fps=100, m1616:///dev/ttyUSB0, "
                                       "framed:///dev/ttyACM0?header=aaabac&dtype=u16&endian=be (see docs/drivers.md)"})
    calibration: str = field(default="", metadata={
        "help": "calibration TOML file (lib/calibration.py format); empty = linear p = pa_per_count x counts"})
    pa_per_count: float = field(default=DEFAULT_PA_PER_COUNT, metadata={
        "help": "slope of the default linear calibration (Pa/count); ignored with a calibration file"})
    saturation_counts: int = field(default=0, metadata={
        "help": "raw count at which a taxel is saturated when the calibration file gives none "
                "(counts; 0 = the device's full scale)"})
    rows: int = field(default=16, metadata={"help": "expected taxel rows (y); other frame sizes are counted, not published"})
    cols: int = field(default=16, metadata={"help": "expected taxel columns (x)"})
    pitch_m: float = field(default=1.25e-3, metadata={"help": "taxel pitch (m), copied into every frame"})
    dead_taxels: tuple[int, ...] = field(default=(), metadata={
        "help": "extra dead taxels, row-major indices i = row*cols + col, e.g. 17,200"})
    stale_status_period_ms: float = field(default=10.0, metadata={
        "help": "while the device is stale/disconnected, republish the last frame with that status this often (ms)"})
    flip_rows: bool = field(default=False, metadata={"help": "mount: mirror the device image along y (rows)"})
    flip_cols: bool = field(default=False, metadata={"help": "mount: mirror the device image along x (columns)"})
    quarter_turns: int = field(default=0, metadata={
        "help": "mount: then turn it counter-clockwise about the pad normal by this many 90-degree steps (0-3)"})


class TactileDriver(DeviceDriver):
    """Reads a tactile matrix, calibrates it and publishes ``tactile/frame``."""

    name = "tactile_driver"
    kind = "tactile"
    outputs = {"frame": Output("tactile/frame", TactileFrame)}
    Params = TactileDriverParams

    def __init__(self, params: TactileDriverParams | None = None) -> None:
        super().__init__(params)
        p = self.params
        if p.rows < 1 or p.cols < 1:
            raise ConfigError(f"tactile_driver: rows and cols must be >= 1, got {p.rows}x{p.cols}")
        if not (math.isfinite(p.pitch_m) and p.pitch_m > 0):
            raise ConfigError(f"tactile_driver: pitch_m must be > 0 (m), got {p.pitch_m}")
        self.n_taxels = p.rows * p.cols
        self.mount = PadMount(p.flip_rows, p.flip_cols, p.quarter_turns)
        self.pad_shape = self.mount.shape(p.rows, p.cols)
        if not p.calibration and not (math.isfinite(p.pa_per_count) and p.pa_per_count > 0):
            raise ConfigError(f"tactile_driver: pa_per_count must be > 0 (Pa/count), got {p.pa_per_count}")
        self.calibration: Calibration | None = None
        self._last: TactileFrame | None = None

    def start(self, ctx: Context) -> None:
        p = self.params
        self.calibration = self._load_calibration()
        rows, cols = self.pad_shape
        self._last = TactileFrame(rows=rows, cols=cols, pitch_m=p.pitch_m,
                                  pressure_pa=np.zeros(self.n_taxels, dtype=np.float32),
                                  saturated=np.zeros(self.n_taxels, dtype=bool),
                                  dead=self._to_pad(self.calibration.apply(np.zeros(self.n_taxels)).dead))
        super().start(ctx)

    def _load_calibration(self) -> Calibration:
        p = self.params
        if p.calibration:
            try:
                cal = load_calibration(p.calibration)
            except OSError as e:
                raise ConfigError(f"tactile_driver: cannot read calibration {p.calibration!r}: {e}") from e
            except ConfigError as e:
                raise ConfigError(f"tactile_driver: {p.calibration}: {e}") from e
        else:
            top = 65535.0
            cal = Calibration(counts=np.array([0.0, top]), pressure_pa=np.array([0.0, top * p.pa_per_count]))
        saturation = cal.saturation_counts or p.saturation_counts or self._device_full_scale()
        cal = dataclasses.replace(cal, dead=np.union1d(cal.dead, np.array(p.dead_taxels, dtype=np.int64)),
                                  saturation_counts=saturation)
        cal.check_size(self.n_taxels)
        return cal

    def _device_full_scale(self) -> int:
        if isinstance(self.backend, Dsacon32Backend):
            return 4095
        if isinstance(self.backend, FramedBackend):
            return _FULL_SCALE[self.backend.format.dtype]
        return 65535

    def on_sample(self, sample: TactileSample, stamp_ns: int, ctx: Context) -> None:
        p = self.params
        if sample.counts.shape != (p.rows, p.cols):
            ctx.count("tactile.size_mismatch")
            ctx.set_status("size-mismatch", f"device sends {sample.counts.shape[0]}x{sample.counts.shape[1]}, "
                                            f"rows x cols is {p.rows}x{p.cols}")
            return
        cal = self.calibration.apply(sample.counts.ravel())
        device_stamp = -1 if sample.device_time_s is None else round(sample.device_time_s * 1e9)
        self._last = dataclasses.replace(self._last, pressure_pa=self._to_pad(cal.pressure_pa.astype(np.float32)),
                                         saturated=self._to_pad(cal.saturated), dead=self._to_pad(cal.dead),
                                         device_stamp=device_stamp)
        ctx.publish("frame", self._last, stamp_ns=stamp_ns)

    def _to_pad(self, taxels: np.ndarray) -> np.ndarray:
        """Device-ordered taxel values (rows × cols, row-major) in the pad's row-major order."""
        if self.mount.identity:
            return taxels
        image = self.mount.apply(taxels.reshape(self.params.rows, self.params.cols))
        return np.ascontiguousarray(image).reshape(-1)

    def publish_status(self, status: str, ctx: Context) -> None:
        ctx.publish("frame", dataclasses.replace(self._last, status=status), stamp_ns=ctx.now_ns())
