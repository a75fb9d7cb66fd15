"""Beyond the paper: how detection depends on the band δ, the sensor noise and an error of μ or
β, over several seeds, and the cost and accuracy of every slip test (a Pareto plot), both on
the detection-only scenes run again with other seeds and noise (``analysis/figure_keys.py``).

Each variant run is replayed once per test (:func:`replay_variant`, in the process that ran
it); the band, μ and the latch are then varied over the kept load factors
(:func:`slipstack.analysis.replay.latch_flags`) and every setting is scored by the one
detection definition (docs/math.md §3.2): missed episodes, delay of the flag's rise
(negative: a warning), and the share of sticking frames flagged outside every episode's
window (false alarms: the controller is off), the latch's hold after slip apart.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import matplotlib.ticker
import numpy as np

from slipstack.analysis.figures import FigureText, plt, save_png
from slipstack.analysis.replay import (LEAD_NS, MARGIN_NS, NO_EPISODES, FrameGammas, Quality, latch_config,
                                       latch_flags, replay_gammas, score_flags)
from slipstack.analysis.runs import Run, contact_beta_s
from slipstack.lib.detection import DetectorConfig

__all__ = ["DetectorSetting", "DETECTOR_SETTINGS", "SENSITIVITY_METHODS", "DELTAS", "ERRORS", "ReplayedRun",
           "replay_variant", "prepare", "Score", "score", "dominated", "sensitivity", "pareto"]


@dataclass(frozen=True)
class DetectorSetting:
    """A deciding slip test and its taxel pooling (``pool`` × ``pool`` blocks; 1: off)."""

    method: str
    pool: int = 1

    @property
    def label(self) -> str:
        return self.method if self.pool == 1 else f"{self.method}, pool {self.pool}"


DETECTOR_SETTINGS: tuple[DetectorSetting, ...] = (
    DetectorSetting("coulomb"), DetectorSetting("decoupled"), DetectorSetting("linear_ls"),
    DetectorSetting("elliptic_ls"), DetectorSetting("tactile_cor"), DetectorSetting("tactile_cor_robust"),
    DetectorSetting("tactile_cor_robust", 2), DetectorSetting("exact"), DetectorSetting("exact", 2))
"""Every deciding test the detector offers on a free object (``tactile_cor_known`` needs a
fixed pivot, which fig14 and fig15 do not have), and pooling 2 for the tactile ones but the
paper's iteration, whose cost (a millisecond a frame) pooling does not change in kind."""
PAPER_ITERATION = "tactile_cor"
"""Replayed on the scenes' own runs only (not on the seeded variants): a millisecond a frame."""

SENSITIVITY_METHODS = ("coulomb", "linear_ls", "tactile_cor_robust", "exact")
"""The tests the sensitivity follows: (7), (5), (11) at the COR of (12) solved robustly (the
paper's iteration gives the same γ where it converges, at many times the cost), and ours."""
DELTAS = (0.05, 0.10, 0.15, 0.20, 0.25, 0.30)
"""Bands δ the sensitivity tries (the material's own is added)."""
ERRORS = (-0.10, 0.0, 0.10)
"""Relative errors of the detector's μ, and of the F/T test's β."""
BETA_METHOD = "linear_ls"
"""The test whose β error is tried: (5), F/T only, with a fixed β."""


@dataclass
class ReplayedRun:
    """What the sensitivity keeps of one variant run: its truth, its latch, and each test's
    load factors per frame (``frames``: setting label → replay; ``beta_frames``: relative β
    error → :data:`BETA_METHOD` with the contact's β_s times (1 + error))."""

    key: str
    scene: str
    seed: int
    noise: float
    truth_ns: np.ndarray
    gross_slip: np.ndarray
    latch: DetectorConfig
    frames: dict[str, FrameGammas] = field(default_factory=dict)
    beta_frames: dict[float, FrameGammas] = field(default_factory=dict)
    agreement: float = math.nan  # share of frames where the replay of the run's own test flags as the run did

    def quality(self, frames: FrameGammas, config: DetectorConfig | None = None, mu_error: float = 0.0) -> Quality:
        flags = latch_flags(frames, config or self.latch, mu_error=mu_error)
        return score_flags(self.truth_ns, self.gross_slip, frames.t_ns, flags, frames.in_contact,
                           self.latch.release_ns)


def replay_variant(run: Run) -> ReplayedRun:
    """Replay ``run`` for the sensitivity: :data:`SENSITIVITY_METHODS`, at the scene's noise every
    setting of :data:`DETECTOR_SETTINGS` (:data:`PAPER_ITERATION` on the scene's own run only),
    and :data:`BETA_METHOD` with each β error. A replay the run already has is taken as it is."""
    exp = run.experiment
    truth = run["rig/truth"]
    out = ReplayedRun(exp.key, exp.key.split("@")[0], run.scene.seed, exp.noise_scale,
                      np.round(truth["t"] * 1e9).astype(np.int64), truth["gross_slip"].astype(bool),
                      latch_config(run))
    if exp.noise_scale != 1.0:
        settings = [DetectorSetting(m) for m in SENSITIVITY_METHODS]
    else:
        settings = [s for s in DETECTOR_SETTINGS if s.method != PAPER_ITERATION or exp.seed is None]
    for s in settings:
        done = run.replays.get(s.method) if s.pool == 1 else None
        out.frames[s.label] = done or replay_gammas(run, s.method, pool=s.pool)
    own = out.frames.get(DetectorSetting(run.detector.method, run.detector.pool).label)
    if own is not None:
        published = run["slip"]["state"]
        flags = latch_flags(own, out.latch)
        n = min(len(published), len(flags))
        out.agreement = float(np.mean(((published[:n] != "stick") & (published[:n] != "no-contact")) == flags[:n]))
    beta_s = contact_beta_s(run.scene)
    for error in ERRORS:
        out.beta_frames[error] = replay_gammas(run, BETA_METHOD, beta_m=beta_s * (1 + error))
    return out


def prepare(run: Run) -> None:
    """In the process that ran it: the run's replays for the sensitivity, kept on the run."""
    run.replays["sensitivity"] = replay_variant(run)


def _replayed(runs) -> list[ReplayedRun]:
    """The sensitivity's replays of the runs given (a scene's own run carries them)."""
    return [r.replays["sensitivity"] if isinstance(r, Run) else r for r in runs]


@dataclass(frozen=True)
class Score:
    """One setting over many runs: its label, mean cost per frame (µs), the pooled quality, and
    over how many runs."""

    label: str
    us_per_frame: float
    quality: Quality
    runs: int = 0

    @property
    def lateness_p50_ms(self) -> float:
        """Median of max(delay, 0) over the detected episodes (ms): a warning counts as on time,
        never better; NaN if none detected."""
        d = self.quality.delays_ns
        return float(np.median(np.maximum(d, 0))) / 1e6 if d else math.nan


def _pooled(qualities) -> Quality:
    total = NO_EPISODES
    for q in qualities:
        total = total + q
    return total


def score(runs: list[ReplayedRun], label: str, **vary) -> Score:
    """Setting ``label`` over those of ``runs`` that replayed it, with ``vary`` passed to
    :meth:`ReplayedRun.quality`."""
    runs = [r for r in runs if label in r.frames]
    frames = [r.frames[label] for r in runs]
    return Score(label, float(np.mean([f.us_per_frame for f in frames])),
                 _pooled(r.quality(f, **vary) for r, f in zip(runs, frames)), len(runs))


def dominated(a: Score, scores: list[Score]) -> bool:
    """Whether another setting is at least as cheap and as good in every respect, and better in one
    (missed share, false alarms, median lateness)."""
    def key(s: Score) -> tuple[float, ...]:
        q = s.quality
        late = s.lateness_p50_ms if q.delays_ns else math.inf
        return s.us_per_frame, q.missed / max(q.episodes, 1), q.false_alarm_share, late

    ka = key(a)
    return any(all(x <= y for x, y in zip(key(b), ka)) and key(b) != ka for b in scores if b is not a)


def _delay_text(q: Quality) -> str:
    if not q.delays_ns:
        return "–"
    d = np.asarray(q.delays_ns) / 1e6
    return f"{np.percentile(d, 50):+.1f} / {np.percentile(d, 95):+.1f}"


def _row(name: str, value: str, q: Quality) -> str:
    return (f"| {name} | {value} | {q.episodes} | {q.missed} | {_delay_text(q)} | {q.false_alarm_share * 100:.2f} | "
            f"{q.latch_hold_share * 100:.2f} |")


_HEADER = ("| test | {what} | episodes | missed | delay p50 / p95 (ms) | false alarms (% of sticking frames) | "
           "of which latch hold (%) |\n| --- | --- | ---: | ---: | ---: | ---: | ---: |")


def sensitivity(*runs_and_out) -> FigureText:
    """Delay and false alarms of four tests against δ, the sensor noise and an error of μ or β."""
    *given, out = runs_and_out
    runs = _replayed(given)
    nominal = [r for r in runs if r.noise == 1.0]
    material_delta = nominal[0].latch.delta
    deltas = sorted({*DELTAS, round(material_delta, 4)})
    noises = sorted({r.noise for r in runs})
    noise_seeds = sorted({r.seed for r in runs if r.noise != 1.0}) or sorted({r.seed for r in nominal})
    noise_runs = [r for r in runs if r.seed in noise_seeds]
    by_delta = {m: [score(nominal, m, config=_with_delta(nominal[0].latch, d)).quality for d in deltas]
                for m in SENSITIVITY_METHODS}
    by_noise = {m: [score([r for r in noise_runs if r.noise == n], m).quality for n in noises]
                for m in SENSITIVITY_METHODS}
    by_mu = {m: [score(nominal, m, mu_error=e).quality for e in ERRORS] for m in SENSITIVITY_METHODS}
    by_beta = [_pooled(r.quality(r.beta_frames[e]) for r in nominal) for e in ERRORS]
    fig, axes = plt.subplots(3, 3, figsize=(15, 10), sharey="row", height_ratios=[3, 2.2, 1.6])
    panels = ((0, "band δ", deltas, by_delta), (1, "sensor noise (× the scene's)", noises, by_noise),
              (2, "error of the detector's μ (%)", [e * 100 for e in ERRORS], by_mu))
    series = [(m, f"C{k}", "o-") for k, m in enumerate(SENSITIVITY_METHODS)]
    for col, xlabel, xs, table in panels:
        lines = [(m, color, style, table[m]) for m, color, style in series]
        if col == 2:
            lines.append((f"{BETA_METHOD}: error of β instead", "k", "s--", by_beta))
        for k, (name, color, style, qs) in enumerate(lines):
            shift = (k - 1.5) * 0.012
            x = np.asarray(xs) * (1 + shift) if col == 1 else np.asarray(xs) + shift * np.ptp(xs) / 3
            p50, lo, hi = (np.array([np.percentile(np.asarray(q.delays_ns) / 1e6, v) if q.delays_ns else np.nan
                                     for q in qs]) for v in (50, 5, 95))
            axes[0, col].errorbar(x, p50, yerr=[p50 - lo, hi - p50], fmt=style, ms=4, capsize=2, color=color,
                                  label=name)
            axes[1, col].plot(xs, [q.false_alarm_share * 100 for q in qs], style, ms=4, color=color, label=name)
            axes[2, col].plot(xs, [q.missed / max(q.episodes, 1) * 100 for q in qs], style, ms=4, color=color,
                              label=name)
        for ax in axes[:, col]:
            ax.set_xlabel(xlabel)
            ax.grid(alpha=0.3)
            if col == 1:
                ax.set_xscale("log", base=2)
                ax.xaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
            if col == 0:
                ax.axvline(material_delta, color="0.5", ls=":", lw=1)
    axes[0, 0].axhline(0, color="0.4", lw=0.8)
    axes[0, 0].set_yscale("symlog", linthresh=10)
    axes[0, 0].set_ylabel("flag rise − true onset (ms)\nmedian, bar 5–95 %")
    axes[1, 0].set_ylabel("false alarms\n(% of sticking frames)")
    axes[2, 0].set_ylabel("missed episodes (%)")
    axes[1, 0].set_yscale("symlog", linthresh=0.1)
    for ax in axes[:, 0]:
        ax.yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
    axes[0, 2].legend(fontsize=8)
    scenes = ", ".join(f"{scene} ×{sum(r.scene == scene for r in nominal)}"
                       for scene in dict.fromkeys(r.scene for r in nominal))
    fig.suptitle(f"Detection against the band, the sensor noise and μ / β errors; runs (seeds) at the scenes' noise: "
                 f"{scenes} (controller off; dotted: the material's δ = {material_delta:.3f})", fontsize=10)
    png = save_png(fig, out, "sensitivity")
    tables = "\n\n".join([
        _HEADER.format(what="band δ") + "\n" + "\n".join(
            _row(m, f"{d:.3f}{' (material)' if abs(d - material_delta) < 5e-5 else ''}", q)
            for m in SENSITIVITY_METHODS for d, q in zip(deltas, by_delta[m])),
        _HEADER.format(what="sensor noise ×") + "\n" + "\n".join(
            _row(m, f"{n:g}", q) for m in SENSITIVITY_METHODS for n, q in zip(noises, by_noise[m])),
        _HEADER.format(what="error of μ (β for the last rows)") + "\n" + "\n".join(
            [_row(m, f"μ {e * 100:+.0f} %", q) for m in SENSITIVITY_METHODS for e, q in zip(ERRORS, by_mu[m])]
            + [_row(BETA_METHOD, f"β {e * 100:+.0f} % of the contact's β_s", q) for e, q in zip(ERRORS, by_beta)])])
    episodes = by_delta["exact"][0].episodes
    worst_mu = {m: by_mu[m][-1].missed for m in SENSITIVITY_METHODS}
    return FigureText(
        "sensitivity", "Beyond the paper — detection against δ, sensor noise and μ or β errors", png,
        "The paper shows its tests on one recorded run each and does not vary its thresholds, its sensors' noise or "
        "its μ and β.",
        f"Over {len(nominal)} runs at the scenes' noise ({scenes} seeds; {episodes} true gross-slip episodes), "
        f"and at each other noise the runs with seed {', '.join(map(str, noise_seeds))} "
        f"(the same noise drawn, scaled; {by_noise['exact'][0].episodes} episodes), every test's load factors "
        f"replayed once and its latch run again for each setting. Detection as docs/math.md §3.2 defines it: "
        f"missed = no flag from {LEAD_NS / 1e6:g} ms before the onset to the end; delay = the flag's rise − the "
        f"onset (negative: a warning); false alarms = sticking frames flagged outside every window [onset − "
        f"{LEAD_NS / 1e6:g} ms, end + the release dwell + {MARGIN_NS / 1e6:g} ms], over all sticking frames. "
        f"With μ {ERRORS[-1] * 100:g} % too high the tests miss "
        + ", ".join(f"{m} {n}" for m, n in worst_mu.items()) + f" of the {episodes} episodes (tables below).",
        "A wider band warns earlier and raises more false alarms; noise raises false alarms of the F/T tests "
        "first; a μ set too high (γ too low) delays or misses onsets, a μ too low flags early. The runs are "
        "the simulated rig's, the noise a scaled copy of the scenes' sensor models.",
        tables)


def _with_delta(config: DetectorConfig, delta: float) -> DetectorConfig:
    return replace(config, delta=delta)


def _beta_points(qs: list[Quality]) -> tuple[list[float], list[list[float]]]:
    p = [[np.percentile(np.asarray(q.delays_ns) / 1e6, v) if q.delays_ns else np.nan for q in qs] for v in (50, 5, 95)]
    return p[0], [np.subtract(p[0], p[1]).tolist(), np.subtract(p[2], p[0]).tolist()]


def pareto(*runs_and_out) -> FigureText:
    """Cost per frame against accuracy of every detector setting, over the nominal-noise variant runs."""
    *given, out = runs_and_out
    nominal = [r for r in _replayed(given) if r.noise == 1.0]
    load = os.getloadavg()
    scores = [score(nominal, s.label) for s in DETECTOR_SETTINGS]
    ranked = [s for s in scores if s.runs == len(nominal)]  # a setting on fewer runs is shown, not ranked
    fig, axes = plt.subplot_mosaic([["cost", "delay"], ["legend", "legend"]], figsize=(13, 6.8),
                                   height_ratios=[4, 1])
    ax0, ax1 = axes["cost"], axes["delay"]
    for k, (s, setting) in enumerate(zip(scores, DETECTOR_SETTINGS)):
        front = s in ranked and not dominated(s, ranked)
        q = s.quality
        marker = "o" if setting.pool == 1 else "s"
        style = {"color": f"C{k % 10}", "ms": 9, "mfc": f"C{k % 10}" if front else "none", "mew": 1.8}
        runs_note = f", {s.runs} of the {len(nominal)} runs: not ranked" if s.runs != len(nominal) else ""
        label = f"{s.label}: missed {q.missed}/{q.episodes}{runs_note}{' (Pareto front)' if front else ''}"
        ax0.plot(s.us_per_frame, q.false_alarm_share * 100, marker, label=label, **style)
        if q.delays_ns:
            d = np.asarray(q.delays_ns) / 1e6
            ax1.plot(s.us_per_frame, np.median(d), marker, **style)
            ax1.vlines(s.us_per_frame, np.percentile(d, 5), np.percentile(d, 95), color=f"C{k % 10}", lw=1)
    for ax in (ax0, ax1):
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.grid(alpha=0.3, which="both")
    ax0.set(xlabel="cost per frame (µs, Detector.step, this machine)",
            ylabel="false alarms (% of sticking frames)",
            title="cost against false alarms (filled: on the Pareto front)")
    ax1.axhline(0, color="0.4", lw=0.8)
    ax1.set(xlabel="cost per frame (µs)", ylabel="flag rise − true onset (ms)",
            title="cost against detection delay\n(median; bar: 5 to 95 %; below 0: a warning)")
    scenes = ", ".join(sorted({r.scene for r in nominal}))
    fig.suptitle(f"Every slip test replayed over {len(nominal)} runs of {scenes} (controller off)", fontsize=11)
    axes["legend"].axis("off")
    axes["legend"].legend(*ax0.get_legend_handles_labels(), fontsize=8, loc="center", ncol=3)
    png = save_png(fig, out, "pareto")
    table = ("| setting | runs | µs per frame | episodes | missed | delay p50 / p95 (ms) | median lateness (ms) | "
             "false alarms (%) | of which latch hold (%) | Pareto front |\n"
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | :---: |\n" + "\n".join(
                 f"| {s.label} | {s.runs} | {s.us_per_frame:.0f} | {s.quality.episodes} | {s.quality.missed} | "
                 f"{_delay_text(s.quality)} | {'–' if math.isnan(s.lateness_p50_ms) else f'{s.lateness_p50_ms:.1f}'} | "
                 f"{s.quality.false_alarm_share * 100:.2f} | "
                 f"{s.quality.latch_hold_share * 100:.2f} | "
                 f"{'yes' if s in ranked and not dominated(s, ranked) else '' if s in ranked else 'not ranked'} |"
                 for s in scores))
    front = " | ".join(s.label for s in ranked if not dominated(s, ranked))
    agreement = min(r.agreement for r in nominal if not math.isnan(r.agreement))
    frames = sum(len(r.frames[DETECTOR_SETTINGS[0].label].t_ns) for r in nominal)
    return FigureText("pareto", "Beyond the paper — cost and accuracy of every slip test", png,
                      "The paper compares the tests (7), (5), (6) and (11)/(12) by their limit curves, not by what "
                      "they cost or how well they detect a real slip.",
                      f"Each setting replays the {frames} contact messages of the sensitivity's {len(nominal)} runs "
                      f"at the scenes' noise through the slip detector node's Detector, timed per frame (load "
                      f"average {load[0]:.1f} / {load[1]:.1f} over 1 / 5 min on {len(os.sched_getaffinity(0))} "
                      f"cores), scored as the sensitivity is. The front is computed over cost, missed share, false "
                      f"alarms and the median lateness max(delay, 0): a flag that rose before the onset counts as "
                      f"on time, not better, and pays for rising early in false alarms. The paper's iteration "
                      f"({PAPER_ITERATION}, a millisecond a frame) is replayed on the scenes' own runs only, so it is "
                      f"shown and not ranked. "
                      f"Not dominated: {front}. "
                      f"The replay of each run's own setting flags as the run's detector did in at least "
                      f"{agreement * 100:.1f} % of the frames.",
                      "Costs are wall time on a shared machine (the load above): compare the settings with each "
                      "other, not with another machine; the F/T tests cost about the same, so which of them is on "
                      "the front can change from run to run. The F/T tests here get β_s of each pressure frame, so "
                      "they are better than without a tactile pad.",
                      table)
