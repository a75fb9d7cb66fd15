"""The monitor: a live one-line status and, on exit, the run's summary.

Listens to ``slip`` (which carries the load it judged and its COR), ``grip/command``,
``rig/truth`` and every node's ``diagnostics`` — not to the 1 kHz ``contact``/``cor``
streams, to keep its share of the CPU small. Every ``status_period_s`` it logs one ``STATUS`` line (the
launcher redraws it in place on a terminal). On stop it logs the summary: slip
episodes detected versus true, detection delay, grip force used, dropped frames,
and the recording's path; with ``summary_path`` it also writes them as JSON.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from slipstack.lib.episodes import INCIPIENT_SHARE, detection_quality
from slipstack.messages import Diagnostics, GripCommand, RigTruth, Slip
from slipstack.nodes.node import Context, Input, Node

__all__ = ["Monitor", "MonitorParams", "summarise"]

_LOSS_KEYS = (".rejected", ".lost", ".dropped_hwm")  # ".dropped" is drain-to-latest, on purpose


@dataclass(frozen=True)
class MonitorParams:
    status_period_s: float = field(default=0.5, metadata={"help": "seconds between STATUS lines"})
    recording: str = field(default="", metadata={"help": "path of the run's recording, shown in the summary if it was written"})
    summary_path: str = field(default="", metadata={"help": "also write the summary as JSON here"})


class Monitor(Node):
    """Live status line and end-of-run summary of a slipstack graph."""

    name = "monitor"
    inputs = {
        "slip": Input("slip", Slip, policy="queue", depth=10000),
        "grip": Input("grip/command", GripCommand, policy="queue", depth=10000),
        "truth": Input("rig/truth", RigTruth, policy="queue", depth=10000),
        "diagnostics": Input("diagnostics", Diagnostics, policy="queue", depth=1000),
    }
    Params = MonitorParams

    def __init__(self, params: MonitorParams | None = None) -> None:
        super().__init__(params)
        self.timers = {"status": self.params.status_period_s}
        self.slip_t: list[int] = []
        self.slip_flag: list[bool] = []
        self.truth_t: list[int] = []
        self.truth_slip: list[bool] = []
        self.truth_fn: list[float] = []
        self.truth_sliding: list[float] = []
        self.grip_fn: list[float] = []
        self.last: dict[str, object] = {}
        self.diagnostics: dict[str, dict] = {}
        self._slip_count_at_status = 0
        self._status_t = 0

    def on_slip(self, msg: Slip, ctx: Context) -> None:
        self.slip_t.append(msg.header.stamp_ns)
        self.slip_flag.append(msg.state not in ("stick", "no-contact"))
        self.last["slip"] = msg

    def on_grip(self, msg: GripCommand, ctx: Context) -> None:
        self.grip_fn.append(msg.f_n_desired)
        self.last["grip"] = msg

    def on_truth(self, msg: RigTruth, ctx: Context) -> None:
        self.truth_t.append(msg.header.stamp_ns)
        self.truth_slip.append(msg.gross_slip)
        self.truth_fn.append(msg.f_n_applied)
        self.truth_sliding.append(msg.sliding_fraction)
        self.last["truth"] = msg

    def on_diagnostics(self, msg: Diagnostics, ctx: Context) -> None:
        self.diagnostics[msg.node] = msg.counters

    def on_timer_status(self, ctx: Context) -> None:
        now = ctx.now_ns()
        dt = (now - self._status_t) / 1e9 if self._status_t else 0.0
        rate = (len(self.slip_t) - self._slip_count_at_status) / dt if dt > 0 else 0.0
        self._status_t, self._slip_count_at_status = now, len(self.slip_t)
        ctx.log("STATUS " + status_line(self.last, rate))

    def stop(self, ctx: Context) -> None:
        summary = summarise(self)
        for line in format_summary(summary):
            ctx.log(line)
        if self.params.summary_path:
            with open(self.params.summary_path, "w") as fh:
                json.dump(summary, fh, indent=1)


def status_line(last: dict[str, object], rate_hz: float) -> str:
    """One line: state, f_n, margin, COR, detector rate."""
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
    return "  ".join(parts)


def summarise(m: Monitor) -> dict:
    """The run's numbers as a JSON-able dict."""
    q = detection_quality(np.array(m.truth_t), np.array(m.truth_slip), np.array(m.slip_t), np.array(m.slip_flag),
                          incipient=np.array(m.truth_sliding) >= INCIPIENT_SHARE)
    losses = {
        node: {k: v for k, v in counters.items() if k.endswith(_LOSS_KEYS) and v}
        for node, counters in m.diagnostics.items()
    }
    skipped = sum(v for counters in m.diagnostics.values() for k, v in counters.items() if k.endswith(".dropped"))
    truth = m.last.get("truth")
    return {
        "slip_frames": len(m.slip_t),
        "true_episodes": len(q.episodes),
        "detected_episodes": q.detected,
        "missed_episodes": q.missed,
        "detection_delay_ms_p50": q.delay_percentile_ms(50) if q.detected else None,
        "detection_delay_ms_p95": q.delay_percentile_ms(95) if q.detected else None,
        "false_slip_rate": q.false_slip_rate,
        "grip_command_mean_n": float(np.mean(m.grip_fn)) if m.grip_fn else None,
        "grip_command_peak_n": float(np.max(m.grip_fn)) if m.grip_fn else None,
        "applied_f_n_mean_n": float(np.mean(m.truth_fn)) if m.truth_fn else None,
        "slip_distance_mm": truth.slip_distance_m * 1e3 if truth else None,
        "slip_angle_deg": math.degrees(truth.slip_angle_rad) if truth else None,
        "losses": {n: v for n, v in losses.items() if v},
        "skipped_for_newer": skipped,
        "recording": m.params.recording if m.params.recording and os.path.exists(m.params.recording) else "",
    }


def format_summary(s: dict) -> list[str]:
    """The summary as readable lines."""
    def num(v: object, fmt: str) -> str:
        return "-" if v is None else format(v, fmt)

    lines = [
        "==== slipstack run summary ====",
        f"slip episodes: {s['detected_episodes']} detected of {s['true_episodes']} true, {s['missed_episodes']} missed",
        f"detection delay: p50 {num(s['detection_delay_ms_p50'], '.1f')} ms, p95 {num(s['detection_delay_ms_p95'], '.1f')} ms;"
        f" false-slip rate {s['false_slip_rate'] * 100:.2f}% of sticking frames",
        f"grip force commanded: mean {num(s['grip_command_mean_n'], '.2f')} N, peak {num(s['grip_command_peak_n'], '.2f')} N;"
        f" applied mean {num(s['applied_f_n_mean_n'], '.2f')} N",
        f"object slid {num(s['slip_distance_mm'], '.2f')} mm and turned {num(s['slip_angle_deg'], '.2f')} deg in all",
    ]
    if s["losses"]:
        for node, counts in sorted(s["losses"].items()):
            lines.append(f"frames lost at {node}: " + ", ".join(f"{k}={v:g}" for k, v in sorted(counts.items())))
    else:
        lines.append("frames lost: none (no rejected frames, sequence gaps or send-queue drops reported)")
    lines.append(f"frames skipped for a newer one (latest-value inputs): {s['skipped_for_newer']:g}")
    if s["recording"]:
        lines.append(f"recording: {s['recording']}")
    return lines
