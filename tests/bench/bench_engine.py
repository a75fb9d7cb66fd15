"""Detection on the second engine's recordings, measured against their truth.

Each recording of ``engine_mujoco.py`` is replayed through the stack's own fusion and
slip detector nodes (built from launch/files/stack.toml with the material under test,
in the in-process executor on the recording's stamps: the path of a lock-step run) and
the flags are scored against ``rig/truth`` (lib/episodes.py, docs/math.md §3.2).
Materials: the shipped files, and per object (μ, pad) the file ``slipstack identify``
writes from that object's force and torque sessions, run as a user runs it.

    python tests/bench/bench_engine.py --recordings DIR [--materials rubber coulomb FILE...] [--identify]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from slipstack.launch.launch_file import load_launch_file
from slipstack.lib.episodes import detection_quality
from slipstack.lib.status import SlipState
from slipstack.messages import decode
from slipstack.nodes.recording.bag_io import read_recording
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from _versions import code_digest

REPLAYED = ("fusion", "slip_detector")
NOT_SLIP = (SlipState.STICK.value, SlipState.NO_CONTACT.value)


@dataclass
class Replay:
    """One recording through the detector: per ``slip`` frame its stamp, flag and contact;
    the truth's stamps and gross slip; the detector's release dwell (ns)."""

    t: np.ndarray
    flag: np.ndarray
    contact: np.ndarray
    truth_t: np.ndarray
    gross: np.ndarray
    release_ns: int
    period_ns: float


def cached_replay(path: Path, launch_args: dict[str, str], cache: Path | None) -> Replay:
    """:func:`replay`, kept in ``cache`` under the recording's and the arguments' names."""
    if cache is None:
        return replay(path, launch_args)
    key = "-".join(f"{k}={Path(v).stem}" for k, v in sorted(launch_args.items()))
    file = cache / f"{path.stem}@{key}.npz"
    if file.exists():
        data = dict(np.load(file))
        return Replay(**{k: (v if v.ndim else v.item()) for k, v in data.items()})
    r = replay(path, launch_args)
    cache.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(file, **r.__dict__)
    return r


def replay(path: Path, launch_args: dict[str, str]) -> Replay:
    """Feed ``path``'s ft/wrench and tactile/frame to the stack's fusion and slip detector."""
    with tempfile.TemporaryDirectory() as run_dir:
        launch = load_launch_file("stack", {"tactile": "true", "controller": "false", **launch_args},
                                  builtins={"run_dir": run_dir})
    entries = {e.name: e for e in launch.nodes}
    nodes = [entries[name].instance() for name in REPLAYED]
    slips: list[bytes] = []
    ex = InProcessExecutor(nodes, names=list(REPLAYED), remaps={n: entries[n].remap for n in REPLAYED},
                           keep_published=False, on_frame=lambda _t, _topic, payload: slips.append(payload),
                           on_frame_topics={"slip"})
    frames = list(read_recording(path, ["ft/wrench", "tactile/frame", "rig/truth"]))
    ex.feed((f.log_time_ns, f.topic, f.payload) for f in frames if f.topic != "rig/truth")
    ex.run()
    ex.stop()
    msgs = [decode(p) for p in slips]
    truth = [decode(f.payload) for f in frames if f.topic == "rig/truth"]
    wrench_t = np.array([f.log_time_ns for f in frames if f.topic == "ft/wrench"])
    return Replay(np.array([m.header.stamp_ns for m in msgs], dtype=np.int64),
                  np.array([m.state not in NOT_SLIP for m in msgs]),
                  np.array([m.state != SlipState.NO_CONTACT.value for m in msgs]),
                  np.array([m.header.stamp_ns for m in truth], dtype=np.int64),
                  np.array([m.gross_slip for m in truth]), round(nodes[1].params.release_ms * 1e6),
                  float(np.median(np.diff(wrench_t))))


@dataclass
class Score:
    """Issue 24's measures of one or more recordings."""

    episodes: int = 0
    missed: int = 0
    stick_frames: int = 0
    false_frames: int = 0
    latch_frames: int = 0  # of the false ones: the latch holding a flag that rose for an episode
    quiet_scenes: int = 0
    quiet_alarming: int = 0
    quiet_alarms: int = 0
    delays: list[float] = field(default_factory=list)  # F/T samples
    holds_ms: list[float] = field(default_factory=list)

    def add(self, other: "Score") -> None:
        for name in ("episodes", "missed", "stick_frames", "false_frames", "latch_frames", "quiet_scenes",
                     "quiet_alarming", "quiet_alarms"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        self.delays += other.delays
        self.holds_ms += other.holds_ms


def score(r: Replay) -> Score:
    """Missed episodes, delays, false-alarm share, latch hold (lib/episodes.py's one definition),
    and the alarms of a recording without a true episode."""
    q = detection_quality(r.truth_t, r.gross, r.t, r.flag, release_ns=r.release_ns, in_contact=r.contact)
    quiet = not q.episodes
    rises = int(np.count_nonzero(r.flag & ~np.concatenate([[False], r.flag[:-1]]))) if quiet else 0
    return Score(episodes=len(q.episodes), missed=q.missed, stick_frames=q.stick_frames,
                 false_frames=q.false_alarm_frames, latch_frames=q.latch_hold_frames, quiet_scenes=int(quiet),
                 quiet_alarming=int(rises > 0), quiet_alarms=rises, delays=[d / r.period_ns for d in q.delays_ns],
                 holds_ms=[h / 1e6 for h in q.holds_ns])


def _pct(values: list[float], q: float, fmt: str = "{:+.1f}") -> str:
    return fmt.format(float(np.percentile(values, q))) if values else "-"


def row(label: str, s: Score) -> str:
    share = 100.0 * s.false_frames / max(s.stick_frames, 1)
    latch = 100.0 * s.latch_frames / max(s.stick_frames, 1)
    return (f"| {label} | {s.episodes} | {s.missed} | {_pct(s.delays, 50)} / {_pct(s.delays, 95)} | "
            f"{_pct(s.delays, 0)} | {share:.2f} % ({latch:.2f} %) | "
            f"{_pct(s.holds_ms, 50, '{:.0f}')} / {_pct(s.holds_ms, 95, '{:.0f}')} | "
            f"{s.quiet_alarming} of {s.quiet_scenes} ({s.quiet_alarms}) |")


HEADER = ["| contact, material file | episodes | missed | delay p50 / p95 (F/T samples) | earliest | "
          "false-alarm share (of it the latch hold) | latch hold after slip p50 / p95 ms | never-slipping scenes "
          "that alarm (alarms) |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]


# -- identification, as a user runs it ----------------------------------------------------

def identify(paths: list[Path], out: Path) -> tuple[Path | None, str]:
    """``slipstack identify PATHS -o out``; (the file or None, the tool's last line)."""
    tool = Path(sys.executable).with_name("slipstack")
    done = subprocess.run([str(tool), "identify", *map(str, paths), "-o", str(out), "-q"],
                          capture_output=True, text=True)
    said = (done.stdout + done.stderr).strip().splitlines()
    return (out if done.returncode == 0 and out.exists() else None), (said[-1] if said else f"exit {done.returncode}")


def read_toml_values(path: Path) -> dict:
    import tomllib
    return tomllib.loads(path.read_text())["material"]


def object_of(meta: dict) -> str:
    sc = meta["scenario"]
    return f"mu{sc['mu']:.2f}_{sc['pad']}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--recordings", type=Path, required=True, help="a folder of engine_mujoco.py recordings")
    ap.add_argument("--materials", nargs="*", default=["rubber", "coulomb", "weakening"],
                    help="material files or launch/materials names (default: the three shipped)")
    ap.add_argument("--identify", action="store_true",
                    help="also: per object, the file slipstack identify writes from its force_ and torque_ sessions")
    ap.add_argument("--scenarios", nargs="*", default=[], help="only recordings whose name starts so")
    ap.add_argument("--launch-arg", action="append", default=[], metavar="NAME=VALUE",
                    help="a further stack.toml argument for the replay (repeatable)")
    ap.add_argument("--json", type=Path, help="write every scenario's scores here")
    ap.add_argument("--cache", type=Path, help="keep each replay's flags here, in a folder named by the code's "
                    "digest and the recordings' folder (other code: a new folder)")
    ap.add_argument("--per-scenario", action="store_true", help="also print one row per recording")
    args = ap.parse_args()
    if args.cache is not None:
        folder = hashlib.sha256(str(args.recordings.resolve()).encode()).hexdigest()[:8]
        args.cache = args.cache / f"{code_digest()}-{folder}"
    metas = {p.with_suffix(".mcap"): json.loads(p.read_text()) for p in sorted(args.recordings.glob("*.json"))}
    metas = {p: m for p, m in metas.items() if p.exists() and not p.name.startswith("ident_")
             and (not args.scenarios or any(p.stem.startswith(s) for s in args.scenarios))}
    if not metas:
        ap.error(f"no engine recordings (.mcap with .json) in {args.recordings}")
    extra = dict(a.split("=", 1) for a in args.launch_arg)
    configs: list[tuple[str, dict[Path, str]]] = [(m, {p: m for p in metas}) for m in args.materials]
    ident_lines = []
    t0 = time.monotonic()
    if args.identify:
        files, cache = {}, Path(tempfile.mkdtemp(prefix="bench-engine-"))
        for obj in sorted({object_of(m) for m in metas.values()}):
            mu, pad = obj.split("_")
            ramps = [args.recordings / f"{kind}_{pad}_{mu}.mcap" for kind in ("force", "torque")]
            if not all(p.exists() for p in ramps):
                continue
            print(f"  identify {obj} ...", file=sys.stderr, flush=True)
            found, said = identify(ramps, cache / f"{obj}.toml")
            truth = next(m for m in metas.values() if object_of(m) == obj)
            if found is None:
                ident_lines.append(f"| {obj} | refused or failed: {said} | | | | |")
                continue
            v = read_toml_values(found)
            mu_true, beta_true = truth["scenario"]["mu"], truth.get("beta_true_m", math.nan)
            ident_lines.append(
                f"| {obj} | {v['mu_s']:.4f} ({100 * (v['mu_s'] / mu_true - 1):+.1f} %) | "
                f"{v['mu_d']:.4f} ({100 * (v['mu_d'] / mu_true - 1):+.1f} %) | "
                f"{1e3 * v['beta_s_m']:.3f} ({100 * (v['beta_s_m'] / beta_true - 1):+.1f} %) | "
                f"{1e3 * v['beta_d_m']:.3f} ({100 * (v['beta_d_m'] / beta_true - 1):+.1f} %) | "
                f"{', '.join(f'{g:.3f}' for g in v.get('onset_gamma', []))} |")
            files[obj] = str(found)
        configs.append(("identified", {p: files[object_of(m)] for p, m in metas.items() if object_of(m) in files}))
    per_scene: dict[str, dict[str, dict]] = {}
    table, scenario_rows = [], []
    for label, chosen in configs:
        total: dict[str, Score] = {}
        for i, (path, material) in enumerate(chosen.items(), 1):
            print(f"\r  {label}: {i}/{len(chosen)} {path.stem:<40}", end="", file=sys.stderr, flush=True)
            s = score(cached_replay(path, {"material": material, **extra}, args.cache))
            per_scene.setdefault(label, {})[path.stem] = {**s.__dict__, "material": material}
            if args.per_scenario:
                scenario_rows.append(row(f"{path.stem}, {label}", s))
            mu = f"μ {metas[path]['scenario']['mu']:g}"
            total.setdefault(mu, Score()).add(s)
        print(file=sys.stderr)
        table += [row(f"{mu}, {label}", s) for mu, s in sorted(total.items(), reverse=True)]
    print(f"\n{len(metas)} recordings from {args.recordings}; wall {time.monotonic() - t0:.0f} s\n")
    if ident_lines:
        print("| object | μ_s | μ_d | β_s mm | β_d mm | onset γ |\n| --- | ---: | ---: | ---: | ---: | --- |")
        print("\n".join(ident_lines) + "\n")
    print("\n".join(HEADER + table))
    if scenario_rows:
        print("\n" + "\n".join(HEADER + scenario_rows))
    if args.json:
        args.json.write_text(json.dumps(per_scene, indent=1))


if __name__ == "__main__":
    main()
