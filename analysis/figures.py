"""The paper's figures, drawn as the paper draws them, from lock-step runs: Figs. 4 and 5 and
what every figure shares.

The figures ``slipstack reproduce`` draws and the runs each needs are
:mod:`slipstack.analysis.figure_keys`. Each ``fig*`` function takes the experiment's
:class:`~slipstack.analysis.runs.Run` (Fig. 5 takes none: it is the limit sets themselves),
writes one PNG and returns a :class:`FigureText`: what the paper shows, what this run shows
(the numbers, computed here from the run's own messages), and where the two differ and why.
Figs. 10–12 and 15 are :mod:`slipstack.analysis.figures_control`, 13 and 14
:mod:`slipstack.analysis.figures_detection`. Units: N, N·m, mm and degrees on the axes; SI inside.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402

from slipstack.analysis.runs import Run, contact_beta_s  # noqa: E402
from slipstack.lib.defaults import MU  # noqa: E402
from slipstack.lib.limit_set import load_factor, torsional_coefficient  # noqa: E402

__all__ = ["FigureText", "save_png", "exact_boundary", "tidy_3d", "PAPER_FIG5"]

SIGMA_PAPER = 0.5
K_PAPER_N = 2.0


@dataclass(frozen=True)
class Fig5Numbers:
    """The numbers of the paper's Fig. 5: μ_s, β (m: the paper prints 0.065 without a unit;
    its τ/β must be a force, so β is a length, read here in metres, SI like its equations)
    and f_n (N)."""

    mu: float = 0.5
    beta_m: float = 0.065
    f_n: float = 10.0


PAPER_FIG5 = Fig5Numbers()


@dataclass(frozen=True)
class FigureText:
    """The text beside one figure: ``paper`` (what the paper shows), ``ours`` (what this
    run shows, with its numbers), ``differences`` (where and why they differ) and a
    Markdown ``table`` of its numbers (tables separated by a blank line), if any."""

    key: str
    title: str
    png: str
    paper: str
    ours: str
    differences: str
    table: str = ""


def save_png(fig, out_dir: Path, key: str) -> str:
    """Write ``fig`` to ``out_dir/<key>.png`` (110 dpi) and close it; returns the file name."""
    path = out_dir / f"{key}.png"
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path.name


def tidy_3d(ax, view: tuple[float, float] = (22, -58), zoom: float = 1.1) -> None:
    """A 3-D axes whose tick labels do not run together: at most four ticks an axis, small
    labels, the axis titles set off from them; the box ``zoom`` times its default size."""
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(matplotlib.ticker.MaxNLocator(4))
        axis.labelpad = 9
    ax.tick_params(labelsize=7, pad=1)
    ax.view_init(*view)
    ax.set_box_aspect(None, zoom=zoom)


def slip_spans(ax, t: np.ndarray, flag: np.ndarray, color: str, label: str) -> None:
    """Shade the intervals where ``flag`` holds."""
    if not len(t):
        return
    edges = np.flatnonzero(np.diff(np.r_[0, flag.astype(int), 0]))
    for k, (a, b) in enumerate(zip(edges[::2], edges[1::2])):
        ax.axvspan(t[a], t[min(b, len(t) - 1)], color=color, alpha=0.2, lw=0, label=label if k == 0 else None)


def flag_strip(ax, t: np.ndarray, flag: np.ndarray, lo: float, color: str, label: str | None) -> None:
    """A thin band at the top of ``ax`` (axes fraction ``lo`` to ``lo + 0.06``) where ``flag`` holds."""
    ax.fill_between(t, lo, lo + 0.06, where=flag, transform=ax.get_xaxis_transform(), color=color, lw=0,
                    label=label, step="post")


def ft_samples(run: Run) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Time (s), f_n (N), |f_t| (N), τ (N·m) of the F/T samples in the pad frame."""
    w = run["ft/wrench"]
    return w["t"], -w["force"][:, 2], np.hypot(w["force"][:, 0], w["force"][:, 1]), w["torque"][:, 2]


def _peak_and_plateau(t, ratio, gross) -> tuple[float, float, float]:
    """Peak of a friction ratio before gross slip, its median while sliding, and the onset time."""
    onset = t[np.argmax(gross)] if gross.any() else t[-1]
    before = ratio[t <= onset + 0.005]
    sliding = ratio[gross] if gross.any() else ratio[-10:]
    return float(before.max()), float(np.median(sliding)), float(onset)


def _peaks_before_each_slip(t, ratio, gross) -> tuple[np.ndarray, np.ndarray]:
    """Times and values of a friction ratio's peak before each gross-slip episode (stick–slip)."""
    edges = np.flatnonzero(np.diff(np.r_[0, gross.astype(int), 0]))
    starts, ends = edges[::2], edges[1::2]
    rest = np.r_[0, ends[:-1]]  # each loading starts where the previous slip ended
    peaks = [a + int(np.argmax(ratio[a:b + 1])) for a, b in zip(rest, starts)]
    return t[peaks], ratio[peaks]


def _relative(measured: float, truth: float) -> str:
    """``measured`` against ``truth`` in words: "+3.1 % above" or "equal to 0.1 %"."""
    error = (measured - truth) / truth * 100
    return f"equal within {abs(error):.1f} %" if abs(error) < 0.05 else \
        f"{abs(error):.1f} % {'above' if error > 0 else 'below'}"


def fig4a(run: Run, out: Path) -> FigureText:
    t, f_n, f_t, _ = ft_samples(run)
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
    slip_spans(ax, t, gross, "C1", "true gross slip (rig)")
    ax.set(xlabel="time (s)", ylabel="μ = |f_t| / f_n", title="Fig. 4a: friction identification, tangential load",
           ylim=(0, max(0.6, np.nanmax(mu) * 1.1)))
    ax.legend(fontsize=8, loc="lower right")
    return FigureText("fig4a", "Fig. 4a — μ(t) under a rising tangential load", save_png(fig, out, "fig4a"),
                      f"At constant f_n the ratio |f_t|/f_n rises to the static coefficient and drops to a "
                      f"lower sliding value with stick–slip; the paper measured μ_s = {MU}.",
                      f"Peak {peak:.3f} at {onset:.2f} s (true gross-slip onset), {_relative(peak, c.mu_s)} the "
                      f"scene's μ_s = {c.mu_s:g}; median while sliding {plateau:.3f}, {_relative(plateau, c.mu_d)} "
                      f"its μ_d = {c.mu_d:g}.",
                      "The same rise, peak and drop to a sliding plateau with stick–slip; the values are the "
                      "scene's rubber, which we gave the paper's μ_s.")


def fig4b(run: Run, out: Path) -> FigureText:
    t, f_n, _, tau = ft_samples(run)
    beta_mm = np.where(f_n > 0.1, np.abs(tau) / np.maximum(f_n, 1e-9), np.nan) * 1e3
    tr = run["rig/truth"]
    sliding_core = np.interp(t, tr["t"], tr["sliding_fraction"]) > 0.9
    peak, plateau, onset = _peak_and_plateau(t, np.nan_to_num(beta_mm), sliding_core)
    peak_t, peaks = _peaks_before_each_slip(t, np.nan_to_num(beta_mm), sliding_core)
    later = float(np.median(peaks[1:])) if len(peaks) > 1 else None  # one loading only (--quick): none
    c = run.scene.contact
    beta_s = contact_beta_s(run.scene) * 1e3
    beta_d = beta_s * c.mu_d / c.mu_s
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ax.plot(t, beta_mm, lw=0.8, color="C0", label="β(t) = |τ| / f_n (F/T sensor)")
    ax.axhline(beta_s, color="C3", ls="--", lw=1, label=f"scene β_s = {beta_s:.2f} mm")
    ax.axhline(beta_d, color="C2", ls="--", lw=1, label=f"scene β_d = β_s μ_d/μ_s = {beta_d:.2f} mm")
    ax.plot(peak_t, peaks, "kv", label=f"peak before each slip: first {peak:.2f} mm"
            + ("" if later is None else f", later (median) {later:.2f} mm"))
    slip_spans(ax, t, sliding_core, "C1", "> 90 % of the capacity sliding (rig)")
    ax.set(xlabel="time (s)", ylabel="β = |τ| / f_n (mm)", title="Fig. 4b: friction identification, torsion",
           ylim=(0, max(beta_s, float(np.nanmax(beta_mm))) * 1.15))
    ax.legend(fontsize=8, loc="lower right")
    return FigureText("fig4b", "Fig. 4b — β(t) under a rising torque", save_png(fig, out, "fig4b"),
                      "At constant f_n the ratio τ/f_n rises to the static torsional coefficient β_s and settles "
                      "to β_d while the object turns with stick–slip; the same finger as Fig. 4a.",
                      f"The fingertip of Fig. 4a and Figs. 10–12. First peak {peak:.3f} mm at {onset:.2f} s, "
                      f"{_relative(peak, beta_s)} the scene's β_s = {beta_s:.3f} mm (μ_s times the pressure-weighted "
                      f"mean distance from the pure-torque COR); median while sliding {plateau:.3f} mm, "
                      f"{_relative(plateau, beta_d)} β_d = β_s·μ_d/μ_s = {beta_d:.3f} mm."
                      + ("" if later is None else f" The {len(peaks) - 1} later loadings peak at {later:.3f} mm "
                         f"(median), {_relative(later, beta_s)} β_s."),
                      "The paper reports β for its own fingertip; ours is the simulated flat pad, so the shape of "
                      "the curve (rise, peak, drop to a sliding plateau) is what compares. The first loading peaks "
                      "below β_s: from rest a twist strains each patch in proportion to its distance from the "
                      "COR, so the rim reaches μ_s first and slides towards μ_d before the centre carries its "
                      "share (partial slip); after a slip every patch re-sticks at its sliding stress and they "
                      "reload together. Fig. 4a has no such loss: a translation strains every patch alike. "
                      "The sliding plateau "
                      "lies above β_s·μ_d/μ_s because under stick–slip every patch re-sticks before it has slid "
                      "far enough for its friction to fall all the way to μ_d, and the patches near the centre "
                      "of rotation hardly slide at all.")


def exact_boundary(phi: np.ndarray, positions: np.ndarray, mu: float, n: int = 181) -> np.ndarray:
    """Points (|f_t|, τ) (N, N·m) on the exact limit curve of pressure ``phi`` (N per point at
    ``positions``, m) in the (f_x, τ) plane, from pure force to pure torque and back."""
    f_n = float(phi.sum())
    beta = torsional_coefficient(phi, positions, mu).beta_m
    pts = []
    for a in np.linspace(0, np.pi, n):
        f_x, tau = math.cos(a) * mu * f_n, math.sin(a) * beta * f_n  # a direction, both axes alike
        r = load_factor(phi, positions, (f_x, 0.0), tau, mu)
        if r.gamma > 0:
            pts.append((f_x / r.gamma, tau / r.gamma))
    return np.array(pts)


def uniform_disc(f_n: float, beta_m: float, mu: float, points: int = 31) -> tuple[np.ndarray, np.ndarray]:
    """A uniform pressure of ``f_n`` (N) on a disc, ``points`` across, sized so that its β_s
    is ``beta_m``: (phi (K,), positions (K, 2) m). Its limit set is that of any size scaled."""
    grid = np.linspace(-1, 1, points)
    xy = np.array([(x, y) for x in grid for y in grid if x * x + y * y <= 1.0])
    phi = np.full(len(xy), f_n / len(xy))
    scale = beta_m / torsional_coefficient(phi, xy, mu).beta_m
    return phi, xy * scale


def fig5a(out: Path) -> FigureText:
    mu, beta, f_n = PAPER_FIG5.mu, PAPER_FIG5.beta_m, PAPER_FIG5.f_n
    phi, positions = uniform_disc(f_n, beta, mu)
    exact = exact_boundary(phi, positions, mu)
    exact = exact[exact[:, 1] >= -1e-12]
    fig, ax = plt.subplots(figsize=(6.4, 6.2))
    ft = np.linspace(0, mu * f_n, 200)
    ax.plot(ft, beta * (f_n - ft / mu), color="C0", label="(5) linear: |f_t|/μ + |τ|/β = f_n")
    ax.plot(exact[:, 0], exact[:, 1], color="k", lw=2, label="b, calculated: the exact limit set (uniform pressure)")
    ellipse = beta * f_n * np.sqrt(np.clip(1 - (ft / (mu * f_n)) ** 2, 0, None))
    ax.plot(ft, ellipse, color="C1", label="(6) elliptic: f_t²/μ² + τ²/β² = f_n²")
    ax.plot([0, mu * f_n, mu * f_n], [beta * f_n, beta * f_n, 0], color="C2", ls="--",
            label="d, decoupled: |f_t| ≤ μ f_n and |τ| ≤ β f_n")
    ax.set(xlabel="|f_t| (N)", ylabel="|τ| (N·m)", xlim=(0, mu * f_n * 1.08), ylim=(0, beta * f_n * 1.1),
           title=f"Fig. 5a: limit curves, μ_s = {mu:g}, β = {beta:g} m, f_n = {f_n:g} N")
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2)
    # how far (5) and (6) lie from b, along rays from the origin, in % of b's radius
    angle = np.arctan2(exact[:, 1] / (beta * f_n), exact[:, 0] / (mu * f_n))
    radius = np.hypot(exact[:, 0] / (mu * f_n), exact[:, 1] / (beta * f_n))
    linear = 1 / (np.abs(np.cos(angle)) + np.abs(np.sin(angle)))
    inside = float(np.max(1 - linear / radius) * 100)
    outside = float(np.max(1 / radius - 1) * 100)
    return FigureText("fig5a", "Fig. 5a — limit curves in the (|f_t|, τ) plane", save_png(fig, out, "fig5a"),
                      f"The paper compares, for μ_s = {mu:g}, β = {beta:g} and f_n = {f_n:g} N, the linear "
                      "approximation (5), the curve calculated from the contact's pressure (b), the elliptic "
                      "approximation (6) and the decoupled test (d); the Coulomb test (7) is the decoupled one "
                      "without its torque side.",
                      f"The same curves in the paper's numbers, β read in metres. Curve b is the exact limit set "
                      f"(docs/math.md §4) of a uniform pressure on a disc sized so that its β_s = {beta:g} m "
                      f"(the set of any size scaled is the same in these axes). (5) lies up to {inside:.1f} % "
                      f"inside b (safe); (6) up to {outside:.1f} % outside it (it calls stick on loads that slide).",
                      "The paper does not give the pressure its curve b was calculated for; a uniform one is the "
                      "usual choice. Its β carries no unit; in metres the torque axis reads in N·m, in another "
                      "unit the curves keep their shapes and only that axis is relabelled. (7) is not drawn: "
                      "its line |f_t| = μ f_n is the decoupled curve's right side.")


def fig5b(out: Path) -> FigureText:
    """The limit surface in {|f_t|, |τ|, f_n}: the plane (5) and the exact surface, both cones."""
    mu, beta, f_top = PAPER_FIG5.mu, PAPER_FIG5.beta_m, PAPER_FIG5.f_n
    phi, positions = uniform_disc(1.0, beta, mu)  # 1 N: the set scales with f_n
    edge = exact_boundary(phi, positions, mu)
    edge = edge[(edge[:, 0] >= 0) & (edge[:, 1] >= 0)]
    f_n = np.linspace(0, f_top, 11)
    fig = plt.figure(figsize=(12, 5.4))
    ax0 = fig.add_subplot(1, 2, 1, projection="3d")
    ft_unit, f_grid = np.meshgrid(np.linspace(0, 1, 15), f_n)  # the plane: f_n = |f_t|/μ + |τ|/β
    ax0.plot_surface(mu * f_grid * ft_unit, beta * f_grid * (1 - ft_unit), f_grid, color="C0", alpha=0.35, lw=0)
    sections = f_n[1::3]
    for fn in sections:
        ax0.plot(edge[:, 0] * fn, edge[:, 1] * fn, fn, color="k", lw=1)
    ax0.plot([], [], color="C0", lw=6, alpha=0.35, label="(5): |f_t|/μ + |τ|/β = f_n (a plane)")
    ax0.plot([], [], color="k", lw=1, label="exact limit set, uniform pressure, at f_n = "
             + ", ".join(f"{fn:g}" for fn in sections) + " N")
    ax0.set(xlabel="|f_t| (N)", ylabel="|τ| (N·m)", zlabel="f_n (N)", title="Fig. 5b: the limit surface")
    tidy_3d(ax0, zoom=0.92)  # the f_n label stays inside its half (at 1.1 it ran into the sections)
    ax0.legend(fontsize=8, loc="upper left")
    ax1 = fig.add_subplot(1, 2, 2)
    for k, fn in enumerate((f_top / 4, f_top / 2, f_top)):
        ax1.plot(edge[:, 0] * fn, edge[:, 1] * fn, color=f"C{k}", lw=2, label=f"exact, f_n = {fn:g} N")
        ax1.plot([0, mu * fn], [beta * fn, 0], color=f"C{k}", ls="--", lw=1, label=f"(5), f_n = {fn:g} N")
    ax1.set(xlabel="|f_t| (N)", ylabel="|τ| (N·m)", xlim=(0, None), ylim=(0, None),
            title="sections at constant f_n: the set grows in proportion")
    ax1.legend(fontsize=8, ncol=2)
    bulge = float(np.max(edge[:, 0] / mu + edge[:, 1] / beta))
    return FigureText("fig5b", "Fig. 5b — the friction plane in {f_t, τ, f_n}", save_png(fig, out, "fig5b"),
                      "The linear limit surface (5) is a plane through the origin of the {|f_t|, |τ|, f_n} space: "
                      "the contact sticks while the load lies above it, and every section at constant f_n is "
                      "the straight line of Fig. 5a, scaled by f_n.",
                      f"In Fig. 5a's numbers (μ = {mu:g}, β = {beta:g} m, uniform pressure), the exact limit set is "
                      f"also a cone (it scales with f_n) but bulges outside the plane: at its furthest point "
                      f"|f_t|/μ + |τ|/β = {bulge:.2f} f_n.",
                      "The plane is conservative: a load between it and the exact surface still sticks, so a "
                      "law built on (5) squeezes up to that factor harder than the contact needs.")


