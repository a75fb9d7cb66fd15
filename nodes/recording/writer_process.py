"""A recording written by a child process: the caller only hands it encoded frames.

More in docs/modules.md, `nodes/recording/writer_process.py`.
"""

from __future__ import annotations

import argparse
import fcntl
import os
import signal
import struct
import subprocess
import sys
from pathlib import Path
from typing import BinaryIO

from slipstack.lib.errors import SlipstackError

__all__ = ["RecordingWriterProcess", "BATCH_BYTES", "PIPE_BYTES", "main"]

BATCH_BYTES = 256 * 1024
"""Bytes of frames gathered before one write to the child (one pipe write per ~1 000 frames)."""
PIPE_BYTES = 1024 * 1024
"""The pipe's buffer, where Linux allows it (64 KiB by default: a batch would wait for the
child to read three quarters of it, ~5 ms each time in ``fig15 --lockstep``)."""
_RECORD = struct.Struct("<qHI")


class RecordingWriterProcess:
    """Write frames to the MCAP file ``path`` through a child process (see the module docstring).

    Args:
        path: output file; it must not exist (never overwritten).
        wall_minus_monotonic_ns: as :class:`~slipstack.nodes.recording.bag_io.RecordingWriter`'s.
    """

    def __init__(self, path: str | os.PathLike, *, wall_minus_monotonic_ns: int | None = None,
                 fmt: str = "slipstack") -> None:
        self.path = Path(path)
        command = [sys.executable, "-m", __name__, str(self.path), "--format", fmt]
        if wall_minus_monotonic_ns is not None:
            command += ["--wall-minus-monotonic-ns", str(int(wall_minus_monotonic_ns))]
        # a session of its own: Ctrl-C in the terminal reaches the caller only, which then closes the pipe
        self._child = subprocess.Popen(command, stdin=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=0,
                                       start_new_session=True)
        self._pipe: BinaryIO = self._child.stdin  # type: ignore[assignment]
        try:
            fcntl.fcntl(self._pipe.fileno(), fcntl.F_SETPIPE_SZ, PIPE_BYTES)
        except (AttributeError, OSError):  # not Linux, or above /proc/sys/fs/pipe-max-size: the default
            pass
        self._buffer = bytearray()
        self._topics: dict[str, bytes] = {}
        self._broken = False
        self._interrupted = False  # a write was cut short: nothing more is sent (see _send)
        self.closed = False

    def write(self, topic: str, payload: bytes, log_time_ns: int) -> None:
        """Append one frame logged at ``log_time_ns`` (ns, the recording's log clock)."""
        name = self._topics.get(topic)
        if name is None:
            name = self._topics[topic] = topic.encode()
        buffer = self._buffer
        buffer += _RECORD.pack(log_time_ns, len(name), len(payload))
        buffer += name
        buffer += payload
        if len(buffer) >= BATCH_BYTES:
            self._send()

    def _send(self) -> None:
        """Send the buffer down the pipe (a blocking write: it returns once every byte is in).

        A write a signal interrupts (Ctrl-C while the child is slow) may have put part of
        the buffer in the pipe, and how much is unknown (the handler's exception comes
        before the count): nothing more is sent then, as if the caller had been killed, so
        the child keeps every whole frame before the cut and drops the one it splits."""
        if not self._broken and not self._interrupted:
            try:
                self._pipe.write(self._buffer)
            except BrokenPipeError:  # the child failed: close() says why
                self._broken = True
            except BaseException:
                self._interrupted = True
                self._buffer.clear()
                raise
        self._buffer.clear()

    def close(self) -> None:
        """Send what is left, let the child finish the file, and wait for it. Idempotent.

        Raises:
            RecordingError: the child failed; the file may be incomplete (its reason attached).
        """
        if self.closed:
            return
        self.closed = True
        self._send()
        try:
            self._pipe.close()
        except BrokenPipeError:
            self._broken = True
        reason = self._child.stderr.read().decode(errors="replace").strip()  # type: ignore[union-attr]
        self._child.stderr.close()  # type: ignore[union-attr]
        if self._child.wait() != 0 or self._broken or self._interrupted:
            from slipstack.nodes.recording.bag_io import RecordingError

            if self._interrupted:
                raise RecordingError(f"the recording {self.path} ends before the frames its last, interrupted "
                                     "write held (Ctrl-C or another signal while its writer was busy); "
                                     "the frames before are intact")
            code = self._child.returncode
            if code < 0:  # e.g. the OOM killer, or kill -9 on the wrong process
                raise RecordingError(f"the recording {self.path} may be incomplete: its writer was killed by "
                                     f"{signal.Signals(-code).name}; run again to record the whole run")
            raise RecordingError(f"the recording {self.path} may be incomplete: its writer failed "
                                 f"({reason or f'exit code {code}'})")

    def __enter__(self) -> "RecordingWriterProcess":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _copy_frames(source: int, path: Path, wall_minus_monotonic_ns: int | None, fmt: str = "slipstack") -> int:
    """Write every frame read from the descriptor ``source`` until its end to ``path`` (format
    ``fmt``); the frame count. It reads what the pipe holds, up to :data:`PIPE_BYTES` at a time."""
    from slipstack.nodes.recording.bag_io import recording_writer
    from slipstack.nodes.recording.loss import written_loss

    count = 0
    pending = bytearray()
    with recording_writer(path, fmt, wall_minus_monotonic_ns=wall_minus_monotonic_ns) as writer:
        while chunk := os.read(source, PIPE_BYTES):
            pending += chunk
            view, at = memoryview(pending), 0
            while len(pending) - at >= _RECORD.size:
                log_time_ns, topic_len, payload_len = _RECORD.unpack_from(view, at)
                end = at + _RECORD.size + topic_len + payload_len
                if end > len(pending):
                    break
                topic = str(view[at + _RECORD.size:at + _RECORD.size + topic_len], "utf-8")
                writer.write(topic, bytes(view[end - payload_len:end]), log_time_ns)
                count += 1
                at = end
            view.release()
            del pending[:at]
            if writer.error is not None:  # a full disk: the caller's close() says so
                raise writer.error
        writer.close(written_loss(writer))  # every frame of the run was handed over: what misses was not written
    if pending:
        raise ValueError(f"the frames ended inside a frame after {count} frames ({len(pending)} bytes left over)")
    return count


def main(argv: list[str] | None = None) -> int:
    """The child: frames on stdin (the format of the module docstring) into the recording PATH."""
    parser = argparse.ArgumentParser(
        prog="python -m slipstack.nodes.recording.writer_process",
        description="Write the frames arriving on stdin to an MCAP recording (the child of "
                    "RecordingWriterProcess; started by `slipstack launch --lockstep`, not by hand).")
    parser.add_argument("path", type=Path, help="the recording to write (must not exist)")
    parser.add_argument("--wall-minus-monotonic-ns", type=int, default=None,
                        help="the clock metadata to store (ns)")
    parser.add_argument("--format", default="slipstack", choices=("slipstack", "ros2"), help="the recording's layout")
    args = parser.parse_args(argv)
    try:
        _copy_frames(sys.stdin.fileno(), args.path, args.wall_minus_monotonic_ns, args.format)
    except (OSError, ValueError, SlipstackError) as exc:
        print(f"{type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
