"""The whole stack in one process, in lock-step with the simulated rig.

For benchmarks and golden files: deterministic (a scene seed fixes everything) and
as fast as the machine allows. Each F/T and tactile sample of the simulator still
travels as device bytes — encoded by the emulator-side codec (ATI RDT records,
DSACON32 packets), decoded by the driver-side codec — and enters the real driver
nodes through their ``on_sample``; from there the real nodes run on the
:class:`~slipstack.nodes.runtime.inprocess.InProcessExecutor`. A grip command takes effect at
the next simulator tick (``tick_ms``), like the real-time rig.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable


from slipstack.lib.calibration import Calibration, save_calibration
from slipstack.lib.protocols import ati_rdt, dsacon32
from slipstack.lib.protocols.stream import Deframer
from slipstack.lib.rig.scene import Scene, load_scene
from slipstack.lib.samples import FtSample, TactileSample
from slipstack.lib.rig.simulator import Simulator
from slipstack.lib.toml_file import resolve_path
from slipstack.messages import RigTruth
from slipstack.nodes.cor_estimator import CorEstimator, CorParams
from slipstack.nodes.ft_driver import FtDriver, FtDriverParams
from slipstack.nodes.fusion import Fusion, FusionParams
from slipstack.nodes.grip_controller import GripController, GripControllerParams
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.runtime.node import Node, Output
from slipstack.nodes.rig import truth_message
from slipstack.nodes.slip_detector import SlipDetector, SlipDetectorParams
from slipstack.nodes.tactile_driver import TactileDriver, TactileDriverParams

__all__ = ["StackConfig", "LockstepStack", "load_scene_by_name"]

_CPF = 1_000_000.0  # counts per N and per N·m of the emulated RDT stream


def load_scene_by_name(name: str) -> Scene:
    """A shipped scene (``fig10``) or a scene file path."""
    return load_scene(resolve_path(name, Path.cwd(), "scenes"))


@dataclass
class StackConfig:
    """Which stack runs on the scene; parameters as the nodes' own."""

    controller: bool = True
    tactile: bool | None = None  # None: as the scene says
    grip: dict[str, Any] = field(default_factory=dict)
    slip: dict[str, Any] = field(default_factory=dict)
    cor: dict[str, Any] = field(default_factory=dict)
    fusion: dict[str, Any] = field(default_factory=dict)
    tick_ms: float = 1.0


class _TruthSource(Node):
    """Publishes ``rig/truth`` for the lock-step loop (no timers, no I/O)."""

    name = "rig"
    outputs = {"truth": Output("rig/truth", RigTruth)}


class _RdtWire:
    """Simulated F/T sample → RDT record bytes → decoded driver-side sample."""

    def __init__(self) -> None:
        self.seq = 0

    def __call__(self, s: FtSample) -> FtSample:
        self.seq += 1
        counts = [round(v * _CPF) for v in (*s.force_n, *s.torque_nm)]
        (record,) = ati_rdt.decode_records(ati_rdt.encode_record(self.seq, self.seq, 0, counts))
        force, torque = ati_rdt.to_wrench(record, _CPF, _CPF)
        return FtSample(stamp_ns=s.stamp_ns, force_n=force, torque_nm=torque, device_seq=record.rdt_sequence,
                        device_time_s=None, status=record.status)


class _DsaconWire:
    """Simulated tactile frame → DSACON32 packet bytes → decoded driver-side sample."""

    def __init__(self, rows: int, cols: int) -> None:
        self.rows, self.cols = rows, cols
        self.deframer = Deframer(dsacon32.PacketCodec(allow_empty=False))

    def __call__(self, s: TactileSample) -> TactileSample | None:
        wire = dsacon32.encode_packet(dsacon32.PacketId.FRAME, dsacon32.encode_frame_payload(s.stamp_ns // 1_000_000, s.counts))
        packets = self.deframer.feed(wire)
        frame = dsacon32.decode_frame_payload(packets[0].payload, self.rows * self.cols) if packets else None
        if frame is None:
            return None
        return TactileSample(stamp_ns=s.stamp_ns, counts=frame.counts.reshape(self.rows, self.cols),
                             device_time_s=frame.timestamp_ms / 1e3)


class LockstepStack:
    """Run ``scene`` through the stack of ``config``; results in :attr:`executor`.

    After :meth:`run`, ``executor.published`` holds every topic (``ft/wrench``,
    ``tactile/frame``, ``contact``, ``cor``, ``slip``, ``grip/command``,
    ``rig/truth``).
    """

    def __init__(self, scene: Scene | str, config: StackConfig | None = None) -> None:
        self.scene = load_scene_by_name(scene) if isinstance(scene, str) else scene
        self.config = cfg = config or StackConfig()
        sc = self.scene
        self.sim = Simulator(sc)
        self.tactile = sc.tactile.enabled if cfg.tactile is None else (cfg.tactile and sc.tactile.enabled)
        self._tmp = tempfile.TemporaryDirectory(prefix="slipstack-lockstep-")
        yaw_deg = math.degrees(sc.ft.yaw_rad)
        self.ft_driver = FtDriver(FtDriverParams(url="rdt://127.0.0.1:1", pad_offset_m=tuple(sc.ft.origin_m),
                                                 pad_rpy_deg=(0.0, 0.0, yaw_deg)))
        nodes: list[Node] = [self.ft_driver, _TruthSource(), Fusion(FusionParams(**{"use_tactile": self.tactile, **cfg.fusion}))]
        self.tactile_driver = None
        if self.tactile:
            cal_path = Path(self._tmp.name) / "calibration.toml"
            pressure, counts = self.sim.tactile.calibration_table()
            save_calibration(Calibration(counts=counts, pressure_pa=pressure,
                                         saturation_counts=sc.tactile.full_scale_counts), cal_path)
            self.tactile_driver = TactileDriver(TactileDriverParams(
                url="dsacon32:///lockstep", calibration=str(cal_path), rows=sc.pad.rows, cols=sc.pad.cols,
                pitch_m=sc.pad.pitch_m))
            nodes += [self.tactile_driver, CorEstimator(CorParams(**cfg.cor))]
        nodes.append(SlipDetector(SlipDetectorParams(**cfg.slip)))
        if cfg.controller:
            nodes.append(GripController(GripControllerParams(**cfg.grip)))
        for driver in (self.ft_driver, self.tactile_driver):
            if driver is not None:
                driver.detach()
        self.executor = InProcessExecutor(nodes)
        self._hosts = {id(h.node): h for h in self.executor.hosts}
        self._rdt = _RdtWire()
        self._dsa = _DsaconWire(sc.pad.rows, sc.pad.cols)
        self._commands_seen = 0

    def _host(self, node: Node):
        return self._hosts[id(node)]

    def run(self, progress: Callable[[float], None] | None = None) -> InProcessExecutor:
        """Simulate the whole scene; ``progress(fraction)`` is called about every 1 %."""
        ex, sim = self.executor, self.sim
        tick = round(self.config.tick_ms * 1e6)
        truth_host = next(h for h in ex.hosts if isinstance(h.node, _TruthSource))
        commands = ex.published["grip/command"]
        next_report = 0.0
        t = 0
        while not sim.done:
            t = min(t + tick, sim.end_ns)
            for s in sim.step_until(t):
                ex.now = max(ex.now, s.stamp_ns)
                if isinstance(s, FtSample):
                    host = self._host(self.ft_driver)
                    host.call("on_sample", self.ft_driver.on_sample, self._rdt(s), host)
                elif isinstance(s, TactileSample):
                    if self.tactile_driver is not None:
                        sample = self._dsa(s)
                        host = self._host(self.tactile_driver)
                        if sample is None:
                            host.count("lockstep.undecodable_frames")
                        else:
                            host.call("on_sample", self.tactile_driver.on_sample, sample, host)
                else:
                    truth_host.publish("truth", truth_message(s), stamp_ns=s.stamp_ns)
                ex.run(until_ns=ex.now)
            if len(commands) > self._commands_seen:
                self._commands_seen = len(commands)
                sim.command_normal_force(commands[-1].f_n_desired)
            if progress is not None and t / sim.end_ns >= next_report:
                progress(t / sim.end_ns)
                next_report += 0.01
        ex.stop()
        return ex

    def close(self) -> None:
        self._tmp.cleanup()
