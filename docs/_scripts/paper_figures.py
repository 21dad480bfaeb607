"""Copy a paper run's figures into the docs (docs/img/paper/), with the run's provenance.

    python docs/_scripts/paper_figures.py OUT       # OUT: the --out of `metasheet run pipelines/paper.toml`

The pictures are the report's (``OUT/paper/report/*.png``: each figure in both columns).
``docs/img/paper/source.json`` records where they come from: the commit (when the run's code
digest is this checkout's and the package has no uncommitted change; else null, and the script
says so), the code digest, the run's start (its first stage's) and each picture's sha256, which
``tests/test_docs_paper.py`` checks against the files. Every write is atomic.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import metasheet
from metasheet.runtime.provenance import code_digest

ROOT = Path(__file__).resolve().parents[2]
DEST = ROOT / "docs" / "img" / "paper"
#: The report's pictures the paper page shows: (file, what it is).
PICTURES = {
    "robot.png": "the robot at rest and after all motors moved (Fig. 4 and 8)",
    "workspace.png": "Fig. 5, the printed foam's prediction",
    "workspace_reproduction.png": "Fig. 5, the reproduction (published constants)",
    "ranges.png": "Fig. 6, the printed foam's prediction",
    "ranges_reproduction.png": "Fig. 6, the reproduction",
    "anisotropy.png": "Fig. 7, the printed foam's prediction",
    "anisotropy_reproduction.png": "Fig. 7, the reproduction",
    "maze.png": "the maze, the printed foam's prediction",
    "maze_reproduction.png": "the maze, the reproduction",
}


def commit_of(digest: str) -> str | None:
    """This checkout's commit when the package's code is that commit's and its digest is ``digest``."""
    if digest != code_digest():
        return None
    try:
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "metasheet"], cwd=ROOT, capture_output=True,
                               text=True, check=True).stdout.strip()
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None
    return None if dirty else head


def main(out: Path) -> int:
    report = out / "paper" / "report"
    manifest = report / "manifest.json"
    if not manifest.is_file():
        print(f"error: {manifest}: no report of a paper run: run `metasheet run pipelines/paper.toml --out {out}` "
              "first", file=sys.stderr)
        return 2
    m = json.loads(manifest.read_text())
    missing = [name for name in PICTURES if not (report / name).is_file()]
    if missing:
        print(f"error: {report}: missing {', '.join(missing)}", file=sys.stderr)
        return 2
    digest = m["versions"]["metasheet_code"]
    commit = commit_of(digest)
    if commit is None:
        print(f"warning: the run's code (digest {digest[:12]}) is not this checkout's committed code: "
              "source.json records no commit", file=sys.stderr)
    sums = {}
    for name in PICTURES:
        data = (report / name).read_bytes()
        metasheet.write_file(DEST / name, data)
        sums[name] = hashlib.sha256(data).hexdigest()
    started = sorted(json.loads(f.read_text()).get("started") or "~" for f in (out / "paper").glob("*/manifest.json"))
    source = {"pipeline": "pipelines/paper.toml", "commit": commit, "code_digest": digest,
              "run_started": started[0], "pictures": {n: {"what": PICTURES[n], "sha256": sums[n]}
                                                            for n in PICTURES}}
    metasheet.write_file(DEST / "source.json", (json.dumps(source, indent=1) + "\n").encode())
    print(f"{len(PICTURES)} pictures -> {DEST.relative_to(ROOT)} (commit {commit or 'none'})")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__.split("\n\n")[1], file=sys.stderr)
        sys.exit(2)
    sys.exit(main(Path(sys.argv[1])))
