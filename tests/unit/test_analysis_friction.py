"""The friction Figs. 10-12 run with (analysis/friction.py): identified, or a declared fallback."""

from __future__ import annotations

import pytest

from slipstack.analysis.friction import Friction, identify_friction, with_friction
from slipstack.analysis.runs import BETA_FIG11_M, EXPERIMENTS
from slipstack.lib.defaults import MU
from slipstack.nodes.recording.bag_io import RecordingWriter


def test_the_identified_friction_reaches_the_detector_and_the_law(tmp_path):
    friction = Friction(0.41, 0.0013, tmp_path / "m.toml", True, True)
    fig11 = with_friction(EXPERIMENTS["fig11"], friction)
    assert fig11.config["beta_m"] == 0.0013 and fig11.config["mu"] == 0.41  # launch arguments: detector and law
    assert fig11.config["material"] == str(tmp_path / "m.toml")
    assert fig11.law_friction == (0.41, 0.0013)
    assert "identified on Fig. 4b" in fig11.friction
    # the Coulomb test of fig10 takes no β; the law's μ is the identified one
    fig10 = with_friction(EXPERIMENTS["fig10"], friction)
    assert "beta_m" not in fig10.config and fig10.config["mu"] == 0.41
    assert EXPERIMENTS["fig11"].arg("beta_m") == BETA_FIG11_M  # the declared one is untouched


def test_a_failed_identification_falls_back_to_the_declared_values_and_says_so(tmp_path):
    empty = tmp_path / "empty.mcap"
    RecordingWriter(empty).close()
    friction = identify_friction([empty], tmp_path)
    assert (friction.mu_s, friction.beta_s_m, friction.material) == (MU, BETA_FIG11_M, None)
    assert "not identified" in friction.describe() and friction.log[0].startswith("identification failed")
    assert not (tmp_path / "material-identified.toml").exists()


@pytest.mark.parametrize("key", ["fig10", "fig11", "fig12"])
def test_without_identification_the_law_runs_with_the_paper_values(key):
    assert EXPERIMENTS[key].law_friction == (MU, BETA_FIG11_M)
