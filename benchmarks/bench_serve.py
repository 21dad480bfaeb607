"""metasheet serve's update rate: visual updates per second while the goal is dragged.

Run (the pipeline's outputs must exist: ``metasheet run pipelines/quick.toml`` first):

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_serve.py [pipelines/quick.toml] [--out ROOT]
        [--model full|reduced|both] [--settings live,default] [--repeats 1] [--seconds 6] [--browser]
        [--scale 1.0]

``--model both`` (the pipeline needs the reduce stage) measures the full and the reduced
model in the same process, their runs interleaved drag by drag and repeat by repeat (the
machine's load hits both alike), and prints each row's median over the repeats and the
ratios reduced / full.

Drives the page's own session (solver thread) and drawing thread on a real viser server on a
free loopback port with scripted drags: the goal moves at 60 updates per second (a mouse
drag's event rate), the latest goal winning as on the page. With ``--browser`` a headless
chromium (Debian's chromium + chromium-driver, selenium) has the page open, so every update
is also encoded and sent over the websocket; the browser's own rendering runs on the same
cores here, which a user's machine would not share with the solver.

Drags (from the rest pose): "translate", a circle of radius 3 mm in the y-z plane, one turn in
2 s (9.4 mm/s); "roll", +-5 deg about the rod (the 6th DOF) at 0.5 Hz; "tilt", +-5 deg about y
at 0.5 Hz; ``--scale`` multiplies every amplitude (on a foam whose strain limit is reached a
few degrees of motor travel from rest, the drags that stay within it). Each runs with the
page's live settings and with the inverse loop's defaults (``drift_tol`` 0.5 instead of 10,
:mod:`metasheet.serve.session`).

Prints one table: control steps per second (each one published), median and 90th-percentile
step time, page updates pushed per second, median draw time, the median tracking error
while moving [mm, deg], the kept-tangent refreshes and the share of the published steps the
reduced model solved (the rest: the full model, outside its training box).
"""

from __future__ import annotations

import argparse
import os
import socket
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from metasheet.robot.inverse import InverseSettings  # noqa: E402
from metasheet.serve.loading import find_outputs, load_robot  # noqa: E402
from metasheet.serve.session import LIVE_SETTINGS, Session  # noqa: E402

from _results import add_save_option, saved_output

PERIOD = 2.0  # [s] of each drag's cycle
DRAGS = {
    "translate": lambda t: np.array([0.0, 3.0 * np.sin(2 * np.pi * t / PERIOD),
                                     3.0 * (np.cos(2 * np.pi * t / PERIOD) - 1), 0.0, 0.0, 0.0]),
    "roll": lambda t: np.array([0.0, 0.0, 0.0, 5.0 * np.sin(2 * np.pi * t / PERIOD), 0.0, 0.0]),
    "tilt": lambda t: np.array([0.0, 0.0, 0.0, 0.0, 5.0 * np.sin(2 * np.pi * t / PERIOD), 0.0]),
}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def open_browser(url: str):
    import shutil

    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = shutil.which("chromium")
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--use-angle=swiftshader",
                "--enable-unsafe-swiftshader", "--window-size=1400,900"):
        opts.add_argument(arg)
    driver = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=opts)
    driver.get(url)
    time.sleep(5)
    return driver


def run_drag(session, page, drag, seconds: float, scale: float = 1.0) -> dict:
    """Stream the drag's goals for ``seconds``; the rates and times while it moves."""
    session.reset()
    session.wait_idle(120)
    rest = session.snapshot().pose
    models = session.current
    refreshes0 = models.refreshes
    snaps, draws0 = [], page.draws
    page.draw_times.clear()
    t0 = time.perf_counter()
    last = session.snapshot().version
    while (t := time.perf_counter() - t0) < seconds:
        session.set_goal(rest + scale * DRAGS[drag](t))
        snap = session.wait(last, timeout=1 / 60)
        if snap is not None:
            last = snap.version
            if snap.mode == "inverse" and snap.status == "moving":
                snaps.append(snap)
    span = time.perf_counter() - t0
    draws = page.draws - draws0
    steps = np.array([s.step_ms for s in snaps]) if snaps else np.array([np.nan])
    return {"steps/s": len(snaps) / span, "step ms median": float(np.median(steps)),
            "step ms p90": float(np.percentile(steps, 90)), "updates/s": draws / span,
            "draw ms median": 1e3 * float(np.median(page.draw_times or [np.nan])),
            "error mm": float(np.median([s.pos_error for s in snaps] or [np.nan])),
            "error deg": float(np.median([s.rot_error for s in snaps] or [np.nan])),
            "refreshes": models.refreshes - refreshes0,
            "reduced %": 100.0 * float(np.mean([s.model == "reduced" for s in snaps] or [np.nan]))}


def _cell(key: str, v: float) -> str:
    return str(int(round(v))) if key in ("refreshes", "reduced %") else f"{v:.2f}" if "error" in key else f"{v:.1f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pipeline", nargs="?", default=str(ROOT / "pipelines" / "quick.toml"))
    ap.add_argument("--out", default=None, help="output root the pipeline ran with")
    ap.add_argument("--model", default="full", choices=("full", "reduced", "both"))
    ap.add_argument("--settings", default="live,default", help="comma-separated: live, default")
    ap.add_argument("--repeats", type=int, default=1, help="runs of each drag (medians over them)")
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--browser", action="store_true", help="keep the page open in headless chromium")
    ap.add_argument("--scale", type=float, default=1.0, help="amplitude factor of every drag")
    add_save_option(ap)
    args = ap.parse_args()

    import viser

    from metasheet.serve.app import Page

    outputs = find_outputs(args.pipeline, args.out)
    all_settings = {"live": LIVE_SETTINGS, "default": InverseSettings()}
    models = ("full", "reduced") if args.model == "both" else (args.model,)
    names = args.settings.split(",")
    pages, drivers, info = {}, [], {}
    try:
        for model in models:  # every page up front: the runs are interleaved below
            for name in names:
                session = Session(lambda m, model=model: load_robot(outputs, model, m), settings=all_settings[name])
                session.start()
                port = free_port()
                server = viser.ViserServer(host="127.0.0.1", port=port, verbose=False)
                pages[model, name] = (session, Page(server, session, outputs, strain_limit=0.3, model=model), server)
                if args.browser:
                    drivers.append(open_browser(f"http://127.0.0.1:{port}"))
                info[model] = session.robot_of("foam")[1]
        runs: dict = {}
        for _ in range(args.repeats):
            for drag in DRAGS:
                for (model, name), (session, page, _) in pages.items():
                    runs.setdefault((drag, name, model), []).append(
                        run_drag(session, page, drag, args.seconds, args.scale))
    finally:
        for d in drivers:
            d.quit()
        for session, page, server in pages.values():
            page.close()
            session.stop()
            server.stop()
    with saved_output(__file__, args.save):
        print(f"\nmetasheet serve, {outputs.directory}")
        for model in models:
            print(f"  {model}: {info[model].description}")
        print(f"drags of {args.seconds:g} s at amplitude x {args.scale:g}, goal events at 60 Hz, medians of "
              f"{args.repeats} run(s); browser connected: {args.browser}; "
              f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}\n")
        med = {k: {key: float(np.median([r[key] for r in rs])) for key in rs[0]} for k, rs in runs.items()}
        keys = list(next(iter(med.values())))
        print("| drag | settings | model | " + " | ".join(keys) + " |")
        print("|---|---|---|" + "---|" * len(keys))
        for (drag, name, model), r in med.items():
            print(f"| {drag} | {name} | {model} | " + " | ".join(_cell(k, r[k]) for k in keys) + " |")
        if len(models) == 2:
            print("\n| drag | settings | updates/s reduced / full | steps/s reduced / full | step ms median full / reduced |")
            print("|---|---|---|---|---|")
            for drag in DRAGS:
                for name in names:
                    f, r = med[drag, name, "full"], med[drag, name, "reduced"]
                    print(f"| {drag} | {name} | {r['updates/s'] / f['updates/s']:.2f} | {r['steps/s'] / f['steps/s']:.2f} "
                          f"| {f['step ms median'] / r['step ms median']:.1f} |")


if __name__ == "__main__":
    main()
