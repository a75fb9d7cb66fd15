"""The finger's command watchdog (plant side): hold, then raise, when grip commands stop."""

from __future__ import annotations

import pytest

from slipstack.lib.rig.actuator import CommandWatchdog

MS = 1_000_000


def test_silent_before_the_first_command_and_while_commands_arrive():
    dog = CommandWatchdog(100 * MS, safe_grip_n=20.0, rise_n_per_s=10.0)
    assert dog.step(500 * MS, 5.0) is None  # no command yet: the scene's own grip stands
    dog.commanded(500 * MS)
    assert dog.step(600 * MS, 5.0) is None  # exactly at the timeout: still in time
    assert not dog.expired


def test_a_silent_controller_makes_the_finger_raise_towards_the_safe_grip_and_never_release():
    dog = CommandWatchdog(100 * MS, safe_grip_n=8.0, rise_n_per_s=10.0)
    dog.commanded(0)
    dog.step(100 * MS, 5.0)
    command = 5.0
    seen = []
    for k in range(1, 60):  # 10 ms ticks from 110 ms
        command = dog.step(100 * MS + k * 10 * MS, command)
        seen.append(command)
    assert dog.expired
    assert seen[0] == pytest.approx(5.1)  # 10 N/s over a 10 ms tick
    assert all(b >= a for a, b in zip(seen, seen[1:]))  # never lower
    assert seen[-1] == pytest.approx(8.0)  # capped at the safe grip
    dog.commanded(800 * MS)
    assert dog.step(810 * MS, 3.0) is None and not dog.expired  # the controller is back: it decides again


def test_hold_only_and_a_command_above_the_safe_grip_is_kept():
    hold = CommandWatchdog(50 * MS)  # safe grip 0: hold only
    hold.commanded(0)
    assert hold.step(60 * MS, 7.0) == 7.0 and hold.step(70 * MS, 7.0) == 7.0
    high = CommandWatchdog(50 * MS, safe_grip_n=5.0)
    high.commanded(0)
    assert high.step(60 * MS, 12.0) == 12.0  # never lowered to the "safe" grip


def test_zero_timeout_disables_and_bad_settings_are_refused():
    off = CommandWatchdog(0, safe_grip_n=20.0)
    off.commanded(0)
    assert off.step(10_000 * MS, 1.0) is None
    for args in ((-1,), (MS, -1.0), (MS, float("nan")), (MS, 1.0, 0.0)):
        with pytest.raises(ValueError):
            CommandWatchdog(*args)
