"""Where a report's numbers came from: pkmtol's version and commit, the input files' hashes, seed, command."""

from __future__ import annotations

import hashlib
import platform
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from pkmtol.model.mechanism import Mechanism


@dataclass(frozen=True)
class Provenance:
    """Everything needed to reproduce a report.

    Attributes:
        version: pkmtol's version.
        commit: The git commit of pkmtol's source (``+dirty`` when it has uncommitted changes),
            None when pkmtol is not run from a git checkout.
        robot_commit: The git commit of the robot folder's repository, if it is in one.
        files: ``(path, SHA-256 hex)`` of every input file (``mechanism.toml``, the limb URDFs,
            their meshes), sorted by path.
        seed: The random seed (None when not known).
        command_line: The command that produced the report (None from Python).
        python: Python, numpy, scipy and Pinocchio versions.
    """

    version: str
    commit: str | None
    robot_commit: str | None
    files: tuple[tuple[str, str], ...]
    seed: int | None
    command_line: str | None
    python: str

    def rows(self) -> list[list[str]]:
        """``[what, value]`` rows, one per file hash."""
        out = [
            ["pkmtol", self.version],
            ["pkmtol git commit", self.commit or "none (not a git checkout)"],
            ["robot folder git commit", self.robot_commit or "none (not in a git repository)"],
            ["seed", "not recorded" if self.seed is None else str(self.seed)],
            ["command line", self.command_line or "not recorded (Python API)"],
            ["software", self.python],
        ]
        out += [[f"SHA-256 {path}", digest] for path, digest in self.files]
        return out


def sha256(path: Path) -> str:
    """SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def input_files(mechanism: Mechanism) -> list[Path]:
    """The files a mechanism was read from: ``mechanism.toml``, each limb's URDF, their meshes."""
    files: set[Path] = set()
    if mechanism.root is not None:
        files.add(Path(mechanism.root) / "mechanism.toml")
    for limb in mechanism.limbs:
        if limb.urdf_path is not None:
            files.add(Path(limb.urdf_path))
        visual = limb.visual_model
        for g in getattr(visual, "geometryObjects", []):
            mesh = getattr(g, "meshPath", "")
            if mesh and Path(mesh).is_file():
                files.add(Path(mesh))
    return sorted(p.resolve() for p in files if p.is_file())


def git_commit(folder: Path) -> str | None:
    """``HEAD`` of the git repository holding ``folder`` (``+dirty`` with changes), or None."""
    try:
        head = subprocess.run(
            ["git", "-C", str(folder), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
            stdin=subprocess.DEVNULL,
            check=False,
        )
        if head.returncode != 0:
            return None
        dirty = subprocess.run(
            ["git", "-C", str(folder), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=10,
            stdin=subprocess.DEVNULL,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def _versions() -> str:
    import numpy
    import pinocchio
    import scipy

    return (
        f"Python {platform.python_version()}, numpy {numpy.__version__}, scipy {scipy.__version__}, "
        f"Pinocchio {pinocchio.__version__}"
    )


def provenance(
    mechanism: Mechanism, seed: int | None = None, argv: Sequence[str] | None = None
) -> Provenance:
    """The provenance of a run on ``mechanism`` (``argv``: the command's words, e.g. ``sys.argv``)."""
    files = input_files(mechanism)
    root = Path(mechanism.root).resolve() if mechanism.root is not None else None
    shown = []
    for p in files:
        try:
            name = str(p.relative_to(root)) if root is not None else str(p)
        except ValueError:
            name = str(p)
        shown.append((name, sha256(p)))
    cmd = None
    if argv is not None:
        import shlex

        words = list(argv)
        if words and Path(words[0]).name in ("pkmtol", "__main__.py"):
            words[0] = "pkmtol"
        cmd = shlex.join(words)
    return Provenance(
        version=package_version(),
        commit=git_commit(Path(__file__).resolve().parent),
        robot_commit=None if root is None else git_commit(root),
        files=tuple(shown),
        seed=seed,
        command_line=cmd,
        python=_versions(),
    )


def package_version() -> str:
    """The installed version of pkmtol (``unknown`` when it is not installed)."""
    from importlib import metadata

    try:
        return metadata.version("pkmtol")
    except metadata.PackageNotFoundError:
        return "unknown"


def current_argv() -> list[str]:
    """The running command's words (``sys.argv``)."""
    return list(sys.argv)
