"""The monitor's summary, health and check against streams whose numbers the tests work
out independently: a lock-step run of a paper scene (real nodes, simulated rig), hand-made
streams, and 200 000 messages for bounded memory."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import stat
import tracemalloc

import numpy as np
import pytest

from slipstack.lib.errors import ConfigError
from slipstack.messages import Diagnostics, GripCommand, Header, RigTruth, Slip, decode, encode
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.launch.lockstep import run_launch_file
from slipstack.nodes.monitor import (
    SILENT_SHOWN, SUMMARY_WIDTH, CommandStats, Coverage, Monitor, MonitorParams, NodeWatch, check_problems,
    format_summary, health_problems, status_line,
)
from slipstack.nodes.monitor import _bus_row, _clip, _health_rows, _losses  # the summary's rows and loss table

MS = 1_000_000
TOPICS = ("slip", "grip/command", "rig/truth")


@pytest.fixture(scope="module")
def fig10_runs() -> dict[bool, list[tuple[int, str, bytes]]]:
    """fig10 cut to 3 s (the load passes μ_s·2 N at 1.4 s), its launch file run in lock-step
    with the controller off and on: every slip, grip/command and rig/truth frame as
    published, with its time."""
    runs = {}
    for controller in (False, True):
        ex = run_launch_file("fig10", {"duration_s": "3", "controller": str(controller).lower(),
                                       "record": "false", "monitor": "false"})
        runs[controller] = [(t, topic, payload) for t, topic, payload in ex.raw if topic in TOPICS]
    return runs


def monitor_over(events, tmp_path, **params) -> tuple[dict, list[str], Monitor]:
    """Feed ``events`` to a monitor on the in-process executor; its JSON summary and log (by
    default the summary's long form, which most tests here read: ``verbose=False`` for the short)."""
    params.setdefault("verbose", True)
    summary_path = tmp_path / "summary.json"
    monitor = Monitor(MonitorParams(summary_path=str(summary_path), **params))
    ex = InProcessExecutor([monitor])
    ex.feed(events)
    ex.run()
    ex.stop()
    return json.loads(summary_path.read_text()), ex.logs, monitor


def health(logs: list[str]) -> str:
    """The summary's HEALTH lines, one per problem."""
    return "\n".join(line for line in logs if "HEALTH:" in line)


def by_topic(events, topic):
    return [decode(payload) for _, t, payload in events if t == topic]


def true_episodes(truth: list[RigTruth]) -> list[tuple[int, int]]:
    """Runs of gross slip, merged when less than 20 ms apart, by a plain loop."""
    runs: list[list[int]] = []
    for m in truth:
        t = m.header.stamp_ns
        if not m.gross_slip:
            continue
        if runs and t - runs[-1][1] <= 2 * MS:  # the next tick: the run goes on
            runs[-1][1] = t
        elif runs and t - runs[-1][1] < 20 * MS:
            runs[-1][1] = t
        else:
            runs.append([t, t])
    return [(a, b) for a, b in runs]


def test_summary_of_a_run_without_controller_matches_the_recorded_truth(fig10_runs, tmp_path):
    events = fig10_runs[False]
    truth, slips = by_topic(events, "rig/truth"), by_topic(events, "slip")
    episodes = true_episodes(truth)
    assert len(episodes) >= 1  # the scene does slip
    flags = [(s.header.stamp_ns, s.state not in ("stick", "no-contact")) for s in slips]
    flagged = [t for t, up in flags if up]
    # detected: a flag from 20 ms before the onset to the end; its delay: that flag's rise
    detected = [ep for ep in episodes if any(ep[0] - 20 * MS <= t <= ep[1] for t in flagged)]
    rises = [t for (t, up), (_, before) in zip(flags, [(0, False), *flags]) if up and not before]
    delays = [max(r for r in rises if r <= min(t for t in flagged if ep[0] - 20 * MS <= t)) - ep[0] for ep in detected]

    s, logs, _ = monitor_over(events, tmp_path)
    assert s["slip_frames"] == len(slips)
    assert s["true_episodes"] == len(episodes)
    assert s["detected_episodes"] == len(detected) and s["missed_episodes"] == len(episodes) - len(detected)
    assert s["detection_delay_ms_p50"] == (pytest.approx(np.percentile(delays, 50) / 1e6) if delays else None)
    assert s["slip_distance_mm"] == pytest.approx(truth[-1].slip_distance_m * 1e3) and s["slip_distance_mm"] > 1.0
    assert s["applied_f_n_mean_n"] == pytest.approx(np.mean([m.f_n_applied for m in truth]))
    assert s["grip_commands"] == 0 and s["grip_command_peak_n"] is None and s["fail_safe_share"] is None
    health_lines = health(logs)
    assert "the object slid" in health_lines
    assert not any("frames lost: none" in line for line in logs)


def test_summary_of_a_controlled_run_counts_force_fail_safe_and_late_commands(fig10_runs, tmp_path):
    """The recorded commands, every 7th turned fail-safe and every 11th stamped 30 ms
    before it left (late for the 20 ms deadline): the summary counts what was sent."""
    events = []
    for k, (t, topic, payload) in enumerate(fig10_runs[True]):
        if topic == "grip/command":
            m = decode(payload)
            h = m.header
            stamp = max(h.pub_ns - 30 * MS, 0) if k % 11 == 0 else h.stamp_ns  # stamps are never negative
            reason = "fail-safe" if k % 7 == 0 else m.reason
            payload = encode(dataclasses.replace(m, reason=reason), Header(stamp, h.seq, h.pub_ns, h.sources))
        events.append((t, topic, payload))
    commands, truth = by_topic(events, "grip/command"), by_topic(events, "rig/truth")
    f_n = np.array([c.f_n_desired for c in commands])
    # judged: the commands while the scene ran (the monitor sets apart those before the first rig/truth,
    # during the drivers' device handshake, and after the last)
    truth_at = [k for k, (_, topic, _) in enumerate(events) if topic == "rig/truth"]
    judged_commands = by_topic(events[truth_at[0]:truth_at[-1]], "grip/command")
    fail_safe = sum(c.reason == "fail-safe" for c in judged_commands)
    # late: computed from a new sample (a stamp other than the previous command's) while the scene ran
    judged_seqs = {c.header.seq for c in judged_commands}
    late = sum(c.header.pub_ns - c.header.stamp_ns > 20 * MS for prev, c in zip([None, *commands], commands)
               if c.header.seq in judged_seqs and (prev is None or c.header.stamp_ns != prev.header.stamp_ns))
    assert fail_safe > 0 and late > 0

    s, logs, _ = monitor_over(events, tmp_path)
    assert s["grip_commands"] == len(commands)
    assert s["grip_command_mean_n"] == pytest.approx(f_n.mean()) and s["grip_command_peak_n"] == f_n.max()
    assert s["grip_command_peak_n"] > 5.0  # the load reached 3 N: at least 3/0.45 = 6.7 N was needed
    assert s["fail_safe_commands"] == fail_safe
    assert s["fail_safe_share"] == pytest.approx(fail_safe / len(judged_commands))
    assert s["late_commands"] == late and s["command_age_ms_max"] == pytest.approx(30.0)
    assert s["applied_f_n_mean_n"] == pytest.approx(np.mean([m.f_n_applied for m in truth]))
    assert s["slip_distance_mm"] < 0.5 and s["true_episodes"] == 0
    health_lines = health(logs)
    assert "fail-safe" in health_lines and "later than 20 ms" in health_lines
    assert not any("frames lost: none" in line for line in logs)


def test_a_detector_stuck_on_slip_has_a_false_alarm_share_near_one(fig10_runs, tmp_path):
    """What the e2e false-alarm bound (20 %) is for: "every episode detected" alone
    passes with a detector that always says slip; its false-alarm share does not (only the
    sticking frames inside the episodes' windows are excused)."""
    events = []
    for t, topic, payload in fig10_runs[False]:
        if topic == "slip":
            m = decode(payload)
            payload = encode(dataclasses.replace(m, state="translation"), m.header)
        events.append((t, topic, payload))
    s, _, _ = monitor_over(events, tmp_path)
    assert s["missed_episodes"] == 0 and s["stick_frames"] > 100
    assert s["false_alarm_share"] > 0.9


def test_a_flag_up_long_before_the_episode_is_an_early_delay_and_its_frames_false_alarms(tmp_path):
    """1 s at 1 kHz, gross slip at 300 ms and 700 ms: the flag is up from 100 ms to 330 ms
    and from 650 ms to 730 ms. Delays -200 and -50 ms (a warning that early; it used to be
    no delay, "already flagged"); the flagged sticking frames before each window (100–279
    and 650–679 ms) are false alarms, over the 960 sticking frames."""
    events = []
    for k in range(1000):
        t = k * MS
        events.append((t, "rig/truth", _truth(t, gross=300 <= k < 320 or 700 <= k < 720)))
        state = "translation" if 100 <= k < 330 or 650 <= k < 730 else "stick"
        events.append((t, "slip", Slip(state=state, header=Header(t, k, t, {}))))
    s, logs, _ = monitor_over([(t, topic, encode(m)) for t, topic, m in events], tmp_path)
    assert s["detected_episodes"] == 2 and s["missed_episodes"] == 0
    assert s["detection_delay_ms_p50"] == pytest.approx(-125.0) and s["stick_frames"] == 960
    assert s["false_alarm_share"] == pytest.approx((180 + 30) / 960) and s["latch_hold_share"] == 0.0
    line = next(line for line in logs if "detection delay:" in line)
    assert "p50 -125.0 ms, p95 -57.5 ms over 2 episodes (negative: a warning before the onset)" in line, line


def test_flags_without_true_slip_are_read_for_what_they_are(fig10_runs, tmp_path):
    """With the controller on, the detector's flags on sticking frames are the early warnings
    it acts on; the summary used to call them a "false-slip rate" either way. (Each run's
    verdicts turned to slip from 1 s on, so that there are flags on sticking frames.)"""
    for controller, reading in ((True, " (controller on: mostly early warnings it acted on, so no gross slip followed)"),
                                (False, " (no grip commands: false alarms)")):
        events = []
        for t, topic, payload in fig10_runs[controller]:
            if topic == "slip" and t >= 1_000 * MS:
                m = decode(payload)
                payload = encode(dataclasses.replace(m, state="translation"), m.header)
            events.append((t, topic, payload))
        s, logs, _ = monitor_over(events, tmp_path)
        line = next(line for line in logs if "sticking frames" in line)
        assert s["false_alarm_share"] > 0
        share = f"{s['false_alarm_share'] * 100:.2f}% of {s['stick_frames']} sticking frames"
        assert line.endswith(f"slip flag without true slip: {share}{reading}"), line
        assert not any("false-slip" in line for line in logs), logs


def test_late_counts_commands_from_new_samples_while_running_and_not_the_watchdog_repeats(tmp_path):
    """1 s of scene at 1 kHz. Late for the 20 ms deadline: one command while the sensors
    started (a 500 ms stall, fail-safe), one while running (30 ms) and one after the scene
    ended. Three watchdog repeats of the last grip (the same stamp, ages 25-65 ms): the
    data's age, not the control path's. Only the running one is a HEALTH problem; the
    summary used to call all six late."""
    events = []

    def command(t_ns: int, k: int, stamp_ns: int, reason: str = "nominal") -> None:
        events.append((t_ns, "grip/command", GripCommand(f_n_desired=2.0, reason=reason,
                                                         header=Header(stamp_ns, k, t_ns, {}))))

    command(0, 0, 0, "fail-safe")
    command(500 * MS, 1, 0 + 1, "fail-safe")  # starting: its sample 500 ms old
    for k in range(1000):
        t = (600 + k) * MS
        events.append((t, "rig/truth", _truth(t)))
        events.append((t, "slip", Slip(state="stick", header=Header(t, k, t, {}))))
        if k == 300:
            command(t + 30 * MS, 2 + k, t)  # late while running
        elif 400 <= k < 470:  # no new verdict for 70 ms: the watchdog repeats three times
            if k < 403:
                command((999 + 25 + 20 * (k - 400)) * MS, 2 + k, 999 * MS, "fail-safe")  # the same stamp
        else:
            command(t + MS, 2 + k, t)
    end = 1600 * MS
    command(end + 30 * MS, 2000, end)  # after the scene, from a new sample
    s, logs, _ = monitor_over([(t, topic, encode(m)) for t, topic, m in events], tmp_path)
    assert (s["late_commands"], s["late_while_starting"], s["late_after_scene"], s["watchdog_repeats"]) == (1, 1, 1, 3)
    assert s["command_age_ms_max"] == pytest.approx(30.0)
    assert s["command_age_ms_max_while_starting"] == pytest.approx(500.0, abs=0.01)
    assert "HEALTH: 1 of " in health(logs) and "grip commands while running" in health(logs), health(logs)
    line = next(line for line in logs if "control path:" in line)
    assert "late (over 20 ms from sample to command) while running" in line, line
    assert "1 more while the sensors started (worst 500 ms: a stall before the stack ran, the grip held)" in line
    assert "1 after the scene ended; 3 watchdog repeats of the last grip while no new verdict came" in line, line


def test_a_clean_run_says_health_ok_and_passes_its_check(fig10_runs, tmp_path):
    check = tmp_path / "check.json"
    s, logs, _ = monitor_over(fig10_runs[True], tmp_path, check_path=str(check))
    assert s["fail_safe_commands"] == 0 and s["late_commands"] == 0  # lock-step: nothing is late
    assert "HEALTH: ok" in [line.split("] ", 1)[-1] for line in logs]
    assert any("frames lost: none" in line for line in logs)
    assert json.loads(check.read_text()) == {"passed": True, "problems": [], "short": [], "judged_whole": True}


def _truth(t_ns: int, *, slid_m: float = 0.0, turned_rad: float = 0.0, gross: bool = False) -> RigTruth:
    return RigTruth(gross_slip=gross, slip_distance_m=slid_m, slip_angle_rad=turned_rad, f_n_applied=5.0,
                    header=Header(t_ns, t_ns // MS, t_ns, {}))


def _diag(node: str, t_ns: int, **counters: float) -> Diagnostics:
    return Diagnostics(node=node, counters=counters, header=Header(t_ns, 0, t_ns, {}))


def test_check_names_every_problem(tmp_path):
    """Slid and turned too far, 50 % fail-safe, a missed episode, a node that died (its
    diagnostics stopped at 1 s of 10 s) and one that came back after 4 s."""
    check = tmp_path / "check.json"
    events = []
    for k in range(10_000):  # 10 s at 1 kHz
        t = k * MS
        events.append((t, "rig/truth", _truth(t, slid_m=0.9e-3 * k / 9999, turned_rad=math.radians(0.7) * k / 9999,
                                               gross=5000 <= k < 5100)))
        events.append((t, "slip", Slip(state="stick", header=Header(t, k, t, {}))))
        events.append((t, "grip/command", GripCommand(f_n_desired=3.0, reason="fail-safe" if k % 2 else "nominal",
                                                      header=Header(t, k, t + MS, {}))))
    for s in range(1, 11):
        t = s * 1_000_000_000 - 1
        events.append((t, "diagnostics", _diag("control", t)))
        if s <= 1:
            events.append((t, "diagnostics", _diag("ft_driver", t, **{"out.ft/wrench.published": 500.0 * s})))
        if s <= 2 or s >= 6:
            events.append((t, "diagnostics", _diag("tactile_driver", t, **{"out.tactile/frame.published": 250.0 * s})))
    s, logs, _ = monitor_over(events, tmp_path, check_path=str(check))
    verdict = json.loads(check.read_text())
    assert verdict["passed"] is False
    problems = "\n".join(verdict["problems"])
    assert "slid 0.90 mm (allowed 0.5 mm)" in problems
    assert "turned 0.70 deg (allowed 0.5 deg)" in problems
    assert "50.0% of the grip commands were fail-safe" in problems
    assert "missed 1 of 1 true slip episodes" in problems
    assert "node ft_driver went silent: no diagnostics for the last 9.0 s" in problems
    assert "node tactile_driver went silent for 4.0 s and came back" in problems
    assert "control" not in problems
    assert len(verdict["problems"]) == 6
    assert s["silent_nodes"] == {"ft_driver": pytest.approx(9.0, abs=1e-6)}
    health_lines = health(logs)
    assert health_lines.splitlines() == [f"[monitor] HEALTH: {p}" for p in verdict["problems"]]


def test_a_node_back_after_a_silence_is_told_restarted_or_stalled(tmp_path):
    """Diagnostics every second, both nodes silent from 2 s to 6 s: fusion comes back with
    its sequence going on (the same process: it stalled), slip_detector with it started
    again (a new process). The summary used to ask "(restarted?)" of both."""
    events = []
    for k in range(10):
        if 2 < k < 6:
            continue
        t = k * 1_000_000_000
        data = {"out.contact.published": 100.0 * k}  # nodes of the data path: their silence fails the check
        events.append((t, "diagnostics", Diagnostics(node="fusion", counters=data, header=Header(t, k, t, {}))))
        seq = k if k <= 2 else k - 6
        events.append((t, "diagnostics", Diagnostics(node="slip_detector", counters=data, header=Header(t, seq, t, {}))))
    s, logs, _ = monitor_over([(t, topic, encode(m)) for t, topic, m in events], tmp_path)
    assert s["nodes_restarted_after_silence"] == ["slip_detector"]
    assert ("node fusion went silent for 4.0 s and came back as the same process (it stalled: a machine too busy, "
            "or stopped and continued)") in health(logs), health(logs)
    assert "node slip_detector went silent for 4.0 s and came back as a new process (restarted)" in health(logs)


def test_a_monitor_that_waited_for_a_core_sees_no_silence(tmp_path):
    """Reports stamped every second by their node; the monitor handled those of 3–6 s in
    one burst at 6 s after a stall: the node was not silent, the monitor was late."""
    events = [(t * MS, "rig/truth", _truth(t * MS)) for t in range(0, 8000, 10)]
    handled_at = {1: 1, 2: 2, 3: 6, 4: 6, 5: 6, 6: 6, 7: 7}  # report stamp (s) -> handled (s)
    events += [(handled * 1_000_000_000, "diagnostics", _diag("control", stamp * 1_000_000_000))
               for stamp, handled in handled_at.items()]
    s, logs, _ = monitor_over(events, tmp_path)
    assert s["silent_nodes"] == {} and s["nodes_that_went_silent"] == {}
    assert health(logs) == "[monitor] HEALTH: ok"


def test_behind_real_time_and_skipped_samples_reach_the_health_line(tmp_path):
    events = [(t * MS, "rig/truth", _truth(t * MS)) for t in range(100)]
    events.append((60 * MS, "diagnostics", _diag("fusion", 60 * MS, **{"in.ft/wrench.received": 1000,
                                                                       "in.ft/wrench.dropped": 400,
                                                                       "out.contact.published": 600})))
    events.append((70 * MS, "diagnostics", _diag("rig", 70 * MS, **{"in.grip/command.received": 1000,
                                                                    "in.grip/command.dropped": 400,
                                                                    "out.rig/truth.published": 70,
                                                                    "timer.tick.skipped": 35})))
    s, logs, _ = monitor_over(events, tmp_path)
    assert s["behind_real_time"] == {"rig": {"timer.tick.skipped": 35}}
    assert s["skipped_for_newer"] == {"fusion": {"ft/wrench": {"skipped": 400, "received": 1000}},
                                      "rig": {"grip/command": {"skipped": 400, "received": 1000}}}
    health_lines = health(logs)
    assert "rig fell behind real time (timer ticks skipped: tick 35; its diagnostics say how late)" in health_lines
    assert "`realtime:=10`" in health_lines and "--lockstep" in health_lines  # what to do next
    # fusion's ft/wrench is a batch input: its drops are a backlog beyond the depth, not "for newer samples"
    assert ("fusion did not examine 40% of ft/wrench (skipped for a newer one, or beyond a batch's depth): "
            "it fell behind its input; free a CPU core") in health_lines
    assert "grip/command" not in health_lines  # the plant acting on the newest command: listed, not a problem
    assert any("rig grip/command 400 of 1000" in line for line in logs)


def test_the_check_file_is_replaced_whole(tmp_path):
    check = tmp_path / "check.json"
    check.write_text("stale content from an earlier run")
    monitor_over([(0, "rig/truth", _truth(0))], tmp_path, check_path=str(check))
    assert json.loads(check.read_text())["passed"] is True
    assert sorted(p.name for p in tmp_path.iterdir()) == ["check.json", "summary.json"]  # no temporary file left
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(check.stat().st_mode) == 0o666 & ~umask


def test_bad_parameters_are_refused():
    with pytest.raises(ConfigError, match="command_deadline_ms"):
        MonitorParams(command_deadline_ms=0.0)
    with pytest.raises(ConfigError, match="check_fail_safe_share"):
        MonitorParams(check_fail_safe_share=1.5)


def _long_stream(n_ticks: int):
    """1 kHz truth, verdicts and commands (3 messages a tick): 20 ms of gross slip every
    second, flagged from 5 ms before; every 100th command fail-safe; diagnostics at 1 Hz."""
    for k in range(n_ticks):
        t = k * MS
        phase = k % 1000
        yield t, "rig/truth", encode(_truth(t, gross=500 <= phase < 520))
        state = "translation" if 495 <= phase < 525 else "stick"
        yield t, "slip", encode(Slip(state=state, header=Header(t, k, t, {})))
        yield t, "grip/command", encode(GripCommand(f_n_desired=2.0 + phase / 1000, reason="fail-safe" if k % 100 == 0
                                                    else "nominal", header=Header(t, k, t + MS, {})))
        if phase == 999:
            yield t, "diagnostics", encode(_diag("control", t, **{"in.ft/wrench.received": k}))


def test_memory_stays_bounded_over_200k_messages(tmp_path):
    """The monitor used to keep every sample in Python lists (~260 MB/h). Over 200 000
    messages the summary must stay right, and what the last 30 000 of them leave
    allocated (traced: tracemalloc slows everything down, so only the end is) must not
    grow with the stream: the old lists kept ~3 MB of it."""
    n_ticks = 66_700  # 3 messages a tick: 200 100 messages, 66.7 s
    summary_path = tmp_path / "summary.json"
    monitor = Monitor(MonitorParams(summary_path=str(summary_path)))
    ex = InProcessExecutor([monitor])
    stream = _long_stream(n_ticks)

    def run_ticks(n: int) -> None:
        for _ in range(n // 1000):
            ex.feed([next(stream) for _ in range(3 * 1000)])
            ex.run()
            ex.logs.clear()

    run_ticks(56_000)
    tracemalloc.start()
    try:
        sizes = []
        for _ in range(5):
            run_ticks(2_000)
            sizes.append(tracemalloc.get_traced_memory()[0])
    finally:
        tracemalloc.stop()
    ex.feed(stream)
    ex.run()
    ex.stop()
    # the old monitor held 5.4 MB here; what stays is per slip episode (a few hundred bytes each,
    # one episode a second in this stream) plus the reallocation steps of its containers
    assert sizes[-1] < 512 * 1024, [f"{s / 1e3:.0f} kB" for s in sizes]
    s = json.loads(summary_path.read_text())
    episodes = len(range(500, n_ticks, 1000))  # one at 500 ms of every second: 67
    assert s["true_episodes"] == s["detected_episodes"] == episodes and s["missed_episodes"] == 0
    assert s["detection_delay_ms_p50"] == pytest.approx(-5.0)
    assert s["false_alarm_share"] == 0.0
    # every 100th command is fail-safe; the very first one came before any valid command: "while starting"
    assert s["grip_commands"] == n_ticks and s["fail_safe_commands"] == math.ceil(n_ticks / 100) - 1
    assert s["fail_safe_while_starting"] == 1
    assert s["grip_command_peak_n"] == pytest.approx(2.999)
    assert s["slip_frames"] == n_ticks


def test_format_summary_without_a_rig_leaves_the_rig_numbers_out():
    monitor = Monitor()
    monitor.episodes.finish()
    from slipstack.nodes.monitor import summarise
    for verbose, no_truth in ((True, "slip: no ground truth on this run"), (False, "slip: no ground truth")):
        lines = format_summary(summarise(monitor, 0), verbose=verbose)
        assert not any(w in line for line in lines for w in ("object", "sticking", "detected of")), lines
        assert any(line.startswith(no_truth) for line in lines), lines
        assert "HEALTH: ok" in lines


def test_losses_are_given_with_their_denominators(tmp_path):
    counters = {"in.ft/wrench.received": 29507.0, "in.ft/wrench.lost": 497.0,
                "in.contact.received": 100.0, "in.contact.rejected": 3.0}
    diag = Diagnostics(node="fusion", status="ok", counters=counters, last_error="", header=Header(MS, 0, MS, {}))
    s, logs, _ = monitor_over([(MS, "diagnostics", encode(diag))], tmp_path)
    line = next(line for line in logs if "frames lost at fusion" in line)
    assert "ft/wrench 497 of 30004 (sequence gaps, of those sent)" in line, line
    assert "contact 3 of 100 (rejected as malformed, of those received)" in line, line
    assert s["losses"]["fusion"]["in.ft/wrench.lost"] == {"topic": "ft/wrench", "lost": 497.0, "of": 30004.0,
                                                          "how": "sequence gaps, of those sent"}


def test_fail_safe_while_starting_and_after_the_scene_is_kept_apart_from_the_running_share():
    from slipstack.messages import GripCommand, Header
    from slipstack.nodes.monitor import CommandStats

    stats = CommandStats()

    def command(k: int, reason: str) -> GripCommand:
        return GripCommand(f_n_desired=5.0, law="exact", reason=reason, header=Header(k * MS, k, k * MS, {}))

    for k in range(3):
        stats.add(command(k, "fail-safe"), 20 * MS)  # sensors not streaming yet
    for k in range(3, 103):
        stats.add(command(k, "fail-safe" if k % 50 == 0 else "slip"), 20 * MS)  # 2 of 100 while running
        stats.truth_seen()
    for k in range(103, 110):
        stats.add(command(k, "fail-safe"), 20 * MS)  # the rig stopped: no truth any more
    assert (stats.count, stats.fail_safe, stats.starting) == (110, 12, 3)
    assert stats.judged(with_rig=True) == (100, 2)
    assert stats.judged(with_rig=False) == (107, 9)  # on hardware the tail is a real hold


def test_the_summary_counts_the_ft_samples_fusion_received_carried_and_the_slip_test_judged(tmp_path):
    events = [(t * MS, "rig/truth", _truth(t * MS)) for t in range(100)]
    events.append((60 * MS, "diagnostics", _diag("fusion", 60 * MS, **{"in.ft/wrench.received": 7000,
                                                                       "fusion.samples": 7000})))
    events.append((61 * MS, "diagnostics", _diag("slip_detector", 61 * MS, **{"slip_test.samples_judged": 6990})))
    s, logs, _ = monitor_over(events, tmp_path)
    assert s["ft_samples"] == {"received": 7000, "carried": 7000, "judged": 6990, "implausible": 0}
    assert s["skipped_for_newer"] == {}
    assert any("samples not examined (skipped for a newer one, or beyond a batch's depth): none" in line
               for line in logs)
    assert any("F/T samples: 7000 received by fusion, 7000 carried in contacts, 6990 judged" in line for line in logs)


# -- the short form: what the terminal shows ------------------------------------------------------
def _troubled_run(seconds: int = 10) -> list:
    """``seconds`` at 1 kHz with everything wrong at once: slid, turned, half the commands fail-safe
    and late, a missed episode, three drivers silent, a disconnected device, the rig behind
    real time, lost frames and skipped samples: more problems than the short form has lines."""
    events = []
    for k in range(seconds * 1000):
        t = k * MS
        events.append((t, "rig/truth", _truth(t, slid_m=0.9e-3 * k / 9999, turned_rad=math.radians(0.7) * k / 9999,
                                               gross=5000 <= k < 5100)))
        events.append((t, "slip", Slip(state="stick", header=Header(t, k, t, {}))))
        events.append((t, "grip/command", GripCommand(f_n_desired=3.0, reason="fail-safe" if k % 2 else "nominal",
                                                      header=Header(t, k, t + 30 * MS, {}))))
    for s in range(1, seconds + 1):
        t = s * 1_000_000_000 - 1
        events.append((t, "diagnostics", _diag("rig", t, **{"out.rig/truth.published": 1000.0 * s,
                                                             "timer.tick.skipped": 35})))
        events.append((t, "diagnostics", _diag("fusion", t, **{"out.contact.published": 900.0 * s,
                                                                "in.ft/wrench.received": 1000.0 * s,
                                                                "in.ft/wrench.dropped": 400.0 * s,
                                                                "in.ft/wrench.lost": 7.0})))
        for k, node in enumerate(("ft_driver", "tactile_driver", "extra_driver")):
            if s <= 1 + k:
                events.append((t, "diagnostics", Diagnostics(node=node, status="disconnected: robotiq:///dev/ttyX",
                                                             counters={}, header=Header(t, s, t, {}))))
    return [(t, topic, encode(m) if not isinstance(m, bytes) else m) for t, topic, m in events]


@pytest.mark.parametrize("run", ["clean", "troubled"])
def test_the_short_summary_is_at_most_twelve_lines_of_100_characters_on_the_terminal(run, fig10_runs, tmp_path):
    """The terminal shows ``[monitor] `` and a line of the short form; the long form is logged
    behind ``detail: `` (kept in the run log, not shown) and written whole to the JSON summary."""
    events = fig10_runs[True] if run == "clean" else _troubled_run()
    s, logs, _ = monitor_over(events, tmp_path, verbose=False)
    start = logs.index("[monitor] ==== slipstack run summary ====")
    shown = [line for line in logs[start:] if not line.startswith("[monitor] detail: ")]
    details = [line[len("[monitor] detail: "):] for line in logs[start:] if line.startswith("[monitor] detail: ")]
    assert 4 <= len(shown) <= 12, shown
    assert max(len(line) for line in shown) <= 100, [line for line in shown if len(line) > 100]
    assert details[0] == "==== slipstack run summary ====" and len(details) > len(shown) - 3
    health_lines = [line for line in shown if line.startswith("[monitor] HEALTH:")]
    if run == "clean":
        assert health_lines == ["[monitor] HEALTH: ok"]
        assert any(line.startswith("[monitor] object: held, slid 0.00 mm") for line in shown), shown
        assert s["health"] == []
    else:
        # every problem is named, in its short words, and the long form has each with what to do
        assert len(s["health"]) >= 10 and all(h["short"] and h["text"] for h in s["health"])
        assert "+" in health_lines[-1] and "more (verbose:=true)" in health_lines[-1], health_lines
        assert sum(line.startswith("HEALTH: ") for line in details) == len(s["health"])
        assert any("MOVED, slid 0.90 mm" in line for line in shown), shown


def test_short_health_lines_name_each_problem_in_a_few_words(tmp_path):
    s, logs, _ = monitor_over(_troubled_run(4), tmp_path, verbose=False)  # 4 s: fewer problems, one a line
    shown = "\n".join(line for line in logs if not line.startswith("[monitor] detail: "))
    assert "HEALTH: object slid 0.36 mm" not in shown  # within 0.5 mm after 4 s: no problem
    assert "HEALTH: fail-safe 50.0% of commands (allowed 1%)" in shown, shown
    assert "commands late (over 20 ms, worst 30 ms)" in shown, shown
    assert "control: 4000 commands; fail-safe 50.0% (1999 of 3999), late" in shown, shown
    assert "bus: 7 frames lost (most: fusion ft/wrench 7 of " in shown and "fusion skipped 40.0% of ft/wrench" in shown


# -- the check judges the control path; advice fits the node ------------------------------------
def test_a_silent_observer_is_reported_and_does_not_fail_the_check(tmp_path):
    """10 s: the recorder (it publishes no data) stalls from 2 s to 6 s and the
    Foxglove bridge stops at 1 s; the data path reports every second. The check passes
    (it used to fail on "node recorder went silent"), and HEALTH still names both."""
    check = tmp_path / "check.json"
    events = [(k * MS, "rig/truth", _truth(k * MS)) for k in range(0, 10_000, 10)]
    for s in range(1, 11):
        t = s * 1_000_000_000 - 1
        events.append((t, "diagnostics", _diag("control", t, **{"in.ft/wrench.received": 500.0 * s,
                                                                 "out.contact.published": 500.0 * s})))
        if s <= 2 or s >= 6:
            events.append((t, "diagnostics", Diagnostics(node="recorder", counters={"recorder.written": 500.0 * s},
                                                         header=Header(t, s, t, {}))))
        if s <= 1:
            events.append((t, "diagnostics", _diag("foxglove", t, **{"in.slip.received": 500.0})))
    s, logs, _ = monitor_over(events, tmp_path, check_path=str(check), verbose=False)
    assert json.loads(check.read_text())["passed"] is True
    assert s["observers"] == ["foxglove", "recorder"]
    shown = [line for line in logs if line.startswith("[monitor] HEALTH:")]
    assert shown == ["[monitor] HEALTH: foxglove silent for the last 9.0 s (observer)",
                     "[monitor] HEALTH: recorder silent 4.0 s, then back (stalled, observer)"], shown
    assert all(not h["fails_check"] for h in s["health"])
    assert "the control path did not depend on it" in s["health"][1]["text"]


def test_behind_real_time_advice_fits_the_node(tmp_path):
    """Raising the priority is advised only to a node of the data path that did not run with
    it: not to the rig under SCHED_FIFO (the default where granted; it was advised
    `realtime:=10` there), not to the recorder, which is not real-time."""
    events = [(t * MS, "rig/truth", _truth(t * MS)) for t in range(100)]
    events.append((60 * MS, "diagnostics", _diag("rig", 60 * MS, **{"out.rig/truth.published": 60,
                                                                    "timer.tick.skipped": 35,
                                                                    "timer.tick.skipped_realtime": 35})))
    events.append((61 * MS, "diagnostics", _diag("ft_driver", 61 * MS, **{"out.ft/wrench.published": 60,
                                                                          "timer.poll.skipped": 3})))
    events.append((62 * MS, "diagnostics", _diag("recorder", 62 * MS, **{"in.slip.received": 60,
                                                                         "timer.poll.skipped": 128})))
    s, logs, _ = monitor_over(events, tmp_path)
    advice = {line.split("HEALTH: ")[1].split()[0]: line for line in logs if "HEALTH:" in line}
    assert "already runs with real-time priority" in advice["rig"] and "realtime:=10" not in advice["rig"]
    assert "`realtime:=10`" in advice["ft_driver"]
    assert "not real-time" in advice["recorder"] and "realtime" not in advice["recorder"].replace("real-time", "")


def test_the_graph_file_says_who_observes(tmp_path, monkeypatch):
    """In a launched graph the monitor takes the observers from ``graph.json``: a rig that stops
    before its scene starts has published no data yet, and was taken for an observer."""
    (tmp_path / "graph.json").write_text(json.dumps({"nodes": {
        "rig": {"outputs": {"rig/truth": "slipstack/RigTruth", "diagnostics": "slipstack/Diagnostics"}},
        "recorder": {"outputs": {"diagnostics": "slipstack/Diagnostics"}}}}))
    monkeypatch.setenv("SLIPSTACK_RUN_DIR", str(tmp_path))
    events = []
    for s in range(1, 11):
        t = s * 1_000_000_000 - 1
        if s <= 1:
            events += [(t, "diagnostics", _diag("rig", t)), (t, "diagnostics", _diag("recorder", t))]
        events.append((t, "diagnostics", _diag("control", t, **{"out.contact.published": 500.0 * s})))
    check = tmp_path / "check.json"
    s, _, _ = monitor_over(events, tmp_path, check_path=str(check))
    assert s["observers"] == ["recorder"]
    assert json.loads(check.read_text())["problems"] == ["node rig went silent: no diagnostics for the last 9.0 s "
                                                         "(dead or stopped?)"]


def test_the_live_line_says_when_the_detector_runs_without_an_identified_material():
    from slipstack.nodes.monitor import status_line

    slip = Slip(state="stick", margin=0.5, header=Header(0, 0, 0, {}))
    assert status_line({"slip": slip}, 500.0).split()[-1] == "Hz"
    line = status_line({"slip": slip}, 500.0, calibration="uncalibrated: no material file, the shipped rubber")
    assert line.endswith("UNCALIBRATED"), line
    line = status_line({"slip": slip}, 500.0, calibration="calibrated-online: from 2 confirmed slip(s)")
    assert line.endswith("CALIBRATED-ONLINE"), line


def test_a_command_is_late_only_past_its_deadline():
    stats = CommandStats()
    assert stats.late_while_running(with_rig=True) == (0, 0)  # no command yet: none late, no age
    deadline = 20 * MS
    for k, age in enumerate([deadline, deadline + 1]):  # exactly at the deadline, then 1 ns past it
        stamp = (k + 1) * 100 * MS
        stats.add(GripCommand(f_n_desired=5.0, header=Header(stamp, k, stamp + age, {"slip": stamp})), deadline)
    assert stats.late_while_running(with_rig=False) == (1, deadline + 1)


def test_coverage_dates_the_seen_and_the_published_frames_at_the_seen_rate():
    cov = Coverage()
    assert cov.up_to_s(21) == (None, None)
    for seq in (2, 6, 10):  # every 10 ms from seq 2 at 1 s: seq 0 would have been at 0.98 s
        cov.add(Slip(header=Header(1_000 * MS + (seq - 2) * 10 * MS, seq, 0, {})), sender="")
    cov.add(Slip(header=Header(0, 99, 0, {})), sender="topic_pub")  # a tool's frame is not the graph's
    assert cov.seen == 3
    assert cov.up_to_s(21) == pytest.approx((0.1, 0.2), abs=1e-12)  # to seq 10; seqs 0..20 published


def test_a_silence_is_a_gap_longer_than_the_limit():
    watch = NodeWatch()
    for stamp in (0, 100 * MS, 201 * MS):  # gaps of exactly the limit, then 1 ms past it
        watch.report(Diagnostics(node="fusion", header=Header(stamp, 0, stamp, {})), stamp, silent_after_ns=100 * MS)
    assert (watch.silences, watch.longest_silence_ns) == (1, 101 * MS)


def test_the_status_line_names_five_silent_nodes_and_counts_the_rest():
    five = [f"n{k}" for k in range(SILENT_SHOWN)]
    assert status_line({}, 0.0, silent=five).endswith("SILENT n0,n1,n2,n3,n4")
    assert status_line({}, 0.0, silent=[*five, "n5", "n6"]).endswith("SILENT n0,n1,n2,n3,n4 +2")


def test_the_first_status_line_has_no_interval_to_rate_and_the_next_says_the_rate(tmp_path):
    events = [(t, "slip", Slip(state="stick", header=Header(t, k, t, {})))
              for k, t in enumerate(range(0, 2_000 * MS, 10 * MS))]
    _, logs, _ = monitor_over(events, tmp_path, status_period_s=1.0)
    rates = [line.split("rate=")[1].split("Hz")[0].strip() for line in logs if "STATUS" in line]
    assert rates[:2] == ["0", "100"]  # 100 frames a second


def test_frames_missed_in_the_middle_are_unseen_but_not_the_streams_tail(tmp_path):
    """The detector published slip frames 0..149 every 10 ms (its diagnostics say so); the
    monitor saw 0..49 and 100..149: 50 unseen, none of them after the last one it saw."""
    seqs = [*range(50), *range(100, 150)]
    events = [(k * 10 * MS, "slip", Slip(state="stick", header=Header(k * 10 * MS, k, k * 10 * MS, {}))) for k in seqs]
    events.append((1_500 * MS, "diagnostics", Diagnostics(node="slip_detector", counters={"out.slip.published": 150.0},
                                                          header=Header(1_500 * MS, 0, 1_500 * MS, {}))))
    s, logs, _ = monitor_over(events, tmp_path)
    assert "the monitor did not see 50 of 150 slip verdicts" in health(logs)  # the check judged part of the run only
    unseen = s["monitor_unseen"]["slip"]
    assert (unseen["seen"], unseen["published"], unseen["unseen"], unseen["tail_unseen"]) == (100, 150, 50, False)
    assert (unseen["seen_up_to_s"], unseen["published_up_to_s"]) == pytest.approx((1.49, 1.49), abs=1e-9)


def test_send_queue_drops_are_counted_of_all_the_node_tried_to_send():
    losses = _losses({"out.slip.published": 90.0, "out.slip.dropped_hwm": 10.0})
    assert (losses["out.slip.dropped_hwm"]["lost"], losses["out.slip.dropped_hwm"]["of"]) == (10.0, 100.0)


def test_the_check_fails_only_past_the_allowed_slip_and_turn(tmp_path):
    s, _, _ = monitor_over([(0, "slip", Slip(state="stick", header=Header(0, 0, 0, {})))], tmp_path)
    p = MonitorParams()  # allowed: 0.5 mm, 0.5 deg

    def moved(slid_mm: float, turned_deg: float) -> list[str]:
        problems = check_problems({**s, "slip_distance_mm": slid_mm, "slip_angle_deg": turned_deg}, p)
        return [x.split(" (")[0] for x in problems if x.startswith("the object")]

    assert moved(0.5, -0.5) == []
    assert moved(0.51, -0.51) == ["the object slid 0.51 mm", "the object turned 0.51 deg"]


def test_a_row_too_long_for_the_summary_is_cut_to_its_width_with_an_ellipsis():
    assert _clip("x" * 90) == "x" * 90
    assert _clip("x" * 91) == "x" * 89 + "…"


def test_the_bus_row_names_the_worst_loss_and_counts_the_others():
    fusion = _losses({"in.cor.received": 95.0, "in.cor.lost": 5.0})
    s = {"losses": {"fusion": fusion, "grip": _losses({"in.slip.received": 99.0, "in.slip.lost": 1.0})},
         "skipped_for_newer": {}, "observers": []}
    assert _bus_row(s) == "bus: 6 frames lost (most: fusion cor 5 of 100, +1 more); every sensor sample examined"
    s["losses"] = {"fusion": fusion}
    assert _bus_row(s) == "bus: 5 frames lost (most: fusion cor 5 of 100); every sensor sample examined"


def test_the_status_line_names_a_driver_whose_device_is_disconnected(tmp_path):
    events = [(t, "diagnostics", Diagnostics(node="ft_driver", status="disconnected", header=Header(t, k, t, {})))
              for k, t in enumerate(range(0, 2_000 * MS, 100 * MS))]
    _, logs, monitor = monitor_over(events, tmp_path, status_period_s=1.0)
    assert any(line.endswith("DISCONNECTED ft_driver") for line in logs if "STATUS" in line)
    assert monitor.disconnected_nodes() == {"ft_driver": "disconnected"}


def test_the_bus_row_judges_skips_of_sensor_samples_only():
    s = {"losses": {}, "observers": [], "skipped_for_newer": {
        "grip_controller": {"slip": {"skipped": 5, "received": 10}},  # a verdict superseded: not a sensor sample
        "fusion": {"ft/wrench": {"skipped": 0, "received": 0}}}}  # nothing received yet: no share to tell
    assert _bus_row(s) == "bus: no frame lost; every sensor sample examined"
    s["skipped_for_newer"]["fusion"]["ft/wrench"] = {"skipped": 1, "received": 4}
    assert _bus_row(s) == "bus: no frame lost; fusion skipped 25.0% of ft/wrench"


def test_the_short_summary_judges_the_object_by_the_run_s_own_limits(tmp_path):
    events = [(t, "rig/truth", RigTruth(f_n_applied=5.0, header=Header(t, k, t, {})))
              for k, t in enumerate(range(0, 1_000 * MS, 10 * MS))]
    s, _, _ = monitor_over(events, tmp_path)
    s["slip_distance_mm"] = 0.7  # past the default 0.5 mm, within this run's 1 mm
    assert format_summary(s)[1].startswith("object: MOVED, slid 0.70 mm")
    assert format_summary(s, MonitorParams(check_slip_mm=1.0))[1].startswith("object: held, slid 0.70 mm")


def test_an_observer_that_fell_behind_is_reported_but_does_not_fail_the_check(tmp_path):
    s, _, _ = monitor_over([(0, "slip", Slip(state="stick", header=Header(0, 0, 0, {})))], tmp_path)
    s = {**s, "behind_real_time": {"recorder": {"timer.flush": 3.0}}, "observers": ["recorder"]}
    p = MonitorParams()
    assert any(x.startswith("recorder fell behind") for x in [x.text for x in health_problems(s, p)])
    assert not any("recorder" in x for x in check_problems(s, p))


def test_health_problems_that_fill_a_line_exactly_share_it():
    rows = _health_rows(["a" * 40, "b" * 40, "c" * 5], room=2)  # 8 + 40 + 2 + 40 = 90 characters
    assert rows == ["HEALTH: " + "a" * 40 + "; " + "b" * 40, "HEALTH: " + "c" * 5]
    assert len(rows[0]) == SUMMARY_WIDTH
