"""``slipstack reproduce --quick``: every figure (the paper's and beyond) drawn, valid, referenced by the report;
Figs. 10–12 run with the friction identified on Fig. 4; a second run is byte-identical."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest

pytest.importorskip("matplotlib")  # the `report` extra; the test extra installs it

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(900)]  # ~40 s of CPU; generous for a busy machine

FIGURES = ["measured", "fig4a", "fig4b", "fig5a", "fig5b", "fig10", "fig11", "fig12", "fig13", "fig14", "cor_median",
           "fig15", "increment", "sensitivity", "pareto", "grip_economy", "limit_errors"]


def reproduce(out, *args):
    done = subprocess.run([sys.executable, "-m", "slipstack.launch.cli", "reproduce", "--quick", "--out", str(out),
                           *args], capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    """One full ``--quick`` reproduction, shared by the tests of this module."""
    out = tmp_path_factory.mktemp("reproduce") / "quick"
    reproduce(out)
    return out


def test_quick_reproduction_draws_every_figure_and_links_it(quick):
    import matplotlib.image

    from slipstack.lib.material import load_material

    out = quick
    page = (out / "index.html").read_text()
    report = (out / "report.md").read_text()
    for key in FIGURES:
        png = out / f"{key}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", key
        pixels = matplotlib.image.imread(png)
        assert pixels.shape[0] > 300 and pixels.shape[1] > 500, (key, pixels.shape)
        assert pixels[..., :3].std() > 0.05, f"{key} is (nearly) blank"
        assert f"src='{key}.png'" in page and f"({key}.png)" in report
    sections = re.findall(r"<section id='(\w+)'>", page)
    assert sections == FIGURES
    assert page.count("<dt>The paper</dt>") == len(FIGURES) and "nan" not in page.lower().split("<body>")[1]
    # Figs. 10-12 ran with what `slipstack identify` found on the Fig. 4 runs, and say so
    identified = load_material(out / "material-identified.toml")
    assert abs(identified.mu_s - 0.45) < 0.02
    assert f"μ_s = {identified.mu_s:.3f} (identified on Fig. 4a)" in report
    # the Pareto replay runs the detector node's own code: its replay of the runs' setting is the live run
    assert "The replay of each run's own setting flags as the run's detector did in at least 100.0 %" in report
    # the report leads with what the paper's test does on measured data, and gives the sensitivity's tables
    assert report.index("## What the paper's method does on measured data") < report.index("## Fig. 4a")
    assert report.count("| test | band δ |") == 1 and "| exact | 0.050 |" in report


def test_a_second_run_publishes_the_same_bytes(quick, tmp_path):
    # lock-step: fig13 alone, in another process, without the other experiments before it
    again = tmp_path / "again"
    reproduce(again, "--only", "fig13")
    first, second = (json.loads((d / "digests.json").read_text()) for d in (quick, again))
    assert set(second) == {"fig13"} and second["fig13"] == first["fig13"]


def test_an_unknown_figure_is_refused_with_the_list(tmp_path):
    done = subprocess.run([sys.executable, "-m", "slipstack.launch.cli", "reproduce", "--only", "fig99",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "fig99" in done.stderr and "fig15" in done.stderr


def test_the_help_lists_every_figure_in_plain_text():
    """``--only`` offers exactly the figures drawn; the help has no Sphinx markup (was: the
    module docstring with ``:data:`~slipstack…``` and an elided, partial figure list)."""
    done = subprocess.run([sys.executable, "-m", "slipstack.launch.cli", "reproduce", "--help"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0
    text = " ".join(done.stdout.split())
    assert ":data:" not in text and ":mod:" not in text and "``" not in text, text
    assert " ".join(FIGURES) in text, text


def test_the_help_loads_no_drawing_or_numeric_stack():
    """What is imported is the load-independent measure of start-up: the figure keys for
    ``--only`` come from a module without matplotlib (or numpy, or the figures)."""
    probe = ("import sys, runpy\n"
             "sys.argv = ['slipstack', 'reproduce', '--help']\n"
             "try:\n    runpy.run_module('slipstack.launch.cli', run_name='__main__')\n"
             "except SystemExit:\n    pass\n"
             "heavy = sorted(m for m in ('matplotlib', 'numpy', 'slipstack.analysis.figures') if m in sys.modules)\n"
             "print('HEAVY', heavy, file=sys.stderr)\n")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    assert "HEAVY []" in done.stderr, done.stderr
