"""The web page of ``metasheet serve``: the robot drawn live in the browser, driven from it.

Built on viser (a web 3D viewer made for robotics, pip-installable with its browser client
prebuilt, no Node or build step): its transform gizmo is the 6-DOF goal handle, its GUI
gives the sliders and panels, and its scene and GUI are shared by every tab. (trame with
pyvista would reuse the project's VTK pipelines, but a draggable 6-DOF gizmo there means
writing VTK widget callbacks through a remote-rendering stack; viser has one ready.)

Threads: viser serves the page from its own event loop and runs our callbacks in its thread
pool; the callbacks only post commands to the :class:`.session.Session` (they return at
once). The session's worker thread solves; a drawing thread (:meth:`Page._loop`) waits for
each new snapshot and sends it (the sheets in colour bands, horns, rod, effector frame,
panel), so neither a slow solve nor a slow draw blocks the page.

The scene is in metres (viser's camera, grid and gizmo sizes are made for metres); the robot
and every number on the page are in mm and degrees (:data:`SCALE` converts).

Every value a tab sends is checked before it reaches the session or the drawing
(:func:`_from_page`): viser only casts it to the widget's type (a menu takes any text, a
number NaN). A refused one is a note on the page; the state and the widgets stay as they were.
"""

from __future__ import annotations

import functools
import logging
import reprlib
import socket
import threading
import time
from collections import deque

import numpy as np

from ..errors import ConfigError
from ..mechanics.rotations import rotation_matrix
from . import scene
from .maze import maze_file, read_maze
from .panel import MEASURED_RATE, RateMeter, status_markdown
from .tracking import check_goal
from .viser_guards import guard_gui_updates, place, pose_of_handle, wxyz

log = logging.getLogger(__name__)

SCALE = 1e-3  # [m/mm]
GOAL_NAMES = ("X [mm]", "Y [mm]", "Z [mm]", "RX [deg]", "RY [deg]", "RZ [deg]")
#: how often the strain (the validity flag) is recomputed when it is not the field drawn [s]
STRAIN_PERIOD = 0.1
CAMERA = {"position": (0.11, -0.20, 0.09), "look_at": (0.0, 0.0, -0.005)}  # [m]


def check_port(host: str, port: int) -> None:
    """ConfigError unless ``host:port`` can be bound now (viser would silently take the next
    free port instead; the page must be where the user was told it is)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the web server binds
        try:
            s.bind((host, port))
        except socket.gaierror as exc:
            raise ConfigError(f"--host: {host!r}: not an address of this machine ({exc.strerror})") from None
        except OSError as exc:
            raise ConfigError(f"--port: {port}: {host}:{port} is not available ({exc.strerror}): another "
                              "program (another metasheet serve?) is using it; choose another port with --port") from None


def _from_page(handler):
    """A GUI callback on values from the page: a refused value (ConfigError) is a note on the
    page, anything else it raises (a malformed message) a note and one log line, never a
    traceback per event (:meth:`Page._refuse`); an accepted value from a tab clears the note."""

    @functools.wraps(handler)
    def guarded(self, event) -> None:
        try:
            handler(self, event)
        except ConfigError as exc:
            self._refuse(str(exc))
        except Exception as exc:  # noqa: BLE001  (a malformed message must not stop the page)
            log.warning("metasheet serve: ignored a malformed update from a tab: %s: %s",
                        type(exc).__name__, reprlib.repr(str(exc)))
            self._refuse(f"ignored a malformed update ({type(exc).__name__})")
        else:
            if getattr(event, "client", None) is not None:
                self.notice = ""
                self._dirty.set()

    return guarded


class Page:
    """The page of one :class:`.session.Session` on a running ``viser.ViserServer``.

    ``outputs`` (:class:`.loading.Outputs`) locates the maze files; ``strain_limit`` [-] the
    validity limit; ``model`` "full" / "reduced" (shown)."""

    def __init__(self, server, session, outputs, *, strain_limit: float, model: str):
        self.server, self.session, self.outputs = server, session, outputs
        self.strain_limit, self.model = strain_limit, model
        self.rate = RateMeter()
        self.field = "displacement"
        self.notice = ""
        self._dirty = threading.Event()
        self._stop = threading.Event()
        self._goal_version = -1
        self._strain = (None, None, 0.0)  # (snapshot version, strain (m,), time)
        self._validity: dict[str, np.ndarray] = {}  # material -> the elements the strain flag counts
        snap = session.snapshot()
        self._material = snap.material
        self._goal_shown = np.array(snap.goal, float)  # the goal the gizmo and the fields show
        self.surface = scene.surface(*self._mesh_of(snap.material))
        self.draws = 0
        self.drawn = -1  # the version of the last snapshot drawn
        self.draw_times: deque = deque(maxlen=1000)  # [s] of the last draws (benchmarks/bench_serve.py)
        self._build_scene(snap)
        self._build_gui(snap)
        guard_gui_updates(server, self._refuse)  # a value viser cannot cast: a note, not its traceback
        cam = server.initial_camera  # every tab's first view, and its "reset view"
        cam.position, cam.look_at, cam.up = CAMERA["position"], CAMERA["look_at"], (0.0, 0.0, 1.0)
        self._thread = threading.Thread(target=self._loop, name="metasheet-serve-draw", daemon=True)
        self._thread.start()

    def _mesh_of(self, material: str):
        geo = self.session.robot_of(material)[1].geometry
        return geo.tets, geo.rest

    # -- the scene ----------------------------------------------------------------------
    def _build_scene(self, snap) -> None:
        sc = self.server.scene
        sc.set_up_direction("+z")
        geo = self.session.robot_of(snap.material)[1].geometry
        tri = np.zeros((3, 3)), np.array([[0, 1, 2]])
        self.bands = [sc.add_mesh_simple(f"/robot/band{k}", *tri, side="double", visible=False)
                      for k in range(scene.BANDS + 1)]
        self.horns = sc.add_line_segments("/robot/horns", scene.horn_segments(geo, snap.x) * SCALE,
                                          (255, 140, 0), thickness=0.003)
        for k, p in enumerate(geo.pivots):
            sc.add_icosphere(f"/robot/pivot{k}", radius=0.004, color=(200, 90, 0), position=p * SCALE)
        self.rod = sc.add_line_segments("/robot/rod", scene.rod_segment(geo, snap.state.p, snap.state.R) * SCALE,
                                        (30, 30, 30), thickness=0.004)
        self.effector = sc.add_frame("/effector", axes_length=0.03, axes_radius=0.0012)
        self.fibers = sc.add_line_segments("/robot/fibers", scene.fiber_segments(geo, snap.x) * SCALE,
                                           (10, 10, 10), thickness=0.0007, visible=False)
        self.goal = sc.add_transform_controls("/goal", scale=0.05, depth_test=False, line_width=3.0)
        self.goal.on_update(self._on_gizmo)

    # -- the controls -------------------------------------------------------------------
    def _build_gui(self, snap) -> None:
        gui = self.server.gui
        gui.configure_theme(control_width="large", show_share_button=False, brand_color=(30, 110, 180))
        gui.main_panel.dock_right()  # the controls beside the robot, not over it
        gui.add_markdown("**metasheet**: drive the robot. Drag the gizmo (the goal) or type a goal; "
                         "the inverse model (eq. 8) follows. Motor sliders: the forward model.")
        gui.add_markdown(f"Update rate {MEASURED_RATE}; this page's own: in the robot state panel.")
        with gui.add_folder("Goal (inverse model)"):
            # one input per component: a vector input loses a component typed quickly after
            # another (each edit sends the whole vector, built from a value not yet echoed)
            self.goal_fields = [gui.add_number(f"goal {name}", float(round(v, 2)), step=0.1)
                                for name, v in zip(GOAL_NAMES, snap.goal)]
            gui.add_button("Go to goal").on_click(self._on_go)
            gui.add_button("Reset to rest").on_click(self._on_reset)
        with gui.add_folder("Motors (forward model)"):
            self.sliders = []
            for k, (a, lo, hi) in enumerate(zip(snap.angles_deg, snap.angle_min_deg, snap.angle_max_deg)):
                s = gui.add_slider(f"motor {k} [deg]", float(lo), float(hi), 0.1, float(round(a, 1)))
                s.on_update(self._on_slider)
                self.sliders.append(s)
        with gui.add_folder("View"):
            self.material = gui.add_dropdown("material", ("foam", "silicone"), initial_value=snap.material)
            self.material.on_update(self._on_material)
            self.color_by = gui.add_dropdown("colour by", tuple(scene.FIELDS), initial_value=self.field)
            self.color_by.on_update(self._on_field)
            self.show_fibers = gui.add_checkbox("show fibres", False)
            self.show_fibers.on_update(lambda e: self._dirty.set())
            self.maze = gui.add_button("Play the maze path")
            self.maze.on_click(self._on_maze)
            self._maze_button(snap.material)
        panel = gui.add_panel()  # the robot's state, docked left: visible while dragging
        with panel.add_tab("Robot state"):
            self.status = gui.add_markdown("")
            self.legend = gui.add_markdown("")
        panel.dock_left()
        panel.set_width(400)

    def _maze_button(self, material: str) -> None:
        """Enable the maze button only when the maze stage wrote this material's series."""
        f = maze_file(self.outputs.directory, material)
        self.maze.disabled = not f.is_file()
        self.maze.hint = (f"replays {f}" if f.is_file() else
                          f"no {f.name}: add the maze stage to the pipeline (pipelines/paper.toml has it)")

    def _show_goal(self, pose) -> None:
        for f, v in zip(self.goal_fields, pose):
            f.value = float(round(v, 2))

    def _move_goal(self, pose) -> None:
        """The gizmo and the goal fields to ``pose`` (6,) [mm, deg]: the goal the session was last given."""
        self._goal_shown = np.array(pose, float)
        place(self.goal, self._goal_shown[:3] * SCALE, wxyz(rotation_matrix(np.radians(self._goal_shown[3:]))))
        self._show_goal(self._goal_shown)

    def _refuse(self, message: str) -> None:
        """Show why a value from the page was refused and put the widgets back as they were."""
        snap = self.session.snapshot()
        self._move_goal(self._goal_shown)
        for s, a in zip(self.sliders, snap.angles_deg):
            s.value = float(round(a, 1))  # the page's own update: _on_slider ignores it
        self.material.value = snap.material
        self.color_by.value = self.field
        self.notice = message
        self._dirty.set()

    # the session checks each value (ConfigError before anything changes): post, then move widgets
    @_from_page
    def _on_gizmo(self, event) -> None:
        pose = pose_of_handle(event.target, SCALE)
        self.session.set_goal(pose)
        self._goal_shown = pose
        self._show_goal(pose)

    @_from_page
    def _on_go(self, event) -> None:
        pose = check_goal([f.value for f in self.goal_fields])
        self.session.set_goal(pose)
        self._move_goal(pose)

    @_from_page
    def _on_reset(self, event) -> None:
        self.session.reset()

    @_from_page
    def _on_slider(self, event) -> None:
        if event.client is None:  # the page itself moved the slider to the solved angle
            return
        self.session.set_motors([s.value for s in self.sliders])

    @_from_page
    def _on_material(self, event) -> None:
        if event.client is not None:
            self.session.set_material(self.material.value)

    @_from_page
    def _on_field(self, event) -> None:
        value = self.color_by.value
        if not isinstance(value, str) or value not in scene.FIELDS:  # drawn at every redraw: never unchecked
            raise ConfigError(f"colour by: {reprlib.repr(value)}: allowed values are {', '.join(scene.FIELDS)}")
        self.field = value
        self._dirty.set()

    @_from_page
    def _on_maze(self, event) -> None:
        try:
            playback = read_maze(maze_file(self.outputs.directory, self.session.snapshot().material))
        except ConfigError as exc:
            raise ConfigError(f"{exc} (pipelines/paper.toml has it)") from None
        self.session.play_maze(playback)

    # -- drawing ------------------------------------------------------------------------
    def _loop(self) -> None:
        last, failed = -1, None
        while not self._stop.is_set():
            snap = self.session.wait(last, timeout=0.25)
            if snap is None:
                if not self._dirty.is_set():
                    continue
                snap = self.session.snapshot()
            self._dirty.clear()
            last = snap.version
            try:
                self.draw(snap)
                failed = None
            except Exception as exc:  # keep drawing the next snapshots; the page stays up
                import traceback

                if (type(exc), str(exc)) != failed:  # its traceback once, not at every redraw
                    traceback.print_exc()
                failed = (type(exc), str(exc))

    def _strain_of(self, snap):
        """The elements' largest principal strains at ``snap`` (m,), recomputed at most every
        :data:`STRAIN_PERIOD` s unless the surface shows them; None when the robot has none."""
        version, strain, at = self._strain
        now = time.perf_counter()
        if version == snap.version or (self.field != "strain" and now - at < STRAIN_PERIOD and strain is not None):
            return strain
        body = self.session.robot_of(snap.material)[0].body
        fn = getattr(body, "max_principal_strain", None)
        strain = None if fn is None else np.asarray(fn(snap.x))
        self._strain = (snap.version, strain, now)
        return strain

    def _checked(self, material: str) -> np.ndarray:
        """(m,) bool: the elements the validity flag counts (away from the grips, :mod:`metasheet.robot.validity`)."""
        if material not in self._validity:
            from ..robot.validity import validity_elements

            self._validity[material] = validity_elements(self.session.robot_of(material)[0])
        return self._validity[material]

    def draw(self, snap) -> None:
        """Send ``snap`` to every tab."""
        t0 = time.perf_counter()
        robot, info = self.session.robot_of(snap.material)
        geo, x = info.geometry, snap.x
        if snap.material != self._material:
            self.surface, self._material = scene.surface(geo.tets, geo.rest), snap.material
            self._maze_button(snap.material)
        strain = self._strain_of(snap)
        values = scene.face_values(self.field, self.surface, geo, x, strain)
        lo, hi = scene.field_range(self.field, values, self.strain_limit)
        limit = self.strain_limit if self.field == "strain" else None
        meshes = scene.band_meshes(self.surface, x, values, lo, hi, limit=limit)
        colors = [tuple(int(c) for c in rgb) for rgb in scene.band_colors(self.field)] + [scene.OVER_LIMIT]
        strain_max, _ = scene.strain_flag(None if strain is None else strain[self._checked(snap.material)],
                                          self.strain_limit)
        with self.server.atomic():
            fibers = bool(self.show_fibers.value)
            for k, h in enumerate(self.bands):
                if k >= len(meshes) or len(meshes[k][1]) == 0:
                    h.visible = False
                    continue
                v, f = meshes[k]
                h.vertices, h.faces, h.color, h.visible = v * SCALE, f, colors[k], True
                h.opacity = 0.3 if fibers else None  # the fibres run inside the sheets
            self.horns.points = scene.horn_segments(geo, x) * SCALE
            self.rod.points = scene.rod_segment(geo, snap.state.p, snap.state.R) * SCALE
            self.effector.position, self.effector.wxyz = snap.state.p * SCALE, wxyz(snap.state.R)
            self.fibers.visible = fibers
            if fibers:
                self.fibers.points = scene.fiber_segments(geo, x) * SCALE
            if snap.goal_version != self._goal_version:  # the session moved the goal: follow
                self._goal_version = snap.goal_version
                self._move_goal(snap.goal)
            for s, a in zip(self.sliders, snap.angles_deg):
                s.value = float(round(a, 1))
            if self.material.value != snap.material:
                self.material.value = snap.material
            label, unit = scene.FIELDS[self.field]
            over = f"; red: beyond the limit {self.strain_limit:g}" if limit is not None else ""
            self.legend.content = f"colour: {label} [{unit}], {lo:g} (dark) to {hi:g} (light), {scene.BANDS} bands{over}"
            self.rate.tick()
            text = status_markdown(snap, strain_max=strain_max, strain_limit=self.strain_limit,
                                   rate=self.rate.rate(), model=self.model)
            self.status.content = text + (f"\n\nnote: {self.notice}" if self.notice else "")
        self.draws += 1
        self.drawn = snap.version
        self.draw_times.append(time.perf_counter() - t0)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5.0)


def serve(outputs, *, host: str = "127.0.0.1", port: int = 8080, model: str = "full",
          strain_limit: float = 0.3, ready=None) -> None:
    """Serve the page of ``outputs`` (:class:`.loading.Outputs`) until interrupted.

    Everything that can fail at start-up (the port, the outputs, the robot) fails before the
    server starts, as a :class:`ConfigError`. ``ready(url)`` is called once the page is up.
    """
    import viser

    from .loading import check_outputs, load_robot
    from .session import Session

    check_outputs(outputs)
    check_port(host, port)
    session = Session(lambda material: load_robot(outputs, model, material))
    session.start()
    server = viser.ViserServer(host=host, port=port, label="metasheet serve", verbose=False)
    page = None
    try:
        if server.get_port() != port:  # taken between our check and viser's bind
            raise ConfigError(f"--port: {port}: {host}:{port} was taken while starting; choose another port")
        page = Page(server, session, outputs, strain_limit=strain_limit, model=model)
        if ready is not None:
            ready(f"http://{host}:{port}")
        while True:
            time.sleep(0.5)
    finally:
        if page is not None:
            page.close()
        session.stop()
        server.stop()
