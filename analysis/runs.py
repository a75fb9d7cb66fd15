"""The paper's §V experiments as lock-step runs, and their topics as arrays.

Each :class:`Experiment` names a shipped scene and the stack the paper used on it —
detection-only experiments (Figs. 4, 13, 14) run with the controller off, at the
scene's constant normal force; control experiments (Figs. 10–12, 15) with the paper's
law. :func:`run_experiment` runs it through :class:`~slipstack.launch.lockstep.LockstepStack`
(the same nodes and device codecs the launched stack runs, deterministic) and returns
a :class:`Run`: each topic as numpy arrays, time in seconds from the scene start.
"""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from slipstack.lib.limit_set import torsional_coefficient
from slipstack.lib.rig.contact import PressureModel
from slipstack.lib.rig.scene import Scene
from slipstack.launch.lockstep import LockstepStack, StackConfig, load_scene_by_name
from slipstack.messages import encode
from slipstack.nodes.recording.bag_io import RecordingWriter

__all__ = ["Experiment", "EXPERIMENTS", "Run", "run_experiment", "payload_digest", "write_recording"]

BETA_FIG11_M = 0.00344  # β_s of the full-pad flat contact of fig11/fig12 (launch files fig11, fig12)
MU_PAPER = 0.45  # the paper's identified μ_s, and every paper scene's
RECORDED_TOPICS = ("ft/wrench", "tactile/frame", "cor", "slip", "grip/command", "rig/truth")
"""What a run's recording keeps: the stack's default recording (``launch/files/stack.toml``)."""


@dataclass(frozen=True)
class Experiment:
    """One paper experiment: a scene and the stack the paper ran on it.

    key: the figure id (``fig4a`` …); scene: a shipped scene name; protocol: one line
    for the report; config: the stack (:class:`StackConfig` keyword arguments);
    friction: where the law's μ and β come from (set by ``analysis/friction.py``);
    beta_from_contact: give the F/T test and the law the scene contact's exact β_s
    (:func:`contact_beta_s`), as ``tests/bench/bench_grip_economy.py`` does.
    """

    key: str
    scene: str
    protocol: str
    config: dict[str, Any] = field(default_factory=dict)
    friction: str = ""
    beta_from_contact: bool = False  # β of the F/T test and law: the scene contact's exact β_s

    @property
    def law_friction(self) -> tuple[float, float]:
        """(μ, β in m) the grip law runs with."""
        grip = self.config.get("grip", {})
        return grip.get("mu", MU_PAPER), grip.get("beta_m", BETA_FIG11_M)


EXPERIMENTS: dict[str, Experiment] = {e.key: e for e in (
    Experiment("fig4a", "fig4a", "constant f_n = 5 N, tangential load rising through a spring; no controller",
               {"controller": False}),
    Experiment("fig4b", "fig4b", "constant f_n = 5 N, torque rising through a torsional spring; no controller",
               {"controller": False}),
    Experiment("fig10", "fig10", "F/T only: Coulomb test (7), linear law f_n = |f_t|/(σμ), σ = 0.5",
               {"controller": True, "slip": {"method": "coulomb"}, "grip": {"law": "linear", "f_max_n": 20.0}}),
    Experiment("fig11", "fig11", "F/T only: pure torque, law (13) with k = 2 N",
               {"controller": True, "slip": {"method": "linear_ls", "beta_m": BETA_FIG11_M},
                "grip": {"law": "ft13", "beta_m": BETA_FIG11_M, "f_max_n": 20.0}}),
    Experiment("fig12", "fig12", "F/T only: force and torque, the σ-variant of law (13)",
               {"controller": True, "slip": {"method": "linear_ls", "beta_m": BETA_FIG11_M},
                "grip": {"law": "ft13_sigma", "beta_m": BETA_FIG11_M, "f_max_n": 20.0}}),
    Experiment("fig13", "fig13", "rotation about a known COR (the motor shaft) at constant f_n = 2 N; "
               "no controller: detection only, test (11) about the shaft",
               {"controller": False, "slip": {"method": "tactile_cor_known", "known_cor_x_m": 0.004,
                                              "known_cor_y_m": 0.002}}),  # launch/scenes/fig13.toml pivot_m
    Experiment("fig14", "fig14", "free object, unknown COR, at constant f_n = 3 N; no controller: detection only",
               {"controller": False, "slip": {"method": "exact"}}),
    Experiment("cor_median", "pure_torque_wedge", "pure torque on a wedge-shaped pressure at constant f_n = 3 N; "
               "no controller: detection only", {"controller": False, "slip": {"method": "exact"}}),
    Experiment("fig15", "fig15", "both sensors: exact test, law (14) with the total increment N_A·δφ",
               {"controller": True, "slip": {"method": "exact"}, "grip": {"law": "tactile14", "f_max_n": 20.0}}),
    Experiment("fig15_per_taxel", "fig15", "both sensors: exact test, law (14) with the per-taxel δφ as printed",
               {"controller": True, "slip": {"method": "exact"},
                "grip": {"law": "tactile14", "increment": "per_taxel", "f_max_n": 20.0}}),
    Experiment("fig15_ft13", "fig15", "F/T only: linear test (5), law (13) with k = 2 N and the contact's exact β_s",
               {"controller": True, "tactile": False, "slip": {"method": "linear_ls", "mu": MU_PAPER},
                "grip": {"law": "ft13", "mu": MU_PAPER, "f_max_n": 20.0}}, beta_from_contact=True),
)}


@dataclass
class Run:
    """One experiment's output: ``topics[name][field]`` arrays, ``t`` in s from the start,
    one tactile contact's ``φ`` from mid-run (``None`` without a tactile pad), and the
    digest of every message it published (equal digests: byte-identical runs)."""

    experiment: Experiment
    scene: Scene
    topics: dict[str, dict[str, np.ndarray]]
    phi_sample: np.ndarray | None = None  # one tactile contact's φ (N,), N, for β_s of the contact
    digest: str = ""  # :func:`payload_digest` of everything the run published

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
    beta = contact_beta_s(scene)
    config = {**exp.config, "slip": {**exp.config.get("slip", {}), "beta_m": beta},
              "grip": {**exp.config.get("grip", {}), "beta_m": beta}}
    return dataclasses.replace(exp, config=config, beta_from_contact=False)


def payload_digest(published: dict[str, list]) -> str:
    """SHA-256 (hex) over every topic's name and its messages' encoded payloads, in order."""
    h = hashlib.sha256()
    for topic in sorted(published):
        h.update(topic.encode() + b"\0")
        for m in published[topic]:
            payload = encode(m)
            h.update(len(payload).to_bytes(8, "little") + payload)
    return h.hexdigest()


def write_recording(published: dict[str, list], path: Path) -> None:
    """Write the :data:`RECORDED_TOPICS` of a lock-step run as an MCAP recording at ``path``."""
    writer = RecordingWriter(path)
    try:
        for topic in RECORDED_TOPICS:
            for m in published.get(topic, []):
                writer.write(topic, encode(m), m.header.stamp_ns)
    finally:
        writer.close()


def run_experiment(exp: Experiment, *, duration_s: float | None = None,
                   progress: Callable[[float], None] | None = None, record: Path | None = None) -> Run:
    """Run ``exp`` in lock-step (``duration_s`` shortens the scene; None: the scene's own);
    ``record``: also write the run there as a recording (:func:`write_recording`)."""
    scene = load_scene_by_name(exp.scene)
    if duration_s is not None:
        scene = dataclasses.replace(scene, duration_s=min(duration_s, scene.duration_s))
    exp = with_contact_beta(exp, scene)
    stack = LockstepStack(scene, StackConfig(**exp.config))
    try:
        ex = stack.run(progress)
    finally:
        stack.close()
    if record is not None:
        write_recording(ex.published, record)
    topics = {topic: _arrays(ex.published.get(topic, []), extract) for topic, extract in _FIELDS.items()}
    tactile = [c for c in ex.published.get("contact", []) if c.has_tactile and c.phi.size]
    return Run(exp, scene, topics, tactile[len(tactile) // 2].phi if tactile else None,
               payload_digest(ex.published))
