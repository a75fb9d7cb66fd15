"""Field paths of ``topic echo --field``: a bad index is an error, not silence."""

from __future__ import annotations

import numpy as np
import pytest

from slipstack.lib.errors import ConfigError
from slipstack.messages import Header, TactileFrame
from slipstack.nodes.tools.topic_echo import MessagePrinter
from slipstack.nodes.tools.topic_format import as_tree, pick


def _frame() -> TactileFrame:
    n = 16 * 16
    return TactileFrame(pressure_pa=np.arange(n, dtype="<f4"), saturated=np.zeros(n, bool),
                        dead=np.zeros(n, bool), header=Header(1, 0, 1, {}))


def test_a_flat_index_into_the_pad_picks_that_taxel():
    assert pick(as_tree(_frame()), "pressure_pa.17") == (True, 17.0)


def test_an_index_past_the_pad_names_the_size():
    printer = MessagePrinter(field="pressure_pa.300", csv_mode=False, no_arr=False, truncate=16)
    with pytest.raises(ConfigError, match=r"256 value\(s\).*0\.\.255"):
        printer.format(_frame())


def test_a_missing_map_key_is_not_an_error():
    assert pick({"counters": {"a": 1}}, "counters.b") == (False, None)
