"""``slipstack identify``: recordings in, a material file out (short synthetic MCAP files)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from slipstack.launch.cli import main
from slipstack.lib.material import detector_thresholds, load_material
from slipstack.messages import Header, RigTruth, Wrench, encode
from slipstack.nodes.recording.bag_io import RecordingWriter

FS = 500.0
F_N = 5.0


def write_ramp(path: Path, *, torsion: bool, static: float, dynamic: float, t_on: float = 1.0,
               duration: float = 2.0, with_wrench: bool = True, seed: int = 0) -> None:
    """A Fig. 4 ramp at constant f_n as the stack records it (pad-frame wrench, truth)."""
    rng = np.random.default_rng(seed)
    writer = RecordingWriter(path)
    for i in range(int(duration * FS)):
        t = i / FS
        ratio = static * t / t_on if t <= t_on else dynamic + (static - dynamic) * np.exp(-(t - t_on) / 0.03)
        ratio += rng.normal(0.0, 6e-6 if torsion else 0.002)  # gamma noise 0.004 in both
        stamp = 1_000_000_000 + round(t * 1e9)
        slip = max(t - t_on, 0.0) * (0.05 if torsion else 2e-3)
        if with_wrench:
            force = (0.0 if torsion else ratio * F_N, 0.0, -F_N)
            torque = (0.0, 0.0, ratio * F_N if torsion else 0.0)
            w = Wrench(force=np.array(force), torque=np.array(torque), frame="pad")
            writer.write("ft/wrench", encode(w, Header(stamp_ns=stamp, seq=i)), stamp)
        truth = RigTruth(slip_distance_m=0.0 if torsion else slip, slip_angle_rad=slip if torsion else 0.0,
                         gross_slip=t > t_on, f_n_applied=F_N, f_n_command=F_N)
        writer.write("rig/truth", encode(truth, Header(stamp_ns=stamp, seq=i)), stamp)
    writer.close()


def test_identify_writes_a_material_that_drives_the_detector(tmp_path: Path, capsys) -> None:
    force, torsion = tmp_path / "force.mcap", tmp_path / "torsion.mcap"
    write_ramp(force, torsion=False, static=0.5, dynamic=0.3)
    write_ramp(torsion, torsion=True, static=1.5e-3, dynamic=0.9e-3, seed=1)
    out = tmp_path / "mine.toml"
    assert main(["identify", str(force), str(torsion), "-o", str(out), "--provenance", "synthetic ramps"]) == 0
    m = load_material(out)
    assert m.name == "mine" and m.provenance == "synthetic ramps"
    assert m.mu_s == pytest.approx(0.5, rel=0.01) and m.mu_d == pytest.approx(0.3, rel=0.01)
    assert m.beta_s_m == pytest.approx(1.5e-3, rel=0.01) and m.beta_d_m == pytest.approx(0.9e-3, rel=0.02)
    assert len(m.onset_gamma) == 2 and all(g == pytest.approx(1.0, abs=0.02) for g in m.onset_gamma)
    assert m.gamma_noise_stick == pytest.approx(0.002 / 0.5, rel=0.3)
    t = detector_thresholds(m)
    assert t.delta == pytest.approx(1.0 - (m.sliding_level - 3 * m.gamma_noise_stick))
    assert t.gamma_release == pytest.approx(m.sliding_level - 4 * m.gamma_noise_slide)
    report = capsys.readouterr()
    assert "identify: [2/2]" in report.err
    assert "material mine (± standard error, ± model error" in report.out
    mu_s_line = next(line for line in report.out.splitlines() if line.startswith("  mu_s "))
    assert mu_s_line.startswith("  mu_s   0.5") and "(stat)" in mu_s_line and "(model)" in mu_s_line
    # Straight synthetic ramps and plateaus that have settled: model errors stay within the noise.
    assert 0.0 <= m.mu_s_model < 0.01 and 0.0 <= m.mu_d_model < 0.003
    assert 0.0 <= m.beta_d_model_m < 0.03e-3


def test_identify_names_what_is_missing(tmp_path: Path, capsys) -> None:
    no_wrench = tmp_path / "truth_only.mcap"
    write_ramp(no_wrench, torsion=False, static=0.5, dynamic=0.3, with_wrench=False)
    assert main(["identify", str(no_wrench), "-o", str(tmp_path / "x.toml"), "-q"]) == 2
    assert "no usable ft/wrench samples" in capsys.readouterr().err
    torsion = tmp_path / "torsion.mcap"
    write_ramp(torsion, torsion=True, static=1.5e-3, dynamic=0.9e-3)
    assert main(["identify", str(torsion), "-o", str(tmp_path / "x.toml"), "-q"]) == 2
    assert "no tangential-force ramp" in capsys.readouterr().err
    assert not (tmp_path / "x.toml").exists()


def test_identify_refuses_a_force_recording_that_never_slips(tmp_path: Path, capsys) -> None:
    """A held object (the default launch's recording) has no onset: the error names the
    recording and what to record instead, and no material file is written."""
    held = tmp_path / "held.mcap"
    write_ramp(held, torsion=False, static=0.2, dynamic=0.2, t_on=10.0)  # rises, never slips
    out = tmp_path / "x.toml"
    assert main(["identify", str(held), "-o", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert "held.mcap" in err and "no-onset" in err and "ident_force" in err
    assert not out.exists()
