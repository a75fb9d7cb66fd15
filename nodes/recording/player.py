"""The player: publish a recording on the bus with its original timing.

More in docs/modules.md, `nodes/recording/player.py`.
"""

from __future__ import annotations

import bisect
import sys
from dataclasses import dataclass, field
from typing import Callable


from slipstack.lib.errors import ConfigError
from slipstack.messages import registry
from slipstack.messages.frame import peek_header, publisher_key, restamp
from slipstack.nodes.recording.bag_io import RecordedFrame, clock_offset_ns, read_recording
from slipstack.nodes.runtime.graph_info import INJECTION_REFUSED, find_run_dir, read_graph, time_base_clock
from slipstack.nodes.runtime.host import DIAGNOSTICS_TOPIC
from slipstack.nodes.runtime.node import Context, Node, Output
from slipstack.nodes.runtime.process import ProcessExecutor, RunSpec
from slipstack.nodes.runtime.tool_pub import BusPublisher, InjectionSender, tool_name

__all__ = ["Playback", "Player", "PlayerParams", "load_frames", "play"]


def load_frames(path: str, topics: list[str] | None = None, start_offset_s: float = 0.0) -> list[RecordedFrame]:
    """The frames to play: ``topics`` only (``None``/empty: all but ``diagnostics`` — every
    live node publishes its own), from ``start_offset_s`` seconds after the recording's
    first frame.

    Raises:
        ConfigError: nothing left to play.
    """
    frames = list(read_recording(path, topics or None))
    if not topics:
        frames = [f for f in frames if f.topic != DIAGNOSTICS_TOPIC]
    if frames and start_offset_s > 0:
        t0 = frames[0].log_time_ns + round(start_offset_s * 1e9)
        frames = frames[bisect.bisect_left([f.log_time_ns for f in frames], t0):]
    if not frames:
        raise ConfigError(f"{path}: no frames to play (topics {topics or 'all'}, start offset {start_offset_s} s)")
    return frames


class Playback:
    """Which frames are due when, for a player whose clock reads ``now_ns``.

    Args:
        frames: in receive order.
        rate: playback speed (2.0 plays twice as fast).
        loop: start over after the last frame.
        restamp_offset_ns: ``None`` keeps the recorded headers; otherwise the
            recording's wall − monotonic offset (:func:`clock_offset_ns`), used to
            shift stamps so the first frame is stamped "now" (module docstring).
    """

    def __init__(self, frames: list[RecordedFrame], rate: float = 1.0, loop: bool = False,
                 restamp_offset_ns: int | None = None) -> None:
        if not rate > 0:
            raise ConfigError(f"playback rate must be > 0, got {rate}")
        self.frames = frames
        self.rate = rate
        self.loop = loop
        self._restamp_offset = restamp_offset_ns
        self._t_rec0 = frames[0].log_time_ns
        self._start_ns: int | None = None
        self._delta = 0
        self._i = 0
        self.passes = 0
        self.sent = 0

    @property
    def done(self) -> bool:
        return self._i >= len(self.frames) and not self.loop

    def _begin(self, now_ns: int) -> None:
        self._start_ns = now_ns
        self._i = 0
        if self._restamp_offset is not None:
            self._delta = now_ns - (self._t_rec0 - self._restamp_offset)

    def next_due_ns(self) -> int | None:
        """When the next frame is due on the player's clock (``None`` before start or when done)."""
        if self._start_ns is None or self._i >= len(self.frames):
            return None
        return self._start_ns + round((self.frames[self._i].log_time_ns - self._t_rec0) / self.rate)

    def due(self, now_ns: int) -> list[tuple[str, bytes]]:
        """``(topic, payload)`` of every frame due at ``now_ns``; the first call starts playback."""
        if self._start_ns is None:
            self._begin(now_ns)
        out = []
        while True:
            if self._i >= len(self.frames):
                if not self.loop:
                    break
                self.passes += 1
                self._begin(now_ns)
            t = self.next_due_ns()
            if t is None or t > now_ns:
                break
            f = self.frames[self._i]
            payload = f.payload if self._restamp_offset is None else restamp(f.payload, self._delta)
            out.append((f.topic, payload))
            self._i += 1
        self.sent += len(out)
        return out


# -- the launch-file node ---------------------------------------------------------------

@dataclass(frozen=True)
class PlayerParams:
    path: str = field(default="", metadata={"help": "recording (.mcap) to play"})
    topics: list[str] = field(default_factory=list, metadata={"help": "topics to play; empty: all but diagnostics"})
    rate: float = field(default=1.0, metadata={"help": "playback speed factor"})
    loop: bool = field(default=False, metadata={"help": "start over at the end"})
    restamp: bool = field(default=False, metadata={"help": "shift header stamps to the player's clock"})
    start_offset_s: float = field(default=0.0, metadata={"help": "skip this much of the start (s)"})


class Player(Node):
    """Plays a recording on the bus; its outputs are the recording's topics."""

    name = "player"
    timers = {"tick": 0.001}
    Params = PlayerParams

    def __init__(self, params: PlayerParams | None = None, *,
                 send: Callable[[str, bytes], None] | None = None) -> None:
        """``send(topic, payload)``, if given, takes every due frame in place of the
        node's outputs, and the node stops after the last one (``bag play`` sends on its
        own endpoint and into the running nodes). Restamped frames land on the
        executor's clock: the graph's time base (``bag play`` gives its executor the
        graph's, nodes/runtime/time_base.py)."""
        super().__init__(params)
        p = self.params
        if not p.path:
            raise ConfigError("player: parameter path (the recording to play) is required")
        frames = load_frames(p.path, list(p.topics), p.start_offset_s)
        self.types: dict[str, str] = {}
        """Played topic → message type name (``""`` for a frame without a readable header)."""
        for f in frames:
            if f.topic not in self.types:
                head = peek_header(f.payload)
                self.types[f.topic] = head.type_name if head else ""
        self.outputs = {t: Output(t, registry[name]) for t, name in self.types.items() if name in registry}
        offset = clock_offset_ns(p.path, frames) if p.restamp else None
        self.playback = Playback(frames, p.rate, p.loop, offset)
        self._send = send

    def on_timer_tick(self, ctx: Context) -> None:
        send = self._send or ctx.publish_raw
        for topic, payload in self.playback.due(ctx.now_ns()):
            send(topic, payload)
        if self.playback.done:
            ctx.set_status("done", f"{self.playback.sent} frames played")
            if self._send is not None:
                ctx.shutdown()


# -- the command line -------------------------------------------------------------------

def play(
    path: str,
    *,
    topics: list[str] | None = None,
    rate: float = 1.0,
    loop: bool = False,
    start_offset_s: float = 0.0,
    restamp_stamps: bool = False,
    endpoint: str | None = None,
    run_dir: str | None = None,
    wait_s: float = 2.0,
    echo: Callable[[str], None] = lambda s: print(s, file=sys.stderr, flush=True),
) -> int:
    """``slipstack bag play``: run a :class:`Player` until done or SIGINT/SIGTERM; returns
    frames sent.

    Publishes on ``endpoint`` (default ``ipc://<run dir>/bag_play-<pid>.pub``, registered in
    the run directory) and injects into every running node that subscribes to a played
    topic; playback starts once they and the graph's recorders have subscribed (or after
    ``wait_s`` each).

    Raises:
        ConfigError: neither ``endpoint`` nor a running graph.
    """
    def send(topic: str, payload: bytes) -> None:
        bus.send(topic, payload)
        injector.send(topic, payload, publisher_key(topic, payload, peek_header(payload)))

    rd = None
    try:
        rd = find_run_dir(run_dir)
    except ConfigError:
        if endpoint is None:
            raise
    graph = read_graph(rd) if rd is not None else {"nodes": {}}
    graph_nodes: dict = graph["nodes"]
    player = Player(PlayerParams(path=path, topics=list(topics or []), rate=rate, loop=loop, restamp=restamp_stamps,
                                 start_offset_s=start_offset_s), send=send)
    played = set(player.types)
    injects: list[tuple[str, str]] = []
    refused: set[str] = set()
    if rd is not None:
        for node in graph_nodes.values():
            injects += [(t, ep) for t, ep in node.get("inject", {}).items() if t in played]
            refused |= {t for t, kind in node.get("inputs", {}).items()
                        if t in played and kind in INJECTION_REFUSED and t not in node.get("inject", {})}
    name = tool_name("bag_play")  # one endpoint per player: ipc binds steal
    bus = BusPublisher(rd, name, player.types, endpoint=endpoint, sndhwm=100_000)
    injector = InjectionSender([ep for _, ep in injects], name, sndhwm=100_000)  # one per node, whatever its topics
    try:
        want: dict[str, int] = {}
        for topic, _ in set(injects):  # the nodes of another machine share its launcher's address
            want[topic] = want.get(topic, 0) + 1
        injector.wait_for_subscriptions(want, wait_s)
        bus.wait_for_recorders(sum(1 for n in graph_nodes.values() if n.get("type") == "recorder"), wait_s)
        echo(f"playing {path}: {len(player.playback.frames)} frames on {', '.join(sorted(played))} at {rate:g}x "
             f"from {bus.endpoint}, into {len(injects)} subscriber(s)")
        if refused:
            echo(f"not into the graph's nodes: {', '.join(sorted(refused))} (only its own nodes publish them; a launch "
                 f"file allows it with allow_inject under [launch]); on the bus for echo and recorders only")
        ProcessExecutor([(player, RunSpec(name=name))], clock=time_base_clock(graph)).run()  # restamps on the graph's
        echo(f"played {player.playback.sent} frames ({player.playback.passes} loops)")
        return player.playback.sent
    finally:
        injector.close()
        bus.close()
