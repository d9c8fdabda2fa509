"""The live explorer: a viser server (its web client is bundled in the wheel: no CDN, works offline).

Long module: one class, :class:`ExplorerApp`: the viser controls and the refresh worker share its state and its lock.

Every control changes :class:`~arcube.explorer.live.LiveModel` and asks one worker thread to refresh; the worker coalesces
requests (a slider dragged fast re-evaluates only for its latest value), runs the kernel on the whole plan (skipped when only
the point along the plan moved), builds the scene at the point shown (:mod:`arcube.explorer.scene`) and sends it in one batch.
:attr:`ExplorerApp.timings` holds the last refresh's milliseconds; :meth:`ExplorerApp.wait_idle` waits for the worker.

The viewer works in metres (three.js' near and far planes suit them); the library's mm are scaled by :data:`SCALE` on the way in.
"""

from __future__ import annotations

import contextlib
import errno
import io
import logging
import socket
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from arcube import interrupts
from arcube.errors import InputError
from arcube.explorer import text
from arcube.explorer.live import Figures, LiveModel, View
from arcube.explorer.scene import cylinder_frames
from arcube.model.body import BodyRadii
from arcube.model.design import PARAM_NAMES, UNITS, Design
from arcube.model.mechanism import ALL_MODES, format_mode, parse_mode
from arcube.optimization.settings import DEFAULT_BOUNDS

__all__ = ["SCALE", "ExplorerApp", "check_port"]

SCALE = 1e-3
"""mm -> m."""
GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("TLS: m, f, p", ("m_x", "m_y", "m_z", "f_x", "f_y", "f_z", "p_x", "p_y", "p_z")),
    ("TMS: d, c, t", ("d_x", "d_y", "d_z", "c_x", "c_y", "t_x", "t_y")),
    ("RTS: r, o, α, β", ("r", "o_x", "o_y", "alpha_x", "alpha_y", "beta_x", "beta_y")),
    ("Mounting and tool: R, L", ("mount_rx", "mount_ry", "mount_rz", "L")),
)
_RADII = (
    ("link", "link radius (mm)", 1.0, 40.0),
    ("actuator", "actuator radius (mm)", 1.0, 80.0),
    ("motor", "motor radius (mm)", 1.0, 60.0),
    ("motor_length", "motor length (mm)", 1.0, 300.0),
)
_TOOL_RGB, _TIP_RGB, _PATIENT_RGB, _SELF_RGB = (60, 60, 70), (20, 20, 20), (220, 20, 60), (160, 40, 200)


def check_port(host: str, port: int) -> None:
    """InputError naming ``port`` when it is not a port number or something listens on it already, ``host`` when it is
    not an address of this machine."""
    if isinstance(port, bool) or not isinstance(port, int) or not 0 < port < 65536:
        raise InputError.of("port", f"must be an integer in 1..65535, got {port!r}")
    try:
        socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError) as exc:  # the address is wrong, not the port
        raise InputError.of(
            "host", f"{host!r}: not an address to listen on ({getattr(exc, 'strerror', None) or exc})"
        ) from None
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the server binds: TIME_WAIT is no conflict
        try:
            probe.bind((host, port))
            probe.listen(1)
        except OSError as exc:
            if exc.errno == errno.EADDRNOTAVAIL:  # not one of this machine's addresses
                raise InputError.of("host", f"{host}: not an address of this machine ({exc.strerror})") from None
            raise InputError.of(
                "port", f"{port} on {host} is in use or not available ({exc.strerror or exc}); choose another"
            ) from None


class ExplorerApp:
    """The server, its controls and scene, and the refresh worker (see the module docstring)."""

    def __init__(
        self,
        model: LiveModel,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        save_path: str | Path = "design_explored.json",
        anatomy_spec: list[str] | None = None,
        anatomy_frame: str = "LPS",
        title: str = "",
    ) -> None:
        import viser

        check_port(host, port)
        # a port scanner's aborted handshake is logged by websockets with a traceback; viser filters it late
        logging.getLogger("websockets").setLevel(logging.CRITICAL)
        self.model, self.host = model, host
        self.anatomy_spec, self.anatomy_frame = anatomy_spec, anatomy_frame
        with contextlib.redirect_stdout(io.StringIO()):  # viser prints its own banner; the caller prints the URL
            self.server = viser.ViserServer(host=host, port=port, label="AR-CUBE explorer", verbose=False)
        self.port = int(self.server.get_port())
        if self.port != port:  # viser moves to the next free port; a race with another program
            self._stop_server()
            raise InputError.of("port", f"{port} on {host} is in use; choose another")
        self.figures: Figures | None = None
        self.view: View | None = None
        self.timings: dict[str, float] = {}
        self.polish_thread: threading.Thread | None = None
        self._previous: Design | None = None
        self._cond = threading.Condition()
        self._need_eval = self._need_view = True
        self._requested, self._completed = 1, 0  # the first refresh
        self._stopping = False
        self._build_scene(title)
        self._build_gui(Path(save_path))
        self._worker = threading.Thread(target=self._run, name="arcube-explore-refresh", daemon=True)
        self._worker.start()

    @property
    def url(self) -> str:
        """The page's address."""
        host = "127.0.0.1" if self.host in ("0.0.0.0", "") else self.host
        return f"http://{host}:{self.port}"

    # ------------------------------------------------------------------ scene
    def _build_scene(self, title: str) -> None:
        import trimesh

        interrupts.check()  # trimesh's optional imports catch BaseException: a Ctrl-C there must not be lost
        sc, m = self.server.scene, self.model
        sc.set_up_direction("+z")
        sc.configure_default_lights(cast_shadow=False)  # shadow passes double the cost of a frame (software WebGL)
        if m.anatomy is not None:
            verts, faces = m.anatomy.vertices_faces()
            sc.add_mesh_simple(
                "/anatomy",
                verts * SCALE,
                faces,
                color=(232, 214, 170),
                opacity=0.5,
                side="double",
                cast_shadow=False,
                receive_shadow=False,
            )
        if m.envelope is not None:  # model §19.5: faint, so that the robot stays readable inside it
            from arcube.evaluation.envelope_drawing import envelope_meshes

            for name, mesh in envelope_meshes(m.envelope):
                sc.add_mesh_simple(
                    f"/envelope/{name}",
                    np.asarray(mesh.vertices) * SCALE,
                    np.asarray(mesh.faces),
                    color=(143, 168, 200),
                    opacity=0.12,
                    side="double",
                    cast_shadow=False,
                    receive_shadow=False,
                )
        drill = np.stack([m.plan.entry, m.plan.target], axis=1) * SCALE
        sc.add_line_segments("/plan/drill", drill, (0, 170, 200), thickness=3.0, thickness_units="screen")
        standoff = m.E_app.reshape(len(m.plan.ids), m.points, 3)[:, 0]
        sc.add_line_segments(
            "/plan/approach",
            np.stack([standoff, m.plan.entry], axis=1) * SCALE,
            (150, 200, 215),
            thickness=1.5,
            thickness_units="screen",
        )
        cyl = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=14)
        ball = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
        z4, z3 = np.tile([1.0, 0.0, 0.0, 0.0], (1, 1)), np.zeros((1, 3))
        flat = {"lod": "off", "cast_shadow": False, "receive_shadow": False}
        self.h_cyl = sc.add_batched_meshes_simple(
            "/robot/links", cyl.vertices, cyl.faces, z4, z3, batched_scales=np.zeros((1, 3)), **flat
        )
        self.h_ball = sc.add_batched_meshes_simple(
            "/robot/joints", ball.vertices, ball.faces, z4, z3, batched_scales=np.zeros(1), **flat
        )
        self.h_marks = sc.add_batched_meshes_simple(
            "/closest/ends",
            ball.vertices,
            ball.faces,
            np.tile(z4, (5, 1)),
            np.zeros((5, 3)),
            batched_scales=np.zeros(5),
            **flat,
        )
        nan_seg = np.zeros((1, 2, 3))
        self.h_patient = sc.add_line_segments(
            "/closest/patient", nan_seg, _PATIENT_RGB, thickness=4.0, thickness_units="screen", visible=False
        )
        self.h_self = sc.add_line_segments(
            "/closest/self", nan_seg, _SELF_RGB, thickness=4.0, thickness_units="screen", visible=False
        )
        centre = np.mean(np.concatenate([m.plan.entry, m.plan.target, m.x[None, :3]]), axis=0) * SCALE
        self.server.initial_camera.look_at = centre
        self.server.initial_camera.position = centre + np.array([0.22, -0.30, 0.22])
        self.server.initial_camera.near, self.server.initial_camera.far = 0.005, 50.0
        self.title = title

    def _draw(self, view: View) -> None:
        """Send the robot at ``view`` (the worker calls this inside ``server.atomic()``)."""
        s = view.solids
        ok = bool(np.all(np.isfinite(s.cylinders)))
        ends = np.concatenate([s.cylinders, np.stack([view.E, view.mp.H])[None]])
        radius = np.concatenate([s.cylinder_radius, [2.0]])
        pos, quat, length = cylinder_frames(ends)
        scales = np.stack([radius, radius, length], axis=1) * SCALE
        rgb = np.concatenate([view.part_rgb[s.cylinder_part], [_TOOL_RGB]])
        if not ok:
            scales[:] = 0.0
        self.h_cyl.batched_positions, self.h_cyl.batched_wxyzs = pos * SCALE, quat
        self.h_cyl.batched_scales, self.h_cyl.batched_colors = scales, rgb
        good = np.all(np.isfinite(s.spheres), axis=1) & ok
        self.h_ball.batched_positions = np.where(good[:, None], s.spheres, 0.0) * SCALE
        self.h_ball.batched_wxyzs = np.tile([1.0, 0.0, 0.0, 0.0], (len(good), 1))
        self.h_ball.batched_scales = np.where(good, s.sphere_radius, 0.0) * SCALE
        self.h_ball.batched_colors = view.part_rgb[s.sphere_part]
        marks, sizes, colours = [view.E], [3.0], [_TIP_RGB]
        for pair, handle, rgb_pair in (
            (view.patient, self.h_patient, _PATIENT_RGB),
            (view.self_, self.h_self, _SELF_RGB),
        ):
            shown = ok and bool(np.isfinite(pair.clearance))
            handle.visible = shown
            if shown:
                handle.points = np.stack([pair.robot, pair.other])[None] * SCALE
                marks += [pair.robot, pair.other]
            else:
                marks += [view.E, view.E]
            sizes += [3.0 if shown else 0.0] * 2
            colours += [rgb_pair] * 2
        self.h_marks.batched_positions = np.array(marks) * SCALE
        self.h_marks.batched_scales = np.array(sizes) * SCALE
        self.h_marks.batched_colors = np.array(colours, dtype=np.uint8)

    # ------------------------------------------------------------------ controls
    def _build_gui(self, save_path: Path) -> None:
        gui, m = self.server.gui, self.model
        gui.configure_theme(control_width="large", show_share_button=False, dark_mode=False)
        gui.add_markdown(f"**AR-CUBE explorer** · {self.title}")
        with gui.add_folder("Figures"):
            self.md_figures = gui.add_markdown("evaluating…")
            self.md_point = gui.add_markdown("")
            n = len(m)
            x = np.arange(n, dtype=float)
            self.plot = gui.add_uplot(
                (x, np.zeros(n), np.zeros(n), np.zeros(n)),
                (
                    {"label": "point"},
                    {"label": "100/η_L (%)", "stroke": "#1f77b4", "scale": "%"},
                    {"label": "clearance (mm)", "stroke": "#d62728", "scale": "mm"},
                    {"label": "self clearance (mm)", "stroke": "#9467bd", "scale": "mm"},
                ),
                axes=(
                    {},
                    {"scale": "%", "label": "100/η_L (%)"},
                    {"scale": "mm", "side": 1, "label": "mm", "grid": {"show": False}},
                ),
                scales={"x": {"time": False}, "%": {"auto": True}, "mm": {"range": (-10.0, 10.0)}},
                title="Along the lines (per trajectory: approach, then drill)",
                aspect=1.6,
            )
        with gui.add_folder("Point along the plan"):
            self.point = gui.add_slider("point", 0, len(m) - 1, 1, int(m.points))
            self.play = gui.add_checkbox(
                "play", False, hint="Step through the lines, approach then drill, trajectory after trajectory."
            )
        with gui.add_folder("Working mode and guards"):
            self.mode = gui.add_dropdown(
                "working mode", [format_mode(s) for s in ALL_MODES], initial_value=format_mode(m.mode)
            )
            self.guards = gui.add_checkbox(
                "guards of arcube design",
                m.guarded,
                hint="model §8.2 and the clearance requirements as guards; off: the paper's model.",
            )
        with gui.add_folder("Body radii", expand_by_default=False):
            self.radii = {
                k: gui.add_slider(label, lo, max(hi, getattr(m.radii, k)), 0.5, float(getattr(m.radii, k)))
                for k, label, lo, hi in _RADII
            }
        self.params: dict[str, Any] = {}
        with gui.add_folder("Design: 27 parameters", expand_by_default=False):
            for group, names in GROUPS:
                with gui.add_folder(group, expand_by_default=False):
                    for name in names:
                        v = float(m.x[PARAM_NAMES.index(name)])
                        lo, hi = DEFAULT_BOUNDS[name]
                        self.params[name] = gui.add_slider(f"{name} ({UNITS[name]})", min(lo, v), max(hi, v), 0.01, v)
        with gui.add_folder("Save and polish"):
            self.save_path = gui.add_text("save to", str(save_path))
            self.save_button = gui.add_button("Save design JSON")
            self.population = gui.add_number("population", 16, min=4, max=400, step=1)
            self.generations = gui.add_number("generations", 15, min=1, max=500, step=1)
            self.free = gui.add_text("free parameters", "all", hint="Names and groups (all, mount), as --free.")
            self.polish_button = gui.add_button(
                "Polish", hint="A short optimization near the current design; loads its best."
            )
            self.progress = gui.add_progress_bar(0.0, visible=False)
            self.revert_button = gui.add_button("Revert polish", visible=False)
            self.md_polish = gui.add_markdown("")
        for name, h in self.params.items():
            h.on_update(lambda ev, name=name: self._set_param(name, ev.target.value))
        for h in self.radii.values():
            h.on_update(lambda _: self._set_radii())
        self.mode.on_update(lambda ev: self._set(mode=parse_mode(ev.target.value)))
        self.guards.on_update(lambda ev: self._set(guarded=bool(ev.target.value)))
        self.point.on_update(lambda _: self.request(evaluate=False))
        self.play.on_update(lambda ev: self._start_play() if ev.target.value else None)
        self.save_button.on_click(self._on_save)
        self.polish_button.on_click(lambda ev: self.start_polish(ev.client))
        self.revert_button.on_click(lambda _: self._previous is not None and self.set_design(self._previous))

    def _set_param(self, name: str, value: float) -> None:
        self.model.set_param(name, value)
        self.request()

    def _set_radii(self) -> None:
        self.model.radii = BodyRadii(**{k: float(h.value) for k, h in self.radii.items()})
        self.request()

    def _set(self, **changes: Any) -> None:
        for k, v in changes.items():
            setattr(self.model, k, v)
        self.request()

    def set_design(self, design: Design) -> None:
        """Show ``design``: every parameter slider moved (bounds widened to hold it), one refresh."""
        for name, value in design.to_dict().items():
            h = self.params[name]
            h.min, h.max = min(h.min, value), max(h.max, value)
            h.value = float(value)
        self.model.load(design)
        self.request()

    def save(self, path: str | Path) -> Path:
        """Write the current design's JSON (atomically); returns the path."""
        out = Path(path).expanduser()
        self.model.current_design().to_json(out)
        return out

    def _on_save(self, event: Any) -> None:
        try:
            out = self.save(self.save_path.value)
        except (OSError, InputError) as exc:
            self._notify(event.client, "Not saved", str(exc), "red")
            return
        self._notify(event.client, "Design saved", str(out.resolve()), "green")
        if event.client is not None:
            event.client.send_file_download(out.name, out.read_bytes())

    @staticmethod
    def _notify(client: Any, title: str, body: str, colour: str) -> None:
        if client is not None:
            client.add_notification(title, body, auto_close_seconds=6.0, color=colour)

    def _start_play(self) -> None:
        def run() -> None:
            while self.play.value and not self._stopping:
                self.point.value = (int(self.point.value) + 1) % len(self.model)
                time.sleep(0.12)

        threading.Thread(target=run, name="arcube-explore-play", daemon=True).start()

    # ------------------------------------------------------------------ polish
    def start_polish(self, client: Any = None) -> threading.Thread | None:
        """Run :func:`arcube.explorer.polish.polish` in the background with the panel's settings."""
        if self.polish_thread is not None and self.polish_thread.is_alive():
            return None
        self.polish_thread = threading.Thread(
            target=self._polish, args=(client,), name="arcube-explore-polish", daemon=True
        )
        self.polish_thread.start()
        return self.polish_thread

    def _polish(self, client: Any) -> None:
        from arcube.explorer.polish import polish

        self.polish_button.disabled = True
        self.progress.value, self.progress.visible = 0.0, True
        self.md_polish.content = "polishing: starting…"

        def progress(row: dict[str, Any]) -> None:
            g, total = int(row["generation"]), int(row.get("total") or 1)
            self.progress.value = min(100.0, 100.0 * g / max(total, 1))
            best = row.get("best_eta_G")
            self.md_polish.content = (
                f"polishing: generation {g}/{total} · best η_G {best if best is None else f'{float(best):.4f}'}"
            )

        try:
            before = self.model.current_design()
            best, summary = polish(
                self.model,
                population=int(self.population.value),
                generations=int(self.generations.value),
                free=self.free.value,
                anatomy_spec=self.anatomy_spec,
                anatomy_frame=self.anatomy_frame,
                progress=progress,
            )
            self._previous = before
            self.set_design(best)
            eta = summary.get("eta_G")
            self.md_polish.content = (
                f"polished: {summary.get('generations', '?')} generations, {summary.get('evaluations', '?')} designs; "
                f"η_G {'—' if eta is None else f'{float(eta):.4f}'}, "
                f"{'feasible' if summary.get('feasible') else 'not feasible'}; loaded"
            )
            self.revert_button.visible = True
            self._notify(client, "Polish done", "the best design is loaded", "green")
        except InputError as exc:
            self.md_polish.content = f"polish: {exc}"
            self._notify(client, "Polish not run", str(exc), "red")
        except Exception as exc:  # a bug: shown, the server keeps running
            self.md_polish.content = f"polish failed: {type(exc).__name__}: {exc}"
        finally:
            self.progress.visible = False
            self.polish_button.disabled = False

    # ------------------------------------------------------------------ refresh worker
    def request(self, evaluate: bool = True) -> None:
        """Ask the worker for a refresh (re-evaluating unless only the point moved)."""
        with self._cond:
            self._need_eval |= evaluate
            self._need_view = True
            self._requested += 1
            self._cond.notify_all()

    def wait_idle(self, timeout: float = 30.0) -> bool:
        """Wait until every refresh asked for so far is drawn; False on timeout."""
        end = time.monotonic() + timeout
        with self._cond:
            target = self._requested
            while self._completed < target:
                left = end - time.monotonic()
                if left <= 0 or not self._worker.is_alive():
                    return False
                self._cond.wait(left)
        return True

    def refresh(self, evaluate: bool = True) -> dict[str, float]:
        """One refresh now, on the calling thread (what the worker runs); returns its timings (ms)."""
        t0 = time.perf_counter()
        if evaluate or self.figures is None:
            self.figures = self.model.evaluate()
        t1 = time.perf_counter()
        view = self.model.view(int(self.point.value))
        t2 = time.perf_counter()
        fig = self.figures
        with self.server.atomic():
            self._draw(view)
            self.md_figures.content = text.markdown_table(fig)
            self.md_point.content = text.point_line(view, fig)
            mm = np.concatenate([fig.points["clearance_mm"], fig.points["self_clearance_mm"]])
            lo, hi = (
                (float(np.min(mm[np.isfinite(mm)])), float(np.max(mm[np.isfinite(mm)])))
                if np.isfinite(mm).any()
                else (-10.0, 10.0)
            )
            pad = 0.05 * (hi - lo) + 1.0
            self.plot.scales = {"x": {"time": False}, "%": {"auto": True}, "mm": {"range": (lo - pad, hi + pad)}}
            self.plot.data = (
                np.arange(len(self.model), dtype=float),
                *(np.asarray(fig.points[k], float) for k in ("dexterity_pct", "clearance_mm", "self_clearance_mm")),
            )
        self.server.flush()
        t3 = time.perf_counter()
        self.view = view
        self.timings = {
            "evaluate_ms": 1e3 * (t1 - t0),
            "scene_ms": 1e3 * (t2 - t1),
            "draw_ms": 1e3 * (t3 - t2),
            "total_ms": 1e3 * (t3 - t0),
        }
        return self.timings

    def _run(self) -> None:
        while True:
            with self._cond:
                while not (self._need_view or self._stopping):
                    self._cond.wait()
                if self._stopping:
                    return
                evaluate, seq = self._need_eval, self._requested
                self._need_eval = self._need_view = False
            try:
                self.refresh(evaluate)
            except Exception as exc:  # keep serving; show what went wrong
                self.md_figures.content = f"refresh failed: {type(exc).__name__}: {exc}"
            with self._cond:
                self._completed = seq
                self._cond.notify_all()

    def stop(self) -> None:
        """Stop the worker and the server."""
        self.play.value = False
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
        self._worker.join(timeout=10)
        self._stop_server()

    def _stop_server(self) -> None:
        with contextlib.redirect_stdout(io.StringIO()):
            self.server.stop()
