"""The friction Figs. 10–12 run with: identified on Figs. 4a/4b, as a user would.

The paper identifies μ and β from its Fig. 4 ramps and uses them in its control
experiments. :func:`identify_friction` does the same with slipstack's own tools: the
Fig. 4a and 4b runs are written as recordings and passed to ``slipstack identify``
(:func:`~slipstack.analysis.identify_cli.identify_material`), which writes a material
file. :func:`with_friction` points an experiment's detector and grip law at that
file, with μ = μ_s and β = β_s identified. A quantity the ramps do not resolve (e.g.
β in a ``--quick`` run, cut before the torsional slip) falls back to the value the
experiment was declared with, and :class:`Friction` says so.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

from slipstack.analysis.runs import BETA_FIG11_M, Experiment
from slipstack.lib.defaults import MU
from slipstack.lib.material import material_toml
from slipstack.nodes.recording.bag_io import RecordingError
from slipstack.analysis.identify_cli import identify_material

__all__ = ["Friction", "identify_friction", "with_friction"]

MATERIAL_FILE = "material-identified.toml"


@dataclass(frozen=True)
class Friction:
    """μ_s and β_s (m) the control experiments use, and where each comes from.

    material: the material file ``slipstack identify`` wrote, or ``None`` if it failed;
    mu_identified, beta_identified: whether each value is the identified one (else the
    declared fallback); log: the identification's report lines.
    """

    mu_s: float
    beta_s_m: float
    material: Path | None
    mu_identified: bool
    beta_identified: bool
    log: tuple[str, ...] = ()

    def describe(self) -> str:
        """One sentence for the report: the values used and their origin."""
        mu = "identified on Fig. 4a" if self.mu_identified else "not identified: the scene's"
        beta = "identified on Fig. 4b" if self.beta_identified else "not identified: fig11's contact β_s"
        return f"μ_s = {self.mu_s:.3f} ({mu}), β_s = {self.beta_s_m * 1e3:.2f} mm ({beta})"


def identify_friction(recordings: list[Path], out_dir: Path) -> Friction:
    """Run ``slipstack identify`` on the Fig. 4 ``recordings``; write the material file
    into ``out_dir``. Never raises on a failed identification: it falls back (see module)."""
    try:
        material, lines = identify_material(recordings, name="identified",
                                            provenance="slipstack reproduce: fig4a and fig4b, lock-step")
    except RecordingError as e:
        return Friction(MU, BETA_FIG11_M, None, False, False, (f"identification failed: {e}",))
    path = out_dir / MATERIAL_FILE
    path.write_text(material_toml(material, "Identified by slipstack reproduce on its Fig. 4a/4b runs."))
    mu_ok, beta_ok = math.isfinite(material.mu_s), math.isfinite(material.beta_s_m)
    return Friction(material.mu_s if mu_ok else MU, material.beta_s_m if beta_ok else BETA_FIG11_M, path,
                    mu_ok, beta_ok, tuple(lines))


def with_friction(exp: Experiment, friction: Friction) -> Experiment:
    """``exp`` with its detector and grip law given ``friction`` (material file, μ, β)."""
    config = {**exp.config, "mu": friction.mu_s}
    if friction.material:
        config["material"] = str(friction.material)
    if exp.arg("beta_m"):  # an F/T test and law with a declared β (the Coulomb test of fig10 takes none)
        config["beta_m"] = friction.beta_s_m
    return dataclasses.replace(exp, config=config, friction=friction.describe())
