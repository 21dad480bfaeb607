"""What the pinned code paths cost: the quick pipeline pinned to AVX2 (metasheet.runtime.cpu) against
this CPU's native kernels, run after run in the same session.

    python benchmarks/bench_code_paths.py [--repeats 3] [--pipeline pipelines/quick.toml] [--save]

Each run is a fresh ``metasheet run --force`` in its own process (the code path is chosen
when numpy loads), the numba cache warm for both; prints the median wall time of each and
their ratio, and whether the two trees hold the same bytes (on an AVX-512 CPU they do not:
that is why the paths are pinned).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _results import add_save_option, saved_output

ROOT = Path(__file__).resolve().parents[1]


def run(pipeline: str, out: Path, decision: str) -> float:
    """Wall time [s] of one forced run with the code paths ``decision`` ("pinned"/"native")."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES", "MKL_CBWR")}
    env["METASHEET_CODE_PATHS"] = decision
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "metasheet.cli", "run", pipeline, "--out", str(out), "--force"],
                   cwd=ROOT, env=env, check=True, capture_output=True)
    return time.perf_counter() - t0


def same_bytes(a: Path, b: Path) -> bool:
    files = [p.relative_to(a) for p in sorted(a.rglob("*")) if p.is_file() and p.name != "manifest.json"]
    return all((a / f).read_bytes() == (b / f).read_bytes() for f in files)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pipeline", default="pipelines/quick.toml")
    ap.add_argument("--repeats", type=int, default=3)
    add_save_option(ap)
    args = ap.parse_args()
    times: dict[str, list[float]] = {"pinned": [], "native": []}
    with tempfile.TemporaryDirectory() as tmp:
        outs = {d: Path(tmp) / d for d in times}
        for d in times:  # warm the numba cache and the page cache
            run(args.pipeline, outs[d], d)
        for _ in range(args.repeats):
            for d in times:
                times[d].append(run(args.pipeline, outs[d], d))
        name = Path(args.pipeline).stem
        same = same_bytes(outs["pinned"] / name, outs["native"] / name)
    pinned, native = (statistics.median(times[d]) for d in ("pinned", "native"))
    with saved_output(__file__, args.save):
        print(f"\n{args.pipeline}, medians of {args.repeats} forced runs each, interleaved\n")
        print("| code paths | wall [s] | ratio to native |")
        print("|---|---|---|")
        print(f"| native (this CPU's kernels) | {native:.1f} | 1.00 |")
        print(f"| pinned (AVX2: metasheet.runtime.cpu) | {pinned:.1f} | {pinned / native:.2f} |")
        print(f"\nsame bytes: {same}")


if __name__ == "__main__":
    main()
