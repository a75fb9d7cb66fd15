"""The RDT link takes only the sensor's stream: other senders never reach it, and
datagrams from the sensor's address whose counters do not continue the requested
stream (stray, stale, forged) are dropped and counted. Real loopback UDP against
the device emulator, on a simulated clock."""

from __future__ import annotations

import select
import socket

import numpy as np

from slipstack.lib.protocols import ati_rdt
from slipstack.nodes.devices import LinkStatus
from slipstack.nodes.devices.backends import backend_from_url
from slipstack.nodes.devices.emulators import RdtUdpServer

MS = 1_000_000


class _Stream:
    """An emulated sensor streaming 1 kHz to a back-end; ``tick`` sends one record
    and polls the back-end once the datagram is readable."""

    def __init__(self) -> None:
        self.server = RdtUdpServer()
        self.backend = backend_from_url(f"{self.server.url}?rate_hz=1000")
        self.now = 1_000 * MS
        self.samples: list = []
        self.backend.open(self.now)

    def tick(self, send: bool = True) -> list:
        self.now += MS
        if send:
            self.server.send_ft([1.0, 2.0, 3.0], [0.0, 0.0, 0.5])
        fd = self.backend.fileno()
        select.select([fd], [], [], 0.05)
        got = self.backend.poll(self.now)
        self.samples += got
        return got

    def client_address(self) -> tuple[str, int]:
        return self.backend._link._handle.getsockname()

    def close(self) -> None:
        self.backend.close()
        self.server.close()


def test_random_36_byte_datagrams_from_the_sensor_s_address_are_not_samples():
    s = _Stream()
    try:
        while len(s.samples) < 5:
            s.tick()
        rng = np.random.default_rng(7)
        for _ in range(200):  # forged from the sensor's own socket: only the content can tell
            s.server._sock.sendto(rng.bytes(36), s.client_address())
        s.tick(send=False)
        s.tick(send=False)
        assert len(s.samples) == 5, [x.force_n for x in s.samples[5:]]
        assert s.backend.counters["implausible_records"] == 200
        n = len(s.samples)
        while len(s.samples) < n + 5:  # the real stream goes on
            s.tick()
        assert [x.device_seq for x in s.samples] == list(range(1, len(s.samples) + 1))
        assert s.backend.status is LinkStatus.OK
    finally:
        s.close()


def test_datagrams_from_any_other_address_never_reach_the_link():
    s = _Stream()
    stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        while len(s.samples) < 3:
            s.tick()
        next_seq = s.samples[-1].device_seq + 1
        forged = ati_rdt.encode_record(next_seq, s.server.ft_sequence + 1, 0, [9e6] * 6)  # plausible counters
        for _ in range(50):
            stranger.sendto(forged, s.client_address())
        s.tick(send=False)
        s.tick(send=False)
        assert len(s.samples) == 3
        while len(s.samples) < 6:
            s.tick()
        assert all(np.allclose(x.force_n, [1.0, 2.0, 3.0]) for x in s.samples)
    finally:
        stranger.close()
        s.close()


def test_a_stream_restarted_by_a_new_request_is_taken_and_stale_records_of_the_old_one_are_not():
    s = _Stream()
    try:
        while len(s.samples) < 5:
            s.tick()
        old = ati_rdt.encode_record(3, 1, 0, [0] * 6)  # a late record of the first stream
        s.server._sock.sendto(old, s.client_address())
        s.tick(send=False)
        assert s.backend.counters["implausible_records"] == 1
        for _ in range(60):  # silence: the back-end requests the stream again, it restarts at 1
            s.tick(send=False)
        while len(s.samples) < 8:
            s.tick()
        assert s.samples[5].device_seq == 1
        assert s.backend.counters["requests"] >= 2
    finally:
        s.close()


def test_random_records_almost_never_pass_the_stream_check():
    rng = np.random.default_rng(11)
    previous = ati_rdt.decode_records(ati_rdt.encode_record(5000, 123_456, 0, [0] * 6))[0]
    records = ati_rdt.decode_records(rng.bytes(36 * 200_000))
    accepted = sum(ati_rdt.follows(previous, r) for r in records) + sum(ati_rdt.follows(None, r) for r in records)
    assert accepted <= 2  # expected: about 0.003 of each kind in 200 000 (a chance of 2**-26 per record)
