"""Contact frames written before version 3 (no ``earlier_*``: recordings made before
every F/T sample was examined) read as contacts without earlier samples; a version this
slipstack cannot read is refused with a message that says which versions it reads."""

from __future__ import annotations

import json

import numpy as np
import pytest

from slipstack.lib.errors import DecodeError
from slipstack.messages import Contact, Header, decode
from slipstack.messages.frame import pack_frame
from slipstack.nodes.recording.bag_io import RecordingWriter
from slipstack.nodes.recording.export import export_recording

_V2_FIELDS = ("rows", "cols", "pitch_m", "phi", "f_n", "f_t", "tau", "cop", "area_m2", "mask", "pair_offset_ns",
              "has_tactile", "status", "tactile_status")
"""The body of a version 2 contact, as b737fcd wrote it."""


def _contact() -> Contact:
    phi = np.zeros(4)
    phi[1] = 2.5
    return Contact(rows=2, cols=2, pitch_m=1e-3, phi=phi, f_n=2.5, f_t=np.array([0.3, -0.1]), tau=1e-3,
                   cop=np.array([1e-3, 0.0]), area_m2=1e-6, mask=phi > 0, pair_offset_ns=-4000, has_tactile=True,
                   status="ok", tactile_status="ok", header=Header(7_000_000, 3, 7_000_100, {"ft": 7_000_000}))


def _frame(version: int, c: Contact) -> bytes:
    return pack_frame(Contact.TYPE, version, c.header, [getattr(c, n) for n in _V2_FIELDS])


def test_a_version_2_contact_reads_as_one_without_earlier_samples():
    c = _contact()
    got = decode(_frame(2, c), Contact)
    assert got.earlier_samples == 0 and got.earlier_stamp_ns.size == 0 and got.earlier_status.size == 0
    assert got.earlier_f_n.dtype == np.float64 and got.earlier_status.dtype == np.uint8
    assert got.header == c.header and got.f_n == 2.5 and got.phi.tolist() == c.phi.tolist()
    assert got.status == "ok" and got.tactile_status == "ok" and got.pair_offset_ns == -4000


def test_a_version_2_contact_still_needs_every_field_it_wrote():
    c = _contact()
    short = pack_frame(Contact.TYPE, 2, c.header, [getattr(c, n) for n in _V2_FIELDS[:-1]])
    with pytest.raises(DecodeError, match="tactile_status: missing"):
        decode(short, Contact)


@pytest.mark.parametrize("version", [1, 4, "3"])
def test_a_version_it_cannot_read_is_refused_naming_the_versions_it_reads(version):
    with pytest.raises(DecodeError, match=r"version: expected 3 \(or 2\)"):
        decode(_frame(version, _contact()), Contact)


def test_an_export_of_an_old_recording_keeps_its_contacts(tmp_path):
    """b737fcd's recordings hold version 2 contacts: `bag export` used to drop every one silently."""
    bag = tmp_path / "v2.mcap"
    c = _contact()
    with RecordingWriter(bag) as w:
        for k in range(5):
            w.write("contact", _frame(2, c), 1_000_000 * k)
    out = tmp_path / "v2.jsonl"
    assert export_recording(bag, out, fmt="jsonl") == 5
    lines = [json.loads(line) for line in out.read_text().splitlines()]
    assert [line["topic"] for line in lines] == ["contact"] * 5
    assert lines[0]["message"]["earlier_samples"] == 0 and lines[0]["message"]["f_n"] == 2.5
