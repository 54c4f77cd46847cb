"""`Viewer`: the arm, its target, its singular directions and replays, live in a browser.

Threads: viser serves the page and its websocket from its own thread. `Viewer.update`
only stores the latest state and wakes the viewer's drawing thread, which draws at most
``rate_hz`` times a second — the newest state, older ones are dropped — so a control loop
calling ``update`` every cycle is never slowed by drawing. Drawing a state costs the
forward kinematics of every frame, one `ratectl.analyze` and a few small websocket
messages. The target gizmo is read and written under a lock: `Viewer.target` may be
read from the control loop while a user drags it.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np
import rich
import viser
from numpy.typing import ArrayLike

from ..arrays import read_only
from ..errors import InputError, RatectlError
from ..model.chain import Chain
from ..singularity import analyze
from ..spatial import quat_from_rotation, rigid_transform_defect, rotation_from_quat
from .geometry import body_polylines, joint_markers, lost_directions, path_points
from .meshes import capsule_mesh, joint_mesh, visual_glb

__all__ = ["Viewer"]

_LINK_RGB = (176, 186, 204)
_JOINT_RGB = (232, 142, 46)
_BASE_RGB = (96, 100, 110)
_MESH_RGBA = (0.72, 0.74, 0.78, 1.0)
_PATH_RGB = (40, 110, 220)
_TRACE_RGB = (30, 160, 90)
_LOST_RGB = {"translation": (220, 30, 30), "rotation": (170, 40, 200)}


@contextlib.contextmanager
def _quiet(on: bool) -> Iterator[None]:
    """Silence viser's banner and stop message (printed with rich's global console)."""
    if not on:
        yield
        return
    console = rich.get_console()
    before = console.quiet
    console.quiet = True
    try:
        yield
    finally:
        console.quiet = before


def _wxyz_position(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return quat_from_rotation(T[..., :3, :3]), T[..., :3, 3]


def _pose(wxyz: ArrayLike, position: ArrayLike) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotation_from_quat(np.asarray(wxyz, dtype=float))
    T[:3, 3] = np.asarray(position, dtype=float)
    return T


class _Arm:
    """The scene nodes of one drawn arm: a frame node per chain frame (moved by `show`)
    holding that body's geometry."""

    def __init__(self, server: viser.ViserServer, chain: Chain, root: str, *, offset: np.ndarray,
                 meshes: bool, radius: float, opacity: float | None = None) -> None:
        self.chain = chain
        self.offset = offset
        self.server = server
        n = chain.dof
        scene = server.scene
        self.nodes = [scene.add_frame(f"{root}/frame{k}", show_axes=False) for k in range(n + 1)]
        self.drawn_meshes = self._add_meshes(root) if meshes and chain.visuals else 0
        if not self.drawn_meshes:
            for k, pts in enumerate(body_polylines(chain)):
                m = capsule_mesh(pts, radius)
                scene.add_mesh_simple(f"{root}/frame{k}/link", m.vertices, m.faces,
                                      color=_BASE_RGB if k == 0 else _LINK_RGB, opacity=opacity)
            for k, centre, axis, kind in joint_markers(chain):
                m = joint_mesh(centre, axis, kind, radius)
                scene.add_mesh_simple(f"{root}/frame{k}/joint", m.vertices, m.faces, color=_JOINT_RGB,
                                      opacity=opacity)
        self.tool = scene.add_frame(f"{root}/frame{n}/tool", axes_length=4.0 * radius,
                                    axes_radius=0.2 * radius, origin_radius=0.3 * radius,
                                    wxyz=quat_from_rotation(chain.tool[:3, :3]),
                                    position=chain.tool[:3, 3])

    def _add_meshes(self, root: str) -> int:
        """The model file's geometry: each link's visual pieces where they can be read, else
        its collision pieces; the number of pieces drawn."""
        by_link: dict[str, dict[str, list]] = {}
        for v in self.chain.visuals:
            by_link.setdefault(v.link, {}).setdefault(v.role, []).append(v)
        drawn = 0
        for link, roles in by_link.items():
            for role in ("visual", "collision"):
                pieces = [(v, visual_glb(v, default_rgba=_MESH_RGBA)) for v in roles.get(role, [])]
                pieces = [(v, g) for v, g in pieces if g is not None]
                if not pieces:
                    continue
                for i, (v, glb) in enumerate(pieces):
                    wxyz, pos = _wxyz_position(np.asarray(v.origin))
                    assert glb is not None
                    self.server.scene.add_glb(f"{root}/frame{v.frame}/{link}_{role}{i}", glb,
                                              wxyz=wxyz, position=pos)
                    drawn += 1
                break
        return drawn

    def show(self, q: np.ndarray) -> np.ndarray:
        """Move the frames to configuration q; returns the frames (n+1, 4, 4)."""
        Ts = self.chain.frames(q)
        wxyz, pos = _wxyz_position(Ts)
        pos = pos + self.offset
        for node, w, p in zip(self.nodes, wxyz, pos, strict=True):
            node.wxyz = w
            node.position = p
        return Ts


class Viewer:
    """A live 3-D view of an arm in the browser (viser), served from a background thread.

    Example::

        v = rc.viewer.Viewer(chain, q)          # prints nothing; open v.url in a browser
        for _ in range(10_000):
            cmd = ctrl.step(q, target=v.target, dt=dt)   # follow the gizmo the user drags
            q = cmd.q_next
            v.update(q, command=cmd)            # never blocks: the viewer throttles itself
        v.close()

    Args:
        chain: the arm. Its URDF geometry (`Chain.visuals`) is drawn where the mesh files
            can be read; otherwise (or with ``meshes=False``) capsules along the links
            (see `ratectl.viewer.geometry`).
        q: the configuration shown first (n,) [rad or m]; default zeros.
        host: the address served on (default loopback, ``127.0.0.1``: only this machine
            can connect).
        port: the TCP port; default None lets the system choose a free one (see `url`).
        target: the target pose (4×4) of the gizmo; default the tool pose at ``q``.
        path: a path to draw: a `ratectl.paths.Path`, (m, 3) points or (m, 4, 4) poses.
        meshes: draw the model file's meshes when the chain has them (default True).
        sliders: add one slider per joint; moving one shows that configuration (`q`
            reads it), as ``ratectl view`` does.
        rate_hz: the most scene updates a second (default 30).
        verbose: let viser print its banner and connection messages.

    Raises:
        InputError: a bad argument; RatectlError: the server cannot be started.
    """

    def __init__(self, chain: Chain, q: ArrayLike | None = None, *, host: str = "127.0.0.1",
                 port: int | None = None, target: ArrayLike | None = None, path: Any = None,
                 meshes: bool = True, sliders: bool = False, rate_hz: float = 30.0,
                 verbose: bool = False) -> None:
        if not isinstance(chain, Chain):
            raise InputError(f"chain must be a ratectl.Chain, got {type(chain).__name__}",
                             argument="chain", value=chain)
        self._chain = chain
        n = chain.dof
        q0 = np.zeros(n) if q is None else self._check_q(q)
        if not (isinstance(rate_hz, int | float) and math.isfinite(rate_hz) and rate_hz > 0):
            raise InputError(f"rate_hz must be a positive number of updates per second, got {rate_hz!r}",
                             argument="rate_hz", value=rate_hz)
        if port is not None and not (isinstance(port, int) and 0 <= port <= 65535):
            raise InputError(f"port must be a TCP port number 0…65535 or None, got {port!r}",
                             argument="port", value=port)
        self._period = 1.0 / float(rate_hz)
        self._lock = threading.Lock()
        self._cond = threading.Condition(self._lock)
        self._closed = False
        self._verbose = bool(verbose)
        try:
            with _quiet(not verbose):
                self._server = viser.ViserServer(host=host, port=0 if port is None else port,
                                                 verbose=verbose)
        except (OSError, RuntimeError) as exc:
            raise RatectlError(f"the viewer cannot serve on {host}:{port}: {exc}") from exc
        self._host = host
        # the scale of the drawing: how far the arm extends from its base at q0 (frames and
        # tool), at least a third of the sum of its link lengths
        Ts = chain.frames(q0)
        pts = np.concatenate([Ts[:, :3, 3], (Ts[-1] @ chain.tool)[None, :3, 3]])
        extent = float(np.max(np.linalg.norm(pts - chain.base[:3, 3], axis=1)))
        self._L = max(extent, chain.reach() / 3.0, 1e-3)
        self._radius = min(max(0.035 * self._L, 0.004), 0.06)
        self._q = q0
        self._command: Any = None
        self._note = ""
        self._seq = 1                 # states stored
        self._drawn = 0               # states drawn (a state and all before it)
        self._frames = 0              # scene updates made by the drawing thread
        self._lost_handle: Any = None
        self._path_handle: Any = None
        self._lost_key: tuple = ()
        self._replay: dict[str, Any] | None = None
        self._extra_arms: list[_Arm] = []
        self._text = ""
        self._draw_lock = threading.RLock()
        self._player: threading.Thread | None = None
        try:
            self._build_scene(q0, target, path, meshes, sliders)
        except Exception:
            self._server.stop()
            raise
        self._thread = threading.Thread(target=self._loop, name="ratectl-viewer", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ public
    @property
    def url(self) -> str:
        """The address to open in a browser, ``http://HOST:PORT``."""
        host = "127.0.0.1" if self._host in ("0.0.0.0", "") else self._host
        return f"http://{host}:{self._server.get_port()}"

    @property
    def port(self) -> int:
        """The TCP port served on."""
        return int(self._server.get_port())

    @property
    def server(self) -> viser.ViserServer:
        """The viser server, to add your own scene nodes or controls (see viser's docs)."""
        return self._server

    @property
    def chain(self) -> Chain:
        return self._chain

    @property
    def q(self) -> np.ndarray:
        """The configuration last given to `update` or set with a slider (read-only copy)."""
        with self._lock:
            return read_only(self._q)

    @property
    def text(self) -> str:
        """The status text shown beside the arm (markdown): σ_min, kind, command, replay."""
        with self._lock:
            return self._text

    @property
    def meshes_drawn(self) -> int:
        """How many pieces of model-file geometry are drawn (0: the arm is drawn as capsules)."""
        return self._arm.drawn_meshes

    @property
    def arm_visible(self) -> bool:
        """Whether the arm (with its tool frame) is drawn; settable."""
        return bool(self._arm.nodes[0].visible)

    @arm_visible.setter
    def arm_visible(self, on: bool) -> None:
        for node in self._arm.nodes:
            node.visible = bool(on)

    def update(self, q: ArrayLike, command: Any = None, *, note: str = "") -> None:
        """Show configuration ``q`` (n,) and, optionally, the controller's `ratectl.Command`.

        Returns at once: the state is stored and drawn by the viewer's thread at most
        ``rate_hz`` times a second (intermediate states are dropped). ``note`` is a line of
        text shown with the status.
        """
        a = self._check_q(q)
        with self._cond:
            if self._closed:
                return
            self._q = a
            self._command = command
            self._note = str(note)
            self._seq += 1
            self._cond.notify_all()

    def sync(self, timeout: float = 5.0) -> bool:
        """Wait until everything given to `update` so far is drawn (sent to the browser);
        False when ``timeout`` [s] passed first. For tests and scripts, not control loops."""
        deadline = time.monotonic() + timeout
        with self._cond:
            want = self._seq
            while self._drawn < want and not self._closed:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(left)
            return self._drawn >= want

    @property
    def target(self) -> np.ndarray:
        """The target pose (4×4, read-only): exactly as last set from Python, or as the user
        dragged it in the browser, whichever happened last."""
        with self._lock:
            return self._target

    @target.setter
    def target(self, T: ArrayLike) -> None:
        T = self._check_pose(T, "target")
        with self._lock:
            self._target = T
            wxyz, pos = _wxyz_position(T)
            self._sent_target = (wxyz, pos)
        self._gizmo.wxyz = wxyz
        self._gizmo.position = pos

    def set_path(self, path: Any) -> None:
        """Draw a path (a `ratectl.paths.Path`, (m, 3) points or (m, 4, 4) poses), replacing
        the one drawn; None removes it."""
        if path is None:
            if self._path_handle is not None:
                self._path_handle.remove()
                self._path_handle = None
            return
        pts = path_points(path)
        segs = np.stack([pts[:-1], pts[1:]], axis=1)
        if self._path_handle is not None:
            self._path_handle.remove()
        self._path_handle = self._server.scene.add_line_segments(
            "/path", segs, colors=_PATH_RGB, thickness=max(0.4 * self._radius, 0.003))

    def replay(self, run: Any, *, others: Mapping[str, Any] | None = None, spacing: float | None = None,
               play: bool = False, speed: float = 1.0) -> None:
        """Play a recorded run with a time slider: an `ratectl.Execution` (from `ratectl.follow`
        or `ratectl.run`) or anything with ``t`` (K,) and ``q`` (K, n).

        Beside the arm: the time, the controller status and singularity kind of the step, the
        distance from the path (position and orientation error) and the largest |q̇_i|/vmax_i
        and |q̈_i|/amax_i of the step, where the run has them. The tool's trace is drawn.

        Args:
            run: the run shown on this viewer's arm.
            others: more runs of the same arm, by name, drawn side by side (each a copy of the
                arm ``spacing`` further along the base y axis; default 1.2 × reach), on the
                same time slider — e.g. the methods of ``ratectl demo``.
            play: start playing at once (a checkbox in the browser starts and stops it).
            speed: playback speed (1 = real time).
        """
        runs = {"": run, **dict(others or {})}
        rows = {name: self._replay_rows(name or "run", r) for name, r in runs.items()}
        if not (isinstance(speed, int | float) and math.isfinite(speed) and speed > 0):
            raise InputError(f"speed must be a positive number, got {speed!r}", argument="speed",
                             value=speed)
        step = self._L * 1.2 if spacing is None else float(spacing)
        t_end = max(float(r["t"][-1]) for r in rows.values())
        t_start = min(float(r["t"][0]) for r in rows.values())
        gui = self._server.gui
        if self._replay is not None:
            self._replay["folder"].remove()
        for arm in self._extra_arms:
            for node in arm.nodes:
                node.remove()
        self._extra_arms = []
        for i, name in enumerate(list(rows)[1:], start=1):
            offset = np.array([0.0, i * step, 0.0])
            arm = _Arm(self._server, self._chain, f"/replay/arm{i}", offset=offset, meshes=True,
                       radius=self._radius)
            self._extra_arms.append(arm)
            self._server.scene.add_label(f"/replay/label{i}", name,
                                         position=offset + np.array([0.0, 0.0, 0.9 * self._L]))
        if others:
            self._server.scene.add_label("/replay/label0", getattr(run, "method", "") or "run",
                                         position=np.array([0.0, 0.0, 0.9 * self._L]))
        for i, r in enumerate(rows.values()):
            p = self._chain.fk(r["q"])[:, :3, 3] + np.array([0.0, i * step, 0.0])
            if len(p) >= 2:
                self._server.scene.add_line_segments(f"/replay/trace{i}", np.stack([p[:-1], p[1:]], 1),
                                                     colors=_TRACE_RGB,
                                                     thickness=max(0.3 * self._radius, 0.002))
        folder = gui.add_folder("Replay")
        with folder:
            dt = float(np.median(np.diff(rows[""]["t"]))) if len(rows[""]["t"]) > 1 else 1e-3
            slider = gui.add_slider("time [s]", min=t_start, max=max(t_end, t_start + dt),
                                    step=dt, initial_value=t_start)
            playing = gui.add_checkbox("play", initial_value=play)
        self._replay = dict(rows=rows, slider=slider, playing=playing, folder=folder, speed=float(speed),
                            t_start=t_start, t_end=t_end, name=getattr(run, "method", "") or "run")
        slider.on_update(lambda _event: self._show_replay(float(slider.value)))
        self._show_replay(t_start)
        if self._player is None:
            self._player = threading.Thread(target=self._play, name="ratectl-viewer-replay", daemon=True)
            self._player.start()

    def _play(self) -> None:
        """Advance the time slider while "play" is checked (wrapping at the end)."""
        last = time.monotonic()
        while not self._closed:
            time.sleep(self._period)
            now = time.monotonic()
            r = self._replay
            if r is not None and r["playing"].value:
                t = float(r["slider"].value) + r["speed"] * (now - last)
                if t > r["t_end"]:
                    t = r["t_start"]
                try:
                    r["slider"].value = t  # its callback draws the step
                except Exception:  # noqa: BLE001 - the server is stopping
                    return
            last = now

    def seek(self, t: float) -> None:
        """Show the replay at time ``t`` [s] (moves the time slider)."""
        if self._replay is None:
            raise InputError("seek needs a replay: call replay(run) first", argument="t", value=t)
        t = min(max(float(t), self._replay["t_start"]), self._replay["t_end"])
        self._replay["slider"].value = t
        self._show_replay(t)

    def close(self) -> None:
        """Stop the drawing thread and the server (the page in the browser goes stale)."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
            self._cond.notify_all()
        self._thread.join(timeout=5.0)
        if self._player is not None:
            self._player.join(timeout=5.0)
        with _quiet(not self._verbose):
            self._server.stop()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "closed" if self._closed else self.url
        return f"Viewer({self._chain.name!r}, {state})"

    # ------------------------------------------------------------------ building
    def _check_q(self, q: ArrayLike) -> np.ndarray:
        a = self._chain.check_q(q)
        if a.shape != (self._chain.dof,):
            raise InputError(f"q must have shape ({self._chain.dof},) — one configuration — got "
                             f"shape {a.shape}", argument="q", value=q)
        return a.copy()

    @staticmethod
    def _check_pose(T: ArrayLike, name: str) -> np.ndarray:
        defect = rigid_transform_defect(T)
        if defect is not None:
            raise InputError(f"{name} {defect}", argument=name, value=T)
        return read_only(np.array(T, dtype=float))

    def _build_scene(self, q0, target, path, meshes, sliders) -> None:
        server, L = self._server, self._L
        scene = server.scene
        scene.set_up_direction("+z")
        server.gui.configure_theme(control_width="medium", show_share_button=False)
        base = self._chain.base
        scene.add_grid("/grid", width=3.0 * L, height=3.0 * L, cell_size=0.1, section_size=0.5,
                       position=(base[0, 3], base[1, 3], base[2, 3]))
        self._arm = _Arm(server, self._chain, "/arm", offset=np.zeros(3), meshes=meshes,
                         radius=self._radius)
        Ts = self._arm.show(q0)
        tool = Ts[-1] @ self._chain.tool
        server.initial_camera.position = tuple(base[:3, 3] + np.array([1.25, -1.6, 0.95]) * L)
        server.initial_camera.look_at = tuple(base[:3, 3] + np.array([0.0, 0.0, 0.35 * L]))
        T = tool if target is None else self._check_pose(target, "target")
        self._target = read_only(np.array(T))
        wxyz, pos = _wxyz_position(self._target)
        self._sent_target = (wxyz, pos)
        self._gizmo = scene.add_transform_controls("/target", scale=0.3 * L, wxyz=wxyz, position=pos,
                                                   depth_test=False)
        scene.add_frame("/target/axes", axes_length=0.08 * L, axes_radius=0.006 * L,
                        origin_radius=0.012 * L)
        self._gizmo.on_update(self._on_drag)
        self._path_handle = None
        if path is not None:
            self.set_path(path)
        with server.gui.add_folder("ratectl"):
            self._status = server.gui.add_markdown("")
        self._sliders = []
        if sliders:
            with server.gui.add_folder("Joints"):
                for k, j in enumerate(self._chain.joints):
                    lo, hi = j.qlim
                    span = 1.0 if j.kind == "prismatic" else math.pi
                    lo = lo if math.isfinite(lo) else -span
                    hi = hi if math.isfinite(hi) else span
                    s = server.gui.add_slider(j.name, min=lo, max=hi, step=(hi - lo) / 1000.0,
                                              initial_value=float(min(max(q0[k], lo), hi)))
                    s.on_update(self._on_slider)
                    self._sliders.append(s)
        self._draw(q0, None, "")

    # ------------------------------------------------------------------ callbacks (viser threads)
    def _on_drag(self, event: Any) -> None:
        if event.client is None:
            return
        g = event.target
        wxyz, pos = np.array(g.wxyz, dtype=float), np.array(g.position, dtype=float)
        with self._lock:
            sw, sp = self._sent_target
            if np.allclose(wxyz, sw, atol=1e-6) and np.allclose(pos, sp, atol=1e-6):
                return  # the browser echoing the pose set from Python
            self._target = read_only(_pose(wxyz, pos))
            self._sent_target = (wxyz, pos)

    def _on_slider(self, event: Any) -> None:
        if event.client is None:
            return
        q = np.array([float(s.value) for s in self._sliders])
        self.update(q)

    # ------------------------------------------------------------------ drawing (viewer thread)
    def _loop(self) -> None:
        next_time = 0.0
        while True:
            with self._cond:
                while self._drawn >= self._seq and not self._closed:
                    self._cond.wait(0.5)
                if self._closed:
                    return
            wait = next_time - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            with self._cond:
                seq, q, command, note = self._seq, self._q, self._command, self._note
            try:
                self._draw(q, command, note)
                self._frames += 1
            except Exception:  # noqa: BLE001 - drawing must never take the caller down
                if self._closed:
                    return
            next_time = time.monotonic() + self._period
            with self._cond:
                self._drawn = seq
                self._cond.notify_all()

    def _draw(self, q: np.ndarray, command: Any, note: str, *, replay_lines: tuple[str, ...] = ()) -> None:
        with self._draw_lock:
            self._draw_locked(q, command, note, replay_lines)

    def _draw_locked(self, q: np.ndarray, command: Any, note: str, replay_lines: tuple[str, ...]) -> None:
        report = analyze(self._chain, q)
        with self._server.atomic():
            Ts = self._arm.show(q)
            self._draw_lost(report, Ts[-1] @ self._chain.tool)
            if self._sliders and not replay_lines:
                for s, v in zip(self._sliders, q, strict=True):
                    v = float(min(max(v, s.min), s.max))
                    if abs(float(s.value) - v) > 1e-9:
                        s.value = v  # type: ignore[misc]  # (viser's setter; mypy sees the getter)
        lines = [f"**{self._chain.name}** — {self._chain.dof} joints",
                 f"σ_min(J_L) = {report.sigma_min_scaled:.4g} · kind: **{report.kind}**"
                 + (" (near-singular)" if report.near_singular and not report.singular else "")
                 + (" (singular)" if report.singular else "")]
        if report.kind != "regular":
            lines.append(f"{report.reason}")
        if command is not None:
            status = getattr(command, "status", "?")
            e_p = 1e3 * getattr(command, "position_error", math.nan)
            e_a = math.degrees(getattr(command, "orientation_error", math.nan))
            lines.append(f"command: **{status}**, |e| = {e_p:.1f} mm, {e_a:.2f}°, "
                         f"damping {getattr(command, 'damping', math.nan):.3g}")
        lines.extend(replay_lines)
        if note:
            lines.append(note)
        text = "\n\n".join(lines)
        with self._lock:
            self._text = text
        if self._status.content != text:
            self._status.content = text

    def _draw_lost(self, report: Any, tool: np.ndarray) -> None:
        dirs = lost_directions(report)
        key = tuple((name, tuple(np.round(d, 3))) for name, d in dirs) + (tuple(np.round(tool[:3, 3], 4)),)
        if key == self._lost_key:
            return
        self._lost_key = key
        if self._lost_handle is not None:
            self._lost_handle.remove()
            self._lost_handle = None
        if not dirs:
            return
        p = tool[:3, 3]
        length = 0.3 * self._L
        pts = np.array([[p, p + length * d] for _, d in dirs])
        colors = np.array([_LOST_RGB[name] for name, _ in dirs], dtype=np.uint8)
        self._lost_handle = self._server.scene.add_arrows(
            "/lost", pts, colors=colors, shaft_radius=0.25 * self._radius, head_radius=0.6 * self._radius,
            head_length=1.6 * self._radius)

    # ------------------------------------------------------------------ replay
    def _replay_rows(self, name: str, run: Any) -> dict[str, Any]:
        try:
            t = np.asarray(run.t, dtype=float)
            q = np.asarray(run.q, dtype=float)
        except (AttributeError, TypeError, ValueError):
            raise InputError(f"replay needs a run with t (K,) and q (K, n) (an Execution), got "
                             f"{type(run).__name__}", argument="run", value=run) from None
        if t.ndim != 1 or len(t) == 0 or q.shape != (len(t), self._chain.dof) or \
                not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))):
            raise InputError(f"replay of {name!r}: t must be (K,) and q (K, {self._chain.dof}) finite "
                             f"arrays, got {t.shape} and {q.shape}", argument="run", value=run)

        def opt(attr):
            v = getattr(run, attr, None)
            return None if v is None else np.asarray(v, dtype=float)

        vmax = opt("vmax")
        amax = opt("amax")
        if vmax is None:
            vmax = np.asarray(self._chain.vmax)
        if amax is None:
            amax = np.asarray(self._chain.amax)
        statuses = tuple(getattr(run, "statuses", ()) or ())
        kinds = getattr(run, "kinds", None)
        return dict(t=t, q=q, qd=opt("qd"), qdd=opt("qdd"), pos=opt("position_error"),
                    ang=opt("orientation_error"), statuses=statuses,
                    kinds=tuple(kinds) if kinds is not None else (), vmax=vmax, amax=amax)

    def _show_replay(self, t: float) -> None:
        assert self._replay is not None
        rows = self._replay["rows"]
        lines = []
        q_main = None
        with self._server.atomic():
            for i, (name, r) in enumerate(rows.items()):
                k = int(min(np.searchsorted(r["t"], t, side="right") - 1, len(r["t"]) - 1))
                k = max(k, 0)
                if i == 0:
                    q_main = r["q"][k]
                else:
                    self._extra_arms[i - 1].show(r["q"][k])
                lines.append(self._replay_line(name or self._replay["name"], r, k))
        assert q_main is not None
        with self._cond:
            self._q = q_main.copy()
        self._draw(q_main, None, "", replay_lines=(f"replay: t = {t:.3f} s", *lines))

    @staticmethod
    def _replay_line(name: str, r: dict[str, Any], k: int) -> str:
        bits = [f"**{name}**:"]
        if r["statuses"]:
            bits.append(f"status **{r['statuses'][k]}**")
        if r["kinds"] and r["kinds"][k]:
            bits.append(f"({r['kinds'][k]})")
        if r["pos"] is not None:
            bits.append(f"path error {1e3 * r['pos'][k]:.2f} mm")
        if r["ang"] is not None:
            bits.append(f"{math.degrees(r['ang'][k]):.3f}°")
        with np.errstate(divide="ignore", invalid="ignore"):
            if r["qd"] is not None and np.all(np.isfinite(r["vmax"])):
                bits.append(f"max |q̇|/vmax {float(np.max(np.abs(r['qd'][k]) / r['vmax'])):.2f}")
            if r["qdd"] is not None and np.all(np.isfinite(r["amax"])):
                bits.append(f"max |q̈|/amax {float(np.max(np.abs(r['qdd'][k]) / r['amax'])):.2f}")
        return " ".join(bits)
