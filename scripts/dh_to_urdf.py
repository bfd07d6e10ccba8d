"""Generate (or check) a robot's limb URDFs from the D–H tables in its mechanism.toml.

A thin wrapper over :func:`pkmtol.model.robot_files.urdfs_from_toml`.

Usage:
    python scripts/dh_to_urdf.py robots/r2rps_ups          # write limb URDFs
    python scripts/dh_to_urdf.py robots/r2rps_ups --check  # exit 1 if a URDF differs from its table
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pkmtol.exceptions import PkmtolError
from pkmtol.model.robot_files import urdfs_from_toml


def generate(folder: Path) -> dict[Path, str]:
    """URDF text per limb file, from the D–H tables of ``folder/mechanism.toml``."""
    return urdfs_from_toml(folder)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("robot", type=Path, help="robot folder holding mechanism.toml")
    ap.add_argument("--check", action="store_true", help="compare instead of writing")
    args = ap.parse_args(argv)
    try:
        urdfs = generate(args.robot)
    except PkmtolError as err:
        print(f"dh_to_urdf: error: {err}", file=sys.stderr)
        return 2
    stale = []
    for path, text in urdfs.items():
        if args.check:
            if not path.is_file() or path.read_text(encoding="utf-8") != text:
                stale.append(path)
        else:
            tmp = path.with_suffix(".urdf.tmp")
            tmp.write_text(text, encoding="utf-8")
            tmp.replace(path)
            print(f"wrote {path}")
    if stale:
        print("out of date with mechanism.toml: " + ", ".join(map(str, stale)), file=sys.stderr)
        print(f"regenerate with: python scripts/dh_to_urdf.py {args.robot}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
