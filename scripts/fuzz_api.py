"""Fuzz the Python API: every public callable with one bad argument at a time (tests/api_fuzzing.py).

    python scripts/fuzz_api.py                       # every case, seed 0
    python scripts/fuzz_api.py --seed 1 --limit 3000 # the first 3,000 of seed 1's order
    python scripts/fuzz_api.py --light               # heavy callables get type errors only
    python scripts/fuzz_api.py --draws 20 --seed 3   # and 20 random values per argument

Prints the callables covered, the calls made, the outcomes, and each place a non-PkmtolError
escaped from with up to three of its cases. Exits 1 if anything escaped or hung.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import api_fuzzing  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seed", type=int, default=0, help="order of the cases (default 0)")
    parser.add_argument("--limit", type=int, default=None, help="at most this many calls (default: all)")
    parser.add_argument("--light", action="store_true", help="heavy callables: type errors only")
    parser.add_argument("--draws", type=int, default=0, help="random bad values more per argument (seeded)")
    parser.add_argument("--only", default=None, help="only targets whose name contains this text")
    parser.add_argument(
        "--check-good", action="store_true", help="first run every good call and report failures"
    )
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="fuzz_api_") as tmp:
        fx = api_fuzzing.Fixtures(Path(tmp))
        known = {t.name for t in api_fuzzing.TARGETS}
        if args.only:
            api_fuzzing.TARGETS[:] = [t for t in api_fuzzing.TARGETS if args.only in t.name]
        if args.check_good:
            bad = api_fuzzing.check_good_calls(fx)
            for name, err in bad.items():
                print(f"good call fails: {name}: {err}")
            if bad:
                return 1
        rep = api_fuzzing.fuzz(fx, args.seed, args.limit, light=args.light, draws=args.draws)
    in_api = api_fuzzing.callables_in_api()
    missing = ", ".join(sorted(in_api - known)) or "none"
    print(f"callables covered: {len(rep.targets)} (in the API: {len(in_api)}; not in the table: {missing})")
    print(f"calls: {rep.calls} in {rep.seconds:.1f} s (seed {args.seed})")
    print("outcomes: " + ", ".join(f"{k} {v}" for k, v in rep.outcomes.most_common()))
    print(f"escapes: {rep.escapes} from {len(rep.bugs)} places")
    for place, examples in sorted(rep.bugs.items(), key=lambda kv: -len(kv[1])):
        print(f"  {len(examples):4d}  {place}")
        for ex in examples[:3]:
            print(f"          {ex}")
    for s in rep.slow:
        print(f"  slow: {s}")
    return 1 if rep.escapes or rep.outcomes["HANG"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
