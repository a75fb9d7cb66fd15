"""``slipstack launch``: start a graph of node processes and supervise it.

Each node runs in a process of its own, or with the other nodes of its ``container``
in one process (their messages to each other then skip the bus; see
``nodes/runtime/process.py``). Starts processes subscribers-first (reverse topological order
of the topic graph, so a publisher's subscribers exist before its data flows), waits
for each to report ready, forwards every log line prefixed with ``[node]``, respawns
crashed nodes per their policy, and on SIGINT/SIGTERM stops them in reverse start
order with SIGINT → SIGTERM → SIGKILL escalation (nodes marked ``stop_first``, the
simulated rig, go first: the simulated world must not run on without its controller).
Children get a parent-death signal, so even a SIGKILLed launcher leaves no orphans
behind.

Respawn: a process that may be respawned has a warm standby (unless ``respawn_standby
= false``), a second process that has imported its modules and waits on stdin (it
binds nothing); a restart wakes it, so the node is back without paying the interpreter
start and the imports again, and a new standby is prepared once it is ready. The first
restart follows ``respawn_delay_s`` after the exit, each further one waits twice as
long; ``respawn_max_retries`` restarts in a row use up the budget, which a process
that stays up ``respawn_reset_s`` gets back. A process whose budget is used up is
*abandoned*: said loudly, and the launch ends with exit 1 if the node is ``required``
or the launch has ``check = true``. Deaths, restarts and abandonments are printed in
the closing lines and written to ``<run_dir>/launch_events.json`` (the run directory
keeps that file and ``check.json`` after the launch; the newest ``KEEP_FINISHED_RUNS``
finished ones are kept). With ``check = true`` the launch ends with ``[launch] check
passed`` or ``[launch] CHECK FAILED: ...`` (exit 1) from the monitor's ``check.json``
and the processes that died and stayed down.

Machines: a launch file with ``[machines.NAME]`` tables is run by one launcher per
machine, ``slipstack launch FILE --machine NAME``; each starts the nodes placed on its
machine (the plan of its share, ``launch/plan.py``, where every endpoint is computed
from the file alike on every machine) and talks to the other launchers
(``launch/peers.py``): ``after`` waits for nodes on other machines, a machine that goes
quiet or stops is reported, and the launchers of machines other than the first start
their nodes on the first machine's clock (``nodes/runtime/time_base.py``).
``--lockstep`` runs the nodes of every machine in one process (placement does not
matter on the simulated clock); it refuses ``--machine``.
"""

from __future__ import annotations

import argparse
import json
import os
import selectors
import signal
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
from slipstack.launch.launch_file import PORT_ARGS, SIM_ARG, LaunchFile, arg_comments, load_launch_file
from slipstack.launch.clock_report import REPORT_PERIOD_S, ClockReport, launcher_node
from slipstack.launch.inject_relay import InjectionRelay
from slipstack.launch.peers import PeerLinks, launcher_endpoint
from slipstack.launch.priority import (
    grant_realtime_priority, has_realtime_priority, set_autogroup_nice,
)
from slipstack.launch.plan import (PEER_WAIT_S, NodePlan, ProcessPlan, launcher_pub_endpoints, plan_launch,
                                   relay_endpoint, remote_sources, runs_on)
from slipstack.launch.run_node import parse_assignments, set_parent_death_signal
from slipstack.nodes.devices.sim_link import SIM_PREFIX
from slipstack.launch.quiet_shutdown import WorldEndFilter, WorldLogLevels
from slipstack.launch.run_log import RunLog, log_path_for
from slipstack.nodes.runtime.logs import DETAIL_PREFIX, LOG_LEVEL_ENV, parse_log_levels
from slipstack.nodes.runtime.curve import INSECURE_ENV, KEYS_ENV, MACHINE_ENV, GraphKeys, machine_env, use_keys
from slipstack.nodes.runtime.graph_info import process_start_ticks, write_graph
from slipstack.nodes.runtime.host import DIAGNOSTICS_TOPIC
from slipstack.nodes.runtime.run_dir import finish_run_dir, make_run_dir, remove_run_dir, write_private_file
from slipstack.nodes.runtime.remote_sources import REMOTE_SOURCES_ENV
from slipstack.nodes.runtime.time_base import CLOCK_OFFSET_ENV

__all__ = ["Launcher", "add_parser", "main_launch"]

READY_TIMEOUT_S = 20.0
STOP_GRACE_S = 0.4       # per node, after SIGINT, before the next node is told to stop
TERM_AFTER_S = 1.5       # from the start of shutdown: SIGTERM whoever is left
KILL_AFTER_S = 2.5       # from the start of shutdown: SIGKILL whoever is left
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
        self.exit_code = 0
        self.start_ticks = process_start_ticks(os.getpid())
        world = {n: tuple(p.node_names) for n, p in self.processes.items() if p.entry.stop_first}
        self._world_levels = WorldLogLevels(os.environ.get(LOG_LEVEL_ENV, ""), world)
        self._world_end = WorldEndFilter(set(world),
                                         {n for n, p in self.processes.items() if p.runs_device_driver})
        for proc in self.processes.values():
            write_private_file(self.run_dir, proc.spec_path.name, json.dumps(proc.spec, indent=1))

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
            env=env, preexec_fn=in_child, start_new_session=True,
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
            while self.control.poll(0):
                event = msgpack.unpackb(self.control.recv())
                if event.get("event") == "ready":
                    pending.discard(event.get("node"))
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
        """Until the nodes on other machines that ``process``'s members start ``after`` are ready."""
        remote = {a for c in process.members for a in c.entry.after if not self.plan.is_local(self.children[a].entry)}
        deadline = time.monotonic() + READY_TIMEOUT_S
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
                    f"ready after {READY_TIMEOUT_S:.0f} s: is `slipstack launch {self.launch.path.name} --machine "
                    f"{self.children[sorted(missing)[0]].entry.machine}` running there?")
            self._forward_logs(0.02)
            self._service_peers()

    def _on_signal(self, signum: int, frame: object) -> None:
        self._stop_requested = True

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
                self._wait_ready(self.processes[name], READY_TIMEOUT_S)
                self._prepare_standby(self.processes[name])
                if self.peers is not None:
                    self.peers.ready = sorted(n for p in started for n in self.processes[p].node_names)
            self._write_graph()
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
            self.echo(f"[launch] error: {exc}")
            self.exit_code = 1
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
        self._report_events()
        if self.launch.check:
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
            self._note_ready_reports()
            now = time.monotonic()
            for c in self.processes.values():
                if c.respawn_at is not None and now >= c.respawn_at:
                    self._respawn(c)
                    continue
                if c.proc is None or c.respawn_at is not None or c.proc.poll() is None:
                    continue
                if not self._on_exit(c, now):
                    return

    def _note_ready_reports(self) -> None:
        """Read the ready reports of respawned nodes; say how long each process was gone."""
        while self.control.poll(0):
            event = msgpack.unpackb(self.control.recv())
            if event.get("event") != "ready":
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

    def _respawn(self, c: _Process) -> None:
        c.respawn_at = None
        c.restarts += 1
        c.budget_used += 1
        c.not_ready = set(c.node_names)
        how = "its warm standby" if c.standby is not None and c.standby.poll() is None else "a new process"
        self.echo(f"[launch] respawning {c.name} (restart {c.budget_used}/{c.entry.respawn_max_retries}) "
                  f"from {how}")
        self._spawn(c)
        self._write_graph()

    def _on_exit(self, c: _Process, now: float) -> bool:
        """Handle the exit of ``c`` (respawn it, abandon it); False if the launch must end."""
        code = c.proc.returncode
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
        if c.abandoned and self.launch.check:
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
        the launch), processes that died and stayed down."""
        problems = monitor_check_problems(self.launch, self.run_dir, self.machine)
        for c in self.processes.values():
            if c.abandoned:
                problems.append(f"{c.name} abandoned after {c.restarts} restarts")
            elif c.deaths and c.proc is None:
                problems.append(f"{c.name} died and was not restarted (respawn = false)")
        return problems

    def _report_check(self) -> None:
        problems = self._check_problems()
        if problems:
            self.echo(f"[launch] CHECK FAILED: {'; '.join(problems)}")
            self.exit_code = 1
        else:
            elsewhere = sorted({e.machine for e in self.launch.nodes if e.type == "monitor" and not self.plan.is_local(e)})
            self.echo("[launch] check passed" + (f" on this machine; the run's own check is on machine "
                                                 f"{', '.join(elsewhere)}, where the monitor runs" if elsewhere else ""))

    def _stop_order(self, started: list[str]) -> list[_Process]:
        """Processes marked ``stop_first`` (the simulated world), then the rest in reverse start order."""
        return [self.processes[n] for n in self.plan.stop_order(started)]

    def _shutdown(self, started: list[str]) -> None:
        self._world_end.world_ending()
        for c in self.processes.values():
            self._dismiss_standby(c)
        t0 = time.monotonic()
        live = [p for p in self._stop_order(started) if p.proc is not None]
        for c in live:
            if c.proc.poll() is None:
                c.proc.send_signal(signal.SIGINT)
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
        for c in live:
            c.proc.wait()
        self._forward_logs(0.0)
        closing = self._world_end.closing_line()
        if closing:
            self.echo(closing)


def monitor_check_problems(launch: LaunchFile, run_dir: Path, machine: str | None = None) -> list[str]:
    """The problems in the monitor's ``check.json`` in ``run_dir`` (none expected without a monitor in the
    launch, or on ``machine``'s share of it)."""
    try:
        fd = os.open(run_dir / CHECK_FILE, os.O_RDONLY | os.O_NOFOLLOW)
        with os.fdopen(fd, "rb") as fh:
            doc = json.loads(fh.read(CHECK_FILE_MAX_BYTES))
        problems = [] if doc["passed"] is True else [str(p) for p in doc.get("problems") or ["not passed"]]
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


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "launch", help="run a graph (default: the simulated rig and the full stack)",
        description="Run a graph of nodes from a TOML launch file; name:=value sets launch arguments.",
    )
    p.add_argument("file", nargs="?", help="launch file (path or shipped name); default: the default graph"
                   ).completer = _shipped_launch_files  # type: ignore[attr-defined]
    p.add_argument("assignments", nargs="*", metavar="name:=value", help="launch argument overrides")
    p.add_argument("--show-args", action="store_true",
                   help="print the launch arguments with their values and comments, and exit")
    p.add_argument("--lockstep", action="store_true",
                   help="run every node in this process on the simulated clock, the rig in lock-step with the "
                        "stack: faster than real time and repeatable bit for bit (simulated devices only; "
                        "a graph over machines runs every machine's nodes here)")
    p.add_argument("--machine", metavar="NAME",
                   help="run the share of machine NAME of a graph with [machines.NAME] tables (run the "
                        "same file and arguments on every machine, each with its own NAME)")
    p.add_argument("--log-level", metavar="LEVEL[,NODE=LEVEL]", default="",
                   help="least level of the node log lines shown and kept: debug, info (default), warning, "
                        "error; for every node, then per node, e.g. warning,ft_driver=debug")
    p.add_argument("--log-file", metavar="PATH",
                   help="keep every line printed here (default: beside the recording, runs/<stamp>.log; "
                        "none when nothing is recorded)")
    p.set_defaults(func=main_launch)


def _shipped_launch_files(**_: object) -> list[str]:
    """Shell completion of the launch file: the shipped ones, by name (``fig15``)."""
    from slipstack.launch.launch_file import launch_files_dir

    return sorted(p.stem for p in launch_files_dir().glob("*.toml"))


def main_launch(args: argparse.Namespace) -> int:
    parse_log_levels(args.log_level)  # a bad level fails before anything starts
    if args.log_level:
        os.environ[LOG_LEVEL_ENV] = args.log_level  # the node processes inherit it
    positional = list(args.assignments)
    file = args.file
    if file is not None and ":=" in file:  # `slipstack launch name:=value` with the default file
        positional.insert(0, file)
        file = None
    run_dir = make_run_dir()
    try:
        builtins = {"run_dir": str(run_dir), SIM_ARG: SIM_PREFIX if args.lockstep else ""}
        launch = load_launch_file(file, parse_assignments(positional), builtins=builtins)
        if args.show_args:
            comments = arg_comments(launch.path)
            for name, value in launch.args.items():
                if name not in ("run_dir", "stamp", SIM_ARG, *PORT_ARGS):
                    note = f"  # {comments[name]}" if name in comments else ""
                    print(f"{name} := {value!r}{note}")
            remove_run_dir(run_dir)
            return 0
        if args.lockstep:
            if args.machine is not None:
                raise ConfigError("--lockstep runs every machine's nodes in this one process; "
                                  "drop --machine (or drop --lockstep to run one machine's share)")
            return run_lockstep(launch, run_dir)
        launcher = Launcher(launch, run_dir, log_file=Path(args.log_file) if args.log_file else log_path_for(launch),
                            machine=args.machine)
    except BaseException:  # a bad launch file leaves no run directory behind
        remove_run_dir(run_dir)
        raise
    return launcher.run()


def run_lockstep(launch: LaunchFile, run_dir: Path, echo: Callable[[str], None] | None = None) -> int:
    """``--lockstep``: ``launch`` in this process on the simulated clock (``launch/lockstep.py``);
    the exit code, 1 if ``check`` is on and the monitor's check failed."""
    from slipstack.launch.lockstep import LockstepRun  # the real-time launch does not import the nodes

    echo = echo or Console()
    try:
        exit_code = LockstepRun(launch, run_dir, echo=echo).run()
        if launch.check:
            problems = monitor_check_problems(launch, run_dir)
            echo(f"[launch] CHECK FAILED: {'; '.join(problems)}" if problems else "[launch] check passed")
            exit_code = exit_code or int(bool(problems))
    finally:
        finish_run_dir(run_dir, keep=(CHECK_FILE,))
    return exit_code
