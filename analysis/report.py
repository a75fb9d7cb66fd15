"""``slipstack report``: a paper-style figure of a recording, or its friction identification.

    slipstack report RECORDING [-o OUT.png] [--title T] [--mu MU]
    slipstack report RECORDING --identify

The figure (matplotlib, Agg) stacks up to four panels on one time axis: sample
stamps (``header.stamp_ns``), s from the scene start (the first ``rig/truth`` sample;
on hardware, the first usable F/T sample):

More in docs/modules.md, `analysis/report.py`.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from slipstack.lib.episodes import find_episodes
from slipstack.lib.errors import ConfigError, DecodeError
from slipstack.lib.status import SLIP_STATES, SlipState
from slipstack.analysis.grasp_report import is_grasp_recording, load_grasp_series, plot_grasp_report
from slipstack.lib.identify import (
    IdentifyConfig,
    RampEstimate,
    identify_beta_loadings,
    identify_mu_loadings,
)
from slipstack.lib.output_file import claim_output, output_file
from slipstack.lib.progress import file_progress
from slipstack.messages import STATUS_OK, Message, decode
from slipstack.nodes.recording.bag_io import RecordingError, read_recording

__all__ = [
    "SLIP_STATES",
    "TORQUE_ARM_M",
    "Identification",
    "RecordingSeries",
    "add_parser",
    "format_identification",
    "identify_recording",
    "load_series",
    "load_kind",
    "plot_report",
    "summarize",
]

TORQUE_ARM_M = 0.01
"""Lever arm (m, half the 16 × 1.25 mm pad) comparing a torque with a force: which ramp
dominates, and the least torque-axis span (the force axis' span × this) in the figure."""

"""``slip.state`` values that are a slip verdict."""

MATPLOTLIB_HINT = "matplotlib is not installed: pip install 'slipstack[report]'"

_Column = Callable[[Any], Any]
_COLUMNS: dict[str, dict[str, _Column]] = {
    "ft/wrench": {
        "usable": lambda m: m.status == STATUS_OK and m.frame == "pad",
        "f_n": lambda m: -m.force[2],
        "f_t": lambda m: m.force[:2],
        "tau": lambda m: m.torque[2],
    },
    "rig/truth": {
        "x": lambda m: m.x, "y": lambda m: m.y, "theta": lambda m: m.theta,
        "slip_distance_m": lambda m: m.slip_distance_m, "slip_angle_rad": lambda m: m.slip_angle_rad,
        "gross_slip": lambda m: m.gross_slip,
        "f_n_applied": lambda m: m.f_n_applied, "f_n_command": lambda m: m.f_n_command,
    },
    "slip": {
        "state": lambda m: m.state, "margin": lambda m: m.margin, "gamma": lambda m: m.gamma,
        "method": lambda m: m.method, "ok": lambda m: m.status == STATUS_OK,
    },
    "grip/command": {"f_n_desired": lambda m: m.f_n_desired, "reason": lambda m: m.reason},
}


@dataclass(frozen=True)
class RecordingSeries:
    """The report's topics of one recording as columns.

    Attributes:
        path: the recording.
        t0_ns: time zero, ns: the first ``rig/truth`` stamp (the scene's start) if the
            recording has truth, else the first usable F/T stamp, else the earliest
            stamp. Samples before it get negative times.
        topics: topic → column → array; every topic has ``stamp_ns`` (int64, ns) and
            ``t_s`` (s from ``t0_ns``), sorted by stamp; columns are those of
            :data:`_COLUMNS` (``ft/wrench``: ``usable`` is False for a sample not ``ok``
            or not in the pad frame). Topics without frames are absent.
        undecodable: frames of these topics that did not decode (skipped).
    """

    path: Path
    t0_ns: int
    topics: dict[str, dict[str, np.ndarray]]
    undecodable: int = 0

    def has(self, topic: str) -> bool:
        return topic in self.topics

    def __getitem__(self, topic: str) -> dict[str, np.ndarray]:
        return self.topics[topic]

    @property
    def duration_s(self) -> float:
        """s from ``t0_ns`` to the last ``rig/truth`` sample (the scene's end) if the
        recording has truth, else to its last sample."""
        if self.has("rig/truth"):
            return float(self["rig/truth"]["t_s"][-1])
        return max((float(c["t_s"][-1]) for c in self.topics.values()), default=0.0)

    def within_scene(self) -> RecordingSeries:
        """The samples with ``0 <= t_s <= duration_s`` (drops start-up and shut-down frames)."""
        end = self.duration_s
        topics = {}
        for topic, cols in self.topics.items():
            keep = (cols["t_s"] >= 0.0) & (cols["t_s"] <= end)
            if keep.any():
                topics[topic] = {name: column[keep] for name, column in cols.items()}
        return RecordingSeries(self.path, self.t0_ns, topics, self.undecodable)


def load_series(path: str | Path, progress: Callable[[int], None] | None = None) -> RecordingSeries:
    """Read and decode the report's topics of a recording (tactile frames are not read);
    ``progress(bytes read)`` after each chunk.

    Raises:
        RecordingError: the file cannot be opened or is not MCAP.
    """
    rows: dict[str, list[Message]] = {topic: [] for topic in _COLUMNS}
    undecodable = 0
    for frame in read_recording(path, _COLUMNS, progress=progress):
        try:
            rows[frame.topic].append(decode(frame.payload))
        except DecodeError:
            undecodable += 1
    topics: dict[str, dict[str, np.ndarray]] = {}
    for topic, messages in rows.items():
        if not messages:
            continue
        messages.sort(key=lambda m: m.header.stamp_ns)
        cols = {"stamp_ns": np.array([m.header.stamp_ns for m in messages], dtype=np.int64)}
        for name, get in _COLUMNS[topic].items():
            cols[name] = np.array([get(m) for m in messages])
        topics[topic] = cols
    if "rig/truth" in topics:
        t0 = int(topics["rig/truth"]["stamp_ns"][0])
    elif "ft/wrench" in topics and topics["ft/wrench"]["usable"].any():
        t0 = int(topics["ft/wrench"]["stamp_ns"][np.argmax(topics["ft/wrench"]["usable"])])
    else:
        t0 = min((int(c["stamp_ns"][0]) for c in topics.values()), default=0)
    for cols in topics.values():
        cols["t_s"] = (cols["stamp_ns"] - t0) / 1e9
    return RecordingSeries(Path(path), t0, topics, undecodable)


# -- identification (paper Fig. 4) --------------------------------------------------------

@dataclass(frozen=True)
class Identification:
    """Friction identification of one recording.

    mu: the ``|f_t|/f_n`` estimate of each loading (``lib/identify.py``), unless the
    torque dominates; beta: the ``|τ|/f_n`` estimates (m) when it does (the other one is
    empty); load: ``force``, ``torque`` or ``combined`` (:func:`load_kind`; a combined
    ramp's ratio is neither μ nor β, its loadings give onsets only); motion_source: ``"rig/truth"`` when the object's true
    slip distance/angle (after the elastic pre-slip) was given to the estimators (``onset_source`` of each
    estimate says what set the onset), else ``"none"`` (ratio drop only);
    samples: usable F/T samples; merged: of those, how many shared a stamp with
    another and were averaged into it.
    Times are s from :attr:`RecordingSeries.t0_ns`.
    """

    mu: tuple[RampEstimate, ...]
    beta: tuple[RampEstimate, ...]
    load: str
    motion_source: str
    samples: int
    merged: int = 0


def _interp_truth(series: RecordingSeries, t_s: np.ndarray, column: str) -> np.ndarray:
    """A truth column at times ``t_s`` (linear; NaN outside the truth's time span)."""
    truth = series["rig/truth"]
    return np.interp(t_s, truth["t_s"], truth[column].astype(float), left=np.nan, right=np.nan)


def _merge_ties(t_s: np.ndarray, *columns: np.ndarray) -> tuple[np.ndarray, ...]:
    """Samples sharing a stamp averaged into one (a driver may stamp a burst of device
    samples with one receive time); returns the unique times and the averaged columns."""
    t, inverse, counts = np.unique(t_s, return_inverse=True, return_counts=True)
    if t.size == t_s.size:
        return (t_s, *(c.astype(float) for c in columns))
    merged = []
    for c in columns:
        sums = np.zeros((t.size, *c.shape[1:]))
        np.add.at(sums, inverse, c.astype(float))
        merged.append(sums / counts.reshape(-1, *([1] * (c.ndim - 1))))
    return (t, *merged)


def identify_recording(series: RecordingSeries, config: IdentifyConfig | None = None) -> Identification:
    """Run the ramp estimator on each loading of the usable F/T samples of ``series``
    (``config``: estimator settings, default :class:`IdentifyConfig`): ``|τ|/f_n`` if the
    torque dominates, else ``|f_t|/f_n``; with ``rig/truth``, its gross-slip flags cut
    the loadings and its slip distance or angle gives the onsets.

    Raises:
        RecordingError: the recording has no usable ``ft/wrench`` samples.
    """
    if not series.has("ft/wrench") or not series["ft/wrench"]["usable"].any():
        raise RecordingError(f"{series.path}: no usable ft/wrench samples (status ok, pad frame) to identify from")
    w = series["ft/wrench"]
    keep = w["usable"].astype(bool)
    t, f_n, f_t, tau = _merge_ties(w["t_s"][keep], w["f_n"][keep], w["f_t"][keep], w["tau"][keep])
    truth = series.has("rig/truth")
    slip = slip_angle = gross = None
    if truth:  # slip after the elastic pre-slip: the onset without the elastic twist
        slip = _interp_truth(series, t, "slip_distance_m")
        slip_angle = np.abs(_interp_truth(series, t, "slip_angle_rad"))
        gross = _nearest_truth(series, t, "gross_slip").astype(bool)
    load = load_kind(f_t, tau)
    config = config or IdentifyConfig()
    if load == "torque":
        mu, beta = (), identify_beta_loadings(t, f_n, tau, gross_slip=gross, slip_rad=slip_angle, config=config)
    else:
        mu, beta = identify_mu_loadings(t, f_n, f_t, gross_slip=gross, slip_m=slip, config=config), ()
    return Identification(mu, beta, load, "rig/truth" if truth else "none",
                          int(keep.sum()), int(keep.sum() - t.size))


def load_kind(f_t: np.ndarray, tau: np.ndarray) -> str:
    """``torque`` when ``max|τ|/L`` is over ten times ``max|f_t|`` (``L`` = :data:`TORQUE_ARM_M`),
    ``force`` when ``max|f_t|`` is over ten times ``max|τ|/L``, else ``combined`` (a pure ramp
    crosses over by a few per cent)."""
    force = float(np.max(np.hypot(f_t[:, 0], f_t[:, 1]))) if f_t.size else 0.0
    torque = float(np.max(np.abs(tau))) / TORQUE_ARM_M if tau.size else 0.0
    return "torque" if torque > 10.0 * force else "force" if force > 10.0 * torque else "combined"


def _nearest_truth(series: RecordingSeries, t_s: np.ndarray, column: str) -> np.ndarray:
    """A truth column at times ``t_s``: the newest truth sample at or before each (the first before any)."""
    truth = series["rig/truth"]
    k = np.clip(np.searchsorted(truth["t_s"], t_s, side="right") - 1, 0, truth["t_s"].size - 1)
    return truth[column][k]


def _value_se(value: float, se: float) -> str:
    """``value ± se`` with 3 decimals, or more (up to 6) so that ``se`` shows 2 significant digits."""
    decimals = 3
    if math.isfinite(se) and se > 0.0:
        decimals = min(max(decimals, 1 - math.floor(math.log10(se))), 6)
    return f"{value:.{decimals}f} ± {se:.{decimals}f}"


def _estimate_lines(est: RampEstimate, symbol: str, scale: float, unit: str) -> list[str]:
    unit_s = f" {unit}" if unit else ""
    static = _value_se(est.static * scale, est.static_se * scale)
    dynamic = _value_se(est.dynamic * scale, est.dynamic_se * scale)
    if math.isfinite(est.onset_t_s):
        low, high = est.onset_interval_s
        onset = f"  onset t = {est.onset_t_s:.3f} s (from {est.onset_source}; between {low:.3f} and {high:.3f} s)"
    else:
        onset = "  onset: none found"
    status = f"  status {est.status.value}: {est.message}" if est.message else f"  status {est.status.value}"
    extras = "".join(f"; {label} {value * scale:.2g}{unit_s}" for label, value in
                     (("ramp noise", est.noise_std), ("peak prominence", est.prominence)) if math.isfinite(value))
    used = f"  {est.n_used} samples used, {est.n_rejected} rejected{extras}"
    models = [f"{symbol}_{kind} {value * scale:.2g}{unit_s}" for kind, value in
              (("s", est.static_model), ("d", est.dynamic_model)) if math.isfinite(value)]
    model = f"  model error (apart from the ± standard errors): {', '.join(models)}" if models else ""
    return [f"  {symbol}_s = {static}{unit_s}   {symbol}_d = {dynamic}{unit_s}", *([model] if model else []),
            onset, status, used]


def format_identification(ident: Identification) -> str:
    """The identification as text: estimates ± standard errors, onset, status."""
    load = {"torque": "the torque ramp dominates", "force": "the tangential force ramp dominates",
            "combined": "force and torque combined (onsets only, no μ or β)"}[ident.load]
    merged = f" ({ident.merged} sharing a stamp averaged)" if ident.merged else ""
    lines = [f"{ident.samples} F/T samples{merged}; {load}; slip onset from "
             + ("the ratio drop or the object's true motion (rig/truth)" if ident.motion_source != "none"
                else "the ratio drop")]
    for ests, title, symbol, scale, unit in ((ident.mu, "friction coefficient μ = |f_t|/f_n", "μ", 1.0, ""),
                                             (ident.beta, "torsional coefficient β = |τ|/f_n", "β", 1e3, "mm")):
        for k, est in enumerate(ests, 1):
            lines.append(f"{title}, loading {k} of {len(ests)}:")
            lines += _estimate_lines(est, symbol, scale, unit)
    return "\n".join(lines)


# -- summary ------------------------------------------------------------------------------

def _spans(series: RecordingSeries, topic: str, mask: np.ndarray) -> list[tuple[float, float]]:
    """Runs of ``mask`` over a topic's samples as ``(start, end)``, s from ``t0_ns``;
    each run extends one sample period past its last sample (a lone sample shows)."""
    stamps = series[topic]["stamp_ns"]
    period = int(np.median(np.diff(stamps))) if stamps.size > 1 else 0
    t0 = series.t0_ns
    return [((e.start_ns - t0) / 1e9, (e.end_ns + period - t0) / 1e9) for e in find_episodes(stamps, mask)]


def summarize(series: RecordingSeries) -> str:
    """A few lines on what the recording shows over ``[0, duration_s]`` (forces,
    verdicts, true slip)."""
    lines = [f"{series.path.name}: {series.duration_s:.2f} s"]
    series = series.within_scene()
    if series.has("ft/wrench"):
        w = series["ft/wrench"]
        ok = w["usable"].astype(bool)
        if ok.any():
            f_t = np.hypot(w["f_t"][ok, 0], w["f_t"][ok, 1])
            lines.append(f"  ft/wrench: {ok.sum()} usable of {ok.size}; f_n {w['f_n'][ok].min():.2f}..{w['f_n'][ok].max():.2f} N, "
                         f"max |f_t| {f_t.max():.2f} N, max |τ| {np.abs(w['tau'][ok]).max() * 1e3:.2f} N·mm")
        else:
            lines.append(f"  ft/wrench: none of {ok.size} samples usable (status ok, pad frame)")
    if series.has("slip"):
        s = series["slip"]
        slipping = np.isin(s["state"], list(SLIP_STATES))
        spans = _spans(series, "slip", slipping)
        first = f", first at {spans[0][0]:.2f} s" if spans else ""
        # flag stretches, not episodes: an episode is true gross slip (the truth line below)
        lines.append(f"  slip ({s['method'][-1]}): flag up on {slipping.mean():.0%} of {slipping.size} frames, "
                     f"in {len(spans)} stretch{'es' if len(spans) != 1 else ''}{first}")
    if series.has("rig/truth"):
        r = series["rig/truth"]
        spans = _spans(series, "rig/truth", r["gross_slip"].astype(bool))
        first = f", first at {spans[0][0]:.2f} s" if spans else ""
        lines.append(f"  truth: {len(spans)} gross-slip episodes{first}; slip distance "
                     f"{r['slip_distance_m'][-1] * 1e3:.2f} mm, angle {math.degrees(r['slip_angle_rad'][-1]):.2f} deg")
    if series.has("grip/command"):
        c = series["grip/command"]
        lines.append(f"  grip/command: f_n desired {c['f_n_desired'].min():.2f}..{c['f_n_desired'].max():.2f} N")
    if series.undecodable:
        lines.append(f"  {series.undecodable} frames did not decode (skipped)")
    return "\n".join(lines)


# -- figure -------------------------------------------------------------------------------

_MARGIN_FLOOR = -1.0  # margins below are drawn at this value (γ → ∞ gives −∞)
_HEADROOM = 1.25  # axes with a top legend span this × the data's range


def _panel_normal_force(ax, series: RecordingSeries) -> None:
    if series.has("rig/truth"):
        r = series["rig/truth"]
        ax.plot(r["t_s"], r["f_n_applied"], color="black", lw=1.6, label="applied (truth)")
    if series.has("grip/command"):
        c = series["grip/command"]
        ax.step(c["t_s"], c["f_n_desired"], where="post", color="tab:blue", lw=1.2, label="commanded (grip/command)")
    elif series.has("rig/truth"):
        r = series["rig/truth"]
        ax.plot(r["t_s"], r["f_n_command"], color="tab:blue", lw=1.2, ls="--", label="commanded (rig)")
    if series.has("ft/wrench"):
        w = series["ft/wrench"]
        ok = w["usable"].astype(bool)
        ax.plot(w["t_s"][ok], w["f_n"][ok], color="tab:orange", lw=0.8, alpha=0.8, label="measured −f_z (F/T)")
    ax.set_ylabel("normal force\n$f_n$ [N]")
    ax.set_ylim(bottom=0.0)


def _panel_load(ax, series: RecordingSeries, mu: float) -> list:
    w = series["ft/wrench"]
    ok = w["usable"].astype(bool)
    t = w["t_s"][ok]
    ax.plot(t, np.hypot(w["f_t"][ok, 0], w["f_t"][ok, 1]), color="tab:red", lw=1.0, label="$|f_t|$")
    ax.plot(t, mu * w["f_n"][ok], color="black", lw=1.0, ls="--", label=f"$\\mu f_n$ ($\\mu$ = {mu:g})")
    ax.set_ylabel("tangential\nload [N]")
    ax.set_ylim(bottom=0.0)
    twin = ax.twinx()
    tau_nmm = w["tau"][ok] * 1e3
    twin.plot(t, tau_nmm, color="tab:purple", lw=0.8, alpha=0.8, label="torque $\\tau$")
    if tau_nmm.size:  # at least the force axis' span times the lever arm: sensor noise stays small
        span = max(float(np.ptp(tau_nmm)), ax.get_ylim()[1] * TORQUE_ARM_M * 1e3) * 1.05
        middle = 0.5 * (float(tau_nmm.max()) + float(tau_nmm.min()))
        twin.set_ylim(middle - span / 2, middle + span / 2)
    twin.set_ylabel("torque $\\tau$ [N·mm]", color="tab:purple")
    twin.tick_params(axis="y", colors="tab:purple")
    return [twin]


def _panel_verdict(ax, series: RecordingSeries) -> None:
    from matplotlib.patches import Patch

    handles = []
    if series.has("slip"):
        s = series["slip"]
        ok = s["ok"].astype(bool) & (s["state"] != SlipState.NO_CONTACT)  # stale or no contact: no margin
        margin = np.maximum(s["margin"][ok].astype(float), _MARGIN_FLOOR)
        handles += ax.plot(s["t_s"][ok], margin, color="tab:green", lw=1.0,
                           label=f"margin $1-\\gamma$ ({s['method'][-1]})")
        for a, b in _spans(series, "slip", np.isin(s["state"], list(SLIP_STATES))):
            ax.axvspan(a, b, ymin=0.5, ymax=1.0, color="tab:orange", alpha=0.35, lw=0)
        handles.append(Patch(color="tab:orange", alpha=0.35, label="slip verdict (upper band)"))
    if series.has("rig/truth"):
        r = series["rig/truth"]
        for a, b in _spans(series, "rig/truth", r["gross_slip"].astype(bool)):
            ax.axvspan(a, b, ymin=0.0, ymax=0.5, color="tab:red", alpha=0.3, lw=0)
        handles.append(Patch(color="tab:red", alpha=0.3, label="true gross slip (lower band)"))
    ax.axhline(0.0, color="grey", lw=0.8)
    lowest = float(np.min(margin)) if series.has("slip") and margin.size else 0.0
    ax.set_ylim(min(lowest, -0.25) - 0.05, 1.05)
    ax.set_ylabel("stick margin\n$1-\\gamma$")
    ax.legend(handles=handles, loc="lower left", ncol=len(handles), fontsize=8, framealpha=0.9)


def _panel_motion(ax, series: RecordingSeries) -> list:
    r = series["rig/truth"]
    ax.plot(r["t_s"], r["slip_distance_m"] * 1e3, color="tab:brown", lw=1.2, label="slip distance")
    ax.set_ylabel("slip distance\n[mm]")
    twin = ax.twinx()
    twin.plot(r["t_s"], np.degrees(r["slip_angle_rad"].astype(float)), color="tab:cyan", lw=1.2, label="slip angle")
    twin.set_ylabel("slip angle [deg]", color="tab:cyan")
    twin.tick_params(axis="y", colors="tab:cyan")
    return [twin]


def _legend(ax, twins: list) -> None:
    """One legend row at the top of the panel, over the headroom left free above the data."""
    handles, labels = ax.get_legend_handles_labels()
    for axis in [ax, *twins]:
        low, high = axis.get_ylim()
        axis.set_ylim(low, low + _HEADROOM * (high - low))
        if axis is not ax:
            h, lab = axis.get_legend_handles_labels()
            handles, labels = handles + h, labels + lab
    legend = ax.legend(handles, labels, loc="upper left", ncol=len(handles), fontsize=8, framealpha=0.9)
    if twins:  # drawn above the twin's lines
        legend.remove()
        twins[-1].add_artist(legend)


def plot_report(series: RecordingSeries, out: str | Path, *, title: str | None = None, mu: float = 0.45) -> list[str]:
    """Draw the figure of the scene's span (:meth:`RecordingSeries.within_scene`) to
    ``out`` (PNG); returns the names of the panels drawn.

    Raises:
        ImportError: matplotlib is missing.
        RecordingError: none of the report's topics is in the recording.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    series = series.within_scene()
    panels: list[tuple[str, Callable[[Any], list | None]]] = []
    if series.has("rig/truth") or series.has("grip/command") or series.has("ft/wrench"):
        panels.append(("normal force", lambda ax: _panel_normal_force(ax, series)))
    if series.has("ft/wrench"):
        panels.append(("tangential load", lambda ax: _panel_load(ax, series, mu)))
    if series.has("slip") or series.has("rig/truth"):
        panels.append(("slip verdict", lambda ax: _panel_verdict(ax, series)))
    if series.has("rig/truth"):
        panels.append(("object motion", lambda ax: _panel_motion(ax, series)))
    if not panels:
        raise RecordingError(f"{series.path}: no ft/wrench, slip, grip/command or rig/truth frames to plot")
    fig, axes = plt.subplots(len(panels), 1, sharex=True, figsize=(10, 2.3 * len(panels) + 0.8), squeeze=False)
    for ax, (name, draw) in zip(axes[:, 0], panels):
        twins = draw(ax)
        if name != "slip verdict":
            _legend(ax, twins or [])
        ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("time [s] (from the scene start)" if series.has("rig/truth")
                           else "time [s] (from the first F/T sample)")
    axes[-1, 0].set_xlim(0.0, max(series.duration_s, 1e-3))
    fig.suptitle(title or f"slipstack report — {series.path.name}")
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return [name for name, _ in panels]


# -- command line -------------------------------------------------------------------------

FIGURE_FORMATS = ("png", "pdf", "svg", "svgz", "eps", "ps", "jpg", "jpeg", "tif", "tiff", "webp", "pgf")
"""Figure files matplotlib writes without extra packages (its Agg, PDF, SVG, PS and PGF backends)."""

def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("report", help="paper-style figure or friction identification of a recording",
                       description="Plot a recording as a paper-style figure (normal force, tangential load and "
                                   "torque, slip verdict, object motion), or with --identify estimate μ_s, μ_d "
                                   "(β_s, β_d) from a friction-ramp recording (slipstack launch fig4a / fig4b).")
    p.add_argument("recording", metavar="RECORDING", help="an .mcap recording (slipstack launch / bag record)")
    p.add_argument("-o", "--output", metavar="OUT.png", help="figure file (default: RECORDING with .png)")
    p.add_argument("--title", help="figure title (default: the recording's name)")
    p.add_argument("--mu", type=float, default=0.45, help="friction coefficient for the μ·f_n line (default 0.45)")
    p.add_argument("--identify", action="store_true",
                   help="friction identification from a ramp recording instead of a figure (no matplotlib needed)")
    p.set_defaults(func=main_report)


def main_report(args: argparse.Namespace) -> int:
    """Run ``slipstack report``; returns the exit code (2: no matplotlib for a figure)."""
    path = Path(args.recording)
    if not path.is_file():
        raise RecordingError(f"no recording at {path}")
    out = Path(args.output) if args.output else path.with_suffix(".png")
    if not args.identify and out.suffix.lower().lstrip(".") not in FIGURE_FORMATS:
        raise ConfigError(f"cannot write a figure as {out.name!r}: the suffix names the format; use one of "
                          f"{', '.join('.' + f for f in FIGURE_FORMATS)}")
    if not args.identify:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            print(f"slipstack report: {MATPLOTLIB_HINT}", file=sys.stderr)
            return 2
    if not args.identify:
        claim_output(out, force=True)  # before the recording is read: a path it cannot write fails now
        grasp = load_grasp_series(path)
        if is_grasp_recording({topic for topic, msgs in grasp.messages.items() if msgs}):
            panels = plot_grasp_report(grasp, out, title=args.title)
            print(out)
            print(f"  panels: {', '.join(panels)}")
            return 0
    with file_progress(path, "report") as progress:
        series = load_series(path, progress)
    if args.identify:
        print(format_identification(identify_recording(series)))
        return 0
    with output_file(out, force=True):  # a figure is replaced; a path it cannot write fails here
        panels = plot_report(series, out, title=args.title, mu=args.mu)
    print(out)
    print(summarize(series))
    print(f"  panels: {', '.join(panels)}")
    return 0
