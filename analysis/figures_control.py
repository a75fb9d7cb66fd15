"""The paper's slip-control figures (Figs. 10–12 and 15) and Correction 2, from lock-step runs.

Each plots the law's set points (circles, ``grip/command``) and the force the finger
applied (dots, the rig's truth) against the load the law saw (the ``slip`` verdict a
command answered), beside the friction limit the contact truly has (the scene's μ_s and
β_s) and the law's own line (the μ and β it was given), coloured by time; and the set
point, applied force, load and slip over time. See :mod:`slipstack.analysis.figures`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slipstack.analysis.figures import (K_PAPER_N, SIGMA_PAPER, FigureText, plt, save_png, tidy_3d)
from slipstack.analysis.runs import Run, contact_beta_s
from slipstack.lib.defaults import MU
from slipstack.lib.grip_laws import cone_margin_demand
from slipstack.lib.limit_set import torsional_coefficient

__all__ = ["SetPoints", "set_points", "saturation_note", "fig10", "fig11", "fig12", "fig15", "increment"]

MAX_CIRCLES = 400
"""Set points drawn at most per panel (evenly picked): more hide each other."""


@dataclass(frozen=True)
class SetPoints:
    """Each grip command with the load it answered: t (s), set point and applied f_n (N),
    |f_t| (N) and |τ| (N·m) of the ``slip`` verdict the command answered."""

    t: np.ndarray
    set_point: np.ndarray
    applied: np.ndarray
    f_t: np.ndarray
    tau: np.ndarray

    def every(self, most: int = MAX_CIRCLES) -> SetPoints:
        """At most ``most`` of them, evenly picked."""
        pick = slice(None, None, max(1, len(self.t) // most))
        return SetPoints(*(a[pick] for a in (self.t, self.set_point, self.applied, self.f_t, self.tau)))


def set_points(run: Run) -> SetPoints:
    """The run's commands, each with the latest verdict at or before it and the applied force then."""
    cmd, s, tr = run["grip/command"], run["slip"], run["rig/truth"]
    k = np.clip(np.searchsorted(s["t"], cmd["t"], side="right") - 1, 0, len(s["t"]) - 1)
    f_t = np.hypot(s["f_t"][k, 0], s["f_t"][k, 1]).astype(float)
    return SetPoints(cmd["t"], cmd["f_n"], np.interp(cmd["t"], tr["t"], tr["f_n_applied"]), f_t,
                     np.abs(s["tau"][k]).astype(float))


def saturation_note(run: Run) -> str:
    """How often the set point sat at its ceiling ``f_max_n`` (the launch argument), or ''."""
    f_max = float(run.experiment.arg("f_max_n"))
    capped = float(np.mean(run["grip/command"]["f_n"] >= f_max - 1e-9))
    return f"the set point sat at its ceiling f_max = {f_max:g} N in {capped * 100:.1f} % of the commands" \
        if capped else ""


def _friction_note(run: Run) -> str:
    """Where the law's μ and β came from, and how often the law wanted more than f_max."""
    mu, beta = run.experiment.law_friction
    note = run.experiment.friction or f"μ = {mu:g}, β = {beta * 1e3:.2f} mm as declared"
    saturated = saturation_note(run)
    return f"{note}; {saturated}" if saturated else note


def _slid(run: Run) -> tuple[float, float]:
    tr = run["rig/truth"]
    return float(tr["slip_distance_m"][-1] * 1e3), float(math.degrees(tr["slip_angle_rad"][-1]))


def _law_panel(fig, ax, x_set: np.ndarray, x_applied: np.ndarray, sp: SetPoints, x_label: str, title: str) -> None:
    """Set points (circles) and applied force (dots) against the load, coloured by time."""
    ax.scatter(x_applied, sp.applied, s=3, c=sp.t, cmap="viridis", label="applied f_n (rig)")
    ax.scatter(x_set, sp.set_point, s=22, facecolors="none", edgecolors=plt.cm.viridis(
        (sp.t - sp.t.min()) / max(float(np.ptp(sp.t)), 1e-9)), lw=0.8, label="set point (grip/command)")
    fig.colorbar(plt.cm.ScalarMappable(norm=plt.Normalize(sp.t.min(), sp.t.max()), cmap="viridis"), ax=ax,
                 label="time (s)")
    ax.set(xlabel=x_label, ylabel="f_n (N)", title=title, xlim=(0, None), ylim=(0, None))


def _time_panel(ax, run: Run, load, load_label: str, turns: bool, ylabel: str = "N") -> None:
    """Set point, applied force and the load over time; the object's slip on a second axis."""
    cmd, tr = run["grip/command"], run["rig/truth"]
    ax.plot(cmd["t"], cmd["f_n"], color="C3", lw=1, label="set point f_n (grip/command)")
    ax.plot(tr["t"], tr["f_n_applied"], color="C0", lw=1, label="applied f_n (rig)")
    ax.plot(tr["t"], load(tr), color="C2", lw=1, label=load_label)
    twin = ax.twinx()
    slip, unit = (np.degrees(np.abs(tr["slip_angle_rad"])), "turned (deg)") if turns else \
        (tr["slip_distance_m"] * 1e3, "slid (mm)")
    twin.plot(tr["t"], slip, color="C4", lw=1, label=f"object {unit}, rig")
    twin.set(ylabel=unit, ylim=(0, max(1.0, 1.2 * float(np.max(slip)))))
    ax.set(xlabel="time (s)", ylabel=ylabel, title="set point, applied force, load and slip")
    lines = ax.get_legend_handles_labels()[0] + twin.get_legend_handles_labels()[0]
    ax.legend(lines, [h.get_label() for h in lines], fontsize=7, loc="upper left")
    ax.set_ylim(0, 1.35 * ax.get_ylim()[1])


def _load_f_t(tr) -> np.ndarray:
    return np.hypot(tr["load_f_t"][:, 0], tr["load_f_t"][:, 1])


def _force_law_row(fig, axes, run: Run, law_line, law_label: str, name: str) -> tuple[float, float]:
    """One row of Fig. 10: f_n against |f_t| with the cone border and the law, and the time panel;
    returns (peak set point N, mean set point N)."""
    mu_s = run.scene.contact.mu_s
    sp = set_points(run)
    shown = sp.every()
    tr = run["rig/truth"]
    applied_ft = np.interp(shown.t, tr["t"], _load_f_t(tr))
    _law_panel(fig, axes[0], shown.f_t, applied_ft, shown, "|f_t| (N)", f"Fig. 10{name}: f_n against |f_t|")
    top = max(float(sp.f_t.max()), 1e-3) * 1.1
    xs = np.linspace(0, top, 50)
    axes[0].plot(xs, xs / mu_s, color="k", lw=1.2, label=f"friction-cone border f_n = |f_t|/μ_s (μ_s = {mu_s:g})")
    axes[0].fill_between(xs, 0, xs / mu_s, color="0.85", lw=0, label="outside the cone: slip", zorder=0)
    axes[0].plot(xs, law_line(xs), color="C3", lw=1.2, label=law_label)
    axes[0].legend(fontsize=7, loc="upper left")
    _time_panel(axes[1], run, _load_f_t, "load |f_t| (rig)", turns=False)
    return float(sp.set_point.max()), float(sp.set_point.mean())


def fig10(linear: Run, ref9: Run, out: Path) -> FigureText:
    mu, _ = linear.experiment.law_friction
    mu9, _ = ref9.experiment.law_friction
    margin = float(ref9.experiment.arg("cone_margin_n"))
    f_nom = float(linear.experiment.arg("f_nom_n"))
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.4), gridspec_kw={"width_ratios": [1.15, 1]})
    peak_a, mean_a = _force_law_row(fig, axes[0], linear, lambda x: np.maximum(x / (SIGMA_PAPER * mu), f_nom),
                                    f"(a) linear law f_n = |f_t|/(σμ), σ = {SIGMA_PAPER:g}, μ = {mu:.3f}", "a")
    peak_b, mean_b = _force_law_row(fig, axes[1], ref9,
                                    lambda x: np.maximum(cone_margin_demand(x, mu9, margin), f_nom),
                                    f"(b) ref. [9]: nearest f_nom, {margin:g} N inside the cone (μ = {mu9:.3f})", "b")
    png = save_png(fig, out, "fig10")
    slid_a, _ = _slid(linear)
    slid_b, _ = _slid(ref9)
    mu_s = linear.scene.contact.mu_s
    return FigureText("fig10", "Fig. 10 — slip control with the F/T sensor only: the linear law and ref. [9]", png,
                      f"(a) The normal force follows |f_t|/(σμ) with σ = {SIGMA_PAPER:g}, μ = {MU} (identified in "
                      "Fig. 4a): the set points lie on a line twice as steep as the border f_n = |f_t|/μ_s of the "
                      "friction cone, and the object does not slip. (b) The strategy of the paper's ref. [9] (its "
                      "Fig. 9): keep the force as near the nominal f_nom and as far from the cone as the load "
                      "allows.",
                      f"Friction used: {_friction_note(linear)}; the scene's μ_s = {mu_s:g}. (a) peak set point "
                      f"{peak_a:.2f} N, mean {mean_a:.2f} N, slid {slid_a:.3f} mm. (b) law cone_margin "
                      f"(docs/math.md §5) with a margin of {margin:g} N from the cone: peak {peak_b:.2f} N, mean "
                      f"{mean_b:.2f} N, slid {slid_b:.3f} mm ({_friction_note(ref9)}).",
                      "The disturbance profile is the scene's (ramp, hold, sine), not the paper's recorded one. "
                      "Ref. [9] is not in the repository: we read its strategy as the least d_f + w/d_s (d_f the "
                      "distance from f_nom, d_s from the cone's border), which keeps a constant margin from the "
                      "border; the linear law's margin grows with the load, so (b) holds the same load with less "
                      "force at high loads and as much at low ones.")


def fig11(run: Run, out: Path) -> FigureText:
    _, beta = run.experiment.law_friction
    beta_s = contact_beta_s(run.scene)
    f_nom = float(run.experiment.arg("f_nom_n"))
    sp = set_points(run)
    shown = sp.every()
    tr = run["rig/truth"]
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(13, 4.6), gridspec_kw={"width_ratios": [1.15, 1]})
    applied_tau = np.interp(shown.t, tr["t"], np.abs(tr["load_tau"]))
    _law_panel(fig, ax0, shown.tau * 1e3, applied_tau * 1e3, shown, "|τ| (N·mm)", "Fig. 11: f_n against |τ| (law 13)")
    xs = np.linspace(0, max(float(sp.tau.max()), 1e-6) * 1.1, 50)
    ax0.plot(xs * 1e3, xs / beta_s, color="k", lw=1.2, label=f"slip limit f_n = |τ|/β_s (the contact's β_s = "
                                                            f"{beta_s * 1e3:.2f} mm)")
    ax0.fill_between(xs * 1e3, 0, xs / beta_s, color="0.85", lw=0, label="below it: the object turns", zorder=0)
    ax0.plot(xs * 1e3, np.maximum(xs / beta + K_PAPER_N, f_nom), color="C3", lw=1.2,
             label=f"law (13): f_n = |τ|/β + k, k = {K_PAPER_N:g} N, β = {beta * 1e3:.2f} mm")
    ax0.legend(fontsize=7, loc="upper left")
    _time_panel(ax1, run, lambda t: np.abs(t["load_tau"]) * 1e3, "load |τ| (N·mm, rig)", turns=True,
                ylabel="f_n (N), |τ| (N·mm)")
    png = save_png(fig, out, "fig11")
    _, turned = _slid(run)
    over = float(np.mean(sp.set_point - sp.tau / beta_s))
    return FigureText("fig11", "Fig. 11 — pure torque, law (13)", png,
                      f"With pure torque the normal force follows |τ|/β + k (k = {K_PAPER_N:g} N): a line offset by "
                      "k from the slip limit, with β identified in Fig. 4b on the same finger.",
                      f"Friction used: {_friction_note(run)}; this contact's exact β_s is {beta_s * 1e3:.2f} mm, so "
                      f"the law's β is {(beta / beta_s - 1) * 100:+.1f} % off it. The set points lie on average "
                      f"{over:.2f} N above the slip limit; object turned {abs(turned):.3f}° in all; peak set point "
                      f"{sp.set_point.max():.2f} N.",
                      "None in kind: the torque profile is the scene's (ramp, hold, sine), not the paper's recorded "
                      "one, and the finger the simulated flat pad.")


def _plane(ax, mu: float, beta: float, top_ft: float, top_tau: float, label: str) -> None:
    """The plane (5), f_n = |f_t|/μ + |τ|/β, over [0, top_ft] × [0, top_tau] (N, N·m), in N, N·mm, N."""
    ft, tau = np.meshgrid(np.linspace(0, top_ft, 12), np.linspace(0, top_tau, 12))
    ax.plot_surface(ft, tau * 1e3, ft / mu + tau / beta, color="0.55", alpha=0.3, lw=0)
    ax.plot([], [], color="0.55", lw=6, alpha=0.4, label=label)


def _set_points_3d(fig, ax, run: Run, sp: SetPoints, mu_s: float, beta_s: float, title: str) -> None:
    """Set points (circles) and applied force (dots) in {|f_t|, |τ|, f_n}, over the friction plane."""
    shown = sp.every(250)
    tr = run["rig/truth"]
    colour = plt.cm.viridis((shown.t - sp.t.min()) / max(float(np.ptp(sp.t)), 1e-9))
    _plane(ax, mu_s, beta_s, float(sp.f_t.max()) * 1.1 + 1e-3, float(sp.tau.max()) * 1.1 + 1e-6,
           f"friction plane (5) of the contact: μ_s = {mu_s:g}, β_s = {beta_s * 1e3:.2f} mm")
    ax.scatter(np.interp(shown.t, tr["t"], _load_f_t(tr)), np.interp(shown.t, tr["t"], np.abs(tr["load_tau"])) * 1e3,
               shown.applied, s=3, c=colour, depthshade=False, label="applied f_n (rig)")
    ax.scatter(shown.f_t, shown.tau * 1e3, shown.set_point, s=20, facecolors="none", edgecolors=colour, lw=0.7,
               depthshade=False, label="set point (grip/command)")
    fig.colorbar(plt.cm.ScalarMappable(norm=plt.Normalize(sp.t.min(), sp.t.max()), cmap="viridis"), ax=ax,
                 label="time (s)", shrink=0.6, pad=0.16)
    ax.set(xlabel="|f_t| (N)", ylabel="|τ| (N·mm)", zlabel="f_n (N)", title=title)
    tidy_3d(ax)
    ax.legend(fontsize=7, loc="upper left")


def _projection(fig, ax, run: Run, sp: SetPoints, mu: float, beta: float, law, law_label: str) -> np.ndarray:
    """Set points and applied force against |f_t|/μ + |τ|/β (the law's μ, β); returns that load per command."""
    x = sp.f_t / mu + sp.tau / beta
    shown = sp.every()
    xs_shown = shown.f_t / mu + shown.tau / beta
    _law_panel(fig, ax, xs_shown, xs_shown, shown, f"|f_t|/μ + |τ|/β (N), μ = {mu:.3f}, β = {beta * 1e3:.2f} mm",
               "projection on the friction plane's normal")
    xs = np.linspace(0, max(float(x.max()), 1e-6) * 1.05, 50)
    ax.plot(xs, xs, color="k", ls="--", lw=1, label="limit (5): f_n = |f_t|/μ + |τ|/β")
    if law is not None:
        ax.plot(xs, law(xs), color="C3", lw=1.2, label=law_label)
    ax.legend(fontsize=7, loc="lower right")  # below the limit line: no set point there
    return x


def fig12(run: Run, out: Path) -> FigureText:
    mu, beta = run.experiment.law_friction
    f_nom = float(run.experiment.arg("f_nom_n"))
    c = run.scene.contact
    beta_s = contact_beta_s(run.scene)
    sp = set_points(run)
    fig = plt.figure(figsize=(15, 5.8))
    ax0 = fig.add_subplot(1, 2, 1, projection="3d")
    _set_points_3d(fig, ax0, run, sp, c.mu_s, beta_s, "Fig. 12: set points {|f_t|, |τ|, f_n}")
    ax1 = fig.add_subplot(1, 2, 2)
    x = _projection(fig, ax1, run, sp, mu, beta, lambda xs: np.maximum(xs / SIGMA_PAPER, f_nom),
                    f"law: f_n = (|f_t|/μ + |τ|/β)/σ, σ = {SIGMA_PAPER:g}")
    png = save_png(fig, out, "fig12")
    slid, turned = _slid(run)
    loaded = x > 0.5
    margin = float(np.min(sp.set_point[loaded] / x[loaded])) if loaded.any() else float("nan")
    true_x = sp.f_t / c.mu_s + sp.tau / beta_s
    above = float(np.mean(sp.set_point >= true_x) * 100)
    return FigureText("fig12", "Fig. 12 — force and torque, F/T only", png,
                      "The set points {f_t, τ, f_n} stay above the linear limit surface (5), the friction plane; "
                      "projected on f_t/μ + τ/β they lie on the law's line, with margin 1/σ = "
                      f"{1 / SIGMA_PAPER:g}.",
                      f"Friction used: {_friction_note(run)}. Set points above the contact's own friction plane "
                      f"(μ_s = {c.mu_s:g}, β_s = {beta_s * 1e3:.2f} mm) in {above:.1f} % of the commands; least set "
                      f"point over |f_t|/μ + |τ|/β over the loaded commands {margin:.2f}; slid {slid:.3f} mm, "
                      f"turned {turned:.3f}°.",
                      ("The ratio never falls below 1/σ: the actuator keeps up with the load and the law never "
                       "asks for more than f_max. " if margin >= 1 / SIGMA_PAPER - 1e-3 else
                       "The ratio falls below 1/σ where the rate-limited actuator lags a rising load or the law "
                       "asks for more than f_max. ")
                      + "The load is the scene's (ramp, hold, sine), not the paper's recorded one.")


def fig15(run: Run, out: Path) -> FigureText:
    tr = run["rig/truth"]
    cmd = run["grip/command"]
    beta_s = torsional_beta(run)
    c = run.scene.contact
    sp = set_points(run)
    fig = plt.figure(figsize=(18, 7.6))
    grid = fig.add_gridspec(2, 3, width_ratios=[1.0, 1.45, 1.0])
    ax0 = fig.add_subplot(grid[0, 0])
    ax0.plot(cmd["t"], cmd["f_n"], color="C3", lw=1, label="a: set point f_n")
    ax0.plot(tr["t"], tr["f_n_applied"], color="C0", lw=1, label="b: real f_n")
    ax0.plot(tr["t"], _load_f_t(tr), color="C2", lw=1, label="c: disturbance force |f_t|")
    ax0.set(ylabel="N", title="Fig. 15a: set point, real force, disturbance")
    ax0.legend(fontsize=7, loc="upper left")
    ax0.set_ylim(0, 1.3 * ax0.get_ylim()[1])
    ax1 = fig.add_subplot(grid[1, 0], sharex=ax0)
    ax1.plot(tr["t"], tr["load_tau"] * 1e3, color="C1", lw=1, label="d: disturbance torque τ (N·mm)")
    twin = ax1.twinx()
    angle = np.degrees(tr["slip_angle_rad"])
    twin.plot(tr["t"], angle, color="C4", lw=1, label="slip angle (deg)")
    twin.set(ylabel="deg", ylim=(min(0.0, float(angle.min())) * 1.2, max(1.0, 1.2 * float(angle.max()))))
    ax1.set(xlabel="time (s)", ylabel="N·mm", title="disturbance torque and slip angle")
    lines = ax1.get_legend_handles_labels()[0] + twin.get_legend_handles_labels()[0]
    ax1.legend(lines, [h.get_label() for h in lines], fontsize=7, loc="lower left")
    ax2 = fig.add_subplot(grid[:, 1], projection="3d")
    _set_points_3d(fig, ax2, run, sp, c.mu_s, beta_s, "Fig. 15b: set points {|f_t|, |τ|, f_n}")
    ax3 = fig.add_subplot(grid[:, 2])
    _projection(fig, ax3, run, sp, c.mu_s, beta_s, None, "")
    png = save_png(fig, out, "fig15")
    slid, turned = _slid(run)
    above = float(np.mean(sp.set_point >= sp.f_t / c.mu_s + sp.tau / beta_s) * 100)
    return FigureText("fig15", "Fig. 15 — slip control with both sensors, law (14)", png,
                      "Law (14) raises f_n only when the tactile test (11) fails, by the increment that makes it "
                      "hold again; (a) shows the set point, the real force and the disturbance force and torque, "
                      "(b) the set points in {f_t, τ, f_n}; the paper reports less force than the F/T-only law "
                      "for the same disturbance.",
                      f"Peak set point {cmd['f_n'].max():.2f} N, mean {cmd['f_n'].mean():.2f} N; set points above "
                      f"the friction plane (5) of the contact (β_s = {beta_s * 1e3:.2f} mm, μ_s = {c.mu_s:g}) in "
                      f"{above:.1f} % of the commands (law (14) needs no plane: (5) is conservative); slid "
                      f"{slid:.3f} mm, turned {turned:.3f}°.",
                      "slipstack's (14) uses the total increment N_A·δφ; the printed per-taxel δφ under-raises "
                      "(Correction 2 below runs both, and law (13), on this scene). The disturbance is the scene's "
                      f"(a force {np.hypot(*run.scene.disturbance.point_m) * 1e3:g} mm off the object's centre, so "
                      "its torque follows it), not the paper's recorded one.")


def torsional_beta(run: Run) -> float:
    """β_s (m) of the run's contact: from a pressure frame of the run if it has one, else the scene's."""
    if run.phi_sample is not None:
        return torsional_coefficient(run.phi_sample, run.scene.pad.positions, run.scene.contact.mu_s).beta_m
    return contact_beta_s(run.scene)


def increment(total: Run, per_taxel: Run, ft13: Run, out: Path) -> FigureText:
    """Correction (b): law (14)'s total increment against the per-taxel one as printed,
    and law (13) with the F/T sensor only, on fig15 in closed loop."""
    runs = (("(14) total N_A·δφ (ours)", total, "C0"), ("(14) per-taxel δφ (as printed)", per_taxel, "C3"),
            ("(13) F/T only, exact β_s", ft13, "C2"))
    fig, ((ax0, axd), (ax1, ax2)) = plt.subplots(2, 2, figsize=(12, 7.5))
    rows = []
    for label, run, color in runs:
        cmd = run["grip/command"]
        tr = run["rig/truth"]
        ax0.plot(cmd["t"], cmd["f_n"], color=color, lw=1, label=label)
        ax1.plot(tr["t"], tr["slip_distance_m"] * 1e3, color=color, lw=1.2, label=label)
        ax2.plot(tr["t"], np.degrees(tr["slip_angle_rad"]), color=color, lw=1.2, label=label)
        slid, turned = _slid(run)
        rows.append((label, float(cmd["f_n"].max()), float(cmd["f_n"].mean()), slid, turned))
    load = total["rig/truth"]
    axd.plot(load["t"], np.hypot(load["load_f_t"][:, 0], load["load_f_t"][:, 1]), color="k", lw=1,
             label="|f_t| of the motor (N)")
    axt = axd.twinx()
    axt.plot(load["t"], np.abs(load["load_tau"]) * 1e3, color="C1", lw=1, label="|τ| of the motor (N·mm)")
    axt.set_ylabel("N·mm")
    lines = axd.get_legend_handles_labels()[0] + axt.get_legend_handles_labels()[0]
    axd.legend(lines, [h.get_label() for h in lines], fontsize=8, loc="upper left")
    axd.set(xlabel="time (s)", ylabel="N", title="the disturbance (the motor, in the total-increment run)")
    ax0.set(xlabel="time (s)", ylabel="set point f_n (N)", title="fig15: grip force commanded")
    ax1.set(xlabel="time (s)", ylabel="mm", title="object slid (rig)")
    ax2.set(xlabel="time (s)", ylabel="deg", title="object turned (rig)")
    for ax in (ax0, ax1, ax2):
        ax.legend(fontsize=8, loc="upper left")
    png = save_png(fig, out, "increment")
    numbers = "; ".join(f"{label}: peak {peak:.2f} N, mean {mean:.2f} N, slid {slid:.2f} mm, turned {turned:.2f}°"
                        for label, peak, mean, slid, turned in rows)
    (_, peak14, mean14, *_), _, (_, peak13, mean13, *_) = rows
    return FigureText("increment", "Correction 2 — law (14)'s increment in closed loop, and (14) against (13)", png,
                      "Law (14) raises every taxel in contact by δφ so that (11) holds again; the paper prints δφ as "
                      "the increment of the normal force. It reports that with both sensors the grip needs less "
                      "force than with the F/T sensor alone.",
                      f"On fig15: {numbers}.",
                      "Raising every taxel by δφ raises f_n by N_A·δφ: the printed per-taxel value commands "
                      "1/N_A of the force that restores (11), so the grip lags the load and the object slides. "
                      f"Less force with both sensors holds for the peak ({peak14:.2f} against {peak13:.2f} N) "
                      f"{'and' if mean14 < mean13 else 'but not'} for the mean ({mean14:.2f} against "
                      f"{mean13:.2f} N): law (14) never releases, so it keeps its peak, and (13) is given this "
                      "contact's exact β_s here.")
