"""Beyond the paper: grip force against the oracle, and how far the limit surfaces (5) and
(6) are from the exact limit set (the cost and accuracy of each slip test is
:mod:`slipstack.analysis.sensitivity`).

More in docs/modules.md, `analysis/beyond.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slipstack.analysis.figures import FigureText, plt, save_png
from slipstack.analysis.grip_oracle import oracle_series
from slipstack.lib.limit_set import load_factor, torsional_coefficient
from slipstack.lib.pad import PadGeometry

__all__ = ["grip_economy", "LimitError", "limit_error", "limit_errors"]


def grip_economy(*runs_and_out, max_samples: int = 400) -> FigureText:
    """Commanded f_n of each grip law on fig15 against the oracle's least holding force."""
    *runs, out = runs_and_out
    fig, (ax, axr) = plt.subplots(2, 1, figsize=(11, 7), sharex=True, gridspec_kw={"height_ratios": [3, 1.3]})
    rows = []
    oracle_mean = None
    for k, run in enumerate(runs):
        tr = run["rig/truth"]
        every = max(1, len(tr["t"]) // max_samples)
        pick = slice(None, None, every)
        oracle = oracle_series(run.scene, tr["x"][pick], tr["y"][pick], tr["theta"][pick], tr["f_n_applied"][pick],
                               tr["load_f_t"][pick], tr["load_tau"][pick]).least
        cmd = run["grip/command"]
        label = run.experiment.protocol.split(":", 1)[-1].strip()
        ax.plot(cmd["t"], cmd["f_n"], color=f"C{k}", lw=1.2, label=f"{run.experiment.key}: {label}")
        ax.plot(tr["t"][pick], oracle, color=f"C{k}", lw=0.8, ls=":")
        finite = np.isfinite(oracle)
        commanded = np.interp(tr["t"][pick], cmd["t"], cmd["f_n"]) if len(cmd["t"]) else np.full(oracle.shape, np.nan)
        o_mean = float(np.mean(oracle[finite])) if finite.any() else math.nan
        oracle_mean = o_mean if oracle_mean is None else oracle_mean
        rows.append((run.experiment.key, float(np.mean(commanded)), float(np.max(commanded)), o_mean,
                     float(np.max(oracle[finite])) if finite.any() else math.nan,
                     float(tr["slip_distance_m"][-1] * 1e3), float(np.mean(commanded[finite] < oracle[finite]) * 100)
                     if finite.any() else math.nan))
    ax.plot([], [], color="k", ls=":", label="the oracle of each run (dotted, its colour)")
    ax.set_ylim(0, 1.45 * ax.get_ylim()[1])  # room for the legend above the curves
    ax.set(ylabel="f_n (N)", title="fig15: commanded grip of each law against the least force that holds the true load")
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3)
    tr = runs[0]["rig/truth"]
    axr.plot(tr["t"], np.hypot(*tr["load_f_t"].T), color="k", lw=1, label="|f_t| transmitted (N)")
    axt = axr.twinx()
    axt.plot(tr["t"], np.abs(tr["load_tau"]) * 1e3, color="C1", lw=1, label="|τ| transmitted (N·mm)")
    axt.set_ylabel("N·mm")
    lines = axr.get_legend_handles_labels()[0] + axt.get_legend_handles_labels()[0]
    axr.legend(lines, [h.get_label() for h in lines], fontsize=8, loc="upper left")
    axr.set(xlabel="time (s)", ylabel="N", title=f"the true load ({runs[0].experiment.key} run)")
    png = save_png(fig, out, "grip_economy")
    numbers = "; ".join(f"{key}: mean {mean:.2f} N ({mean / om:.2f}× its oracle's mean {om:.2f} N), peak "
                        f"{peak:.2f} N (oracle peak {op:.2f} N), below the oracle in {below:.0f} % of the samples, "
                        f"slid {slid:.2f} mm"
                        for key, mean, peak, om, op, slid, below in rows)
    return FigureText("grip_economy", "Beyond the paper — grip force of each law against the oracle", png,
                      "The paper compares the laws with each other (less force with both sensors), not with the "
                      "least force the contact needs.",
                      f"The oracle is the least f_n with which the true pressure holds the true load (μ = μ_s, "
                      f"the rig's truth, {len(tr['t'][::max(1, len(tr['t']) // max_samples)])} truth samples per "
                      f"run; the code of "
                      f"tests/bench/bench_grip_economy.py). {numbers}.",
                      "A run that slides transmits only sliding friction, so its oracle is lower than the load it "
                      "resists: compare the ratios of runs that held. The oracle knows the true pressure and load; "
                      "every law sees them through sensors and must keep a margin (f_nom, the onset band).")


@dataclass(frozen=True)
class LimitError:
    """How the F/T limit surfaces misjudge γ for one pressure, over every load direction.

    beta_m: β_s of the pressure (m). angles: (K,) direction in the plane (u, v) =
    (|f_t|/(μ f_n), τ/(β_s f_n)), rad; exact: (K,) boundary radius of the exact limit set
    in that plane (1 on the surfaces' own axes); linear, elliptic: γ by (5) and (6) over the
    exact γ, minus 1, worst over the directions of f_t (> 0: conservative, < 0: unsafe).
    """

    beta_m: float
    angles: np.ndarray
    exact: np.ndarray
    linear: np.ndarray
    elliptic: np.ndarray


def limit_error(phi: np.ndarray, positions: np.ndarray, mu: float, n: int = 121,
                f_t_directions: int = 4) -> LimitError:
    """The exact limit set of ``phi`` (N per taxel at ``positions``, m) against (5) and (6)
    with its own β_s, for loads (f_t, τ about the pad origin) in ``n`` directions of the
    (u, v) plane and ``f_t_directions`` directions of f_t in the pad plane."""
    f_n = float(np.sum(phi))
    beta = torsional_coefficient(phi, positions, mu).beta_m
    angles = np.linspace(-np.pi / 2, np.pi / 2, n)
    exact = np.full(n, np.inf)
    linear, elliptic = np.full(n, np.inf), np.full(n, np.inf)
    lin_hi, ell_hi = np.full(n, -np.inf), np.full(n, -np.inf)
    for psi in np.linspace(0, np.pi, f_t_directions, endpoint=False):
        for k, a in enumerate(angles):
            u, v = math.cos(a), math.sin(a)
            f_t = mu * f_n * u * np.array([math.cos(psi), math.sin(psi)])
            gamma = load_factor(phi, positions, f_t, beta * f_n * v, mu).gamma
            exact[k] = min(exact[k], 1 / gamma)
            for model, lo, hi in ((abs(u) + abs(v), linear, lin_hi), (1.0, elliptic, ell_hi)):
                ratio = model / gamma - 1
                lo[k], hi[k] = min(lo[k], ratio), max(hi[k], ratio)
    # keep the error of larger magnitude per direction, with its sign; below 0.05 % it is the solver's tolerance
    linear = np.where(np.abs(linear) >= np.abs(lin_hi), linear, lin_hi)
    elliptic = np.where(np.abs(elliptic) >= np.abs(ell_hi), elliptic, ell_hi)
    return LimitError(beta, angles, exact, np.where(np.abs(linear) < 5e-4, 0.0, linear),
                      np.where(np.abs(elliptic) < 5e-4, 0.0, elliptic))


def _pressures(pad: PadGeometry, f_n: float) -> dict[str, np.ndarray]:
    """Uniform over the pad, Hertzian (a = 8 mm) at its centre, Hertzian (a = 5 mm) at (4, 2) mm; N per taxel."""
    p = pad.positions

    def hertz(a_m: float, centre: tuple[float, float]) -> np.ndarray:
        shape = np.sqrt(np.clip(1 - np.sum((p - centre) ** 2, axis=1) / a_m ** 2, 0, None))
        return shape * f_n / shape.sum()

    return {"uniform": np.full(pad.n_taxels, f_n / pad.n_taxels), "Hertzian, a = 8 mm": hertz(8e-3, (0.0, 0.0)),
            "off-centre Hertzian, a = 5 mm at (4, 2) mm": hertz(5e-3, (4e-3, 2e-3))}


def limit_errors(out: Path) -> FigureText:
    """The exact limit set against (5) and (6) for three pressures, with the worst error of each."""
    mu, f_n = 0.5, 10.0
    pad = PadGeometry()
    half = pad.pitch_m * pad.cols / 2 * 1e3
    fig, axes = plt.subplots(1, 3, figsize=(12, 5.6))
    worst = []
    for ax, (name, phi) in zip(axes, _pressures(pad, f_n).items()):
        e = limit_error(phi, pad.positions, mu)
        a = np.linspace(-np.pi / 2, np.pi / 2, 200)
        ax.plot(e.exact * np.cos(e.angles), e.exact * np.sin(e.angles), "k", lw=2, label="exact (worst f_t direction)")
        diamond = np.abs(np.cos(a)) + np.abs(np.sin(a))  # |u| + |v| = 1 in the direction a
        ax.plot(np.cos(a) / diamond, np.sin(a) / diamond, color="C0", label="(5) linear")
        ax.plot(np.cos(a), np.sin(a), color="C1", label="(6) elliptic")
        inset = ax.inset_axes([0.02, 0.36, 0.28, 0.28])
        inset.imshow(phi.reshape(pad.rows, pad.cols), origin="lower", cmap="Greys", vmin=0,
                     extent=(-half, half, -half, half))
        inset.set_xticks([])
        inset.set_yticks([])
        lin_lo, lin_hi = float(e.linear.min()), float(e.linear.max())
        ell_lo, ell_hi = float(e.elliptic.min()), float(e.elliptic.max())
        worst.append((name, e.beta_m, lin_lo, lin_hi, ell_lo, ell_hi))
        ax.set(xlim=(0, 1.15), ylim=(-1.15, 1.15), aspect="equal", xlabel="|f_t| / (μ f_n)", ylabel="τ / (β_s f_n)",
               title=f"{name}\nβ_s = {e.beta_m * 1e3:.2f} mm; γ error (5): {lin_lo * 100:+.0f}…"
                     f"{lin_hi * 100:+.0f} %, "
                     f"(6): {ell_lo * 100:+.0f}…{ell_hi * 100:+.0f} %")
        ax.title.set_fontsize(9)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="lower left")
    png = save_png(fig, out, "limit_errors")
    numbers = "; ".join(f"{name} (β_s = {beta * 1e3:.2f} mm): (5) {lo5 * 100:+.1f} to {hi5 * 100:+.1f} %, "
                        f"(6) {lo6 * 100:+.1f} to {hi6 * 100:+.1f} %" for name, beta, lo5, hi5, lo6, hi6 in worst)
    return FigureText("limit_errors", "Beyond the paper — the exact limit set against (5) and (6)", png,
                      "The paper uses (5) and (6) as approximations of the limit surface, with β identified on one "
                      "contact, and does not say how far they are from the exact set.",
                      f"At f_n = {f_n:g} N, μ = {mu:g}, each pressure with its own β_s, τ about the pad origin (as "
                      f"the F/T sensor measures it), every load direction in the plane and four directions of f_t: "
                      f"γ of (5) and (6) over the exact γ, minus 1 (positive: the test says slip sooner than the "
                      f"contact does, conservative; negative: it says stick while the contact slides): {numbers}.",
                      _limit_differences(worst))


def _limit_differences(worst: list[tuple[str, float, float, float, float, float]]) -> str:
    """Where (5) and (6) go wrong, from the worst errors of each pressure (name, β_s, lo5, hi5, lo6, hi6)."""
    centred = [w for w in worst if not w[0].startswith("off-centre")]
    off = [w for w in worst if w[0].startswith("off-centre")]
    lo5 = min(w[2] for w in centred)
    lo6 = min(w[4] for w in centred)
    text = (f"On the centred pressures (5) is conservative (worst {lo5 * 100:+.1f} %): the exact set is convex and "
            f"holds the pure-force and pure-torque points, hence the straight line between them; (6) bulges beyond "
            f"the exact set on combined loads and says stick up to {-lo6 * 100:.1f} % too late.")
    if off:
        _, _, o5, _, o6, _ = off[0]
        text += (f" On the off-centre pressure the torque about the pad origin is not the torque about the contact: "
                 f"a pure force there twists the contact, so both surfaces misplace the set, (5) by up to "
                 f"{-o5 * 100:.0f} % and (6) by up to {-o6 * 100:.0f} % on the unsafe side. The tactile tests "
                 f"use the pressure itself and have none of this error.")
    return text
