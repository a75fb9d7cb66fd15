"""The run's log file: every line the launcher prints, kept beside the recording.

``runs/<stamp>.mcap`` gets ``runs/<stamp>.log`` (the recorder's path with ``.log``), so
the log outlives the run directory, which is removed at the end. Each line is written
with its wall-clock time; lines held back from the terminal (a quiet normal shutdown,
``launch/quiet_shutdown.py``) are written too, marked ``(not shown)``. The file is
bounded: past :data:`MAX_LOG_BYTES` it says so once and takes no more lines. A write
that fails (a full disk) never stops the launch: the terminal says so once and gets
every later line alone.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

from slipstack.launch.launch_file import LaunchFile
from slipstack.lib.errors import ConfigError
from slipstack.lib.output_file import why_unwritable

__all__ = ["RunLog", "log_path_for", "MAX_LOG_BYTES"]

MAX_LOG_BYTES = 64 * 1024 * 1024


def log_path_for(launch: LaunchFile) -> Path | None:
    """Where the run's log goes: beside the recording of the launch's recorder node, with
    the suffix ``.log``; ``None`` when the launch records nothing."""
    for entry in launch.nodes:
        if entry.type == "recorder" and entry.params.get("path"):
            return Path(str(entry.params["path"])).with_suffix(".log")
    return None


class RunLog:
    """``echo`` that also appends each line to ``path`` (``None``: the terminal only)."""

    def __init__(self, echo: Callable[[str], None], path: Path | None) -> None:
        self.echo = echo
        self.path = path
        self._fh = None
        self._written = 0
        if path is not None:
            try:
                path.parent.mkdir(exist_ok=True)  # runs/ beside the recording, never a whole tree
                self._fh = open(path, "a", encoding="utf-8", errors="replace")
            except OSError as exc:
                raise ConfigError(f"cannot write the run's log {path} ({why_unwritable(path, exc)}): it goes beside the "
                                  "recording, in a folder that exists and you may write; pass recording:=PATH "
                                  "(or --log-file PATH) there") from None

    def __call__(self, line: str) -> None:
        self.echo(line)
        self._write(line)

    def held(self, line: str) -> None:
        """A line kept from the terminal: into the file only."""
        self._write(f"{line} (not shown)")

    def _write(self, line: str) -> None:
        if self._fh is None or self._written > MAX_LOG_BYTES:
            return
        now = time.time()
        text = f"{time.strftime('%Y-%m-%dT%H:%M:%S', time.localtime(now))}.{int(now % 1 * 1000):03d} {line}\n"
        self._written += len(text)
        if self._written > MAX_LOG_BYTES:
            text = f"[launch] log file full ({MAX_LOG_BYTES} bytes): later lines are on the terminal only\n"
        try:
            self._fh.write(text)
            self._fh.flush()
        except OSError as exc:  # the disk is full: the launch goes on, the terminal keeps the lines
            self.close()
            self.echo(f"[launch] WARNING: cannot write the run's log {self.path} ({exc.strerror}); "
                      "later lines are on the terminal only")

    def close(self) -> None:
        fh, self._fh = self._fh, None
        if fh is not None:
            try:
                fh.close()
            except OSError:  # its last flush failed (a full disk): said where the write failed
                pass
