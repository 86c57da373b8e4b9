"""A UVC camera through V4L2 asking for MJPEG: the camera's own JPEG bytes, without OpenCV.

The daemon forwards these bytes to viewers as they come (no decoding, no re-encoding, no
OpenCV: the robot's 32-bit Atom spends its core on the motion loop); only ball vision decodes,
at its own rate. The calls are the kernel's streaming I/O with memory-mapped buffers
(``Documentation/userspace-api/media/v4l/mmap.rst``): ``VIDIOC_QUERYCAP``, ``VIDIOC_S_FMT``
(``V4L2_PIX_FMT_MJPEG``), ``VIDIOC_S_PARM`` (frame rate, best effort), ``VIDIOC_REQBUFS``,
``VIDIOC_QUERYBUF`` + ``mmap``, ``VIDIOC_QBUF``, ``VIDIOC_STREAMON``, then per frame ``poll`` +
``VIDIOC_DQBUF`` (copy ``bytesused`` bytes) + ``VIDIOC_QBUF``.

The structures are ``ctypes`` structures of ``linux/videodev2.h``, so their sizes (and with
them the ioctl numbers) follow the platform's ABI: 32-bit i386 (the robot) and x86-64 differ in
``v4l2_buffer`` (``timeval`` and the pointer union) and ``v4l2_format``. Every system call goes
through a :class:`Device`, the seam where tests put a fake camera.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import fcntl
import mmap
import os
import select
from dataclasses import dataclass
from typing import Protocol

from robot_daemon.vision.frames import JpegFrame
from schemas.errors import CameraError

# -- linux/videodev2.h ---------------------------------------------------------------------------
V4L2_BUF_TYPE_VIDEO_CAPTURE = 1
V4L2_MEMORY_MMAP = 1
V4L2_FIELD_ANY = 0
V4L2_CAP_VIDEO_CAPTURE = 0x00000001
V4L2_CAP_STREAMING = 0x04000000
V4L2_CAP_DEVICE_CAPS = 0x80000000
V4L2_BUF_FLAG_ERROR = 0x00000040


def fourcc(code: str) -> int:
    a, b, c, d = (ord(ch) for ch in code)
    return a | b << 8 | c << 16 | d << 24


V4L2_PIX_FMT_MJPEG = fourcc("MJPG")


class Capability(ctypes.Structure):
    _fields_ = [
        ("driver", ctypes.c_char * 16),
        ("card", ctypes.c_char * 32),
        ("bus_info", ctypes.c_char * 32),
        ("version", ctypes.c_uint32),
        ("capabilities", ctypes.c_uint32),
        ("device_caps", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32 * 3),
    ]


class PixFormat(ctypes.Structure):
    _fields_ = [
        (name, ctypes.c_uint32)
        for name in (
            "width", "height", "pixelformat", "field", "bytesperline", "sizeimage",
            "colorspace", "priv", "flags", "ycbcr_enc", "quantization", "xfer_func",
        )
    ]  # fmt: skip


class _FormatUnion(ctypes.Union):
    # v4l2_window holds pointers: the union is pointer-aligned (208 bytes on x86-64, 204 on i386).
    _fields_ = [("pix", PixFormat), ("raw_data", ctypes.c_uint8 * 200), ("_align", ctypes.c_void_p)]


class Format(ctypes.Structure):
    _fields_ = [("type", ctypes.c_uint32), ("fmt", _FormatUnion)]


class Fract(ctypes.Structure):
    _fields_ = [("numerator", ctypes.c_uint32), ("denominator", ctypes.c_uint32)]


class CaptureParm(ctypes.Structure):
    _fields_ = [
        ("capability", ctypes.c_uint32),
        ("capturemode", ctypes.c_uint32),
        ("timeperframe", Fract),
        ("extendedmode", ctypes.c_uint32),
        ("readbuffers", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32 * 4),
    ]


class _ParmUnion(ctypes.Union):
    _fields_ = [("capture", CaptureParm), ("raw_data", ctypes.c_uint8 * 200)]


class StreamParm(ctypes.Structure):
    _fields_ = [("type", ctypes.c_uint32), ("parm", _ParmUnion)]


class RequestBuffers(ctypes.Structure):
    _fields_ = [
        ("count", ctypes.c_uint32),
        ("type", ctypes.c_uint32),
        ("memory", ctypes.c_uint32),
        ("capabilities", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
    ]


class Timeval(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_usec", ctypes.c_long)]


class Timecode(ctypes.Structure):
    _fields_ = [
        ("type", ctypes.c_uint32),
        ("flags", ctypes.c_uint32),
        ("frames", ctypes.c_uint8),
        ("seconds", ctypes.c_uint8),
        ("minutes", ctypes.c_uint8),
        ("hours", ctypes.c_uint8),
        ("userbits", ctypes.c_uint8 * 4),
    ]


class _BufferM(ctypes.Union):
    _fields_ = [
        ("offset", ctypes.c_uint32),
        ("userptr", ctypes.c_ulong),
        ("planes", ctypes.c_void_p),
        ("fd", ctypes.c_int32),
    ]


class Buffer(ctypes.Structure):
    _fields_ = [
        ("index", ctypes.c_uint32),
        ("type", ctypes.c_uint32),
        ("bytesused", ctypes.c_uint32),
        ("flags", ctypes.c_uint32),
        ("field", ctypes.c_uint32),
        ("timestamp", Timeval),
        ("timecode", Timecode),
        ("sequence", ctypes.c_uint32),
        ("memory", ctypes.c_uint32),
        ("m", _BufferM),
        ("length", ctypes.c_uint32),
        ("reserved2", ctypes.c_uint32),
        ("request_fd", ctypes.c_int32),
    ]


def _ioc(direction: int, nr: int, size: int) -> int:
    return direction << 30 | size << 16 | ord("V") << 8 | nr


_W, _R = 1, 2
VIDIOC_QUERYCAP = _ioc(_R, 0, ctypes.sizeof(Capability))
VIDIOC_S_FMT = _ioc(_R | _W, 5, ctypes.sizeof(Format))
VIDIOC_REQBUFS = _ioc(_R | _W, 8, ctypes.sizeof(RequestBuffers))
VIDIOC_QUERYBUF = _ioc(_R | _W, 9, ctypes.sizeof(Buffer))
VIDIOC_QBUF = _ioc(_R | _W, 15, ctypes.sizeof(Buffer))
VIDIOC_DQBUF = _ioc(_R | _W, 17, ctypes.sizeof(Buffer))
VIDIOC_STREAMON = _ioc(_W, 18, ctypes.sizeof(ctypes.c_int))
VIDIOC_STREAMOFF = _ioc(_W, 19, ctypes.sizeof(ctypes.c_int))
VIDIOC_S_PARM = _ioc(_R | _W, 22, ctypes.sizeof(StreamParm))

# Buffers the driver fills while one is read: enough that a late read still finds a frame.
BUFFERS = 4
# A camera that delivers nothing for this long is stalled (s): read() gives None.
FRAME_TIMEOUT = 2.0


class V4L2Error(CameraError):
    """A V4L2 camera that cannot be opened or give MJPEG frames; the message names the fix."""


class Device(Protocol):
    """The system calls of a V4L2 capture (the seam for a fake camera in tests)."""

    def open(self, path: str) -> int: ...
    def ioctl(self, fd: int, request: int, arg: ctypes.Structure | ctypes.c_int) -> None: ...
    def mmap(self, fd: int, length: int, offset: int) -> mmap.mmap | memoryview: ...
    def wait(self, fd: int, timeout: float) -> bool: ...
    def close(self, fd: int) -> None: ...


class LinuxDevice:
    """The real kernel."""

    def open(self, path: str) -> int:
        return os.open(path, os.O_RDWR | os.O_NONBLOCK)

    def ioctl(self, fd: int, request: int, arg: ctypes.Structure | ctypes.c_int) -> None:
        while True:
            try:
                fcntl.ioctl(fd, request, arg, True)
                return
            except InterruptedError:
                continue

    def mmap(self, fd: int, length: int, offset: int) -> mmap.mmap:
        return mmap.mmap(fd, length, mmap.MAP_SHARED, mmap.PROT_READ, offset=offset)

    def wait(self, fd: int, timeout: float) -> bool:
        readable, _, _ = select.select([fd], [], [], timeout)
        return bool(readable)

    def close(self, fd: int) -> None:
        os.close(fd)


@dataclass(frozen=True)
class Negotiated:
    """What a V4L2 device agreed to: its driver and card, frame size and rate."""

    driver: str
    card: str
    width: int
    height: int
    fps: float  # 0.0: the driver did not say


class V4L2Source:
    """MJPEG frames of a V4L2 camera as :class:`JpegFrame` (``read`` gives None when none came
    within :data:`FRAME_TIMEOUT`)."""

    def __init__(
        self, path: str, width: int, height: int, fps: float, device: Device | None = None
    ) -> None:
        self.path = path
        self.dev: Device = device or LinuxDevice()
        self.dropped = 0  # frames the driver marked bad (skipped)
        self._maps: list[mmap.mmap | memoryview] = []
        self._streaming = False
        try:
            self.fd = self.dev.open(path)
        except OSError as exc:
            raise V4L2Error(
                f"cannot open camera {path}: {exc.strerror}: is it plugged in "
                "(`ls /dev/video*`) and are you in the 'video' group? Use --camera none to "
                "run without it"
            ) from None
        try:
            self.info = self._start(width, height, fps)
        except BaseException:
            self.close()
            raise

    def _ioctl(self, name: str, request: int, arg: ctypes.Structure | ctypes.c_int) -> None:
        try:
            self.dev.ioctl(self.fd, request, arg)
        except OSError as exc:
            raise V4L2Error(f"camera {self.path}: {name} failed: {exc.strerror}") from None

    def _start(self, width: int, height: int, fps: float) -> Negotiated:
        cap = Capability()
        self._ioctl("VIDIOC_QUERYCAP", VIDIOC_QUERYCAP, cap)
        caps = cap.device_caps if cap.capabilities & V4L2_CAP_DEVICE_CAPS else cap.capabilities
        if not caps & V4L2_CAP_VIDEO_CAPTURE or not caps & V4L2_CAP_STREAMING:
            raise V4L2Error(
                f"{self.path} ({cap.card.decode(errors='replace')}) is not a streaming capture "
                "device: pick the camera's capture node (`v4l2-ctl --list-devices`)"
            )
        fmt = Format(type=V4L2_BUF_TYPE_VIDEO_CAPTURE)
        fmt.fmt.pix.width, fmt.fmt.pix.height = width, height
        fmt.fmt.pix.pixelformat, fmt.fmt.pix.field = V4L2_PIX_FMT_MJPEG, V4L2_FIELD_ANY
        self._ioctl("VIDIOC_S_FMT", VIDIOC_S_FMT, fmt)
        if fmt.fmt.pix.pixelformat != V4L2_PIX_FMT_MJPEG:
            raise V4L2Error(
                f"camera {self.path} ({cap.card.decode(errors='replace')}) does not offer MJPEG "
                "(`v4l2-ctl -d DEV --list-formats`): use a UVC camera that does, or install "
                "the vision extra (OpenCV) for raw frames"
            )
        self.width, self.height = int(fmt.fmt.pix.width), int(fmt.fmt.pix.height)
        got_fps = self._set_fps(fps)
        req = RequestBuffers(count=BUFFERS, type=V4L2_BUF_TYPE_VIDEO_CAPTURE)
        req.memory = V4L2_MEMORY_MMAP
        self._ioctl("VIDIOC_REQBUFS", VIDIOC_REQBUFS, req)
        if req.count < 1:
            raise V4L2Error(f"camera {self.path} gave no capture buffers")
        for i in range(req.count):
            buf = self._buffer(i)
            self._ioctl("VIDIOC_QUERYBUF", VIDIOC_QUERYBUF, buf)
            self._maps.append(self.dev.mmap(self.fd, buf.length, buf.m.offset))
            self._ioctl("VIDIOC_QBUF", VIDIOC_QBUF, buf)
        self._ioctl("VIDIOC_STREAMON", VIDIOC_STREAMON, ctypes.c_int(V4L2_BUF_TYPE_VIDEO_CAPTURE))
        self._streaming = True
        driver = cap.driver.decode(errors="replace")
        return Negotiated(
            driver, cap.card.decode(errors="replace"), self.width, self.height, got_fps
        )

    def _set_fps(self, fps: float) -> float:
        """Ask for ``fps`` (a driver may refuse or round): the rate it set, 0.0 if unknown."""
        parm = StreamParm(type=V4L2_BUF_TYPE_VIDEO_CAPTURE)
        parm.parm.capture.timeperframe = Fract(1000, max(1, round(fps * 1000)))
        try:
            self.dev.ioctl(self.fd, VIDIOC_S_PARM, parm)
        except OSError:
            return 0.0
        t = parm.parm.capture.timeperframe
        return t.denominator / t.numerator if t.numerator else 0.0

    @staticmethod
    def _buffer(index: int = 0) -> Buffer:
        buf = Buffer(index=index, type=V4L2_BUF_TYPE_VIDEO_CAPTURE)
        buf.memory = V4L2_MEMORY_MMAP
        return buf

    def read(self) -> JpegFrame | None:
        if not self.dev.wait(self.fd, FRAME_TIMEOUT):
            return None
        buf = self._buffer()
        try:
            self.dev.ioctl(self.fd, VIDIOC_DQBUF, buf)
        except OSError as exc:
            if exc.errno == errno.EAGAIN:
                return None
            raise V4L2Error(f"camera {self.path}: VIDIOC_DQBUF failed: {exc.strerror}") from None
        try:
            n = min(int(buf.bytesused), len(self._maps[buf.index]))
            data = bytes(self._maps[buf.index][:n])
        finally:
            self._ioctl("VIDIOC_QBUF", VIDIOC_QBUF, buf)
        # A frame the driver marks bad, or one cut short (no SOI), is skipped, not forwarded.
        if buf.flags & V4L2_BUF_FLAG_ERROR or not data.startswith(b"\xff\xd8"):
            self.dropped += 1
            return None
        return JpegFrame(data, self.width, self.height)

    def close(self) -> None:
        fd = getattr(self, "fd", -1)  # -1: never opened, or closed
        if fd < 0:
            return
        if self._streaming:
            with _quiet():
                self.dev.ioctl(fd, VIDIOC_STREAMOFF, ctypes.c_int(V4L2_BUF_TYPE_VIDEO_CAPTURE))
            self._streaming = False
        for m in self._maps:
            if isinstance(m, mmap.mmap):
                with _quiet():
                    m.close()
        self._maps.clear()
        with _quiet():
            self.dev.close(fd)
        self.fd = -1


def _quiet() -> contextlib.AbstractContextManager[None]:
    return contextlib.suppress(OSError, ValueError)
