"""``slipstack report``: identification numbers and the figure from synthetic recordings."""

from __future__ import annotations

import argparse
import re
import struct
import sys

import numpy as np
import pytest
from slipstack.messages import GripCommand, Header, RigTruth, Slip, Wrench, encode
from slipstack.nodes.recording.bag_io import RecordingWriter
from slipstack.analysis.report import (
    MATPLOTLIB_HINT,
    add_parser,
    identify_recording,
    load_series,
)

T0_NS = 10_000_000_000      # monotonic stamp of the scene start
WALL = 1_700_000_000_000_000_000 - T0_NS
FT_HZ, TRUTH_HZ = 500, 250
F_N = 5.0                   # N
MU_S, MU_D = 0.45, 0.36
RATE = 0.8                  # dμ/dt on the ramp, 1/s (4 N/s at 5 N, as in fig4a)
ONSET_S = MU_S / RATE       # 0.5625 s
DURATION_S = 2.0
SLIDE_M_PER_S = 0.05        # object speed once sliding: the 0.1 mm threshold is 2 ms away
BETA_S, BETA_D = 1.33e-3, 1.06e-3  # m (a Hertzian tip of radius 5 mm at 5 N)


def _stamp(t_s: float) -> int:
    return T0_NS + round(t_s * 1e9)


def _header(t_s: float, seq: int) -> Header:
    return Header(_stamp(t_s), seq, _stamp(t_s) + 10_000, {})


def write_ramp(path, *, truth: bool = True, torque: bool = False, tied_stamps: bool = False) -> None:
    """A Fig. 4 ramp: load/f_n rises at RATE to the static value at ONSET_S, then sits at
    the dynamic one (small Gaussian noise). ``torque``: the ramp is τ/f_n (β, m) and
    f_t ≈ 0; ``tied_stamps``: F/T samples come in pairs sharing one stamp (a driver
    stamping a burst with one receive time)."""
    rng = np.random.default_rng(1)
    dynamic, scale = (BETA_D, BETA_S / MU_S) if torque else (MU_D, 1.0)
    with RecordingWriter(path, wall_minus_monotonic_ns=WALL) as w:
        for k in range(int(DURATION_S * FT_HZ)):
            t = k / FT_HZ
            ratio = RATE * scale * t if t <= ONSET_S else dynamic
            f_n = F_N + rng.normal(0.0, 0.002)
            load = ratio * F_N + rng.normal(0.0, 0.002 * scale)
            force = [rng.normal(0, 0.002), 0.0, -f_n] if torque else [load, 0.0, -f_n]
            stamp_t = (k - k % 2) / FT_HZ if tied_stamps else t
            msg = Wrench(force=np.array(force), torque=np.array([0.0, 0.0, load if torque else 0.0]),
                         frame="pad", device_seq=k)
            w.write("ft/wrench", encode(msg, _header(stamp_t, k)), _stamp(t) + WALL + 50_000)
        if not truth:
            return
        for k in range(int(DURATION_S * TRUTH_HZ)):
            t = k / TRUTH_HZ
            moved = max(t - ONSET_S, 0.0) * SLIDE_M_PER_S
            msg = RigTruth(x=0.0 if torque else moved, theta=moved / 0.005 if torque else 0.0,
                           gross_slip=t > ONSET_S, slip_distance_m=0.0 if torque else moved,
                           slip_angle_rad=moved / 0.005 if torque else 0.0, f_n_applied=F_N, f_n_command=F_N)
            w.write("rig/truth", encode(msg, _header(t, k)), _stamp(t) + WALL + 80_000)
            ratio = RATE * t if t <= ONSET_S else MU_D
            slip = Slip(state="stick" if t < ONSET_S else "translation", margin=1.0 - ratio / MU_S, method="coulomb",
                        gamma=ratio / MU_S, f_n=F_N, f_t=np.array([ratio * F_N, 0.0]))
            w.write("slip", encode(slip, _header(t, k)), _stamp(t) + WALL + 90_000)
            if k % 25 == 0:
                cmd = GripCommand(f_n_desired=F_N, law="exact", reason="nominal")
                w.write("grip/command", encode(cmd, _header(t, k // 25)), _stamp(t) + WALL + 95_000)


def run_cli(*argv: str) -> int:
    parser = argparse.ArgumentParser(prog="slipstack")
    add_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["report", *argv])
    return args.func(args)


def printed_estimates(text: str) -> list[tuple[str, tuple[float, float]]]:
    """``("μ_s", (value, se))`` for each ``μ_s = 0.4513 ± 0.00005`` in the output."""
    return [(name, (float(v), float(se))) for name, v, se in re.findall(r"(\S+_[sd]) = (\S+) ± (\S+)", text)]


def assert_printed(shown: tuple[float, float], value: float, se: float) -> None:
    """Printed with >= 3 decimals and the standard error to 2 significant digits."""
    assert shown[0] == pytest.approx(value, abs=5e-4)
    assert shown[1] == pytest.approx(se, rel=0.05)


def test_identify_recovers_mu_and_onset_with_truth(tmp_path):
    path = tmp_path / "fig4a.mcap"
    write_ramp(path)
    ident = identify_recording(load_series(path))
    (mu,) = ident.mu  # one loading
    assert mu.ok and ident.beta == () and ident.load == "force"
    assert ident.motion_source == "rig/truth" and mu.onset_source == "slip"
    # onset: the last sample before the slip distance grows (the truth's gross-slip onset)
    assert mu.onset_t_s == pytest.approx(ONSET_S, abs=0.005)
    assert mu.static == pytest.approx(MU_S, abs=0.005)
    assert mu.dynamic == pytest.approx(MU_D, abs=0.002)
    assert 0 < mu.static_se < 0.002 and 0 < mu.dynamic_se < 0.001


def test_identify_without_truth_uses_the_ratio_drop_and_merges_tied_stamps(tmp_path, capsys):
    path = tmp_path / "hw.mcap"
    write_ramp(path, truth=False, tied_stamps=True)
    assert run_cli(str(path), "--identify") == 0
    out = capsys.readouterr().out
    assert "1000 F/T samples (500 sharing a stamp averaged)" in out
    assert "slip onset from the ratio drop" in out
    ident = identify_recording(load_series(path))
    (mu,) = ident.mu
    assert mu.ok and mu.onset_source == "ratio" and ident.merged == 500
    assert mu.onset_t_s == pytest.approx(ONSET_S, abs=0.006)  # pairs: a 4 ms time grid
    assert mu.static == pytest.approx(MU_S, abs=0.005)
    assert mu.dynamic == pytest.approx(MU_D, abs=0.002)
    printed = dict(printed_estimates(out))
    assert_printed(printed["μ_s"], mu.static, mu.static_se)
    assert_printed(printed["μ_d"], mu.dynamic, mu.dynamic_se)
    assert "status ok" in out


def test_identify_torque_ramp_gives_beta(tmp_path, capsys):
    path = tmp_path / "fig4b.mcap"
    write_ramp(path, torque=True)
    ident = identify_recording(load_series(path))
    (beta,) = ident.beta
    assert ident.load == "torque" and ident.mu == () and beta.ok
    assert beta.onset_source == "slip"
    assert beta.static == pytest.approx(BETA_S, rel=0.02)
    assert beta.dynamic == pytest.approx(BETA_D, rel=0.01)
    assert beta.onset_t_s == pytest.approx(ONSET_S, abs=0.005)
    assert run_cli(str(path), "--identify") == 0
    out = capsys.readouterr().out
    assert "the torque ramp dominates" in out
    printed = dict(printed_estimates(out))
    assert_printed(printed["β_s"], beta.static * 1e3, beta.static_se * 1e3)
    assert "β_d = " in out and " mm" in out


def test_time_zero_is_the_scene_start_and_frames_are_sorted(tmp_path):
    path = tmp_path / "a.mcap"
    write_ramp(path)
    series = load_series(path)
    assert series.t0_ns == T0_NS
    assert series["rig/truth"]["t_s"][0] == 0.0
    assert series.duration_s == pytest.approx((DURATION_S * TRUTH_HZ - 1) / TRUTH_HZ)
    assert np.all(np.diff(series["ft/wrench"]["stamp_ns"]) > 0)
    assert series["ft/wrench"]["f_n"][0] == pytest.approx(F_N, abs=0.01)  # −force[2]


def test_figure_without_matplotlib_fails_clearly_but_identify_works(tmp_path, monkeypatch, capsys):
    path = tmp_path / "a.mcap"
    write_ramp(path, truth=False)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # `import matplotlib` raises ImportError
    assert run_cli(str(path), "-o", str(tmp_path / "x.png")) == 2
    err = capsys.readouterr().err
    assert "pip install 'slipstack[report]'" in err and MATPLOTLIB_HINT in err
    assert not (tmp_path / "x.png").exists()
    assert run_cli(str(path), "--identify") == 0


def _png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def test_figure_is_a_png_with_the_panels_that_have_data(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    path = tmp_path / "fig4a.mcap"
    write_ramp(path)
    out = tmp_path / "figs" / "fig4a.png"
    assert run_cli(str(path), "-o", str(out), "--title", "Fig. 4a") == 0
    text = capsys.readouterr().out
    assert text.splitlines()[0] == str(out)
    assert "panels: normal force, tangential load, slip verdict, object motion" in text
    assert "truth: 1 gross-slip episodes, first at 0.56 s" in text
    # the flag's stretches are not called episodes (an episode is true gross slip)
    assert re.search(r"slip \(\w+\): flag up on \d+% of \d+ frames, in \d+ stretch(es)?", text), text
    data = out.read_bytes()
    width, height = _png_size(data)
    assert (width, height) == (1100, 1100) and 30_000 < len(data) < 2_000_000
    # without truth (real hardware) the motion panel is left out; default output name
    hw = tmp_path / "hw.mcap"
    write_ramp(hw, truth=False)
    assert run_cli(str(hw)) == 0
    text = capsys.readouterr().out
    assert "panels: normal force, tangential load\n" in text + "\n"
    assert _png_size((tmp_path / "hw.png").read_bytes())[1] < height
