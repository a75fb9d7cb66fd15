"""``slipstack report`` on a two-finger recording: the grasp's figure (docs/math.md §9).

More in docs/modules.md, `analysis/grasp_report.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slipstack.lib.errors import ConfigError, DecodeError
from slipstack.lib.status import SLIP_STATES
from slipstack.messages import decode
from slipstack.nodes.recording.bag_io import RecordingError, read_recording

__all__ = ["GRASP_TOPICS", "is_grasp_recording", "GraspSeries", "load_grasp_series", "plot_grasp_report"]

GRASP_TOPICS = ("rig/truth", "rig/grasp", "grip/command", "grasp/state", "grasp/goal", "finger0/slip", "finger1/slip")


def is_grasp_recording(topics: set[str]) -> bool:
    """A two-finger recording: it holds the grasp node's state or the gripper rig's truth."""
    return bool({"rig/grasp", "grasp/state"} & topics)


@dataclass(frozen=True)
class GraspSeries:
    """The grasp figure's messages of a recording, by topic, in stamp order; ``t0_ns`` the scene's start."""

    path: Path
    messages: dict[str, list]
    t0_ns: int

    def t(self, topic: str) -> np.ndarray:
        return np.array([(m.header.stamp_ns - self.t0_ns) * 1e-9 for m in self.messages.get(topic, [])])


def load_grasp_series(path: str | Path) -> GraspSeries:
    """Read a recording's grasp topics (frames that do not decode are skipped)."""
    messages: dict[str, list] = {topic: [] for topic in GRASP_TOPICS}
    for frame in read_recording(path, GRASP_TOPICS):
        try:
            messages[frame.topic].append(decode(frame.payload))
        except DecodeError:
            continue
    for msgs in messages.values():
        msgs.sort(key=lambda m: m.header.stamp_ns)
    truth = messages["rig/truth"]
    t0 = truth[0].header.stamp_ns if truth else min(
        (m[0].header.stamp_ns for m in messages.values() if m), default=0)
    return GraspSeries(Path(path), messages, t0)


def _oracle(series: GraspSeries) -> tuple[np.ndarray, np.ndarray, str]:
    """``(t, least holding squeeze)`` of the oracle, and why not when it cannot be computed."""
    from slipstack.analysis.grip_oracle import grasp_oracle_series
    from slipstack.nodes.rig import load_scene_by_name

    truth, grasp = series.messages["rig/truth"], series.messages["rig/grasp"]
    if not truth or not grasp:
        return np.zeros(0), np.zeros(0), "no rig/grasp truth"
    try:
        scene = load_scene_by_name(grasp[0].scene)
    except ConfigError as exc:
        return np.zeros(0), np.zeros(0), f"scene {grasp[0].scene!r}: {exc}"
    if scene.gripper is None:
        return np.zeros(0), np.zeros(0), f"scene {scene.name} is not a gripper's"
    by_stamp = {m.header.stamp_ns: m for m in grasp}
    pairs = [(t, by_stamp[t.header.stamp_ns]) for t in truth if t.header.stamp_ns in by_stamp]
    step = max(1, len(pairs) // 400)  # the oracle is a solve per sample: 400 points draw the line
    pairs = pairs[::step]
    x, y, th, f = (np.array([getattr(t, k) for t, _ in pairs]) for k in ("x", "y", "theta", "f_n_applied"))
    f_t = tuple(np.array([[g.f_x[i], g.f_y[i]] for _, g in pairs]) for i in (0, 1))
    tau = tuple(np.array([g.tau[i] for _, g in pairs]) for i in (0, 1))
    least = grasp_oracle_series(scene, x, y, th, f, f_t, tau).least
    return np.array([(t.header.stamp_ns - series.t0_ns) * 1e-9 for t, _ in pairs]), least, ""


def _goal(series: GraspSeries):
    goals = [g for g in series.messages["grasp/goal"] if g.mode != "hold"]
    return goals[0] if goals else None


def _panel_motion(ax, series: GraspSeries) -> None:
    truth = series.messages["rig/truth"]
    t = series.t("rig/truth")
    goal = _goal(series)
    if goal is None or not truth:
        ax.plot(t, [1e3 * m.slip_distance_m for m in truth], color="C3", label="gross slip [mm] (truth)")
        ax.plot(t, [math.degrees(abs(m.slip_angle_rad)) for m in truth], color="C4", label="gross turn [deg] (truth)")
        ax.set_ylabel("slip")
        return
    t_goal = (goal.header.stamp_ns - series.t0_ns) * 1e-9
    k = int(np.searchsorted(t, t_goal))
    start = truth[min(k, len(truth) - 1)]
    states = series.messages["grasp/state"]
    ts = series.t("grasp/state")
    after = ts >= t_goal
    if goal.mode == "pivot":
        moved = [abs(math.degrees(m.theta - start.theta)) for m in truth]
        seen = [math.degrees(s.progress) for s, a in zip(states, after) if a]
        target, unit = math.degrees(goal.angle_rad), "deg"
        ax.set_ylabel("turned [deg]")
    else:
        moved = [1e3 * math.hypot(m.x - start.x, m.y - start.y) for m in truth]
        seen = [1e3 * s.progress for s, a in zip(states, after) if a]
        target, unit = 1e3 * goal.distance_m, "mm"
        ax.set_ylabel("moved [mm]")
    rate = math.degrees(goal.rate_rad_s) if goal.mode == "pivot" else 1e3 * goal.speed_m_s
    ax.plot(t[k:], moved[k:], color="C0", label=f"{goal.mode} (truth)")
    ax.plot(ts[after], seen, color="C1", lw=1, label="as the pads see it")
    ax.axhline(target, color="k", ls="--", lw=1, label=f"target {target:g} {unit} at {rate:g} {unit}/s")
    ramp_end = t_goal + target / rate if rate > 0 else t_goal
    ax.plot([t_goal, ramp_end], [0.0, target], color="k", ls=":", lw=1, label="at the rate asked")
    ax.axvline(t_goal, color="0.6", lw=0.8)


def _panel_squeeze(ax, series: GraspSeries) -> str:
    truth, cmds, states = (series.messages[t] for t in ("rig/truth", "grip/command", "grasp/state"))
    ax.plot(series.t("grip/command"), [c.f_n_desired for c in cmds], color="C1", lw=0.8, label="commanded")
    ax.plot(series.t("rig/truth"), [m.f_n_applied for m in truth], color="C0", label="applied (truth)")
    ax.plot(series.t("grasp/state"), [s.least_n for s in states], color="C2", lw=0.8,
            label="least holding, measured (both F/T)")
    t_o, least, why = _oracle(series)
    if least.size:
        ax.plot(t_o, least, color="k", ls="--", lw=1, label="oracle's least holding (true loads)")
    ax.set_ylabel("squeeze [N]")
    return why


def _panel_gamma(ax, series: GraspSeries) -> None:
    for finger, color in ((0, "C0"), (1, "C3")):
        slips = series.messages[f"finger{finger}/slip"]
        t = series.t(f"finger{finger}/slip")
        if not slips:
            continue
        gamma = np.array([s.gamma for s in slips])
        ax.plot(t, np.where(np.isfinite(gamma), gamma, np.nan), color=color, lw=0.8, label=f"finger {finger} γ")
        sliding = np.array([s.state in SLIP_STATES for s in slips])
        ax.fill_between(t, 0, 1.1, where=sliding, color=color, alpha=0.12, step="post", lw=0,
                        label=f"finger {finger} slip flagged")
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.set_ylim(0.0, 1.15)
    ax.set_ylabel("load factor γ")


def _panel_share(ax, series: GraspSeries) -> None:
    states = series.messages["grasp/state"]
    t = series.t("grasp/state")
    ax.plot(t, [s.share[0] for s in states], color="C0", label="finger 0's share")
    ax.plot(t, [s.share[1] for s in states], color="C3", label="finger 1's share")
    ax.set_ylim(0.0, 1.0)
    ax.set_ylabel("tangential load share")


def plot_grasp_report(series: GraspSeries, out: str | Path, *, title: str | None = None) -> list[str]:
    """Draw the grasp figure to ``out``; the names of the panels drawn (and why the oracle is
    missing, if it is)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not series.messages["rig/truth"] and not series.messages["grasp/state"]:
        raise RecordingError(f"{series.path}: no rig/truth or grasp/state frames to plot")
    panels = [("motion", _panel_motion), ("squeeze", _panel_squeeze), ("load factors", _panel_gamma),
              ("load split", _panel_share)]
    fig, axes = plt.subplots(len(panels), 1, sharex=True, figsize=(10, 2.4 * len(panels) + 0.8), squeeze=False)
    notes = []
    for ax, (name, draw) in zip(axes[:, 0], panels):
        why = draw(ax, series)
        if why:
            notes.append(f"no oracle: {why}")
        ax.legend(loc="upper left", fontsize=8, ncol=3, framealpha=0.9)
        ax.grid(True, alpha=0.3)
    end = max((float(series.t(topic)[-1]) for topic in ("rig/truth", "grasp/state") if series.messages[topic]),
              default=1.0)
    axes[-1, 0].set_xlim(0.0, max(end, 1e-3))
    axes[-1, 0].set_xlabel("time [s] (from the scene start)")
    fig.suptitle(title or f"slipstack report — {series.path.name} (two fingers)")
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return [name for name, _ in panels] + notes
