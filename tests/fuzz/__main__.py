"""``python -m tests.fuzz [--seed S] [--cases N] [--jobs J] [--keep FOLDER] [--first K] [--lines FILE]
[--formats F,G]``: run the fuzzing gate, print the count of cases by outcome and by format, keep every misbehaving
case, exit 1 if any misbehaved; ``--lines`` also writes every case's outcome and last line, tab-separated, to read
the messages; ``--formats`` runs only the cases of some formats among those numbered."""

import argparse
import collections
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from .cases import FORMATS
from .run import GOOD, KEPT, run_case


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m tests.fuzz", description=__doc__)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cases", type=int, default=84 * len(FORMATS),
                        help=f"how many cases (default {84 * len(FORMATS)}: 84 of each of the {len(FORMATS)} formats)")
    parser.add_argument("--first", type=int, default=0, help="the number of the first case (default 0)")
    parser.add_argument("--jobs", type=int, default=2, help="cases run at once (default 2)")
    parser.add_argument("--keep", type=Path, default=KEPT, help=f"where misbehaving cases go (default {KEPT})")
    parser.add_argument("--lines", type=Path, help="write each case's number, name, outcome and last line here")
    parser.add_argument("--formats", help="only the cases of these formats (comma-separated), among the numbers "
                                          "given: case n is of the format n modulo their number")
    args = parser.parse_args(argv)

    started = time.perf_counter()
    outcomes, by_format, bad = collections.Counter(), collections.defaultdict(collections.Counter), []
    numbers = range(args.first, args.first + args.cases)
    if args.formats:
        chosen = set(args.formats.split(","))
        if chosen - set(FORMATS):
            parser.error(f"unknown formats {', '.join(sorted(chosen - set(FORMATS)))}; choose among "
                         f"{', '.join(sorted(FORMATS))}")
        numbers = [n for n in numbers if sorted(FORMATS)[n % len(FORMATS)] in chosen]
    lines = open(args.lines, "w") if args.lines else None
    with ProcessPoolExecutor(args.jobs) as pool:
        for done, (number, name, fmt, outcome, tail) in enumerate(
                pool.map(run_case, [args.seed] * len(numbers), numbers, [args.keep] * len(numbers)), 1):
            outcomes[outcome] += 1
            by_format[fmt][outcome] += 1
            if lines:
                print(number, name, outcome, tail[-1] if tail else "", sep="\t", file=lines, flush=True)
            if outcome not in GOOD:
                bad.append((number, name, outcome, tail))
                print(f"{outcome}: case {number}: {name}: {tail[-1] if tail else ''}", flush=True)
            if done % 100 == 0:
                so_far = ", ".join(f"{count} {outcome}" for outcome, count in outcomes.most_common())
                print(f"... {done} cases in {time.perf_counter() - started:.0f} s: {so_far}", file=sys.stderr,
                      flush=True)
    print(f"\n{sum(outcomes.values())} cases of seed {args.seed} in {time.perf_counter() - started:.0f} s:")
    for outcome, count in outcomes.most_common():
        print(f"  {count:6d}  {outcome}")
    print("by format:")
    for fmt in sorted(by_format):
        print(f"  {fmt:16s} " + ", ".join(f"{count} {outcome}" for outcome, count in by_format[fmt].most_common()))
    if bad:
        print(f"{len(bad)} cases misbehaved; kept under {args.keep}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
