"""Frame sources: video files, image folders, live cameras, paced replay, and multi-camera sync.

Every source yields :class:`Frame` records (``frame`` index, ``t_s`` seconds, ``camera`` name,
``image``). Frame times, in order of preference:

- video: ``<video stem>.timestamps.txt`` beside the video (one ``frame t_s`` pair per line, the
  authoritative times; the k-th decoded frame gets the k-th line), else the container's
  presentation time (``CAP_PROP_POS_MSEC``), else ``frame / fps``;
- image folder: ``timestamps.txt`` inside the folder or ``<folder>.timestamps.txt`` beside it (the
  k-th image in natural name order gets the k-th line), else ``frame / fps`` with a configured ``fps``.

Bad input raises :class:`~estimators.errors.SourceError` naming the file (or camera index) and what
was wrong. A video that stops decoding before its announced end does not raise: the source ends
and sets ``.error`` (the run keeps what was processed and reports the error after writing).
"""

from __future__ import annotations

import os
import queue
import re
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # quiet FFmpeg; errors are reported by us
os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from estimators.errors import SourceError  # noqa: E402

__all__ = [
    "Frame",
    "FrameSet",
    "Source",
    "VideoSource",
    "ImageFolderSource",
    "PacedSource",
    "PrefetchSource",
    "SyncedSource",
    "open_capture",
    "natural_key",
    "read_timestamps",
    "timestamps_path_for",
    "IMAGE_SUFFIXES",
    "VIDEO_SUFFIXES",
]

# the file names taken as images and as videos, by every command (run, batch folders, evaluate, calibrate)
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp")
VIDEO_SUFFIXES = (".mkv", ".mp4", ".avi", ".mov", ".webm", ".m4v", ".mpg", ".mpeg", ".ts", ".h264")


@dataclass(frozen=True)
class Frame:
    """One image of one camera.

    Attributes:
        frame: frame index (from the timestamps file when there is one, else the decode count).
        t_s: frame time, seconds.
        camera: camera name in the rig (``cam0``...).
        image: (H, W) uint8 grey or (H, W, 3) uint8 BGR, the raw fisheye image.
    """

    frame: int
    t_s: float
    camera: str
    image: np.ndarray


@dataclass(frozen=True)
class FrameSet:
    """The frames of every camera at one instant (kept in step by ``t_s``).

    Attributes:
        frame: the first camera's frame index; t_s: the first camera's frame time (s).
        frames: camera name -> :class:`Frame`, in the rig's camera order.
    """

    frame: int
    t_s: float
    frames: dict[str, Frame] = field(default_factory=dict)

    @property
    def images(self) -> dict[str, np.ndarray]:
        """Camera name -> image, as ``FrontEnd.process`` takes them."""
        return {k: f.image for k, f in self.frames.items()}


def natural_key(path: str | Path) -> tuple:
    """Sort key of a path in natural order: digit runs compare as numbers, so ``frame_2`` comes before
    ``frame_10`` (plain name order puts ``frame_10`` first); names whose numbers are zero-padded to one
    width keep their name order. Ties (``f_01``, ``f_1``) are broken by the plain text."""
    text = str(path)
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", text)), text


def timestamps_path_for(path: str | Path) -> Path:
    """``<dir>/<stem>.timestamps.txt`` for a video ``<dir>/<stem>.<ext>``."""
    p = Path(path)
    return p.with_name(p.stem + ".timestamps.txt")


def read_timestamps(path: str | Path) -> list[tuple[int, float]]:
    """Read a ``frame t_s`` file (``#`` comments allowed); frame ints and times both strictly increasing.

    Raises:
        SourceError: a malformed line (file and line number named), or frame numbers or times that do
            not increase (the line number and both values named).
    """
    path = Path(path)
    out: list[tuple[int, float]] = []
    with path.open() as f:
        for lineno, line in enumerate(f, start=1):
            s = line.split("#", 1)[0].strip()
            if not s:
                continue
            parts = s.replace(",", " ").split()
            try:
                if len(parts) != 2:
                    raise ValueError
                frame, t_s = int(parts[0]), float(parts[1])
            except ValueError:
                raise SourceError(
                    f"{path}:{lineno}: expected 'frame t_s' (an integer and seconds), got {s!r}"
                ) from None
            if not np.isfinite(t_s):
                raise SourceError(f"{path}:{lineno}: t_s is not finite: {s!r}")
            if out and frame <= out[-1][0]:
                raise SourceError(
                    f"{path}:{lineno}: frame numbers must increase; frame {frame} follows frame "
                    f"{out[-1][0]} (line {s!r})"
                )
            if out and t_s <= out[-1][1]:
                raise SourceError(f"{path}:{lineno}: times must increase; {t_s!r} follows {out[-1][1]!r}")
            out.append((frame, t_s))
    return out


class Source(ABC):
    """An iterable of :class:`Frame` of one camera. ``error`` is set when it ended early on bad data."""

    camera: str = "cam0"
    error: str | None = None
    frames_read: int = 0

    @abstractmethod
    def __iter__(self) -> Iterator[Frame]: ...

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release the underlying file or device."""

    def __enter__(self) -> Source:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _size_check(image: np.ndarray, expected_size: tuple[int, int] | None, what: str) -> None:
    if expected_size is None:
        return
    h, w = image.shape[:2]
    ew, eh = int(expected_size[0]), int(expected_size[1])
    if (w, h) != (ew, eh):
        raise SourceError(
            f"{what}: frames are {w}x{h} pixels but the calibration expects {ew}x{eh} "
            "(wrong video for this camera, or a resized recording)"
        )


def open_capture(ref: str | int | Path) -> cv2.VideoCapture:
    """Open a video file, URL or camera index with OpenCV; SourceError naming it when that fails."""
    if isinstance(ref, int) or (isinstance(ref, str) and ref.isdigit()):
        index = int(ref)
        cap = cv2.VideoCapture(index)
        if not cap.isOpened():
            cap.release()
            raise SourceError(f"camera index {index}: cannot be opened (no such device, or it is busy)")
        return cap
    s = str(ref)
    cap = cv2.VideoCapture(s, cv2.CAP_FFMPEG)
    if not cap.isOpened():
        cap.release()
        raise SourceError(f"{s}: cannot be opened by OpenCV's FFmpeg backend (not a video, or unreachable)")
    return cap


def is_grey_video(path: str | Path) -> bool:
    """Whether the video file ``path``'s stream is itself grey (e.g. the simulator's ``--grey`` FFV1):
    its decoder's pixel format is one 8-bit grey plane (``CAP_PROP_CODEC_PIXEL_FORMAT`` ``Y800``) and
    its first frame read with ``CAP_PROP_CONVERT_RGB`` off is (H, W) uint8 of the container's size.
    A colour YUV stream (MJPEG, MPEG-4, H.264) also reads as one (H, W) plane then, its luma: it is
    not grey. Raises SourceError when it cannot be opened."""
    cap = open_capture(path)
    try:
        cap.set(cv2.CAP_PROP_CONVERT_RGB, 0)
        ok, img = cap.read()
        w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        fmt = int(cap.get(cv2.CAP_PROP_CODEC_PIXEL_FORMAT))
    finally:
        cap.release()
    return (
        fmt == cv2.VideoWriter_fourcc(*"Y800")
        and bool(ok)
        and img is not None
        and img.ndim == 2
        and img.dtype == np.uint8
        and img.shape == (h, w)
    )


class VideoSource(Source):
    """Frames of one video file (or stream URL), decoded with OpenCV's FFmpeg backend.

    Args:
        path: video file or URL.
        camera: camera name the frames belong to.
        expected_size: (width, height) pixels from the calibration; a mismatch is a SourceError.
        fps: frame rate to assume (Hz) when the video gives no usable times (overrides the container's).
        grey: yield (H, W) uint8 grey frames instead of BGR. A file whose stream is already full-range
            grey (e.g. the simulator's ``--grey`` FFV1, or MJPEG's luma) is read without any colour
            conversion (``CAP_PROP_CONVERT_RGB`` off: the decoder's plane as it is, checked on the first
            frame against ``cvtColor(BGR2GRAY)`` of the converted decode); other streams are decoded to
            BGR and converted once per frame (``grey_mode`` says which: ``"native"`` or ``"converted"``).

    The frame times come from ``<video stem>.timestamps.txt`` beside the video when it exists.
    The file is opened and its first frame decoded on construction, so bad input fails before a run
    starts. When decoding stops before the announced frame count (timestamps lines, else the
    container's count), iteration ends and ``error`` says where.
    """

    def __init__(
        self,
        path: str | Path,
        camera: str = "cam0",
        expected_size: tuple[int, int] | None = None,
        fps: float | None = None,
        grey: bool = False,
    ):
        self.path = str(path)
        self.camera = camera
        self.error = None
        self.frames_read = 0
        self.grey = bool(grey)
        self.grey_mode: str | None = None
        is_url = "://" in self.path
        if not is_url:
            p = Path(self.path)
            if not p.exists():
                raise SourceError(f"{p}: video file not found")
            if p.is_dir():
                raise SourceError(
                    f"{p}: is a folder; expected a video file (use inputs.images for image folders)"
                )
            if p.stat().st_size == 0:
                raise SourceError(f"{p}: video file is empty (0 bytes)")
        ts_path = None if is_url else timestamps_path_for(self.path)
        self.timestamps: list[tuple[int, float]] | None = None
        self.timestamps_path: Path | None = None
        if ts_path is not None and ts_path.is_file():
            self.timestamps = read_timestamps(ts_path)
            self.timestamps_path = ts_path
        self._cap = open_capture(self.path)
        self.fps = float(fps) if fps else (self._cap.get(cv2.CAP_PROP_FPS) or 0.0)
        if not np.isfinite(self.fps) or self.fps <= 0 or self.fps > 1000:
            self.fps = 0.0
        count = self._cap.get(cv2.CAP_PROP_FRAME_COUNT)
        self.frame_count: int | None = int(count) if np.isfinite(count) and count > 0 else None
        if self.timestamps is not None:
            self.frame_count = len(self.timestamps)
        ok, img = self._cap.read()
        if not ok or img is None:
            self._cap.release()
            raise SourceError(f"{self.path}: no frame could be decoded (corrupt or truncated video)")
        _size_check(img, expected_size, self.path)
        self.size = (int(img.shape[1]), int(img.shape[0]))
        pos0 = self._cap.get(cv2.CAP_PROP_POS_MSEC)
        if self.grey:
            img = self._grey_setup(img, probe=not is_url)
        self._first = (img, pos0)
        self._fps_given = fps is not None

    @property
    def frame_times(self) -> str:
        """Where the frame times come from (``summary.json`` ``frame_times``): the timestamps file's path,
        ``"inputs.fps"`` (frame / fps), or ``"container"`` (the container's presentation times, frame /
        its fps where it gives none)."""
        if self.timestamps_path is not None:
            return str(self.timestamps_path)
        return "inputs.fps" if self._fps_given else "container"

    def _grey_setup(self, bgr: np.ndarray, probe: bool) -> np.ndarray:
        """Choose how grey frames are made; returns the first frame as (H, W) uint8 grey."""
        grey = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY) if bgr.ndim == 3 else bgr
        if probe:
            # a second capture opened without conversion (switching CONVERT_RGB on an open FFmpeg
            # capture mid-stream garbles the frames that follow)
            cap = open_capture(self.path)
            try:
                cap.set(cv2.CAP_PROP_CONVERT_RGB, 0)
                ok, raw = cap.read()
            except BaseException:
                cap.release()
                raise
            if (
                ok
                and raw is not None
                and raw.dtype == np.uint8
                and raw.shape == grey.shape
                # the decoder's own plane is the grey image (full range): not a limited-range luma
                and int(cv2.absdiff(raw, grey).max()) <= 2
            ):
                self._cap.release()
                self._cap = cap  # already past frame 0, like the one it replaces
                self.grey_mode = "native"
                return raw
            cap.release()
        self.grey_mode = "converted"
        return grey

    def _time(self, k: int, pos_msec: float) -> tuple[int, float]:
        if self.timestamps is not None:
            return self.timestamps[k]
        if not self._fps_given and np.isfinite(pos_msec) and (pos_msec > 0 or k == 0):
            return k, pos_msec / 1000.0
        if self.fps > 0:
            return k, k / self.fps
        raise SourceError(f"{self.path}: no frame times (no timestamps file, no container times, no fps)")

    def __iter__(self) -> Iterator[Frame]:
        if self._first is None:
            raise SourceError(f"{self.path}: a VideoSource can be iterated once")
        img, pos = self._first
        self._first = None
        k = 0
        last_t = -np.inf
        while True:
            if self.timestamps is not None and k >= len(self.timestamps):
                self.error = (
                    f"{self.path}: the video has more frames than {self.timestamps_path} has lines "
                    f"({len(self.timestamps)}); stopped there"
                )
                break
            frame, t_s = self._time(k, pos)
            if t_s <= last_t:  # a container with broken times: fall back to the frame rate
                t_s = last_t + (1.0 / self.fps if self.fps > 0 else 1e-3)
            last_t = t_s
            self.frames_read = k + 1
            yield Frame(frame, float(t_s), self.camera, img)
            ok, img = self._cap.read()
            if not ok or img is None:
                break
            if img.ndim == 3 and self.grey:
                img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
            # the container's time only when there is no timestamps file (one call into OpenCV less per
            # frame: each gives up and takes back the GIL, a wait of up to sys.getswitchinterval())
            pos = self._cap.get(cv2.CAP_PROP_POS_MSEC) if self.timestamps is None else 0.0
            k += 1
        n = self.frames_read
        if self.error is None and self.frame_count is not None and n < self.frame_count:
            exact = self.timestamps is not None
            # container counts are estimates (duration x fps): allow one frame of slack there
            if exact or n < self.frame_count - 1:
                self.error = (
                    f"{self.path}: decoding stopped after {n} of {self.frame_count} frames "
                    "(truncated or corrupt video); frames before the break were processed"
                )
        self.close()

    def close(self) -> None:
        if getattr(self, "_cap", None) is not None:
            self._cap.release()


class ImageFolderSource(Source):
    """Frames from a folder of images, in natural name order (``frame_2`` before ``frame_10``,
    :func:`natural_key`); with a timestamps file the k-th image gets its k-th line.

    Args:
        folder: folder of ``.png/.jpg/...`` images.
        camera: camera name; expected_size: (width, height) from the calibration.
        fps: frame rate (Hz) used when there is no timestamps file.
        grey: read as grey (H, W) instead of BGR.

    The frame times come from ``folder/timestamps.txt`` or ``<folder>.timestamps.txt`` when one exists.
    """

    def __init__(
        self,
        folder: str | Path,
        camera: str = "cam0",
        expected_size: tuple[int, int] | None = None,
        fps: float | None = None,
        grey: bool = False,
    ):
        self.folder = Path(folder)
        self.camera = camera
        self.error = None
        self.frames_read = 0
        self.expected_size = expected_size
        self.grey = grey
        if not self.folder.is_dir():
            raise SourceError(f"{self.folder}: image folder not found")
        self.files = sorted((p for p in self.folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES),
                            key=natural_key)
        if not self.files:
            raise SourceError(f"{self.folder}: no images ({', '.join(IMAGE_SUFFIXES)}) in the folder")
        cands = [self.folder / "timestamps.txt", self.folder.with_name(self.folder.name + ".timestamps.txt")]
        self.timestamps = None
        self.frame_times = "inputs.fps"  # where the frame times come from: this or the timestamps file
        for c in cands:
            if c.is_file():
                self.timestamps = read_timestamps(c)
                self.frame_times = str(c)
                if len(self.timestamps) < len(self.files):
                    raise SourceError(
                        f"{c}: {len(self.timestamps)} timestamps for {len(self.files)} images "
                        f"in {self.folder}"
                    )
                break
        if self.timestamps is None and not fps:
            raise SourceError(
                f"{self.folder}: no timestamps.txt and no frame rate; give inputs.fps (Hz, e.g. --set "
                f"inputs.fps=30) or a timestamps file ('frame t_s' per line) {' or '.join(map(str, cands))}"
            )
        self.fps = float(fps) if fps else None
        self.frame_count = len(self.files)

    def __iter__(self) -> Iterator[Frame]:
        flag = cv2.IMREAD_GRAYSCALE if self.grey else cv2.IMREAD_COLOR
        for k, p in enumerate(self.files):
            img = cv2.imread(str(p), flag)
            if img is None:
                self.error = f"{p}: image could not be decoded (corrupt or not an image); stopped there"
                return
            if k == 0:
                _size_check(img, self.expected_size, str(p))
            elif self.expected_size is None and k > 0 and img.shape[:2] != self._shape:
                self.error = (
                    f"{p}: size {img.shape[1]}x{img.shape[0]} differs from the first image; stopped there"
                )
                return
            self._shape = img.shape[:2]
            if self.timestamps is not None:
                frame, t_s = self.timestamps[k]
            else:
                frame, t_s = k, k / self.fps
            self.frames_read = k + 1
            yield Frame(frame, float(t_s), self.camera, img)


class PacedSource(Source):
    """Replays another source at its real rate: frame k is released at ``start + (t_k - t_0) / speed``.

    A stand-in for a live camera in tests and demos. The monotonic clock when the last frame was
    released is ``last_arrival_s``; when it was due (when a camera would have delivered it, however
    late the replay got there) is ``last_due_s``.

    Args:
        inner: the source to replay; speed: replay speed factor (2 = twice real time).
        clock / sleep: injectable for tests (default ``time.monotonic`` / ``time.sleep``).
    """

    def __init__(
        self,
        inner: Source,
        speed: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ):
        if not speed > 0:
            raise SourceError(f"PacedSource: speed must be > 0, got {speed!r}")
        self.inner = inner
        self.camera = inner.camera
        self.speed = float(speed)
        self.clock = clock
        self.sleep = sleep
        self.error = None
        self.last_arrival_s: float | None = None
        self.last_due_s: float | None = None

    def __iter__(self) -> Iterator[Frame]:
        start = None
        t0 = None
        for f in self.inner:
            if start is None:
                start, t0 = self.clock(), f.t_s
            due = start + (f.t_s - t0) / self.speed
            wait = due - self.clock()
            if wait > 0:
                self.sleep(wait)
            self.last_due_s = due
            self.last_arrival_s = self.clock()
            self.frames_read += 1
            yield f
        self.error = self.inner.error

    def close(self) -> None:
        self.inner.close()


_END = object()


class PrefetchSource(Source):
    """Decodes another source's frames ahead in a background thread (at most ``depth`` waiting).

    OpenCV releases the GIL while it decodes, so with a second core free the next frame is ready
    when the run loop asks for it; memory stays bounded (``depth`` frames). Errors of the inner
    source are raised in the consumer; ``error``, ``frame_count``, ``fps``, ``path``... are the
    inner source's.

    Args:
        inner: the source to read ahead; depth: frames decoded ahead (>= 1).
    """

    def __init__(self, inner: Source, depth: int = 2):
        if depth < 1:
            raise SourceError(f"PrefetchSource: depth must be >= 1, got {depth!r}")
        self.inner = inner
        self.camera = inner.camera
        self.depth = int(depth)
        self.frames_read = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __getattr__(self, name: str):  # frame_count, fps, path, size, grey_mode... of the inner source
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)

    @property
    def error(self) -> str | None:  # type: ignore[override]
        return self.inner.error

    def __iter__(self) -> Iterator[Frame]:
        q: queue.Queue = queue.Queue(maxsize=self.depth)
        stop = self._stop

        def put(item) -> bool:
            while not stop.is_set():
                try:
                    q.put(item, timeout=0.05)
                    return True
                except queue.Full:
                    continue
            return False

        def work() -> None:
            try:
                for f in self.inner:
                    if not put(f):
                        return
                put(_END)
            except BaseException as e:  # handed to the consumer, raised there
                put(e)

        self._thread = threading.Thread(target=work, name=f"decode-{self.camera}", daemon=True)
        self._thread.start()
        try:
            while True:
                item = q.get()
                if item is _END:
                    return
                if isinstance(item, BaseException):
                    raise item
                self.frames_read += 1
                yield item
        finally:
            self._halt()

    def _halt(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)

    def close(self) -> None:
        self._halt()  # the decoder thread is out of the inner source before it is released
        self.inner.close()


class SyncedSource:
    """Keeps several cameras' sources in step by ``t_s``; yields :class:`FrameSet`.

    Frames of all cameras whose times lie within ``tolerance_s`` of each other form one set. When they
    do not, the earliest frame has no partner: it is dropped and counted in ``dropped[camera]``. The
    sync ends when any source ends.

    Args:
        sources: one source per camera, in the rig's camera order (names must be unique).
        tolerance_s: largest spread of times within one set, seconds.
    """

    def __init__(self, sources: list[Source], tolerance_s: float = 0.005):
        names = [s.camera for s in sources]
        if not sources or len(set(names)) != len(names):
            raise SourceError(f"SyncedSource: expected one source per camera with unique names, got {names}")
        self.sources = list(sources)
        self.tolerance_s = float(tolerance_s)
        self.dropped: dict[str, int] = {n: 0 for n in names}
        self.sets = 0

    @property
    def error(self) -> str | None:
        """The first source error (a video that broke halfway), or None."""
        errs = [s.error for s in self.sources if s.error]
        return "; ".join(errs) if errs else None

    def __iter__(self) -> Iterator[FrameSet]:
        its = [iter(s) for s in self.sources]
        try:
            heads = [next(it) for it in its]
        except StopIteration:
            return
        while True:
            ts = [h.t_s for h in heads]
            if max(ts) - min(ts) <= self.tolerance_s + 1e-12:
                self.sets += 1
                yield FrameSet(heads[0].frame, heads[0].t_s, {h.camera: h for h in heads})
                try:
                    heads = [next(it) for it in its]
                except StopIteration:
                    return
            else:
                i = int(np.argmin(ts))  # the earliest frame has no partner in time: drop it
                self.dropped[heads[i].camera] += 1
                try:
                    heads[i] = next(its[i])
                except StopIteration:
                    return

    def close(self) -> None:
        for s in self.sources:
            s.close()
