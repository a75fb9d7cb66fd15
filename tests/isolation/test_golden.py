"""Every processing node against recorded inputs and recorded expected outputs.

More in docs/modules.md, `tests/isolation/test_golden.py`.
"""

from __future__ import annotations

import functools
import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
from golden_config import GOLDENS, NODES, Golden, build_node
from make_golden import compare_recordings, write_golden

from slipstack.lib.pad import PadGeometry
from slipstack.messages import Message, decode
from slipstack.nodes.recording.bag_io import RecordingWriter, match_outputs, read_recording, replay_into

CASES = [(g, n) for g in GOLDENS for n in NODES if g.tactile or n != "cor_estimator"]


@pytest.mark.parametrize(("golden", "node_name"), CASES, ids=[f"{g.name}-{n}" for g, n in CASES])
def test_node_reproduces_recorded_outputs(golden: Golden, node_name: str) -> None:
    node = build_node(golden, node_name)
    replayed = replay_into(node, golden.path)
    for output in node.outputs.values():
        frames = list(read_recording(golden.path, [output.topic]))
        recorded = [decode(f.payload) for f in frames]
        mine = replayed.get(output.topic, [])
        result = match_outputs(recorded, mine)
        assert result.mismatches == [], result.mismatches[:5]
        assert result.matched == len(recorded) == len(mine) > 50, result
        assert [(m.header.seq, m.header.pub_ns) for m in mine] == [(m.header.seq, m.header.pub_ns) for m in recorded]


def test_goldens_cover_slip_onset_and_the_grip_reaction() -> None:
    """The recordings exercise what state a node keeps: a slip onset, the latch, a grip rise."""
    for g in GOLDENS:
        slips = [decode(f.payload) for f in read_recording(g.path, ["slip"])]
        grips = [decode(f.payload).f_n_desired for f in read_recording(g.path, ["grip/command"])]
        states = [m.state for m in slips]
        onset = next(k for k, s in enumerate(states) if s in ("translation", "rotation", "combined"))
        assert states[onset - 1] == "stick", g.name
        assert max(grips[onset:]) > grips[onset - 1] + 1.0, g.name  # the law raised the grip by > 1 N
    tactile = next(g for g in GOLDENS if g.tactile)
    cases = {decode(f.payload).case for f in read_recording(tactile.path, ["cor"])}
    assert {"rotation", "none"} <= cases or {"on-taxel", "none"} <= cases, cases


def test_golden_files_are_fresh(tmp_path: Path) -> None:
    for g in GOLDENS:
        write_golden(g, tmp_path / g.path.name)
        diffs = compare_recordings(g.path, tmp_path / g.path.name)
        assert diffs == [], f"{g.path} is stale (run tests/isolation/make_golden.py): {diffs[:3]}"


# --- invariants that do not come from the code ----------------------------------------

SAMPLED_FRAMES = 20
"""Frames per recording checked against the brute-force maximiser (~0.1 s each)."""


def _load_brute_force():
    path = Path(__file__).resolve().parents[1] / "unit" / "test_limit_set.py"
    spec = importlib.util.spec_from_file_location("_limit_set_brute_force", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.brute_force_gamma


brute_force_gamma = _load_brute_force()


def _recorded(golden: Golden) -> dict[str, list[Message]]:
    """topic → decoded messages of the recording, in recorded order."""
    return _recorded_file(golden.path)


@functools.cache
def _recorded_file(path: Path) -> dict[str, list[Message]]:
    topics: dict[str, list[Message]] = {}
    for frame in read_recording(path):
        topics.setdefault(frame.topic, []).append(decode(frame.payload))
    return topics


def _by_stamp(messages: list[Message]) -> dict[int, Message]:
    return {m.header.stamp_ns: m for m in messages}


def _sample(items: list, n: int = SAMPLED_FRAMES) -> list:
    """``n`` items spread evenly over ``items`` (first and last included)."""
    if len(items) <= n:
        return list(items)
    return [items[round(k * (len(items) - 1) / (n - 1))] for k in range(n)]


def _positions(contact) -> np.ndarray:
    return PadGeometry(contact.rows, contact.cols, contact.pitch_m).positions


@pytest.mark.parametrize("golden", GOLDENS, ids=[g.name for g in GOLDENS])
def test_recorded_contacts_carry_the_measured_wrench(golden: Golden) -> None:
    """Fusion: Σφ = f_n = −F_z of the paired wrench, f_t and τ passed on, φ ≥ 0 and only
    in the mask, the centre of pressure Σφp/f_n."""
    topics = _recorded(golden)
    wrenches = _by_stamp(topics["ft/wrench"])
    # the driver's status frames while its device handshake runs carry no pressure
    first_tactile_ns = min((m.header.stamp_ns for m in topics.get("tactile/frame", []) if m.status == "ok"),
                           default=math.inf)
    checked = 0
    for c in topics["contact"]:
        w = wrenches[c.header.sources["ft"]]
        assert w.frame == "pad", w.frame  # the driver moved the wrench to the pad frame
        assert c.f_n == pytest.approx(-w.force[2], rel=1e-12)
        assert tuple(c.f_t) == pytest.approx(tuple(w.force[:2]), rel=1e-12, abs=1e-15)
        assert c.tau == pytest.approx(w.torque[2], rel=1e-12, abs=1e-15)
        if not c.has_tactile:  # F/T only, or no tactile frame yet
            assert c.header.stamp_ns <= first_tactile_ns and c.phi.size == 0
            continue
        assert c.has_tactile and c.status == "ok"
        assert (c.phi >= 0).all() and (c.phi[~c.mask] == 0).all()
        assert c.phi.sum() == pytest.approx(c.f_n, rel=1e-12)
        assert tuple(c.cop) == pytest.approx(tuple(c.phi @ _positions(c) / c.phi.sum()), abs=1e-12)
        checked += 1
    assert checked > (0.9 * len(topics["contact"]) if golden.tactile else -1), checked


def _linear_limit_surface_gamma(f_t, tau: float, f_n: float, mu: float, beta_m: float) -> float:
    """The paper's linear limit surface (5): ``|f_t|/(μ f_n) + |τ|/(β f_n)``."""
    return math.hypot(*f_t) / (mu * f_n) + abs(tau) / (beta_m * f_n)


@pytest.mark.parametrize("golden", GOLDENS, ids=[g.name for g in GOLDENS])
def test_recorded_gamma_agrees_with_an_independent_computation(golden: Golden) -> None:
    """Slip detector: γ on 20 frames against brute force (exact test) or the paper's (5)."""
    topics = _recorded(golden)
    contacts = _by_stamp(topics["contact"])
    exact = golden.slip["method"] == "exact"
    loaded = [s for s in topics["slip"] if s.f_n > 0 and (s.tau != 0 or s.f_t.any())
              and (contacts[s.header.stamp_ns].has_tactile or not exact)]
    assert len(loaded) > 0.9 * len(topics["slip"])
    for s in _sample(loaded):
        c = contacts[s.header.stamp_ns]
        assert (s.f_n, tuple(s.f_t), s.tau) == (c.f_n, tuple(c.f_t), c.tau)  # judged the contact it names
        if exact:
            expected = brute_force_gamma(c.phi, _positions(c), s.f_t, s.tau, golden.slip["mu"])
            assert s.gamma == pytest.approx(expected, rel=1e-6), s.header
        else:
            assert golden.slip["method"] == "linear_ls"
            expected = _linear_limit_surface_gamma(s.f_t, s.tau, s.f_n, golden.slip["mu"], golden.slip["beta_m"])
            assert s.gamma == pytest.approx(expected, rel=1e-12), s.header
        assert s.margin == pytest.approx(1.0 - expected, abs=1e-6)


def test_recorded_cor_attains_the_brute_force_load_factor() -> None:
    """COR estimator: at the published COR, ``|τ + f_t × p_c| / (μ Σ φ_i |p_i − p_c|)``
    (computed here from the contact) is the brute-force maximum, and the published
    capacity and load torque are those sums."""
    golden = next(g for g in GOLDENS if g.tactile)
    topics = _recorded(golden)
    contacts = _by_stamp(topics["contact"])
    rotating = [r for r in topics["cor"] if r.case in ("rotation", "on-taxel")]
    assert len(rotating) >= 10, len(rotating)
    mu = golden.cor["mu"]
    for r in _sample(rotating):
        c = contacts[r.header.stamp_ns]
        P = _positions(c)
        capacity = mu * float(c.phi @ np.hypot(*(P - r.p_c).T))
        load_torque = c.tau + c.f_t[0] * r.p_c[1] - c.f_t[1] * r.p_c[0]
        assert r.torque_capacity == pytest.approx(capacity, rel=1e-9)
        assert r.load_torque == pytest.approx(load_torque, rel=1e-9, abs=1e-15)
        expected = brute_force_gamma(c.phi, P, c.f_t, c.tau, mu)
        assert abs(load_torque) / capacity == pytest.approx(expected, rel=1e-6), r.header
        assert r.gamma == pytest.approx(expected, rel=1e-6)


def _check_grip_commands(golden: Golden, commands: list[Message], node) -> None:
    """f_nom ≤ f ≤ f_max; |Δf| ≤ slew limit × Δt (publication times); no fall without a new slip verdict."""
    p = node.params
    assert (p.f_nom_n, p.f_max_n) == (golden.grip["f_nom_n"], golden.grip["f_max_n"])
    f = np.array([m.f_n_desired for m in commands])
    assert (f >= p.f_nom_n).all() and (f <= p.f_max_n).all(), (f.min(), f.max())
    dt_s = np.diff([m.header.pub_ns for m in commands]) * 1e-9
    assert (dt_s > 0).all()
    assert (np.abs(np.diff(f)) <= p.max_rate_n_per_s * dt_s * (1 + 1e-9)).all()
    verdict = [m.header.sources.get("slip") for m in commands]
    for k in range(1, len(commands)):
        if verdict[k] == verdict[k - 1]:  # a watchdog step: nothing new came in
            assert f[k] >= f[k - 1], (commands[k].header, f[k - 1], f[k], commands[k].reason)


@pytest.mark.parametrize("golden", GOLDENS, ids=[g.name for g in GOLDENS])
def test_recorded_grip_commands_respect_bounds_and_slew_limit(golden: Golden) -> None:
    commands = _recorded(golden)["grip/command"]
    assert len(commands) > 50
    _check_grip_commands(golden, commands, build_node(golden, "grip_controller"))


GAP_NS = (150_000_000, 200_000_000)
"""Slip verdicts cut from the replay (ns from the scene start): mid-episode in both recordings."""


@pytest.mark.parametrize("golden", GOLDENS, ids=[g.name for g in GOLDENS])
def test_grip_never_falls_while_the_slip_verdicts_stop(golden: Golden, tmp_path: Path) -> None:
    """The recording replayed into the grip controller with 50 ms of verdicts cut out: the
    watchdog keeps commanding, and the command never falls until a verdict comes again."""
    cut = tmp_path / "cut.mcap"
    with RecordingWriter(cut, wall_minus_monotonic_ns=0) as writer:
        for frame in read_recording(golden.path):
            stamp = decode(frame.payload).header.stamp_ns
            if not (frame.topic == "slip" and GAP_NS[0] <= stamp < GAP_NS[1]):
                writer.write(frame.topic, frame.payload, frame.log_time_ns)
    node = build_node(golden, "grip_controller")
    commands = replay_into(node, cut)["grip/command"]
    in_gap = [m for m in commands if GAP_NS[0] <= m.header.pub_ns < GAP_NS[1]]
    assert any(m.reason == "fail-safe" for m in in_gap), [m.reason for m in in_gap]
    _check_grip_commands(golden, commands, node)
