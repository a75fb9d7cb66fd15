"""Faults on the stack as users run it, one row per trial: did the object stay, did the grip fall?

Every trial launches Fig. 15 in real time with its default arguments (recorder and check
on) in each user configuration, ``one`` machine (``slipstack launch fig15``) and ``two``
(``slipstack launch two_hosts --machine robot`` and ``--machine workstation``, each with
its own run root and key directory, on 127.0.0.1 and 127.0.0.2), applies one fault of
issue 29 while the disturbance pulls, and reads the run's recording and log:

More in docs/modules.md, `tests/bench/bench_chaos.py`.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import random
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import zmq

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _versions import print_versions  # noqa: E402
from _stack import StackRun, free_udp_port, long_scene, pid_alive  # noqa: E402

from slipstack.lib.protocols import ati_rdt  # noqa: E402
from slipstack.messages import Header, Slip, Wrench, decode, encode  # noqa: E402
from slipstack.nodes.recording.bag_io import read_recording  # noqa: E402

FAULT_AT_S = 4.5  # into the scene: fig15's step to 1.8 N, the grip near its highest
LOWERED_BY_N = 0.2  # the law itself moved the grip by at most 0.1 N over these windows on valid data
RECOVERY_CAP_NS = 3_000_000_000


# -- the configurations ------------------------------------------------------------------------
@dataclass
class Stack:
    """A launched configuration: its launchers (the last runs control, monitor and recorder)."""

    config: str
    runs: list[StackRun]
    recording: Path
    summary: Path
    rdt_port: int
    started_ns: int = 0

    @property
    def control(self) -> StackRun:
        return self.runs[-1]

    def graph(self, run: StackRun | None = None) -> dict:
        return json.loads(((run or self.control).run_root / "current" / "graph.json").read_text())

    def pid(self, node: str) -> int | None:
        """The live process of ``node`` on whichever machine runs it."""
        for run in self.runs:
            pid = self.graph(run)["nodes"].get(node, {}).get("pid")
            if pid and pid_alive(pid):
                return pid
        return None

    def cli(self, *args: str, timeout: float = 60.0) -> subprocess.CompletedProcess:
        """``slipstack ARGS`` against the graph, from the machine of the control path."""
        return subprocess.run([sys.executable, "-m", "slipstack.launch.cli", *args], env=self.control.env,
                              capture_output=True, text=True, timeout=timeout)

    def wait_end(self, timeout_s: float = 120.0) -> None:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end and any(r.running() for r in self.runs):
            time.sleep(0.2)

    def stop(self) -> None:
        for run in self.runs:
            run.stop()


def launch_config(config: str, tmp: Path, extra: list[str] = ()) -> Stack:
    """Fig. 15 with its default arguments in ``config`` (``one`` or ``two`` machines); the recording,
    the JSON summary and the F/T emulator's port are placed so the bench can read and reach them."""
    recording, summary, port = tmp / "run.mcap", tmp / "summary.json", free_udp_port()
    common = [f"recording:={recording}", f"summary:={summary}", f"rdt_port:={port}", *extra]
    roots = []
    for name in ("robot", "workstation") if config == "two" else ("one",):
        (tmp / name).mkdir(mode=0o700)
        roots.append(tmp / name)
    if config == "one":
        runs = [StackRun(["fig15", *common], run_root=roots[0])]
    else:
        keys = tmp / "keys"
        subprocess.run([sys.executable, "-m", "slipstack.launch.cli", "keys", str(keys), "--machine", "robot",
                        "--machine", "workstation"], check=True, capture_output=True, timeout=60)
        first = random.randrange(20000, 32000, 100)
        args = ["two_hosts", f"keys:={keys}", f"first_port:={first}", f"last_port:={first + 99}", *common]
        runs = [StackRun([*args, "--machine", m], run_root=r) for m, r in zip(("robot", "workstation"), roots)]
    stack = Stack(config, runs, recording, summary, port)
    try:
        for run in runs:
            run.wait_running(timeout_s=120)
    except RuntimeError:
        stack.stop()
        raise
    stack.started_ns = time.monotonic_ns()
    return stack


# -- the trials: each applies its fault and returns (start, end) in monotonic ns -------------
def _at_fault_time(stack: Stack) -> int:
    """Sleep until the fault's time in the scene (counted from the graph's start); now, ns."""
    time.sleep(max(0.0, FAULT_AT_S - (time.monotonic_ns() - stack.started_ns) / 1e9))
    return time.monotonic_ns()


def _kill_control(stack: Stack) -> None:
    pid = stack.pid("grip_controller")
    os.kill(pid, signal.SIGKILL)
    end = time.monotonic() + 30
    while time.monotonic() < end and stack.pid("grip_controller") in (None, pid):
        time.sleep(0.01)


def trial_launch(stack: Stack) -> tuple[int, int]:
    """Item 10: no fault; the launch itself, judged from its first command on."""
    return stack.started_ns, stack.started_ns


def trial_restart(stack: Stack) -> tuple[int, int]:
    """Item 2: the control container killed on valid data and respawned."""
    t0 = _at_fault_time(stack)
    _kill_control(stack)
    return t0, time.monotonic_ns()


def trial_bias_then_crash(stack: Stack) -> tuple[int, int]:
    """Item 2: one RDT BIAS datagram (the F/T reads ~0 from then on), then the control container killed."""
    t0 = _at_fault_time(stack)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
        udp.sendto(ati_rdt.encode_request(ati_rdt.Command.BIAS), ("127.0.0.1", stack.rdt_port))
    time.sleep(0.1)
    _kill_control(stack)
    return t0, time.monotonic_ns()


def trial_inject_grip_command(stack: Stack) -> tuple[int, int]:
    """Item 8: ``topic pub grip/command`` 2 N for 1 s (refused), then the same frames written to the
    finger's injection endpoint by hand (the rig has none)."""
    t0 = _at_fault_time(stack)
    pub = stack.cli("topic", "pub", "grip/command", "{f_n_desired: 2.0, law: manual}", "--rate", "50",
                    "--times", "50")
    print(f"    topic pub grip/command: exit {pub.returncode}: {pub.stderr.strip()[:100]}", flush=True)
    return t0, time.monotonic_ns()


def _write_raw(endpoints: set[str], topic: bytes, frames: Callable[[int], bytes], seconds: float,
               period_s: float) -> None:
    """Frames ``frames(k)`` on ``topic`` every ``period_s`` for ``seconds``, written straight to
    injection ``endpoints`` by a local process (no tool, no registration)."""
    ctx = zmq.Context()
    try:
        sock = ctx.socket(zmq.PUB)
        for endpoint in endpoints:
            sock.connect(endpoint)
        time.sleep(0.2)
        end, k = time.monotonic() + seconds, 0
        while time.monotonic() < end:
            sock.send_multipart([topic, frames(k), b"intruder"])
            k += 1
            time.sleep(period_s)
    finally:
        ctx.destroy(linger=0)


def _stamped(k: int) -> Header:
    now = time.monotonic_ns()
    return Header(now, k, now, {})


def trial_inject_slip(stack: Stack) -> tuple[int, int]:
    """Item 8: forged "ok, no load" slip verdicts written to the controller's injection endpoint, 1 s."""
    t0 = _at_fault_time(stack)
    _write_raw(set(stack.graph()["nodes"]["grip_controller"]["inject"].values()), b"slip",
               lambda k: encode(Slip(status="ok", state="stick", method="exact", gamma=0.0, margin=1.0, f_n=0.5,
                                     header=_stamped(k))), 1.0, 0.001)
    return t0, time.monotonic_ns()


def trial_full_disk(stack: Stack) -> tuple[int, int]:
    """Item 3: the launch's run log on a full file system (set up by ``launch_config``'s
    caller: see ``TRIALS``); the fault is the disk filling while the scene runs."""
    t0 = _at_fault_time(stack)
    filler = stack.recording.parent / "disk" / "filler"
    try:
        with open(filler, "wb") as fh:
            while True:
                fh.write(b"\0" * 65536)
    except OSError:
        pass  # full
    return t0, time.monotonic_ns()


def trial_heavy_frames(stack: Stack) -> tuple[int, int]:
    """Item 4: 70 KB wrench frames (8000 header sources) at 500 Hz for 3 s into fusion."""
    t0 = _at_fault_time(stack)
    sources = {f"s{i}": i for i in range(8000)}
    _write_raw({stack.graph()["nodes"]["fusion"]["inject"]["ft/wrench"]}, b"ft/wrench",
               lambda k: encode(Wrench(force=np.array([0.0, 0.0, -14.0]), torque=np.zeros(3),
                                       header=Header(time.monotonic_ns(), k, time.monotonic_ns(), sources))),
               3.0, 0.002)
    return t0, time.monotonic_ns()


def trial_killed_monitor(stack: Stack) -> tuple[int, int]:
    """Item 6: the monitor SIGKILLed; the summary must still come."""
    t0 = _at_fault_time(stack)
    os.kill(stack.pid("monitor"), signal.SIGKILL)
    return t0, time.monotonic_ns()


def trial_forged_rdt(stack: Stack) -> tuple[int, int]:
    """Item 7: 2 s of garbage and forged RDT datagrams to the F/T sensor's port; the
    summary must name the attack."""
    t0 = _at_fault_time(stack)
    rng = np.random.default_rng(7)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            udp.sendto(rng.bytes(36), ("127.0.0.1", stack.rdt_port))
            time.sleep(0.001)
    return t0, time.monotonic_ns()


@dataclass(frozen=True)
class Trial:
    run: Callable[[Stack], tuple[int, int]]
    item: str
    configs: tuple[str, ...] = ("one", "two")


TRIALS = {
    "launch": Trial(trial_launch, "10"),
    "restart": Trial(trial_restart, "2"),
    "bias_then_crash": Trial(trial_bias_then_crash, "2"),
    "inject_grip_command": Trial(trial_inject_grip_command, "8"),
    "inject_slip": Trial(trial_inject_slip, "8"),
    "full_disk": Trial(trial_full_disk, "3"),
    "heavy_frames": Trial(trial_heavy_frames, "4"),
    "killed_monitor": Trial(trial_killed_monitor, "6"),
    "forged_rdt": Trial(trial_forged_rdt, "7"),
}


# -- what a row says ---------------------------------------------------------------------------
@dataclass
class Row:
    config: str
    trial: str
    item: str
    slid_mm: float = float("nan")
    turned_deg: float = float("nan")
    before_n: float = float("nan")
    lowest_n: float = float("nan")
    summary: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def lowered(self) -> bool:
        return not self.lowest_n >= self.before_n - LOWERED_BY_N

    @property
    def held(self) -> bool:
        return self.slid_mm < 0.005 and self.turned_deg < 0.005 and not self.lowered


def measure(row: Row, stack: Stack, fault: tuple[int, int]) -> Row:
    """Fill ``row`` from the recording (truth, finger, commands) and the control machine's log."""
    t0, t1 = fault
    frames = {"rig/truth": [], "grip/state": [], "grip/command": []}
    for f in read_recording(stack.recording, list(frames)):
        frames[f.topic].append(decode(f.payload))
    truth, commands = frames["rig/truth"], frames["grip/command"]
    # the finger's reports; on a build without them (a baseline), the rig's truth says the same
    finger = [(s.header.stamp_ns, s.f_n_command) for s in frames["grip/state"] or truth]
    if truth:
        row.slid_mm = max(t.slip_distance_m for t in truth) * 1e3
        row.turned_deg = float(np.degrees(max(abs(t.slip_angle_rad) for t in truth)))
    back = next((c.header.pub_ns for c in commands if c.header.pub_ns > t1 and c.reason != "fail-safe"), None)
    if t0 == t1 == stack.started_ns:  # the launch: from the finger's own grip to its first valid command
        row.before_n = finger[0][1] if finger else float("nan")
        t0 = commands[0].header.pub_ns if commands else t0
    else:
        prior = [f for stamp, f in finger if stamp < t0]
        row.before_n = prior[-1] if prior else float("nan")
    end = min(back if back is not None else t1 + RECOVERY_CAP_NS, t1 + RECOVERY_CAP_NS)
    # the finger reports at 100 Hz: a fault the control path rides through can end between two reports
    window = [f for stamp, f in finger if t0 <= stamp <= end] or [f for stamp, f in finger if stamp >= t0][:1]
    row.lowest_n = min(window) if window else float("nan")
    log = stack.control.log()
    health = next((line for line in log.splitlines() if "HEALTH:" in line), "no summary")
    check = next((line for line in log.splitlines() if "check passed" in line or "CHECK FAILED" in line), "")
    row.summary = f"{health.split('HEALTH:', 1)[-1].strip()[:70]} | {check.replace('[launch] ', '')[:60]}"
    return row


def run_trial(name: str, config: str) -> Row:
    trial = TRIALS[name]
    row = Row(config, name, trial.item)
    with tempfile.TemporaryDirectory(prefix="ssc-", dir="/tmp") as tmp:
        tmp = Path(tmp)
        extra: list[str] = []
        if name == "full_disk":  # the recording and the run's log on a 4 MiB file system
            disk = tmp / "disk"
            disk.mkdir()
            subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4m", "tmpfs", str(disk)], check=True)
            extra = [f"--log-file={disk / 'run.log'}"]
        stack = None
        try:
            stack = launch_config(config, tmp, extra)
            fault = trial.run(stack)
            stack.wait_end()
            measure(row, stack, fault)
        except Exception as exc:  # a trial that breaks the stack, or a stack that does not start, is a row too
            row.notes.append(f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"[:200])
        finally:
            if stack is not None:
                stack.stop()
            if name == "full_disk":
                subprocess.run(["umount", str(tmp / "disk")], check=False)
    return row


# -- the older kill series (respawn and recovery times) ------------------------------------------
def _hog() -> None:
    while True:
        pass


def kill_series(args: argparse.Namespace) -> int:
    """SIGKILL the tactile driver, the F/T driver and the control container in turn, every
    ``--every`` s of a ``--duration`` s fig15 on one machine: respawn, recovery to a valid
    command, the grip before and the lowest until then, the slip added."""
    targets = {"tactile_driver": "tactile_driver", "ft_driver": "ft_driver", "control": "grip_controller"}
    with tempfile.TemporaryDirectory(prefix="ssc-", dir="/tmp") as tmp:
        tmp = Path(tmp)
        scene = long_scene("fig15", args.duration, tmp / "scene.toml")
        (tmp / "root").mkdir(mode=0o700)
        rec = tmp / "chaos.mcap"
        with StackRun(["fig15", f"scene:={scene}", f"recording:={rec}", f"rdt_port:={free_udp_port()}"],
                      run_root=tmp / "root") as run:
            run.wait_running()
            graph_path = run.run_root / "current" / "graph.json"
            kills = []
            order = list(targets.items())
            for i in range(int((args.duration - 4.0) // args.every)):
                time.sleep(args.every)
                label, node = order[i % len(order)]
                old = json.loads(graph_path.read_text())["nodes"][node].get("pid")
                if not old or not pid_alive(old):
                    continue
                kill_ns = time.monotonic_ns()
                os.kill(old, signal.SIGKILL)
                back = None
                end = time.monotonic() + 30
                while back is None and time.monotonic() < end:
                    pid = json.loads(graph_path.read_text())["nodes"][node].get("pid")
                    back = time.monotonic_ns() if pid and pid != old and pid_alive(pid) else None
                    time.sleep(0.005)
                kills.append({"process": label, "kill_ns": kill_ns, "return_ns": back,
                              "respawn_ms": (back - kill_ns) / 1e6 if back else float("nan")})
            while run.running():
                time.sleep(0.2)
        cmds = [decode(f.payload) for f in read_recording(rec, ["grip/command"])]
        truth = [decode(f.payload) for f in read_recording(rec, ["rig/truth"])]
    print(f"{'process':<16}{'respawn ms':>12}{'recovery ms':>13}{'grip before N':>15}{'lowest N':>10}{'slip mm':>9}")
    for k in kills:
        back = k["return_ns"]
        valid = next((c for c in cmds if back and c.header.pub_ns >= back and c.reason != "fail-safe"), None)
        recovery = (valid.header.pub_ns - back) / 1e6 if valid else float("nan")
        window_end = valid.header.pub_ns if valid else k["kill_ns"] + 2_000_000_000
        before = [c.f_n_desired for c in cmds if c.header.pub_ns < k["kill_ns"]]
        window = [c.f_n_desired for c in cmds if k["kill_ns"] <= c.header.pub_ns <= window_end]
        slid = [t.slip_distance_m for t in truth if k["kill_ns"] <= t.header.stamp_ns <= window_end + 500_000_000]
        nan = float("nan")
        print(f"{k['process']:<16}{k['respawn_ms']:>12.0f}{recovery:>13.0f}{before[-1] if before else nan:>15.2f}"
              f"{min(window) if window else nan:>10.2f}{(slid[-1] - slid[0]) * 1e3 if len(slid) > 1 else 0:>9.3f}")
    for label in targets:
        resp = [k["respawn_ms"] for k in kills if k["process"] == label]
        if resp:
            print(f"{label}: median respawn {statistics.median(resp):.0f} ms over {len(resp)} kills")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trial", action="append", choices=sorted(TRIALS), help="run only these (repeatable)")
    ap.add_argument("--config", action="append", choices=("one", "two"), help="only these configurations")
    ap.add_argument("--hogs", type=int, default=0, help="busy-loop processes beside the stack")
    ap.add_argument("--kill-series", action="store_true", help="the older series of kills instead (one machine)")
    ap.add_argument("--duration", type=float, default=24.0, help="--kill-series: scene length, s")
    ap.add_argument("--every", type=float, default=3.0, help="--kill-series: seconds between kills")
    args = ap.parse_args()
    print_versions()

    hogs = [multiprocessing.Process(target=_hog, daemon=True) for _ in range(args.hogs)]
    for h in hogs:
        h.start()
    try:
        if args.kill_series:
            return kill_series(args)
        names = args.trial or list(TRIALS)
        rows = []
        for name in names:
            for config in args.config or TRIALS[name].configs:
                print(f"{config} machine(s), {name} ...", flush=True)
                rows.append(run_trial(name, config))
    finally:
        for h in hogs:
            h.terminate()
    print(f"\nfig15, default arguments; load average {' '.join(f'{x:.1f}' for x in os.getloadavg())}, "
          f"{args.hogs} CPU hogs\n")
    print("| config | trial (item) | slid mm | turned deg | grip before N | lowest after N | held | summary |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        notes = " " + "; ".join(r.notes) if r.notes else ""
        print(f"| {r.config} | {r.trial} ({r.item}) | {r.slid_mm:.2f} | {r.turned_deg:.2f} | {r.before_n:.2f} | "
              f"{r.lowest_n:.2f} | {'yes' if r.held else 'NO'} | {r.summary}{notes} |")
    return 0 if all(r.held for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
