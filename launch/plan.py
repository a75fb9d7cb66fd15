"""The launch plan: from a parsed launch file to what runs where, as a value.

:func:`plan_launch` decides, without binding a socket or writing a file, which nodes
run, in which processes (a ``container`` groups nodes into one), on which endpoints,
with which run spec (the JSON each process reads: ``nodes/runtime/process.py``), and
in which order processes start and stop. ``launch/launcher.py`` supervises processes
from a plan; ``launch/lockstep.py`` runs the same plan's nodes in one process on the
simulated clock.

Start order: subscribers before publishers (reverse topological order of the topic
graph, so a publisher's subscribers exist before its data flows), then every node's
``after`` list. Stop order: nodes marked ``stop_first`` (the simulated rig), then the
others in reverse start order.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from slipstack.lib.errors import ConfigError
from slipstack.launch.launch_file import LaunchFile, NodeEntry, free_port
from slipstack.messages import Diagnostics
from slipstack.nodes.device_driver import DeviceDriver
from slipstack.nodes.runtime.host import DIAGNOSTICS_TOPIC
from slipstack.nodes.runtime.transport import ipc_endpoint

__all__ = ["NodePlan", "ProcessPlan", "LaunchPlan", "plan_launch", "tapped_topics"]


@dataclass
class NodePlan:
    """One node of the graph: how it is wired (topic → message type name per input and output)."""

    entry: NodeEntry
    endpoint: str
    process: str  # name of the ProcessPlan that runs it
    outputs: dict[str, str] = field(default_factory=dict)
    inputs: dict[str, str] = field(default_factory=dict)
    inject: dict[str, str] = field(default_factory=dict)


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


@dataclass
class LaunchPlan:
    """What a launch runs: nodes, processes, endpoints, start order (process names)."""

    launch: LaunchFile
    run_dir: Path
    control_endpoint: str
    nodes: dict[str, NodePlan]
    processes: dict[str, ProcessPlan]
    order: list[str]

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


def plan_launch(launch: LaunchFile, run_dir: Path) -> LaunchPlan:
    """The plan of ``launch`` in ``run_dir``; nothing is bound or written.

    Raises:
        ConfigError: ``after`` constraints that form a cycle.
    """
    control_ep = f"ipc://{run_dir}/launcher.ctl"
    children: dict[str, NodePlan] = {}
    processes: dict[str, ProcessPlan] = {}
    nodes = {e.name: e.instance() for e in launch.nodes}
    for e in launch.nodes:
        ep = f"tcp://127.0.0.1:{free_port()}" if e.transport == "tcp" else ipc_endpoint(run_dir, e.name)
        child = NodePlan(e, ep, e.container or e.name)
        child.outputs = {t: nodes[e.name].outputs[n].type.TYPE for n, t in e.output_topics(nodes[e.name]).items()}
        child.outputs[DIAGNOSTICS_TOPIC] = Diagnostics.TYPE  # every node publishes it
        child.inputs = {t: nodes[e.name].inputs[n].type.TYPE for n, t in e.input_topics(nodes[e.name]).items()}
        child.inject = {t: ipc_endpoint(run_dir, f"{e.name}.in") for t in child.inputs}
        children[e.name] = child
        proc = processes.setdefault(child.process, ProcessPlan(child.process, [], run_dir / f"{child.process}.spec.json"))
        proc.members.append(child)
    publishers: dict[str, list[str]] = {}
    for name, c in children.items():
        for topic in c.outputs:
            publishers.setdefault(topic, []).append(name)
    taps = {n: tapped for n in children if (tapped := tapped_topics(nodes[n])) is not None}
    specs: dict[str, dict] = {}
    for name, c in children.items():
        # a subscriber in the publisher's own process gets its messages handed over there
        expected = {
            topic: sum(1 for other in children.values() if topic in other.inputs and other.process != c.process)
            + sum(1 for tap, tapped in taps.items() if tap != name and (not tapped or topic in tapped))
            for topic in c.outputs
        }
        local = {t: [p for p in publishers.get(t, []) if p != name and children[p].process == c.process]
                 for t in c.inputs}
        specs[name] = {
            "name": name,
            "pub": c.endpoint,
            "subs": {t: [children[p].endpoint for p in publishers.get(t, [])
                         if children[p].process != c.process] for t in c.inputs},
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
    return LaunchPlan(launch, run_dir, control_ep, children, processes, _start_order(children, processes))


def _start_order(children: dict[str, NodePlan], procs: dict[str, ProcessPlan]) -> list[str]:
    """Processes, subscribers before publishers: reverse topological order, back edges ignored."""
    downstream = {
        name: [o for o, op in procs.items() if o != name and op.inputs & p.outputs] for name, p in procs.items()
    }
    after = {
        name: {children[a].process for c in p.members for a in c.entry.after} - {name}
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
