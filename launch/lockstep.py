"""``slipstack launch FILE --lockstep``: a launch plan run in one process on the simulated clock.

More in docs/modules.md, `launch/lockstep.py`.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path
from typing import Callable

from slipstack.lib.errors import ConfigError
from slipstack.launch.launch_file import SIM_ARG, LaunchFile, load_launch_file
from slipstack.launch.plan import LaunchPlan, plan_launch, tapped_topics
from slipstack.nodes.device_driver import DeviceDriver
from slipstack.nodes.devices.sim_link import SIM_PREFIX, host_side_changes, is_simulated
from slipstack.nodes.recording.bag_io import RecordingError, claim_recording_path
from slipstack.nodes.recording.writer_process import RecordingWriterProcess
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.runtime.node import Node
from slipstack.nodes.runtime.stage_cpu import STAGE_CPU_ENV, stage_cpu_from_env

__all__ = ["LockstepRun", "check_lockstep", "run_launch_file", "STEP_NS", "DIAGNOSTICS_PERIOD_S"]

STEP_NS = 100_000_000
"""Simulated time advanced between checks for the end of the run and progress reports (100 ms)."""
DIAGNOSTICS_PERIOD_S = 1.0
"""Simulated seconds between each node's ``diagnostics`` (as in a real-time launch)."""
PROGRESS_STEPS = 10
"""Progress lines per run (one every 10 % of the simulated time)."""


def check_lockstep(launch: LaunchFile) -> None:
    """Raise ConfigError, saying what to do, if ``launch`` cannot run in lock-step."""
    name = launch.path.name
    for e in launch.nodes:
        if issubclass(e.cls, DeviceDriver) and not is_simulated(str(e.params.get("url", ""))):
            raise ConfigError(
                f"{name}: --lockstep runs simulated devices only, and node {e.name} reads the device "
                f"{e.params.get('url', '')!r}; give it the simulated twin (sim: before the URL, served by the "
                "simulated rig in the same launch) or launch without --lockstep")
        own_io = e.cls.io_sources is not Node.io_sources
        if own_io and not issubclass(e.cls, DeviceDriver) and not getattr(e.cls, "taps_bus", False):
            raise ConfigError(f"{name}: node {e.name} ({e.type}) does I/O of its own and cannot run in lock-step; "
                              f"leave it out of this launch (its enabled argument) or launch without --lockstep")
    if math.isinf(launch.duration_s):
        raise ConfigError("--lockstep runs as fast as the CPU on the simulated clock: give a finite duration_s "
                          "(duration_s:=inf keeps a real-time launch up until Ctrl-C)")
    if not any(e.required for e in launch.nodes) and launch.duration_s <= 0:
        raise ConfigError(f"{name}: a lock-step run needs an end: a required node that finishes (the simulated rig) "
                          "or a duration (duration_s:=SECONDS if the file declares it)")


class _Recording:
    """The plan's recorder: every frame of its topics, as it is published, to a writer
    in a child process (the MCAP work runs on another core)."""

    def __init__(self, path: Path, topics: set[str], fmt: str) -> None:
        claim_recording_path(path)  # before the run: an unwritable or existing path fails now
        self.topics = topics
        self.writer = RecordingWriterProcess(path, wall_minus_monotonic_ns=0, fmt=fmt)

    def __call__(self, t_ns: int, topic: str, payload: bytes) -> None:
        if not self.topics or topic in self.topics:
            self.writer.write(topic, payload, t_ns)


class LockstepRun:
    """Run ``launch`` in lock-step in ``run_dir`` (for ``check.json`` and the device addresses).

    ``echo`` receives every log line (``[node] text``); :meth:`run` returns the exit code.
    With ``keep_published`` the executor keeps every message (``executor.published``;
    memory grows with the run: for analysis of short scenes).
    """

    def __init__(self, launch: LaunchFile, run_dir: Path, *, echo: Callable[[str], None] = print,
                 keep_published: bool = False) -> None:
        check_lockstep(launch)
        self.launch = launch
        self.echo = echo
        self.plan: LaunchPlan = plan_launch(launch, run_dir, lockstep=True)
        self.recordings: list[_Recording] = []
        self.stage_cpu = stage_cpu_from_env("lockstep")
        nodes: list[Node] = []
        names: list[str] = []
        try:  # a recording's writer already started is finished (and its child process ended) if the rest fails
            for name in self.plan.node_order():
                entry = self.plan.nodes[name].entry
                node = entry.instance()
                tapped = tapped_topics(node)
                if tapped is not None:
                    self.recordings.append(_Recording(Path(node.params.path), tapped, node.params.format))
                    echo(f"[{name}] recording to {node.params.path}")
                    continue
                nodes.append(node)
                names.append(name)
            self.executor = InProcessExecutor(
                nodes, names=names, remaps={e.name: e.remap for e in launch.nodes},
                diagnostics_period_s=DIAGNOSTICS_PERIOD_S, keep_published=keep_published, on_frame=self._on_frame,
                on_frame_topics=self._recorded_topics(), log=echo, stage_cpu=self.stage_cpu,
                io_changes=host_side_changes)
        except BaseException:
            self._close_recordings()
            raise
        self.required = [e.name for e in launch.nodes if e.required and e.name in names]
        self.end_ns = round(launch.duration_s * 1e9) if launch.duration_s > 0 else None

    def _recorded_topics(self) -> set[str] | None:
        """The topics some recording writes (``None``: every topic)."""
        if any(not recording.topics for recording in self.recordings):
            return None
        return set().union(*(recording.topics for recording in self.recordings))

    def _on_frame(self, t_ns: int, topic: str, payload: bytes) -> None:
        for recording in self.recordings:
            recording(t_ns, topic, payload)

    def run(self, progress: Callable[[float], None] | None = None) -> int:
        """Run to the end, stop every node (stop order of the plan), close the recordings.

        ``progress(fraction)`` is called every 10 % of the expected simulated time and once at the
        end with 1.0 (default: a ``[lockstep] STATUS`` line every 10 %). Interrupted (Ctrl-C), the
        nodes are stopped and the recordings closed all the same."""
        ex = self.executor
        wall0, cpu0 = time.monotonic(), time.process_time()
        scene_ns = self._expected_end_ns()
        next_report = 1
        try:
            while True:
                until = ex.now_ns + STEP_NS if self.end_ns is None else min(ex.now_ns + STEP_NS, self.end_ns)
                ex.advance(until, stop_at_shutdown_of=self.required)
                finished = [n for n in ex.finished() if n in self.required]
                if finished:
                    self.echo(f"[lockstep] {finished[0]} finished at {ex.now_ns / 1e9:.3f} s simulated")
                    break
                if self.end_ns is not None and ex.now_ns >= self.end_ns:
                    self.echo(f"[lockstep] duration {self.launch.duration_s:g} s reached")
                    break
                if scene_ns and next_report <= PROGRESS_STEPS and ex.now_ns * PROGRESS_STEPS >= next_report * scene_ns:
                    if progress is not None:
                        progress(min(ex.now_ns / scene_ns, 1.0))
                    else:
                        self.echo(f"[lockstep] STATUS {ex.now_ns / 1e9:.1f} of {scene_ns / 1e9:.1f} s simulated "
                                  f"({100 * ex.now_ns // scene_ns}%), {time.monotonic() - wall0:.1f} s")
                    next_report += 1
        finally:
            running = {h.name for h in ex.hosts}
            ex.stop(n for n in self.plan.node_stop_order() if n in running)
            self._close_recordings()
        if progress is not None:
            progress(1.0)
        wall, cpu = time.monotonic() - wall0, time.process_time() - cpu0
        self.echo(f"[lockstep] {ex.now_ns / 1e9:.2f} s simulated in {wall:.2f} s ({cpu:.2f} s CPU), "
                  f"{ex.now_ns / 1e9 / max(wall, 1e-9):.1f}x real time")
        if self.stage_cpu is not None:
            self.echo(f"[lockstep] CPU by node ({STAGE_CPU_ENV}=1; s): {self._cpu_by_node()}")
        return 0

    def _close_recordings(self) -> None:
        """Finish every recording; then raise the first writer's failure, if any."""
        failures = []
        for recording in self.recordings:
            try:
                recording.writer.close()
            except RecordingError as exc:
                failures.append(exc)
        if failures:
            raise failures[0]

    def _cpu_by_node(self) -> str:
        """Each node's and the executor's CPU (s) over the run, largest first."""
        totals: dict[str, int] = {}
        for (owner, _), ns in self.stage_cpu.ns.items():
            totals[owner] = totals.get(owner, 0) + ns
        return ", ".join(f"{owner} {ns / 1e9:.2f}" for owner, ns in sorted(totals.items(), key=lambda kv: -kv[1]))

    def _expected_end_ns(self) -> int | None:
        """The simulated time the run is expected to end at, for progress (the rig's scene, or the duration)."""
        ends = [self.end_ns] if self.end_ns is not None else []
        for name in self.required:
            scene = getattr(self.executor.host(name).node, "scene", None)
            if scene is not None:
                ends.append(round(scene.duration_s * 1e9))
        return min(ends) if ends else None


def run_launch_file(file: str | Path, args: dict[str, str] | None = None, *,
                    progress: Callable[[float], None] | None = None,
                    echo: Callable[[str], None] = lambda line: None) -> InProcessExecutor:
    """Run the launch file ``file`` with ``args`` (name → value, as ``name:=value``) in lock-step, in a
    temporary run directory; the executor after the run, every published message in ``published``.

    For analysis, benchmarks and golden files: pass ``record``/``monitor`` arguments to
    leave those nodes out when they are not wanted.
    """
    with tempfile.TemporaryDirectory(prefix="slipstack-lockstep-") as run_dir:
        launch = load_launch_file(file, args, builtins={"run_dir": run_dir, SIM_ARG: SIM_PREFIX})
        run = LockstepRun(launch, Path(run_dir), echo=echo, keep_published=True)
        run.run(progress)
        return run.executor
