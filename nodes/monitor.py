"""The monitor: a live one-line status and, on exit, the run's summary and its health.

It listens to ``slip``, ``grip/command``, ``rig/truth``, ``grasp/goal`` and every node's ``diagnostics``,
not to the 1 kHz ``contact`` stream, to keep its share of the CPU small. It logs a ``STATUS`` line
every ``status_period_s``. When it stops, it logs the summary's short form (at most 12 lines), then
the long form as ``detail:`` lines for the run log. It writes the summary as JSON (``summary_path``)
and the check's verdict (``check_path``). docs/summary.md gives the layout, what each count
means (false alarms by the one definition of docs/math.md §3.2) and what fails the check.
Memory stays bounded: running sums and counts, the detection quality streamed by
EpisodeTracker, one counter map per node.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tempfile
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from slipstack.lib.episodes import EpisodeTracker
from slipstack.lib.errors import ConfigError
from slipstack.lib.late_ticks import behind_real_time_advice
from slipstack.lib.status import SLIP_STATES, SlipState
from slipstack.messages import Diagnostics, GraspGoal, GripCommand, Message, RigTruth, Slip
from slipstack.nodes.runtime.graph_info import RUN_DIR_ENV, read_graph
from slipstack.nodes.runtime.host import DIAGNOSTICS_TOPIC
from slipstack.nodes.runtime.logs import DETAIL_PREFIX
from slipstack.nodes.runtime.node import Context, Input, Node

__all__ = ["Monitor", "MonitorParams", "Problem", "summarise", "health_problems", "check_problems", "held_motion",
           "format_summary", "format_details", "status_line", "summary_from_recording", "CALIBRATION_STATUSES"]

CALIBRATION_STATUSES = ("uncalibrated", "calibrated-online", "refused-material")
"""The slip detector's statuses when no identified material gives its thresholds."""

_LOSS_KEYS = (".rejected", ".lost", ".dropped_hwm")  # ".dropped" is drain-to-latest, on purpose
FAIL_SAFE = "fail-safe"
DISCONNECTED = "disconnected"
SKIP_WARN_SHARE = 0.25
"""A node that skipped more than this share of the sensor samples (:data:`SENSOR_TOPICS`)
of a latest-value input is reported on the HEALTH line (at the paper rates fusion skips
5–8 % of F/T samples on a shared 2-core machine: normal; a quarter means the control
path is falling behind). Other skips (the rig acting on the newest grip command) are
only listed."""
SENSOR_TOPICS = ("ft/wrench", "tactile/frame")
MAX_OTHER_NODES = 32
"""Senders of diagnostics outside the graph (tools, other names) the monitor watches; frames of
further ones are counted and dropped (a flood of made-up names must not grow it)."""
MAX_KEPT_COUNTERS = 512
MAX_COUNTER_NAME = 160
"""Counters kept per node, and the longest name kept (characters)."""
SILENT_SHOWN = 5
"""Silent nodes named on the live line; the rest are counted."""
JUDGED_INPUTS = {"grip": "grip commands", "slip": "slip verdicts", "truth": "truth frames"}
"""The inputs the check judges, and what the summary calls their frames: every one of them the graph
published must reach the monitor, or the summary says which it did not see (:class:`Coverage`)."""
SUSPECT_DEVICE_COUNTERS = {"rejected_bytes": "bytes rejected", "crc_errors": "frames failing their check",
                           "implausible_records": "records out of the stream", "bad_frames": "inconsistent frames"}
"""Driver counters (``device.<name>``, nodes/devices/backends.py) that mean the link carried what no sensor sent."""
MOTIONS = ("pivot", "slide")
"""The goals that move the object on purpose: the check judges the motion against what they command."""
MAX_GOALS = 64
"""Goals kept one by one; further ones are counted, and the check does not pass a run it judged in part."""
MARK_PERIOD_NS = 4_000_000
MARKS_KEPT = 4096
"""The truth is kept at most every 4 ms, for the last 4096 marks (16 s at 250 Hz), to find it at a goal's
stamp: a monitor that waited for a core reads a backlog of truth before the goal that came meanwhile."""


@dataclass(frozen=True)
class MonitorParams:
    status_period_s: float = field(default=0.5, metadata={"help": "seconds between STATUS lines"})
    recording: str = field(default="", metadata={"help": "path of the run's recording, shown in the summary if it was written"})
    summary_path: str = field(default="", metadata={"help": "also write the summary as JSON here"})
    command_deadline_ms: float = field(default=20.0, metadata={
        "help": "a grip command older than this at publish (ms from its sensor sample) counts as late"})
    silent_after_s: float = field(default=2.5, metadata={
        "help": "a node whose diagnostics (sent every 1 s) stop for longer than this (s) is reported silent"})
    check_path: str = field(default="", metadata={
        "help": 'on stop, write {"passed": bool, "problems": [...]} as JSON here (the launcher\'s check = true)'})
    check_slip_mm: float = field(default=0.5, metadata={"help": "check fails if the object slid more (mm; rig only)"})
    check_turn_deg: float = field(default=0.5, metadata={
        "help": "check fails if the object turned more (deg; rig only)"})
    check_pivot_deg: float = field(default=2.0, metadata={
        "help": "a pivot goal fails the check unless the object turned within this of its angle (deg; rig only)"})
    check_pivot_slip_mm: float = field(default=1.0, metadata={
        "help": "a pivot goal fails the check if the object slid more while it pivoted (mm; rig only)"})
    check_slide_mm: float = field(default=2.0, metadata={
        "help": "a slide goal fails the check unless the object moved within this of its distance (mm; rig only) "
                "and turned at most check_turn_deg"})
    check_fail_safe_share: float = field(default=0.01, metadata={
        "help": "check fails if a larger share (0..1) of the grip commands was fail-safe"})
    verbose: bool = field(default=False, metadata={
        "help": "print the summary's long form (default: at most 12 short lines; the long form goes to the run log)"})

    def __post_init__(self) -> None:
        for name in ("status_period_s", "command_deadline_ms", "silent_after_s", "check_slip_mm", "check_turn_deg",
                     "check_pivot_deg", "check_pivot_slip_mm", "check_slide_mm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"monitor: {name} must be a finite number > 0, got {value!r}")
        if not (0.0 <= self.check_fail_safe_share <= 1.0):
            raise ConfigError(f"monitor: check_fail_safe_share must be in [0, 1], got {self.check_fail_safe_share!r}")
        for name in ("summary_path", "check_path"):
            path = getattr(self, name)
            if path and os.path.isdir(path):
                raise ConfigError(f"monitor: {name} {path} is a directory; give a file in it "
                                  f"(summary:={os.path.join(path, 'summary.json')})")
        folder = os.path.dirname(os.path.abspath(self.summary_path))
        if self.summary_path and not os.path.isdir(folder):
            raise ConfigError(f"monitor: the folder of summary_path {self.summary_path} does not exist; create it "
                              "or give a path in a folder that does")


@dataclass
class CommandStats:
    """Running numbers of ``grip/command``: count, sum and peak of f_n (N), fail-safe
    counts, and how late the commands computed from a new sample left.

    Two stretches of fail-safe commands are expected and kept apart from the share that
    judges the run: *starting* (every command before the first one on valid data: the
    sensors were not streaming yet) and, with a simulated rig, *after the scene* (the
    commands since the rig's last truth message: the world stopped before its controller).

    A command's age at publish (``pub_ns − stamp_ns``, ns) is its latency only when it was
    computed from a new sample. A *watchdog repeat* (the controller's watchdog repeating
    the last grip because no new verdict came: the same ``slip`` source stamp as the
    previous command, or the same stamp without one) carries the age of the last data,
    which grows while the data stays away: it is counted as a repeat and as fail-safe,
    not as late. Late commands are kept per stretch like the fail-safe ones: ``late``
    and ``age_max_ns`` are those while running (the stretch since the last truth message
    stays open, ``late_after_truth``, until the next one comes); ``late_starting`` and
    ``age_max_starting_ns`` those while the sensors started.
    """

    count: int = 0
    f_n_sum: float = 0.0
    f_n_peak: float = -math.inf
    fail_safe: int = 0
    watchdog_repeats: int = 0
    late: int = 0
    age_max_ns: int = 0
    late_starting: int = 0
    age_max_starting_ns: int = 0
    starting: int = 0
    after_truth: int = 0
    fail_safe_after_truth: int = 0
    late_after_truth: int = 0
    age_max_after_truth_ns: int = 0
    last_verdict_ns: int | None = None

    def add(self, msg: GripCommand, deadline_ns: int) -> None:
        self.count += 1
        self.f_n_sum += msg.f_n_desired
        self.f_n_peak = max(self.f_n_peak, msg.f_n_desired)
        held = msg.reason == FAIL_SAFE
        self.fail_safe += held
        starting = held and self.starting == self.count - 1
        self.starting += starting
        self.after_truth += 1
        self.fail_safe_after_truth += held
        verdict_ns = msg.header.sources.get("slip", msg.header.stamp_ns)
        repeat = verdict_ns == self.last_verdict_ns
        self.last_verdict_ns = verdict_ns
        self.watchdog_repeats += repeat
        if repeat:
            return
        age = msg.header.pub_ns - msg.header.stamp_ns
        if starting:
            self.late_starting += age > deadline_ns
            self.age_max_starting_ns = max(self.age_max_starting_ns, age)
        else:
            self.late_after_truth += age > deadline_ns
            self.age_max_after_truth_ns = max(self.age_max_after_truth_ns, age)

    def truth_seen(self) -> None:
        """The scene is still running: the commands so far were during it."""
        self.after_truth = self.fail_safe_after_truth = 0
        self._commit_late()

    def late_while_running(self, with_rig: bool) -> tuple[int, int]:
        """(late commands, largest age in ns) while the stack ran: without a rig the
        stretch after the last truth message is part of the run too."""
        if with_rig:
            return self.late, self.age_max_ns
        return self.late + self.late_after_truth, max(self.age_max_ns, self.age_max_after_truth_ns)

    def _commit_late(self) -> None:
        self.late += self.late_after_truth
        self.age_max_ns = max(self.age_max_ns, self.age_max_after_truth_ns)
        self.late_after_truth = self.age_max_after_truth_ns = 0

    def judged(self, with_rig: bool) -> tuple[int, int]:
        """(commands, fail-safe commands) while the stack ran: without the starting and,
        with a rig, the after-the-scene stretches (a command in both counts once)."""
        tail, tail_held = (self.after_truth, self.fail_safe_after_truth) if with_rig else (0, 0)
        tail, tail_held = min(tail, self.count - self.starting), min(tail_held, self.fail_safe - self.starting)
        return self.count - self.starting - tail, self.fail_safe - self.starting - tail_held


@dataclass
class Coverage:
    """What the monitor saw of one judged input (:data:`JUDGED_INPUTS`), to compare with what the graph
    published on it: frames handled from the graph's own nodes (not from tools), and the sequence
    number and stamp (ns) of the first and the last of them."""

    seen: int = 0
    first: tuple[int, int] | None = None
    last: tuple[int, int] | None = None

    def add(self, msg: Message, sender: str) -> None:
        if sender:
            return
        self.seen += 1
        mark = (msg.header.seq, msg.header.stamp_ns)
        self.first = self.first or mark
        self.last = mark

    def up_to_s(self, published: int) -> tuple[float | None, float | None]:
        """(seconds from the stream's first frame to the last one seen, to the last one published),
        on a steady rate estimated from the frames seen; ``None`` where it cannot be told."""
        if self.first is None or self.last is None or self.last[0] <= self.first[0]:
            return None, None
        period = (self.last[1] - self.first[1]) / (self.last[0] - self.first[0])
        start = self.first[1] - self.first[0] * period
        return (self.last[1] - start) / 1e9, (published - 1) * period / 1e9


@dataclass(frozen=True, slots=True)
class TruthMark:
    """The rig's truth at one instant: the slip totals (mm, deg) and the object's pose (deg, mm)."""

    slid_mm: float
    turned_deg: float
    theta_deg: float
    x_mm: float
    y_mm: float

    @classmethod
    def of(cls, msg: RigTruth) -> TruthMark:
        return cls(msg.slip_distance_m * 1e3, math.degrees(msg.slip_angle_rad), math.degrees(msg.theta),
                   msg.x * 1e3, msg.y * 1e3)


@dataclass
class GoalLeg:
    """One ``grasp/goal`` and the truth at its stamp (``None`` until a truth that late came): the
    goal's leg of the run lasts until the next goal or the end. ``target``: a pivot's angle (deg)
    or a slide's distance (mm); ``dated``: False when the truth kept no longer reached back to
    the goal's stamp (it starts at the oldest mark kept)."""

    mode: str
    target: float
    stamp_ns: int
    start: TruthMark | None = None
    dated: bool = True


@dataclass
class NodeWatch:
    """One node's diagnostics: its latest counters, when the last report arrived
    (executor time, ns) and the silences between its reports, by the reports' own stamps
    (the sender's clock: a monitor that waited for a core sees no silence), the longest
    and how many exceeded the limit, and whether it came back after one as a new process
    (its diagnostics' sequence number started again) or as the same one (it stalled)."""

    counters: dict = field(default_factory=dict)
    status: str = "ok"
    disconnected_since_ns: int | None = None
    """Stamp of the first report of the current ``disconnected`` status (``None``: connected)."""
    last_seen_ns: int = 0
    last_stamp_ns: int | None = None
    silences: int = 0
    longest_silence_ns: int = 0
    last_seq: int | None = None
    restarted: bool = False

    had_device: bool = False
    """It reported a device status (``disconnected``): a driver, in the data path even before it publishes."""

    @property
    def observer(self) -> bool:
        """It published no data and drives no device (the recorder, the Foxglove bridge, a
        monitor): the control path does not depend on it."""
        return not self.had_device and not any(
            k.startswith("out.") and k.endswith(".published") and v for k, v in self.counters.items())

    def report(self, msg: Diagnostics, now_ns: int, silent_after_ns: int) -> None:
        stamp = msg.header.stamp_ns
        if self.last_stamp_ns is not None:
            gap = stamp - self.last_stamp_ns
            self.longest_silence_ns = max(self.longest_silence_ns, gap)
            self.silences += gap > silent_after_ns
            self.restarted |= gap > silent_after_ns and self.last_seq is not None and msg.header.seq <= self.last_seq
        self.last_seq = msg.header.seq
        self.counters = _kept(msg.counters)
        self.status = msg.status
        if not msg.status.startswith(DISCONNECTED):
            self.disconnected_since_ns = None
        elif self.disconnected_since_ns is None:
            self.disconnected_since_ns = stamp
            self.had_device = True
        self.last_seen_ns = now_ns
        self.last_stamp_ns = stamp


def _kept(counters: dict) -> dict:
    """The counters of one report the monitor keeps: at most :data:`MAX_KEPT_COUNTERS`, names of
    at most :data:`MAX_COUNTER_NAME` characters (a node's own are far fewer and shorter)."""
    if len(counters) <= MAX_KEPT_COUNTERS and all(len(k) <= MAX_COUNTER_NAME for k in counters):
        return counters
    kept = {}
    for key, value in counters.items():
        if len(key) <= MAX_COUNTER_NAME:
            kept[key] = value
            if len(kept) == MAX_KEPT_COUNTERS:
                break
    return kept


class Monitor(Node):
    """Live status line and end-of-run summary of a slipstack graph."""

    name = "monitor"
    inputs = {
        "slip": Input("slip", Slip, policy="queue", depth=10000),
        "grip": Input("grip/command", GripCommand, policy="queue", depth=10000),
        "truth": Input("rig/truth", RigTruth, policy="queue", depth=10000),
        "goal": Input("grasp/goal", GraspGoal, policy="queue", depth=64),
        "diagnostics": Input("diagnostics", Diagnostics, policy="queue", depth=1000),
    }
    Params = MonitorParams
    outlives_graph = True  # a launch stops it last and lets it write the summary

    def __init__(self, params: MonitorParams | None = None, *, graph_nodes: set[str] | None = None) -> None:
        """``graph_nodes``: the names of the graph's nodes, whose silence the monitor judges
        (``None``: read from the run's ``graph.json`` at start, if launched; else every sender)."""
        super().__init__(params)
        self.graph_nodes = graph_nodes
        self.ignored_diagnostics = 0
        """Diagnostics frames from senders beyond :data:`MAX_OTHER_NODES` outside the graph, not watched."""
        self.timers = {"status": self.params.status_period_s}
        self.episodes = EpisodeTracker()
        self.commands = CommandStats()
        self.slip_frames = 0
        self.slip_verdicts = 0  # slip frames whose state is a slip
        self.truth_frames = 0
        self.applied_f_n_sum = 0.0
        self.first_truth_ns: int | None = None
        self.marks: deque[tuple[int, TruthMark]] = deque(maxlen=MARKS_KEPT)
        self.goals: list[GoalLeg] = []
        self.undated: deque[GoalLeg] = deque()  # goals stamped after the newest truth so far, oldest first
        self.goals_not_kept = 0
        self.last: dict[str, object] = {}
        self.nodes: dict[str, NodeWatch] = {}
        self.coverage = {name: Coverage() for name in JUDGED_INPUTS}
        self.topics = {name: self.inputs[name].topic for name in JUDGED_INPUTS}
        """Input → its topic in the graph (remapped at start)."""
        self.numbered: dict[str, dict[str, int]] = {}
        """Node → topic → frames it published, as the launcher heard it when the graph stopped (read at stop)."""
        self._deadline_ns = round(self.params.command_deadline_ms * 1e6)
        self._silent_after_ns = round(self.params.silent_after_s * 1e9)
        self._at_status = (0, 0, 0, 0)  # time, slip frames, commands, fail-safe commands at the last STATUS
        self.declared: dict[str, bool] | None = None
        """Node name → whether it only observes (publishes nothing but diagnostics), as the running
        graph declares it (None: no graph file; the counters tell, :class:`NodeWatch`)."""

    def on_slip(self, msg: Slip, ctx: Context) -> None:
        self.coverage["slip"].add(msg, ctx.sender)
        self.slip_frames += 1
        slipping = msg.state in SLIP_STATES
        self.slip_verdicts += slipping
        self.episodes.add_verdict(msg.header.stamp_ns, slipping, msg.state != SlipState.NO_CONTACT)
        self.last["slip"] = msg

    def on_grip(self, msg: GripCommand, ctx: Context) -> None:
        self.coverage["grip"].add(msg, ctx.sender)
        self.commands.add(msg, self._deadline_ns)
        self.last["grip"] = msg

    def on_truth(self, msg: RigTruth, ctx: Context) -> None:
        self.coverage["truth"].add(msg, ctx.sender)
        self.truth_frames += 1
        self.applied_f_n_sum += msg.f_n_applied
        self.episodes.add_truth(msg.header.stamp_ns, msg.gross_slip)
        self.last["truth"] = msg
        self.commands.truth_seen()
        stamp = msg.header.stamp_ns
        if self.first_truth_ns is None:
            self.first_truth_ns = stamp
        if not self.marks or stamp - self.marks[-1][0] >= MARK_PERIOD_NS:
            self.marks.append((stamp, TruthMark.of(msg)))
        while self.undated and self.undated[0].stamp_ns <= stamp:
            self.undated.popleft().start = TruthMark.of(msg)

    def on_goal(self, msg: GraspGoal, ctx: Context) -> None:
        if len(self.goals) >= MAX_GOALS:
            self.goals_not_kept += 1
            return
        target = {"pivot": math.degrees(msg.angle_rad), "slide": msg.distance_m * 1e3}.get(msg.mode, 0.0)
        leg = GoalLeg(msg.mode, target, msg.header.stamp_ns)
        self.goals.append(leg)
        if not self.marks or self.marks[-1][0] < leg.stamp_ns:
            self.undated.append(leg)  # dated by the first truth at or after its stamp
            return
        leg.start = next((mark for stamp, mark in reversed(self.marks) if stamp <= leg.stamp_ns), None)
        if leg.start is None:
            leg.start, leg.dated = self.marks[0][1], False

    def start(self, ctx: Context) -> None:
        self.topics = {name: ctx.input_topic(name) for name in JUDGED_INPUTS}
        if self.graph_nodes is None and os.environ.get(RUN_DIR_ENV):
            try:
                nodes = read_graph(Path(os.environ[RUN_DIR_ENV]))["nodes"]
                self.graph_nodes = set(nodes)
                self.declared = {name: set(entry.get("outputs", {})) <= {DIAGNOSTICS_TOPIC}
                                 for name, entry in nodes.items()}
            except (OSError, ValueError, KeyError, TypeError, AttributeError):
                ctx.log("warning: cannot read the graph's node list; every sender of diagnostics is judged")

    def on_diagnostics(self, msg: Diagnostics, ctx: Context) -> None:
        watch = self.nodes.get(msg.node)
        if watch is None:
            others = sum(not self.in_graph(name) for name in self.nodes)
            if not self.in_graph(msg.node) and others >= MAX_OTHER_NODES:
                self.ignored_diagnostics += 1
                return
            watch = self.nodes[msg.node] = NodeWatch()
        watch.report(msg, ctx.now_ns(), self._silent_after_ns)

    def in_graph(self, name: str) -> bool:
        """A node of the graph (every sender when the graph's node list is not known)."""
        return self.graph_nodes is None or name in self.graph_nodes

    def silent_nodes(self, now_ns: int) -> dict[str, float]:
        """Nodes of the graph silent now (longer than ``silent_after_s``): name → seconds since
        their last report (a tool that ended, or a forged name, is no silent node)."""
        return {name: (now_ns - w.last_seen_ns) / 1e9 for name, w in self.nodes.items()
                if now_ns - w.last_seen_ns > self._silent_after_ns and self.in_graph(name)}

    def disconnected_nodes(self, since_before_ns: int | None = None) -> dict[str, str]:
        """Nodes whose latest diagnostics say ``disconnected``: name → that status; with
        ``since_before_ns``, only those disconnected since before that stamp."""
        return {name: w.status for name, w in self.nodes.items() if w.disconnected_since_ns is not None
                and (since_before_ns is None or w.disconnected_since_ns <= since_before_ns)}

    def on_timer_status(self, ctx: Context) -> None:
        now = ctx.now_ns()
        t0, slips0, cmds0, fs0 = self._at_status
        dt = (now - t0) / 1e9 if t0 else 0.0
        rate = (self.slip_frames - slips0) / dt if dt > 0 else 0.0
        cmds, fail_safe = self.commands.count - cmds0, self.commands.fail_safe - fs0
        self._at_status = (now, self.slip_frames, self.commands.count, self.commands.fail_safe)
        ctx.log("STATUS " + status_line(self.last, rate, (fail_safe, cmds), sorted(self.silent_nodes(now)),
                                        sorted(self.disconnected_nodes()), self.detector_calibration()))

    def detector_calibration(self) -> str | None:
        """The slip detector's status when its thresholds are not from an identified material
        (``uncalibrated: ...``, ``calibrated-online: ...``, ``refused-material: ...``); None otherwise."""
        watch = self.nodes.get("slip_detector")
        return watch.status if watch is not None and watch.status.split(":")[0] in CALIBRATION_STATUSES else None

    def published(self) -> dict[str, int]:
        """Input → frames the graph published on its topic: the most of what the publishers' newest
        diagnostics say (``out.<topic>.published``) and what they reported as they stopped."""
        out = {}
        for name, topic in self.topics.items():
            key = f"out.{topic}.published"
            said = sum(w.counters.get(key, 0) for w in self.nodes.values())
            out[name] = int(max(said, sum(topics.get(topic, 0) for topics in self.numbered.values())))
        return out

    def read_numbered(self) -> None:
        """What each node published, from the launcher's report in the run directory (launched only)."""
        from slipstack.nodes.recording.loss import NUMBERED_REPORT

        run_dir = os.environ.get(RUN_DIR_ENV)
        if not run_dir:
            return
        try:
            numbered = json.loads((Path(run_dir) / NUMBERED_REPORT).read_text())
            self.numbered = {str(node): {str(t): int(n) for t, n in topics.items()}
                             for node, topics in numbered.items()}
        except (OSError, ValueError, TypeError, AttributeError):
            self.numbered = {}

    def stop(self, ctx: Context) -> None:
        self.read_numbered()
        self.episodes.finish()
        summary = summarise(self, ctx.now_ns())
        for line in format_summary(summary, self.params, verbose=self.params.verbose):
            ctx.log(line)
        if not self.params.verbose:  # the long form, for the run log (the terminal does not show it)
            for line in format_summary(summary, self.params, verbose=True):
                ctx.log(DETAIL_PREFIX + line)
        problems = health_problems(summary, self.params)
        summary["health"] = [dataclasses.asdict(x) for x in problems]
        files = [(self.params.summary_path, summary)] if self.params.summary_path else []
        if self.params.check_path:
            failed = [x for x in problems if x.fails_check]
            files.append((self.params.check_path, {"passed": not failed, "problems": [x.text for x in failed],
                                                   "short": [x.short for x in failed],
                                                   "judged_whole": not summary["monitor_unseen"]}))
        for path, content in files:
            try:
                write_json_atomically(path, content)
            except OSError as exc:  # a full disk: the lines above are the summary
                ctx.report_error(f"cannot write {path} ({exc.strerror})")


def summary_from_recording(monitor: Monitor, path: str, log: Callable[[str], None]) -> None:
    """Run ``monitor`` over the recording ``path`` (its inputs, each at the time the recorder
    received it): its summary goes to ``log`` (the live STATUS lines left out) and to its
    summary and check files, as at the end of a run. The launch does this when its monitor
    died during the run, which would otherwise sum up only the time since it came back."""
    from slipstack.nodes.recording.bag_io import replay_into

    replay_into(monitor, path, log=lambda line: None if "] STATUS " in line else log(line))


def write_json_atomically(path: str, content: dict) -> None:
    """Write ``content`` as JSON to a temporary file beside ``path``, then rename it over
    ``path``: a reader sees the old file or the whole new one, never a part. The file
    gets the usual permissions (0666 less the umask), not the temporary file's 0600."""
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".monitor-", suffix=".json", dir=folder)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)
        with os.fdopen(fd, "w") as fh:
            json.dump(content, fh, indent=1)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def status_line(last: dict[str, object], rate_hz: float, fail_safe: tuple[int, int] = (0, 0),
                silent: list[str] | None = None, disconnected: list[str] | None = None,
                calibration: str | None = None) -> str:
    """One line: state, f_n, command, margin, COR, detector rate; then, when there are
    any, the fail-safe commands ``fail_safe = (held, of commands)`` since the last line,
    the silent nodes, the nodes whose device is disconnected, and the detector's
    calibration when no identified material gives its thresholds."""
    slip = last.get("slip")
    grip = last.get("grip")
    parts = [f"state={slip.state if slip else '-':<11}"]
    parts.append(f"f_n={slip.f_n:6.2f} N" if slip else "f_n=   -  ")
    parts.append(f"cmd={grip.f_n_desired:6.2f} N" if grip else "cmd=   -  ")
    margin = slip.margin if slip else float("nan")
    parts.append(f"margin={margin:+.3f}" if math.isfinite(margin) else "margin=  -   ")
    if slip is not None and slip.p_c_valid:
        parts.append(f"cor=({slip.p_c[0] * 1e3:+.2f},{slip.p_c[1] * 1e3:+.2f}) mm")
    else:
        parts.append("cor=-")
    parts.append(f"rate={rate_hz:5.0f} Hz")
    held, commands = fail_safe
    if held:
        parts.append(f"FAIL-SAFE {held / commands * 100:.0f}% ({held} of {commands} commands)")
    if silent:
        more = f" +{len(silent) - SILENT_SHOWN}" if len(silent) > SILENT_SHOWN else ""
        parts.append("SILENT " + ",".join(silent[:SILENT_SHOWN]) + more)
    if disconnected:
        parts.append("DISCONNECTED " + ",".join(disconnected))
    if calibration:
        parts.append(calibration.split(":")[0].upper())
    return "  ".join(parts)


def _share(part: int, whole: int) -> float | None:
    return part / whole if whole else None


def summarise(m: Monitor, now_ns: int) -> dict:
    """The run's numbers as a JSON-able dict (``now_ns``: executor time of the end)."""
    q = m.episodes.quality()
    cmd = m.commands
    losses = {node: _losses(w.counters) for node, w in m.nodes.items()}
    skipped = {
        node: {k[3:-8]: {"skipped": v, "received": w.counters.get(k[:-8] + ".received", 0)}
               for k, v in w.counters.items() if k.startswith("in.") and k.endswith(".dropped") and v}
        for node, w in m.nodes.items()
    }
    behind = {
        node: {k: v for k, v in w.counters.items() if k.startswith("timer.") and k.endswith(".skipped") and v}
        for node, w in m.nodes.items()
    }
    silent_now = m.silent_nodes(now_ns)
    went_silent = {name: w.longest_silence_ns / 1e9 for name, w in m.nodes.items() if w.silences and m.in_graph(name)}
    truth = m.last.get("truth")
    judged, judged_fail_safe = cmd.judged(with_rig=truth is not None)
    late, age_max_ns = cmd.late_while_running(with_rig=truth is not None)
    unseen = _unseen(m)
    if unseen:
        losses[m.name] = {**losses.get(m.name, {}), **{
            f"unseen.{u['topic']}": {"topic": u["topic"], "lost": u["unseen"], "of": u["published"],
                                     "how": "not seen by the monitor, of those published"} for u in unseen.values()}}
    return {
        "has_truth": truth is not None,
        "slip_frames": m.slip_frames,
        "true_episodes": m.episodes.episode_count if truth else None,
        "detected_episodes": m.episodes.detected if truth else None,
        "missed_episodes": m.episodes.missed if truth else None,
        "detection_delay_ms_p50": q.delay_percentile_ms(50) if q.delays_ns and truth else None,
        "detection_delay_ms_p95": q.delay_percentile_ms(95) if q.delays_ns and truth else None,
        "latch_hold_ms_p50": q.hold_percentile_ms(50) if q.holds_ns and truth else None,
        "latch_hold_ms_p95": q.hold_percentile_ms(95) if q.holds_ns and truth else None,
        "stick_frames": q.stick_frames if truth else None,
        "false_alarm_share": q.false_alarm_share if truth else None,
        "latch_hold_share": q.latch_hold_share if truth else None,
        "slip_verdicts": m.slip_verdicts,
        "grip_commands": cmd.count,
        "grip_command_mean_n": cmd.f_n_sum / cmd.count if cmd.count else None,
        "grip_command_peak_n": cmd.f_n_peak if cmd.count else None,
        "commands_while_running": judged,
        "fail_safe_commands": judged_fail_safe,
        "fail_safe_share": _share(judged_fail_safe, judged),
        "fail_safe_while_starting": cmd.starting,
        "fail_safe_after_scene": cmd.fail_safe_after_truth if truth else 0,
        "command_deadline_ms": m.params.command_deadline_ms,
        "late_commands": late,
        "late_share": _share(late, judged),
        "command_age_ms_max": age_max_ns / 1e6 if judged else None,
        "late_while_starting": cmd.late_starting,
        "command_age_ms_max_while_starting": cmd.age_max_starting_ns / 1e6 if cmd.starting else None,
        "late_after_scene": cmd.late_after_truth if truth else 0,
        "watchdog_repeats": cmd.watchdog_repeats,
        "applied_f_n_mean_n": m.applied_f_n_sum / m.truth_frames if m.truth_frames else None,
        "slip_distance_mm": truth.slip_distance_m * 1e3 if truth else None,
        "slip_angle_deg": math.degrees(truth.slip_angle_rad) if truth else None,
        "goals": _goal_legs(m),
        "goals_not_kept": m.goals_not_kept,
        "losses": {n: v for n, v in losses.items() if v},
        "monitor_unseen": unseen,
        "skipped_for_newer": {n: v for n, v in skipped.items() if v},
        "ft_samples": _ft_samples(m.nodes),
        "behind_real_time": {n: v for n, v in behind.items() if v},
        "silent_nodes": silent_now,
        # with a simulated rig, the devices close when its scene ends: only earlier losses count
        "disconnected_nodes": m.disconnected_nodes(truth.header.stamp_ns if truth else None),
        "detector_calibration": m.detector_calibration(),
        "nodes_that_went_silent": went_silent,
        "nodes_restarted_after_silence": sorted(name for name, w in m.nodes.items() if w.restarted),
        "observers": sorted(name for name, w in m.nodes.items()
                            if (m.declared or {}).get(name, w.observer)),
        "behind_while_realtime": sorted(name for name, w in m.nodes.items() if any(
            k.startswith("timer.") and k.endswith(".skipped_realtime") and v for k, v in w.counters.items())),
        "recording": m.params.recording if m.params.recording and os.path.exists(m.params.recording) else "",
        "recorders": _recorders(m.nodes),
        "device_rejects": _device_rejects(m.nodes),
        "diagnostics_senders_outside_graph": sorted(name for name in m.nodes if not m.in_graph(name)),
        "diagnostics_ignored": m.ignored_diagnostics,
        "clock_offsets": _clock_offsets(m.nodes),
        "injected": {what: sum(w.counters.get(key, 0) for w in m.nodes.values()) for what, key in INJECTED.items()},
        "steps_without_a_start": sum(w.counters.get("grip.waiting_to_start", 0) for w in m.nodes.values()),
    }


def _goal_legs(m: Monitor) -> list[dict]:
    """Each goal's leg of the run, from the truth at its stamp to the truth at the next one's (or the
    last): ``at_s`` from the first truth; ``slid_mm``, ``turned_deg``: the slip totals' growth
    (path length, signed angle); ``moved``: the pose's change, a pivot's turn (deg), a slide's
    distance (mm); ``None`` without truth."""
    truth = m.last.get("truth")
    end = TruthMark.of(truth) if truth else None
    out = []
    for k, leg in enumerate(m.goals):
        a = leg.start
        b = m.goals[k + 1].start if k + 1 < len(m.goals) and m.goals[k + 1].start is not None else end
        row = {"mode": leg.mode, "target": leg.target, "slid_mm": None, "turned_deg": None, "moved": None,
               "at_s": (leg.stamp_ns - m.first_truth_ns) / 1e9 if m.first_truth_ns is not None else None,
               "dated": leg.dated}
        if a is not None and b is not None:
            row["slid_mm"], row["turned_deg"] = b.slid_mm - a.slid_mm, b.turned_deg - a.turned_deg
            row["moved"] = (abs(b.theta_deg - a.theta_deg) if leg.mode == "pivot"
                            else math.hypot(b.x_mm - a.x_mm, b.y_mm - a.y_mm))
        out.append(row)
    return out


def _unseen(m: Monitor) -> dict[str, dict]:
    """The judged inputs of which the graph published frames the monitor did not see: input →
    ``{topic, seen, published, unseen, seen_up_to_s, published_up_to_s}`` (the times from the
    stream's first frame; ``None`` where they cannot be told)."""
    out = {}
    for name, published in m.published().items():
        c = m.coverage[name]
        if published > c.seen:
            seen_s, published_s = c.up_to_s(published)
            out[name] = {"topic": m.topics[name], "seen": c.seen, "published": published,
                         "unseen": published - c.seen, "seen_up_to_s": seen_s, "published_up_to_s": published_s,
                         "tail_unseen": c.last is None or c.last[0] + 1 < published}
    return out


INJECTED = {"grip_commands": "rig.manual_commands", "slip_verdicts": "grip.injected_verdicts",
            "finger_reports": "grip.injected_finger_reports"}
"""What tools injected where the launch allows it (``allow_inject``): summary key → counter."""




def _ft_samples(nodes: dict[str, NodeWatch]) -> dict[str, float]:
    """F/T samples over the run: ``received`` by fusion (its ``ft/wrench`` input), ``carried``
    in its contacts, ``judged`` by the slip test (a verdict on valid data or a loss of
    contact; the rest had no usable data and held the grip)."""
    totals = {"received": 0.0, "carried": 0.0, "judged": 0.0, "implausible": 0.0}
    for w in nodes.values():
        c = w.counters
        if "fusion.samples" in c:
            totals["received"] += c.get("in.ft/wrench.received", 0)
            totals["carried"] += c["fusion.samples"]
            totals["implausible"] += c.get("fusion.implausible_ft", 0)
        totals["judged"] += c.get("slip_test.samples_judged", 0)
    return totals


def _device_rejects(nodes: dict[str, NodeWatch]) -> dict[str, dict[str, float]]:
    """Per driver, its device counters that say the link carried what no sensor sent."""
    out = {}
    for node, w in sorted(nodes.items()):
        seen = {k: w.counters[f"device.{k}"] for k in SUSPECT_DEVICE_COUNTERS if w.counters.get(f"device.{k}")}
        if seen:
            out[node] = seen
    return out


def _recorders(nodes: dict[str, NodeWatch]) -> dict[str, dict]:
    """Each recorder's status and how often it fell behind (its counters ``recorder.*``)."""
    return {node: {"status": w.status, "fell_behind": w.counters.get("recorder.fell_behind", 0)}
            for node, w in sorted(nodes.items()) if "recorder.written" in w.counters}


def _clock_offsets(nodes: dict[str, NodeWatch]) -> dict[str, dict[str, dict[str, float]]]:
    """The launchers' newest clock offsets (a graph over machines, launch/clock_report.py):
    ``{launcher: {other machine: {"offset_ms", "uncertainty_ms"}}}``."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for node, w in sorted(nodes.items()):
        for key, value in w.counters.items():
            if key.startswith("clock.") and key.endswith(".offset_ns"):
                peer = key[len("clock."):-len(".offset_ns")]
                out.setdefault(node, {})[peer] = {
                    "offset_ms": value / 1e6, "uncertainty_ms": w.counters.get(f"clock.{peer}.uncertainty_ns", 0.0) / 1e6}
    return out


def _losses(counters: dict) -> dict[str, dict[str, float]]:
    """Frames a node lost, each with its denominator: ``{what: {"lost": n, "of": total,
    "topic": t, "how": ...}}`` for rejected frames (of those received), sequence gaps (of
    those sent: received + lost) and send-queue drops (of those published)."""
    out = {}
    for key, n in counters.items():
        if not n or not key.endswith(_LOSS_KEYS):
            continue
        stem, kind = key.rsplit(".", 1)
        topic = stem.split(".", 1)[1] if "." in stem else stem
        received = counters.get(f"{stem}.received", 0)
        of, how = {"rejected": (received, "rejected as malformed, of those received"),
                   "lost": (received + n, "sequence gaps, of those sent"),
                   "dropped_hwm": (counters.get(f"{stem}.published", 0) + n, "send queue full, of those sent")}[kind]
        out[key] = {"topic": topic, "lost": n, "of": of, "how": how}
    return out


SUMMARY_WIDTH = 90
"""Characters of a summary line: within 100 on the terminal behind the launcher's ``[monitor] ``."""
SUMMARY_MAX_LINES = 12
TITLE = "==== slipstack run summary ===="


@dataclass(frozen=True)
class Problem:
    """One thing that went wrong: ``short`` for the summary's HEALTH line, ``text`` with its
    numbers and what to do (the long form, ``check.json``); ``fails_check``: it fails the run's
    check (docs/summary.md says which do)."""

    short: str
    text: str
    fails_check: bool = True


def health_problems(s: dict, p: MonitorParams) -> list[Problem]:
    """What the HEALTH lines report: first what fails the check (the object slid or turned
    more than allowed, too many fail-safe commands, missed episodes, a silent node of the
    data path, no valid sensor data at all), then what is only reported (an observer's
    silence, disconnected devices, signs of falling behind, sensor attacks, the recording's
    loss, what tools injected)."""
    return (_check_problems(s, p) + _silence_problems(s) + _device_problems(s) + _behind_problems(s)
            + _sensor_problems(s) + _recording_problems(s) + _injection_problems(s))


def check_problems(s: dict, p: MonitorParams) -> list[str]:
    """What fails the run's check (``check = true`` in a launch file), in words; empty: passed."""
    return [x.text for x in health_problems(s, p) if x.fails_check]


def _check_problems(s: dict, p: MonitorParams) -> list[Problem]:
    out = []
    slid, turned = held_motion(s)
    apart = " apart from the goals" if _motion_legs(s) else ""
    if slid is not None and slid > p.check_slip_mm:
        out.append(Problem(f"object slid {slid:.2f} mm{apart} (allowed {p.check_slip_mm:g})",
                           f"the object slid {slid:.2f} mm{apart} (allowed {p.check_slip_mm:g} mm)"))
    if turned is not None and abs(turned) > p.check_turn_deg:
        out.append(Problem(f"object turned {abs(turned):.2f} deg{apart} (allowed {p.check_turn_deg:g})",
                           f"the object turned {abs(turned):.2f} deg{apart} (allowed {p.check_turn_deg:g} deg)"))
    for leg in _motion_legs(s):
        out += _goal_problems(leg, p)
    if s.get("goals_not_kept"):
        out.append(Problem(f"{s['goals_not_kept']} goals after the first {MAX_GOALS} not judged one by one",
                           f"{s['goals_not_kept']} grasp goals came after the first {MAX_GOALS}: the check judged "
                           "the last kept goal up to the end of the run, theirs included; send fewer goals (`topic "
                           "pub` without --once repeats its goal every second)"))
    share = s["fail_safe_share"]
    if share is not None and share > p.check_fail_safe_share:
        out.append(Problem(f"fail-safe {share * 100:.1f}% of commands (allowed {p.check_fail_safe_share * 100:g}%)",
                           f"{share * 100:.1f}% of the grip commands were fail-safe ({s['fail_safe_commands']} of "
                           f"{s['commands_while_running']}; allowed {p.check_fail_safe_share * 100:g}%)"))
    if s["missed_episodes"]:
        out.append(Problem(f"detector missed {s['missed_episodes']} of {s['true_episodes']} slip episodes",
                           f"the detector missed {s['missed_episodes']} of {s['true_episodes']} true slip episodes"))
    if s["grip_commands"] and s["fail_safe_while_starting"] == s["grip_commands"]:
        out.append(Problem("every command fail-safe: no valid sensor data",
                           f"all {s['grip_commands']} grip commands were fail-safe: the controller never had valid "
                           "sensor data (are the sensors connected and streaming?)"))
    out += _unseen_problems(s)
    if not s["grip_commands"] and s.get("steps_without_a_start"):
        out.append(Problem("no command: no trusted sensor data, the finger kept its grip",
                           "the controller sent no grip command: it never had trusted sensor data nor the finger's "
                           "report (grip/state), so the finger kept its own grip (are the sensors connected and "
                           "streaming? docs/safety.md, clause 4)"))
    return out


def _motion_legs(s: dict) -> list[dict]:
    """The pivot and slide goals' legs with truth: the check judges them against their goal."""
    return [leg for leg in s.get("goals") or [] if leg["mode"] in MOTIONS and leg["moved"] is not None]


def held_motion(s: dict) -> tuple[float | None, float | None]:
    """How far the object slid (mm) and turned (deg, signed) outside the pivot and slide goals:
    the truth's totals less those goals' legs; ``None`` without truth."""
    slid, turned = s["slip_distance_mm"], s["slip_angle_deg"]
    if slid is None or turned is None:
        return None, None
    legs = _motion_legs(s)
    return slid - sum(leg["slid_mm"] for leg in legs), turned - sum(leg["turned_deg"] for leg in legs)


def _goal_problems(leg: dict, p: MonitorParams) -> list[Problem]:
    """A pivot goal's leg must turn the object by its angle (± ``check_pivot_deg``) and slide it at
    most ``check_pivot_slip_mm``; a slide goal's must move it by its distance (± ``check_slide_mm``)
    and turn it at most ``check_turn_deg``: short of the goal, past it (a drop), or off its axis."""
    at, target, moved = _num(leg["at_s"], ".1f"), leg["target"], leg["moved"]
    pivot = leg["mode"] == "pivot"
    tol, unit, verb = (p.check_pivot_deg, "deg", "turned") if pivot else (p.check_slide_mm, "mm", "moved")
    out = []
    if not leg.get("dated", True):
        out.append(Problem(f"{leg['mode']} goal at {at} s came too late to date: judged in part",
                           f"the {leg['mode']} goal stamped {at} s reached the monitor when the truth it keeps no "
                           "longer reached back to that time (it waited for a CPU core), so its motion was judged "
                           "from the oldest truth kept; free a CPU core, or give the monitor a real-time priority "
                           "(its `realtime_priority` in the launch file)"))
    if abs(moved - target) > tol:
        out.append(Problem(f"{leg['mode']} {target:g} {unit} at {at} s: {verb} {moved:.2f} {unit} (allowed ±{tol:g})",
                           f"the object {verb} {moved:.2f} {unit} after the {leg['mode']} goal at {at} s (commanded "
                           f"{target:g} {unit}, allowed ±{tol:g}): short of it (the load could not move it so far, "
                           "the run ended, or a later goal came first) or past it (the grasp lost it); grasp/state's "
                           "`ended` says how the motion ended"))
    if pivot and leg["slid_mm"] > p.check_pivot_slip_mm:
        out.append(Problem(f"pivot at {at} s: object slid {leg['slid_mm']:.2f} mm (allowed {p.check_pivot_slip_mm:g})",
                           f"the object slid {leg['slid_mm']:.2f} mm after the pivot goal at {at} s (allowed "
                           f"{p.check_pivot_slip_mm:g} mm): it did not only turn"))
    if not pivot and abs(leg["turned_deg"]) > p.check_turn_deg:
        out.append(Problem(f"slide at {at} s: object turned {abs(leg['turned_deg']):.2f} deg "
                           f"(allowed {p.check_turn_deg:g})",
                           f"the object turned {abs(leg['turned_deg']):.2f} deg after the slide goal at {at} s "
                           f"(allowed {p.check_turn_deg:g} deg): it did not only slide"))
    return out


def _unseen_problems(s: dict) -> list[Problem]:
    """Frames of the judged inputs the graph published and the monitor never saw: the check judged
    part of the run only, so it does not pass it."""
    unseen = s.get("monitor_unseen") or {}
    if not unseen:
        return []
    parts = [f"{u['unseen']} of {u['published']} {JUDGED_INPUTS[name]}" for name, u in unseen.items()]
    truth = unseen.get("truth")
    seen_s, of_s = (truth["seen_up_to_s"], truth["published_up_to_s"]) if truth else (None, None)
    until = f"truth up to {seen_s:.1f} s of {of_s:.1f} s" if seen_s is not None else ""
    if truth and truth["tail_unseen"]:
        short = (f"monitor saw {until}" if until else f"monitor missed the last of {truth['published']} truth frames"
                 ) + ": not judged to the end"
    else:
        name, u = max(unseen.items(), key=lambda item: item[1]["unseen"])
        short = f"monitor missed {u['unseen']} of {u['published']} {JUDGED_INPUTS[name]}: judged in part"
    return [Problem(short, f"the monitor did not see {', '.join(parts)}" + (f" (it saw {until})" if until else "")
                    + ": it fell behind its inputs (it waited for a CPU core, or was stopped), so the check judged "
                    "only what it saw; free a CPU core, or give the monitor a real-time priority (its "
                    "`realtime_priority` in the launch file)")]


def _silence_problems(s: dict) -> list[Problem]:
    """Nodes silent at the end, or silent for a while and back. A node of the data path fails
    the check; an observer (it published no data: the recorder, the Foxglove bridge) is
    reported only, as the control path does not depend on it."""
    out = []
    observers = set(s["observers"])
    for node, seconds in sorted(s["silent_nodes"].items()):
        observer = node in observers
        out.append(Problem(f"{node} silent for the last {seconds:.1f} s" + (" (observer)" if observer else ""),
                           f"node {node} went silent: no diagnostics for the last {seconds:.1f} s (dead or stopped?)"
                           + (_OBSERVER_NOTE if observer else ""), not observer))
    for node, seconds in sorted(s["nodes_that_went_silent"].items()):
        if node in s["silent_nodes"]:
            continue
        observer = node in observers
        restarted = node in s["nodes_restarted_after_silence"]
        how = ("as a new process (restarted)" if restarted else
               "as the same process (it stalled: a machine too busy, or stopped and continued)")
        out.append(Problem(f"{node} silent {seconds:.1f} s, then back ({'restarted' if restarted else 'stalled'}"
                           + (", observer)" if observer else ")"),
                           f"node {node} went silent for {seconds:.1f} s and came back {how}"
                           + (_OBSERVER_NOTE if observer else ""), not observer))
    return out


_OBSERVER_NOTE = ("; it only observes (it publishes no data), so the control path did not depend on it and the "
                  "check does not judge it")


def _device_problems(s: dict) -> list[Problem]:
    """Drivers whose device was disconnected at the end (with a rig: already before its scene ended)."""
    return [Problem(_clip(f"{node} {status}", 60), f"{node} ended {status} (see docs/drivers.md)", False)
            for node, status in sorted(s["disconnected_nodes"].items())]


def device_problems(s: dict) -> list[str]:
    """Drivers whose device was disconnected at the end, in words."""
    return [x.text for x in _device_problems(s)]


def _sensor_problems(s: dict) -> list[Problem]:
    """Sensors under attack or off: device links that carried what no sensor sends (forged,
    stray or garbage data), an F/T sensor reading implausibly low against the pad (biased,
    tared under load, or spoofed); diagnostics from made-up senders beyond the bound."""
    out = []
    for node, seen in sorted(s.get("device_rejects", {}).items()):
        what = ", ".join(f"{SUSPECT_DEVICE_COUNTERS[k]} {v:g}" for k, v in sorted(seen.items()))
        out.append(Problem(f"{node}: its link carried invalid data ({what.split(',')[0]})",
                           f"{node}'s device link carried data that is no valid sample ({what}): forged, stray or "
                           "garbage datagrams, another program writing to the link, or bytes lost or damaged on "
                           "it; find what else writes to it (docs/drivers.md)", False))
    ft = s.get("ft_samples") or {}
    if ft.get("implausible"):
        out.append(Problem(f"F/T implausibly low vs the pad in {ft['implausible']:g} samples",
                           f"the F/T sensor read implausibly low against the pad in {ft['implausible']:g} of "
                           f"{ft['received']:g} samples (biased, tared under load, or spoofed): the grip was held; "
                           "tare it unloaded (docs/safety.md, clause 7)", False))
    if s.get("diagnostics_ignored"):
        out.append(Problem(f"{s['diagnostics_ignored']:g} diagnostics from unknown senders ignored",
                           f"{s['diagnostics_ignored']:g} diagnostics frames from more than {MAX_OTHER_NODES} senders "
                           "outside the graph were ignored (made-up node names on the bus?)", False))
    return out


def _recording_problems(s: dict) -> list[Problem]:
    """A recorder that cannot write its file (a full disk) or fell behind."""
    out = []
    for node, r in sorted(s.get("recorders", {}).items()):
        if r["status"].startswith("error: cannot write the recording"):
            why = r["status"].split(": ")[-1]
            out.append(Problem(f"recorder cannot write its file ({why})",
                               f"the recorder cannot write its file ({why}): the frames since are counted, not "
                               "recorded (the launch's recording line says how many)", False))
        elif r["fell_behind"]:
            out.append(Problem(f"{node} fell behind {r['fell_behind']:g}x",
                               f"{node} fell behind {r['fell_behind']:g}x (frames written over 1 s after they were "
                               "sent): a busy machine; the launch's recording line says what the file misses", False))
    return out


def _behind_problems(s: dict) -> list[Problem]:
    """Signs that the graph fell behind: late commands, timer ticks skipped, more than
    :data:`SKIP_WARN_SHARE` of a sensor topic's samples not examined by a node of the data path."""
    out = []
    observers = set(s["observers"])
    if s["late_commands"]:
        out.append(Problem(
            f"{s['late_commands']} of {s['commands_while_running']} commands late (over "
            f"{s['command_deadline_ms']:g} ms, worst {s['command_age_ms_max']:.0f} ms)",
            f"{s['late_commands']} of {s['commands_while_running']} grip commands while running "
            f"({s['late_share'] * 100:.2g}%) left later than {s['command_deadline_ms']:g} ms after their sample "
            f"(worst {s['command_age_ms_max']:.1f} ms): the control path waited for a CPU core; free a core or "
            "raise the stack's priority (the launch file's `realtime_priority` or `nice`)", False))
    for node, timers in sorted(s["behind_real_time"].items()):
        skipped = sum(timers.values())
        ticks = ", ".join(f"{k.split('.')[1]} {v:g}" for k, v in sorted(timers.items()))
        if node in observers:
            out.append(Problem(f"{node} fell behind ({skipped:g} timer ticks skipped; observer)",
                               f"{node} fell behind (timer ticks skipped: {ticks}): it is not real-time and "
                               "waited for a CPU core; what it records or shows lags behind the graph (`slipstack "
                               "bag info` shows any frames it lost); free a core or record fewer topics", False))
            continue
        out.append(Problem(f"{node} behind real time ({skipped:g} timer ticks skipped)",
                           f"{node} fell behind real time (timer ticks skipped: {ticks}; its diagnostics say how "
                           f"late): {behind_real_time_advice(node in s['behind_while_realtime'])}", False))
    for node, inputs in sorted(s["skipped_for_newer"].items()):
        if node in observers:
            continue
        for topic, n in sorted(inputs.items()):
            share = n["skipped"] / n["received"] if n["received"] else 0.0
            if topic in SENSOR_TOPICS and share > SKIP_WARN_SHARE:
                out.append(Problem(f"{node} skipped {share * 100:.0f}% of {topic}",
                                   f"{node} did not examine {share * 100:.0f}% of {topic} (skipped for a newer one, "
                                   "or beyond a batch's depth): it fell behind its input; free a CPU core or raise "
                                   "the stack's priority (the launch file's `realtime_priority` or `nice`)", False))
    return out


def _injection_problems(s: dict) -> list[Problem]:
    """Grip commands the finger took from a tool, slip verdicts and finger reports the controller did not trust."""
    n = s.get("injected", {})
    if not any(n.values()):
        return []
    return [Problem(f"injected by tools: {n['grip_commands']:g} grip commands, {n['slip_verdicts']:g} verdicts",
                    f"injected by tools (allow_inject): {n['grip_commands']:g} grip commands obeyed (the finger's log "
                    f"names who sent them), {n['slip_verdicts']:g} verdicts and {n['finger_reports']:g} finger reports "
                    "not trusted (the grip held)", False)]


def behind_problems(s: dict) -> list[str]:
    """Signs that the graph fell behind, in words."""
    return [x.text for x in _behind_problems(s)]


def _clip(text: str, width: int = SUMMARY_WIDTH) -> str:
    return text if len(text) <= width else text[: width - 1] + "…"


def _num(v: float | None, fmt: str) -> str:
    return "-" if v is None else format(v, fmt)


def _pct(v: float | None) -> str:
    return "-" if v is None else f"{v * 100:.1f}%"


# -- the summary: short (the terminal) and long (verbose:=true, the run log) --------------------------
def format_summary(s: dict, p: MonitorParams | None = None, *, verbose: bool = False) -> list[str]:
    """The summary: at most :data:`SUMMARY_MAX_LINES` lines of at most :data:`SUMMARY_WIDTH`
    characters, one subject a line (docs/summary.md); ``verbose``: the long form, every count
    with its denominator and a HEALTH line per problem with what to do."""
    p = p or MonitorParams()
    problems = health_problems(s, p)
    if verbose:
        return format_details(s, problems, p)
    rows = [TITLE, *(_truth_rows(s, p) if s["has_truth"] else _no_truth_rows(s)), _control_row(s), _bus_row(s)]
    clocks = [f"{peer} {c['offset_ms']:+.3f} ms ± {c['uncertainty_ms']:.3f}"
              for peers in s.get("clock_offsets", {}).values() for peer, c in sorted(peers.items())]
    if clocks:
        rows.append("clocks: " + ", ".join(clocks) + " (other machines' minus ours)")
    if s["detector_calibration"]:
        row = "detector: " + s["detector_calibration"]
        rows.append(row if len(row) <= SUMMARY_WIDTH else row.split(" (")[0])  # its numbers: the long form
    if s["recording"]:
        rows.append("recording: " + s["recording"])
    rows = [_clip(row) for row in rows]
    return rows + _health_rows([x.short for x in problems], max(1, SUMMARY_MAX_LINES - len(rows)))


def _truth_rows(s: dict, p: MonitorParams) -> list[str]:
    held_slid, held_turned = held_motion(s)
    held = "held" if held_slid <= p.check_slip_mm and abs(held_turned) <= p.check_turn_deg else "MOVED"
    legs = _motion_legs(s)
    rows = [f"object: {held}{' apart from the goals' if legs else ''}, slid {_num(s['slip_distance_mm'], '.2f')} mm "
            f"and turned {_num(s['slip_angle_deg'], '.2f')} deg in all"]
    if legs:
        rows.append(_goal_row(legs, p))
    n, found = s["true_episodes"], s["detected_episodes"]
    if not n:
        slip = "no true slip episode"
    else:
        slip = f"{found} of {n} true episodes detected ({s['missed_episodes']} missed)"
        if found:
            slip += f", delay p50 {s['detection_delay_ms_p50']:.1f} ms, p95 {s['detection_delay_ms_p95']:.1f} ms"
    rows.append("slip: " + slip)
    share = s["false_alarm_share"]
    reading = "" if not share else (" (early warnings acted on)" if s["grip_commands"] else " (false alarms)")
    rows.append(f"flags: {_pct(share) if share is None else f'{share * 100:.2f}%'} of {s['stick_frames']} sticking "
                f"frames flagged outside slip{reading}")
    rows.append(f"grip: commanded mean {_num(s['grip_command_mean_n'], '.2f')} N, peak "
                f"{_num(s['grip_command_peak_n'], '.2f')} N; applied mean {_num(s['applied_f_n_mean_n'], '.2f')} N")
    return rows


def _goal_row(legs: list[dict], p: MonitorParams) -> str:
    """The pivot and slide goals: the one goal's motion against its command, or how many went as commanded."""
    missed = [leg for leg in legs if _goal_problems(leg, p)]
    if len(legs) == 1:
        return "goal: " + _goal_text(legs[0], p) + (": NOT as commanded" if missed else ": as commanded")
    row = f"goal: {len(legs) - len(missed)} of {len(legs)} pivots and slides as commanded"
    return row + (f"; not: {_goal_text(missed[0], p)}" if missed else "")


def _goal_text(leg: dict, p: MonitorParams) -> str:
    """``pivot 30 deg at 1.5 s: turned 29.00 deg (±2), slid 0.17 mm`` (or a slide's, moved and turned)."""
    head = f"{leg['mode']} {leg['target']:g} "
    if leg["mode"] == "pivot":
        return (head + f"deg at {_num(leg['at_s'], '.1f')} s: turned {leg['moved']:.2f} deg (±{p.check_pivot_deg:g}),"
                f" slid {leg['slid_mm']:.2f} mm")
    return (head + f"mm at {_num(leg['at_s'], '.1f')} s: moved {leg['moved']:.2f} mm (±{p.check_slide_mm:g}), "
            f"turned {abs(leg['turned_deg']):.2f} deg")


def _no_truth_rows(s: dict) -> list[str]:
    return [f"slip: no ground truth (real hardware); slip in {s['slip_verdicts']} of {s['slip_frames']} verdicts",
            f"grip: commanded mean {_num(s['grip_command_mean_n'], '.2f')} N, peak "
            f"{_num(s['grip_command_peak_n'], '.2f')} N"]


def _control_row(s: dict) -> str:
    if not s["grip_commands"]:
        return "control: no grip commands (detection only, or the controller never ran)"
    row = (f"control: {s['grip_commands']} commands; fail-safe {_pct(s['fail_safe_share'])} "
           f"({s['fail_safe_commands']} of {s['commands_while_running']}), late {_pct(s['late_share'])}")
    if s["late_commands"]:
        row += f" ({s['late_commands']}, worst {s['command_age_ms_max']:.0f} ms)"
    return row


def _bus_row(s: dict) -> str:
    """Frames lost (the most at one node and topic, if it fits) and the largest share of a sensor
    topic a node of the data path skipped."""
    lost = sorted(((c["lost"], c["of"], node, c["topic"]) for node, counts in s["losses"].items()
                   for c in counts.values()), reverse=True)
    skipped = sorted(((n["skipped"] / n["received"], node, topic) for node, inputs in s["skipped_for_newer"].items()
                      if node not in s["observers"] for topic, n in inputs.items()
                      if topic in SENSOR_TOPICS and n["received"]), reverse=True)
    skip = (f"; {skipped[0][1]} skipped {skipped[0][0] * 100:.1f}% of {skipped[0][2]}" if skipped
            else "; every sensor sample examined")
    if not lost:
        return "bus: no frame lost" + skip
    n, of, node, topic = lost[0]
    total = f"bus: {sum(x[0] for x in lost):g} frames lost"
    most = f" (most: {node} {topic} {n:g} of {of:g}" + (f", +{len(lost) - 1} more)" if len(lost) > 1 else ")")
    return total + most + skip if len(total + most + skip) <= SUMMARY_WIDTH else total + skip


def _health_rows(shorts: list[str], room: int) -> list[str]:
    """One HEALTH line per problem while they fit in ``room`` lines; else packed, the rest counted."""
    if not shorts:
        return ["HEALTH: ok"]
    if len(shorts) <= room:
        return [_clip("HEALTH: " + short) for short in shorts]
    rows: list[str] = []
    for k, short in enumerate(shorts):
        more = f"; +{len(shorts) - k} more (verbose:=true)"
        if rows and len(rows[-1]) + 2 + len(short) <= SUMMARY_WIDTH - (len(more) if len(rows) == room else 0):
            rows[-1] += "; " + short
        elif len(rows) < room:
            rows.append(_clip("HEALTH: " + short))
        else:
            rows[-1] = rows[-1][: SUMMARY_WIDTH - len(more)] + more
            break
    return rows


def format_details(s: dict, problems: list[Problem], p: MonitorParams | None = None) -> list[str]:
    """The long form: every count with its denominator, a HEALTH line per problem with what to do."""
    p = p or MonitorParams()
    lines = [TITLE]
    if s["has_truth"]:
        lines += [
            f"slip episodes: {s['detected_episodes']} detected of {s['true_episodes']} true, {s['missed_episodes']} missed",
            _delay_line(s),
            _false_alarm_line(s),
            f"grip force commanded: mean {_num(s['grip_command_mean_n'], '.2f')} N, peak "
            f"{_num(s['grip_command_peak_n'], '.2f')} N; applied mean {_num(s['applied_f_n_mean_n'], '.2f')} N",
            f"object slid {_num(s['slip_distance_mm'], '.2f')} mm and turned {_num(s['slip_angle_deg'], '.2f')} deg in all",
        ]
        lines += [f"goal {_goal_text(leg, p)} (the truth from this goal to the next or the end)"
                  for leg in _motion_legs(s)]
    else:
        lines += [
            "slip: no ground truth on this run (no rig/truth topic: real hardware), so no true episodes, missed "
            f"slips or flags without true slip; the detector said slip in {s['slip_verdicts']} of {s['slip_frames']} verdicts",
            f"grip force commanded: mean {_num(s['grip_command_mean_n'], '.2f')} N, peak "
            f"{_num(s['grip_command_peak_n'], '.2f')} N",
        ]
    if s["detector_calibration"]:
        lines.append(f"detector {s['detector_calibration']}")
    if not s["grip_commands"]:
        lines.append("control path: no grip commands (a detection-only graph, or the controller never ran)")
    else:
        lines.append(
            f"control path: {s['grip_commands']} grip commands; fail-safe while running {_pct(s['fail_safe_share'])}"
            f" ({s['fail_safe_commands']} of {s['commands_while_running']}), {s['fail_safe_while_starting']} more while"
            f" the sensors started" + (f", {s['fail_safe_after_scene']} after the scene ended" if s["has_truth"] else "")
            + "; " + _late_text(s))
    lines.extend(f"HEALTH: {problem.text}" for problem in problems)
    if not problems:
        lines.append("HEALTH: ok")
    if s["losses"]:
        for node, counts in sorted(s["losses"].items()):
            lines.append(f"frames lost at {node}: " + "; ".join(
                f"{c['topic']} {c['lost']:g} of {c['of']:g} ({c['how']})" for _, c in sorted(counts.items())))
    elif problems:
        lines.append("frames lost on the bus: none reported (no rejected frames, sequence gaps or send-queue drops);"
                     " see HEALTH for what did go wrong")
    else:
        lines.append("frames lost: none (no rejected frames, sequence gaps or send-queue drops reported)")
    skips = [f"{node} {topic} {n['skipped']:g} of {n['received']:g}"
             for node, inputs in sorted(s["skipped_for_newer"].items()) for topic, n in sorted(inputs.items())]
    lines.append("samples not examined (skipped for a newer one, or beyond a batch's depth): "
                 + ("; ".join(skips) if skips else "none"))
    ft = s.get("ft_samples")
    if ft and ft["received"]:
        lines.append(f"F/T samples: {ft['received']:g} received by fusion, {ft['carried']:g} carried in contacts, "
                     f"{ft['judged']:g} judged by the slip test (the others had no usable data: grip held)")
    clocks = [f"{node}: {peer} {c['offset_ms']:+.3f} ms ± {c['uncertainty_ms']:.3f} ms"
              for node, peers in sorted(s.get("clock_offsets", {}).items()) for peer, c in sorted(peers.items())]
    if clocks:
        lines.append("clock offsets between the machines (their clock minus the launcher's): " + "; ".join(clocks))
    if s["observers"]:
        lines.append("observers (they published no data; their silence does not fail the check): "
                     + ", ".join(s["observers"]))
    if s["recording"]:
        lines.append(f"recording: {s['recording']}")
    return lines


def _delay_line(s: dict) -> str:
    """Detection delay (flag rise − true onset; negative: a warning) over the detected episodes."""
    if not s["true_episodes"]:
        return "detection delay: - (no true slip episode)"
    if not s["detected_episodes"]:
        return "detection delay: - (no episode detected)"
    n = s["detected_episodes"]
    return (f"detection delay: p50 {s['detection_delay_ms_p50']:.1f} ms, p95 {s['detection_delay_ms_p95']:.1f} ms"
            f" over {n} episode{'s' if n != 1 else ''} (negative: a warning before the onset)")


def _false_alarm_line(s: dict) -> str:
    """The share of truly sticking frames flagged outside every episode's window, read for
    what it is: with the controller on, mostly the early warnings it acted on (so no gross
    slip followed); with no grip commands, false alarms. The latch hold after slip apart."""
    reading = ("controller on: mostly early warnings it acted on, so no gross slip followed" if s["grip_commands"]
               else "no grip commands: false alarms")
    share = s["false_alarm_share"]
    hold = s["latch_hold_share"]
    return (f"slip flag without true slip: {share * 100:.2f}% of {s['stick_frames']} sticking frames"
            + (f", {hold * 100:.2f}% of them the latch held after a slip" if hold else "")
            + (f" ({reading})" if share else ""))


def _late_text(s: dict) -> str:
    """Late commands (computed from a new sample, more than the deadline after it) per
    stretch, and the watchdog repeats, whose age is the data's and not the control path's."""
    pct = "-" if s["late_share"] is None else f"{s['late_share'] * 100:.1f}%"
    text = f"late (over {s['command_deadline_ms']:g} ms from sample to command) while running {pct} ({s['late_commands']})"
    if s["late_while_starting"]:
        text += (f", {s['late_while_starting']} more while the sensors started (worst "
                 f"{s['command_age_ms_max_while_starting']:.0f} ms: a stall before the stack ran, the grip held)")
    if s["late_after_scene"]:
        text += f", {s['late_after_scene']} after the scene ended"
    if s["watchdog_repeats"]:
        text += (f"; {s['watchdog_repeats']} watchdog repeat{'s' if s['watchdog_repeats'] != 1 else ''} of the last "
                 "grip while no new verdict came (counted as fail-safe, not late)")
    return text
