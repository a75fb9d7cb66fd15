"""A command's output file, claimed before the work that fills it: made at once, never
overwritten unless asked, or refused with what to do; removed again if the work fails.
Its folder is made if that folder's parent exists, never a whole tree (a typo's)."""

from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from slipstack.lib.errors import ConfigError

__all__ = ["claim_output", "output_file", "writable_folder", "why_unwritable"]


def claim_output(path: Path, *, what: str = "the output", change: str = "choose another -o path",
                 force: bool = False, force_option: str | None = "--overwrite") -> None:
    """Create the empty file ``path`` (and its folder, one level), so that a path that cannot be
    written fails before the work, not after it.

    Args:
        what: how the message names the file (``the recording``).
        change: how to name another path (``pass recording:=NEW.mcap``).
        force: replace an existing file (never a folder, and a link is replaced, not followed).
        force_option: the option that sets ``force``, offered when the file exists (``None``: none).

    Raises:
        ConfigError: ``path`` exists (and not ``force``) or cannot be written; says what to do.
    """
    try:
        path.parent.mkdir(exist_ok=True)
        if force and (path.is_symlink() or path.is_file()):
            path.unlink()
        open(path, "xb").close()
    except OSError as exc:
        if os.path.lexists(path):
            instead = f", or {force_option} to overwrite it" if force_option and not path.is_dir() else " or delete it"
            raise ConfigError(f"{what} {path} exists; {change}{instead}") from None
        if not os.path.lexists(path.parent.parent):
            raise ConfigError(f"the folder {path.parent.parent} of {what} {path} does not exist; create it "
                              f"(mkdir -p) or {change} in a folder that does") from None
        raise ConfigError(f"cannot write {what} {path} ({why_unwritable(path, exc)}); {change} in a folder you may "
                          "write") from None


@contextmanager
def output_file(path: Path, **claim: object) -> Iterator[Path]:
    """:func:`claim_output` ``path`` for the block, which writes it; if the block fails, the
    file is removed again (no half-written output is left behind)."""
    claim_output(path, **claim)  # type: ignore[arg-type]
    try:
        yield path
    except BaseException:
        path.unlink(missing_ok=True)
        raise


def why_unwritable(path: Path, exc: OSError) -> str:
    """Why ``path`` cannot be written, in words (a file where a folder should be, not "File exists";
    a missing folder above the one level that is made, not "No such file or directory")."""
    below = path
    for folder in path.parents:
        if os.path.lexists(folder):
            if not folder.is_dir():
                return f"{folder} is a file, not a folder"
            return exc.strerror if below in (path, path.parent) else f"the folder {below} does not exist"
        below = folder
    return exc.strerror


def writable_folder(folder: Path, option: str) -> None:
    """Make ``folder`` (one level) and prove it writable, before the work that fills it.

    Raises:
        ConfigError: it cannot be made or written; says what to do.
    """
    try:
        folder.mkdir(exist_ok=True)
        probe = folder / f".slipstack-write-test-{os.getpid()}"
        open(probe, "xb").close()
        probe.unlink()
    except OSError as exc:
        raise ConfigError(f"cannot write into {folder} ({why_unwritable(folder / 'x', exc)}); choose an {option} folder "
                          "you may write") from None
