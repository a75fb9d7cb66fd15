"""The paper's slip-detection figures (Figs. 13 and 14) and Correction 1, from lock-step runs.

Beside the deciding test the run published, each shows what the paper's own method says
on the same contacts (:mod:`slipstack.analysis.replay`): test (11) at the COR of the
paper's Fig. 7 iteration, as a 0/1 trace of ``γ > 1`` per frame (the paper's plain
test) and with the detector's onset band and latch. See :mod:`slipstack.analysis.figures`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from slipstack.analysis.figures import FigureText, flag_strip, plt, save_png
from slipstack.analysis.replay import gammas, latch_config, latch_flags
from slipstack.analysis.runs import Run

__all__ = ["fig13", "fig14", "cor_median"]


def _zero_one(ax, traces: list[tuple[str, np.ndarray, np.ndarray, str]]) -> None:
    """Stacked 0/1 traces (name, flags, their times in s, colour), the first on top."""
    for k, (name, flag, t, color) in enumerate(traces):
        base = 1.5 * (len(traces) - 1 - k)
        ax.step(t, base + flag.astype(float), where="post", color=color, lw=1)
        ax.text(t[0], base + 1.12, name, fontsize=7, color=color, va="bottom")
    ax.set_yticks([1.5 * k + v for k in range(len(traces)) for v in (0, 1)],
                  ["0", "1"] * len(traces), fontsize=7)
    ax.set_ylim(-0.2, 1.5 * len(traces) + 0.1)


def _truth_on(t: np.ndarray, run: Run) -> np.ndarray:
    tr = run["rig/truth"]
    return np.interp(t, tr["t"], tr["gross_slip"].astype(float)) > 0.5


def _first(t: np.ndarray, flag: np.ndarray) -> float:
    return float(t[np.argmax(flag)]) if flag.any() else float("nan")


def fig13(run: Run, out: Path) -> FigureText:
    pivot = tuple(run.scene.dof.pivot_m)
    s = run["slip"]
    tr = run["rig/truth"]
    delta = run.detector.delta
    judged = (s["status"] == "ok") & s["p_c_valid"].astype(bool) & (s["gamma"] > 0)
    plain = judged & (s["gamma"] > 1.0)  # the paper's test: (11) fails, this frame alone
    band = s["state"] != "stick"
    gross = _truth_on(s["t"], run)
    fig, (ax0, ax1, ax2) = plt.subplots(1, 3, figsize=(16, 4.4))
    ax0.plot(tr["t"], np.degrees(tr["theta"]), color="C0", label="object angle (encoder)")
    flag_strip(ax0, s["t"], band, 0.93, "C3", "slip flagged (γ ≥ 1 − δ, latched)")
    flag_strip(ax0, tr["t"], tr["gross_slip"].astype(bool), 0.86, "C1", "true gross slip (rig)")
    ax0.set(xlabel="time (s)", ylabel="angle (deg)", title="Fig. 13a: rotation about a known COR")
    ax0.legend(fontsize=8, loc="lower right")
    _zero_one(ax1, [("(11) as the paper tests it: τ_t > τ_c", plain, s["t"], "C0"),
                    (f"(11) with the onset band: γ ≥ 1 − δ = {1 - delta:.2f}, latched", band, s["t"], "C3"),
                    ("true gross slip (rig)", gross, s["t"], "C1")])
    ax1.set(xlabel="time (s)", title="Fig. 13b: output of the test (0: stick, 1: slip)")
    p_c = np.stack(s["p_c"][judged]).astype(float)
    f_t = np.stack(s["f_t"][judged]).astype(float)
    load = np.abs(s["tau"][judged] + f_t[:, 0] * p_c[:, 1] - f_t[:, 1] * p_c[:, 0])  # n = τ + f_t × p_c
    t_j = s["t"][judged]
    ax2.plot(t_j, load * 1e3, lw=1, color="C3", label="τ_t = |τ + f_t × p_c| (load)")
    ax2.plot(t_j, load / s["gamma"][judged] * 1e3, lw=1, color="C0", label="τ_c = μ Σ φ_i |p_i − p_c| (capacity)")
    ax2.set(xlabel="time (s)", ylabel="N·mm", title="Fig. 13c: test (11) about the shaft, from the detector")
    ax2.legend(fontsize=8, loc="lower center")
    png = save_png(fig, out, "fig13")
    about_pivot = bool(judged.any()) and bool(np.allclose(p_c, pivot))
    first_flag, first_gross = _first(s["t"], band), _first(s["t"], gross)
    gamma_max = float(np.max(s["gamma"][judged])) if judged.any() else float("nan")
    return FigureText("fig13", "Fig. 13 — slip detection with a known COR", png,
                      "At constant f_n the object turns about a known pivot; test (11) compares the load torque "
                      "about it with the capacity, and its output (b) says slip while τ_t > τ_c.",
                      f"The detector evaluates (11) about the shaft at ({pivot[0] * 1e3:g}, {pivot[1] * 1e3:g}) mm "
                      f"(method tactile_cor_known{'' if about_pivot else '; NOT about the pivot'}), δ = {delta:.3f}. "
                      f"True gross slip in {gross.mean() * 100:.1f} % of frames. The paper's test τ_t > τ_c says slip "
                      f"in {plain.mean() * 100:.1f} % of the frames (γ at most {gamma_max:.3f}); with the onset "
                      f"band the flag is up in {band.mean() * 100:.1f} %, during gross slip in "
                      f"{np.mean(band[gross]) * 100 if gross.any() else 0:.1f} %; first flag {first_flag:.3f} s, "
                      f"first gross slip {first_gross:.3f} s ({(first_gross - first_flag) * 1e3:+.0f} ms of warning).",
                      "Measured by the sensors, τ_t never exceeds τ_c (see the first section): the rubber's edges "
                      "slide at μ_d before the whole contact lets go, so the object turns before τ_t reaches the "
                      "static capacity, and while it slides τ_t stays below it (μ_d < μ_s). The paper's trace in "
                      "(b) therefore stays at stick here, and the flag comes from the onset band and the latch.")


def fig14(run: Run, out: Path) -> FigureText:
    s = run["slip"]
    tr = run["rig/truth"]
    cor = run["cor"]
    paper = gammas(run, "tactile_cor")  # the paper's Fig. 7 iteration for the COR, then (11)
    paper_t = paper.t_ns * 1e-9
    paper_plain = paper.gamma > 1.0
    paper_band = latch_flags(paper, latch_config(run))
    exact_flag = s["state"] != "stick"
    fig, axes = plt.subplots(2, 3, figsize=(16, 8))
    ax = axes[0, 0]
    ax.plot(tr["t"], np.degrees(tr["theta"]), color="C0", label="rotation θ (deg)")
    twin = ax.twinx()
    twin.plot(tr["t"], tr["slip_distance_m"] * 1e3, color="0.5", lw=1, ls=":", label="slid (mm)")
    twin.set_ylabel("mm")
    ax.set(xlabel="time (s)", ylabel="deg", title="Fig. 14a: rotation of the object")
    lines = ax.get_legend_handles_labels()[0] + twin.get_legend_handles_labels()[0]
    ax.legend(lines, [h.get_label() for h in lines], fontsize=8, loc="upper left")
    ax = axes[0, 1]
    gross_s = _truth_on(s["t"], run)
    _zero_one(ax, [("paper: Fig. 7 COR, (11) τ_t > τ_c", paper_plain, paper_t, "C0"),
                   ("paper: Fig. 7 COR, (11) with the band, latched", paper_band, paper_t, "C2"),
                   ("exact test, band, latched (the run's)", exact_flag, s["t"], "C3"),
                   ("true gross slip (rig)", gross_s, s["t"], "C1")])
    ax.set(xlabel="time (s)", title="Fig. 14b: the alert of each method (0: stick, 1: slip)")
    _torque_panel(axes[0, 2], cor, reach_m=run.scene.pad.pitch_m * run.scene.pad.cols)
    ax = axes[1, 0]
    ax.plot(s["t"], s["f_t"][:, 0], lw=1, label="f_tx")
    ax.plot(s["t"], s["f_t"][:, 1], lw=1, label="f_ty")
    ax.set(xlabel="time (s)", ylabel="N", title="tangential force components")
    ax.legend(fontsize=8)
    ax = axes[1, 1]
    tip = ax.scatter(s["f_t"][:, 0], s["f_t"][:, 1], s=1, c=s["t"], cmap="viridis")
    fig.colorbar(tip, ax=ax, label="time (s)")
    ax.set(aspect="equal", adjustable="datalim", xlabel="f_tx (N)", ylabel="f_ty (N)",
           title="the f_t vector's tip over time")
    ax = axes[1, 2]
    half = run.scene.pad.pitch_m * run.scene.pad.cols / 2 * 1e3
    gross_cor = _truth_on(cor["t"], run)
    ok = (cor["case"] == "rotation") & gross_cor
    tv = tr["cor_valid"].astype(bool) & tr["gross_slip"].astype(bool)
    ax.plot(tr["cor"][tv, 0] * 1e3, tr["cor"][tv, 1] * 1e3, ".", ms=1.5, color="k", zorder=3, label="true COR (rig)")
    ax.plot(cor["p_c"][ok, 0] * 1e3, cor["p_c"][ok, 1] * 1e3, ".", ms=3, color="C3", alpha=0.5,
            label="estimated COR of impending slip")
    ax.add_patch(plt.Rectangle((-half, -half), 2 * half, 2 * half, fill=False, ls=":", color="0.5"))
    ax.set(xlim=(-half * 1.1, half * 1.1), ylim=(-half * 1.1, half * 1.1), aspect="equal", xlabel="x (mm)",
           ylabel="y (mm)", title="COR path on the pad, during gross slip")
    ax.legend(fontsize=8, loc="lower left", markerscale=4)
    png = save_png(fig, out, "fig14")
    rotation = cor["case"] == "rotation"
    both = np.flatnonzero(tv)
    err = float("nan")
    if rotation.any() and both.size:
        est_t = cor["t"][rotation]
        idx = np.clip(np.searchsorted(est_t, tr["t"][both]), 0, est_t.size - 1)
        err = float(np.median(np.hypot(*(cor["p_c"][rotation][idx] - tr["cor"][both]).T)) * 1e3)
    gross_p = _truth_on(paper_t, run)

    def during(flag: np.ndarray, gross: np.ndarray) -> float:
        return float(np.mean(flag[gross]) * 100) if gross.any() else 0.0

    return FigureText("fig14", "Fig. 14 — free object, unknown COR, controller off", png,
                      "The object slips under combined force and torque and turns; the COR estimated from the "
                      "tactile pressure by the paper's iteration (its Fig. 7) moves on the pad, and test (11) about "
                      "it raises the alert as the object turns.",
                      f"Over the gross-slip frames the alert is up: the paper's method, Fig. 7 COR and (11) "
                      f"τ_t > τ_c per frame, in {during(paper_plain, gross_p):.1f} % (γ at most "
                      f"{float(np.nanmax(paper.gamma)):.3f}); the same with the onset band and latch in "
                      f"{during(paper_band, gross_p):.1f} %; the exact test with band and latch (the run's own "
                      f"detector) in {during(exact_flag, gross_s):.1f} %. Median distance between the estimated COR "
                      f"and the rig's true one during gross slip {err:.2f} mm; turned "
                      f"{np.degrees(tr['theta'][-1]):.2f}°, slid {tr['slip_distance_m'][-1] * 1e3:.2f} mm in all.",
                      "The paper's (11) on measured loads hardly ever fails (see the first section), so its alert "
                      "needs the onset band; the estimate is the COR of *impending* slip, the rig's that of the "
                      "actual motion, so they agree best at onset.")


def _torque_panel(ax, cor: dict[str, np.ndarray], reach_m: float) -> None:
    """τ_t and τ_c about the COR of impending slip, where the estimator found a rotation
    about a point within ``reach_m`` (m) of the pad centre."""
    # a COR far off the pad is a near-translation: both torques about it grow with the distance
    ok = (cor["case"] == "rotation") & (np.hypot(*cor["p_c"].astype(float).T) <= reach_m)
    ax.plot(cor["t"][ok], np.abs(cor["load"][ok]) * 1e3, ".", ms=1.5, color="C3", label="τ_t = |τ + f_t × p_c| (load)")
    ax.plot(cor["t"][ok], cor["capacity"][ok] * 1e3, ".", ms=1.5, color="C0",
            label="τ_c = μ Σ φ_i |p_i − p_c| (capacity)")
    if ok.any():
        ax.set_ylim(0, 1.2 * np.percentile(np.r_[np.abs(cor["load"][ok]), cor["capacity"][ok]], 99) * 1e3)
    ax.set(xlabel="time (s)", ylabel="N·mm", title="load torque against capacity about the COR")
    ax.legend(fontsize=8, markerscale=6)


def cor_median(run: Run, out: Path) -> FigureText:
    """Correction (a): under a pure torque the COR is the weighted geometric median."""
    tr = run["rig/truth"]
    cor = run["cor"]
    pad = run.scene.pad
    phi = run.phi_sample
    positions = pad.positions
    cop = phi @ positions / phi.sum()
    est = cor["p_c"][cor["case"] == "rotation"].astype(float)
    est_median = np.median(est, axis=0) if est.size else np.full(2, np.nan)
    sliding = tr["cor_valid"].astype(bool) & tr["gross_slip"].astype(bool)
    true = np.median(tr["cor"][sliding], axis=0) if sliding.any() else np.full(2, np.nan)
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(12, 4.6), gridspec_kw={"width_ratios": [1.1, 1]})
    half = pad.pitch_m * pad.cols / 2 * 1e3
    image = ax0.scatter(*(positions * 1e3).T, c=phi * 1e3, cmap="Greys", marker="s", s=110)
    fig.colorbar(image, ax=ax0, label="φ per taxel (mN)")
    ax0.plot(*true * 1e3, "+", color="C2", ms=16, mew=2.5, label="true COR while slipping (rig, median)")
    ax0.plot(*est_median * 1e3, "o", mfc="none", mec="C3", ms=11, mew=2, label="our COR estimate (cor topic)")
    ax0.plot(*cop * 1e3, "x", color="C0", ms=11, mew=2.5, label="centre of pressure")
    ax0.set(xlabel="x (mm)", ylabel="y (mm)", xlim=(-half, half), ylim=(-half / 2, half / 2), aspect="equal",
            title="Correction 1: pure torque on a wedge-shaped pressure")
    ax0.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=2)
    x_mm = positions[:, 0] * 1e3
    columns = np.unique(np.round(x_mm, 6))
    profile = np.array([phi[np.isclose(x_mm, c)].sum() for c in columns]) * 1e3
    ax1.bar(columns, profile, width=pad.pitch_m * 1e3 * 0.9, color="0.75", label="pressure summed over y (mN)")
    ax1.axvline(cop[0] * 1e3, color="C0", lw=2, label=f"centre of pressure x = {cop[0] * 1e3:.2f} mm")
    ax1.axvline(est_median[0] * 1e3, color="C3", lw=2, ls="--",
                label=f"our estimate (geometric median) x = {est_median[0] * 1e3:.2f} mm")
    ax1.axvline(true[0] * 1e3, color="C2", lw=2, ls=":", label=f"true COR (rig) x = {true[0] * 1e3:.2f} mm")
    ax1.set(xlabel="x (mm)", ylabel="mN", title="along the wedge: where the object turns")
    ax1.legend(fontsize=8, loc="upper left")
    png = save_png(fig, out, "cor_median")
    err_est = float(np.hypot(*(est_median - true)) * 1e3)
    err_cop = float(np.hypot(*(cop - true)) * 1e3)
    if not sliding.any():
        outcome = (f"The object did not slip in this run; our estimate x = {est_median[0] * 1e3:.2f} mm, the "
                   f"centre of pressure x = {cop[0] * 1e3:.2f} mm.")
    else:
        outcome = (f"On a wedge-shaped pressure twisted by a pure torque the object turned about x = "
                   f"{true[0] * 1e3:.2f} mm (rig, median over the gross slip); our estimate, the pressure's "
                   f"weighted geometric median, lies {err_est:.2f} mm from it, the centre of pressure "
                   f"{err_cop:.2f} mm.")
    return FigureText("cor_median", "Correction 1 — a pure torque turns the object about the geometric median", png,
                      "The paper computes the COR from (12) and derives that for a pure torque (f_t = 0) it is the "
                      "centre of pressure.",
                      outcome,
                      "That derivation is the step we correct: (12) with f_t = 0 is the optimality condition of "
                      "min Σ φ_i |p_i − c|, whose solution is the weighted geometric median; setting the "
                      "distances |p_i − c| aside, as the derivation does, gives the centre of pressure, which "
                      "equals the median only for a symmetric pressure (docs/math.md §4.3). The capacity T(c) is "
                      "least at the median, so a test about the centre of pressure overstates it.")
