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
    assert off.due_ns(10 * MS) is None  # no wake-up asked of the driver either
    for args in ((-1,), (MS, -1.0), (MS, float("nan")), (MS, 1.0, 0.0)):
        with pytest.raises(ValueError):
            CommandWatchdog(*args)


def test_a_new_watchdog_is_not_expired_and_one_with_defaults_only_holds():
    dog = CommandWatchdog(50 * MS)  # the defaults: safe grip 0 N (hold only), 10 N/s
    assert not dog.expired
    assert dog.step(0, 0.5) is None and not dog.expired  # no command yet
    dog.commanded(0)
    assert dog.step(60 * MS, 0.5) == 0.5 and dog.step(70 * MS, 0.5) == 0.5  # held, never raised nor lowered
    assert dog.expired
    default_rate = CommandWatchdog(50 * MS, safe_grip_n=8.0)
    default_rate.commanded(0)
    default_rate.step(60 * MS, 2.0)
    assert default_rate.step(160 * MS, 2.0) == pytest.approx(3.0)  # 10 N/s over 100 ms


def test_the_raise_counts_only_time_that_passed_since_the_last_tick():
    dog = CommandWatchdog(50 * MS, safe_grip_n=8.0, rise_n_per_s=10.0)
    dog.commanded(0)
    assert dog.step(200 * MS, 2.0) == 2.0  # the first tick after the silence: no earlier tick to count from
    assert dog.step(200 * MS, 2.0) == 2.0  # the same instant again: no time passed, no raise
    assert dog.step(190 * MS, 2.0) == 2.0  # a clock that steps back raises nothing either
    assert dog.step(290 * MS, 2.0) == pytest.approx(3.0)


def test_a_slow_raise_rate_is_accepted():
    dog = CommandWatchdog(50 * MS, safe_grip_n=8.0, rise_n_per_s=0.5)
    dog.commanded(0)
    dog.step(60 * MS, 2.0)
    assert dog.step(1060 * MS, 2.0) == pytest.approx(2.5)


def test_the_driver_is_woken_just_past_the_timeout_then_every_period_while_expired():
    dog = CommandWatchdog(1, safe_grip_n=8.0)  # the shortest timeout: 1 ns
    assert dog.due_ns(10 * MS) is None  # no command yet
    dog.commanded(100)
    assert dog.due_ns(10 * MS) == 102  # the first instant at which step() acts
    dog.step(102, 2.0)
    assert dog.expired and dog.due_ns(10 * MS) == 102 + 10 * MS
