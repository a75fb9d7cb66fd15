"""A normal end of a simulated run stays quiet: the drivers' device-loss lines after the world stopped.

The simulated world (the rig, a ``stop_first`` node) stops first, at the end of its scene
or on Ctrl-C, and closes the emulated devices; the drivers, still running, then see their
devices vanish and say so, as they must on hardware (``error: URL: …; retrying``). On a
normal end those lines are expected: :class:`WorldEndFilter` holds them back and the
launcher prints one line instead, naming the drivers and how many lines it held
(:meth:`WorldEndFilter.closing_line`); every held line still goes to the run's log file.

More in docs/modules.md, `launch/quiet_shutdown.py`.
"""

from __future__ import annotations

import logging
import re

from slipstack.nodes.runtime.logs import level_of, parse_log_levels

__all__ = ["SCENE_FINISHED", "WorldEndFilter", "WorldLogLevels"]

SCENE_FINISHED = re.compile(r"^scene \S+ finished$")
"""The rig's line at the end of its scene (``nodes/rig.py``), written before it closes the devices."""
_DEVICE_ERROR = re.compile(r"^error: \S+://")  # a driver's report_error: "error: URL: what; retrying ..."


class WorldEndFilter:
    """Decides which driver lines are the expected aftermath of the simulated world stopping.

    Args:
        world: names of the processes that simulate the world (``stop_first``).
        drivers: names of the processes that run device drivers.
    """

    def __init__(self, world: set[str], drivers: set[str]) -> None:
        self.world = world
        self.drivers = drivers
        self.ended = False
        self.held: dict[str, int] = {}

    def world_ending(self) -> None:
        """The launcher begins a shutdown: the world is stopped first."""
        self.ended = self.ended or bool(self.world)

    def keep(self, process: str, line: str) -> bool:
        """Whether ``line`` of ``process`` goes to the terminal (False: it is held, counted)."""
        if process in self.world and SCENE_FINISHED.match(line):
            self.ended = True
        if self.ended and process in self.drivers and _DEVICE_ERROR.match(line):
            self.held[process] = self.held.get(process, 0) + 1
            return False
        return True

    def closing_line(self) -> str | None:
        """The one line that replaces the held ones, or ``None`` if none was held."""
        if not self.held:
            return None
        names = ", ".join(sorted(self.held))
        return (f"[launch] {names}: devices closed as the simulated world stopped (normal at the end of a run; "
                f"{sum(self.held.values())} retry line(s) in the run's log file)")


class WorldLogLevels:
    """``--log-level`` for the simulated world's processes: they log at info at least, so
    the launcher sees :data:`SCENE_FINISHED`, and the launcher shows only their lines at
    the level asked for.

    Args:
        spec: the ``--log-level`` text (``"warning,monitor=info"``; empty: info).
        world: the world's process names with the names of the nodes each runs.
    """

    def __init__(self, spec: str, world: dict[str, tuple[str, ...]]) -> None:
        default, per_node = parse_log_levels(spec)
        self.spec = spec
        self._raised = {process: tuple(n for n in nodes if per_node.get(n, default) > logging.INFO)
                        for process, nodes in world.items()}
        self._least = {process: min((per_node.get(n, default) for n in nodes), default=logging.INFO)
                       for process, nodes in world.items()}

    def spec_for(self, process: str) -> str:
        """The level spec ``process`` runs with: the one asked for, its world nodes at info at most."""
        raised = self._raised.get(process, ())
        return ",".join([self.spec, *(f"{node}=info" for node in raised)]) if raised else self.spec

    def shown(self, process: str, line: str) -> bool:
        """Whether ``line`` of ``process`` is at the level asked for (always, for a process not of the world)."""
        return level_of(line) >= self._least.get(process, logging.NOTSET)
