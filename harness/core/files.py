"""Writing files whole, and saying which file a write error hit.

    files.write_whole(path, b"...")                        # bytes or str
    files.write_whole(path, lambda f: fig.savefig(f, format="png"))   # a writer of a binary file

The data goes to a temporary file in the same folder (``.NAME.PID.RANDOM.tmp``), then
``os.replace`` puts it at ``path`` in one step: a reader sees the old file or the new one,
never a half-written one. On any error the temporary file is removed and a :class:`WriteError`
names ``path`` (``Errno 28`` alone says nothing about which file). A process killed between
the two steps leaves its ``.tmp`` file: :func:`sweep_temps` removes those of dead processes.
"""

from __future__ import annotations

import errno
import os
import re
import tempfile
from pathlib import Path
from typing import BinaryIO, Callable, Union

PathLike = Union[str, os.PathLike]

_HINTS = {
    errno.ENOSPC: "the disk is full: free space there or choose another output folder",
    errno.EDQUOT: "the disk quota is used up: free space there or choose another output folder",
    errno.EROFS: "the file system is read-only: choose another output folder",
    errno.EACCES: "no permission to write there: choose another output folder or fix its permissions",
    errno.EPERM: "no permission to write there: choose another output folder or fix its permissions",
}


#: The errors of a write that the file system refused (full, read-only, not permitted).
WRITE_ERRNOS = frozenset(_HINTS)


class WriteError(OSError):
    """A file could not be written: ``str()`` names it, the OS reason and what to do;
    ``errno`` and ``filename`` are those of the failed write."""

    def __init__(self, path: PathLike, e: OSError) -> None:
        super().__init__(e.errno or 0, e.strerror or str(e))
        self.filename = str(path)
        hint = _HINTS.get(e.errno or 0)
        self.message = f"cannot write {path}: {e.strerror or e} (errno {e.errno})" + (f"; {hint}" if hint else "")

    def __str__(self) -> str:
        return self.message


def temp_name(path: PathLike) -> str:
    """The prefix of the temporary files :func:`write_whole` uses for ``path``."""
    return f".{Path(path).name}.{os.getpid()}."


def write_whole(path: PathLike, data: Union[bytes, str, Callable[[BinaryIO], None]]) -> Path:
    """Write ``path`` whole: ``data`` (bytes, text as UTF-8, or a function that writes to the
    open binary file it is given) goes to a temporary file beside it, which then replaces
    ``path``. Raises :class:`WriteError` naming ``path``; no temporary file is left."""
    out = Path(path)
    tmp = None
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=temp_name(out), suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            if isinstance(data, str):
                f.write(data.encode("utf-8"))
            elif isinstance(data, (bytes, bytearray, memoryview)):
                f.write(data)
            else:
                data(f)
        os.chmod(tmp, 0o644)  # mkstemp makes 0600; the file is meant to be read like any other
        os.replace(tmp, out)
        tmp = None
    except OSError as e:
        raise WriteError(out, e) from e
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
    return out


_TEMP_RE = re.compile(r"^\..+\.(\d+)\.[A-Za-z0-9_]+\.tmp$")


def pid_alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (ours or not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def orphaned_entries(folder: PathLike, pattern: "re.Pattern[str]") -> list[os.DirEntry]:
    """The entries of ``folder`` (not below) whose name matches ``pattern`` with the pid of a
    process that is gone in its first group, owned by this user: what a killed harness left."""
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return []
    found = []
    for ent in entries:
        m = pattern.fullmatch(ent.name)
        if not m or int(m.group(1)) == os.getpid() or pid_alive(int(m.group(1))):
            continue
        try:
            if ent.stat(follow_symlinks=False).st_uid == os.getuid():
                found.append(ent)
        except OSError:
            pass
    return found


def sweep_temps(folder: PathLike) -> int:
    """Remove the temporary files :func:`write_whole` left in ``folder`` (not below) when its
    process was killed: those of processes that are gone, owned by this user. Returns how many."""
    n = 0
    for ent in orphaned_entries(folder, _TEMP_RE):
        try:
            os.unlink(ent.path)
            n += 1
        except OSError:
            pass
    return n
