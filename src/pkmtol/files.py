"""Output files are written whole or not at all."""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from pkmtol.exceptions import OutputError


def stage(path: Path | str, data: bytes) -> str:
    """Write ``data`` to a new temporary file beside ``path`` and return its name (the caller renames it).

    The temporary file gets the permissions an ordinary new file would get (``0666 & ~umask``;
    ``mkstemp`` creates 0600).

    Raises:
        OutputError: the folder is missing or not writable (the temporary file is removed).
    """
    path = Path(path)
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
        os.replace(tmp, path)
    except OSError as err:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise OutputError(path, f"{err.strerror or err}; choose another output location") from err
