"""``slipstack launch``: start a graph of node processes and supervise it.

More in docs/modules.md, `launch/launcher.py`.
"""

from __future__ import annotations

import json
import os
import selectors
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import msgpack
import zmq

from slipstack.lib.errors import ConfigError, SlipstackError
from slipstack.messages import Diagnostics
from slipstack.launch.launch_file import LaunchFile
from slipstack.launch.clock_report import REPORT_PERIOD_S, ClockReport, launcher_node
from slipstack.launch.inject_relay import InjectionRelay
from slipstack.launch.peers import PeerLinks, launcher_endpoint
from slipstack.launch.priority import (
    grant_realtime_priority, has_realtime_priority, set_autogroup_nice,
)
from slipstack.launch.plan import (PEER_WAIT_S, NodePlan, ProcessPlan, launcher_pub_endpoints, machine_endpoints,
                                   plan_launch, relay_endpoint, remote_sources, runs_on)
from slipstack.launch.run_node import set_parent_death_signal
from slipstack.launch.quiet_shutdown import WorldEndFilter, WorldLogLevels
from slipstack.launch.run_log import RunLog
from slipstack.nodes.monitor import write_json_atomically
from slipstack.nodes.recording.loss import NUMBERED_REPORT, RECORDING_REPORT, loss_text
from slipstack.nodes.runtime.logs import DETAIL_PREFIX, LOG_LEVEL_ENV
from slipstack.nodes.runtime.curve import INSECURE_ENV, KEYS_ENV, MACHINE_ENV, GraphKeys, machine_env, use_keys
from slipstack.nodes.runtime.graph_info import PARAM_REPLY, process_start_ticks, write_graph
from slipstack.nodes.runtime.host import DIAGNOSTICS_TOPIC
from slipstack.nodes.runtime.run_dir import finish_run_dir, write_private_file
from slipstack.nodes.runtime.remote_sources import REMOTE_SOURCES_ENV
from slipstack.nodes.runtime.time_base import CLOCK_OFFSET_ENV
from slipstack.nodes.runtime.transport import LISTEN_FDS_ENV, listening_socket

__all__ = ["Launcher", "run_lockstep", "monitor_check_problems"]

READY_TIMEOUT_S = 20.0
INTERRUPTED_EXIT = 130   # the launch stopped by Ctrl-C before its graph ran (as a shell's 128 + SIGINT)
STOP_GRACE_S = 0.4       # per node, after SIGINT, before the next node is told to stop
TERM_AFTER_S = 1.5       # from the start of shutdown: SIGTERM whoever is left
KILL_AFTER_S = 2.5       # from the start of shutdown: SIGKILL whoever is left
RESPAWN_PRIORITY = 1     # SCHED_FIFO of a restarting process until it is ready (where the launcher may set it)
FINISH_LIMIT_S = 60.0    # then the recorder and the monitor: time to write what they hold (docs/safety.md)
FINISH_NOTE_S = 3.0      # said on the terminal once it takes this long
STOP_REPORT_WAIT_S = 2.0  # after the graph stopped: how long its stop reports may still be on their way
CLOCK_EXCHANGES = 10     # ping exchanges with the first machine before its clock offset is used
DRIFT_CHECK_S = 5.0      # how often the clock offset in use is compared with a fresh estimate
EVENTS_FILE = "launch_events.json"
CHECK_FILE = "check.json"  # written by the monitor (its ``check_path``) when it stops
CHECK_FILE_MAX_BYTES = 1 << 20


@dataclass
class _Process(ProcessPlan):
    """One OS process of the plan and its state while the launch runs."""

    proc: subprocess.Popen | None = None
    restarts: int = 0
    """Restarts over the whole launch."""
    deaths: int = 0
    """Exits with a nonzero code or by a signal while the launch was running (not on shutdown)."""
    budget_used: int = 0
    """Restarts since the process last stayed up ``respawn_reset_s``."""
    abandoned: bool = False
    spawned_at: float = 0.0
    died_at: float | None = None
    """When a respawned process's predecessor exited (monotonic s), until all its nodes are ready again."""
    not_ready: set[str] = field(default_factory=set)
    respawn_at: float | None = None
    standby: subprocess.Popen | None = None
    """A process with the node's modules imported, waiting on stdin to start (respawn in a fraction of the time)."""
    buffer: bytes = b""
    realtime_refused_said: bool = False
    """The log has said that its ``realtime_priority`` was not granted (once per launch)."""
    restarting_for: str = ""
    """A parameter change it was stopped for (``slipstack param set``): restarted at once, not a death."""


class Console:
    """Prints log lines; on a terminal, ``STATUS`` lines are redrawn in place on one line.
    Detail lines (``detail: …``, the summary's long form) are left to the run's log file."""

    def __init__(self, stream=None) -> None:
        self.stream = stream or sys.stdout
        self.live = self.stream.isatty()
        self._status_shown = False

    def __call__(self, line: str) -> None:
        text = line.split("] ", 1)[-1]
        if text.startswith(DETAIL_PREFIX):  # for the run's log file only
            return
        is_status = text.startswith("STATUS ")
        if self.live and is_status:
            self.stream.write("\r\x1b[K" + line)
            self._status_shown = True
        else:
            if self._status_shown:
                self.stream.write("\r\x1b[K")
                self._status_shown = False
            self.stream.write(line + "\n")
        self.stream.flush()


class Launcher:
    """Run the graph of ``launch``; ``echo`` receives every log line."""

    def __init__(self, launch: LaunchFile, run_dir: Path, *, echo: Callable[[str], None] | None = None,
                 log_file: Path | None = None, machine: str | None = None) -> None:
        self.launch = launch
        self.echo = RunLog(echo or Console(), log_file)
        self.run_dir = run_dir
        self.machine = _check_machine(launch, machine)
        self.plan = plan_launch(launch, run_dir, self.machine)
        self.peers: PeerLinks | None = None
        self.relay: InjectionRelay | None = None
        """Injection from tools on other machines into this machine's nodes (with machines)."""
        self.clock_report: ClockReport | None = None
        """This launcher's clock offsets on ``diagnostics`` (with machines)."""
        self._next_clock_report = 0.0
        self.remote_sources = remote_sources(self.plan)
        """Topic → the other machines its data comes from, for the nodes that name them when it stops."""
        self.clock_offset_ns = 0
        """Added to this machine's monotonic clock by its nodes: the first machine's time base."""
        self._next_drift_check = 0.0
        self._drift_warned = False
        self.zctx = zmq.Context.instance()
        self.control_ep = self.plan.control_endpoint
        self.control = self.zctx.socket(zmq.PULL)
        self.control.setsockopt(zmq.LINGER, 0)
        self.control.bind(self.control_ep)
        self.selector = selectors.DefaultSelector()
        self.children: dict[str, NodePlan] = self.plan.nodes
        self.processes: dict[str, _Process] = {
            name: _Process(p.name, p.members, p.spec_path, p.spec) for name, p in self.plan.processes.items()}
        self.order: list[str] = self.plan.order  # process names, in start order
        self._stop_requested = False
        self._signals = 0
        self._starting: _Process | None = None
        """The process the start waits on: it may not handle SIGINT yet (a traceback from its imports)."""
        self._numbered: dict[str, dict[str, int]] = {}
        self._summary_gap = ""
        """What the run's summary misses (the monitor died and nothing was recorded); "" if nothing."""
        """Node → topic → frames it published, as its process stopped (its stop report)."""
        self.exit_code = 0
        self.error = ""
        """Why the launch failed to run (its start failed), if it did."""
        self.start_ticks = process_start_ticks(os.getpid())
        world = {n: tuple(p.node_names) for n, p in self.processes.items() if p.entry.stop_first}
        self._world_levels = WorldLogLevels(os.environ.get(LOG_LEVEL_ENV, ""), world)
        self._world_end = WorldEndFilter(set(world),
                                         {n for n, p in self.processes.items() if p.runs_device_driver})
        for proc in self.processes.values():
            write_private_file(self.run_dir, proc.spec_path.name, json.dumps(proc.spec, indent=1))
        self.held_ports: dict[str, socket.socket] = {}
        """tcp endpoint → the listening socket held for the node that binds it, the whole launch."""
        self._claim_tcp_ports()

    def _claim_tcp_ports(self) -> None:
        """Bind every tcp port this machine's nodes publish on before any starts, and hold it for the
        whole launch: a node's socket takes it over (nodes/runtime/transport.py: listening_socket), so
        a port stays claimed while its node restarts and nothing else can take it meanwhile."""
        fixed = set(machine_endpoints(self.launch).values())
        for c in self.processes.values():
            for member in c.members:
                for ep in {member.endpoint, member.remote_endpoint} - {None}:
                    if not ep.startswith("tcp://") or ep in self.held_ports:
                        continue
                    try:
                        self.held_ports[ep] = listening_socket(ep)
                    except OSError as exc:
                        self._release_ports()
                        where = (f"a port the launch file fixes ([machines.{member.entry.machine}] ports); stop that "
                                 "process (`ss -ltnp` shows who) or give the machine other ports, on every machine"
                                 if ep in fixed else "a free port a moment ago; stop that process (`ss -ltnp` shows "
                                 "who) or start the launch again, which picks another")
                        raise SlipstackError(f"node {member.entry.name} cannot have {ep} ({exc.strerror}): {where}") \
                            from None

    def _release_ports(self) -> None:
        for sock in self.held_ports.values():
            sock.close()
        self.held_ports.clear()

    def _listen_fds(self, c: _Process) -> dict[str, int]:
        """The held listening sockets of ``c``'s members: endpoint → descriptor (inherited by its process)."""
        return {ep: sock.fileno() for ep, sock in self.held_ports.items()
                if any(ep in (m.endpoint, m.remote_endpoint) for m in c.members)}

    # -- processes --------------------------------------------------------------------------
    def _spawn(self, c: _Process) -> None:
        """Start ``c``: wake its warm standby if it has one, else a new process."""
        standby, c.standby = c.standby, None
        c.proc = None
        if standby is not None and standby.poll() is None:
            try:
                standby.stdin.write(b"go\n")
                standby.stdin.close()
                c.proc = standby
            except OSError:  # it died just now
                standby.kill()
        if c.proc is None:
            c.proc = self._popen(c, standby=False)
        c.buffer = b""
        c.spawned_at = time.monotonic()

    def _prepare_standby(self, c: _Process) -> None:
        """Give a respawning process a warm standby: a process with its modules imported, waiting to start."""
        if c.entry.respawn and c.entry.respawn_standby and c.standby is None and not self._stop_requested:
            c.standby = self._popen(c, standby=True)

    def _dismiss_standby(self, c: _Process) -> None:
        """End ``c``'s standby: SIGKILL is clean for it, as it has opened and bound nothing yet."""
        standby, c.standby = c.standby, None
        if standby is None:
            return
        standby.kill()
        standby.stdin.close()
        standby.wait()

    def _popen(self, c: _Process, *, standby: bool) -> subprocess.Popen:
        node_type = "container" if c.is_container else c.entry.type
        cmd = [sys.executable, "-m", "slipstack.launch.run_node", node_type, "--spec", str(c.spec_path),
               *(["--standby"] if standby else [])]
        env = dict(os.environ, PYTHONUNBUFFERED="1", SLIPSTACK_RUN_DIR=str(self.run_dir),
                   **{LOG_LEVEL_ENV: self._world_levels.spec_for(c.name)})
        env.update(self._security_env())
        listen = self._listen_fds(c)
        if listen:
            env[LISTEN_FDS_ENV] = json.dumps(listen)
        if self.clock_offset_ns:
            env[CLOCK_OFFSET_ENV] = str(self.clock_offset_ns)
        if self.remote_sources:
            env[REMOTE_SOURCES_ENV] = json.dumps(self.remote_sources)
        nice = c.entry.nice

        def in_child() -> None:
            set_parent_death_signal()
            if nice:
                try:
                    os.nice(nice)
                except OSError:  # raising priority needs the privilege: run at normal priority
                    pass
                set_autogroup_nice(nice)

        proc = subprocess.Popen(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            stdin=subprocess.PIPE if standby else subprocess.DEVNULL,
            env=env, preexec_fn=in_child, start_new_session=True, pass_fds=tuple(listen.values()),
        )
        os.set_blocking(proc.stdout.fileno(), False)
        self.selector.register(proc.stdout, selectors.EVENT_READ, c)
        return proc

    def _grant_realtime(self, c: _Process) -> None:
        """Give ``c``'s process, now ready, its ``realtime_priority`` (every thread); say once per
        launch if it was not granted. A process starts (and a standby waits) at normal scheduling:
        its imports and kernel loads, about a second of CPU, run beside the graph, not ahead of it."""
        realtime = c.entry.realtime_priority
        if not realtime or c.proc is None:
            return
        grant_realtime_priority(c.proc.pid, realtime)  # without the privilege: by nice (checked below)
        if not c.realtime_refused_said and not has_realtime_priority(c.proc.pid):
            c.realtime_refused_said = True
            self.echo(f"[launch] {c.label}: realtime_priority {realtime} not granted (it needs root, CAP_SYS_NICE "
                      f"or `ulimit -r {realtime}`); it runs at normal scheduling, nice {c.entry.nice}")

    def _security_env(self) -> dict[str, str]:
        """The environment that gives a node process the graph's (or this machine's) keys."""
        env: dict[str, str] = {}
        keys = self._keys_dir()
        if keys is not None:
            env[KEYS_ENV] = str(keys)
            if self.machine is not None:
                env[MACHINE_ENV] = machine_env(self.machine, self._machine_hosts())
        if self.launch.insecure:
            env[INSECURE_ENV] = "1"
        return env

    def _keys_dir(self) -> Path | None:
        return self.launch.machines[self.machine].keys if self.machine is not None else self.launch.keys

    def _machine_hosts(self) -> dict[str, str]:
        """Address → machine name, for the server key a tcp connection checks."""
        return {m.address: m.name for m in self.launch.machines.values()}

    def _forward_logs(self, timeout: float) -> None:
        ready = sorted(self.selector.select(timeout), key=lambda k: not k[0].data.entry.stop_first)  # the world first
        for key, _ in ready:
            c: _Process = key.data
            try:
                chunk = key.fileobj.read()
            except (OSError, ValueError):
                chunk = b""
            if not chunk:
                self.selector.unregister(key.fileobj)
                if c.buffer:
                    self.echo(f"[{c.name}] {c.buffer.decode(errors='replace')}")
                    c.buffer = b""
                continue
            c.buffer += chunk
            *lines, c.buffer = c.buffer.split(b"\n")
            for line in lines:
                text = line.decode(errors="replace")
                if not self._world_end.keep(c.name, text):
                    self.echo.held(f"[{c.name}] {text}")
                elif self._world_levels.shown(c.name, text):
                    self.echo(f"[{c.name}] {text}")

    def _wait_ready(self, process: _Process, timeout: float) -> None:
        """Until every node of ``process`` has reported ready."""
        deadline = time.monotonic() + timeout
        pending = process.node_names
        while pending:
            if self._stop_requested:
                raise SlipstackError("interrupted while starting")
            self._read_control(pending)
            proc = process.proc
            if proc is not None and proc.poll() is not None:
                self._forward_logs(0.05)
                raise SlipstackError(f"{process.label} exited with code {proc.returncode} before it was ready; "
                                     "see its log lines above")
            if time.monotonic() > deadline:
                raise SlipstackError(f"node(s) {', '.join(sorted(pending))} not ready after {timeout:.0f} s")
            self._forward_logs(0.01)
            self._service_peers()
        self._grant_realtime(process)

    def _write_graph(self, state: str = "running") -> None:
        keys = self._keys_dir()
        graph = {
            "run_dir": str(self.run_dir),
            "launcher_pid": os.getpid(),
            "launcher_start_ticks": self.start_ticks,
            "launch_file": str(self.launch.path),
            "keys": str(keys) if keys else "",
            "state": state,
            "control": self.control_ep,
            "started_ns": time.time_ns(),
            "nodes": {name: self._graph_node(c) for name, c in self.children.items()},
        }
        if self.machine is not None:
            for name, endpoint in launcher_pub_endpoints(self.launch, self.run_dir, self.machine).items():
                graph["nodes"][launcher_node(name)] = {
                    "type": "launcher", "pid": os.getpid() if name == self.machine else None, "pub": endpoint,
                    "inputs": {}, "outputs": {DIAGNOSTICS_TOPIC: Diagnostics.TYPE}, "inject": {}, "restarts": 0,
                    "machine": name}
            graph["machine"] = {"name": self.machine, "hosts": self._machine_hosts(),
                                "clock_offset_ns": self.clock_offset_ns, "peers": self._peer_report()}
        if self.peers is not None:
            self.peers.state = state
        write_graph(self.run_dir, graph)

    def _graph_node(self, c: NodePlan) -> dict:
        """One node of ``graph.json`` (a node of another machine: its tcp endpoint, no pid)."""
        proc = self.processes.get(c.process) if self.plan.is_local(c.entry) else None
        entry = {"type": c.entry.type, "pid": proc.proc.pid if proc and proc.proc else None, "pub": c.endpoint,
                 "inputs": c.inputs, "outputs": c.outputs, "inject": c.inject,
                 "restarts": proc.restarts if proc else 0, "process": c.process}
        if self.machine is not None:
            entry.update(machine=c.entry.machine, pub_remote=c.remote_endpoint)
        return entry

    def _peer_report(self) -> dict[str, dict]:
        """Each other machine's state and clock offset (its clock minus ours, ns) as this launcher sees them."""
        report: dict[str, dict] = {}
        for name, peer in (self.peers.peers.items() if self.peers else ()):
            est = peer.offset()
            report[name] = {"state": peer.state or "unreachable", "quiet": peer.quiet,
                            "ready": sorted(peer.ready),
                            **({"offset_ns": est.offset_ns, "uncertainty_ns": est.uncertainty_ns,
                                "exchanges": est.samples} if est else {})}
        return report

    # -- other machines ----------------------------------------------------------------------
    def _service_peers(self) -> None:
        if self.peers is not None:
            self.peers.service()

    def _reference(self) -> str:
        """The first machine: its clock is the graph's time base."""
        return next(iter(self.launch.machines))

    def _join_peers(self) -> None:
        """Link to the other machines' launchers; on a machine other than the first, wait for the
        first one's launcher and take its clock as this machine's nodes' time base."""
        use_keys(self._keys_dir(), self.machine, self._machine_hosts(), insecure=self.launch.insecure)
        self.peers = PeerLinks(self.zctx, self.launch.machines, self.machine, self.echo)
        pubs = launcher_pub_endpoints(self.launch, self.run_dir, self.machine)
        self.clock_report = ClockReport(self.zctx, self.machine, pubs[self.machine],  # and the tcp one, for the others
                                        launcher_pub_endpoints(self.launch, self.run_dir, None)[self.machine])
        self.relay = InjectionRelay(self.zctx, relay_endpoint(self.launch.machines[self.machine]),
                                    [ep for p in self.processes.values() for c in p.members for ep in c.inject.values()])
        reference = self._reference()
        if reference == self.machine:
            return
        peer = self.peers.peers[reference]
        self.echo(f"[launch] machine {self.machine}: waiting for {peer.label} at {launcher_endpoint(peer.machine)} "
                  "(its time base is the graph's)")
        deadline = time.monotonic() + PEER_WAIT_S
        while (peer.offset() is None or peer.offset().samples < CLOCK_EXCHANGES) and not self._stop_requested:
            if time.monotonic() > deadline:
                raise SlipstackError(
                    f"{peer.label} did not answer within {PEER_WAIT_S:.0f} s: start `slipstack launch "
                    f"{self.launch.path.name} --machine {reference}` there, and check that this machine reaches "
                    f"{launcher_endpoint(peer.machine)} and that both hold the right keys")
            self._forward_logs(0.02)
            self.peers.service()
        est = peer.offset()
        if est is None:
            raise SlipstackError("interrupted while waiting for the other machines")
        self.clock_offset_ns = est.offset_ns
        self.echo(f"[launch] clock of machine {reference} is {est.offset_ns / 1e6:+.3f} ms from ours "
                  f"(± {est.uncertainty_ns / 1e3:.0f} µs, {est.samples} exchanges); this machine's nodes run on it")
        self._next_drift_check = time.monotonic() + DRIFT_CHECK_S
        timeout = self._controller_timeout_ns()
        if timeout is not None and est.uncertainty_ns > timeout / 2:
            self.echo(f"[launch] WARNING: the clock offset to machine {reference} is uncertain by "
                      f"{est.uncertainty_ns / 1e6:.1f} ms, more than half the grip controller's {timeout / 1e6:g} ms "
                      "timeout: ages of messages between the machines may be misjudged by that much (a slow or "
                      "busy link); check the link's round trip")

    def _controller_timeout_ns(self) -> int | None:
        """The shortest input timeout of the graph's grip controllers (ns); None without one."""
        timeouts = [float(e.instance().params.timeout_ms) for e in self.launch.nodes if e.type == "grip_controller"]
        return round(min(timeouts) * 1e6) if timeouts else None

    def _check_drift(self) -> None:
        """Every ``DRIFT_CHECK_S``: refresh the peers' state and clock offsets in ``graph.json``, and
        warn when this machine's nodes' clock drifted from the first machine's by more than half the
        grip controller's input timeout (ages would be misjudged by that much)."""
        if self.peers is None or time.monotonic() < self._next_drift_check:
            return
        self._next_drift_check = time.monotonic() + DRIFT_CHECK_S
        self._write_graph()
        if self.machine == self._reference():
            return
        est = self.peers.peers[self._reference()].offset()
        timeout = self._controller_timeout_ns()
        if est is None or timeout is None:
            return
        error = abs(est.offset_ns - self.clock_offset_ns) + est.uncertainty_ns
        if error > timeout / 2 and not self._drift_warned:
            self.echo(f"[launch] WARNING: this machine's clock drifted {error / 1e6:.1f} ms from machine "
                      f"{self._reference()}'s since the launch, more than half the grip controller's "
                      f"{timeout / 1e6:g} ms timeout: ages of messages between the machines are misjudged by that "
                      "much; keep the machines' clocks disciplined (NTP/PTP) and restart the launch")
        self._drift_warned = error > timeout / 2

    def _report_clocks(self) -> None:
        """Every ``REPORT_PERIOD_S``: this launcher's clock offsets on ``diagnostics`` (launch/clock_report.py)."""
        if self.clock_report is None or time.monotonic() < self._next_clock_report:
            return
        self._next_clock_report = time.monotonic() + REPORT_PERIOD_S
        quiet = [p.label for p in self.peers.peers.values() if p.quiet]
        warning = "; ".join([*(f"{label} went quiet" for label in quiet),
                             *([f"the clock drifted from machine {self._reference()}'s beyond half the grip "
                                "controller's timeout"] if self._drift_warned else [])])
        self.clock_report.publish(time.monotonic_ns() + self.clock_offset_ns,
                                  {name: p.offset() for name, p in self.peers.peers.items()}, self.clock_offset_ns,
                                  warning)

    def _required_peer_stopped(self) -> bool:
        """True (and said) if another machine's launcher stopped while running a ``required`` node:
        the launch ends on every machine, as it would on one."""
        for name, peer in (self.peers.peers.items() if self.peers else ()):
            required = sorted(e.name for e in self.launch.nodes if e.machine == name and e.required)
            if peer.state == "stopped" and required:
                self.echo(f"[launch] {peer.label} stopped, and it ran required node(s) {', '.join(required)}; "
                          "stopping this machine's share too")
                return True
        return False

    def _wait_for_peers(self, process: _Process) -> None:
        """Until the nodes on other machines that ``process``'s members start ``after`` are ready; for the
        simulated world (``stop_first``), every node of the other machines: it must not run while a
        controller elsewhere is still coming up (as PEER_WAIT_S allows another machine's launcher)."""
        remote = {a for c in process.members for a in c.entry.after if not self.plan.is_local(self.children[a].entry)}
        if process.entry.stop_first:
            remote |= {name for name, c in self.children.items() if not self.plan.is_local(c.entry)}
        deadline = time.monotonic() + PEER_WAIT_S
        while remote:
            missing = {a for a in remote if a not in self.peers.peers[self.children[a].entry.machine].ready}
            if not missing:
                return
            if self._stop_requested:
                raise SlipstackError("interrupted while starting")
            if time.monotonic() > deadline:
                where = {self.peers.peers[self.children[a].entry.machine].label for a in missing}
                raise SlipstackError(
                    f"{process.label} starts after {', '.join(sorted(missing))} on {', '.join(sorted(where))}, not "
                    f"ready after {PEER_WAIT_S:.0f} s: is `slipstack launch {self.launch.path.name} --machine "
                    f"{self.children[sorted(missing)[0]].entry.machine}` running there?")
            self._forward_logs(0.02)
            self._service_peers()

    def _on_signal(self, signum: int, frame: object) -> None:
        self._stop_requested = True
        self._signals += 1

    # -- the run ------------------------------------------------------------------------------
    def run(self) -> int:
        """Start, supervise until a signal, the duration or a required node ends; stop; report."""
        old = {s: signal.signal(s, self._on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
        started: list[str] = []
        try:
            if self.machine is not None:
                self._join_peers()
            self._write_graph("starting")  # endpoints are known now; tools may attach early
            for name in self.order:
                if self.peers is not None:
                    self._wait_for_peers(self.processes[name])
                self._spawn(self.processes[name])
                started.append(name)
                self._write_graph("starting")  # its pid: `node list` shows it up while the others start
                self._starting = self.processes[name]
                self._wait_ready(self.processes[name], READY_TIMEOUT_S)
                self._starting = None
                if self.peers is not None:
                    self.peers.ready = sorted(n for p in started for n in self.processes[p].node_names)
            self._write_graph()
            for name in started:  # once the graph runs: their imports do not delay its start
                self._prepare_standby(self.processes[name])
            ready = [f"{n} ({', '.join(c.entry.name for c in self.processes[n].members)})"
                     if self.processes[n].is_container else n for n in started]
            where = f" on machine {self.machine}" if self.machine is not None else ""
            if started:
                self.echo(f"[launch] {sum(len(self.processes[n].members) for n in started)} nodes ready{where} in "
                          f"{len(started)} processes: {', '.join(ready)}; run dir {self.run_dir}")
            else:  # an operator's machine: tools attach to the graph through this launcher's run directory
                self.echo(f"[launch] no nodes{where}; the graph's tools attach here, run dir {self.run_dir}")
            self._supervise()
        except SlipstackError as exc:
            if self._stop_requested:  # Ctrl-C (or SIGTERM) before the graph ran: the operator's stop
                self.echo(f"[launch] {exc}")
                self.exit_code = INTERRUPTED_EXIT
            else:
                self.echo(f"[launch] error: {exc}")
                self.exit_code = 1
                self.error = str(exc)
        finally:
            self._shutdown(started)
            for s, h in old.items():
                signal.signal(s, h)
            self.control.close(linger=0)
            if self.peers is not None:
                self.peers.close()
            if self.relay is not None:
                self.relay.close()
            if self.clock_report is not None:
                self.clock_report.close()
            self._release_ports()
        recording = self._read_recording_report()
        self._summary_from_recording(recording)
        self._report_recording(recording)
        self._report_events()
        if self.launch.check and self.exit_code == INTERRUPTED_EXIT:
            self.echo("[launch] no check: the graph never ran")
        elif self.launch.check:
            self._report_check()
        finish_run_dir(self.run_dir, keep=(EVENTS_FILE, CHECK_FILE))
        self.echo.close()
        return self.exit_code

    def _supervise(self) -> None:
        end = time.monotonic() + self.launch.duration_s if self.launch.duration_s > 0 else None
        while not self._stop_requested:
            if end is not None and time.monotonic() >= end:
                self.echo(f"[launch] duration {self.launch.duration_s:g} s reached")
                return
            self._forward_logs(0.05)
            self._service_peers()
            self._check_drift()
            self._report_clocks()
            if self._required_peer_stopped():
                return
            self._read_control()
            now = time.monotonic()
            for c in self.processes.values():
                if c.respawn_at is not None and now >= c.respawn_at:
                    self._respawn(c)
                    continue
                if c.proc is None or c.respawn_at is not None or c.proc.poll() is None:
                    continue
                if not self._on_exit(c, now):
                    return

    def _read_control(self, starting: set[str] | None = None) -> None:
        """Read the ready reports (of the nodes in ``starting`` while the graph starts; of
        respawned nodes, saying how long each process was gone), the stop reports (what each
        node published, for the recorder's count of what it misses) and the parameter changes
        ``slipstack param set`` asks for."""
        while self.control.poll(0):
            try:
                event = msgpack.unpackb(self.control.recv())
            except ValueError:
                continue
            if not isinstance(event, dict):
                continue
            if event.get("event") == "stopped" and isinstance(event.get("numbered"), dict):
                self._numbered[str(event.get("node"))] = event["numbered"]
            if event.get("event") == "set_param":
                self._set_param(event, starting is not None)
                continue
            if event.get("event") != "ready":
                continue
            if starting is not None:
                starting.discard(event.get("node"))
                continue
            for c in self.processes.values():
                if event.get("node") in c.not_ready:
                    c.not_ready.discard(event.get("node"))
                    if not c.not_ready and c.died_at is not None:
                        self._grant_realtime(c)
                        self.echo(f"[launch] {c.name} ready again {1e3 * (time.monotonic() - c.died_at):.0f} ms "
                                  "after it exited")
                        c.died_at = None
                        self._prepare_standby(c)

    def _set_param(self, event: dict, graph_starting: bool = False) -> None:
        """``{"node", "name", "value"}``: write the new value into the node's run spec and restart
        its process (the node's own start: a grip controller starts from the force the pad
        measures), if the launch file lets it restart (``respawn``) and the value is valid."""
        node, name, value = event.get("node"), event.get("name"), event.get("value")
        plan = self.children.get(node) if isinstance(node, str) else None
        c = self.processes.get(plan.process) if plan is not None and self.plan.is_local(plan.entry) else None
        why = ("the graph is still starting: set it once `slipstack node list` shows it up" if graph_starting else
               "no such node on this machine" if c is None or not isinstance(name, str) else
               "its process may not be restarted (respawn = false in the launch file)" if not c.entry.respawn else
               "it is restarting already" if c.proc is None or c.respawn_at is not None or c.restarting_for else "")
        if not why:
            params = {**plan.entry.params, name: value}
            try:
                from slipstack.nodes.runtime.node import make_params

                make_params(plan.entry.cls.Params, params, node)
            except SlipstackError as exc:
                why = str(exc)
        reply = event.get("reply")
        answer = (lambda ok, text: write_private_file(self.run_dir, f"{PARAM_REPLY}{reply}.json",
                                                      json.dumps({"ok": ok, "message": text}))
                  ) if isinstance(reply, int) else (lambda ok, text: None)
        if why:
            self.echo(f"[launch] param set {node} {name} refused: {why}")
            answer(False, why)
            return
        plan.entry.params[name] = value
        for member in c.spec.get("members", [c.spec]):
            if member.get("name") == node:
                member["params"] = dict(plan.entry.params)
        write_private_file(self.run_dir, c.spec_path.name, json.dumps(c.spec, indent=1))
        c.restarting_for = f"{node} {name} := {value!r}"
        self.echo(f"[launch] param set: {c.restarting_for}; restarting {c.label}")
        answer(True, f"restarting {c.label}")
        c.proc.send_signal(signal.SIGINT)

    def _respawn(self, c: _Process) -> None:
        c.respawn_at = None
        c.restarts += 1
        c.not_ready = set(c.node_names)
        how = "its warm standby" if c.standby is not None and c.standby.poll() is None else "a new process"
        if c.restarting_for:
            c.restarting_for = ""
            self.echo(f"[launch] restarting {c.name} with its new parameter from {how}")
            self._spawn(c)
            self._write_graph()
            return
        c.budget_used += 1
        self.echo(f"[launch] respawning {c.name} (restart {c.budget_used}/{c.entry.respawn_max_retries}) "
                  f"from {how}")
        self._spawn(c)
        if c.entry.realtime_priority and c.proc is not None:  # the graph waits for it: ahead of other work,
            grant_realtime_priority(c.proc.pid, RESPAWN_PRIORITY)  # behind the running nodes; its own once ready
        self._write_graph()

    def _on_exit(self, c: _Process, now: float) -> bool:
        """Handle the exit of ``c`` (respawn it, abandon it); False if the launch must end."""
        code = c.proc.returncode
        if c.restarting_for and code == 0:  # stopped for a parameter change: back at once, no restart used
            self._forward_logs(0.0)
            c.respawn_at, c.died_at = now, now
            return True
        c.restarting_for = ""
        if code != 0:
            c.deaths += 1
        self._forward_logs(0.0)
        self.echo(f"[launch] {c.label} exited with code {code}")
        if now - c.spawned_at >= c.entry.respawn_reset_s:
            c.budget_used = 0  # it was healthy for a while: a fresh budget
        if c.entry.respawn and c.budget_used < c.entry.respawn_max_retries:
            c.respawn_at = now + c.entry.respawn_delay_s * 2 ** c.budget_used
            c.died_at = now
            return True
        c.proc = None
        self._dismiss_standby(c)
        if c.entry.respawn:
            c.abandoned = True
            self.echo(f"[launch] ABANDONED {c.name}: it exited {c.budget_used + 1} times in a row (restarted "
                      f"{c.budget_used}x, respawn_max_retries = {c.entry.respawn_max_retries}); it stays down")
        if c.entry.required:
            self.echo(f"[launch] {c.name} is required; stopping the launch (it exited with code {code})")
            if code != 0 or c.abandoned:
                self.exit_code = 1
            return False
        if c.abandoned and self.launch.check and not c.observes_only:
            self.echo("[launch] check = true: a node was abandoned; stopping the launch")
            self.exit_code = 1
            return False
        return True

    def _report_events(self) -> None:
        """Print each process's deaths and restarts; write them to ``launch_events.json``."""
        events = {
            name: {"nodes": sorted(c.node_names), "died": c.deaths, "respawned": c.restarts, "abandoned": c.abandoned}
            for name, c in self.processes.items()
        }
        for name, e in events.items():
            if e["abandoned"]:
                self.echo(f"[launch] {name}: died {e['died']}x, abandoned after {e['respawned']} restarts")
            elif e["died"] or e["respawned"]:
                self.echo(f"[launch] {name}: died {e['died']}x, respawned {e['respawned']}x")
        write_private_file(self.run_dir, EVENTS_FILE, json.dumps({"exit_code": self.exit_code, "processes": events},
                                                                  indent=1))

    def _check_problems(self) -> list[str]:
        """What failed the run: the monitor's ``check.json`` problems (none expected without a monitor in
        the launch), processes of the data path that died and stayed down (an observer's death is said,
        not judged)."""
        problems = monitor_check_problems(self.launch, self.run_dir, self.machine)
        if self.error:  # the monitor may have seen nothing wrong: nothing ran
            problems.insert(0, f"the launch failed ({self.error})")
        if self._summary_gap:
            problems.append(self._summary_gap)
        for c in self.processes.values():
            if c.abandoned:
                down = f"{c.name} abandoned after {c.restarts} restarts"
            elif c.deaths and c.proc is None:
                down = f"{c.name} died and was not restarted (respawn = false)"
            else:
                continue
            if c.observes_only:
                self.echo(f"[launch] {down}: it only observes (publishes no data), so the check does not judge it")
            else:
                problems.append(down)
        return problems

    def _report_check(self) -> None:
        problems = self._check_problems()
        details = f" (details: {self.echo.path})" if self.echo.path is not None else ""
        if problems:
            self.echo(f"[launch] CHECK FAILED: {'; '.join(problems)}{details}")
            self.exit_code = 1
        else:
            elsewhere = sorted({e.machine for e in self.launch.nodes if e.type == "monitor" and not self.plan.is_local(e)})
            self.echo("[launch] check passed" + (f" on this machine; the run's own check is on machine "
                                                 f"{', '.join(elsewhere)}, where the monitor runs" if elsewhere else "")
                      + details)

    def _read_stop_reports(self, nodes: set[str]) -> None:
        """Read the control socket until each of ``nodes`` sent its stop report, for at most
        :data:`STOP_REPORT_WAIT_S`: a process may exit before its report reached this socket (one
        read at once missed a driver's and left the recording's count of it inexact)."""
        deadline = time.monotonic() + STOP_REPORT_WAIT_S
        self._read_control()
        while not nodes <= self._numbered.keys() and time.monotonic() < deadline:
            if self.control.poll(50):
                self._read_control()

    def _stop_order(self, started: list[str]) -> list[_Process]:
        """Processes marked ``stop_first`` (the simulated world), then the rest in reverse start order."""
        return [self.processes[n] for n in self.plan.stop_order(started)]

    def _shutdown(self, started: list[str]) -> None:
        self._world_end.world_ending()
        for c in self.processes.values():
            self._dismiss_standby(c)
        live = [p for p in self._stop_order(started) if p.proc is not None]
        stopped = [c for c in live if not c.outlives_graph]
        self._stop_graph(stopped)
        self._read_stop_reports({n for c in stopped for n in c.node_names})
        try:  # the recorder counts what its file misses against it
            write_private_file(self.run_dir, NUMBERED_REPORT, json.dumps(self._numbered))
        except OSError as exc:
            self.echo(f"[launch] cannot write {NUMBERED_REPORT} in the run directory ({exc.strerror})")
        self._let_finish([c for c in live if c.outlives_graph])
        for c in live:
            c.proc.wait()
        self._forward_logs(0.0)
        closing = self._world_end.closing_line()
        if closing:
            self.echo(closing)

    def _stop_signal(self, c: _Process) -> signal.Signals:
        """SIGINT, its stop; SIGTERM to the process the start waits on, which may be importing
        still: Python's SIGINT would print a traceback there, SIGTERM ends it silently (and is
        handled as SIGINT once the node runs, ``nodes/runtime/process.py``)."""
        return signal.SIGTERM if c is self._starting else signal.SIGINT

    def _stop_graph(self, live: list[_Process]) -> None:
        """Stop ``live`` in order: SIGINT, then SIGTERM and SIGKILL to whoever is left."""
        t0 = time.monotonic()
        for c in live:
            if c.proc.poll() is None:
                c.proc.send_signal(self._stop_signal(c))
                deadline = time.monotonic() + STOP_GRACE_S
                while c.proc.poll() is None and time.monotonic() < deadline:
                    self._forward_logs(0.01)
        escalations = ((TERM_AFTER_S, signal.SIGTERM), (KILL_AFTER_S, signal.SIGKILL))
        for after, sig in escalations:
            while any(c.proc.poll() is None for c in live) and time.monotonic() - t0 < after:
                self._forward_logs(0.02)
            for c in live:
                if c.proc.poll() is None:
                    self.echo(f"[launch] {c.name} still running; sending {sig.name}")
                    c.proc.send_signal(sig)

    def _let_finish(self, live: list[_Process]) -> None:
        """Stop the recorder and the monitor once the rest has stopped, and wait while they write
        what they still hold, up to :data:`FINISH_LIMIT_S` (a further Ctrl-C cuts it short)."""
        running = [c for c in live if c.proc.poll() is None]
        for c in running:
            c.proc.send_signal(self._stop_signal(c))
        t0, signals, said = time.monotonic(), self._signals, False
        while any(c.proc.poll() is None for c in running):
            waited = time.monotonic() - t0
            if waited > FINISH_LIMIT_S or self._signals > signals:
                break
            if not said and waited > FINISH_NOTE_S:
                said = True
                names = ", ".join(c.name for c in running if c.proc.poll() is None)
                self.echo(f"[launch] waiting for {names} to finish writing (at most {FINISH_LIMIT_S:g} s; "
                          "Ctrl-C again to stop now)")
            self._forward_logs(0.05)
        for c in running:
            if c.proc.poll() is None:
                why = "Ctrl-C again" if self._signals > signals else f"not done after {FINISH_LIMIT_S:g} s"
                self.echo(f"[launch] {c.name} stopped with SIGKILL ({why}): what it still held is lost"
                          + (" and its file is unfinished (bag info reads it up to its last chunk; missing ?)"
                             if any(m.entry.cls.taps_bus for m in c.members) else ""))
                c.proc.send_signal(signal.SIGKILL)

    def _read_recording_report(self) -> dict | None:
        """The recorder's report in the run directory (its file and what it misses); ``None`` if none."""
        try:
            fd = os.open(self.run_dir / RECORDING_REPORT, os.O_RDONLY | os.O_NOFOLLOW)
            with os.fdopen(fd, "rb") as fh:
                report = json.loads(fh.read(CHECK_FILE_MAX_BYTES))
            if isinstance(report.get("topics"), dict) and isinstance(report.get("path"), str):
                return report
            raise ValueError("not a recorder's report")
        except FileNotFoundError:
            return None
        except (OSError, ValueError, AttributeError) as exc:
            self.echo(f"[launch] the recorder's {RECORDING_REPORT} is unreadable ({exc})")
            return None

    def _summary_from_recording(self, recording: dict | None) -> None:
        """The monitor died during the run (or did not finish), or did not see every frame it judges
        (it fell behind): its summary would cover only part of the run, or be missing. Sum the run up
        from the recording instead, into the same summary and check files; without a recording, say
        what the summary misses (the monitor's own summary says what it did not see)."""
        monitor = next((c for c in self.processes.values() if any(m.entry.type == "monitor" for m in c.members)), None)
        if monitor is None:
            return
        died = monitor.deaths or (monitor.proc is not None and monitor.proc.returncode)
        if not died and _read_check(self.run_dir).get("judged_whole", True) is not False:
            return
        path = recording["path"] if recording else ""
        if not path or not os.path.isfile(path):
            if died:
                self._summary_gap = (f"the monitor died {monitor.deaths}x and nothing was recorded: its summary "
                                     "covers only the time since it came back")
                self.echo(f"[launch] {self._summary_gap}")
            return
        why = f"died {monitor.deaths}x" if died else "did not see every frame (it fell behind)"
        self.echo(f"[launch] the monitor {why} during the run: the run's summary from the recording {path}")
        member = next(m for m in monitor.members if m.entry.type == "monitor")
        from slipstack.nodes.monitor import summary_from_recording

        summary_from_recording(member.entry.instance(graph_nodes=set(self.children)), path,
                               lambda line: self.echo(line.replace("[monitor]", "[monitor, from the recording]", 1)))

    def _report_recording(self, report: dict | None) -> None:
        """The recorder's count of what its file misses: one line, and ``recording_loss`` in the
        summary JSON."""
        if report is None:
            return
        loss = report["topics"]
        self.echo(f"[launch] recording {report['path']}: {loss_text(loss, topics_shown=1)}")
        summary = next((e.params.get("summary_path") for e in self.launch.nodes
                        if e.type == "monitor" and self.plan.is_local(e) and e.params.get("summary_path")), None)
        if summary and os.path.isfile(summary):
            try:
                with open(summary, encoding="utf-8") as fh:
                    doc = json.load(fh)
                doc["recording_loss"] = loss
                write_json_atomically(summary, doc)
            except (OSError, ValueError) as exc:
                self.echo(f"[launch] cannot add the recording's loss to {summary} ({exc})")


def _read_check(run_dir: Path) -> dict:
    """The monitor's ``check.json`` in ``run_dir``; ``{}`` if it is missing or unreadable."""
    try:
        return _load_check(run_dir)
    except (OSError, ValueError):
        return {}


def _load_check(run_dir: Path) -> dict:
    fd = os.open(run_dir / CHECK_FILE, os.O_RDONLY | os.O_NOFOLLOW)
    with os.fdopen(fd, "rb") as fh:
        doc = json.loads(fh.read(CHECK_FILE_MAX_BYTES))
    return doc if isinstance(doc, dict) else {}


def monitor_check_problems(launch: LaunchFile, run_dir: Path, machine: str | None = None) -> list[str]:
    """The problems in the monitor's ``check.json`` in ``run_dir`` (none expected without a monitor in the
    launch, or on ``machine``'s share of it)."""
    try:
        doc = _load_check(run_dir)
        words = doc.get("short") or doc.get("problems")  # the HEALTH lines' short phrases, if the monitor wrote them
        problems = [] if doc["passed"] is True else [str(p) for p in words or ["not passed"]]
    except FileNotFoundError:
        monitored = any(e.type == "monitor" for e in launch.nodes if runs_on(e, machine))
        problems = [f"no {CHECK_FILE} from the monitor (did it not stop cleanly?)"] if monitored else []
    except (OSError, ValueError, TypeError, KeyError) as exc:
        problems = [f"{CHECK_FILE} is unreadable ({exc})"]
    return problems


def _check_machine(launch: LaunchFile, machine: str | None) -> str | None:
    """``--machine``: required by a graph with machines, one of them; refused by a graph without.
    With keys, this machine's key pair must be in its key directory."""
    names = list(launch.machines)
    if not names:
        if machine is not None:
            raise ConfigError(f"{launch.path.name} declares no [machines.NAME]: run it without --machine")
        return None
    if machine is None or machine not in launch.machines:
        got = f"no machine {machine!r}" if machine is not None else "it spans several machines"
        raise ConfigError(f"{launch.path.name}: {got}; run `slipstack launch {launch.path.name} --machine NAME` on "
                          f"each of them, NAME one of: {', '.join(names)}")
    keys = launch.machines[machine].keys
    if keys is not None:  # fail now, with how to make them
        GraphKeys.load(keys, machine, {m.address: m.name for m in launch.machines.values()})
    return machine


def run_lockstep(launch: LaunchFile, run_dir: Path, echo: Callable[[str], None] | None = None,
                 log_file: Path | None = None) -> int:
    """``--lockstep``: ``launch`` in this process on the simulated clock (``launch/lockstep.py``),
    every line also into ``log_file`` as the real-time launch writes it; the exit code, 1 if
    ``check`` is on and the monitor's check failed."""
    from slipstack.launch.lockstep import LockstepRun  # the real-time launch does not import the nodes

    echo = RunLog(echo or Console(), log_file)
    try:
        exit_code = LockstepRun(launch, run_dir, echo=echo).run()
        if launch.check:
            problems = monitor_check_problems(launch, run_dir)
            echo(f"[launch] CHECK FAILED: {'; '.join(problems)}" if problems else "[launch] check passed")
            exit_code = exit_code or int(bool(problems))
    finally:
        finish_run_dir(run_dir, keep=(CHECK_FILE,))
        echo.close()
    return exit_code
