"""An output folder holds one whole run: one writer at a time, written all or nothing, with a manifest.

:class:`RunFolder` is what ``pkmtol allocate --out`` and
:func:`~pkmtol.present.tables.write_outputs` write through:

* **one writer**: entering it takes an exclusive, non-blocking ``flock`` on the folder (released
  when the process ends, even if it is killed); a second run into the same folder is refused with
  :class:`~pkmtol.exceptions.OutputLockedError` before it computes anything;
* **all or nothing**: :meth:`RunFolder.write` is given every file already rendered in memory; it
  first writes each to a temporary file beside its destination, and only when all are written
  renames them into place. If any write fails, the temporary files are removed and the folder
  is as it was;
* **no mixed runs**: the files of the previous run that this run does not write again are removed
  — those its manifest lists, and nothing else: a file no manifest says pkmtol wrote (a user's
  own ``tolerances.pdf``) is left alone, even under one of pkmtol's names; a run that writes
  a file of that name replaces it;
* **no clobbering within a run**: a file outside the folder (``--html``, ``--report``,
  ``--plan``) that is one of the run's own files, or another outside file, is refused before
  anything is written;
* **a manifest**: :data:`MANIFEST` (JSON) lists the files of the run, written last. A folder
  without it (or whose manifest lists a file that is missing) holds no complete run.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Mapping
from pathlib import Path
from types import TracebackType
from typing import Any

from pkmtol.exceptions import OutputError, OutputLockedError
from pkmtol.files import replace, signals_deferred, stage, write_atomic

#: The manifest of a run: ``{"pkmtol_run": 1, "files": [...], "outside": [...]}``.
MANIFEST = "pkmtol-run.json"
#: Files a pkmtol run may write into its folder (removed when a new run does not write them).
RUN_FILES = tuple(
    [f"allocation.{ext}" for ext in ("json", "csv", "md")]
    + [
        f"{stem}.{fmt}"
        for stem in ("sensitivity", "dlambda_histogram", "tolerances")
        for fmt in ("png", "svg", "pdf")
    ]
)


class RunFolder:
    """The output folder of one run, held exclusively while the run computes and writes.

    Args:
        path: The folder (created if missing).

    Raises:
        OutputError: the folder cannot be created or is not writable.
        OutputLockedError: another process holds it.
    """

    def __init__(self, path: Path | str) -> None:
        self.path = Path(path)
        self._fd: int | None = None

    def __enter__(self) -> RunFolder:
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise OutputError(self.path, f"{err.strerror or err}; choose another --out folder") from err
        if not os.access(self.path, os.W_OK):
            raise OutputError(self.path, "folder is not writable; choose another --out folder")
        self._fd = _lock(self.path)
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, tb: TracebackType | None
    ) -> None:
        if self._fd is not None:
            os.close(self._fd)  # releases the lock
            self._fd = None

    def write(self, files: Mapping[str, bytes], outside: Mapping[Path, bytes] | None = None) -> list[Path]:
        """Write the run: ``files`` (name → bytes) into the folder, ``outside`` (path → bytes) elsewhere.

        Returns:
            The paths written, in the order given (folder files first).

        Raises:
            OutputError: a file cannot be written; nothing has changed then.
        """
        for name in files:
            if Path(name).name != name or name in (MANIFEST, "", ".", ".."):
                raise OutputError(self.path / name, "a run file must be a plain file name in the folder")
        targets = [(self.path / name, data) for name, data in files.items()]
        targets += [(Path(p), data) for p, data in (outside or {}).items()]
        check_distinct([self.path / MANIFEST] + [path for path, _ in targets])
        staged: list[tuple[Path, str]] = []
        try:
            for path, data in targets:
                staged.append((path, stage(path, data)))
        except OutputError:
            for _, tmp in staged:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
            raise
        previous = self._previous_files()
        manifest = {
            "pkmtol_run": 1,
            "files": list(files),
            "outside": [str(Path(p)) for p in (outside or {})],
        }
        with signals_deferred():  # a Ctrl-C lands before the first rename or after the manifest
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.path / MANIFEST)  # from here until the new manifest: no complete run
            for path, tmp in staged:
                replace(tmp, path)
            for name in sorted(previous - set(files)):
                with contextlib.suppress(OSError):
                    (self.path / name).unlink()
            write_atomic(self.path / MANIFEST, (json.dumps(manifest, indent=2) + "\n").encode())
        return [path for path, _ in targets]

    def _previous_files(self) -> set[str]:
        """The run files of the folder's previous run: those its manifest lists (issue 25: only those)."""
        names: set[str] = set()
        try:
            doc: Any = json.loads((self.path / MANIFEST).read_text(encoding="utf-8"))
            listed = doc.get("files", []) if isinstance(doc, dict) else []
        except (OSError, ValueError):
            listed = []
        for name in listed:
            if isinstance(name, str) and Path(name).name == name and name not in ("", ".", "..", MANIFEST):
                names.add(name)
        return names


def check_distinct(paths: list[Path]) -> None:
    """Refuse two outputs of one run that are the same file (``--html`` at ``allocation.json``).

    Raises:
        OutputError: names both, before anything is written.
    """
    seen: dict[str, Path] = {}
    for path in paths:
        key = os.path.realpath(path)
        if key in seen:
            other = seen[key]
            raise OutputError(
                path, f"is also {other} of the same run: one would overwrite the other; give another path"
            )
        seen[key] = path


def _lock(folder: Path) -> int:
    """An exclusive lock on ``folder`` (a file descriptor to close to release it)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no locking
        return os.open(folder, os.O_RDONLY)
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as err:
        os.close(fd)
        raise OutputLockedError(folder, None) from err
    return fd
