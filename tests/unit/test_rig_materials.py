"""The rig's contact materials: picked by a scene key or applied to any scene."""

from __future__ import annotations

import pytest

from slipstack.lib.errors import ConfigError
from slipstack.lib.rig.scene import RIG_MATERIALS, parse_scene, with_rig_material
from slipstack.nodes.rig import load_scene_by_name

BASE = {"object": {}, "dof": {"free": ["x"]}, "disturbance": {}}


def test_scene_key_picks_the_material_and_explicit_mu_wins() -> None:
    sc = parse_scene({**BASE, "contact": {"model": "flat", "material": "weakening"}})
    assert (sc.contact.mu_s, sc.contact.mu_d) == RIG_MATERIALS["weakening"] == (0.5, 0.3)
    sc = parse_scene({**BASE, "contact": {"model": "flat", "material": "coulomb", "mu_s": 0.6}})
    assert (sc.contact.mu_s, sc.contact.mu_d) == (0.6, 0.45)
    assert parse_scene({**BASE, "contact": {"model": "flat"}}).contact.mu_d == 0.36  # rubber by default
    with pytest.raises(ConfigError, match="contact.material: must be one of rubber, coulomb, weakening"):
        parse_scene({**BASE, "contact": {"model": "flat", "material": "steel"}}, source="s.toml")


def test_with_rig_material_changes_only_the_friction() -> None:
    sc = load_scene_by_name("fig15")
    coulomb = with_rig_material(sc, "coulomb")
    assert coulomb.contact.mu_d == coulomb.contact.mu_s == 0.45 and coulomb.name == "fig15@coulomb"
    assert coulomb.disturbance == sc.disturbance and coulomb.contact.model == sc.contact.model
    with pytest.raises(ConfigError, match="unknown rig material"):
        with_rig_material(sc, "steel")


@pytest.mark.parametrize("material", sorted(RIG_MATERIALS))
def test_negative_scenes_exist_for_every_material(material: str) -> None:
    for kind in ("hold_force", "hold_torsion"):
        sc = load_scene_by_name(f"{kind}_{material}")
        assert (sc.contact.mu_s, sc.contact.mu_d) == RIG_MATERIALS[material]
        assert sc.expect.slips_at_initial is False
