"""``slipstack reproduce --quick``: every paper figure drawn, valid, referenced by the report."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

pytest.importorskip("matplotlib")  # the `report` extra; the test extra installs it

pytestmark = pytest.mark.e2e

FIGURES = ["fig4a", "fig4b", "fig5a", "fig10", "fig11", "fig12", "fig13", "fig14", "fig15"]


def test_quick_reproduction_draws_every_figure_and_links_it(tmp_path):
    import matplotlib.image

    out = tmp_path / "repro"
    done = subprocess.run([sys.executable, "-m", "slipstack.launch.cli", "reproduce", "--quick", "--out", str(out)],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
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


def test_an_unknown_figure_is_refused_with_the_list(tmp_path):
    done = subprocess.run([sys.executable, "-m", "slipstack.launch.cli", "reproduce", "--only", "fig99",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "fig99" in done.stderr and "fig15" in done.stderr
