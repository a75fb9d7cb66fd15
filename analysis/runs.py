"""The paper's §V experiments as lock-step runs, and their topics as arrays.

Each :class:`Experiment` is a shipped paper launch file (``launch/files/<key>.toml``,
the graph ``slipstack launch <key>`` starts) and the arguments the paper's run differs
in: detection-only experiments (Figs. 4, 13, 14) run with the controller off, at the
scene's constant normal force; control experiments (Figs. 10–12, 15) with the launch
file's law. :func:`run_experiment` runs it like ``slipstack launch <key> --lockstep``
(``launch/lockstep.py``: the same nodes, device codecs and parameters, deterministic)
and returns a :class:`Run`: each topic as numpy arrays, time in seconds from the start
of the run (the scene starts once the drivers' devices stream, a few ms in).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from slipstack.lib.rig.scene import Scene
from slipstack.launch.launch_file import load_launch_file
from slipstack.launch.lockstep import run_launch_file

__all__ = ["Experiment", "EXPERIMENTS", "Run", "run_experiment", "BETA_FIG11_M"]

BETA_FIG11_M: float = load_launch_file("fig11", builtins={"run_dir": "/nonexistent"}).args["beta_m"]
"""β_s of the full-pad flat contact of fig11/fig12 (m), as the launch file ``fig11`` sets it."""


@dataclass(frozen=True)
class Experiment:
    """One paper experiment: a launch file and the arguments the paper ran it with.

    key: the figure id and its launch file (``fig4a`` …); scene: the shipped scene it
    runs; protocol: one line for the report; config: launch arguments overriding the
    file's (name → value, as ``name:=value``; recording and monitor are off).
    """

    key: str
    scene: str
    protocol: str
    config: dict[str, Any] = field(default_factory=dict)


EXPERIMENTS: dict[str, Experiment] = {e.key: e for e in (
    Experiment("fig4a", "fig4a", "constant f_n = 5 N, tangential load rising through a spring; no controller"),
    Experiment("fig4b", "fig4b", "constant f_n = 5 N, torque rising through a torsional spring; no controller"),
    Experiment("fig10", "fig10", "F/T only: Coulomb test (7), linear law f_n = |f_t|/(σμ), σ = 0.5"),
    Experiment("fig11", "fig11", "F/T only: pure torque, law (13) with k = 2 N and β = 3.44 mm"),
    Experiment("fig12", "fig12", "F/T only: force and torque, the σ-variant of law (13)"),
    Experiment("fig13", "fig13", "rotation about a known COR (the motor shaft) at constant f_n = 2 N; "
               "no controller: detection only", {"controller": False}),
    Experiment("fig14", "fig14", "free object, unknown COR, at constant f_n = 3 N; no controller: detection only",
               {"controller": False}),
    Experiment("fig15", "fig15", "both sensors: exact test, law (14) with the total increment N_A·δφ"),
)}


@dataclass
class Run:
    """One experiment's output: ``topics[name][field]`` arrays, ``t`` in s from the start,
    and one tactile contact's ``φ`` from mid-run (``None`` without a tactile pad)."""

    experiment: Experiment
    scene: Scene
    topics: dict[str, dict[str, np.ndarray]]
    phi_sample: np.ndarray | None = None  # one tactile contact's φ (N,), N, for β_s of the contact

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


def run_experiment(exp: Experiment, *, duration_s: float | None = None,
                   progress: Callable[[float], None] | None = None) -> Run:
    """Run ``exp`` in lock-step (``duration_s`` shortens the scene; None: the scene's own)."""
    args = {"record": "false", "monitor": "false",
            **{k: str(v).lower() if isinstance(v, bool) else str(v) for k, v in exp.config.items()}}
    if duration_s is not None:
        args["duration_s"] = str(duration_s)
    ex = run_launch_file(exp.key, args, progress=progress)
    scene: Scene = ex.host("rig").node.scene
    if duration_s is not None:
        scene = dataclasses.replace(scene, duration_s=min(duration_s, scene.duration_s))
    topics = {topic: _arrays(ex.published.get(topic, []), extract) for topic, extract in _FIELDS.items()}
    tactile = [c for c in ex.published.get("contact", []) if c.has_tactile and c.phi.size]
    return Run(exp, scene, topics, tactile[len(tactile) // 2].phi if tactile else None)
