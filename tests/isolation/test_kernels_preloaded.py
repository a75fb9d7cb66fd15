"""A control node loads every numba kernel it uses in ``start``, before it reports ready:
its first contact must not compile a kernel or load one from numba's cache (that took
10-20 ms, on a fresh install seconds, in the first contact of a launch).

Each case runs in a fresh interpreter (this one has compiled and run the kernels for
other tests): it starts the control nodes on the in-process executor, notes every
kernel specialisation loaded so far, hands them contacts that take every path through
the kernels (a twist about an off-centre point, a pure torque, a pure pull), and
reports the specialisations added while they handled them. Nothing here is timed.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

CHILD = """
import json, sys
sys.path.insert(0, {here!r})
from numba.core.registry import CPUDispatcher
from sensor_frames import MS, tactile, wrench
from slipstack.nodes.cor_estimator import CorEstimator, CorParams
from slipstack.nodes.fusion import Fusion
from slipstack.nodes.grip_controller import GripController, GripControllerParams
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.slip_detector import SlipDetector, SlipDetectorParams


def loaded():
    kernels = {{}}
    for name, module in list(sys.modules.items()):
        if name.startswith("slipstack") and module is not None:
            for attr, value in vars(module).items():
                if isinstance(value, CPUDispatcher):
                    kernels[name + "." + attr] = [str(s) for s in value.signatures]
    return kernels


ex = InProcessExecutor([Fusion(), CorEstimator(CorParams({cor})), SlipDetector(SlipDetectorParams({detector})),
                        GripController(GripControllerParams({controller}))])
ex.run(until_ns=0)  # starts the nodes: what they do before they report ready
before = loaded()
ex.feed([tactile(0, 4.0), wrench(1, 4.0, 0.2, tau=2e-3), wrench(2, 4.0, 0.0, tau=2e-3), wrench(3, 4.0, 0.3)])
ex.run(until_ns=5 * MS)
assert len(ex.published["grip/command"]) >= 3, ex.published
added = {{k: [s for s in v if s not in before.get(k, [])] for k, v in loaded().items()}}
print(json.dumps({{k: v for k, v in added.items() if v}}))
"""


@pytest.mark.parametrize("cor, detector, controller", [
    ("", "", ""),  # the stack's defaults: the exact solver, test and law
    ("solver='robust'", "method='tactile_cor_robust', pool=2", "law='tactile14'"),
    ("solver='paper'", "method='decoupled'", "law='ft13'"),  # F/T test with β_s from the pad
])
def test_the_first_contact_after_start_compiles_and_loads_no_kernel(cor, detector, controller):
    script = CHILD.format(here=str(Path(__file__).parent), cor=cor, detector=detector, controller=controller)
    child = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert child.returncode == 0, child.stderr
    added = json.loads(child.stdout.strip().splitlines()[-1])
    assert added == {}, f"kernels loaded on the first contact instead of in start: {added}"
