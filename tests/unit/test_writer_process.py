"""A recording written by a child process: the same file, bounded, finished whatever the caller does."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from slipstack.messages import Diagnostics, Header, TactileFrame, Wrench, encode
from slipstack.nodes.recording.bag_io import RecordingError, RecordingWriter, read_recording, recording_info
from slipstack.nodes.recording.loss import written_loss
from slipstack.nodes.recording.writer_process import BATCH_BYTES, RecordingWriterProcess

OFFSET = 1_700_000_000_000_000_000


def frames(n: int) -> list[tuple[str, bytes, int]]:
    """n frames on three topics over n ms, diagnostics every 100: several batches and chunks."""
    out = []
    for k in range(n):
        stamp = 5_000_000_000 + k * 1_000_000
        out.append(("ft/wrench", encode(Wrench(force=np.array([0.001 * k, 0.0, 10.0]), torque=np.zeros(3),
                                               device_seq=k, header=Header(stamp, k, stamp + 1000, {}))), stamp))
        if k % 2 == 0:
            out.append(("tactile/frame", encode(TactileFrame(
                pressure_pa=np.full(256, 1000.0 + k, dtype="<f4"), saturated=np.zeros(256, bool),
                dead=np.zeros(256, bool), header=Header(stamp, k // 2, stamp + 2000, {}))), stamp + 1))
        if k % 100 == 0:
            out.append(("diagnostics", encode(Diagnostics(node="relay", counters={"k": k},
                                                          header=Header(stamp, k // 100, stamp, {}))), stamp + 2))
    return out


def test_the_child_writes_the_file_an_in_process_writer_writes_byte_for_byte(tmp_path):
    sent = frames(1500)
    assert sum(len(p) for _, p, _ in sent) > 4 * BATCH_BYTES  # several batches down the pipe
    with RecordingWriter(tmp_path / "here.mcap", wall_minus_monotonic_ns=OFFSET) as here:
        for topic, payload, t in sent:
            here.write(topic, payload, t)
        here.close(written_loss(here))  # the child's record: every frame it was handed is in the file
    with RecordingWriterProcess(tmp_path / "child.mcap", wall_minus_monotonic_ns=OFFSET) as child:
        for topic, payload, t in sent:
            child.write(topic, payload, t)
    assert (tmp_path / "child.mcap").read_bytes() == (tmp_path / "here.mcap").read_bytes()
    assert [(f.topic, f.payload, f.log_time_ns) for f in read_recording(tmp_path / "child.mcap", tolerant=False)] \
        == sent


def test_a_child_that_cannot_write_fails_the_close_with_its_reason_and_the_caller_goes_on(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    writer = RecordingWriterProcess(blocker / "run.mcap")
    for topic, payload, t in frames(1500):  # the caller is never stopped by the failed child
        writer.write(topic, payload, t)
    with pytest.raises(RecordingError, match=r"run\.mcap may be incomplete: its writer failed \(.*Error"):
        writer.close()
    writer.close()  # idempotent: reported once



def test_a_killed_child_fails_the_close_naming_the_signal_and_the_caller_goes_on(tmp_path):
    import signal

    writer = RecordingWriterProcess(tmp_path / "run.mcap")
    os.kill(writer._child.pid, signal.SIGKILL)
    for topic, payload, t in frames(1500):  # several batches into a pipe nobody reads: dropped, not raised
        writer.write(topic, payload, t)
    with pytest.raises(RecordingError, match=r"run\.mcap may be incomplete: its writer was killed by SIGKILL"):
        writer.close()


CALLER = textwrap.dedent("""
    import os, signal, sys
    import numpy as np
    from slipstack.messages import Header, Wrench, encode
    from slipstack.nodes.recording.writer_process import RecordingWriterProcess
    writer = RecordingWriterProcess(sys.argv[1])
    for k in range(4000):
        writer.write("ft/wrench", encode(Wrench(force=np.array([0.0, 0.0, 10.0]), torque=np.zeros(3), device_seq=k,
                                                header=Header(k, k, k, {}))), k)
    if sys.argv[2] == "kill":
        os.kill(os.getpid(), signal.SIGKILL)
    try:  # Ctrl-C in a terminal: the whole foreground process group gets SIGINT
        os.killpg(os.getpgrp(), signal.SIGINT)
        signal.pause()
    except KeyboardInterrupt:
        writer.close()
        print("closed after Ctrl-C")
""")


def wait_for_finished_recording(path, deadline_s: float = 60.0) -> list:
    """The frames of ``path`` once it is a finished recording (the child may still be writing)."""
    t_end = time.monotonic() + deadline_s
    while True:
        try:
            return list(read_recording(path, tolerant=False))
        except (RecordingError, FileNotFoundError):
            if time.monotonic() > t_end:
                raise
            time.sleep(0.1)


def test_a_caller_killed_with_sigkill_leaves_a_finished_recording_of_what_it_had_sent(tmp_path):
    path = tmp_path / "killed.mcap"
    done = subprocess.run([sys.executable, "-c", CALLER, str(path), "kill"], timeout=120)
    assert done.returncode == -9
    got = wait_for_finished_recording(path)
    # every batch sent before the kill is in the file, in order; the caller's unsent buffer is lost
    assert len(got) >= 4000 - BATCH_BYTES // 80
    assert [f.log_time_ns for f in got] == list(range(len(got)))


def test_ctrl_c_reaches_the_caller_not_the_child_and_the_recording_is_complete(tmp_path):
    path = tmp_path / "interrupted.mcap"
    done = subprocess.run([sys.executable, "-c", CALLER, str(path), "ctrl-c"], timeout=120, capture_output=True,
                          text=True, start_new_session=True)  # its own group: the SIGINT stays in there
    assert done.stdout.strip() == "closed after Ctrl-C", done.stderr
    assert [f.log_time_ns for f in read_recording(path, tolerant=False)] == list(range(4000))


INTERRUPTED_WRITE = textwrap.dedent("""
    import os, signal, sys, threading, time
    from slipstack.nodes.recording.bag_io import RecordingError
    from slipstack.nodes.recording.writer_process import RecordingWriterProcess

    writer = RecordingWriterProcess(sys.argv[1])
    os.kill(writer._child.pid, signal.SIGSTOP)  # a stalled disk: the pipe fills and a batch write blocks
    def interrupt_then_resume():
        time.sleep(1.0)
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.5)
        os.kill(writer._child.pid, signal.SIGCONT)
    threading.Thread(target=interrupt_then_resume, daemon=True).start()
    sent = 0
    try:
        for k in range(200_000):
            writer.write("t", k.to_bytes(8, "little") * 100, k)
            sent = k + 1
    except KeyboardInterrupt:
        pass
    try:
        writer.close()
    except RecordingError as exc:
        print(exc, file=sys.stderr)
    print(sent)
""")


def test_ctrl_c_during_a_blocked_write_loses_no_frame_and_repeats_none(tmp_path):
    """Ctrl-C while the caller waits in a write to a full pipe (the child slow): the batch
    in flight may be partly in the pipe, by an unknown count. The recording must be a
    finished file of whole frames, each once and in order, from the first on, and the
    close must say that it ends at the interrupted write."""
    path = tmp_path / "blocked.mcap"
    done = subprocess.run([sys.executable, "-c", INTERRUPTED_WRITE, str(path)], timeout=120,
                          capture_output=True, text=True, start_new_session=True)
    assert done.returncode == 0, done.stderr[-2000:]
    sent = int(done.stdout)
    got = list(read_recording(path, tolerant=False))
    assert [f.log_time_ns for f in got] == list(range(len(got)))
    assert 0 < len(got) <= sent + 1  # the frame being appended when Ctrl-C came may be in too
    assert all(f.payload == f.log_time_ns.to_bytes(8, "little") * 100 for f in got)
    assert "interrupted" in done.stderr and str(path) in done.stderr


def test_a_lock_step_recording_counts_every_frame_it_was_handed(tmp_path):
    """written_loss was taken before the last chunk was written: a short lock-step run's file said
    nothing of its loss (bag info: "missing ?" on every topic, "the recorder did not close the file")."""
    sent = frames(50)  # one chunk
    with RecordingWriterProcess(tmp_path / "child.mcap", wall_minus_monotonic_ns=OFFSET) as child:
        for topic, payload, t in sent:
            child.write(topic, payload, t)
    info = recording_info(tmp_path / "child.mcap")
    assert {t: (i.count, i.missing) for t, i in info.topics.items()} \
        == {t: (sum(s == t for s, _, _ in sent), 0) for t in {s for s, _, _ in sent}}
