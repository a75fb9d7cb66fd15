"""The paper's §V experiments as lock-step runs, and their topics as arrays.

More in docs/modules.md, `analysis/runs.py`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from slipstack.lib.defaults import MU
from slipstack.lib.limit_set import torsional_coefficient
from slipstack.lib.rig.contact import PressureModel
from slipstack.lib.rig.scene import Scene
from slipstack.lib.toml_file import SHIPPED_ROOT, read_toml, toml_value
from slipstack.analysis.figure_keys import parse_variant
from slipstack.launch.launch_file import load_launch_file
from slipstack.launch.lockstep import run_launch_file
from slipstack.messages import encode
from slipstack.nodes.rig import load_scene_by_name

__all__ = ["Experiment", "EXPERIMENTS", "experiment", "Run", "run_experiment", "payload_digest", "launch_args",
           "BETA_FIG11_M"]


def launch_args(launch: str) -> dict[str, Any]:
    """The declared arguments (name → value) of the shipped launch file ``launch``."""
    return load_launch_file(launch, builtins={"run_dir": "/nonexistent"}).args


BETA_FIG11_M: float = launch_args("fig11")["beta_m"]
"""β_s of the full-pad flat contact of fig11/fig12 (m), as the launch file ``fig11`` sets it."""


@dataclass(frozen=True)
class Experiment:
    """One paper experiment: a launch file and the arguments the paper ran it with.

    key: the figure id (``fig4a``, ``fig15_per_taxel`` …); launch: the shipped launch
    file; protocol: one line for the report; config: launch arguments overriding the
    file's (name → value, as ``name:=value``; the monitor is off);
    friction: where the law's μ and β come from (set by ``analysis/friction.py``);
    beta_from_contact: give the F/T test and the law the scene contact's exact β_s
    (:func:`contact_beta_s`), as ``tests/bench/bench_grip_economy.py`` does;
    seed, noise_scale: the scene run with another seed (its sensor noise and surface) and
    its sensors' noise scaled (the sensitivity of ``analysis/sensitivity.py``).
    """

    key: str
    launch: str
    protocol: str
    config: dict[str, Any] = field(default_factory=dict)
    friction: str = ""
    beta_from_contact: bool = False
    seed: int | None = None
    noise_scale: float = 1.0

    def arg(self, name: str) -> Any:
        """The launch argument ``name`` this experiment runs with (its own, else the file's)."""
        return self.config[name] if name in self.config else launch_args(self.launch)[name]

    @property
    def law_friction(self) -> tuple[float, float]:
        """(μ, β in m) the grip law runs with (a NaN μ is the material's: the paper's)."""
        mu, beta = self.arg("mu"), self.arg("beta_m")
        return (MU if mu != mu else mu), (beta or BETA_FIG11_M)


EXPERIMENTS: dict[str, Experiment] = {e.key: e for e in (
    Experiment("fig4a", "fig4a", "constant f_n = 5 N, tangential load rising through a spring; no controller",
               {"controller": False}),
    Experiment("fig4b", "fig4b", "constant f_n = 5 N, torque rising through a torsional spring; no controller",
               {"controller": False}),
    Experiment("fig10", "fig10", "F/T only: Coulomb test (7), linear law f_n = |f_t|/(σμ), σ = 0.5"),
    Experiment("fig10b", "fig10", "F/T only: Coulomb test (7), the strategy of the paper's ref. [9] (law cone_margin)",
               {"law": "cone_margin"}),
    Experiment("fig11", "fig11", "F/T only: pure torque, law (13) with k = 2 N"),
    Experiment("fig12", "fig12", "F/T only: force and torque, the σ-variant of law (13)"),
    Experiment("fig13", "fig13", "rotation about a known COR (the motor shaft) at constant f_n = 2 N; "
               "no controller: detection only, test (11) about the shaft"),
    Experiment("fig14", "fig14", "free object, unknown COR, at constant f_n = 3 N; no controller: detection only"),
    Experiment("cor_median", "fig14", "pure torque on a wedge-shaped pressure at constant f_n = 3 N; "
               "no controller: detection only", {"scene": "pure_torque_wedge"}),
    Experiment("fig15", "fig15", "both sensors: exact test, law (14) with the total increment N_A·δφ"),
    Experiment("fig15_per_taxel", "fig15", "both sensors: exact test, law (14) with the per-taxel δφ as printed",
               {"increment": "per_taxel"}),
    Experiment("fig15_ft13", "fig15", "F/T only: linear test (5), law (13) with k = 2 N and the contact's exact β_s",
               {"tactile": False, "method": "linear_ls", "law": "ft13", "mu": MU}, beta_from_contact=True),
    Experiment("fig15_exact_law", "fig15", "both sensors: exact test, law γ·f_n/σ (the stack's default law)",
               {"law": "exact"}),
    Experiment("fig15_open", "fig15", "fig15's disturbance at the constant initial f_n; no controller: detection only",
               {"controller": False}),
)}


def experiment(key: str) -> Experiment:
    """The experiment ``key``: one of :data:`EXPERIMENTS`, or a variant of one with another seed
    and sensor noise (:func:`slipstack.analysis.figure_keys.variant_key`)."""
    variant = parse_variant(key)
    if variant is None:
        return EXPERIMENTS[key]
    scene, seed, noise = variant
    base = EXPERIMENTS[scene]
    # every test is replayed on a variant: the live detector's cheapest test keeps the run cheap
    return dataclasses.replace(base, key=key, seed=seed, noise_scale=noise, config={**base.config, "method": "coulomb"})


@dataclass
class Run:
    """One experiment's output: ``topics[name][field]`` arrays, ``t`` in s from the start,
    one tactile contact's ``φ`` from mid-run (``None`` without a tactile pad), the
    digest of every message it published (equal digests: byte-identical runs), and the
    slip detector's parameters (the material's thresholds filled in)."""

    experiment: Experiment
    scene: Scene
    topics: dict[str, dict[str, np.ndarray]]
    phi_sample: np.ndarray | None = None  # one tactile contact's φ (N,), N, for β_s of the contact
    digest: str = ""  # :func:`payload_digest` of everything the run published
    detector: Any = None  # the slip detector's parameters as the run resolved them (SlipDetectorParams)
    contacts: list = field(default_factory=list)  # the ``contact`` messages as published, for replays
    replays: dict = field(default_factory=dict, repr=False)  # test → its replay (analysis/replay.py), computed once

    def __getitem__(self, topic: str) -> dict[str, np.ndarray]:
        return self.topics.get(topic, {})


_FIELDS = {
    "ft/wrench": lambda m: {"force": m.force, "torque": m.torque},
    "contact": lambda m: {"f_n": m.f_n, "f_t": m.f_t, "tau": m.tau, "cop": m.cop, "has_tactile": m.has_tactile,
                          "phi": m.phi if m.has_tactile else None},
    "cor": lambda m: {"case": m.case, "p_c": m.p_c, "capacity": m.torque_capacity, "load": m.load_torque,
                      "gamma": m.gamma},
    "slip": lambda m: {"state": m.state, "gamma": m.gamma, "margin": m.margin, "f_n": m.f_n, "f_t": m.f_t,
                       "tau": m.tau, "p_c": m.p_c, "p_c_valid": m.p_c_valid, "status": m.status},
    "grip/command": lambda m: {"f_n": m.f_n_desired, "reason": m.reason},
    "rig/truth": lambda m: {"x": m.x, "y": m.y, "theta": m.theta, "gross_slip": m.gross_slip, "cor": m.cor,
                            "cor_valid": m.cor_valid, "slip_distance_m": m.slip_distance_m,
                            "slip_angle_rad": m.slip_angle_rad, "f_n_applied": m.f_n_applied,
                            "f_n_command": m.f_n_command, "load_f_t": m.load_f_t, "load_tau": m.load_tau,
                            "sliding_fraction": m.sliding_fraction},
}


def _arrays(messages: list, extract: Callable[[Any], dict[str, Any]]) -> dict[str, np.ndarray]:
    if not messages:
        return {}
    rows = [extract(m) for m in messages]
    out = {k: np.array([r[k] for r in rows], dtype=object if any(r[k] is None for r in rows) else None)
           for k in rows[0]}
    out["t"] = np.array([m.header.stamp_ns for m in messages]) * 1e-9
    return out


def contact_beta_s(scene: Scene) -> float:
    """β_s (m) of the scene's contact at its initial grip and pose: μ_s times the
    pressure-weighted mean distance from the pure-torque COR (``lib/limit_set.py``)."""
    x, y, theta = scene.object.pose
    phi = PressureModel(scene.contact, scene.pad, scene.object.pose).phi(scene.finger.f_initial_N, complex(x, y),
                                                                          theta)
    return torsional_coefficient(phi, scene.pad.positions, scene.contact.mu_s).beta_m


def with_contact_beta(exp: Experiment, scene: Scene) -> Experiment:
    """``exp`` with the scene contact's β_s in its detector and law if it asks for it."""
    if not exp.beta_from_contact:
        return exp
    return dataclasses.replace(exp, config={**exp.config, "beta_m": contact_beta_s(scene)}, beta_from_contact=False)


def _toml_table(table: dict[str, Any], name: str = "") -> list[str]:
    """``table`` as TOML lines (scalars and lists first, then tables and arrays of tables)."""
    lines = [f"{key} = {toml_value(v)}" for key, v in table.items()
             if not isinstance(v, dict) and not (isinstance(v, list) and v and isinstance(v[0], dict))]
    for key, v in table.items():
        full = f"{name}.{key}" if name else key
        if isinstance(v, dict):
            lines += ["", f"[{full}]", *_toml_table(v, full)]
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                lines += ["", f"[[{full}]]", *_toml_table(item, full)]
    return lines


def scene_variant(scene: str, seed: int | None, noise_scale: float, folder: Path) -> Path:
    """A copy of the shipped ``scene`` with another ``seed`` and its F/T and tactile noise
    scaled by ``noise_scale``, written into ``folder``; returns its path."""
    data = read_toml(SHIPPED_ROOT / "scenes" / f"{scene}.toml", "scene")
    defaults = load_scene_by_name(scene)
    if seed is not None:
        data["seed"] = seed
    sensors = data.setdefault("sensors", {})
    ft, tactile = sensors.setdefault("ft", {}), sensors.setdefault("tactile", {})
    ft["noise_force_N"] = defaults.ft.noise_force_N * noise_scale
    ft["noise_torque_Nm"] = defaults.ft.noise_torque_Nm * noise_scale
    tactile["noise_counts"] = defaults.tactile.noise_counts * noise_scale
    path = folder / f"{scene}-seed{data.get('seed', 0)}-noise{noise_scale:g}.toml"
    path.write_text("\n".join(_toml_table(data)) + "\n")
    return path


def payload_digest(published: dict[str, list]) -> str:
    """SHA-256 (hex) over every topic's name and its messages' encoded payloads, in order."""
    return raw_digest((topic, encode(m)) for topic, messages in published.items() for m in messages)


def raw_digest(frames) -> str:
    """:func:`payload_digest` of the ``(topic, payload)`` frames as published (each topic's in order)."""
    by_topic: dict[str, list[bytes]] = {}
    for topic, payload in frames:
        by_topic.setdefault(topic, []).append(payload)
    h = hashlib.sha256()
    for topic in sorted(by_topic):
        h.update(topic.encode() + b"\0")
        for payload in by_topic[topic]:
            h.update(len(payload).to_bytes(8, "little") + payload)
    return h.hexdigest()


def run_experiment(exp: Experiment, *, duration_s: float | None = None,
                   progress: Callable[[float], None] | None = None, record: Path | None = None) -> Run:
    """Run ``exp`` in lock-step (``duration_s`` shortens the scene; None: the scene's own);
    ``record``: the launch file's recorder writes the run there (its default topics)."""
    exp = with_contact_beta(exp, load_scene_by_name(str(exp.arg("scene"))))
    args = {"monitor": "false", "record": "false",
            **{k: str(v).lower() if isinstance(v, bool) else str(v) for k, v in exp.config.items()}}
    if record is not None:
        args.update(record="true", recording=str(record))
    if duration_s is not None:
        args["duration_s"] = str(duration_s)
    with tempfile.TemporaryDirectory(prefix="slipstack-scene-") as folder:
        if exp.seed is not None or exp.noise_scale != 1.0:
            args["scene"] = str(scene_variant(str(exp.arg("scene")), exp.seed, exp.noise_scale, Path(folder)))
        ex = run_launch_file(exp.launch, args, progress=progress)
    scene: Scene = ex.host("rig").node.scene
    if duration_s is not None:
        scene = dataclasses.replace(scene, duration_s=min(duration_s, scene.duration_s))
    topics = {topic: _arrays(ex.published.get(topic, []), extract) for topic, extract in _FIELDS.items()}
    tactile = [c for c in ex.published.get("contact", []) if c.has_tactile and c.phi.size]
    detector = ex.host("slip_detector").node.params
    return Run(exp, scene, topics, tactile[len(tactile) // 2].phi if tactile else None,
               raw_digest((topic, payload) for _, topic, payload in ex.raw), detector,
               list(ex.published.get("contact", [])))
