"""What a recording misses, per topic, counted against what each publisher sent (hand-made streams)."""

from __future__ import annotations

import numpy as np

from slipstack.messages import Diagnostics, Header, Wrench, encode
from slipstack.messages.frame import peek_header
from slipstack.nodes.recording.loss import LossLedger, loss_text


def _wrench(seq: int) -> bytes:
    return encode(Wrench(force=np.zeros(3), header=Header(seq + 1, seq, seq + 1, {})))


def _diag(node: str, seq: int, published: int, *, final: bool = False) -> bytes:
    counters = {"out.ft/wrench.published": published, **({"stopped": 1} if final else {})}
    return encode(Diagnostics(node=node, counters=counters, header=Header(seq + 1, seq, seq + 1, {})))


def _feed(ledger: LossLedger, topic: str, payload: bytes) -> int:
    return ledger.frame(topic, payload, peek_header(payload))


def test_gaps_a_restart_and_the_tail_after_the_last_frame_are_each_counted():
    ledger = LossLedger()
    for seq in [0, 1, 2, 5, 6]:  # 3 and 4 dropped on the way
        _feed(ledger, "ft/wrench", _wrench(seq))
    for seq in [2, 3]:  # restarted: its 0 and 1 never came
        _feed(ledger, "ft/wrench", _wrench(seq))
    ledger.numbered_at_stop({"ft_driver": {"ft/wrench": 10}})  # it sent 0..9 after the restart: 4..9 never came
    loss = ledger.report({"ft/wrench": 7}, {})["ft/wrench"]
    assert (loss["sequence_gaps"], loss["after_last"], loss["before_first"]) == (2 + 2, 6, 0)
    assert loss["missing"] == 10 and loss["exact"] and loss["recorded"] == 7


def test_the_tail_from_diagnostics_is_exact_only_once_the_last_one_came():
    ledger = LossLedger()
    for seq in range(5):
        _feed(ledger, "ft/wrench", _wrench(seq))
    _feed(ledger, "diagnostics", _diag("ft_driver", 0, 8))
    loss = ledger.report({"ft/wrench": 5}, {})["ft/wrench"]
    assert loss["after_last"] == 3 and not loss["exact"]
    assert "at least 3 of 8" in loss_text(ledger.report({"ft/wrench": 5}, {}))
    _feed(ledger, "diagnostics", _diag("ft_driver", 1, 9, final=True))
    loss = ledger.report({"ft/wrench": 5}, {})["ft/wrench"]
    assert loss["after_last"] == 4 and loss["exact"]


def test_frames_not_written_and_a_topic_never_received_are_missing():
    ledger = LossLedger()
    for seq in range(4):
        _feed(ledger, "ft/wrench", _wrench(seq))
    ledger.numbered_at_stop({"ft_driver": {"ft/wrench": 4}, "tactile_driver": {"tactile/frame": 3}})
    report = ledger.report({"ft/wrench": 1}, {"ft/wrench": 3})
    assert report["ft/wrench"]["missing"] == 3 and report["ft/wrench"]["not_written"] == 3
    assert report["tactile/frame"] == {"recorded": 0, "missing": 3, "sequence_gaps": 0, "before_first": 0,
                                       "after_last": 3, "not_written": 0, "exact": True}
    assert loss_text(LossLedger().report({}, {})) == "every frame sent is in it"
