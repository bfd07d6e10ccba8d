"""Generate (or check) a robot's limb URDFs from the D–H tables in its mechanism.toml.

Usage:
    python scripts/dh_to_urdf.py robots/r2rps_ups          # write limb URDFs
    python scripts/dh_to_urdf.py robots/r2rps_ups --check  # exit 1 if a URDF differs from its table
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from pathlib import Path

from pkmtol.model.dh import to_urdf
from pkmtol.model.loader import read_dh
from pkmtol.model.reading import TomlReader


def generate(folder: Path) -> dict[Path, str]:
    """URDF text per limb file, from the D–H tables of ``folder/mechanism.toml``."""
    path = folder / "mechanism.toml"
    doc = tomllib.loads(path.read_text(encoding="utf-8"))
    platform = doc.get("platform_link", "platform")
    base = doc.get("base_link", "base")
    out = {}
    for i, ld in enumerate(doc["limbs"]):
        if "dh" not in ld:
            continue
        table = read_dh(TomlReader(path, ld, prefix=f"limbs[{i}]."))
        out[folder / ld["urdf"]] = to_urdf(table, ld["name"], base, platform, ld["name"])
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("robot", type=Path, help="robot folder holding mechanism.toml")
    ap.add_argument("--check", action="store_true", help="compare instead of writing")
    args = ap.parse_args(argv)
    stale = []
    for path, text in generate(args.robot).items():
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
