"""The run root and run directories: private to the user, written without following links.

More in docs/modules.md, `nodes/runtime/run_dir.py`.
"""

from __future__ import annotations

import os
import shutil
import stat
import tempfile
from pathlib import Path

from slipstack.lib.errors import ConfigError

__all__ = ["RUN_ROOT_ENV", "CURRENT_LINK", "KEEP_FINISHED_RUNS", "run_root", "make_run_dir", "remove_run_dir",
           "finish_run_dir", "write_private_file", "point_current"]

RUN_ROOT_ENV = "SLIPSTACK_RUN_ROOT"
CURRENT_LINK = "current"
RUN_PREFIX = "run"
FINISHED_MARK = ".finished"
KEEP_FINISHED_RUNS = 20


def _check_private_dir(path: Path) -> None:
    """Raise ConfigError unless ``path`` is a directory owned by this user, mode 0700 or stricter."""
    try:
        st = os.stat(path)
    except OSError as exc:
        raise ConfigError(f"run root {path} cannot be used ({exc.strerror}); remove it, "
                          f"or set ${RUN_ROOT_ENV} to a private directory") from None
    uid = os.getuid()
    link = os.lstat(path)
    problem = None
    if not stat.S_ISDIR(st.st_mode):
        problem = "not a directory"
    elif st.st_uid != uid:
        problem = f"owned by uid {st.st_uid}, not by you (uid {uid})"
    elif link.st_uid != uid:
        problem = f"a symbolic link owned by uid {link.st_uid}, not by you (uid {uid})"
    elif st.st_mode & 0o077:
        problem = f"open to other users (mode {stat.S_IMODE(st.st_mode):04o})"
    if problem:
        fix = f"chmod 700 {path}" if problem.startswith("open") else f"remove {path}"
        raise ConfigError(
            f"run root {path} is {problem}; it must be a directory of yours with mode 0700. "
            f"{fix[0].upper()}{fix[1:]}, or set ${RUN_ROOT_ENV} to a private directory."
        )


def run_root() -> Path:
    """Where run directories live: ``$SLIPSTACK_RUN_ROOT`` or ``/tmp/slipstack-<uid>``.

    Created with mode 0700 if missing.

    Raises:
        ConfigError: it exists but is not a directory owned by this user with mode 0700.
    """
    path = Path(os.environ.get(RUN_ROOT_ENV) or os.path.join(tempfile.gettempdir(), f"slipstack-{os.getuid()}"))
    try:
        path.mkdir(mode=0o700, parents=True)
    except FileExistsError:
        pass
    _check_private_dir(path)
    return path


def make_run_dir() -> Path:
    """A new private (mode 0700) run directory for one launched graph, in :func:`run_root`.

    Finished run directories beyond the newest ``KEEP_FINISHED_RUNS`` are removed.
    """
    root = run_root()
    finished = sorted(root.glob(f"{RUN_PREFIX}-*/{FINISHED_MARK}"), key=lambda p: p.lstat().st_mtime)
    for mark in finished[:-KEEP_FINISHED_RUNS]:
        remove_run_dir(mark.parent)
    return Path(tempfile.mkdtemp(prefix=f"{RUN_PREFIX}-", dir=root))


def remove_run_dir(run_dir: Path) -> None:
    """Delete ``run_dir`` and everything in it (it is ours: made by :func:`make_run_dir`)."""
    shutil.rmtree(run_dir, ignore_errors=True)


def finish_run_dir(run_dir: Path, keep: tuple[str, ...]) -> None:
    """End of a launch: delete everything in ``run_dir`` but the files named in ``keep``; mark it finished."""
    for entry in run_dir.iterdir():
        if entry.name in keep:
            continue
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            entry.unlink(missing_ok=True)
    write_private_file(run_dir, FINISHED_MARK, "")


def write_private_file(directory: Path, name: str, text: str) -> Path:
    """Write ``text`` to ``directory/name`` (mode 0600) atomically, never through a symlink.

    Returns the path written. A symlink or file already at ``name`` is replaced, not
    followed; a directory there raises ``IsADirectoryError``.
    """
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.", dir=directory)  # O_EXCL | O_NOFOLLOW, mode 0600
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, directory / name)
    except BaseException:
        os.unlink(tmp)
        raise
    return directory / name


def point_current(run_dir: Path) -> None:
    """Point ``<run root>/current`` at ``run_dir`` (atomically replacing the old link).

    Raises:
        ConfigError: ``current`` exists and is not a symlink (says what to remove).
    """
    root = run_root()
    link = root / CURRENT_LINK
    if os.path.lexists(link) and not link.is_symlink():
        raise ConfigError(f"{link} is not a symlink to a run directory; remove it (tools use it to find the newest run)")
    tmp_link = root / f".{CURRENT_LINK}-{os.getpid()}"
    if os.path.lexists(tmp_link):
        tmp_link.unlink()
    tmp_link.symlink_to(run_dir)
    os.replace(tmp_link, link)
