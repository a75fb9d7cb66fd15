"""rig: the simulated laboratory rig behind real device protocols.

More in docs/modules.md, `nodes/rig.py`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from slipstack.lib.calibration import Calibration, save_calibration
from slipstack.lib.errors import ConfigError
from slipstack.lib.late_ticks import LateTicks
from slipstack.lib.rig.actuator import CommandWatchdog
from slipstack.lib.rig.scene import Scene, load_scene, with_rig_material
from slipstack.lib.samples import MAX_SAMPLE_RATE_HZ, FtSample, TactileSample
from slipstack.lib.rig.simulator import Simulator, Truth, compile_kernels as compile_rig_kernels
from slipstack.lib.protocols.crc import compile_kernels as compile_crc_kernels
from slipstack.lib.toml_file import resolve_path
from slipstack.messages import GraspTruth, GripCommand, GripState, RigTruth
from slipstack.messages.types import MAX_GRIP_FORCE_N
from slipstack.nodes.devices.emulators import (
    BotaEmulator, Dsacon32Emulator, M1616Emulator, RdtSimServer, RdtUdpServer, RobotiqEmulator, WsgEmulator,
)
from slipstack.nodes.devices.sim_link import SIM_PREFIX, is_simulated
from slipstack.nodes.runtime.node import Context, Input, Node, Output
from slipstack.nodes.runtime.scheduling import runs_realtime

__all__ = ["Rig", "RigParams", "load_scene_by_name", "truth_message", "grasp_truth_message", "with_rates"]

_NS_PER_MS = 1_000_000
_LATE_TICK_MS = 10
"""A tick later than this (ms) after its due time is reported: half the grip controller's timeout."""
_LATE_REPORT_EVERY_S = 10
"""At most one "fell behind real time" report per this long (s)."""
_MAX_NAMED_SENDERS = 16
"""Senders of manual commands named in the log (one line each); more are only counted."""

FT_PROTOCOLS = ("rdt", "robotiq", "bota")
TACTILE_PROTOCOLS = ("dsacon32", "m1616")


@dataclass(frozen=True)
class RigParams:
    scene: str = field(default="default", metadata={"help": "scene file: a path or a shipped name (fig10, ...)"})
    ft_protocol: str = field(default="rdt", metadata={"help": f"F/T emulator: one of {FT_PROTOCOLS}"})
    rdt_port: int = field(default=49152, metadata={"help": "UDP port of the RDT emulator"})
    rdt_host: str = field(default="127.0.0.1", metadata={
        "help": "address the RDT emulator binds; sim:HOST: the simulated device table instead (lock-step runs)"})
    ft_link: str = field(default="", metadata={
        "help": "pty symlink path for a serial F/T emulator; sim:PATH: the simulated device table (lock-step runs)"})
    tactile_protocol: str = field(default="dsacon32", metadata={"help": f"tactile emulator: one of {TACTILE_PROTOCOLS}"})
    tactile_link: str = field(default="", metadata={
        "help": "pty symlink path for the tactile emulator; sim:PATH: the simulated device table (lock-step runs)"})
    calibration_out: str = field(default="", metadata={"help": "write the tactile calibration TOML here"})
    tactile: bool = field(default=True, metadata={
        "help": "serve the scene's tactile sensor; false: no tactile device (an F/T-only run of a scene with a pad)"})
    contact_material: str = field(default="", metadata={
        "help": "make the scene's contact of this rig material (rubber, coulomb, weakening); empty: the scene's"})
    ft_rate_hz: float = field(default=0.0, metadata={"help": "F/T sample rate (Hz); 0: the scene's"})
    tactile_rate_hz: float = field(default=0.0, metadata={"help": "tactile frame rate (Hz); 0: the scene's"})
    truth_rate_hz: float = field(default=0.0, metadata={"help": "rig/truth rate (Hz); 0: the scene's"})
    tick_ms: float = field(default=1.0, metadata={"help": "real-time step of the rig node (ms)"})
    wait_for_drivers_s: float = field(default=30.0, metadata={
        "help": "the scene starts when every emulated sensor is streaming to a driver, or after this long (s)"})
    run_s: float = field(default=0.0, metadata={
        "help": "how long the rig runs from the scene's start (s): 0: until the scene ends; longer: the world goes "
                "on after the scene, holding its last load; inf: until stopped (interactive use)"})
    command_timeout_ms: float = field(default=100.0, metadata={
        "help": "finger watchdog: no grip/command for this long after the first one -> hold and raise (ms); 0: off"})
    watchdog_grip_n: float = field(default=0.0, metadata={
        "help": "the watchdog raises the command towards this safe grip (N); 0: it only holds"})
    watchdog_rise_n_per_s: float = field(default=10.0, metadata={"help": "the watchdog's raise rate (N/s)"})
    finger1_rdt_port: int = field(default=0, metadata={
        "help": "a gripper scene: UDP port of finger 1's RDT emulator (its own F/T stream; the same host)"})
    finger1_ft_link: str = field(default="", metadata={
        "help": "a gripper scene: pty link of finger 1's serial F/T emulator; sim:PATH in lock-step runs"})
    finger1_tactile_link: str = field(default="", metadata={
        "help": "a gripper scene: pty link of finger 1's tactile emulator; sim:PATH in lock-step runs"})
    gripper: bool = field(default=False, metadata={
        "help": "a gripper scene: serve an emulated WSG 50 at gripper_address and squeeze as it is told; "
                "false: the squeeze follows grip/command"})
    gripper_address: str = field(default="127.0.0.1:1000", metadata={
        "help": "TCP HOST:PORT of the emulated gripper (sim:HOST:PORT: the simulated device table, lock-step runs)"})
    part_width_mm: float = field(default=20.0, metadata={"help": "the emulated gripper finds the part at this width (mm)"})
    grip_state_rate_hz: float = field(default=100.0, metadata={
        "help": "rate of the finger's report on grip/state (Hz; and at once when its mode changes)"})


class Rig(Node):
    """The simulated rig: plant, sensors and device emulators."""

    name = "rig"
    inputs = {"grip": Input("grip/command", GripCommand)}
    outputs = {"truth": Output("rig/truth", RigTruth), "grasp": Output("rig/grasp", GraspTruth),
               "finger": Output("grip/state", GripState)}
    Params = RigParams
    precise_timers = True  # sensor samples leave on the simulated tick, not up to 1 ms late

    def __init__(self, params: RigParams | None = None) -> None:
        super().__init__(params)
        p = self.params
        if p.ft_protocol not in FT_PROTOCOLS:
            raise ConfigError(f"rig ft_protocol must be one of {FT_PROTOCOLS}, got {p.ft_protocol!r}")
        if p.tactile_protocol not in TACTILE_PROTOCOLS:
            raise ConfigError(f"rig tactile_protocol must be one of {TACTILE_PROTOCOLS}, got {p.tactile_protocol!r}")
        scene = load_scene_by_name(p.scene)
        if p.contact_material:
            scene = with_rig_material(scene, p.contact_material)
        self.scene = with_rates(scene, p.ft_rate_hz, p.tactile_rate_hz, p.truth_rate_hz)
        self.timers = {"tick": p.tick_ms / 1e3}
        self.sim: Simulator | None = None
        self.ft_devs: list = []  # per finger
        self.tactile_devs: list = []
        self.gripper: WsgEmulator | None = None
        if p.gripper:
            if self.scene.fingers != 2:
                raise ConfigError(f"rig: gripper = true needs a gripper scene ([gripper]); {self.scene.name} has one finger")
            self.inputs = {}  # the squeeze comes from the emulated gripper, not from grip/command
        self._powered_ns = 0
        self._t0: int | None = None
        self.late_ticks = LateTicks(round(p.tick_ms * 1e6), _LATE_TICK_MS * _NS_PER_MS,
                                    _LATE_REPORT_EVERY_S * 1000 * _NS_PER_MS)
        if not p.grip_state_rate_hz > 0:
            raise ConfigError(f"rig grip_state_rate_hz must be > 0 Hz, got {p.grip_state_rate_hz!r}")
        self._state_period_ns = round(1e9 / p.grip_state_rate_hz)
        self._next_state_ns = 0
        self._finger_mode = "initial"
        self._commanded_by = ""
        self._named_senders: set[str] = set()
        try:
            self.watchdog = CommandWatchdog(round(p.command_timeout_ms * 1e6), p.watchdog_grip_n,
                                            p.watchdog_rise_n_per_s)
        except ValueError as exc:
            raise ConfigError(f"rig: {exc}") from None

    def start(self, ctx: Context) -> None:
        p, scene = self.params, self.scene
        compile_rig_kernels()  # loaded before the scene starts, not on its first slip or re-shape
        compile_crc_kernels()  # the device emulators frame CRCs from the first sample on
        self.sim = Simulator(scene)
        devices = [(p.rdt_port, p.ft_link, p.tactile_link, "")]
        if scene.fingers == 2:
            devices.append((p.finger1_rdt_port, p.finger1_ft_link, p.finger1_tactile_link, "finger1_"))
        if scene.ft.enabled:
            self.ft_devs = [self._ft_device(port, link, prefix) for port, link, _, prefix in devices]
        if p.gripper:
            self.gripper = WsgEmulator(p.gripper_address, part_width_mm=p.part_width_mm)
        if scene.tactile.enabled and p.tactile:
            self.tactile_devs = [self._tactile_device(link, prefix) for _, _, link, prefix in devices]
            if p.calibration_out:
                pressure, counts = self.sim.tactile.calibration_table()
                save_calibration(Calibration(counts=counts, pressure_pa=pressure,
                                             saturation_counts=scene.tactile.full_scale_counts),
                                 p.calibration_out)
        self._powered_ns = ctx.now_ns()
        ctx.log(f"scene {scene.name}: {scene.description} ({scene.duration_s:g} s, free dof {list(scene.dof.free)})")

    def _ft_device(self, port: int, link: str, prefix: str):
        """One finger's F/T emulator (``prefix`` names its parameters: "" for finger 0)."""
        p, scene = self.params, self.scene
        if p.ft_protocol == "rdt":
            if port <= 0:
                raise ConfigError(f"rig: set {prefix}rdt_port (the UDP port of that finger's RDT emulator)")
            host = p.rdt_host
            return RdtSimServer(host[len(SIM_PREFIX):], port) if is_simulated(host) else RdtUdpServer(host, port)
        link = self._link(link, f"{prefix}ft_link")
        if p.ft_protocol == "robotiq":
            return RobotiqEmulator(link, streaming=False)
        return BotaEmulator(link, streaming=False, rate_hz=scene.ft.rate_hz)

    def _tactile_device(self, link: str, prefix: str):
        """One finger's tactile emulator."""
        pad = self.scene.pad
        link = self._link(link, f"{prefix}tactile_link")
        if self.params.tactile_protocol == "dsacon32":
            return Dsacon32Emulator(link, rows=pad.rows, cols=pad.cols, texel_size_m=pad.pitch_m)
        return M1616Emulator(link)

    @staticmethod
    def _link(path: str, name: str) -> str:
        if not path:
            raise ConfigError(f"rig: set {name} (where the emulator's pseudo-terminal link goes)")
        return path

    def on_grip(self, msg: GripCommand, ctx: Context) -> None:
        if self._t0 is None:
            return
        if not self.sim.command_normal_force(msg.f_n_desired):
            ctx.count("rig.rejected_commands")
            return
        self.watchdog.commanded(ctx.now_ns())
        if ctx.sender:
            self._manual_command(msg, ctx)
        if ctx.sender != self._commanded_by:  # a manual command is reported with its sender at once
            self._commanded_by = ctx.sender
            self._next_state_ns = 0
        self._set_finger_mode("following", ctx)
        self._report_finger(ctx)

    def _manual_command(self, msg: GripCommand, ctx: Context) -> None:
        """A command a tool injected (the launch allows it): counted, and its sender named once."""
        ctx.count("rig.manual_commands")
        if ctx.sender not in self._named_senders and len(self._named_senders) < _MAX_NAMED_SENDERS:
            self._named_senders.add(ctx.sender)
            ctx.log(f"manual grip/command from {ctx.sender}: {msg.f_n_desired:.2f} N (injected by a tool; "
                    f"the launch file allows it in [launch] allow_inject)")

    def _set_finger_mode(self, mode: str, ctx: Context) -> None:
        if mode != self._finger_mode:
            self._finger_mode = mode
            self._next_state_ns = 0  # a change is reported at once

    def _report_finger(self, ctx: Context) -> None:
        """``grip/state`` when due: the force the finger holds to, its mode and who commanded it."""
        now = ctx.now_ns()
        if now < self._next_state_ns:
            return
        self._next_state_ns = now + self._state_period_ns
        sender = "".join(c if c.isalnum() or c in "_.+-" else "_" for c in self._commanded_by)[:64]
        ctx.publish("finger", GripState(f_n_command=min(self.sim.normal_force_command, MAX_GRIP_FORCE_N),
                                        mode=self._finger_mode, commanded_by=sender), stamp_ns=now)

    def _guard_finger(self, ctx: Context) -> None:
        """The finger's command watchdog: hold, or raise towards the safe grip, without commands."""
        was_expired = self.watchdog.expired
        command = self.watchdog.step(ctx.now_ns(), self.sim.normal_force_command)
        if command is not None:
            self.sim.command_normal_force(command)
            ctx.count("rig.watchdog_ticks")
            self._set_finger_mode("watchdog", ctx)
            if not was_expired:
                ctx.log(f"finger watchdog: no grip/command for {self.params.command_timeout_ms:g} ms; "
                        f"holding {command:.2f} N" + (f", raising towards {self.watchdog.safe_grip_n:g} N"
                                                      if self.watchdog.safe_grip_n > command else ""))
                ctx.set_status("watchdog", "no grip/command: the finger holds its grip")
        elif was_expired:
            ctx.set_status("ok")

    def _tell_if_late(self, ctx: Context) -> None:
        """Count a tick that came late (its process waited for a core) and say so, rate-limited."""
        now = ctx.now_ns()
        if self.late_ticks.tick(now):
            ctx.count("rig.late_ticks")
        report = self.late_ticks.report(now, self._t0, runs_realtime())
        if report is not None:
            ctx.report_error(report)

    def _devices(self) -> list:
        return [*self.ft_devs, *self.tactile_devs]

    def _sensors_streaming(self) -> bool:
        """Every emulated sensor has been started by its driver (M1616 pushes unasked), and the
        emulated gripper holds the part."""
        held = self.gripper is None or (self.gripper.holding and self.gripper.stream_period_ns > 0)
        return held and all(getattr(d, "acquiring", getattr(d, "streaming", True)) for d in self._devices())

    def _serve_gripper(self, ctx: Context) -> None:
        """The emulated gripper answers its driver and streams the squeeze; the fingers squeeze as it says."""
        gripper, sim = self.gripper, self.sim
        gripper.tick(ctx.now_ns(), sim.normal_force_applied if self._t0 is not None else 0.0)
        if self._t0 is not None and gripper.squeeze_n != sim.normal_force_command:
            sim.command_normal_force(gripper.squeeze_n)

    def on_timer_tick(self, ctx: Context) -> None:
        sim = self.sim
        for dev in self._devices():
            dev.service()
        if self.gripper is not None:
            self._serve_gripper(ctx)
        self._report_finger(ctx)
        if self._t0 is None:  # the experiment starts once the drivers read the sensors
            waited = (ctx.now_ns() - self._powered_ns) / 1e9
            if not self._sensors_streaming() and waited < self.params.wait_for_drivers_s:
                return
            if waited >= self.params.wait_for_drivers_s:
                ctx.log(f"warning: sensors not streaming after {waited:.0f} s; starting the scene anyway")
            self._t0 = ctx.now_ns()
            ctx.log(f"sensors streaming; scene {self.scene.name} starts")
        self._tell_if_late(ctx)
        if self.gripper is None:
            self._guard_finger(ctx)
        for sample in sim.step_until(ctx.now_ns() - self._t0):
            if isinstance(sample, FtSample):
                if self.ft_devs and not self.ft_devs[sample.finger].send_ft(sample.force_n, sample.torque_nm):
                    ctx.count("rig.ft_not_sent")
            elif isinstance(sample, TactileSample):
                if self.tactile_devs and not self.tactile_devs[sample.finger].send_tactile(sample.counts):
                    ctx.count("rig.tactile_not_sent")
            else:
                stamp = self._t0 + sample.stamp_ns
                ctx.publish("truth", truth_message(sample), stamp_ns=stamp)
                if sample.finger_loads:
                    ctx.publish("grasp", grasp_truth_message(sample, self.params.scene), stamp_ns=stamp)
        if sim.done and (ctx.now_ns() - self._t0) / 1e9 >= self.params.run_s:
            ctx.log(f"scene {self.scene.name} finished")
            ctx.shutdown()

    def stop(self, ctx: Context) -> None:
        for dev in self._devices():
            dev.close()
        if self.gripper is not None:
            self.gripper.close()


def load_scene_by_name(name: str) -> Scene:
    """A shipped scene (``fig10``) or a scene file path (relative to the current directory)."""
    return load_scene(resolve_path(name, Path.cwd(), "scenes"))


def with_rates(scene: Scene, ft_hz: float = 0.0, tactile_hz: float = 0.0, truth_hz: float = 0.0) -> Scene:
    """``scene`` with its sensor and truth rates (Hz) replaced where the value is > 0.

    Raises:
        ConfigError: a rate above :data:`~slipstack.lib.samples.MAX_SAMPLE_RATE_HZ`, or not a number.
    """
    for name, hz in (("ft_rate_hz", ft_hz), ("tactile_rate_hz", tactile_hz), ("truth_rate_hz", truth_hz)):
        if not 0.0 <= hz <= MAX_SAMPLE_RATE_HZ:
            raise ConfigError(f"rig {name} must be 0 (the scene's) up to {MAX_SAMPLE_RATE_HZ:g} Hz, got {hz:g}")
    if ft_hz > 0:
        scene = replace(scene, ft=replace(scene.ft, rate_hz=ft_hz))
    if tactile_hz > 0:
        scene = replace(scene, tactile=replace(scene.tactile, rate_hz=tactile_hz))
    if truth_hz > 0:
        scene = replace(scene, sim=replace(scene.sim, truth_rate_hz=truth_hz))
    return scene


def truth_message(t: Truth) -> RigTruth:
    """The ``rig/truth`` message of one :class:`Truth` sample."""
    return RigTruth(
        x=t.x, y=t.y, theta=t.theta, vx=t.vx, vy=t.vy, omega=t.omega, gross_slip=bool(t.gross_slip),
        cor=np.array(t.cor if t.cor is not None else (0.0, 0.0), dtype=float), cor_valid=t.cor is not None,
        slip_distance_m=t.slip_distance_m, slip_angle_rad=t.slip_angle_rad, f_n_applied=t.f_n_applied,
        f_n_command=t.f_n_command, sliding_fraction=t.slip_fraction,
        load_f_t=np.array(t.load_force, dtype=float), load_tau=t.load_torque,
    )


def grasp_truth_message(t: Truth, scene: str) -> GraspTruth:
    """The ``rig/grasp`` message of a gripper's :class:`Truth` sample (its per-finger loads) of ``scene``."""
    loads = np.array(t.finger_loads, dtype=float)
    return GraspTruth(f_x=loads[:, 0].copy(), f_y=loads[:, 1].copy(), tau=loads[:, 2].copy(),
                      weight=np.array(t.weight, dtype=float), mass_kg=t.mass_kg, scene=scene)
