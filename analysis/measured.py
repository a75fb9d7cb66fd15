"""What the paper's method does on measured data: the report's first section.

The paper's test (11) says slip when the load torque about the COR exceeds the capacity,
γ = τ_t/τ_c > 1. An F/T sensor measures the friction the contact *transmits*, which never
exceeds what it can transmit, so on measured data γ ≤ 1 up to noise (docs/math.md §3.1).
Here every detection-only run (controller off) is replayed through (11) at the paper's COR
(its Fig. 7 iteration; about the known shaft on fig13), and beside it through the onset
band and latch with (11), the exact test and the F/T tests (5) and (7), and each is scored
against the rig's true onsets (:mod:`slipstack.analysis.replay`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slipstack.analysis.figures import FigureText, plt, save_png, slip_spans
from slipstack.analysis.replay import (LEAD_NS, NO_EPISODES, FrameGammas, Quality, gammas, latch_config,
                                       latch_flags, score_flags)
from slipstack.analysis.runs import Run
from slipstack.lib.episodes import MIN_GAP_NS, find_episodes

__all__ = ["MethodOnRun", "paper_test", "prepare", "measured"]

BANDED = (("(11), onset band", None), ("exact, onset band", "exact"), ("(5) F/T, onset band", "linear_ls"),
          ("(7) F/T, onset band", "coulomb"))
"""The methods with the detector's band and latch: (label, test; None: the paper's (11))."""
PLAIN = "(11) as the paper tests it: γ > 1"


def paper_test(run: Run) -> str:
    """The paper's (11) on this run: about the known shaft where the run has one (Fig. 13),
    else at the COR of its Fig. 7 iteration."""
    return "tactile_cor_known" if run.detector.method == "tactile_cor_known" else "tactile_cor"


@dataclass(frozen=True)
class MethodOnRun:
    """One method on one run: its flags, its quality, and (11)'s load factors."""

    label: str
    frames: FrameGammas
    flags: np.ndarray
    quality: Quality


def _truth_ns(run: Run) -> np.ndarray:
    return np.round(run["rig/truth"]["t"] * 1e9).astype(np.int64)


def prepare(run: Run) -> None:
    """In the process that ran it: the replays this section needs, kept on the run."""
    for test in (paper_test(run), *(t for _, t in BANDED if t)):
        gammas(run, test)


def _methods(run: Run) -> list[MethodOnRun]:
    truth, gross = _truth_ns(run), run["rig/truth"]["gross_slip"].astype(bool)
    config = latch_config(run)
    paper = gammas(run, paper_test(run))
    out = []
    plain = np.nan_to_num(paper.gamma) > 1.0
    out.append(MethodOnRun(PLAIN, paper, plain,
                           score_flags(truth, gross, paper.t_ns, plain, paper.in_contact, config.release_ns)))
    for label, test in BANDED:
        frames = paper if test is None else gammas(run, test)
        flags = latch_flags(frames, config)
        out.append(MethodOnRun(label, frames, flags,
                               score_flags(truth, gross, frames.t_ns, flags, frames.in_contact, config.release_ns)))
    return out


def _onset_gammas(run: Run, paper: FrameGammas) -> list[float]:
    """(11)'s largest γ within ± LEAD_NS of each true onset."""
    episodes = find_episodes(_truth_ns(run), run["rig/truth"]["gross_slip"].astype(bool), min_gap_ns=MIN_GAP_NS)
    out = []
    for ep in episodes:
        near = np.abs(paper.t_ns - ep.start_ns) <= LEAD_NS
        if near.any() and np.isfinite(paper.gamma[near]).any():
            out.append(float(np.nanmax(paper.gamma[near])))
    return out


def measured(*runs_and_out) -> FigureText:
    """(11) on its own against the band, on every detection-only run."""
    *runs, out = runs_and_out
    results = {run.experiment.key: _methods(run) for run in runs}
    labels = [m.label for m in next(iter(results.values()))]
    pooled = {label: NO_EPISODES for label in labels}
    for methods in results.values():
        for m in methods:
            pooled[m.label] = pooled[m.label] + m.quality
    keys = list(results)
    gamma_max = {key: float(np.nanmax(methods[0].frames.gamma)) for key, methods in results.items()}
    above = {key: float(np.mean(np.nan_to_num(methods[0].frames.gamma) > 1.0) * 100) for key, methods in results.items()}
    at_onsets = {run.experiment.key: _onset_gammas(run, results[run.experiment.key][0].frames) for run in runs}
    onsets = [g for gs in at_onsets.values() for g in gs]
    fig = plt.figure(figsize=(18, 5.6))
    grid = fig.add_gridspec(2, 3, width_ratios=[1.3, 1, 1.15], height_ratios=[3, 1.2])
    example = next((r for r in runs if r.experiment.key == "fig13"), runs[0])
    _onset_panel(fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[1, 0]), example, results)
    ax1 = fig.add_subplot(grid[:, 1])
    ax1.bar(np.arange(len(keys)), [gamma_max[k] for k in keys], color="C0", width=0.6, alpha=0.6,
            label="largest γ over the run")
    for k, key in enumerate(keys):
        ax1.text(k, gamma_max[key] + 0.01, f"{gamma_max[key]:.3f}", ha="center", fontsize=8)
        ax1.plot(np.full(len(at_onsets[key]), k), at_onsets[key], "o", ms=4, color="C3", mfc="none",
                 label="γ at a true onset (± the window)" if k == 0 else None)
    ax1.axhline(1.0, color="k", lw=1.2, label="γ = 1: (11) fails above")
    ax1.set_xticks(np.arange(len(keys)), keys, fontsize=8)
    ax1.set(ylim=(0, 1.15), ylabel="γ of (11)", title="(11) on measured data: γ ≤ 1 up to noise")
    ax1.legend(fontsize=8, loc="lower right")
    ax2 = fig.add_subplot(grid[:, 2])
    for k, label in enumerate(labels):
        d = np.asarray(pooled[label].delays_ns) / 1e6
        ax2.plot(d, np.full(d.size, k) + np.random.default_rng(k).uniform(-0.15, 0.15, d.size), "o", ms=3,
                 color=f"C{k}", alpha=0.7)
    ax2.axvline(0, color="0.4", lw=0.8)
    ax2.set_yticks(range(len(labels)), [f"{label}\nmissed {pooled[label].missed}/{pooled[label].episodes}, false "
                                        f"alarms {pooled[label].false_alarm_share * 100:.2f} %" for label in labels],
                   fontsize=7)
    ax2.set(xlabel="flag rise − true onset (ms; negative: a warning)", ylim=(-0.6, len(labels) - 0.2),
            title="delay of each method, every episode of every run")
    ax2.set_xscale("symlog", linthresh=10)
    png = save_png(fig, out, "measured")
    plain, band = pooled[PLAIN], pooled[BANDED[0][0]]
    per_run = {key: methods[0].quality for key, methods in results.items()}
    detected_in = [k for k, q in per_run.items() if q.episodes - q.missed]
    rows = "\n".join(
        f"| {label} | {q.episodes} | {q.missed} | {_p(q, 50)} | {_p(q, 95)} | {q.false_alarm_share * 100:.2f} | "
        f"{q.latch_hold_share * 100:.2f} |" for label, q in pooled.items())
    table = ("| method | episodes | missed | delay p50 (ms) | delay p95 (ms) | false alarms (% of sticking frames) | "
             "of which latch hold (%) |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: |\n" + rows + "\n\n"
             "| run | episodes | detected by (11) alone | largest γ of (11) | frames with γ > 1 (%) | γ at the onsets |\n"
             "| --- | ---: | ---: | ---: | ---: | ---: |\n"
             + "\n".join(f"| {k} | {per_run[k].episodes} | {per_run[k].episodes - per_run[k].missed} | "
                         f"{gamma_max[k]:.3f} | {above[k]:.3f} | {_span(at_onsets[k])} |" for k in keys))
    where = (f", all of them in {', '.join(detected_in)}, where the noise lifts γ to at most "
             f"{max(gamma_max[k] for k in detected_in):.3f}" if detected_in else "")
    return FigureText(
        "measured", "What the paper's method does on measured data", png,
        "Test (11) says slip when the load torque about the COR exceeds the capacity, τ_t > τ_c (γ > 1), and the "
        "paper's figures show its output as a 0/1 trace.",
        f"An F/T sensor measures the friction the contact transmits, and friction never transmits more than it can: "
        f"on measured data γ ≤ 1 up to noise (docs/math.md §3.1). Over {len(runs)} detection-only runs "
        f"({', '.join(keys)}) the largest γ of (11) is {max(gamma_max.values()):.3f}; at the {len(onsets)} true "
        f"onsets with a verdict it lies in {_span(onsets)}. (11) on its own detects "
        f"{plain.episodes - plain.missed} of {plain.episodes} episodes{where}. The onset band flags when the contact "
        f"is at its limit, γ ≥ 1 − δ, and the latch holds the flag through the drop to sliding friction: with it "
        f"(11) misses {band.missed}, median delay {_p(band, 50)} ms (negative: before the onset), false alarms "
        f"{band.false_alarm_share * 100:.2f} % of the sticking frames; the other tests with the band are in the "
        f"table.",
        "The paper's own runs flagged slip with (11); on a contact that transmits only what it can hold that "
        "needs γ > 1 on measured loads, which only noise, an underestimated μ or a delayed load measurement gives. "
        "Every flag of slipstack's detector comes from the onset band (the figures below show both). The band "
        "warns early, and a flag up more than the detection window before the onset counts as a false alarm: "
        "that is most of the false alarms above.",
        table)


def _span(values: list[float]) -> str:
    return f"{min(values):.3f}–{max(values):.3f}" if values else "–"


def _p(q: Quality, pct: float) -> str:
    return f"{np.percentile(np.asarray(q.delays_ns) / 1e6, pct):+.1f}" if q.delays_ns else "–"


def _onset_panel(ax, flags_ax, run: Run, results: dict[str, list[MethodOnRun]]) -> None:
    """(11)'s γ around the run's first true onset with the band's edge; below, the 0/1 flags."""
    methods = results[run.experiment.key]
    paper, band = methods[0], methods[1]
    tr = run["rig/truth"]
    gross = tr["gross_slip"].astype(bool)
    onset = float(tr["t"][np.argmax(gross)]) if gross.any() else float(tr["t"][len(tr["t"]) // 2])
    t = paper.frames.t_ns * 1e-9
    near = np.abs(t - onset) <= 0.6
    near_tr = np.abs(tr["t"] - onset) <= 0.6
    delta = run.detector.delta
    ax.plot(t[near], paper.frames.gamma[near], color="C0", lw=1, label="γ of (11)")
    ax.axhline(1.0, color="k", lw=1.2, label="γ = 1: (11) fails above")
    ax.axhline(1 - delta, color="C3", ls="--", lw=1, label=f"1 − δ = {1 - delta:.3f}: the onset band")
    slip_spans(ax, tr["t"][near_tr], gross[near_tr], "C1", "true gross slip (rig)")
    ax.set(ylabel="γ", ylim=(0, 1.25), title=f"{run.experiment.key}: (11) around the first onset")
    ax.tick_params(labelbottom=False)
    ax.legend(fontsize=7, loc="lower right")
    for k, (name, flag, times, color) in enumerate((
            ("(11) alone", paper.flags[near], t[near], "C0"), ("(11) with the band", band.flags[near], t[near], "C3"),
            ("true gross slip", gross[near_tr], tr["t"][near_tr], "C1"))):
        base = 1.4 * (2 - k)
        flags_ax.step(times, base + flag.astype(float), where="post", color=color, lw=1.2)
        flags_ax.text(times[0], base + 0.35, name, fontsize=7, color=color)
    flags_ax.set_yticks([1.4 * k + v for k in range(3) for v in (0, 1)], ["0", "1"] * 3, fontsize=6)
    flags_ax.set(xlabel="time (s)", xlim=ax.get_xlim())
