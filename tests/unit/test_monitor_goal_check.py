"""The monitor's check of a commanded pivot or slide (``grasp/goal``): the object must turn or move by
what the goal commands, within the stated tolerances, and not move otherwise; the hold rule judges
the rest of the run. Hand-made truth streams through the real monitor, and hand-made summaries."""

from __future__ import annotations

import dataclasses
import json
import math

import pytest

from slipstack.lib.errors import ConfigError
from slipstack.messages import GraspGoal, Header, RigTruth
from slipstack.nodes import monitor
from slipstack.nodes.monitor import (
    MAX_GOALS, SUMMARY_WIDTH, Monitor, MonitorParams, check_problems, format_summary, held_motion,
)
from slipstack.nodes.runtime.inprocess import InProcessExecutor

MS = 1_000_000
GOAL_S, MOVE_FROM_S, MOVE_TO_S, END_S = 1.0, 1.2, 2.2, 3.0


def _ramp(t_s: float, end: float, start_s: float = MOVE_FROM_S, stop_s: float = MOVE_TO_S) -> float:
    """0 before ``start_s``, ``end`` after ``stop_s``, linear between."""
    return end * min(1.0, max(0.0, (t_s - start_s) / (stop_s - start_s)))


def _stream(goal: GraspGoal | None, *, theta_deg=0.0, x_mm=0.0, slid_mm=0.0, turned_deg=0.0,
            slid_before_mm=0.0) -> list:
    """Truth at 100 Hz for 3 s with ``goal`` at 1 s; the object moves between 1.2 and 2.2 s to the
    given pose change (deg, mm) and slip totals (mm, deg); ``slid_before_mm`` it slid at 0.5 s."""
    events = []
    for k in range(round(END_S * 100) + 1):
        t_ns = k * 10 * MS
        t = t_ns / 1e9
        before = slid_before_mm if t >= 0.5 else 0.0
        truth = RigTruth(theta=math.radians(_ramp(t, theta_deg)), x=_ramp(t, x_mm) * 1e-3,
                         slip_distance_m=(before + _ramp(t, slid_mm)) * 1e-3,
                         slip_angle_rad=math.radians(_ramp(t, turned_deg)), f_n_applied=10.0,
                         header=Header(t_ns, k, t_ns, {}))
        events.append((t_ns, "rig/truth", truth))
        if goal is not None and k == round(GOAL_S * 100):
            events.append((t_ns, "grasp/goal", dataclasses.replace(goal, header=Header(t_ns, 0, t_ns, {}))))
    return events


def _pivot(angle_deg: float = 30.0) -> GraspGoal:
    return GraspGoal(mode="pivot", angle_rad=math.radians(angle_deg), rate_rad_s=math.radians(30.0))


def _slide(distance_mm: float = 20.0) -> GraspGoal:
    return GraspGoal(mode="slide", distance_m=distance_mm * 1e-3, speed_m_s=0.02)


def _judge(events, tmp_path, **params) -> tuple[dict, dict, list[str]]:
    """The monitor over ``events``: its JSON summary, its check file and its short summary."""
    summary, check = tmp_path / "summary.json", tmp_path / "check.json"
    p = MonitorParams(summary_path=str(summary), check_path=str(check), **params)
    ex = InProcessExecutor([Monitor(p)])
    ex.feed(events)
    ex.run()
    ex.stop()
    s = json.loads(summary.read_text())
    return s, json.loads(check.read_text()), format_summary(s, p)


def test_a_pivot_that_turns_by_its_angle_passes_the_check(tmp_path):
    """The shipped pivot's numbers (turned 29.0 deg of 30, slip angle 28.3, slid 0.17 mm): passed,
    where the hold rule alone failed it (object turned 28.3 deg, allowed 0.5)."""
    s, check, rows = _judge(_stream(_pivot(), theta_deg=-29.0, turned_deg=-28.3, slid_mm=0.17), tmp_path)
    assert check["passed"] is True, check
    (leg,) = s["goals"]
    assert leg["mode"] == "pivot" and leg["at_s"] == pytest.approx(GOAL_S)
    assert leg["target"] == pytest.approx(30.0) and leg["moved"] == pytest.approx(29.0, abs=1e-9)
    assert leg["slid_mm"] == pytest.approx(0.17, abs=1e-9) and leg["turned_deg"] == pytest.approx(-28.3, abs=1e-9)
    assert held_motion(s) == pytest.approx((0.0, 0.0), abs=1e-9)
    assert rows[1] == "object: held apart from the goals, slid 0.17 mm and turned -28.30 deg in all"
    assert rows[2] == "goal: pivot 30 deg at 1.0 s: turned 29.00 deg (±2), slid 0.17 mm: as commanded"
    assert rows[-1] == "HEALTH: ok"


@pytest.mark.parametrize("late_s", [0.5, 2.0])
def test_a_goal_that_reaches_the_monitor_late_is_judged_from_its_stamp(late_s, tmp_path):
    """A monitor that waited for a core reads its backlog of truth before the goal that came meanwhile:
    the goal (stamped 1 s) handled after the truth up to 1.5 s or 3 s is still judged from 1 s on."""
    events = _stream(_pivot(), theta_deg=-29.0, turned_deg=-28.3, slid_mm=0.17)
    goal = next(e for e in events if e[1] == "grasp/goal")
    events.remove(goal)
    late = (round((GOAL_S + late_s) * 1e9) + 1, "grasp/goal", goal[2])  # handled then, stamped 1 s
    s, check, _ = _judge(sorted([*events, late], key=lambda e: e[0]), tmp_path)
    assert check["passed"] is True, check
    assert s["goals"][0]["moved"] == pytest.approx(29.0, abs=1e-9) and s["goals"][0]["at_s"] == pytest.approx(GOAL_S)


def test_a_goal_older_than_the_truth_kept_is_judged_in_part(tmp_path, monkeypatch):
    monkeypatch.setattr(monitor, "MARKS_KEPT", 50)  # 0.5 s of this stream's truth
    events = _stream(None, theta_deg=-29.0, turned_deg=-28.3, slid_mm=0.17)
    goal = dataclasses.replace(_pivot(), header=Header(round(GOAL_S * 1e9), 0, round(GOAL_S * 1e9), {}))
    s, check, _ = _judge([*events, (round(END_S * 1e9), "grasp/goal", goal)], tmp_path)
    assert s["goals"][0]["dated"] is False
    assert "pivot goal at 1.0 s came too late to date: judged in part" in check["short"]


@pytest.mark.parametrize("theta_deg, why", [(-27.9, "short of its angle"), (-32.1, "past it"),
                                            (-110.0, "the bar fell to hanging: the grasp lost it")])
def test_a_pivot_short_of_or_past_its_angle_fails(theta_deg, why, tmp_path):
    s, check, rows = _judge(_stream(_pivot(), theta_deg=theta_deg, turned_deg=theta_deg, slid_mm=0.2), tmp_path)
    assert check["passed"] is False, why
    assert check["short"] == [f"pivot 30 deg at 1.0 s: turned {-theta_deg:.2f} deg (allowed ±2)"], why
    assert check["problems"][0].startswith(f"the object turned {-theta_deg:.2f} deg after the pivot goal at 1.0 s "
                                           "(commanded 30 deg, allowed ±2)")
    assert rows[2].endswith(": NOT as commanded") and all(len(r) <= SUMMARY_WIDTH for r in rows)


def test_a_pivot_that_also_slides_fails(tmp_path):
    _, check, _ = _judge(_stream(_pivot(), theta_deg=-30.0, turned_deg=-30.0, slid_mm=1.2), tmp_path)
    assert check["short"] == ["pivot at 1.0 s: object slid 1.20 mm (allowed 1)"]


def test_slip_outside_the_goal_is_judged_by_the_hold_rule(tmp_path):
    """The object slid 0.6 mm before the pivot goal came: the hold rule (0.5 mm) fails it, the pivot passes."""
    _, check, rows = _judge(_stream(_pivot(), theta_deg=-30.0, turned_deg=-30.0, slid_mm=0.2, slid_before_mm=0.6),
                            tmp_path)
    assert check["problems"] == ["the object slid 0.60 mm apart from the goals (allowed 0.5 mm)"]
    assert rows[1].startswith("object: MOVED apart from the goals, slid 0.80 mm")


def test_a_slide_is_judged_by_its_distance_and_must_not_turn(tmp_path):
    s, check, rows = _judge(_stream(_slide(), x_mm=-20.6, slid_mm=20.5), tmp_path)
    assert check["passed"] is True, check
    assert s["goals"][0]["moved"] == pytest.approx(20.6, abs=1e-9)
    assert rows[2] == "goal: slide 20 mm at 1.0 s: moved 20.60 mm (±2), turned 0.00 deg: as commanded"
    _, check, _ = _judge(_stream(_slide(), x_mm=-20.6, slid_mm=20.5, turned_deg=0.8), tmp_path)
    assert check["short"] == ["slide at 1.0 s: object turned 0.80 deg (allowed 0.5)"]
    _, check, _ = _judge(_stream(_slide(), x_mm=-23.0, slid_mm=23.0), tmp_path)
    assert check["short"] == ["slide 20 mm at 1.0 s: moved 23.00 mm (allowed ±2)"]


@pytest.mark.parametrize("goal", [None, GraspGoal(mode="hold")])
def test_without_a_pivot_or_slide_goal_the_hold_rule_judges_the_whole_run(goal, tmp_path):
    _, check, rows = _judge(_stream(goal, theta_deg=-29.0, turned_deg=-28.3, slid_mm=0.17), tmp_path)
    assert check["problems"] == ["the object turned 28.30 deg (allowed 0.5 deg)"]
    assert rows[1] == "object: MOVED, slid 0.17 mm and turned -28.30 deg in all"
    assert not rows[2].startswith("goal:")


def test_the_goal_rule_on_hand_made_summaries_at_its_tolerances(tmp_path):
    s, _, _ = _judge(_stream(None), tmp_path)
    p = MonitorParams(check_pivot_deg=2.0, check_pivot_slip_mm=1.0, check_slide_mm=2.0, check_turn_deg=0.5)

    def judged(mode: str, moved: float, slid: float = 0.0, turned: float = 0.0) -> list[str]:
        leg = {"mode": mode, "target": 30.0 if mode == "pivot" else 20.0, "at_s": 1.5, "moved": moved,
               "slid_mm": slid, "turned_deg": turned}
        return check_problems({**s, "goals": [leg], "slip_distance_mm": slid, "slip_angle_deg": turned}, p)

    assert judged("pivot", 28.0, slid=1.0, turned=-28.0) == [] and judged("pivot", 32.0) == []
    assert len(judged("pivot", 27.99)) == len(judged("pivot", 32.01)) == len(judged("pivot", 30.0, slid=1.01)) == 1
    assert judged("slide", 18.0, slid=18.0, turned=-0.5) == [] and judged("slide", 22.0, slid=22.0) == []
    assert len(judged("slide", 22.01)) == len(judged("slide", 20.0, turned=0.51)) == 1
    # a goal without truth after it (a real gripper: no rig) is not judged, nor is the hold rule
    leg = {"mode": "pivot", "target": 30.0, "at_s": None, "moved": None, "slid_mm": None, "turned_deg": None}
    assert check_problems({**s, "goals": [leg], "slip_distance_mm": None, "slip_angle_deg": None}, p) == []


def test_goals_beyond_the_bound_are_counted_and_fail_the_check(tmp_path):
    events = _stream(None)
    events += [(t, "grasp/goal", GraspGoal(mode="hold", header=Header(t, 0, t, {})))
               for t in range(0, (MAX_GOALS + 3) * MS, MS)]
    s, check, _ = _judge(sorted(events, key=lambda e: e[0]), tmp_path)
    assert len(s["goals"]) == MAX_GOALS and s["goals_not_kept"] == 3
    assert check["short"] == [f"3 goals after the first {MAX_GOALS} not judged one by one"]


@pytest.mark.parametrize("name", ["check_pivot_deg", "check_pivot_slip_mm", "check_slide_mm"])
def test_goal_tolerances_must_be_positive(name):
    with pytest.raises(ConfigError, match=f"monitor: {name} must be a finite number > 0"):
        MonitorParams(**{name: 0.0})
