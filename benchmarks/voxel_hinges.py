"""How well a voxel size resolves the printed walls: edge-only hinges and one-voxel-thick walls
of one print's sheets at each voxel size (metasheet.fem.voxel.hinges; issue 62, item 1).

    python benchmarks/voxel_hinges.py --outputs outputs/paper --voxels 0.3 0.25 0.2 --save
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import add_save_option, saved_output  # noqa: E402
from bench_printed_robot import voxel_sheet  # noqa: E402
from dns_convergence import LABELS  # noqa: E402


def main() -> None:
    from metasheet.fem.voxel.hinges import edge_hinges, thin_share

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outputs", type=Path, required=True, help="a pipeline's output folder (through printmap)")
    ap.add_argument("--voxels", type=float, nargs="+", default=[0.3, 0.25, 0.2], help="voxel edges [mm]")
    ap.add_argument("--gauge", choices=("seed", "point"), default="seed")
    ap.add_argument("--seed", type=int, default=None)
    add_save_option(ap)
    args = ap.parse_args()
    rows = []
    for voxel in args.voxels:
        for label in LABELS:
            _, sheet, seed = voxel_sheet(args.outputs, voxel, args.gauge, args.seed, label)
            n = int((sheet.phases > 0).sum())
            rows.append((voxel, label, n, edge_hinges(sheet.phases), thin_share(sheet.phases)))
            print(f"  {voxel:g} mm {label}: done", file=sys.stderr, flush=True)
    with saved_output(__file__, args.save):
        print(f"One print (seed {seed}, gauge {args.gauge!r}) of `{args.outputs}`.\n")
        print("| voxel [mm] | sheet | solid voxels | edge-only hinges | per 1,000 voxels | one voxel thick |")
        print("|---|---|---|---|---|---|")
        for voxel, label, n, hinges, thin in rows:
            print(f"| {voxel:g} | {label} | {n:,} | {hinges:,} | {1000 * hinges / n:.2f} | {100 * thin:.1f} % |")


if __name__ == "__main__":
    main()
