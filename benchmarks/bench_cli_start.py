"""A command's start: the seconds before ``metasheet`` does anything (issue 59).

    python benchmarks/bench_cli_start.py [--before DIR] [--repeats 7]

Every ``metasheet`` command that reads a pipeline imports the stages (``metasheet stages`` does
only that), and every test that runs the command in a subprocess pays it again. Times, in fresh
processes, ``import metasheet.pipeline.stages``, ``metasheet stages`` and ``metasheet
--version`` with this checkout and, with ``--before DIR``, with the package in ``DIR`` (e.g.
``git worktree add DIR <rev>``), interleaved so that the machine's load hits both alike, and
prints the median wall seconds of each and their ratio.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASES = {
    "import metasheet.pipeline.stages": [sys.executable, "-c", "import metasheet.pipeline.stages"],
    "metasheet stages": [sys.executable, "-m", "metasheet", "stages"],
    "metasheet --version": [sys.executable, "-m", "metasheet", "--version"],
}


def once(cmd: list[str], package_root: Path) -> float:
    """Wall seconds of ``cmd`` with ``package_root`` first on the path."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(package_root), os.environ.get("PYTHONPATH", "")])}
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, cwd="/", check=True, capture_output=True)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, help="a checkout of the code before (its root holds metasheet/)")
    ap.add_argument("--repeats", type=int, default=7)
    a = ap.parse_args()
    roots = {"now": ROOT, **({"before": a.before.resolve()} if a.before else {})}
    times = {(case, k): [] for case in CASES for k in roots}
    for _ in range(a.repeats):
        for case, cmd in CASES.items():
            for k, root in roots.items():
                times[case, k].append(once(cmd, root))
    print(f"| command | {' | '.join(f'{k} [s]' for k in roots)} |" + (" now / before |" if a.before else ""))
    print("|---|" + "---:|" * (len(roots) + bool(a.before)))
    for case in CASES:
        med = {k: statistics.median(times[case, k]) for k in roots}
        ratio = f" {med['now'] / med['before']:.2f} |" if a.before else ""
        print(f"| `{case}` | {' | '.join(f'{med[k]:.2f}' for k in roots)} |{ratio}")
    print(f"(median of {a.repeats} fresh processes each, interleaved)")


if __name__ == "__main__":
    main()
