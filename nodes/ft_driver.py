"""ft_driver: a 6-axis F/T sensor (URL-chosen back-end) → ``ft/wrench``.

Per decoded sample, in this order:

More in docs/modules.md, `nodes/ft_driver.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from slipstack.lib.errors import ConfigError
from slipstack.lib.filters import LowPass
from slipstack.lib.frames import rotation_rpy
from slipstack.lib.fusion import SensorMount, wrench_to_pad
from slipstack.lib.samples import FtSample
from slipstack.messages import Wrench
from slipstack.nodes.device_driver import DeviceDriver
from slipstack.nodes.runtime.node import Context, Output

__all__ = ["FtDriver", "FtDriverParams"]


@dataclass(frozen=True)
class FtDriverParams:
    url: str = field(metadata={"help": "device URL, e.g. rdt://192.168.1.1:49152?cpf=1000000&cpt=1000000, "
                                       "robotiq:///dev/ttyUSB0, bota:///dev/ttyUSB0 (see docs/drivers.md)"})
    tare_on_start: bool = field(default=False, metadata={
        "help": "average the first tare_samples samples and subtract them as the bias (sensor frame)"})
    tare_samples: int = field(default=100, metadata={"help": "samples averaged for a tare (count, >= 1)"})
    lowpass_hz: float = field(default=0.0, metadata={
        "help": "first-order low-pass cut-off (Hz); 0 = off; dt = 1/rate_hz of the URL"})
    to_pad: bool = field(default=True, metadata={
        "help": "publish in the pad frame F (frame='pad') using pad_offset_m and pad_rpy_deg; "
                "false publishes the sensor frame (frame='sensor')"})
    pad_offset_m: tuple[float, ...] = field(default=(0.0, 0.0, 0.0), metadata={
        "help": "x,y,z position of the sensor origin in the pad frame F (m)"})
    pad_rpy_deg: tuple[float, ...] = field(default=(0.0, 0.0, 0.0), metadata={
        "help": "roll,pitch,yaw of the sensor frame relative to F (deg; R_FS = Rz(yaw) Ry(pitch) Rx(roll); "
                "a sensor turned about z only is 0,0,yaw)"})
    stale_status_period_ms: float = field(default=10.0, metadata={
        "help": "while the device is stale/disconnected, republish the last wrench with that status "
                "this often (ms)"})


class FtDriver(DeviceDriver):
    """Reads a 6-axis F/T sensor and publishes ``ft/wrench`` (bias, low-pass, sensor→pad)."""

    name = "ft_driver"
    kind = "ft"
    outputs = {"wrench": Output("ft/wrench", Wrench)}
    Params = FtDriverParams

    def __init__(self, params: FtDriverParams | None = None) -> None:
        super().__init__(params)
        p = self.params
        if p.tare_samples < 1:
            raise ConfigError(f"ft_driver: tare_samples must be >= 1, got {p.tare_samples}")
        if not (math.isfinite(p.lowpass_hz) and p.lowpass_hz >= 0):
            raise ConfigError(f"ft_driver: lowpass_hz must be a finite number >= 0 (Hz), got {p.lowpass_hz}")
        if len(p.pad_offset_m) != 3 or len(p.pad_rpy_deg) != 3:
            raise ConfigError("ft_driver: pad_offset_m and pad_rpy_deg need exactly 3 numbers each, e.g. 0,0,0.01")
        rpy = [math.radians(a) for a in p.pad_rpy_deg]
        mount = SensorMount(R_FS=tuple(map(tuple, rotation_rpy(*rpy).tolist())), p_SF=tuple(p.pad_offset_m))
        self.R_FS = np.array(mount.R_FS)
        self.p_SF = np.array(mount.p_SF)
        self.frame = "pad" if p.to_pad else "sensor"
        self.bias = np.zeros(6)
        self.filter = LowPass(p.lowpass_hz)
        self._tare_sum: np.ndarray | None = None
        self._tare_n = 0
        self._force = np.zeros(3)
        self._torque = np.zeros(3)
        if p.tare_on_start:
            self.tare()

    def tare(self) -> None:
        """Average the next ``tare_samples`` samples and use the mean as the new bias."""
        self._tare_sum = np.zeros(6)
        self._tare_n = 0

    def on_sample(self, sample: FtSample, stamp_ns: int, ctx: Context) -> None:
        raw = np.concatenate([sample.force_n, sample.torque_nm])
        status = "ok" if not sample.status else f"device-status 0x{sample.status:04x}"
        if self._tare_sum is not None:
            status = "taring"
            self._tare_sum += raw
            self._tare_n += 1
            if self._tare_n >= self.params.tare_samples:
                self.bias = self._tare_sum / self._tare_n
                self._tare_sum = None
                self.filter.reset()
                ctx.count("ft.tares")
                ctx.log(f"tared over {self._tare_n} samples: bias force {self.bias[:3]} N, torque {self.bias[3:]} N·m")
        w = self.filter.step(raw - self.bias, self.sample_period_s)
        force, torque = (wrench_to_pad(w[:3], w[3:], self.R_FS, self.p_SF) if self.params.to_pad
                         else (w[:3], w[3:]))
        self._force, self._torque = force, torque
        seq = -1 if sample.device_seq is None else sample.device_seq
        self._publish(status, seq, stamp_ns, ctx)

    def publish_status(self, status: str, ctx: Context) -> None:
        self._publish(status, -1, ctx.now_ns(), ctx)

    def on_link_lost(self) -> None:
        self.filter.reset()

    def _publish(self, status: str, seq: int, stamp_ns: int, ctx: Context) -> None:
        msg = Wrench(force=self._force, torque=self._torque, frame=self.frame, device_seq=seq, status=status)
        ctx.publish("wrench", msg, stamp_ns=stamp_ns)
