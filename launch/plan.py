"""The launch plan: from a parsed launch file to what runs where, as a value.

:func:`plan_launch` decides, without binding a socket or writing a file, which nodes
run, in which processes (a ``container`` groups nodes into one), on which endpoints,
with which run spec (the JSON each process reads: ``nodes/runtime/process.py``), and
in which order processes start and stop. ``launch/launcher.py`` supervises processes
from a plan; ``launch/lockstep.py`` runs the same plan's nodes in one process on the
simulated clock.

More in docs/modules.md, `launch/plan.py`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from slipstack.lib.errors import ConfigError
from slipstack.launch.launch_file import LaunchFile, Machine, NodeEntry, free_port
from slipstack.messages import Diagnostics
from slipstack.nodes.device_driver import DeviceDriver
from slipstack.nodes.runtime.graph_info import INJECTION_REFUSED
from slipstack.nodes.runtime.host import DIAGNOSTICS_TOPIC
from slipstack.nodes.runtime.transport import ipc_endpoint, machine_ports, tcp_endpoint

__all__ = ["NodePlan", "ProcessPlan", "LaunchPlan", "plan_launch", "tapped_topics", "machine_endpoints", "runs_on",
           "remote_sources", "relay_endpoint", "launcher_pub_endpoints", "PEER_WAIT_S"]

PEER_WAIT_S = 60.0
"""How long (s) a machine's launcher waits for the first machine's to answer, and so how long
a publisher with subscribers on another machine waits for them in its readiness handshake."""


@dataclass
class NodePlan:
    """One node of the graph: how it is wired (topic → message type name per input and output)."""

    entry: NodeEntry
    endpoint: str
    process: str  # name of the ProcessPlan that runs it
    outputs: dict[str, str] = field(default_factory=dict)
    inputs: dict[str, str] = field(default_factory=dict)
    inject: dict[str, str] = field(default_factory=dict)
    remote_endpoint: str | None = None
    """The tcp endpoint it binds as well, for subscribers and tools on other machines (None: one machine)."""


@dataclass
class ProcessPlan:
    """One OS process: a single node, or a container of nodes sharing one loop.

    ``spec`` is the run spec the process reads from ``spec_path`` (the launcher writes it).
    """

    name: str
    members: list[NodePlan]
    spec_path: Path
    spec: dict = field(default_factory=dict)

    @property
    def entry(self) -> NodeEntry:
        """Process settings (respawn, required, nice): the members share them."""
        return self.members[0].entry

    @property
    def runs_device_driver(self) -> bool:
        """A member is a device driver (its device may vanish when the simulated world stops)."""
        return any(issubclass(m.entry.cls, DeviceDriver) for m in self.members)

    @property
    def outlives_graph(self) -> bool:
        """A member records or sums up the others (``Node.outlives_graph``): stopped last, given time to finish."""
        return any(m.entry.cls.outlives_graph for m in self.members)

    @property
    def is_container(self) -> bool:
        return bool(self.entry.container)

    @property
    def label(self) -> str:
        """How log lines name it: ``container NAME`` or ``node NAME (TYPE)``."""
        return f"container {self.name}" if self.is_container else f"node {self.name} ({self.entry.type})"

    @property
    def node_names(self) -> set[str]:
        return {c.entry.name for c in self.members}

    @property
    def inputs(self) -> set[str]:
        return {t for c in self.members for t in c.inputs}

    @property
    def outputs(self) -> set[str]:
        return {t for c in self.members for t in c.outputs}

    @property
    def observes_only(self) -> bool:
        """It publishes nothing but diagnostics (the monitor, the recorder, the Foxglove bridge):
        the control path does not depend on it, so the run's check does not judge it (docs/summary.md)."""
        return self.outputs <= {DIAGNOSTICS_TOPIC}


@dataclass
class LaunchPlan:
    """What a launch runs: nodes, processes, endpoints, start order (process names).

    ``nodes`` holds every node of the graph; ``processes`` and ``order`` only those that
    run here (the share of ``machine``; every node if None)."""

    launch: LaunchFile
    run_dir: Path
    control_endpoint: str
    nodes: dict[str, NodePlan]
    processes: dict[str, ProcessPlan]
    order: list[str]
    machine: str | None = None

    def is_local(self, entry: NodeEntry) -> bool:
        """True if this plan runs ``entry`` (every node, without a machine)."""
        return runs_on(entry, self.machine)

    def node_order(self) -> list[str]:
        """Node names in start order (a container's members in launch-file order)."""
        return [c.entry.name for p in self.order for c in self.processes[p].members]

    def node_stop_order(self) -> list[str]:
        """Node names in stop order, every process started."""
        return [c.entry.name for p in self.stop_order(self.order) for c in self.processes[p].members]

    def stop_order(self, started: list[str]) -> list[str]:
        """Of the ``started`` processes: those marked ``stop_first`` (the simulated world), then the
        rest in reverse start order."""
        procs = [self.processes[n] for n in reversed(started)]
        return [p.name for p in procs if p.entry.stop_first] + [p.name for p in procs if not p.entry.stop_first]


def tapped_topics(node: object) -> set[str] | None:
    """Topics a bus tap (the recorder) subscribes to: a set, empty for all; None if no tap."""
    if not getattr(node, "taps_bus", False):
        return None
    return set(node.params.topics)


def runs_on(entry: NodeEntry, machine: str | None) -> bool:
    """True if the launcher of ``machine`` runs ``entry`` (None: the one launcher of every node)."""
    return machine is None or entry.machine == machine


def machine_endpoints(launch: LaunchFile) -> dict[str, str]:
    """Node name → the tcp endpoint it binds on its machine (empty without machines)."""
    out: dict[str, str] = {}
    for m in launch.machines.values():
        ports = machine_ports(m.ports[0], [e.name for e in launch.nodes if e.machine == m.name])
        out.update({name: tcp_endpoint(m.address, port) for name, port in ports.items()})
    return out


def relay_endpoint(machine: Machine) -> str:
    """Where the launcher of ``machine`` takes frames injected by tools on other machines: its
    address, the last of its ports (launch/inject_relay.py)."""
    return tcp_endpoint(machine.address, machine.ports[1])


def launcher_pub_endpoints(launch: LaunchFile, run_dir: Path, machine: str | None) -> dict[str, str]:
    """Machine → where its launcher publishes its ``diagnostics`` (clock offsets, launch/clock_report.py), as
    seen from ``machine``: ipc in ``run_dir`` for its own, the next-to-last port of the others' (of every
    machine's if None)."""
    return {name: f"ipc://{run_dir}/launcher.pub" if name == machine else tcp_endpoint(m.address, m.ports[1] - 1)
            for name, m in launch.machines.items()}


def plan_launch(launch: LaunchFile, run_dir: Path, machine: str | None = None, *, lockstep: bool = False) -> LaunchPlan:
    """The plan of ``launch`` in ``run_dir`` (the share of ``machine`` of a graph with
    machines; None: every node here); nothing is bound or written. A ``lockstep`` plan's
    endpoints are never bound, so the length limit of an ipc path does not apply to them.

    Raises:
        ConfigError: ``after`` constraints that form a cycle; a machine the file does not declare.
    """
    if machine is not None and machine not in launch.machines:
        raise ConfigError(f"{launch.path.name}: no machine {machine!r}; "
                          f"machines: {', '.join(launch.machines) or 'none'}")
    control_ep = f"ipc://{run_dir}/launcher.ctl"
    children: dict[str, NodePlan] = {}
    processes: dict[str, ProcessPlan] = {}
    nodes = {e.name: e.instance() for e in launch.nodes}
    remote = machine_endpoints(launch) if machine is not None else {}
    launchers = list(launcher_pub_endpoints(launch, run_dir, machine).values()) if machine is not None else []
    for e in launch.nodes:
        runs_here = runs_on(e, machine)
        if not runs_here or (remote and e.transport == "tcp"):
            ep = remote[e.name]  # a node elsewhere, or one only on tcp: its machine's port
        elif e.transport == "tcp":
            ep = f"tcp://127.0.0.1:{free_port()}"
        else:
            ep = ipc_endpoint(run_dir, e.name, bound=not lockstep)
        child = NodePlan(e, ep, e.container or e.name, remote_endpoint=remote.get(e.name))
        child.outputs = {t: nodes[e.name].outputs[n].type.TYPE for n, t in e.output_topics(nodes[e.name]).items()}
        child.outputs[DIAGNOSTICS_TOPIC] = Diagnostics.TYPE  # every node publishes it
        child.inputs = {t: nodes[e.name].inputs[n].type.TYPE for n, t in e.input_topics(nodes[e.name]).items()}
        children[e.name] = child
        injectable = [t for t, kind in child.inputs.items()
                      if kind not in INJECTION_REFUSED or t in launch.allow_inject]
        if not runs_here:  # another machine's launcher runs it; tools here inject through it
            child.inject = {t: relay_endpoint(launch.machines[e.machine]) for t in injectable}
            continue
        child.inject = {t: ipc_endpoint(run_dir, f"{e.name}.in", bound=not lockstep) for t in injectable}
        proc = processes.setdefault(child.process, ProcessPlan(child.process, [], run_dir / f"{child.process}.spec.json"))
        proc.members.append(child)
    publishers: dict[str, list[str]] = {}
    for name, c in children.items():
        for topic in c.outputs:
            publishers.setdefault(topic, []).append(name)
    taps = {n: tapped for n in children if (tapped := tapped_topics(nodes[n])) is not None}
    here = {c.entry.name for p in processes.values() for c in p.members}
    specs: dict[str, dict] = {}
    for name, c in children.items():
        if name not in here:
            continue
        # a subscriber in the publisher's own process gets its messages handed over there
        expected = {
            topic: sum(1 for other in children.values() if topic in other.inputs and other.process != c.process)
            + sum(1 for tap, tapped in taps.items() if tap != name and (not tapped or topic in tapped))
            for topic in c.outputs
        }
        local = {t: [p for p in publishers.get(t, []) if p != name and children[p].process == c.process]
                 for t in c.inputs}
        specs[name] = {
            # subscribers on another machine may take as long as its launcher does to come up
            **({"handshake_timeout_s": PEER_WAIT_S} if _feeds_elsewhere(c, children, taps, here) else {}),
            "name": name,
            "pub": c.endpoint,
            "pub_remote": c.remote_endpoint if c.remote_endpoint != c.endpoint else None,
            "subs": {t: [children[p].endpoint for p in publishers.get(t, []) if children[p].process != c.process]
                     + (launchers if t == DIAGNOSTICS_TOPIC else []) for t in c.inputs},
            "remap": c.entry.remap,
            "inject": c.inject,
            "expected_subscribers": {t: n for t, n in expected.items() if n},
            "control": control_ep,
            "local": {t: ps for t, ps in local.items() if ps},
            "params": c.entry.params,
        }
    for proc in processes.values():
        if proc.is_container:
            proc.spec = {"container": proc.name,
                         "members": [{"type": c.entry.type, **specs[c.entry.name]} for c in proc.members]}
        else:
            proc.spec = specs[proc.members[0].entry.name]
    order = _start_order(children, processes, here)
    return LaunchPlan(launch, run_dir, control_ep, children, processes, order, machine)


def remote_sources(plan: LaunchPlan) -> dict[str, str]:
    """Topic → the other machines its data passes through on its way to ``plan``'s machine, as a
    label (``"machine robot, 127.0.0.1"``): the topic graph followed upstream from the topic's
    publishers, ``diagnostics`` left out (every node publishes it). Only topics with such a machine;
    {} without machines. What ``$SLIPSTACK_REMOTE_SOURCES`` carries (nodes/runtime/remote_sources.py)."""
    if plan.machine is None:
        return {}
    publishers: dict[str, list[NodePlan]] = {}
    for c in plan.nodes.values():
        for topic in c.outputs:
            publishers.setdefault(topic, []).append(c)
    out: dict[str, str] = {}
    for topic in publishers:
        if topic == DIAGNOSTICS_TOPIC:
            continue
        machines: set[str] = set()
        seen, pending = {topic}, [topic]
        while pending:
            for c in publishers.get(pending.pop(), []):
                machines.add(c.entry.machine)
                fresh = set(c.inputs) - seen - {DIAGNOSTICS_TOPIC}
                seen |= fresh
                pending += sorted(fresh)
        machines.discard(plan.machine)
        if machines:
            out[topic] = "; ".join(f"machine {m}, {plan.launch.machines[m].address}" for m in sorted(machines))
    return out


def _feeds_elsewhere(c: NodePlan, children: dict[str, NodePlan], taps: dict[str, set[str]], here: set[str]) -> bool:
    """True if a node or bus tap that does not run ``here`` (on another machine) subscribes to an output of ``c``."""
    remote = [o for name, o in children.items() if name not in here]
    tapped = [taps[o.entry.name] for o in remote if o.entry.name in taps]
    return any(topic in o.inputs for topic in c.outputs for o in remote) or any(
        not t or t & set(c.outputs) for t in tapped)


def _start_order(children: dict[str, NodePlan], procs: dict[str, ProcessPlan], here: set[str]) -> list[str]:
    """Processes, subscribers before publishers: reverse topological order, back edges ignored;
    ``after`` a node not ``here`` (on another machine) is left to the launcher."""
    downstream = {
        name: [o for o, op in procs.items() if o != name and op.inputs & p.outputs] for name, p in procs.items()
    }
    after = {  # a node on another machine: the launcher waits for it before the spawn
        name: {children[a].process for c in p.members for a in c.entry.after
               if a in here} - {name}
        for name, p in procs.items()
    }
    seen: set[str] = set()
    post: list[str] = []

    def visit(n: str) -> None:
        seen.add(n)
        for m in downstream[n]:
            if m not in seen:
                visit(m)
        post.append(n)

    for name in procs:  # launch-file order breaks ties
        if name not in seen:
            visit(name)
    # post-order: every process after all it feeds (cycles cut where entered); then
    # honour explicit `after` constraints, keeping that order otherwise
    order: list[str] = []
    pending = post
    while pending:
        ready = [n for n in pending if after[n] <= set(order)]
        if not ready:
            raise ConfigError(f"'after' constraints form a cycle among {pending}")
        order.append(ready[0])
        pending = [n for n in pending if n != ready[0]]
    return order
