"""The paper's figures, drawn as the paper draws them, from lock-step runs.

The figures ``slipstack reproduce`` draws and the runs each needs are
:mod:`slipstack.analysis.figure_keys`. Each ``fig*`` function takes the experiment's :class:`~slipstack.analysis.runs.Run`
(Fig. 5 takes none: it is the limit sets themselves), writes one PNG and returns a
:class:`FigureText`: what the paper shows, what this run shows (the numbers, computed
here from the run's own messages), and where the two differ and why. Units: N, N·m,
mm and degrees on the axes; SI inside.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from slipstack.analysis.runs import BETA_FIG11_M, Run  # noqa: E402
from slipstack.lib.defaults import MU  # noqa: E402
from slipstack.lib.limit_set import load_factor, torsional_coefficient  # noqa: E402
from slipstack.lib.pad import PadGeometry  # noqa: E402

__all__ = ["FigureText", "save_png", "exact_boundary"]

SIGMA_PAPER = 0.5
K_PAPER_N = 2.0


@dataclass(frozen=True)
class FigureText:
    """The text beside one figure: ``paper`` (what the paper shows), ``ours`` (what this
    run shows, with its numbers) and ``differences`` (where and why they differ)."""

    key: str
    title: str
    png: str
    paper: str
    ours: str
    differences: str


def save_png(fig, out_dir: Path, key: str) -> str:
    """Write ``fig`` to ``out_dir/<key>.png`` (110 dpi) and close it; returns the file name."""
    path = out_dir / f"{key}.png"
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path.name


def _slip_spans(ax, t: np.ndarray, flag: np.ndarray, color: str, label: str) -> None:
    """Shade the intervals where ``flag`` holds."""
    if not len(t):
        return
    edges = np.flatnonzero(np.diff(np.r_[0, flag.astype(int), 0]))
    for k, (a, b) in enumerate(zip(edges[::2], edges[1::2])):
        ax.axvspan(t[a], t[min(b, len(t) - 1)], color=color, alpha=0.2, lw=0, label=label if k == 0 else None)


def _flag_strip(ax, t: np.ndarray, flag: np.ndarray, lo: float, color: str, label: str | None) -> None:
    """A thin band at the top of ``ax`` (axes fraction ``lo`` to ``lo + 0.06``) where ``flag`` holds."""
    ax.fill_between(t, lo, lo + 0.06, where=flag, transform=ax.get_xaxis_transform(), color=color, lw=0,
                    label=label, step="post")


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


def _ft(run: Run) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Time (s), f_n (N), |f_t| (N), τ (N·m) of the F/T samples in the pad frame."""
    w = run["ft/wrench"]
    return w["t"], -w["force"][:, 2], np.hypot(w["force"][:, 0], w["force"][:, 1]), w["torque"][:, 2]


def _peak_and_plateau(t, ratio, gross) -> tuple[float, float, float]:
    """Peak of a friction ratio before gross slip, its mean while sliding, and the onset time."""
    onset = t[np.argmax(gross)] if gross.any() else t[-1]
    before = ratio[t <= onset + 0.005]
    sliding = ratio[gross] if gross.any() else ratio[-10:]
    return float(before.max()), float(np.median(sliding)), float(onset)


def fig4a(run: Run, out: Path) -> FigureText:
    t, f_n, f_t, _ = _ft(run)
    mu = np.where(f_n > 0.1, f_t / np.maximum(f_n, 1e-9), np.nan)
    tr = run["rig/truth"]
    gross = np.interp(t, tr["t"], tr["gross_slip"].astype(float)) > 0.5
    peak, plateau, onset = _peak_and_plateau(t, np.nan_to_num(mu), gross)
    c = run.scene.contact
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ax.plot(t, mu, lw=0.8, color="C0", label="μ(t) = |f_t| / f_n (F/T sensor)")
    ax.axhline(c.mu_s, color="C3", ls="--", lw=1, label=f"scene μ_s = {c.mu_s:g}")
    ax.axhline(c.mu_d, color="C2", ls="--", lw=1, label=f"scene μ_d = {c.mu_d:g}")
    ax.plot([onset], [peak], "kv", label=f"measured peak {peak:.3f}")
    _slip_spans(ax, t, gross, "C1", "true gross slip (rig)")
    ax.set(xlabel="time (s)", ylabel="μ = |f_t| / f_n", title="Fig. 4a: friction identification, tangential load",
           ylim=(0, max(0.6, np.nanmax(mu) * 1.1)))
    ax.legend(fontsize=8, loc="lower right")
    return FigureText("fig4a", "Fig. 4a — μ(t) under a rising tangential load", save_png(fig, out, "fig4a"),
                      f"At constant f_n the ratio |f_t|/f_n rises to the static coefficient and drops to a "
                      f"lower sliding value with stick–slip; the paper measured μ_s = {MU}.",
                      f"Peak {peak:.3f} at {onset:.2f} s (true gross-slip onset), median while sliding "
                      f"{plateau:.3f}; the scene's rubber has μ_s = {c.mu_s:g}, μ_d = {c.mu_d:g}.",
                      "The peak sits slightly below μ_s: the contact's edges already slide at μ_d before the "
                      "whole contact lets go (slip weakening), so the measured ratio never reaches μ_s exactly.")


def fig4b(run: Run, out: Path) -> FigureText:
    t, f_n, _, tau = _ft(run)
    beta_mm = np.where(f_n > 0.1, np.abs(tau) / np.maximum(f_n, 1e-9), np.nan) * 1e3
    tr = run["rig/truth"]
    sliding_core = np.interp(t, tr["t"], tr["sliding_fraction"]) > 0.9
    peak, plateau, onset = _peak_and_plateau(t, np.nan_to_num(beta_mm), sliding_core)
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ax.plot(t, beta_mm, lw=0.8, color="C0", label="β(t) = |τ| / f_n (F/T sensor)")
    ax.plot([onset], [peak], "kv", label=f"measured peak {peak:.3f} mm")
    ax.axhline(plateau, color="C2", ls="--", lw=1, label=f"median while sliding {plateau:.3f} mm")
    _slip_spans(ax, t, sliding_core, "C1", "> 90 % of the capacity sliding (rig)")
    ax.set(xlabel="time (s)", ylabel="β = |τ| / f_n (mm)", title="Fig. 4b: friction identification, torsion")
    ax.legend(fontsize=8, loc="lower right")
    return FigureText("fig4b", "Fig. 4b — β(t) under a rising torque", save_png(fig, out, "fig4b"),
                      "At constant f_n the ratio τ/f_n rises to the static torsional coefficient β_s and settles "
                      "to β_d while the object turns with stick–slip.",
                      f"Peak β_s ≈ {peak:.3f} mm at {onset:.2f} s, median while sliding β_d ≈ {plateau:.3f} mm "
                      f"(Hertzian fingertip: μ·(3π/16)·a predicts about 1.33 and 1.06 mm for a = 5 mm).",
                      "The paper reports β for its own fingertip; ours is the simulated Hertzian tip, so only the "
                      "shape of the curve (rise, peak, drop to a sliding plateau) is comparable.")


def exact_boundary(phi: np.ndarray, pad: PadGeometry, mu: float, f_n: float, n: int = 181):
    """Points (|f_t|, τ) on the exact limit curve of pressure ``phi`` in the (f_x, τ) plane."""
    pts = []
    for a in np.linspace(0, np.pi, n):
        direction = (math.cos(a), 0.0, math.sin(a) * 1e-2)  # (f_x N, f_y N, τ N·m) scaled to be comparable
        r = load_factor(phi, pad.positions, direction[:2], direction[2], mu)
        if r.gamma > 0:
            pts.append((direction[0] / r.gamma, direction[2] / r.gamma))
    return np.array(pts)


def fig5a(out: Path) -> FigureText:
    mu, f_n = 0.5, 10.0
    pad = PadGeometry()
    uniform = np.full(pad.n_taxels, f_n / pad.n_taxels)
    r = np.hypot(*pad.positions.T)
    a = 8e-3
    hertz = np.sqrt(np.clip(1 - (r / a) ** 2, 0, None))
    hertz *= f_n / hertz.sum()
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    ft = np.linspace(0, mu * f_n, 200)
    beta_u = torsional_coefficient(uniform, pad.positions, mu).beta_m
    beta = beta_u
    ax.plot(ft, beta * (f_n - ft / mu) * 1e3, color="C0", label="(5) linear: |f_t|/μ + |τ|/β = f_n")
    ax.plot(ft, beta * f_n * np.sqrt(np.clip(1 - (ft / (mu * f_n)) ** 2, 0, None)) * 1e3, color="C1",
            label="(6) elliptic: f_t²/μ² + τ²/β² = f_n²")
    ax.plot([0, mu * f_n, mu * f_n], [beta * f_n * 1e3, beta * f_n * 1e3, 0], color="C2", ls="--",
            label="decoupled: |f_t| ≤ μ f_n and |τ| ≤ β f_n")
    ax.axvline(mu * f_n, color="C4", ls=":", label="(7) Coulomb: |f_t| ≤ μ f_n (τ ignored)")
    worst = {}
    for label, phi, color in (("uniform pad", uniform, "k"), ("Hertzian, a = 8 mm", hertz, "C3")):
        b = exact_boundary(phi, pad, mu, f_n)
        ax.plot(b[:, 0], np.abs(b[:, 1]) * 1e3, color=color, lw=2 if color == "k" else 1.5,
                label=f"exact limit set, {label}")
        beta_p = torsional_coefficient(phi, pad.positions, mu).beta_m
        ell = beta_p * f_n * np.sqrt(np.clip(1 - (b[:, 0] / (mu * f_n)) ** 2, 0, None))
        worst[label] = float(np.max(np.abs(ell - np.abs(b[:, 1])) / (beta_p * f_n)))
    ax.set(xlabel="|f_t| (N)", ylabel="|τ| (N·mm)", xlim=(0, mu * f_n * 1.08), ylim=(0, beta * f_n * 1e3 * 1.1),
           title=f"Fig. 5a: limit curves at f_n = {f_n:g} N, μ = {mu:g} (β = β_s of the uniform pad)")
    fig.set_size_inches(6.4, 6.2)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2)
    return FigureText("fig5a", "Fig. 5a — limit curves in the (|f_t|, τ) plane", save_png(fig, out, "fig5a"),
                      "The paper compares approximate limit curves for μ = 0.5, β = 0.065, f_n = 10 N: the "
                      "linear surface (5), the ellipse (6), and the decoupled and Coulomb tests.",
                      f"The exact limit set (§4 of docs) of a uniform 16×16 pad (β_s = {beta_u * 1e3:.2f} mm) and "
                      f"of a Hertzian pressure; the ellipse (6) with each pressure's own β_s errs by up to "
                      + ", ".join(f"{v * 100:.1f} % of β_s f_n ({k})" for k, v in worst.items()) + ".",
                      "We draw the curves with the β_s of a real 20 mm pad (the paper's β = 0.065 is in its own "
                      "units); the exact curve is what the simulated contact really holds.")


def fig5b(out: Path) -> FigureText:
    """The limit surface in {|f_t|, |τ|, f_n}: the plane (5) and the exact surface, both cones."""
    mu = 0.5
    pad = PadGeometry()
    unit = np.full(pad.n_taxels, 1.0 / pad.n_taxels)  # 1 N spread evenly: the set scales with f_n
    beta = torsional_coefficient(unit, pad.positions, mu).beta_m
    edge = exact_boundary(unit, pad, mu, 1.0)  # (|f_t|, τ) per newton of f_n
    edge = edge[(edge[:, 0] >= 0) & (edge[:, 1] >= 0)]
    f_n = np.linspace(0, 10, 11)
    fig = plt.figure(figsize=(12, 5))
    ax0 = fig.add_subplot(1, 2, 1, projection="3d")
    ft_unit, tau_unit = np.meshgrid(np.linspace(0, 1, 15), f_n)  # the plane: f_n = |f_t|/μ + |τ|/β
    ft_plane = mu * tau_unit * ft_unit
    tau_plane = beta * tau_unit * (1 - ft_unit)
    ax0.plot_surface(ft_plane, tau_plane * 1e3, tau_unit, color="C0", alpha=0.35, lw=0)
    for fn in f_n[1::3]:
        ax0.plot(edge[:, 0] * fn, edge[:, 1] * fn * 1e3, fn, color="k", lw=1)
    ax0.plot([], [], color="C0", lw=6, alpha=0.35, label="(5): |f_t|/μ + |τ|/β = f_n (a plane)")
    ax0.plot([], [], color="k", lw=1, label="exact limit set of a uniform pad, at f_n = 1, 4, 7, 10 N")
    ax0.set(xlabel="|f_t| (N)", ylabel="|τ| (N·mm)", zlabel="f_n (N)", title="Fig. 5b: the limit surface")
    ax0.view_init(elev=20, azim=-55)
    ax0.legend(fontsize=8, loc="upper left")
    ax1 = fig.add_subplot(1, 2, 2)
    for k, fn in enumerate((2.5, 5.0, 10.0)):
        ax1.plot(edge[:, 0] * fn, edge[:, 1] * fn * 1e3, color=f"C{k}", lw=2, label=f"exact, f_n = {fn:g} N")
        ax1.plot([0, mu * fn], [beta * fn * 1e3, 0], color=f"C{k}", ls="--", lw=1,
                 label=f"(5), f_n = {fn:g} N")
    ax1.set(xlabel="|f_t| (N)", ylabel="|τ| (N·mm)", xlim=(0, None), ylim=(0, None),
            title="sections at constant f_n: the set grows in proportion")
    ax1.legend(fontsize=8, ncol=2)
    bulge = float(np.max(edge[:, 0] / mu + edge[:, 1] / beta))
    return FigureText("fig5b", "Fig. 5b — the friction plane in {f_t, τ, f_n}", save_png(fig, out, "fig5b"),
                      "The linear limit surface (5) is a plane through the origin of the {|f_t|, |τ|, f_n} space: "
                      "the contact sticks while the load lies above it, and every section at constant f_n is "
                      "the straight line of Fig. 5a, scaled by f_n.",
                      f"With μ = {mu:g} and the β_s of a uniform 16×16 pad ({beta * 1e3:.2f} mm), the exact limit "
                      f"set is also a cone (it scales with f_n) but bulges outside the plane: at its furthest "
                      f"point |f_t|/μ + |τ|/β = {bulge:.2f} f_n.",
                      "The plane is conservative: a load between it and the exact surface still sticks, so a "
                      "law built on (5) squeezes up to that factor harder than the contact needs.")


def _cone_plot(run: Run, out: Path, key: str, x_label: str, x_of, law_line, law_label: str, title: str,
               turns: bool = False):
    """The law's set points against its line, and force and slip over time (``turns``: the
    object can only rotate, so its slip is an angle)."""
    w = run["slip"]
    cmd = run["grip/command"]
    tr = run["rig/truth"]
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4))
    x = x_of(w)
    ax0.plot(x, w["f_n"], ".", ms=1.5, color="C0", label="measured (x, f_n)")
    xs = np.linspace(0, max(float(np.max(x)), 1e-9) * 1.05, 50)
    ax0.plot(xs, law_line(xs), color="C3", label=law_label)
    ax0.set(xlabel=x_label, ylabel="f_n (N)", title=title)
    ax0.legend(fontsize=8)
    ax1.plot(cmd["t"], cmd["f_n"], color="C3", lw=1, label="set point f_n (grip/command)")
    ax1.plot(tr["t"], tr["f_n_applied"], color="C0", lw=1, label="applied f_n (rig)")
    ax1b = ax1.twinx()
    slip, unit = (np.degrees(np.abs(tr["slip_angle_rad"])), "turned (deg)") if turns else \
        (tr["slip_distance_m"] * 1e3, "slid (mm)")
    ax1b.plot(tr["t"], slip, color="C2", lw=1, label=f"object {unit}, rig")
    ax1b.set(ylabel=unit, ylim=(0, max(1.0, 1.2 * float(np.max(slip)))))
    ax1.set(xlabel="time (s)", ylabel="f_n (N)", title="set point, applied force and slip")
    lines = ax1.get_legend_handles_labels()[0] + ax1b.get_legend_handles_labels()[0]
    ax1.legend(lines, [h.get_label() for h in lines], fontsize=8, loc="lower center")
    return save_png(fig, out, key)


def _slid(run: Run) -> tuple[float, float]:
    tr = run["rig/truth"]
    return float(tr["slip_distance_m"][-1] * 1e3), float(math.degrees(tr["slip_angle_rad"][-1]))


def _friction_note(run: Run) -> str:
    """Where the law's μ and β came from, and how often the law wanted more than f_max."""
    mu, beta = run.experiment.law_friction
    note = run.experiment.friction or f"μ = {mu:g}, β = {beta * 1e3:.2f} mm as declared"
    f_max = run.experiment.config.get("grip", {}).get("f_max_n", math.inf)
    capped = float(np.mean(run["grip/command"]["f_n"] >= f_max - 1e-9))
    return note + (f"; the set point sat at its ceiling f_max = {f_max:g} N in {capped * 100:.0f} % of the commands"
                   if capped else "")


def fig10(run: Run, out: Path) -> FigureText:
    mu, _ = run.experiment.law_friction
    png = _cone_plot(run, out, "fig10", "|f_t| (N)", lambda s: np.hypot(s["f_t"][:, 0], s["f_t"][:, 1]),
                     lambda x: np.maximum(x / (SIGMA_PAPER * mu), 2.0),
                     f"law f_n = |f_t|/(σμ), σ = {SIGMA_PAPER:g}, μ = {mu:.3f}",
                     "Fig. 10a: f_n against |f_t| (linear law)")
    slid, turned = _slid(run)
    peak = float(run["grip/command"]["f_n"].max())
    return FigureText("fig10", "Fig. 10 — linear slip control, F/T sensor only", png,
                      f"The normal force follows |f_t|/(σμ) with σ = {SIGMA_PAPER:g}, μ = {MU} (identified in "
                      "Fig. 4a): the set points lie on a line twice as steep as the friction cone, and the object "
                      "does not slip.",
                      f"Friction used: {_friction_note(run)}; the scene's μ_s = {run.scene.contact.mu_s:g}. "
                      f"Peak set point {peak:.2f} N; object slid {slid:.3f} mm in all.",
                      "None in kind; the disturbance profile is the scene's (ramp, hold, sine), not the paper's "
                      "recorded one.")


def fig11(run: Run, out: Path) -> FigureText:
    _, beta = run.experiment.law_friction
    png = _cone_plot(run, out, "fig11", "|τ| (N·mm)", lambda s: np.abs(s["tau"]) * 1e3,
                     lambda x: x * 1e-3 / beta + K_PAPER_N,
                     f"law (13): f_n = |τ|/β + k, k = {K_PAPER_N:g} N, β = {beta * 1e3:.2f} mm",
                     "Fig. 11: f_n against |τ| (law 13)", turns=True)
    slid, turned = _slid(run)
    return FigureText("fig11", "Fig. 11 — pure torque, law (13)", png,
                      f"With pure torque the normal force follows |τ|/β + k (k = {K_PAPER_N:g} N): a line offset by "
                      "k, with β identified in Fig. 4b.",
                      f"Friction used: {_friction_note(run)}; this contact's exact β_s is "
                      f"{BETA_FIG11_M * 1e3:.2f} mm. Object turned {turned:.3f}° in all; peak set point "
                      f"{run['grip/command']['f_n'].max():.2f} N.",
                      "Fig. 4b's ramp runs on a curved (Hertzian) fingertip, Fig. 11 on a flat contact over the "
                      "whole pad: β depends on the pressure's shape, so the identified β is smaller than this "
                      "contact's and law (13) squeezes harder than it needs to (safe, not economical). In the "
                      "paper both experiments use the same finger.")


def fig12(run: Run, out: Path) -> FigureText:
    mu, beta = run.experiment.law_friction
    s = run["slip"]
    ft = np.hypot(s["f_t"][:, 0], s["f_t"][:, 1])
    tau = np.abs(s["tau"])
    fig = plt.figure(figsize=(11, 4.2))
    ax0 = fig.add_subplot(1, 2, 1, projection="3d")
    ax0.scatter(ft, tau * 1e3, s["f_n"], s=1, c=s["t"], cmap="viridis")
    ax0.set(xlabel="|f_t| (N)", ylabel="|τ| (N·mm)", zlabel="f_n (N)", title="Fig. 12: set points {f_t, τ, f_n}")
    ax1 = fig.add_subplot(1, 2, 2)
    x = ft / mu + tau / beta
    ax1.plot(x, s["f_n"], ".", ms=1.5, label="measured")
    xs = np.linspace(0, x.max() * 1.05, 50)
    ax1.plot(xs, np.maximum(xs / SIGMA_PAPER, 2.0), color="C3", label="law: f_n = (|f_t|/μ + |τ|/β)/σ")
    ax1.plot(xs, xs, color="k", ls="--", lw=1, label="limit (5): f_n = |f_t|/μ + |τ|/β")
    ax1.set(xlabel=f"|f_t|/μ + |τ|/β (N), μ = {mu:.3f}, β = {beta * 1e3:.2f} mm", ylabel="f_n (N)",
            title="projection")
    ax1.legend(fontsize=8)
    png = save_png(fig, out, "fig12")
    slid, turned = _slid(run)
    margin = float(np.min(s["f_n"][x > 0.5] / x[x > 0.5])) if (x > 0.5).any() else float("nan")
    return FigureText("fig12", "Fig. 12 — force and torque, F/T only", png,
                      "The set points {f_t, τ, f_n} stay above the linear limit surface; projected on "
                      "f_t/μ + τ/β they lie on the law's line, with margin 1/σ = 2.",
                      f"Friction used: {_friction_note(run)}. Least f_n/(|f_t|/μ + |τ|/β) over the loaded samples "
                      f"{margin:.2f}; slid {slid:.3f} mm, turned {turned:.3f}°.",
                      "The ratio dips below 2 while the rate-limited actuator catches up with a rising load, and "
                      "wherever the law asks for more than f_max. β is Fig. 4b's fingertip's, smaller than this "
                      "contact's (see Fig. 11), so the law asks for more than it needs.")


def _detector_delta(run: Run) -> float:
    """The onset band δ the run's detector used (its material's, unless set)."""
    return run.detector.delta


def fig13(run: Run, out: Path) -> FigureText:
    pivot = tuple(run.scene.dof.pivot_m)
    s = run["slip"]
    tr = run["rig/truth"]
    delta = _detector_delta(run)
    fig, (ax0, ax1, ax2) = plt.subplots(1, 3, figsize=(15, 4))
    ax0.plot(tr["t"], np.degrees(tr["theta"]), color="C0", label="object angle (encoder)")
    _flag_strip(ax0, s["t"], s["state"] != "stick", 0.93, "C3", "slip flagged (γ ≥ 1 − δ, latched)")
    _flag_strip(ax0, tr["t"], tr["gross_slip"].astype(bool), 0.86, "C1", "true gross slip (rig)")
    ax0.set(xlabel="time (s)", ylabel="angle (deg)", title="Fig. 13: rotation about a known COR")
    ax0.legend(fontsize=8, loc="lower right")
    # the detector's own verdict: its load (f_t, τ), the pivot it judged about, and γ = τ_t/τ_c
    judged = (s["status"] == "ok") & s["p_c_valid"].astype(bool) & (s["gamma"] > 0)
    p_c = np.stack(s["p_c"][judged]).astype(float)
    f_t = np.stack(s["f_t"][judged]).astype(float)
    load = np.abs(s["tau"][judged] + f_t[:, 0] * p_c[:, 1] - f_t[:, 1] * p_c[:, 0])  # n = τ + f_t × p_c
    capacity = load / s["gamma"][judged]
    t_j = s["t"][judged]
    ax1.plot(t_j, load * 1e3, lw=1, color="C3", label="τ_t = |τ + f_t × p_c| (load)")
    ax1.plot(t_j, capacity * 1e3, lw=1, color="C0", label="τ_c = μ Σ φ_i |p_i − p_c| (capacity)")
    ax1.set(xlabel="time (s)", ylabel="N·mm", title="test (11) about the shaft, from the detector")
    ax1.legend(fontsize=8, loc="lower center")
    ax2.plot(s["t"], s["gamma"], lw=1, color="C0", label="γ = τ_t / τ_c (detector, slip topic)")
    ax2.axhline(1.0, color="k", lw=1, label="γ = 1: (11) fails")
    ax2.axhline(1.0 - delta, color="C3", ls="--", lw=1, label=f"1 − δ = {1 - delta:.2f}: slip flagged")
    _flag_strip(ax2, s["t"], s["state"] != "stick", 0.93, "C3", None)
    _flag_strip(ax2, tr["t"], tr["gross_slip"].astype(bool), 0.86, "C1", None)
    ax2.set(xlabel="time (s)", ylabel="γ", ylim=(0, 1.3), title="load factor about the shaft")
    ax2.legend(fontsize=8, loc="lower right")
    png = save_png(fig, out, "fig13")
    flagged = s["state"] != "stick"
    gross = np.interp(s["t"], tr["t"], tr["gross_slip"].astype(float)) > 0.5
    about_pivot = bool(judged.any()) and bool(np.allclose(p_c, pivot))
    first_flag = float(s["t"][np.argmax(flagged)]) if flagged.any() else float("nan")
    first_gross = float(s["t"][np.argmax(gross)]) if gross.any() else float("nan")
    lead_ms = (first_gross - first_flag) * 1e3
    return FigureText("fig13", "Fig. 13 — slip detection with a known COR", png,
                      "At constant f_n the object turns about a known pivot; test (11) compares the load torque "
                      "about it with the capacity and flags rotational slip while τ_t > τ_c.",
                      f"The detector evaluates (11) about the shaft at ({pivot[0] * 1e3:g}, {pivot[1] * 1e3:g}) mm "
                      f"(method tactile_cor_known{'' if about_pivot else '; NOT about the pivot'}), δ = {delta:.3f}. "
                      f"True gross slip in {gross.mean() * 100:.1f} % of frames, flagged in "
                      f"{flagged.mean() * 100:.1f} %; flagged during gross slip "
                      f"{np.mean(flagged[gross]) * 100 if gross.any() else 0:.1f} %; first flag {first_flag:.3f} s, "
                      f"first gross slip {first_gross:.3f} s ({lead_ms:+.0f} ms of warning).",
                      f"γ peaks at {float(np.max(s['gamma'])):.2f}: the rubber's edges already slide at μ_d before "
                      "the whole contact lets go, so the object turns before τ_t reaches the static capacity, and "
                      "while it slides τ_t stays below it (μ_d < μ_s). The flag therefore comes from the onset band "
                      "1 − δ and the latch, not from τ_t > τ_c.")


def fig14(run: Run, out: Path) -> FigureText:
    s = run["slip"]
    tr = run["rig/truth"]
    cor = run["cor"]
    fig, axes = plt.subplots(2, 3, figsize=(15, 7.5))
    ax = axes[0, 0]
    ax.plot(tr["t"], tr["slip_distance_m"] * 1e3, color="C0", label="slid (mm)")
    _flag_strip(ax, s["t"], s["state"] != "stick", 0.93, "C3", "slip alert")
    _flag_strip(ax, tr["t"], tr["gross_slip"].astype(bool), 0.86, "C1", "true gross slip (rig)")
    ax.set(xlabel="time (s)", ylabel="mm", title="Fig. 14: displacement and the alert")
    ax.legend(fontsize=8, loc="center left")
    _torque_panel(axes[0, 1], cor, reach_m=run.scene.pad.pitch_m * run.scene.pad.cols)
    ax = axes[0, 2]
    ax.plot(s["t"], s["f_t"][:, 0], lw=1, label="f_tx")
    ax.plot(s["t"], s["f_t"][:, 1], lw=1, label="f_ty")
    ax.set(xlabel="time (s)", ylabel="N", title="tangential force components")
    ax.legend(fontsize=8)
    ax = axes[1, 0]
    tip = ax.scatter(s["f_t"][:, 0], s["f_t"][:, 1], s=1, c=s["t"], cmap="viridis")
    fig.colorbar(tip, ax=ax, label="time (s)")
    ax.set(aspect="equal", adjustable="datalim", xlabel="f_tx (N)", ylabel="f_ty (N)", title="the f_t vector's tip over time")
    ax = axes[1, 1]
    half = run.scene.pad.pitch_m * run.scene.pad.cols / 2 * 1e3
    gross = np.interp(cor["t"], tr["t"], tr["gross_slip"].astype(float)) > 0.5
    ok = (cor["case"] == "rotation") & gross
    tv = tr["cor_valid"].astype(bool) & tr["gross_slip"].astype(bool)
    ax.plot(tr["cor"][tv, 0] * 1e3, tr["cor"][tv, 1] * 1e3, ".", ms=1.5, color="k", zorder=3, label="true COR (rig)")
    ax.plot(cor["p_c"][ok, 0] * 1e3, cor["p_c"][ok, 1] * 1e3, ".", ms=3, color="C3", alpha=0.5,
            label="estimated COR of impending slip")
    ax.add_patch(plt.Rectangle((-half, -half), 2 * half, 2 * half, fill=False, ls=":", color="0.5"))
    ax.set(xlim=(-half * 1.1, half * 1.1), ylim=(-half * 1.1, half * 1.1), aspect="equal", xlabel="x (mm)",
           ylabel="y (mm)", title="COR path on the pad, during gross slip")
    ax.legend(fontsize=8, loc="lower left", markerscale=4)
    axes[1, 2].axis("off")
    png = save_png(fig, out, "fig14")
    ok = cor["case"] == "rotation"
    both = np.flatnonzero(tv)
    err = float("nan")
    if ok.any() and both.size:
        est_t = cor["t"][ok]
        idx = np.clip(np.searchsorted(est_t, tr["t"][both]), 0, est_t.size - 1)
        err = float(np.median(np.hypot(*(cor["p_c"][ok][idx] - tr["cor"][both]).T)) * 1e3)
    flagged = s["state"] != "stick"
    gross = np.interp(s["t"], tr["t"], tr["gross_slip"].astype(float)) > 0.5
    return FigureText("fig14", "Fig. 14 — free object, unknown COR, controller off", png,
                      "The object slips under combined force and torque; the COR estimated from the tactile "
                      "pressure moves on the pad, and the alert rises with the displacement.",
                      f"Flagged during {np.mean(flagged[gross]) * 100 if gross.any() else 0:.1f} % of the gross-slip "
                      f"frames; median distance between the estimated COR and the rig's true one during gross slip "
                      f"{err:.2f} mm; slid {tr['slip_distance_m'][-1] * 1e3:.2f} mm in all.",
                      "The estimate is the COR of *impending* slip (the weighted geometric median family of "
                      "solutions); the rig's COR is of the actual motion, so they agree best at onset.")


def fig15(run: Run, out: Path) -> FigureText:
    s = run["slip"]
    tr = run["rig/truth"]
    cmd = run["grip/command"]
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4))
    ax0.plot(cmd["t"], cmd["f_n"], color="C3", lw=1, label="set point f_n")
    ax0.plot(tr["t"], tr["f_n_applied"], color="C0", lw=1, label="real f_n")
    ax0.plot(tr["t"], np.hypot(tr["load_f_t"][:, 0], tr["load_f_t"][:, 1]), color="C2", lw=1,
             label="disturbance |f_t| (N)")
    axb = ax0.twinx()
    axb.plot(tr["t"], np.degrees(tr["slip_angle_rad"]), color="C4", lw=1, label="slip angle (deg)")
    axb.set(ylabel="deg", ylim=(min(0.0, float(np.min(np.degrees(tr["slip_angle_rad"])))) * 1.2,
                               max(1.0, 1.2 * float(np.max(np.degrees(tr["slip_angle_rad"]))))))
    lines = ax0.get_legend_handles_labels()[0] + axb.get_legend_handles_labels()[0]
    ax0.legend(lines, [h.get_label() for h in lines], fontsize=8, loc="center right")
    ax0.set(xlabel="time (s)", ylabel="N", title="Fig. 15a: set point, real force, disturbance, angle")
    pad = run.scene.pad
    beta = torsional_coefficient(run.phi_sample, pad.positions, MU).beta_m if run.phi_sample is not None \
        else BETA_FIG11_M
    x = np.hypot(s["f_t"][:, 0], s["f_t"][:, 1]) / MU + np.abs(s["tau"]) / beta
    ax1.plot(x, s["f_n"], ".", ms=1.5, label="measured")
    xs = np.linspace(0, x.max() * 1.05, 50)
    ax1.plot(xs, xs, "k--", lw=1, label="f_n = |f_t|/μ + |τ|/β (limit (5))")
    ax1.set(xlabel=f"|f_t|/μ + |τ|/β (N), β = β_s = {beta * 1e3:.2f} mm of this contact", ylabel="f_n (N)",
            title="Fig. 15b: projection")
    ax1.legend(fontsize=8)
    png = save_png(fig, out, "fig15")
    slid, turned = _slid(run)
    return FigureText("fig15", "Fig. 15 — slip control with both sensors, law (14)", png,
                      "Law (14) raises f_n only when the tactile test (11) fails, by the increment that makes it "
                      "hold again; the paper reports less force than the F/T-only law for the same disturbance.",
                      f"Peak set point {cmd['f_n'].max():.2f} N, mean {cmd['f_n'].mean():.2f} N; slid {slid:.3f} mm, "
                      f"turned {turned:.3f}°.",
                      "slipstack's (14) uses the total increment N_A·δφ; the printed per-taxel δφ under-raises "
                      "(Correction 2 below runs both, and law (13), on this scene).")


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
                      "The paper computes the COR from (12). For a pure torque (f_t = 0) it does not say where that "
                      "point is; it is easy to take the centre of pressure.",
                      outcome,
                      "(12) with f_t = 0 is the optimality condition of min Σ φ_i |p_i − c|: the weighted geometric "
                      "median, which equals the centre of pressure only for a symmetric pressure. The capacity "
                      "T(c) is least there, so a test about the centre of pressure overstates it.")


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
