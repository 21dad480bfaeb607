"""metasheet serve in a real browser: Debian's chromium, headless, driven by selenium.

Builds a small pipeline's robot outputs (material, orient at 12 mm, robot; ~15 s), starts
``metasheet serve`` on a free loopback port, loads the page and checks that

* the robot renders: the canvas is not blank (pixel statistics of a screenshot);
* a goal typed into the page's own goal fields and sent with its "Go to goal" button moves
  the motors and the drawn robot (the canvas changes), and the motor angles and pose the
  page reports match ``metasheet robot goto --pipeline`` (the same robot) for the same goal;
* dragging the goal gizmo with the mouse drives the robot (the goal and the pose change);
* a second tab sees the same robot, and closing the first leaves the server serving.

The screenshot is kept in the test's tmp dir (and copied to ``$METASHEET_SERVE_SCREENSHOT``
when set: that is how docs/serve.png is made). Marker "system": needs the chromium and
chromium-driver packages (.ci/run's second phase installs them).
"""

import os
import re
import shutil
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

pytestmark = pytest.mark.system

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
ARROW_Z = (54, 142, 226)  # the colour of the gizmo's z arrow [RGB]
GOAL = [2.0, -1.0, 1.0, -3.0, 2.0, 1.0]  # x, y, z [mm], rx, ry, rz [deg]: reachable, 5 deg of motor travel
PIPELINE = """[pipeline]
name = "small"
stages = ["material", "orient", "robot"]

[material]
source = "config"

[orient]
mesh_size = 12.0

[robot]
compare_published = false
compare_models = false
"""


def metasheet(*args, **kw):
    return subprocess.run([sys.executable, "-m", "metasheet.cli", *args], capture_output=True, text=True,
                          timeout=300, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"}, **kw)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    if not (CHROMIUM and CHROMEDRIVER):
        pytest.skip("needs the chromium and chromium-driver packages (apt-get install chromium chromium-driver)")
    d = tmp_path_factory.mktemp("serve_browser")
    (d / "small.toml").write_text(PIPELINE)
    r = metasheet("run", str(d / "small.toml"), "--out", str(d / "out"))
    assert r.returncode == 0, r.stderr
    return d


@pytest.fixture(scope="module")
def server(outputs):
    port = free_port()
    log = open(outputs / "serve.log", "w")
    proc = subprocess.Popen([sys.executable, "-m", "metasheet.cli", "serve", str(outputs / "small.toml"), "--out",
                             str(outputs / "out"), "--port", str(port)], stdout=log, stderr=subprocess.STDOUT,
                            env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.time() + 120
        while "serving the robot at" not in (outputs / "serve.log").read_text():
            assert proc.poll() is None, (outputs / "serve.log").read_text()
            assert time.time() < deadline, "metasheet serve did not start in 120 s"
            time.sleep(0.3)
        yield url, proc
    finally:
        proc.terminate()
        proc.wait(20)
        log.close()


@pytest.fixture(scope="module")
def browser(server):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    # no GPU here: WebGL through SwiftShader, chromium's software renderer
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--use-angle=swiftshader",
                "--enable-unsafe-swiftshader", "--window-size=1400,900"):
        opts.add_argument(arg)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
    driver.set_page_load_timeout(60)
    yield driver
    driver.quit()


# -- reading and driving the page -----------------------------------------------------------

def page_text(driver) -> str:
    from selenium.webdriver.common.by import By

    return driver.find_element(By.TAG_NAME, "body").text


def wait_for(driver, predicate, timeout=90.0, what="the page"):
    deadline = time.time() + timeout
    while time.time() < deadline:
        text = page_text(driver)
        if predicate(text):
            return text
        time.sleep(0.25)
    raise AssertionError(f"{what}: not seen in {timeout} s; the page shows:\n{page_text(driver)}")


def reported(driver) -> dict:
    """The panel's status, motor angles [deg] (its table), pose and goal [mm, deg]."""
    from selenium.webdriver.common.by import By

    text = page_text(driver)
    rows = driver.find_elements(By.CSS_SELECTOR, "table tbody tr")
    angles = [float(r.find_elements(By.TAG_NAME, "td")[1].text) for r in rows[:6]]
    vec = r"(-?[\d.]+) (-?[\d.]+) (-?[\d.]+) \| (-?[\d.]+) (-?[\d.]+) (-?[\d.]+)"
    return {"status": re.search(r"status: (\S+?):", text).group(1).lower(), "angles": np.array(angles),
            "pose": np.array(re.search(r"pose \[mm, deg\]: " + vec, text).groups(), float),
            "goal": np.array(re.search(r"goal \[mm, deg\]: " + vec, text).groups(), float),
            "rate": float(re.search(r"updates: ([\d.]+) per s", text).group(1))}


def field(driver, label):
    """The input of the GUI element labelled ``label``."""
    from selenium.webdriver.common.by import By

    lab = driver.find_element(By.XPATH, f"//label[normalize-space(text())='{label}']")
    return lab.find_element(By.XPATH, "./ancestor::*[.//input][1]").find_element(By.TAG_NAME, "input")


def type_goal(driver, goal):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    names = ("X [mm]", "Y [mm]", "Z [mm]", "RX [deg]", "RY [deg]", "RZ [deg]")
    for name, v in zip(names, goal):
        box = field(driver, f"goal {name}")
        box.click()
        box.send_keys(Keys.CONTROL, "a")
        box.send_keys(f"{v:g}", Keys.TAB)
        # one field at a time: typed back to back, an edit was seen lost on the server (the
        # field showed 0, the goal kept 2.00; viser's websocket under the software renderer)
        time.sleep(0.3)
    driver.find_element(By.XPATH, "//button[normalize-space(.)='Go to goal']").click()


def canvas_pixels(driver) -> np.ndarray:
    """(h, w, 3) the 3D view's central region (the notification and panels are outside it)."""
    import io

    from PIL import Image
    from selenium.webdriver.common.by import By

    canvas = max(driver.find_elements(By.TAG_NAME, "canvas"), key=lambda c: c.size["width"] * c.size["height"])
    img = np.asarray(Image.open(io.BytesIO(canvas.screenshot_as_png)).convert("RGB"), float)
    h, w = img.shape[:2]
    return img[h // 4: 3 * h // 4, w // 4: 3 * w // 4]


def not_blank(img) -> float:
    """Fraction of the pixels that differ from the most common (background) colour."""
    flat = img.reshape(-1, 3)
    q = (flat // 16).astype(int)
    keys, counts = np.unique(q[:, 0] * 256 + q[:, 1] * 16 + q[:, 2], return_counts=True)
    bg = flat[(q[:, 0] * 256 + q[:, 1] * 16 + q[:, 2]) == keys[counts.argmax()]].mean(axis=0)
    return float(np.mean(np.abs(flat - bg).max(axis=1) > 40))


def close_notifications(driver):
    from selenium.webdriver.common.by import By

    for b in driver.find_elements(By.CSS_SELECTOR, ".mantine-Notification-closeButton"):
        try:
            b.click()
        except Exception:  # already gone
            pass


# -- the test ---------------------------------------------------------------------------------

def test_drive_the_robot_from_the_page(server, browser, outputs, tmp_path):
    url, proc = server
    browser.get(url)
    wait_for(browser, lambda t: "status:" in t and "motor 5 [deg]" in t, what="the panel")
    time.sleep(3)  # the first meshes reach the canvas
    close_notifications(browser)
    before = canvas_pixels(browser)
    assert not_blank(before) > 0.03, "the 3D view is blank: the robot did not render"
    rest = reported(browser)
    assert rest["status"] == "reached" and np.allclose(rest["angles"], 60.0, atol=0.01)

    type_goal(browser, GOAL)
    wait_for(browser, lambda t: re.search(r"status: (reached|UNREACHABLE):", t) and "goal [mm, deg]: 2.00 -1.00" in t,
             what="the goal reached")
    page = reported(browser)
    assert page["status"] == "reached"
    assert np.max(np.abs(page["angles"] - rest["angles"])) > 1.0  # the motors moved
    np.testing.assert_allclose(page["pose"], GOAL, atol=0.25)
    time.sleep(1.0)
    after = canvas_pixels(browser)
    assert np.mean(np.abs(after - before)) > 0.5, "the drawn robot did not move"
    browser.save_screenshot(str(tmp_path / "serve.png"))
    if os.environ.get("METASHEET_SERVE_SCREENSHOT"):  # the README's picture, in 128 colours (small)
        from PIL import Image

        Image.open(tmp_path / "serve.png").convert("RGB").quantize(128).save(os.environ["METASHEET_SERVE_SCREENSHOT"])

    # the same goal through the command line: the same motors and pose, within the loops' tolerances
    r = metasheet("robot", "goto", "--pipeline", str(outputs / "small.toml"), "--out", str(outputs / "out"), "--",
                  *[f"{v:g}" for v in GOAL])
    assert r.returncode == 0, r.stdout + r.stderr
    cli_angles = np.array(re.search(r"motor angles \[deg\]: (.*)", r.stdout).group(1).split(), float)
    cli_pose = np.array(re.search(r"X Y Z \[mm\] (\S+) (\S+) (\S+) \| RX RY RZ \[deg\] (\S+) (\S+) (\S+)",
                                  r.stdout).groups(), float)
    np.testing.assert_allclose(page["angles"], cli_angles, atol=0.5)  # [deg]
    np.testing.assert_allclose(page["pose"], cli_pose, atol=0.2)  # [mm, deg]


def test_drag_the_goal_gizmo(server, browser):
    """Press on the gizmo's vertical (z) arrow and drag it up: the goal moves, the robot follows."""
    import io

    from PIL import Image
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    close_notifications(browser)
    start = reported(browser)
    canvas = max(browser.find_elements(By.TAG_NAME, "canvas"), key=lambda c: c.size["width"] * c.size["height"])
    img = np.asarray(Image.open(io.BytesIO(canvas.screenshot_as_png)).convert("RGB"), int)
    h, w = img.shape[:2]
    arrow = np.abs(img - ARROW_Z).max(axis=2) < 30  # the gizmo's z arrow (its own light blue)
    arrow[:, : w // 5] = arrow[4 * h // 5:] = False  # not the corner axes widget
    ys, xs = np.nonzero(arrow)
    assert len(ys) > 20, "no gizmo z arrow found in the 3D view"
    upper = ys < np.percentile(ys, 30)  # grab it high, away from the other handles
    x, y = int(np.median(xs[upper])), int(np.median(ys[upper]))
    scale = canvas.size["width"] / w  # screenshot pixels -> CSS pixels
    chain = ActionChains(browser).move_to_element_with_offset(
        canvas, int(x * scale - canvas.size["width"] / 2), int(y * scale - canvas.size["height"] / 2)).click_and_hold()
    for _ in range(4):  # ~0.3 mm per pixel: a drag of ~2-3 mm up
        chain = chain.move_by_offset(0, -2).pause(0.1)
    chain.release().perform()
    wait_for(browser, lambda t: reported(browser)["goal"][2] > start["goal"][2] + 0.5, timeout=30,
             what="the goal moved up by the drag")
    wait_for(browser, lambda t: re.search(r"status: (reached|UNREACHABLE):", t), what="the robot settled")
    moved = reported(browser)
    assert moved["goal"][2] > start["goal"][2] + 0.5
    assert moved["pose"][2] > start["pose"][2] + 0.5 or moved["status"] == "unreachable"


def test_tabs_share_the_robot_and_closing_one_leaves_the_server_serving(server, browser):
    url, proc = server
    first = browser.current_window_handle
    shown = reported(browser)
    browser.switch_to.new_window("tab")
    browser.get(url)
    wait_for(browser, lambda t: "status:" in t and "motor 5 [deg]" in t, what="the second tab's panel")
    time.sleep(1.0)
    np.testing.assert_allclose(reported(browser)["goal"], shown["goal"], atol=0.01)  # the same robot
    second = browser.current_window_handle
    browser.switch_to.window(first)
    browser.close()  # a tab goes away
    browser.switch_to.window(second)
    type_goal(browser, [0.0, 0.0, 0.5, 0.0, 0.0, 0.0])
    wait_for(browser, lambda t: "goal [mm, deg]: 0.00 0.00 0.50" in t and re.search(r"status: (reached|UNREACHABLE):", t),
             what="a goal from the remaining tab")
    assert proc.poll() is None  # the server lives on
    browser.get(url)  # and serves a fresh load
    wait_for(browser, lambda t: "status:" in t, what="the page after a reload")
