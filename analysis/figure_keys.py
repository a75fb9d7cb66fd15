"""The names of the figures ``slipstack reproduce`` draws and the runs each is drawn from.

Plain data, no drawing imports: ``slipstack reproduce --help`` lists these keys without
loading matplotlib. :mod:`slipstack.analysis.catalogue` maps each key to its drawing
function. The sensitivity runs are the detection-only scenes again with other seeds and
sensor noise: ``fig14@seed1@noise4`` is fig14 with seed 1 and four times its noise.
"""

from __future__ import annotations

__all__ = ["FIGURE_KEYS", "figure_runs", "variant_key", "parse_variant", "SENSITIVITY_SCENES"]

FIGURE_KEYS = ("measured", "fig4a", "fig4b", "fig5a", "fig5b", "fig10", "fig11", "fig12", "fig13", "fig14",
               "cor_median", "fig15", "increment", "sensitivity", "pareto", "grip_economy", "limit_errors")
"""Every figure, in the report's order: what the paper's method does on measured data, the
paper's figures, then those beyond the paper."""

SENSITIVITY_SCENES = ("fig4a", "fig4b", "fig14", "fig15_open")
"""The detection-only runs (controller off) the sensitivity and the Pareto plot replay: the
identification ramps (stick–slip: many episodes) and the free objects."""
_OWN_RUN_ONLY = ("fig14",)
"""Scenes the sensitivity takes only as run for their figure: fig14 has one episode a run."""
_SEEDS, _NOISE = (1, 2), (0.5, 2.0, 4.0)
"""Seeds beside the scenes' own, at their sensor noise; noise scales beside it, with the first
of these seeds (the same noise drawn, scaled)."""
_QUICK_SEEDS, _QUICK_NOISE = (1,), (2.0,)

_RUNS = {"measured": ("fig4a", "fig4b", "fig13", "fig14", "fig15_open"), "fig5a": (), "fig5b": (),
         "fig10": ("fig10", "fig10b"), "limit_errors": (), "increment": ("fig15", "fig15_per_taxel", "fig15_ft13"),
         "grip_economy": ("fig15", "fig15_per_taxel", "fig15_ft13", "fig15_exact_law")}


def variant_key(scene: str, seed: int, noise: float) -> str:
    """The run of ``scene`` with ``seed`` and its sensor noise times ``noise``."""
    return f"{scene}@seed{seed}@noise{noise:g}"


def parse_variant(key: str) -> tuple[str, int, float] | None:
    """(scene, seed, noise scale) of a :func:`variant_key`, or None for a plain experiment."""
    if "@" not in key:
        return None
    scene, seed, noise = key.split("@")
    return scene, int(seed.removeprefix("seed")), float(noise.removeprefix("noise"))


def _variants(quick: bool) -> tuple[str, ...]:
    """Each scene as run for its figure, then with each seed, then with the first seed at each noise."""
    seeds, noises = (_QUICK_SEEDS, _QUICK_NOISE) if quick else (_SEEDS, _NOISE)
    keys: list[str] = []
    for scene in SENSITIVITY_SCENES:
        keys.append(scene)
        if scene not in _OWN_RUN_ONLY:
            keys += [variant_key(scene, s, 1.0) for s in seeds] + [variant_key(scene, seeds[0], n) for n in noises]
    return tuple(keys)


def figure_runs(key: str, quick: bool = False) -> tuple[str, ...]:
    """The experiments (``analysis/runs.py`` keys, or variant keys) a figure is drawn from, in
    argument order (a figure without an entry is drawn from the experiment of its own name)."""
    if key in ("sensitivity", "pareto"):
        return _variants(quick)
    return _RUNS.get(key, (key,))
