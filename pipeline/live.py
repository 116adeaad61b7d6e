"""Live mode of ``fisheye-des live``: cameras by index or URL, always the newest frame, bounded latency.

- A grabber thread per camera reads continuously and keeps only the newest frame; a frame replaced
  before the pipeline took it is *stale*: dropped and counted, so latency stays bounded whatever the
  pipeline's speed.
- A camera that stops delivering (read fails, or no frame for ``stall_timeout_s``) is reopened with
  exponential back-off (``reconnect_initial_s`` doubling up to ``reconnect_max_s``); the run goes on.
- Latency per frame = from the frame's arrival (grabber clock; a paced replay's due time) to its
  ``tracks.jsonl`` line being written and flushed; median / p99 / max go to ``summary.json``, with its
  parts (lag, queue, process, write; decode beside) in ``latency_parts`` and, on request, per frame
  in a CSV (``run_live(latency_log=...)``).
- Preview: the annotated frame to ``preview.mp4``, or served as MJPEG on ``http://127.0.0.1:PORT/``
  (:class:`MjpegServer`, loopback only).
- Ego-motion: constant velocity, or a TUM trajectory file that grows while the run goes
  (:class:`GrowingTrajectory`, re-read when a frame's ``t_s`` passes its end).
- Testable without a camera: a video file entry is replayed at its real rate (:class:`PacedSource`),
  and frames then carry the video's own ``t_s``.
"""

from __future__ import annotations

import gc
import http.server
import multiprocessing
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from estimators.egomotion import EgoMotion, TumTrajectory, parse_tum_line
from estimators.errors import ConfigError, InputError, SourceError
from estimators.se3 import Pose
from pipeline.config import PipelineConfig, write_resolved
from pipeline.run import (
    FramePoseCache,
    RunningStats,
    StageTimings,
    build_egomotion,
    build_frontend,
    build_fusion,
    build_rig,
    error_text,
    frozen_gc,
    on_frame_clock,
    reads_grey,
    stopped_error,
)
from pipeline.sinks import (
    SUMMARY_NAME,
    TRACKS_NAME,
    Annotator,
    TracksWriter,
    VideoWriter,
    make_output_dir,
    write_json,
)
from pipeline.sources import PacedSource, Source, VideoSource, open_capture

__all__ = [
    "LIVE_SWITCH_INTERVAL_S",
    "PAIR_WAIT_SLACK_S",
    "SKIP_AFTER_INTERVALS",
    "SKIPPED",
    "DECODE_LEAD",
    "DECODE_LEAD_SLACK_S",
    "LiveFrame",
    "frame_time",
    "Grabber",
    "CaptureReader",
    "SourceReader",
    "GrowingTrajectory",
    "MjpegServer",
    "LiveResult",
    "run_live",
    "latency_log_stages",
    "make_reader_factory",
]


#: Python's thread switch interval (s) while ``run_live`` runs (``sys.setswitchinterval``).
LIVE_SWITCH_INTERVAL_S = 0.0005

#: Scheduling slack (s) added to two frame intervals: how long a camera's partner frame is waited for.
PAIR_WAIT_SLACK_S = 0.1

#: Longest single condition wait (s), so waits re-read the injected clock.
_WAIT_POLL_S = 0.05

#: Retrieve is skipped for a frame the run loop will not take when the loop's expected ready time is
#: more than this many frame intervals away (1 = the next frame arrives first; the 0.1 is arrival jitter).
SKIP_AFTER_INTERVALS = 1.1

#: A paced replay starts decoding a frame this many times its longest recent decode time before the
#: frame is due, plus :data:`DECODE_LEAD_SLACK_S` (s); see :class:`SourceReader`. The margin covers a
#: decode slowed by the pipeline's thread on the same core (the grabber runs at ``live.grabber_nice``).
DECODE_LEAD = 1.5
DECODE_LEAD_SLACK_S = 0.002

#: What a reader's ``read()`` returns as the image of a frame it grabbed but did not decode (see
#: :attr:`CaptureReader.wanted`): counted as grabbed and stale, never published.
SKIPPED = object()


def set_thread_nice(nice: int | None) -> int | None:
    """Give the calling thread the nice value ``nice`` (None: leave it) when the OS allows it (Linux:
    per thread); returns the thread's nice value as it runs, None when it cannot be read."""
    import os

    if not hasattr(os, "setpriority") or not hasattr(threading, "get_native_id"):
        return None
    tid = threading.get_native_id()
    if nice is not None:
        try:
            os.setpriority(os.PRIO_PROCESS, tid, int(nice))
        except OSError:  # below the process's value without CAP_SYS_NICE: the thread keeps its own
            pass
    try:
        return os.getpriority(os.PRIO_PROCESS, tid)
    except OSError:
        return None


def _detection_worker_init(nice: int | None) -> None:
    import os
    import signal

    import cv2

    import trackers.features  # noqa: F401  (the jobs' code, imported before the first job)

    cv2.setNumThreads(1)  # one thread, on the cores the run was given
    set_thread_nice(nice)
    # Ctrl-C reaches the whole process group, and a supervisor's SIGTERM may too (systemd's default
    # KillMode=control-group): the run ends the worker itself (its shutdown, after summary.json), so the
    # worker ignores both (otherwise each Ctrl-C printed the worker's KeyboardInterrupt traceback, and a
    # SIGTERM killed it under the run: summary.json's worker_cpu_s null, a detection's join a broken
    # pool); and it ends when the run's process is gone without a shutdown (SIGKILL, an unhandled
    # SIGTERM): otherwise it stayed, an orphan waiting for jobs, for good
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    parent = multiprocessing.parent_process()
    if parent is not None:

        def orphaned() -> None:
            parent.join()  # (its sentinel: readable once the parent process has ended)
            os._exit(1)

        threading.Thread(target=orphaned, name="parent-watch", daemon=True).start()


def _worker_nice() -> int | None:
    return set_thread_nice(None)


def _worker_pid() -> int:
    import os

    return os.getpid()


def process_cpu_s(pid: int | None) -> float | None:
    """CPU seconds (user + system, all threads) that process ``pid`` has used so far, from
    ``/proc/<pid>/stat`` (fields 14 and 15, utime and stime, in clock ticks); None when ``pid`` is None
    or the file cannot be read (not Linux, the process gone)."""
    import os

    if pid is None:
        return None
    try:
        stat = Path(f"/proc/{int(pid)}/stat").read_text()
        ticks = os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError):
        return None
    # "pid (comm) state ppid ...": comm may hold spaces and parentheses, so split after its last ")";
    # then field 3 (state) is index 0, utime (field 14) index 11, stime (field 15) index 12
    fields = stat[stat.rfind(")") + 2 :].split()
    try:
        return (int(fields[11]) + int(fields[12])) / ticks
    except (IndexError, ValueError):
        return None


def detection_worker(nice: int | None) -> ProcessPoolExecutor:
    """The deferred re-detection's executor (``FrontEnd.defer_detection``): one child process (spawned:
    no fork of a process with camera threads) at ``nice``, so that a detection runs in the loop's idle
    time and a busy core gives it only its weight's share. A process, not a thread: a low-priority thread
    holding the GIL (ORB's Python around its C++ calls) when it is preempted stops the loop until it
    runs again (measured: the loop thread's off-CPU time per frame p99 4-9 -> 34-46 ms). Started, and
    its imports done, before it returns."""
    ex = ProcessPoolExecutor(
        max_workers=1,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_detection_worker_init,
        initargs=(nice,),
    )
    try:
        ex.nice = ex.submit(_worker_nice).result()  # (the value it runs at, for summary.json)
        ex.pid = ex.submit(_worker_pid).result()  # (its CPU time, read from /proc, for summary.json)
    except BaseException:
        ex.shutdown(wait=False, cancel_futures=True)
        raise
    return ex


@dataclass(frozen=True)
class LiveFrame:
    """The newest frame of one camera.

    Attributes:
        seq: index of the frame in the camera's stream (counts stale frames too).
        t_s: the video's own time (replayed files) or None (cameras: the run's clock gives it).
        image: (H, W) or (H, W, 3) uint8; arrival_s: ``time.monotonic()`` when it arrived: when it was
            read (cameras), when it was due (paced replays: when the camera would have delivered it).
        published_s: ``time.monotonic()`` when the grabber made it the newest frame (>= arrival_s).
        decode_s: seconds the reader spent decoding (and converting) it, None when not measured.
    """

    seq: int
    t_s: float | None
    image: np.ndarray
    arrival_s: float
    published_s: float | None = None
    decode_s: float | None = None


def frame_time(f: LiveFrame) -> float:
    """The time cameras are paired by: the video's own ``t_s`` (replays), else the arrival (monotonic)."""
    return f.arrival_s if f.t_s is None else f.t_s


class CaptureReader:
    """A camera index or stream URL read with OpenCV (``read() -> (image or None, None)``).

    With ``grey`` the frame is converted to (H, W) grey here, in the grabber's thread (``cvtColor``
    releases the GIL), so the pipeline's thread gets what a grey detector works on.
    """

    ends = False  # a camera never ends: a failure means reopen
    arrival_s = None  # the grabber stamps the arrival itself
    decode_s: float | None = None  # seconds the last frame's retrieve (+ grey conversion) took
    #: set by the :class:`Grabber` of the lead camera: ``wanted() -> bool``, False when the run loop will
    #: still be busy when the next frame arrives (this one would be dropped unseen); None: always retrieve
    wanted: Callable[[], bool] | None = None

    def __init__(self, ref: int | str, timeout_s: float = 5.0, grey: bool = False):
        import cv2

        self.ref = ref
        self.grey = bool(grey)
        if isinstance(ref, str) and "://" in ref:
            ms = int(timeout_s * 1000)
            self.cap = cv2.VideoCapture(
                ref, cv2.CAP_FFMPEG, [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, ms, cv2.CAP_PROP_READ_TIMEOUT_MSEC, ms]
            )
            if not self.cap.isOpened():
                self.cap.release()
                raise SourceError(
                    f"{ref}: cannot be opened by OpenCV's FFmpeg backend (unreachable or not a stream)"
                )
        else:
            self.cap = open_capture(ref)

    def read(self) -> tuple[np.ndarray | None, float | None]:
        # read() = grab() (waits for the device's next frame) + retrieve() (decodes / converts it): split
        # so that ``decode_s`` is the decode (retrieve + grey conversion), not the wait for the camera
        # (with OpenCV's FFmpeg backend, i.e. URLs, grab() decodes and retrieve() only converts).
        # A frame the loop will not take (it is still busy when the next one arrives) is grabbed, so the
        # device's queue moves on, but not retrieved: with V4L2 the retrieve is the MJPEG decode / colour
        # conversion, with FFmpeg the pixel-format conversion (grab decodes there).
        self.decode_s = None
        if not self.cap.grab():
            return None, None
        wanted = self.wanted
        if wanted is not None and not wanted():
            return SKIPPED, None
        t0 = time.perf_counter()
        ok, img = self.cap.retrieve()
        if not ok or img is None:
            return None, None
        if self.grey and img.ndim == 3:
            import cv2

            img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        self.decode_s = time.perf_counter() - t0
        return img, None

    def close(self) -> None:
        self.cap.release()


class SourceReader:
    """A recorded :class:`Source` (e.g. a paced video replay) read frame by frame; it ends at its end.

    A :class:`PacedSource` is paced here (same rule: frame k is due at ``start + (t_k - t_0) / speed``
    on its clock) so that :meth:`set_start` can give the replays of one rig a common start: each
    replay's schedule then agrees with the others' whenever each camera was opened (a camera opened
    late publishes its overdue frames at once, with their due time as arrival), instead of starting
    when its own thread first reads. Without ``set_start`` the schedule starts at the first read.

    ``arrival_s``: for a paced replay, when the last frame was due (clock of the PacedSource), i.e.
    when a camera would have delivered it; the grabber takes that as the frame's arrival, so a replay
    that falls behind its schedule shows as latency, not as a later arrival. None otherwise.

    ``decode_s``: seconds the last frame's decode took (the inner source's next frame, without the
    pacing wait). A replay hands over finished frames at their due time, like a camera whose driver
    does a frame's work during its readout: frame k+1 is decoded shortly before it is due (from
    its predicted due time, the last interval after frame k's, minus ``DECODE_LEAD`` times the
    longest of the last decode times and ``DECODE_LEAD_SLACK_S``), not as soon as frame k is
    handed over. The decode's CPU time is still taken from the core, at the time a camera's
    driver would take it; decoding right after frame k was handed over (as before) took the core
    from the pipeline just when it started on frame k (at 1080p, 30 Hz, one core: the frame waited
    2-8 ms to be taken and its processing lost 2-10 ms to the next frame's decode). A decode that
    finishes late still shows as lag (the arrival is the due time).
    """

    ends = True

    def __init__(self, source: Source):
        self.source = source
        self._paced = source if isinstance(source, PacedSource) else None
        self._it = iter(source.inner if self._paced is not None else source)
        self.arrival_s: float | None = None
        self.decode_s: float | None = None
        self.start_s: float | None = None  # the schedule's start (clock of the PacedSource)
        self._t0: float | None = None
        self._due: float | None = None  # the last frame's due time (clock of the PacedSource)
        self._interval: float | None = None  # the last interval between due times (s)
        self._decodes: deque[float] = deque(maxlen=8)  # the last decode times (s, pacing clock)

    def set_start(self, start_s: float) -> None:
        """Start the replay's schedule at ``start_s`` (s, the PacedSource's clock, e.g. monotonic)."""
        self.start_s = float(start_s)

    def read(self) -> tuple[np.ndarray | None, float | None]:
        p = self._paced
        if p is not None and self._interval is not None and self._decodes:
            # decode just in time: start at the predicted due time (last due + last interval) minus
            # the decode's lead, never before now (the previous frame was handed over already)
            lead = DECODE_LEAD * max(self._decodes) + DECODE_LEAD_SLACK_S
            wait = self._due + self._interval - lead - p.clock()
            if wait > 0:
                p.sleep(wait)
        t0 = time.perf_counter()
        c0 = p.clock() if p is not None else 0.0
        f = next(self._it, None)
        self.decode_s = time.perf_counter() - t0 if f is not None else None
        if p is None:
            self.arrival_s = getattr(self.source, "last_due_s", None)
            return (None, None) if f is None else (f.image, f.t_s)
        if f is None:
            p.error = p.inner.error
            return None, None
        self._decodes.append(p.clock() - c0)  # the decode on the pacing clock
        if self.start_s is None:
            self.start_s = p.clock()
        if self._t0 is None:
            self._t0 = f.t_s
        due = self.start_s + (f.t_s - self._t0) / p.speed  # due = start + (t_k - t_0) / speed
        if self._due is not None:
            self._interval = due - self._due
        self._due = due
        wait = due - p.clock()
        if wait > 0:
            p.sleep(wait)
        p.last_due_s, p.last_arrival_s = due, p.clock()
        p.frames_read += 1
        self.arrival_s = due
        return f.image, f.t_s

    def close(self) -> None:
        self.source.close()


class Grabber:
    """Reads one camera in a thread and keeps only the newest frame.

    Args:
        open_reader: returns a fresh reader (``.read() -> (image or None, t_s or None)``, ``.close()``,
            ``.ends``); raises SourceError when the camera cannot be opened.
        name: camera name (for messages).
        reconnect_initial_s / reconnect_max_s: back-off of reopen attempts (doubling), seconds.
        stall_timeout_s: no frame for this long counts as a stopped camera (reopened).
        skip_unwanted: give readers that can grab without decoding (a ``wanted`` attribute, e.g.
            :class:`CaptureReader`) :meth:`wanted`, so a frame the run loop will not take is not decoded.
            For the lead camera only: the loop tells it when it expects to be ready (:meth:`expect_ready`).

    Counters: ``grabbed``, ``stale`` (replaced before taken, or skipped), ``skipped`` (grabbed but not
    decoded: the loop was busy past the next frame), ``reconnects``, ``errors`` (last message), ``lag``
    (for readers that give a due time, e.g. a paced replay: how late frames were published).
    """

    def __init__(
        self,
        open_reader: Callable[[], Any],
        name: str = "cam0",
        reconnect_initial_s: float = 0.2,
        reconnect_max_s: float = 5.0,
        stall_timeout_s: float = 2.0,
        clock: Callable[[], float] = time.monotonic,
        nice: int | None = None,
        skip_unwanted: bool = False,
    ):
        self.open_reader = open_reader
        self.skip_unwanted = bool(skip_unwanted)
        self._ready_s: float | None = None  # when the run loop expects to take its next frame (clock)
        self._grab_s: deque[float] = deque(maxlen=9)  # clock at the last grabs (skipped ones too)
        self.skipped = 0
        self.name = name
        self.backoff0 = float(reconnect_initial_s)
        self.backoff_max = float(reconnect_max_s)
        self.stall_timeout_s = float(stall_timeout_s)
        self.clock = clock
        self._cond = threading.Condition()
        self._latest: LiveFrame | None = None
        self._recent: deque[LiveFrame] = deque(maxlen=8)  # the last frames, to pair cameras by time
        self._last_publish_s: float | None = None  # clock when the last frame was published
        self._started_s: float | None = None  # clock when the thread was started
        self._taken_seq = -1
        self._stop = threading.Event()
        self.finished = False
        self.grabbed = 0
        self.stale = 0
        self.reconnects = 0
        self.lag = RunningStats()  # seconds from a replayed frame's due time to its publication
        self.nice_wanted = nice
        self.nice: int | None = None  # the thread's nice value as it runs (Linux), None when not read
        self.last_error: str | None = None
        self._reader = None
        self._thread = threading.Thread(target=self._loop, name=f"grab-{name}", daemon=True)

    def start(self, reader: Any = None) -> Grabber:
        """Start the thread; ``reader``: an already opened reader (so open errors reach the caller)."""
        self._reader = reader
        self._started_s = self.clock()
        self._thread.start()
        return self

    def _publish(
        self,
        image: np.ndarray,
        t_s: float | None,
        arrival_s: float | None = None,
        decode_s: float | None = None,
    ) -> None:
        with self._cond:
            if self._latest is not None and self._latest.seq > self._taken_seq:
                self.stale += 1  # never taken: dropped in favour of the newer frame
            now = self.clock()
            self._last_publish_s = now
            if arrival_s is not None:
                self.lag.add(max(0.0, now - arrival_s))
            self._latest = LiveFrame(
                self.grabbed, t_s, image, now if arrival_s is None else arrival_s, now, decode_s
            )
            self._recent.append(self._latest)
            self.grabbed += 1
            self._cond.notify_all()

    def expect_ready(self, ready_s: float | None) -> None:
        """The run loop expects to take its next frame at ``ready_s`` (clock; None: now / unknown)."""
        self._ready_s = ready_s

    def wanted(self) -> bool:
        """Whether the frame just grabbed will be taken: False only when the run loop expects to be busy
        for more than ``SKIP_AFTER_INTERVALS`` frame intervals (from the last grabs' times), i.e. a newer
        frame will have arrived by then. True while either is unknown."""
        ready, g = self._ready_s, self._grab_s
        if ready is None or len(g) < 3:
            return True
        interval = (g[-1] - g[0]) / (len(g) - 1)  # mean interval between grabs
        return not interval > 0 or ready - self.clock() <= SKIP_AFTER_INTERVALS * interval

    def _skip(self) -> None:
        """A frame grabbed but not decoded: counted as grabbed and stale (dropped), not published."""
        with self._cond:
            self._last_publish_s = self.clock()  # the camera is alive
            self.grabbed += 1
            self.stale += 1
            self.skipped += 1

    def _loop(self) -> None:
        self.nice = set_thread_nice(self.nice_wanted)
        backoff = self.backoff0
        reader = self._reader
        while not self._stop.is_set():
            if reader is None:
                try:
                    reader = self.open_reader()
                    self.reconnects += 1
                    backoff = self.backoff0
                except SourceError as e:
                    self.last_error = str(e)
                    self._stop.wait(backoff)
                    backoff = min(backoff * 2, self.backoff_max)
                    continue
            if self.skip_unwanted and hasattr(reader, "wanted") and reader.wanted is None:
                reader.wanted = self.wanted
            t_read = self.clock()
            try:
                image, t_s = reader.read()
            except Exception as e:  # a driver error is a stopped camera, not the end of the run
                image, t_s = None, None
                self.last_error = f"{self.name}: {e}"
            if image is not None:
                self._grab_s.append(self.clock())
            if image is SKIPPED:
                self._skip()
                continue
            arrival = getattr(reader, "arrival_s", None)  # a paced replay's due time, else now
            dec = getattr(reader, "decode_s", None)
            if image is not None and (
                getattr(reader, "ends", False) or self.clock() - t_read <= self.stall_timeout_s
            ):
                self._publish(image, t_s, arrival, dec)
                continue
            if image is not None:  # arrived, but after a stall: keep it, then reopen
                self._publish(image, t_s, arrival, dec)
            if getattr(reader, "ends", False) and image is None:
                reader.close()
                break
            self.last_error = self.last_error or f"{self.name}: camera stopped delivering frames"
            reader.close()
            reader = None
            self._stop.wait(backoff)
            backoff = min(backoff * 2, self.backoff_max)
        if reader is not None:
            reader.close()
        with self._cond:
            self.finished = True
            self._cond.notify_all()

    def take(self, timeout_s: float) -> LiveFrame | None:
        """The newest frame not taken yet; waits up to ``timeout_s`` (s, on ``clock``). None on timeout
        or when finished."""
        self._ready_s = None  # the loop is ready now: the next frame is wanted
        with self._cond:
            deadline = self.clock() + timeout_s
            while self._latest is None or self._latest.seq <= self._taken_seq:
                if self.finished:
                    return None
                left = deadline - self.clock()
                if left <= 0:
                    return None
                self._cond.wait(min(left, _WAIT_POLL_S))
            self._taken_seq = self._latest.seq
            return self._latest

    def _pair_wait_s(self) -> float:
        """How long (s, on ``clock``) :meth:`nearest` waits for a frame at or after the lead's time:
        two of this camera's frame intervals (from its recent frame times) plus scheduling slack, at
        most ``stall_timeout_s``; ``stall_timeout_s`` while the interval is unknown. Caller holds the
        lock."""
        if len(self._recent) < 2:
            return self.stall_timeout_s
        span = frame_time(self._recent[-1]) - frame_time(self._recent[0])
        if not span > 0:
            return self.stall_timeout_s
        interval = span / (len(self._recent) - 1)
        return min(self.stall_timeout_s, 2.0 * interval + PAIR_WAIT_SLACK_S)

    def nearest(self, t: float, tolerance_s: float) -> LiveFrame | None:
        """This camera's frame of frame time ``t`` (another camera's frame; s, :func:`frame_time`).

        Pairing is in frame time: of the last few frames, the one whose time is nearest ``t`` joins
        when ``|time - t| <= tolerance_s``. Waiting is in wall time (on ``clock``) and separate from the
        tolerance: until this camera has a frame at or after ``t`` (so the nearest one is known),
        at most about two frame intervals (:meth:`_pair_wait_s`), and not
        at all for a camera that published nothing for ``stall_timeout_s`` (stopped) or finished.
        None when there is no frame within the tolerance.
        """
        with self._cond:
            now = self.clock()
            deadline = now + self._pair_wait_s()
            last = self._last_publish_s if self._last_publish_s is not None else self._started_s
            if last is not None:  # a stopped camera (nothing for stall_timeout_s) is not waited for
                deadline = min(deadline, last + self.stall_timeout_s)
            while not self.finished and (not self._recent or frame_time(self._recent[-1]) < t):
                left = deadline - self.clock()
                if left <= 0:
                    break
                self._cond.wait(min(left, _WAIT_POLL_S))
            if not self._recent:
                return None
            best = min(self._recent, key=lambda f: abs(frame_time(f) - t))
            if abs(frame_time(best) - t) > tolerance_s:
                return None
            self._taken_seq = max(self._taken_seq, best.seq)
            return best

    def stop(self, timeout_s: float = 5.0) -> None:
        self._stop.set()
        self._thread.join(timeout_s)


# ------------------------------------------------------------------------------------- ego-motion
class GrowingTrajectory(EgoMotion):
    """A TUM trajectory file that another program appends to during the run.

    ``covers(t_s)`` re-reads the file when ``t_s`` lies past the last pose (and the file changed); an
    incomplete last line (no newline yet) is ignored until it is complete. Poses are interpolated as in
    :class:`~estimators.egomotion.TumTrajectory`; outside the span ``pose_at`` raises InputError.
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._traj: TumTrajectory | None = None
        self._stamp: tuple[float, int] | None = None
        self.reloads = 0
        self._reload()

    def _reload(self) -> None:
        try:
            st = self.path.stat()
        except FileNotFoundError:
            return
        stamp = (st.st_mtime, st.st_size)
        if stamp == self._stamp:
            return
        self._stamp = stamp
        text = self.path.read_text()
        rows = []
        for lineno, line in enumerate(text.splitlines(keepends=True), start=1):
            if not line.endswith("\n"):
                break  # being written
            vals = parse_tum_line(line, f"{self.path}:{lineno}")  # TumTrajectory.load's line checks
            if vals is None:
                continue
            if rows and vals[0] <= rows[-1][0]:
                continue  # a repeated stamp from the writer: keep the first
            rows.append(vals)
        if len(rows) >= 2:
            a = np.array(rows)
            self._traj = TumTrajectory(a[:, 0], a[:, 1:4], a[:, 4:8], source=str(self.path))
            self.reloads += 1

    @property
    def start_s(self) -> float | None:
        return None if self._traj is None else float(self._traj.t_s[0])

    @property
    def end_s(self) -> float | None:
        return None if self._traj is None else float(self._traj.t_s[-1])

    def covers(self, t_s: float) -> bool:
        if self._traj is None or not self._traj.covers(t_s):
            self._reload()
        return self._traj is not None and self._traj.covers(t_s)

    def pose_at(self, t_s: float) -> Pose:
        if not self.covers(t_s):
            span = "no poses yet" if self._traj is None else f"poses up to {self.end_s:.3f} s"
            raise InputError(f"{self.path}: no pose for t={t_s:.3f} s ({span})")
        return self._traj.pose_at(t_s)

    def velocity_at(self, t_s: float) -> np.ndarray:
        if not self.covers(t_s):
            raise InputError(f"{self.path}: no pose for t={t_s:.3f} s")
        return self._traj.velocity_at(t_s)


# ------------------------------------------------------------------------------------------ MJPEG
class MjpegServer:
    """Serves the newest published frame as MJPEG on ``http://127.0.0.1:PORT/stream.mjpg``.

    ``/`` is a page showing it; ``/frame.jpg`` the newest frame alone. Bound to loopback only.

    Args:
        port: TCP port (0 = any free port; the chosen one is ``.port``).
        quality: JPEG quality 1..100.

    Raises:
        ConfigError: the port cannot be listened on (in use), naming it and the way out.
    """

    def __init__(self, port: int = 0, quality: int = 80):
        self.quality = int(quality)
        self._cond = threading.Condition()
        self._jpeg: bytes | None = None
        self._seq = 0
        self._closed = False
        server = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def log_message(self, *args) -> None:  # quiet
                pass

            def do_GET(self) -> None:  # noqa: N802 - http.server's name
                if self.path in ("/", "/index.html"):
                    body = (
                        b"<html><head><title>fisheye-des live</title></head><body style='margin:0;"
                        b"background:#111'><img src='/stream.mjpg' style='max-width:100%'></body></html>"
                    )
                    self.send_response(200)
                    self.send_header("Content-Type", "text/html")
                    self.send_header("Content-Length", str(len(body)))
                    self.end_headers()
                    self.wfile.write(body)
                elif self.path.startswith("/frame.jpg"):
                    jpeg = server.wait_frame(-1, 2.0)
                    if jpeg is None:
                        self.send_error(503, "no frame yet")
                        return
                    self.send_response(200)
                    self.send_header("Content-Type", "image/jpeg")
                    self.send_header("Content-Length", str(len(jpeg[1])))
                    self.end_headers()
                    self.wfile.write(jpeg[1])
                elif self.path.startswith("/stream.mjpg"):
                    self.send_response(200)
                    self.send_header("Cache-Control", "no-cache")
                    self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
                    self.end_headers()
                    seq = -1
                    try:
                        while True:
                            got = server.wait_frame(seq, 1.0)
                            if server._closed:
                                break
                            if got is None:
                                continue
                            seq, jpeg = got
                            self.wfile.write(
                                b"--frame\r\nContent-Type: image/jpeg\r\n"
                                + f"Content-Length: {len(jpeg)}\r\n\r\n".encode()
                                + jpeg
                                + b"\r\n"
                            )
                            self.wfile.flush()
                    except (BrokenPipeError, ConnectionResetError):
                        pass
                else:
                    self.send_error(404)

        try:
            self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", int(port)), Handler)
        except OSError as e:  # the port is taken (another preview, a web server) or not ours to bind
            raise ConfigError(
                f"live.preview_port {port}: the MJPEG preview cannot listen on 127.0.0.1:{port} "
                f"({e.strerror or e}); give another --port (0: any free one), or --preview file / none"
            ) from None
        self.httpd.daemon_threads = True
        self.port = int(self.httpd.server_address[1])
        self._thread = threading.Thread(
            target=self.httpd.serve_forever, kwargs={"poll_interval": 0.1}, name="mjpeg", daemon=True
        )
        self._thread.start()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/stream.mjpg"

    def publish(self, image: np.ndarray) -> None:
        """Encode ``image`` (H, W[, 3]) uint8 as JPEG and make it the newest frame."""
        import cv2

        ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, self.quality])
        if not ok:
            raise InputError("MjpegServer.publish: JPEG encoding failed")
        with self._cond:
            self._jpeg = buf.tobytes()
            self._seq += 1
            self._cond.notify_all()

    def wait_frame(self, after_seq: int, timeout_s: float) -> tuple[int, bytes] | None:
        """The newest frame once its sequence number passes ``after_seq`` (None on timeout/close)."""
        with self._cond:
            self._cond.wait_for(
                lambda: self._closed or (self._jpeg is not None and self._seq > after_seq), timeout_s
            )
            if self._closed or self._jpeg is None or self._seq <= after_seq:
                return None
            return self._seq, self._jpeg

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        self.httpd.shutdown()
        self.httpd.server_close()
        self._thread.join(2.0)


# ------------------------------------------------------------------------------------------- loop
class _GcClock:
    """Total seconds (``time.perf_counter``) spent in Python's cyclic garbage collector since it was
    made, any thread; ``close()`` stops counting."""

    def __init__(self) -> None:
        self.total_s = 0.0
        self._t0 = 0.0
        gc.callbacks.append(self._on_gc)

    def _on_gc(self, phase: str, info: dict) -> None:
        if phase == "start":
            self._t0 = time.perf_counter()
        else:
            self.total_s += time.perf_counter() - self._t0

    def close(self) -> None:
        if self._on_gc in gc.callbacks:
            gc.callbacks.remove(self._on_gc)


@dataclass
class LiveResult:
    """Frames processed, stale frames dropped, latency statistics (seconds), reconnects, summary."""

    out_dir: Path
    frames: int
    stale: int
    latency: dict[str, Any]
    reconnects: int
    summary: dict[str, Any]


def make_reader_factory(
    ref: int | str,
    camera: str,
    paced: bool = True,
    expected_size=None,
    timeout_s: float = 5.0,
    grey: bool = False,
) -> Callable[[], Any]:
    """A function opening camera ``ref``: a device index, a URL, or (testing) a video file replayed
    at its real rate when ``paced``.

    ``grey``: deliver (H, W) grey frames, made in the grabber's thread: a video file through
    ``VideoSource(grey=True)`` (a grey video read without colour conversion, as ``run`` reads it), a
    camera or URL converted once per frame (:class:`CaptureReader`)."""
    if isinstance(ref, str) and "://" not in ref and not ref.isdigit():

        def open_file() -> SourceReader:
            src: Source = VideoSource(ref, camera=camera, expected_size=expected_size, grey=grey)
            return SourceReader(PacedSource(src) if paced else src)

        return open_file
    index_or_url = int(ref) if isinstance(ref, str) and ref.isdigit() else ref
    return lambda: CaptureReader(index_or_url, timeout_s, grey=grey)


def latency_log_stages() -> tuple[str, ...]:
    """The stages whose times ``run_live``'s latency CSV gives per frame, as ``<stage>_s`` columns beside
    the latency parts: the front end's (``trackers.frontend.STAGES``), then fusion's
    (``estimators.fusion.STAGES``: ``estimate`` and ``fuse``). A slow frame's time is then found in its
    stages (a periodic ORB detection, the re-detection after a cut), not only in ``process_s``."""
    from estimators.fusion import STAGES as FUSION_STAGES
    from trackers.frontend import STAGES

    return (*STAGES, *FUSION_STAGES)


def _stage_cells(stages: tuple[str, ...], *timings: dict[str, float] | None) -> str:
    """One frame's stage columns of the latency CSV: seconds from the ``timings`` mappings (front end,
    fusion) for each of ``stages``, empty where no mapping has the stage."""
    merged: dict[str, float] = {}
    for tm in timings:
        merged.update(tm or {})
    return ",".join("" if merged.get(k) is None else f"{merged[k]:.6f}" for k in stages)


def run_live(
    cfg: PipelineConfig,
    out_dir: str | Path,
    *,
    rig: Any = None,
    egomotion: Any = None,
    frontend: Any = None,
    fusion: Any = None,
    readers: list[Callable[[], Any]] | None = None,
    max_frames: int | None = None,
    on_frame: Callable[[int, dict], None] | None = None,
    on_event: Callable[[str], None] | None = None,
    latency_log: str | Path | None = None,
) -> LiveResult:
    """Run the pipeline on live cameras until ``live.duration_s``, ``max_frames``, the end of replayed
    files, or Ctrl-C; write tracks.jsonl (flushed per frame), summary.json and the resolved config.

    Args:
        readers: one reader factory per rig camera (default from ``live.cameras``).
        on_frame: called after each written frame with (frame count, {"latency_s": ...}) (tests).
        on_event: called with human-readable notes (the preview URL); the CLI prints them.
        latency_log: a CSV file to write one line per processed frame to: ``seq, t_s`` and the latency
            with its parts in seconds (``latency_s = lag_s + queue_s + process_s + write_s``; ``decode_s``
            beside), as in summary.json's ``latency_parts``; then ``process_cpu_s`` (the loop thread's CPU
            time within process_s) and ``gc_s`` (garbage collection within process_s + write_s); then the
            frame's stage times, ``<stage>_s`` for each of :func:`latency_log_stages` (the front end's
            and fusion's ``timings``; empty where a stage reported none). Its folder must exist (it is
            opened before the cameras, and so before ``out_dir`` is made).

    Raises:
        SourceError: a camera that cannot be opened at start (index that does not exist, bad URL).
        ConfigError: live.deferred_detection true with a front end that has no ``defer_detection``.
        InputError: ``latency_log`` cannot be written (raised before any camera is opened).
        KeyboardInterrupt: re-raised after the outputs are written.
        FisheyeDesError: a stage refused a frame mid-run: after the outputs are written (``error`` in
            summary.json), raised again (same class) with "(outputs up to frame set N are in DIR)".
    """
    # bad input (calibration, trajectory, a stage's settings) fails here, before anything is written
    lv = cfg.live
    rig = rig if rig is not None else build_rig(cfg)
    names = list(rig.names)
    if egomotion is None:
        if cfg.ego_motion.trajectory is not None:
            egomotion = on_frame_clock(GrowingTrajectory(cfg.ego_motion.trajectory), cfg)
        else:
            egomotion = build_egomotion(cfg)
    if not isinstance(egomotion, FramePoseCache):  # one pose per frame for the loop and fusion
        egomotion = FramePoseCache(egomotion)
    frontend = frontend if frontend is not None else build_frontend(cfg, rig)
    fusion = fusion if fusion is not None else build_fusion(cfg, rig, egomotion)
    defer = lv.deferred_detection
    if defer and not hasattr(frontend, "defer_detection"):  # (asked for, not silently left undone)
        raise ConfigError(
            f"live.deferred_detection true: the front end {type(frontend).__name__} has no defer_detection "
            "(its detections cannot run off the frame's path); expected a FrontEnd, or set "
            "live.deferred_detection false"
        )
    if readers is None:
        if len(lv.cameras) != len(names):
            raise SourceError(
                f"live.cameras has {len(lv.cameras)} entries for a rig of {len(names)} ({names})"
            )
        readers = []
        # the fast path of `run`: grey frames for grey detectors, or when every camera is a grey video file
        grey = reads_grey(cfg, lv.cameras)
        for name, ref in zip(names, lv.cameras, strict=True):
            m = rig[name].model
            readers.append(make_reader_factory(ref, name, lv.paced, (int(m.width), int(m.height)), grey=grey))
    # the per-frame latency CSV is opened before any camera: a path that cannot be written fails here
    # (its folder must exist: it is opened before the output folder is made)
    log = None
    log_stages = latency_log_stages() if latency_log is not None else ()
    if latency_log is not None:
        try:
            log = Path(latency_log).open("w", encoding="utf-8")
        except OSError as e:
            raise InputError(f"latency_log: cannot write {str(latency_log)!r} ({e.strerror or e})") from None
        log.write("seq,t_s,latency_s,lag_s,queue_s,process_s,write_s,decode_s,process_cpu_s,gc_s,"
                  + ",".join(f"{k}_s" for k in log_stages) + "\n")
    grabbers: list[Grabber] = []
    opened: list[Any] = []
    worker = writer = server = video = None
    # everything the set-up starts is stopped again when a later step fails (a camera that does not
    # open, a detector the worker cannot take, a preview port in use, an --out that cannot be made): no
    # worker process, grabber thread or open file outlives the error
    try:
        for factory in readers:
            opened.append(factory())  # open errors (no such camera) surface here, before the run
        if defer:  # the periodic re-detection off the frame's path (a worker process), before the grabbers
            worker = detection_worker(lv.detection_nice)
            frontend.defer_detection(worker)
        server = MjpegServer(lv.preview_port) if lv.preview == "mjpeg" else None
        # The output folder only once the cameras, the worker and the preview port are open: a start that
        # fails on those leaves no folder and an earlier run's outputs in --out as they were. From here on
        # the outputs are written (config.resolved.yaml; tracks.jsonl and preview.mp4 created, truncated
        # when there); only a failure to write them (a full disk) or to start a grabber thread still
        # stops the start after this point, and leaves what was written.
        out = make_output_dir(out_dir)
        write_resolved(cfg, out)
        writer = TracksWriter(out / TRACKS_NAME)
        video = VideoWriter(out / "preview.mp4", 30.0) if lv.preview == "file" else None
        # Replayed files of one rig share one schedule start, set once all are open: a camera that took
        # longer to open does not run behind the others (pairing is by the videos' own t_s).
        start_replays = time.monotonic()
        for r in opened:
            if hasattr(r, "set_start"):
                r.set_start(start_replays)
        for name, factory, first in zip(names, readers, opened, strict=True):
            g = Grabber(
                factory,
                name,
                lv.reconnect_initial_s,
                lv.reconnect_max_s,
                lv.stall_timeout_s,
                nice=lv.grabber_nice,
                skip_unwanted=not grabbers,  # the lead camera: frames the loop will not take stay undecoded
            )
            grabbers.append(g.start(first))
    except BaseException:
        for g in grabbers:
            g.stop()
        for r in opened[len(grabbers) :]:
            r.close()
        if worker is not None:
            frontend.defer_detection(None)
            worker.shutdown(wait=True, cancel_futures=True)
        for sink in (writer, server, video, log):
            if sink is not None:
                sink.close()
        raise
    annotator = Annotator(rig, egomotion) if lv.preview != "none" else None
    if on_event is not None:
        if server is not None:
            on_event(f"preview: http://127.0.0.1:{server.port}/ (MJPEG stream {server.url})")
        if video is not None:
            on_event(f"preview: {video.path}")
    latency = RunningStats()  # arrival -> line written and flushed = waited (arrival -> taken) + processing
    waited, processing = RunningStats(), RunningStats()
    # the same latency in four consecutive parts, per frame (they add up to it exactly):
    # lag (arrival -> published by the grabber; a replay behind its schedule), queue (published -> taken
    # by the loop: the frame waits in the grabber's one-frame slot while the previous frame is processed),
    # process (taken -> reports: pairing, pose, front end, fusion), write (the tracks.jsonl line encoded,
    # written and flushed); and, beside them, the reader's decode time of the frame
    # beside them too, where a slow frame's time went: process_cpu (the loop thread's own CPU time from
    # taken to reports; process minus this is time the core gave to the grabbers or to other programs)
    # and gc (Python's cyclic collector, any thread, from taken to written)
    parts = {k: RunningStats() for k in ("lag", "queue", "process", "write", "decode", "process_cpu", "gc")}
    gc_clock = _GcClock()
    unpaired: dict[str, int] = {}  # processed lead frames another camera had no frame within tolerance for
    busy: deque[float] = deque(maxlen=15)  # the last frames' times from taken to ready for the next (s)
    timings = StageTimings()
    frames = 0
    no_pose = 0
    before_start = 0  # of no_pose: frames before the trajectory's first pose (another clock?)
    gap_before = gap_after = None  # s: the farthest skipped frame before the first / after the last pose
    interrupted = False
    failed: Exception | None = None
    # The grabber threads need the GIL for a moment between frames; while the pipeline runs Python, a
    # waiting thread gets it only after the switch interval (5 ms by default), several times per frame,
    # so on one core a replay at 60-100 Hz fell behind its camera's schedule. A short interval while
    # live lets each frame arrive on time.
    switch_interval = sys.getswitchinterval()
    sys.setswitchinterval(min(switch_interval, LIVE_SWITCH_INTERVAL_S))
    # the worker's CPU time over the loop (what the second core costs): read at loop start and end
    worker_pid = getattr(worker, "pid", None)
    worker_cpu_start = process_cpu_s(worker_pid)
    start_mono = time.monotonic()
    start_unix = time.time()
    t_start = time.perf_counter()
    last_t_s = -np.inf
    try:
        with frozen_gc():  # no 50-80 ms full collection of the set-up's objects mid-run
            while True:
                if lv.duration_s is not None and time.monotonic() - start_mono >= lv.duration_s:
                    break
                if max_frames is not None and frames >= max_frames:
                    break
                lead = grabbers[0].take(timeout_s=0.25)
                t_taken = time.monotonic()
                cpu_taken, gc_taken = time.thread_time(), gc_clock.total_s
                if lead is not None and busy:  # busy until about the median of the last frames' times
                    grabbers[0].expect_ready(t_taken + sorted(busy)[len(busy) // 2])
                if lead is None:
                    if grabbers[0].finished:
                        break
                    continue
                images = {names[0]: lead.image}
                missing = []
                for g, n in zip(grabbers[1:], names[1:], strict=True):
                    # the other cameras' frame of the same instant (nearest in frame time, within the
                    # tolerance; waited for about two of its frame intervals); without one the lead frame
                    # goes on alone and the miss is counted (below, once the frame is processed)
                    f = g.nearest(frame_time(lead), lv.sync_tolerance_s)
                    if f is not None:
                        images[n] = f.image
                    else:
                        missing.append(n)
                if lead.t_s is not None:
                    t_s = lead.t_s
                elif lv.clock == "unix":
                    t_s = start_unix + (lead.arrival_s - start_mono)
                else:
                    t_s = lead.arrival_s - start_mono
                if t_s <= last_t_s:
                    continue
                if not egomotion.covers(t_s):
                    start = getattr(egomotion, "start_s", None)
                    if start is not None and t_s < start:  # a file that grows never reaches back to it
                        no_pose += 1
                        before_start += 1
                        gap_before = max(gap_before or 0.0, start - t_s)
                        continue
                    wait_until = time.monotonic() + lv.trajectory_wait_s
                    while not egomotion.covers(t_s) and time.monotonic() < wait_until:
                        time.sleep(0.01)
                    if not egomotion.covers(t_s):
                        no_pose += 1
                        end = getattr(egomotion, "end_s", None)
                        if end is not None:
                            gap_after = max(gap_after or 0.0, t_s - end)
                        continue
                last_t_s = t_s
                for n in missing:  # counted for processed frames only: frames_without_partner <= frames
                    unpaired[n] = unpaired.get(n, 0) + 1
                # The body pose lets the front end take the drone's own rotation out of feature motion.
                obs = frontend.process(images, lead.seq, t_s, T_W_B=egomotion.pose_at(t_s))
                front_tm = getattr(frontend, "timings", None)
                timings.add_all(front_tm)
                reports = fusion.step(obs, lead.seq, t_s)
                fusion_tm = getattr(fusion, "timings", None)
                timings.add_all(fusion_tm)
                t_proc = time.monotonic()
                cpu_s = time.thread_time() - cpu_taken
                items = writer.write(lead.seq, t_s, reports)  # one write + flush per frame
                t_done = time.monotonic()
                gc_s = gc_clock.total_s - gc_taken
                timings.add("write", t_done - t_proc)
                lat = t_done - lead.arrival_s
                latency.add(lat)
                waited.add(t_taken - lead.arrival_s)
                processing.add(t_done - t_taken)
                pub = lead.arrival_s if lead.published_s is None else lead.published_s
                lag_s, queue_s = pub - lead.arrival_s, t_taken - pub
                parts["lag"].add(lag_s)
                parts["queue"].add(queue_s)
                parts["process"].add(t_proc - t_taken)
                parts["write"].add(t_done - t_proc)
                if lead.decode_s is not None:
                    parts["decode"].add(lead.decode_s)
                parts["process_cpu"].add(cpu_s)
                parts["gc"].add(gc_s)
                if log is not None:
                    log.write(
                        f"{lead.seq},{t_s!r},{lat:.6f},{lag_s:.6f},{queue_s:.6f},{t_proc - t_taken:.6f},"
                        f"{t_done - t_proc:.6f},{'' if lead.decode_s is None else f'{lead.decode_s:.6f}'},"
                        f"{cpu_s:.6f},{gc_s:.6f},{_stage_cells(log_stages, front_tm, fusion_tm)}\n"
                    )
                frames += 1
                if annotator is not None and frames % cfg.outputs.every_n == 0:
                    img = annotator.draw(images, items, t_s, lead.seq)
                    if server is not None:
                        server.publish(img)
                    if video is not None:
                        video.write(img)
                if on_frame is not None:
                    on_frame(frames, {"latency_s": lat})
                busy.append(time.monotonic() - t_taken)  # taken -> ready for the next frame
    except KeyboardInterrupt:
        interrupted = True
    except Exception as e:  # a stage refused a frame (or failed): recorded, raised below with where to look
        failed = e
    finally:
        deferred = None
        # the outputs first, the worker last: its shutdown waits for a detection under way (kornia on a
        # CPU: ~1 s), and a Ctrl-C or an error there must not cost tracks.jsonl or summary.json; a second
        # Ctrl-C or SIGTERM while the grabbers stop (up to 5 s a camera) or the files close does not either
        try:
            try:
                gc_clock.close()
                sys.setswitchinterval(switch_interval)
                for g in grabbers:
                    g.stop()
                # the detection under way (if any) is dropped; the process ends with the run
                if worker is not None:
                    frontend.defer_detection(None)
                    per_cam = getattr(frontend, "deferred", {})
                    worker_cpu_end = process_cpu_s(worker_pid)
                    deferred = {
                        "worker_nice": getattr(worker, "nice", None),
                        # CPU seconds (user + system) the worker process used from loop start to end; None
                        # where /proc cannot be read
                        "worker_cpu_s": (
                            None if worker_cpu_start is None or worker_cpu_end is None
                            else worker_cpu_end - worker_cpu_start
                        ),
                        "joined": {n: d["joined"] for n, d in per_cam.items()},
                        "frames_late": {n: d["frames_late"] for n, d in per_cam.items()},
                    }
                writer.close()
                if log is not None:
                    log.close()
                if server is not None:
                    server.close()
                if video is not None:
                    video.close()
            except KeyboardInterrupt:  # (after the loop's end too: the run is interrupted)
                interrupted = True
                raise
            finally:
                wall = time.perf_counter() - t_start
                summary = {
                    "mode": "live",
                    "frames": frames,
                    "tracks": len(writer.track_ids),
                    "wall_s": wall,
                    "frames_per_s": frames / wall if wall > 0 else None,
                    "interrupted": interrupted,
                    # the message of the error that stopped the run (null when it ended normally)
                    "error": None if failed is None else error_text(failed),
                    "latency": latency.summary(),
                    # latency split: from arrival until the loop took the frame, and from then to its line
                    "latency_waited": waited.summary(),
                    "latency_processing": processing.summary(),
                    # the same split finer (they add up per frame): lag + queue + process + write; decode
                    # beside
                    "latency_parts": {k: v.summary() for k, v in parts.items()},
                    # replays only: how late each frame was published after it was due (the grabber's lag)
                    "replay_lag": {g.name: g.lag.summary() for g in grabbers if g.lag.n},
                    "stale_frames_dropped": {g.name: g.stale for g in grabbers},
                    "frames_grabbed": {g.name: g.grabbed for g in grabbers},
                    "drop_rate": {g.name: g.stale / g.grabbed if g.grabbed else None for g in grabbers},
                    # of the dropped: grabbed but never decoded (the loop was busy past the next frame;
                    # cameras)
                    "frames_not_decoded": {g.name: g.skipped for g in grabbers},
                    "reopened": {g.name: max(0, g.reconnects) for g in grabbers},
                    "grabber_nice": {g.name: g.nice for g in grabbers},
                    # the re-detections run off the frame's path (live.deferred_detection): the worker
                    # process's nice value and CPU seconds over the loop; per feature tracker, detections
                    # joined and the frames processed in all between each detection's frame and its join
                    "deferred_detection": deferred,
                    "last_camera_error": {g.name: g.last_error for g in grabbers if g.last_error},
                    "frames_without_pose": no_pose,
                    "frames_before_trajectory": before_start,
                    "pose_gap_before_s": gap_before,
                    "pose_gap_after_s": gap_after,
                    "frames_without_partner": {n: unpaired.get(n, 0) for n in names[1:]},
                    "timings": timings.summary(),
                    "parameters": cfg.model_dump(mode="json"),
                }
                write_json(out / SUMMARY_NAME, summary)
        finally:
            if worker is not None:
                worker.shutdown(wait=True, cancel_futures=True)
    if interrupted:
        raise KeyboardInterrupt
    if failed is not None:
        raise stopped_error(failed, frames, out)
    return LiveResult(
        out,
        frames,
        sum(g.stale for g in grabbers),
        summary["latency"],
        sum(g.reconnects for g in grabbers),
        summary,
    )
