"""``make demo`` / ``python -m cadfeat.cli.demo``: run the flagship study (the NEMA 17 motor mount, designed for
pose accuracy with g_POSE and confirmed in the closed loop by ``cadfeat run``'s fast check) and say where the
revised STEP/STL files and the report are, with a short before/after summary."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from cadfeat.cli import run_guarded

FLAGSHIP = Path(__file__).resolve().parents[2] / "studies" / "nema17_mount.toml"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cadfeat.cli.demo", description=__doc__)
    parser.add_argument("--out", default=None, help="output folder (default exports/nema17_mount/)")
    parser.add_argument("--quiet", action="store_true", help="no progress display")
    parser.add_argument("--force", action="store_true",
                        help="write into an existing folder cadfeat did not create (other files untouched)")
    args = parser.parse_args(argv)

    from cadfeat.study.run import run_study  # lazy: keeps `cadfeat --help` fast

    t0 = time.perf_counter()
    results = []
    status = run_guarded(lambda: results.append(run_study(FLAGSHIP, args.out, quiet=args.quiet, force=args.force)),
                         "cadfeat demo")
    if status:
        return status
    result = results[0]
    print()
    print(result.summary())
    out = result.out_dir
    print()
    print(f"revised part:   {out / 'optimised.step'}  (and {out / 'optimised.stl'})")
    print(f"original part:  {out / 'original.step'}")
    report = out / "report.html"
    print(f"report:         {report if report.exists() else '(cadfeat.report not available)'}")
    print(f"all numbers:    {out / 'results.json'}")
    print(f"done in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
