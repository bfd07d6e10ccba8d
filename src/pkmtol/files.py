"""Output files are written whole or not at all.

A destination that is a symbolic link is written through: the file it points to is replaced
whole and the link stays. A destination that exists but is not a regular file (a device such as
``/dev/null``, a FIFO, a socket, a folder) is refused with :class:`OutputError`: an atomic write
would replace it by a regular file (as root, ``/dev/null`` became a 7 kB file), and a write into
it could not be whole or not at all (docs/outputs.md).
"""

from __future__ import annotations

import contextlib
import os
import signal
import stat
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

from pkmtol.exceptions import OutputError


def destination(path: Path | str) -> Path:
    """The file a write to ``path`` replaces: ``path``, or the target of the symbolic link it is.

    Raises:
        OutputError: it exists and is not a regular file (device, FIFO, socket, folder).
    """
    path = Path(path)
    real = Path(os.path.realpath(path)) if path.is_symlink() else path
    try:
        mode = os.stat(real).st_mode
    except FileNotFoundError:
        return real
    except OSError as err:
        raise OutputError(path, f"{err.strerror or err}; choose another output location") from err
    if not stat.S_ISREG(mode):
        what = "a folder" if stat.S_ISDIR(mode) else "a device, FIFO or socket, not a regular file"
        raise OutputError(
            path, f"is {what}; pkmtol writes whole regular files only — give a file path (docs/outputs.md)"
        )
    return real


def stage(path: Path | str, data: bytes) -> str:
    """Write ``data`` to a new temporary file beside ``path`` and return its name (the caller renames it).

    The temporary file gets the permissions an ordinary new file would get (``0666 & ~umask``;
    ``mkstemp`` creates 0600).

    Raises:
        OutputError: the folder is missing or not writable (the temporary file is removed).
    """
    path = destination(path)
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        return tmp
    except OSError as err:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        raise OutputError(path, f"{err.strerror or err}; choose another output location") from err


_COMMITS = [0]


def commits() -> int:
    """How many files this process has renamed into place (for "nothing was written" on Ctrl-C)."""
    return _COMMITS[0]


def replace(tmp: str, path: Path | str) -> None:
    """``os.replace(tmp, destination(path))``, counted by :func:`commits`."""
    os.replace(tmp, destination(path))
    _COMMITS[0] += 1


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM while a run's files are renamed into place; they arrive afterwards.

    A Ctrl-C then stops the run before its first file or after its last one, never between two
    (POSIX main thread; elsewhere nothing changes).
    """
    held = (signal.SIGINT, signal.SIGTERM)
    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def write_atomic(path: Path | str, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder, renamed over it.

    The file is either the old one, or the complete new one — never a partial write. It gets the
    permissions an ordinary new file would get (``0666 & ~umask``).

    Raises:
        OutputError: the folder is missing or not writable (the temporary file is removed).
    """
    path = Path(path)
    tmp = stage(path, data)
    try:
        with signals_deferred():
            replace(tmp, path)
    except OSError as err:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise OutputError(path, f"{err.strerror or err}; choose another output location") from err
