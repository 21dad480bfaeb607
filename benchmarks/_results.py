"""A benchmark's table, kept: ``--save`` writes what the benchmark printed to
``benchmarks/results/<script>.md``, under one line that gives the command, the date and the
machine. The documentation's Performance page includes these files as they are
(``docs/_scripts/hooks.py``), so its tables are the benchmarks' own output, never retyped.

    ap = argparse.ArgumentParser(...)
    add_save_option(ap)
    args = ap.parse_args()
    ...                                   # the measurements
    with saved_output(__file__, args.save):
        print(...)                        # the table: on the screen, and in the file

Markdown tables are kept as Markdown. A benchmark that prints aligned text passes
``fenced=True``, which puts it in a text block. The file is written to a temporary name and
renamed into place, and only when the block ends without an error.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import io
import os
import platform
import shlex
import sys
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"
ROOT = RESULTS.parents[1]
#: environment variables that change what a benchmark measures, shown in its command line
ENV_SHOWN = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS")


def add_save_option(ap: argparse.ArgumentParser) -> None:
    """Add ``--save`` to a benchmark's argument parser."""
    ap.add_argument("--save", action="store_true",
                    help="also write the printed table to benchmarks/results/<script>.md "
                         "(included by the documentation's Performance page)")


def cpu_model() -> str:
    """The CPU's model name (Linux /proc/cpuinfo; elsewhere platform.processor())."""
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine() or "unknown CPU"


def command_line(script: str) -> str:
    """The command that ran ``script``, from the repository root, with the thread settings."""
    path = Path(script).resolve()
    with contextlib.suppress(ValueError):
        path = path.relative_to(ROOT)
    env = [f"{k}={os.environ[k]}" for k in ENV_SHOWN if k in os.environ]
    return " ".join([*env, "python", shlex.join([path.as_posix(), *sys.argv[1:]])])


def provenance(script: str) -> str:
    """One line: the command, the date and the machine (and how busy it was)."""
    load = f", load average {os.getloadavg()[0]:.1f}" if hasattr(os, "getloadavg") else ""
    return (f"Measured with `{command_line(script)}` on {datetime.date.today().isoformat()}: "
            f"{cpu_model()}, {os.cpu_count()} cores{load}, Python {platform.python_version()}.")


def _blank_lines_around_tables(text: str) -> str:
    """A blank line before and after each block of ``|`` lines: Markdown needs it there."""
    out: list[str] = []
    for line in text.splitlines():
        is_row = line.lstrip().startswith("|")
        prev_row = bool(out) and out[-1].lstrip().startswith("|")
        if out and out[-1].strip() and line.strip() and is_row != prev_row:
            out.append("")
        out.append(line)
    return "\n".join(out)


def results_text(script: str, printed: str, *, fenced: bool = False) -> str:
    """The results file of ``script`` for what it ``printed``."""
    body = printed.strip("\n")
    body = f"```text\n{body}\n```" if fenced else _blank_lines_around_tables(body)
    return f"{provenance(script)}\n\n{body}\n"


class _Tee(io.TextIOBase):
    def __init__(self, *streams):
        self.streams = streams

    def write(self, s: str) -> int:
        for stream in self.streams:
            stream.write(s)
        return len(s)

    def flush(self) -> None:
        for stream in self.streams:
            stream.flush()


@contextlib.contextmanager
def saved_output(script: str, save: bool, *, fenced: bool = False):
    """What is printed inside the block goes to stdout and, with ``save``, to
    ``benchmarks/results/<script's stem>.md`` once the block ends without an error."""
    if not save:
        yield
        return
    buffer = io.StringIO()
    with contextlib.redirect_stdout(_Tee(sys.stdout, buffer)):
        yield
    RESULTS.mkdir(exist_ok=True)
    final = RESULTS / f"{Path(script).stem}.md"
    tmp = final.with_name(f".{final.name}.tmp-{os.getpid()}")
    tmp.write_text(results_text(script, buffer.getvalue(), fenced=fenced), encoding="utf-8")
    os.replace(tmp, final)
    print(f"saved {final.relative_to(ROOT) if final.is_relative_to(ROOT) else final}", file=sys.stderr)
