"""The head camera drawn by MuJoCo: offscreen OpenGL on the CPU (EGL or OSMesa, Mesa's llvmpipe).

An OpenGL context belongs to the thread that made it current, and MuJoCo's render context to
that GL context. So the camera owns one thread of its own: it creates the GL context, the
``MjrContext`` and a private ``MjData`` there, and draws every frame there. Callers hand it a
copy of the state (:meth:`MujocoCamera.capture`, cheap, under the world's lock) and wait for the
frame, so physics never waits for a frame being drawn and never shares its ``MjData`` with GL.

The backend is ``MUJOCO_GL`` (``egl`` or ``osmesa``) when set, else EGL then OSMesa. When no
backend can make a context the constructor raises :class:`GLUnavailableError` (a
:class:`~schemas.errors.CameraError`), one line naming the cause and the fix, and the world falls
back to its OpenCV renderer. Shadows, reflections, skybox and haze are off: on llvmpipe they cost
the camera most of its frame rate (reference/physics.md: 17–22 fps with them, 140–190 without).

Frames are BGR ``uint8`` (height, width, 3), row 0 at the top: what the OpenCV renderer returns
and the ``sim`` camera source sends.
"""

from __future__ import annotations

import atexit
import logging
import os
import queue
import threading
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from schemas.errors import CameraError
from schemas.extras import message

if TYPE_CHECKING:
    import mujoco

log = logging.getLogger(__name__)

BACKENDS = ("egl", "osmesa")
# Long enough for llvmpipe to compile its shaders on a busy machine; a hung driver gives up here.
START_TIMEOUT_S = 30.0
FRAME_TIMEOUT_S = 10.0
_DISABLED = ("disable", "disabled", "off", "false", "0")
_OFF_FLAGS = ("mjRND_SHADOW", "mjRND_REFLECTION", "mjRND_SKYBOX", "mjRND_HAZE")
# Render threads, ended at exit while the interpreter can still run them (a daemon thread left
# to finalization died there with a traceback). The queues are those not yet told to end; the
# threads are joined whoever told them (a camera's finalizer may already have, at exit too).
_RUNNING: dict[threading.Thread, queue.Queue[Any]] = {}
_THREADS: weakref.WeakSet[threading.Thread] = weakref.WeakSet()
_exit_hook: list[bool] = []  # registered once, see _end_at_exit
_BUFFER_SIZE = threading.Lock()  # see _RenderThread.run


def _end(thread: threading.Thread) -> None:
    requests = _RUNNING.pop(thread, None)
    if requests is not None:
        requests.put(None)


def _end_render_threads() -> None:
    for thread in list(_RUNNING):
        _end(thread)
    for thread in list(_THREADS):
        thread.join(timeout=5.0)


def _end_at_exit() -> None:
    # After the first context exists: mujoco.egl registers the termination of its display then,
    # and exit hooks run last-registered first, so the threads free their contexts before it.
    if not _exit_hook:
        _exit_hook.append(True)
        atexit.register(_end_render_threads)


class GLUnavailableError(CameraError):
    """No OpenGL backend can make an offscreen context here (no EGL/OSMesa libraries, or
    PyOpenGL missing): use the OpenCV renderer instead."""


@dataclass(frozen=True)
class CameraState:
    """What the camera needs of the physics state: a copy taken under the world's lock."""

    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray


def backend_order() -> tuple[str, ...]:
    """The GL backends to try, in order. PyOpenGL binds one platform per process, so an
    explicit ``MUJOCO_GL`` or ``PYOPENGL_PLATFORM`` is the only one tried; ``MUJOCO_GL=disable``
    (MuJoCo's own word) tries none: the world draws with OpenCV."""
    if os.environ.get("MUJOCO_GL", "").strip().lower() in _DISABLED:
        return ()
    for var in ("MUJOCO_GL", "PYOPENGL_PLATFORM"):
        chosen = os.environ.get(var, "").strip().lower()
        if chosen in BACKENDS:
            return (chosen,)
    return BACKENDS


def _gl_context_class(backend: str) -> Any:
    if backend == "egl":
        from mujoco.egl import GLContext
    else:
        from mujoco.osmesa import GLContext
    return GLContext


class MujocoCamera:
    """Renders ``camera`` of ``model`` at ``width`` × ``height`` in a thread of its own."""

    def __init__(
        self, model: mujoco.MjModel, width: int, height: int, camera: str = "head_camera"
    ) -> None:
        try:
            import mujoco
        except ImportError as exc:
            raise GLUnavailableError(message("physics", f"the MuJoCo camera ({exc})")) from None
        self.model = model
        self.width, self.height = int(width), int(height)
        self.camera_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        if self.camera_id < 0:
            cams = mujoco.mjtObj.mjOBJ_CAMERA
            names = [mujoco.mj_id2name(model, cams, i) for i in range(model.ncam)]
            raise CameraError(f"the model has no camera named {camera!r} (it has {names})")
        self.camera = camera
        self.backend = ""
        self.frames = 0
        self._requests: queue.Queue[tuple[CameraState, queue.Queue[Any]] | None] = queue.Queue()
        self._lock = threading.Lock()  # one frame at a time: callers queue behind each other
        self._closed = False
        started: queue.Queue[BaseException | str] = queue.Queue()
        # The thread holds the model and the queue, never this object: a camera nobody holds
        # any more is collected, and the finalizer tells the thread to free GL and end.
        server = _RenderThread(mujoco, model, self.width, self.height, self.camera_id)
        self._thread = threading.Thread(
            target=server.run,
            args=(self._requests, started),
            name=f"mujoco-camera-{camera}",
            daemon=True,
        )
        self._thread.start()
        try:
            outcome = started.get(timeout=START_TIMEOUT_S)
        except queue.Empty:
            self._closed = True
            raise GLUnavailableError(
                f"the GL context did not start within {START_TIMEOUT_S:.0f} s "
                "(a hung GL driver?); set MUJOCO_GL=osmesa or run without the MuJoCo camera"
            ) from None
        if isinstance(outcome, BaseException):
            self._closed = True
            self._thread.join(timeout=5.0)
            raise outcome
        self.backend = outcome
        _RUNNING[self._thread] = self._requests
        _THREADS.add(self._thread)
        _end_at_exit()
        weakref.finalize(self, _end, self._thread)

    def __repr__(self) -> str:
        state = "closed" if self._closed else f"{self.frames} frames"
        return f"<MujocoCamera {self.camera} {self.width}×{self.height} {self.backend}: {state}>"

    # -- the caller's side -----------------------------------------------------------------------
    def capture(self, data: mujoco.MjData) -> CameraState:
        """A copy of what a frame needs: take it under the lock that guards ``data``."""
        return CameraState(data.qpos.copy(), data.mocap_pos.copy(), data.mocap_quat.copy())

    def render(self, data: mujoco.MjData | CameraState) -> np.ndarray:
        """The camera's view of ``data`` (or of a captured state): BGR uint8 (h, w, 3)."""
        state = data if isinstance(data, CameraState) else self.capture(data)
        if state.qpos.shape != (self.model.nq,):
            raise CameraError(
                f"a state with {state.qpos.size} qpos for a model with {self.model.nq}"
            )
        reply: queue.Queue[Any] = queue.Queue(maxsize=1)
        with self._lock:
            if self._closed or not self._thread.is_alive():
                raise CameraError("the MuJoCo camera is closed")
            self._requests.put((state, reply))
            try:
                result = reply.get(timeout=FRAME_TIMEOUT_S)
            except queue.Empty:
                raise CameraError(
                    f"the MuJoCo camera drew no frame within {FRAME_TIMEOUT_S:.0f} s"
                ) from None
        if isinstance(result, BaseException):
            raise CameraError(f"the MuJoCo camera failed to draw: {result}") from result
        self.frames += 1
        return result

    def close(self) -> None:
        """Stop the render thread; it frees its GL resources on the way out."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            _end(self._thread)
        self._thread.join(timeout=5.0)

    def __enter__(self) -> MujocoCamera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _RenderThread:
    """The camera's own thread: it makes the GL context current and draws every frame."""

    def __init__(self, mj: Any, model: Any, width: int, height: int, camera_id: int) -> None:
        self.mj, self.model, self.width, self.height = mj, model, width, height
        self.camera_id = camera_id

    def _open_context(self) -> tuple[Any, str]:
        if not backend_order():
            raise GLUnavailableError("MUJOCO_GL=disable turns the MuJoCo camera off")
        errors = []
        for backend in backend_order():
            try:
                ctx = _gl_context_class(backend)(self.width, self.height)
                ctx.make_current()
            except Exception as exc:  # ImportError, a missing library, a failed eglInitialize
                first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                errors.append(f"{backend}: {first}")
                continue
            return ctx, backend
        raise GLUnavailableError(
            f"no OpenGL backend for the MuJoCo camera ({'; '.join(errors)}); install EGL or "
            "OSMesa (apt-get install libegl1 libgl1-mesa-dri libosmesa6) and PyOpenGL, or the "
            "world uses its OpenCV renderer"
        )

    def run(self, requests: queue.Queue[Any], started: queue.Queue[BaseException | str]) -> None:
        mj, model = self.mj, self.model
        try:
            ctx, backend = self._open_context()
        except BaseException as exc:
            started.put(exc)
            return
        mjr = None
        try:
            # The offscreen buffer is the image's size: llvmpipe clears and multisamples all
            # of it every frame, and the model's 640 × 480 made a 320 × 240 frame cost ~7 %
            # more CPU. The context reads the size as it is made, so one camera at a time sets
            # it (cameras of other sizes may share the model); visual settings only.
            with _BUFFER_SIZE:
                glob = model.vis.global_
                glob.offwidth, glob.offheight = self.width, self.height
                mjr = mj.MjrContext(model, mj.mjtFontScale.mjFONTSCALE_100.value)
            mj.mjr_setBuffer(mj.mjtFramebuffer.mjFB_OFFSCREEN.value, mjr)
            scene = mj.MjvScene(model, maxgeom=max(1000, 4 * model.ngeom))
            for name in _OFF_FLAGS:
                scene.flags[getattr(mj.mjtRndFlag, name)] = 0
            option = mj.MjvOption()
            cam = mj.MjvCamera()
            cam.type = mj.mjtCamera.mjCAMERA_FIXED
            cam.fixedcamid = self.camera_id
            data = mj.MjData(model)
            rect = mj.MjrRect(0, 0, self.width, self.height)
            rgb = np.empty((self.height, self.width, 3), dtype=np.uint8)
        except BaseException as exc:
            started.put(GLUnavailableError(f"the {backend} GL context is unusable: {exc}"))
            _free(ctx, mjr)
            return
        started.put(backend)
        try:
            while (item := requests.get()) is not None:
                state, reply = item
                try:
                    data.qpos[:] = state.qpos
                    data.mocap_pos[:] = state.mocap_pos
                    data.mocap_quat[:] = state.mocap_quat
                    # Positions only: body poses, then the cameras and lights that follow them.
                    mj.mj_kinematics(model, data)
                    mj.mj_comPos(model, data)
                    mj.mj_camlight(model, data)
                    mj.mjv_updateScene(
                        model, data, option, None, cam, mj.mjtCatBit.mjCAT_ALL.value, scene
                    )
                    mj.mjr_render(rect, scene, mjr)
                    mj.mjr_readPixels(rgb, None, rect, mjr)
                    # OpenGL's rows start at the bottom; RGB → BGR like OpenCV's images.
                    reply.put(np.ascontiguousarray(rgb[::-1, :, ::-1]))
                except Exception as exc:
                    reply.put(exc)
        finally:
            _free(ctx, mjr)


def _free(ctx: Any, mjr: Any) -> None:
    # Freed by the thread whose context is current: a context freed by the garbage collector
    # at exit raises from OSMesa's destructor.
    if mjr is not None:
        mjr.free()
    ctx.free()


class WorldCamera:
    """The physics world's head camera: MuJoCo's view while a GL backend works, else the
    world's OpenCV renderer (``fallback``). The MuJoCo camera and its thread are made on the
    first frame, so a world nobody watches starts no GL at all; a failure is logged once."""

    def __init__(
        self,
        model: mujoco.MjModel,
        width: int,
        height: int,
        fallback: Callable[[], np.ndarray],
        camera: str = "head_camera",
    ) -> None:
        self.model, self.width, self.height, self.camera = model, width, height, camera
        self.fallback = fallback
        self.mujoco: MujocoCamera | None = None
        self.unavailable: str | None = None  # why frames come from OpenCV
        self._make = threading.Lock()

    @property
    def renderer(self) -> str:
        """``mujoco-egl``/``mujoco-osmesa`` once MuJoCo draws, ``opencv`` after a fallback."""
        if self.mujoco is not None:
            return f"mujoco-{self.mujoco.backend}"
        return "opencv" if self.unavailable else "not started"

    def render(self, lock: Any, data: mujoco.MjData) -> np.ndarray:
        """A frame of ``data``, whose state is copied under ``lock`` (the world's)."""
        cam = self._camera()
        if cam is None:
            return self.fallback()
        with lock:
            state = cam.capture(data)
        return cam.render(state)

    def _camera(self) -> MujocoCamera | None:
        with self._make:
            if self.mujoco is None and self.unavailable is None:
                try:
                    self.mujoco = MujocoCamera(self.model, self.width, self.height, self.camera)
                except GLUnavailableError as exc:
                    self.unavailable = str(exc)
                    log.warning("%s: the camera draws with OpenCV", exc)
            return self.mujoco

    def close(self) -> None:
        with self._make:
            if self.mujoco is not None:
                self.mujoco.close()
