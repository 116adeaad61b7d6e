"""The run loop of ``fisheye-des run``: sources -> front end -> fusion -> sinks, streaming.

Per frame set: decode (the sources), ``FrontEnd.process`` (detect, track, group, associate),
``ObstacleFusion.step`` (estimate, fuse), then one flushed ``tracks.jsonl`` line (write). Nothing
is kept per frame, so memory stays flat over a long video; per-stage timings are running
statistics over a bounded reservoir. Ctrl-C (KeyboardInterrupt) and a video that breaks halfway
both leave every output written so far: ``tracks.jsonl`` up to the last frame, ``summary.json``,
``config.resolved.yaml``, and the annotated video / plots when asked for.

Batch: :func:`run_batch` runs several recordings in parallel worker processes, one folder each.
"""

from __future__ import annotations

import contextlib
import gc
import math
import os
import random
import sys
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from estimators.errors import ConfigError, FisheyeDesError, InputError, SourceError
from pipeline.config import PipelineConfig, t0_beside_trajectory, write_resolved
from pipeline.sinks import (
    SUMMARY_NAME,
    TRACKS_NAME,
    Annotator,
    TracksWriter,
    VideoWriter,
    make_output_dir,
    make_plots,
    write_json,
)
from pipeline.sources import (
    VIDEO_SUFFIXES,
    ImageFolderSource,
    PrefetchSource,
    Source,
    SyncedSource,
    VideoSource,
    is_grey_video,
)
from trackers.detectors import GREY_DETECTORS

__all__ = [
    "RunningStats",
    "StageTimings",
    "FramePoseCache",
    "ClockOffset",
    "EDGE_S",
    "on_frame_clock",
    "RunResult",
    "build_rig",
    "build_egomotion",
    "build_frontend",
    "build_fusion",
    "tracked_pixel_scale",
    "tracked_window_px",
    "open_inputs",
    "run",
    "run_batch",
    "error_text",
    "stopped_error",
    "find_recording",
    "GREY_DETECTORS",
    "wants_grey",
    "cpus_allowed",
    "frozen_gc",
]


# ----------------------------------------------------------------------------------- frame loops
@contextlib.contextmanager
def frozen_gc():
    """Keep Python's cyclic garbage collector off the objects that exist when a frame loop starts.

    Everything alive at entry (modules, the config, the built rig, front end and fusion: ~90,000
    objects) is moved to the collector's permanent generation (``gc.freeze``), so a full collection
    during the loop scans only what the loop created. Without it a full (generation 2) collection
    stops one frame for 50-80 ms (measured at 640x480: one in the first ~60 frames), which is a live
    run's 99th-percentile latency by itself. Frozen objects are still freed by reference counting;
    only cycles among them wait until the loop ends (``gc.unfreeze`` puts them back in the oldest
    generation). The young generations are collected first, so the set-up's own garbage is not frozen.
    """
    gc.collect(1)
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


# ------------------------------------------------------------------------------------- statistics
class RunningStats:
    """Count, mean, max, total of a stream of durations, and median/p99 over a bounded reservoir.

    Memory is O(``reservoir``) however long the run (Vitter's algorithm R: the k-th sample replaces a
    random slot with probability ``reservoir / k``, so the reservoir is a uniform sample of all).
    """

    def __init__(self, reservoir: int = 2048, seed: int = 0):
        self.capacity = int(reservoir)
        self._samples: list[float] = []
        self._rng = random.Random(seed)
        self.n = 0
        self.total = 0.0
        self.max = -math.inf

    def add(self, x: float) -> None:
        x = float(x)
        self.n += 1
        self.total += x
        self.max = max(self.max, x)
        if len(self._samples) < self.capacity:
            self._samples.append(x)
        else:
            j = self._rng.randrange(self.n)
            if j < self.capacity:
                self._samples[j] = x

    def summary(self) -> dict[str, float | int]:
        """``{"n", "median_s", "p99_s", "mean_s", "max_s", "total_s"}`` (the bench's Stats keys)."""
        if self.n == 0:
            return {"n": 0}
        a = np.asarray(self._samples)
        return {
            "n": self.n,
            "median_s": float(np.percentile(a, 50)),
            "p99_s": float(np.percentile(a, 99)),
            "mean_s": self.total / self.n,
            "max_s": self.max,
            "total_s": self.total,
        }


class StageTimings:
    """Running statistics per named stage (seconds per frame)."""

    def __init__(self, reservoir: int = 2048):
        self.reservoir = reservoir
        self.stages: dict[str, RunningStats] = {}

    def add(self, stage: str, seconds: float) -> None:
        st = self.stages.get(stage)
        if st is None:
            st = self.stages[stage] = RunningStats(self.reservoir, seed=len(self.stages))
        st.add(seconds)

    def add_all(self, timings: Mapping[str, float] | None) -> float:
        """Add each finite stage time of timings (stage -> s); returns their sum (s)."""
        total = 0.0
        for k, v in (timings or {}).items():
            if v is not None and math.isfinite(float(v)):
                self.add(k, float(v))
                total += float(v)
        return total

    def summary(self) -> dict[str, dict[str, float | int]]:
        return {k: v.summary() for k, v in self.stages.items()}


# ------------------------------------------------------------------------------------- ego-motion
class FramePoseCache:
    """An ego-motion source that remembers its last answer, so the run loop (the front end's body pose)
    and fusion (``pose_at`` / ``velocity_at`` of the same frame time) compute a frame's pose once.

    A TUM trajectory's ``pose_at`` (slerp, quaternion to matrix, a checked ``Pose``) costs 0.2-0.3 ms of
    CPU here; it was asked twice per frame. ``covers`` and anything else go to the wrapped source
    unchanged (a growing trajectory still re-reads its file). Answers are the wrapped source's own
    objects for the same ``t_s`` (s); velocities are (3,) m/s in W, returned as copies.

    Args:
        inner: an ``estimators.egomotion.EgoMotion`` (``pose_at``, ``velocity_at``, ``covers``).
    """

    def __init__(self, inner: Any):
        self.inner = inner
        self._pose_t: float | None = None
        self._pose: Any = None
        self._vel_t: float | None = None
        self._vel: np.ndarray | None = None

    def pose_at(self, t_s: float) -> Any:
        """``T_W_B`` at ``t_s`` (s): the wrapped source's, computed once per distinct time in a row."""
        if t_s != self._pose_t or self._pose is None:
            self._pose = self.inner.pose_at(t_s)  # errors (outside the span) raise as before
            self._pose_t = t_s
        return self._pose

    def velocity_at(self, t_s: float) -> np.ndarray:
        """Body velocity ``v_W`` (3,) m/s at ``t_s`` (s), a copy of the remembered answer."""
        if t_s != self._vel_t or self._vel is None:
            self._vel = np.asarray(self.inner.velocity_at(t_s), dtype=float)
            self._vel_t = t_s
        return self._vel.copy()

    def covers(self, t_s: float) -> bool:
        return self.inner.covers(t_s)

    def __getattr__(self, name: str) -> Any:  # anything else (a trajectory's start_s, end_s): the inner's
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)


#: How far (s) past either end of a trajectory a frame time may lie and take that end's pose: half a
#: millisecond, the rounding of a video's own frame times where its container stores whole milliseconds
#: (Matroska), so the frame a trajectory ends on (1.466667 s) is covered at its rounded time (1.467 s).
#: At 20 m/s that is 1 cm of motion; beyond it a frame outside the span is an error, as before.
EDGE_S = 0.5e-3


class ClockOffset:
    """A trajectory read at frame times: frame time ``t_s`` is its time ``t_s + offset_s``
    (``ego_motion.time_offset_s``, the trajectory's clock minus the frames'; 0 when they share one), and a
    time within :data:`EDGE_S` outside its span takes the nearer end's pose (the rounding of a video's
    own frame times). ``pose_at``, ``velocity_at``, ``covers`` and ``start_s`` are in frame times. An
    error outside the span names the frame time (and, with an offset, the trajectory's); for a frame before
    the first pose it says how long before, and names ``ego_motion.time_offset_s``: a trajectory on
    another clock (a flight log's) is the usual cause.

    Args:
        inner: an ``estimators.egomotion.TumTrajectory`` (pose times ``t_s``) or a
            ``pipeline.live.GrowingTrajectory`` (``start_s``, ``end_s``), on the trajectory's clock.
        offset_s: seconds added to a frame time, finite.
    """

    def __init__(self, inner: Any, offset_s: float = 0.0):
        self.inner = inner
        self.offset_s = float(offset_s)

    def _span(self) -> tuple[float, float] | None:
        """The trajectory's first and last pose times (its clock); None before it has two poses."""
        t = getattr(self.inner, "t_s", None)
        if t is not None:
            return float(t[0]), float(t[-1])
        lo, hi = self.inner.start_s, self.inner.end_s
        return None if lo is None else (lo, hi)

    @property
    def start_s(self) -> float | None:
        """The frame time of the trajectory's first pose; None before it has two poses."""
        span = self._span()
        return None if span is None else span[0] - self.offset_s

    @property
    def end_s(self) -> float | None:
        """The frame time of the trajectory's last pose (so far, for a growing file); None before two."""
        span = self._span()
        return None if span is None else span[1] - self.offset_s

    def _at(self, t_s: float) -> float:
        """Frame time ``t_s`` on the trajectory's clock, moved onto an end it misses by <= EDGE_S."""
        t = t_s + self.offset_s
        if self.inner.covers(t):
            return t
        span = self._span()
        if span is not None:
            lo, hi = span
            if lo - EDGE_S <= t < lo:
                return lo
            if hi < t <= hi + EDGE_S:
                return hi
        return t

    def _ask(self, what: str, t_s: float) -> Any:
        try:
            return getattr(self.inner, what)(self._at(t_s))
        except InputError as e:
            msg = str(e)
            if self.offset_s:
                msg = f"frame time {t_s:.6f} s + ego_motion.time_offset_s {self.offset_s!r} s: {msg}"
            start = self.start_s
            if start is not None and t_s < start:
                msg += (f"; the frame is {start - t_s:.6f} s before the trajectory's first pose: a "
                        "trajectory on another clock needs ego_motion.time_offset_s (its time minus the "
                        "frame's)")
            raise InputError(msg) from None

    def pose_at(self, t_s: float) -> Any:
        return self._ask("pose_at", t_s)

    def velocity_at(self, t_s: float) -> np.ndarray:
        return self._ask("velocity_at", t_s)

    def covers(self, t_s: float) -> bool:
        return self.inner.covers(self._at(t_s))


def on_frame_clock(trajectory: Any, cfg: PipelineConfig) -> ClockOffset:
    """``trajectory`` read at frame times (:class:`ClockOffset` by ``ego_motion.time_offset_s``)."""
    return ClockOffset(trajectory, cfg.ego_motion.time_offset_s)


# -------------------------------------------------------------------------------------- factories
def build_rig(cfg: PipelineConfig) -> Any:
    """The ``estimators.rig.Rig`` of the config: from the calibration file, or the inline cameras."""
    if cfg.rig.calibration is not None:
        from estimators.calibration import load_rig

        return load_rig(cfg.rig.calibration)
    if cfg.rig.cameras:
        from estimators.cameras import make_camera_model
        from estimators.rig import Camera, Rig, down_T_C_B, forward_T_C_B, up_T_C_B

        mounts = {"forward": forward_T_C_B, "up": up_T_C_B, "down": down_T_C_B}
        cams = []
        for c in cfg.rig.cameras:
            model = make_camera_model(c.model, **c.params)
            cams.append(Camera(c.name, model, mounts[c.mount](c.position_m)))
        return Rig(tuple(cams))
    raise ConfigError(
        "no cameras: give a calibration file (--calibration PATH or rig.calibration in the config) "
        "or rig.cameras"
    )


def build_egomotion(cfg: PipelineConfig) -> Any:
    """``TumTrajectory`` from ``ego_motion.trajectory`` (on the frames' clock: ``time_offset_s``) or
    ``ConstantVelocity`` from ``speed_mps``."""
    from estimators.egomotion import ConstantVelocity, TumTrajectory

    em = cfg.ego_motion
    if em.trajectory is not None:
        return on_frame_clock(TumTrajectory.load(em.trajectory), cfg)
    if em.speed_mps is not None:
        return ConstantVelocity(speed_mps=em.speed_mps, t0_s=em.t0_s)
    raise ConfigError(
        "no ego-motion: give --trajectory PATH (TUM file of T_W_B) or --speed-mps V (constant speed along "
        "body x, m/s), or ego_motion.trajectory / ego_motion.speed_mps in the config"
    )


def build_frontend(cfg: PipelineConfig, rig: Any) -> Any:
    """``trackers.frontend.FrontEnd(rig, detector=name, detector_options=..., features=..., ...)``."""
    from trackers.frontend import FrontEnd

    opts = cfg.tracker.frontend_options()
    if cfg.detector.options:
        opts["detector_options"] = dict(cfg.detector.options)
    try:
        return FrontEnd(rig, detector=cfg.detector.name, **opts)
    except TypeError as e:
        raise ConfigError(f"detector.options / tracker: {e}") from None


def tracked_pixel_scale(cfg: PipelineConfig, rig: Any) -> dict[str, float]:
    """Per camera, the scale its features are tracked at by the front end ``cfg`` configures
    (``trackers.frontend.tracked_scale`` of its max_width): fusion's ``pixel_scale``."""
    from trackers.frontend import MAX_WIDTH_PX, tracked_scale

    return tracked_scale(rig, cfg.tracker.frontend_options().get("max_width", MAX_WIDTH_PX))


def tracked_window_px(cfg: PipelineConfig, rig: Any) -> dict[str, int]:
    """Per camera, the KLT window (tracked px) of the front end ``cfg`` configures
    (``trackers.frontend.tracked_window`` of ``tracker.features``): fusion's ``window_px``."""
    from trackers.frontend import tracked_window

    return tracked_window(rig, cfg.tracker.features)


def build_fusion(cfg: PipelineConfig, rig: Any, egomotion: Any, settings: Any = None) -> Any:
    """``estimators.fusion.ObstacleFusion(rig, egomotion, settings, pixel_scale, window_px)``:
    settings ``FusionSettings(**fusion)`` of ``cfg`` unless given; pixel_scale and window_px the
    front end's (``tracked_pixel_scale``, ``tracked_window_px``)."""
    from estimators.fusion import FusionSettings, ObstacleFusion

    if settings is None:
        settings = FusionSettings(**cfg.fusion.settings_kwargs())
    return ObstacleFusion(rig, egomotion, settings, pixel_scale=tracked_pixel_scale(cfg, rig),
                          window_px=tracked_window_px(cfg, rig))


def wants_grey(cfg: PipelineConfig) -> bool:
    """``inputs.grey``, or by default whether the detector works on grey images (``GREY_DETECTORS``)."""
    if cfg.inputs.grey is not None:
        return bool(cfg.inputs.grey)
    return cfg.detector.name.lower() in GREY_DETECTORS


def reads_grey(cfg: PipelineConfig, refs: Iterable[str | Path]) -> bool:
    """Whether the videos ``refs`` (one per camera; run, live and bench decide alike) are decoded
    to grey: ``wants_grey``, or by default (``inputs.grey`` null) also when every file's stream is
    itself grey (``pipeline.sources.is_grey_video``): a colour detector (navlights) finds nothing in
    it, so it is read without any colour conversion, as for ORB alone. One colour video: all colour."""
    if wants_grey(cfg):
        return True
    if cfg.inputs.grey is not None:
        return False
    return all(Path(str(r)).is_file() and is_grey_video(r) for r in refs)


def cpus_allowed() -> int:
    """How many CPUs this process may run on (its affinity mask where the OS has one)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def open_inputs(cfg: PipelineConfig, rig: Any) -> SyncedSource:
    """One source per rig camera (videos or image folders, in the rig's order), kept in step by t_s."""
    names = list(rig.names)
    inp = cfg.inputs
    if inp.videos and inp.images:
        raise ConfigError("inputs: give videos or image folders, not both")
    refs = list(inp.videos or inp.images)
    if not refs:
        raise ConfigError("no input: give --video PATH (one per camera, cam0 first) or inputs.videos")
    if len(refs) != len(names):
        raise ConfigError(
            f"{len(refs)} input(s) for a rig of {len(names)} camera(s) ({', '.join(names)}); "
            "expected one video or image folder per camera, in that order"
        )
    sources: list[Source] = []
    # grey for a grey detector, or when every video is itself grey (as bench's LoopingSource decides)
    grey = wants_grey(cfg) if inp.images else reads_grey(cfg, refs)
    # Read-ahead only when a second CPU can decode while the loop runs: on one core the thread overlaps
    # nothing (measured at 720p, one pinned core: same CPU per frame with and without it, within the
    # noise of a shared machine) and only moves the decode time into other stages' clocks.
    ahead = inp.prefetch if cpus_allowed() > 1 else 0
    try:
        for name, ref in zip(names, refs, strict=True):
            model = rig[name].model
            size = (int(model.width), int(model.height))
            if inp.images:
                sources.append(
                    ImageFolderSource(ref, camera=name, expected_size=size, fps=inp.fps, grey=grey)
                )
            else:
                src: Source = VideoSource(ref, camera=name, expected_size=size, fps=inp.fps, grey=grey)
                sources.append(PrefetchSource(src, ahead) if ahead else src)
    except BaseException:
        for s in sources:
            s.close()
        raise
    return SyncedSource(sources, tolerance_s=inp.sync_tolerance_s)


# ------------------------------------------------------------------------------------------- run
def error_text(e: BaseException) -> str:
    """The ``error`` that summary.json records for an exception that stopped a run mid-way: the
    message of a fisheye-des error, else the exception's type and message."""
    return str(e) if isinstance(e, FisheyeDesError) else f"{type(e).__name__}: {e}"


def stopped_error(e: Exception, frames: int, out: Path) -> Exception:
    """What a run (or live run) stopped by ``e`` raises once its outputs are written: a fisheye-des
    error again, same class, its message ending "(outputs up to frame set N are in DIR)"; anything
    else (a bug) unchanged. The fisheye-des error carries ``frames`` and ``out_dir`` (what was kept)."""
    if isinstance(e, FisheyeDesError):
        kept = type(e)(f"{e} (outputs up to frame set {frames} are in {out})")
        kept.__cause__ = e
        kept.frames = frames
        kept.out_dir = out
        return kept
    return e


@dataclass
class RunResult:
    """What a run did: output folder, frame sets processed, distinct tracks, wall time, frames/s, and
    the error (a video that broke) or interruption that ended it early."""

    out_dir: Path
    frames: int
    tracks: int
    wall_s: float
    frames_per_s: float
    error: str | None = None
    interrupted: bool = False
    summary: dict[str, Any] = field(default_factory=dict)


class _NoProgress:
    """The progress bar when it is off: tqdm(disable=True) still builds a multiprocessing lock on
    creation (~0.1 s of CPU, inside the run's measured time on a 150-frame bench clip)."""

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def _progress(total: int | None, enabled: bool, desc: str):
    if not enabled:
        return _NoProgress()
    from tqdm import tqdm

    return tqdm(
        total=total,
        unit="frame",
        desc=desc,
        file=sys.stderr,
        disable=not enabled,
        dynamic_ncols=True,
        smoothing=0.1,
    )


def run(
    cfg: PipelineConfig,
    out_dir: str | Path | None = None,
    *,
    rig: Any = None,
    egomotion: Any = None,
    source: SyncedSource | None = None,
    frontend: Any = None,
    fusion: Any = None,
    progress: bool | None = None,
    config_source: str | Path | None = None,
    overrides: tuple[str, ...] | list[str] = (),
    raise_on_source_error: bool = True,
) -> RunResult:
    """Run the pipeline over recorded inputs and write the outputs into ``out_dir``.

    Args:
        cfg: the validated config; out_dir: output folder (default ``cfg.outputs.dir``, else ``runs/run``).
        rig, egomotion, source, frontend, fusion: injected stages (tests, demo); built from ``cfg`` when None.
        progress: show a tqdm bar on stderr (default ``cfg.outputs.progress``).
        config_source, overrides: recorded in the resolved config's header.
        raise_on_source_error: after writing everything, raise the SourceError of a video that broke
            halfway (the CLI then exits non-zero); otherwise it is only in the result and summary.

    Raises:
        KeyboardInterrupt: re-raised after every output so far has been written.
        FisheyeDesError: a stage refused a frame mid-run (a frame of the wrong size, a time outside the
            trajectory): after every output so far has been written, with ``error`` in summary.json,
            raised again (same class) with "(outputs up to frame set N are in DIR)" appended.
    """
    out = Path(out_dir) if out_dir is not None else (cfg.outputs.dir or Path("runs") / "run")
    # bad input fails here, before anything is written
    rig = rig if rig is not None else build_rig(cfg)
    egomotion = egomotion if egomotion is not None else build_egomotion(cfg)
    if not isinstance(egomotion, FramePoseCache):  # one pose per frame for the loop and fusion
        egomotion = FramePoseCache(egomotion)
    source = source if source is not None else open_inputs(cfg, rig)
    try:
        frontend = frontend if frontend is not None else build_frontend(cfg, rig)
        fusion = fusion if fusion is not None else build_fusion(cfg, rig, egomotion)
        make_output_dir(out)  # an --out that is a file or cannot be written: one line, nothing run
    except BaseException:
        source.close()
        raise
    write_resolved(cfg, out, source=config_source, overrides=overrides)
    show = cfg.outputs.progress if progress is None else progress

    total = None
    counts = [getattr(s, "frame_count", None) for s in source.sources]
    if counts and all(c for c in counts):
        total = min(counts)
    if cfg.inputs.max_frames:
        total = min(total, cfg.inputs.max_frames) if total else cfg.inputs.max_frames
    fps_in = next((s.fps for s in source.sources if getattr(s, "fps", None)), None)

    timings = StageTimings()
    per_frame = RunningStats()
    writer = TracksWriter(out / TRACKS_NAME)
    video = VideoWriter(out / "annotated.mp4", fps_in or 30.0) if cfg.outputs.annotated_video else None
    annotator = Annotator(rig, egomotion) if video is not None else None
    frames = 0
    interrupted = False
    failed: Exception | None = None
    first_t = last_t = None
    t_start = time.perf_counter()
    cpu_start = time.process_time()
    bar = _progress(total, show, out.name)
    it = iter(source)
    perf = time.perf_counter
    max_frames = cfg.inputs.max_frames or 0
    every_n = cfg.outputs.every_n
    add = timings.add
    try:
        with frozen_gc():  # no full collection of the set-up's objects in the loop
            while True:
                t0 = perf()
                fs = next(it, None)
                t1 = perf()
                if fs is None:
                    break
                # The body pose lets the front end take the drone's own rotation out of feature motion;
                # outside the trajectory's span fusion.step raises the error that names the frame.
                T_W_B = egomotion.pose_at(fs.t_s) if egomotion.covers(fs.t_s) else None
                t1p = perf()
                obs = frontend.process(fs.images, fs.frame, fs.t_s, T_W_B=T_W_B)
                reports = fusion.step(obs, fs.frame, fs.t_s)
                t2 = perf()
                items = writer.write(fs.frame, fs.t_s, reports)
                t3 = t_ann = perf()
                if video is not None and frames % every_n == 0:
                    video.write(annotator.draw(fs.images, items, fs.t_s, fs.frame))
                    t_ann = perf()
                    add("annotate", t_ann - t3)
                # stage times, each millisecond counted once: the front end's and fusion's own (detect ...
                # fuse), "unattributed" (time inside FrontEnd.process / ObstacleFusion.step that their own
                # stage timings do not cover), the loop's decode, write, annotate, and "loop" (the rest:
                # statistics, progress bar, pose look-up)
                staged = (timings.add_all(getattr(frontend, "timings", None))
                          + timings.add_all(getattr(fusion, "timings", None)))
                add("decode", t1 - t0)
                add("write", t3 - t2)
                add("unattributed", max(0.0, (t2 - t1p) - staged))
                first_t = fs.t_s if first_t is None else first_t
                last_t = fs.t_s
                frames += 1
                bar.update(1)
                t4 = perf()
                per_frame.add(t4 - t0)
                add("loop", (t1p - t1) + (t4 - t_ann))  # the loop's own: pose look-up, statistics, progress
                if max_frames and frames >= max_frames:
                    break
    except KeyboardInterrupt:
        interrupted = True
    except Exception as e:  # a stage refused a frame (or failed): recorded, raised below with where to look
        failed = e
    finally:
        try:  # (a second Ctrl-C or SIGTERM in the closes still writes summary.json, then no plots)
            bar.close()
            writer.close()
            source.close()
            if video is not None:
                video.close()
        except KeyboardInterrupt:  # (after a normal end too: the run is interrupted)
            interrupted = True
            raise
        finally:
            wall = time.perf_counter() - t_start
            cpu = time.process_time() - cpu_start  # all threads of this process (OpenCV's too)
            error = source.error if failed is None else error_text(failed)
            summary = {
                "frames": frames,
                "tracks": len(writer.track_ids),
                "track_reports_by_status": dict(writer.statuses),
                "wall_s": wall,
                "frames_per_s": frames / wall if wall > 0 else None,
                "cpu_s": cpu,
                "cpu_s_per_frame": cpu / frames if frames else None,
                "t_s_first": first_t,
                "t_s_last": last_t,
                "interrupted": interrupted,
                "error": error,
                "dropped_unpaired_frames": dict(source.dropped),
                "rig": {"kind": getattr(rig, "kind", None), "cameras": list(getattr(rig, "names", []))},
                "inputs": [getattr(s, "path", getattr(s, "folder", None)) for s in source.sources],
                "frame_times": {s.camera: s.frame_times for s in source.sources},
                "timings": timings.summary(),
                "per_frame": per_frame.summary(),
                "outputs": {"tracks": TRACKS_NAME, "config": "config.resolved.yaml"},
                "parameters": cfg.model_dump(mode="json"),
                "pid": os.getpid(),
            }
            if video is not None and video.frames:
                summary["outputs"]["annotated_video"] = video.path.name
            write_json(out / SUMMARY_NAME, summary)  # first: a second Ctrl-C during the plots loses nothing
        if cfg.outputs.plots and frames:
            try:
                names = [p.name for p in make_plots(out / TRACKS_NAME, out, cfg.outputs.max_plot_tracks)]
                summary["outputs"]["plots"] = names
            except FisheyeDesError as e:  # a plot is never worth losing the run over
                summary["outputs"]["plots_error"] = str(e)
            write_json(out / SUMMARY_NAME, summary)
    if interrupted:
        raise KeyboardInterrupt
    if failed is not None:
        raise stopped_error(failed, frames, out)
    result = RunResult(
        out, frames, len(writer.track_ids), wall, summary["frames_per_s"] or 0.0, error, interrupted, summary
    )
    if error and raise_on_source_error:
        raise SourceError(f"{error} (outputs up to frame set {frames} are in {out})")
    return result


# ------------------------------------------------------------------------------------------ batch
def find_recording(folder: Path, names: list[str]) -> list[Path] | None:
    """The videos of camera ``names`` in a recording folder (``<name>.<ext>``), or None when absent."""
    found = []
    for n in names:
        cands = [folder / f"{n}{ext}" for ext in VIDEO_SUFFIXES if (folder / f"{n}{ext}").is_file()]
        if not cands:
            return None
        found.append(cands[0])
    return found


# a batch worker process's state: the batch's stop event (set by the parent on a Ctrl-C or SIGTERM) and
# whether a recording is under way (a signal between recordings must not end the worker's own loop)
_BATCH_WORKER: dict[str, Any] = {"stop": None, "in_job": False, "interrupted": False}


def _batch_worker_init(stop: Any) -> None:
    """A batch worker process: a Ctrl-C (the terminal's, to the whole process group) or a SIGTERM (from
    the parent, or a supervisor's to every process of the unit: systemd's KillMode=control-group) stops
    the recording under way as in a single run
    (its summary.json written, ``interrupted`` true); later signals do nothing, so that the clean-up
    is not cut short; a recording not yet started is not run (the stop event)."""
    import signal

    _BATCH_WORKER["stop"] = stop

    def interrupt(signum: int, frame: Any) -> None:  # (the handlers stay: a signal already pending
        if _BATCH_WORKER["in_job"] and not _BATCH_WORKER["interrupted"]:  # when one became SIG_IGN raised
            _BATCH_WORKER["interrupted"] = True  # "ignored due to race condition")
            raise KeyboardInterrupt

    signal.signal(signal.SIGINT, interrupt)
    signal.signal(signal.SIGTERM, interrupt)


# why a recording did not run, or stopped, when a signal reached its worker process alone
_WORKER_INTERRUPTED = "its worker process was interrupted"


def _batch_pool_job(args: tuple[dict, str, str | None]) -> dict:
    """:func:`_batch_worker` in a worker process: not run once the batch is stopped; an interrupted
    recording is reported as such (``interrupted``). A recording is under way (``in_job``) from before
    the stop event is read: a signal between that read and the recording's start stops it too. A worker
    once interrupted runs no other recording: a signal that reached it directly (a Ctrl-C, systemd's
    SIGTERM to the whole group) can come before the parent sets the stop event, and the worker, which
    takes no second signal, would run the next recording to its end."""
    _BATCH_WORKER["in_job"] = True
    try:
        if _BATCH_WORKER["stop"].is_set():
            return {"out_dir": args[1], "frames": 0, "not_run": True}
        if _BATCH_WORKER["interrupted"]:
            return {"out_dir": args[1], "frames": 0, "not_run": True, "why": _WORKER_INTERRUPTED}
        return _batch_worker(args)
    except KeyboardInterrupt:
        if _BATCH_WORKER["stop"].is_set():
            return {"out_dir": args[1], "interrupted": True}
        return {"out_dir": args[1], "interrupted": True, "why": _WORKER_INTERRUPTED}
    finally:
        _BATCH_WORKER["in_job"] = False


def _batch_worker(args: tuple[dict, str, str | None]) -> dict:
    cfg_dict, out_dir, config_source = args
    try:
        cfg = PipelineConfig.model_validate(cfg_dict)
        r = run(cfg, out_dir, progress=False, config_source=config_source, raise_on_source_error=False)
        return {
            "out_dir": out_dir,
            "frames": r.frames,
            "tracks": r.tracks,
            "frames_per_s": r.frames_per_s,
            "error": r.error,
        }
    except FisheyeDesError as e:  # refused at the start (0 frames) or stopped mid-way (the frames kept)
        return {"out_dir": out_dir, "frames": getattr(e, "frames", 0), "error": str(e)}


def _pool_result(f: Any, out_dir: str) -> dict:
    """The result of the batch worker future ``f`` for the recording written to ``out_dir``. A worker
    process that died (the system killed it, e.g. out of memory) breaks the pool: every recording not
    finished then gets an error (its folder, if it started, keeps what it wrote) and the batch exits 2.
    A bug in a recording is raised on with the recording named."""
    from concurrent.futures.process import BrokenProcessPool

    try:
        return f.result()
    except BrokenProcessPool:
        if Path(out_dir).is_dir():
            why = ("its worker process died, or was stopped when another did (killed by the system: out of "
                   "memory?); what it wrote is in its folder")
        else:
            why = "not run: a worker process of the batch died (killed by the system: out of memory?)"
        return {"out_dir": out_dir, "frames": 0, "error": why}
    except Exception as e:
        e.add_note(f"(in the batch's recording {out_dir})")
        raise


def _stopped_result(f: Any, out_dir: str) -> dict:
    """The result of the batch worker future ``f`` (done or cancelled) once the batch was stopped: not
    run when cancelled, else as :func:`_pool_result` gives it (a worker that died: an error line), a bug
    as an error line (the stop is what the batch reports)."""
    if f.cancelled():
        return {"out_dir": out_dir, "frames": 0, "not_run": True}
    try:
        return _pool_result(f, out_dir)
    except Exception as e:
        return {"out_dir": out_dir, "frames": 0, "error": f"{type(e).__name__}: {e}"}


def run_batch(
    cfg: PipelineConfig,
    items: list[Path],
    out_root: Path,
    workers: int | None = None,
    camera_names: list[str] | None = None,
    config_source: str | Path | None = None,
    on_done: Callable[[dict], None] | None = None,
) -> list[dict]:
    """Run several recordings in parallel worker processes, one result folder each.

    Args:
        items: video files (one mono run each) and folders; a folder holding ``<cam>.<ext>`` videos for
            every camera name is one recording (its ``camchain.yaml`` / ``trajectory.tum`` are used when the
            config has none), otherwise each video file directly inside it is one mono run.
        out_root: results go to ``out_root/<video or folder stem>/``.
        workers: process count, at least 1 (default: CPU count, at most the number of runs).
        camera_names: rig camera names used to recognise recording folders (default ``["cam0"]``, or
            ``["cam0", "cam1"]`` for a two-camera calibration).

    Returns one dict per run (out_dir, frames, tracks, frames_per_s, error), in input order; a
    recording a signal stopped has ``interrupted`` true, one never started ``not_run`` true, and
    either may give ``why`` (a signal to its worker process alone, not the batch's stop).

    Raises:
        KeyboardInterrupt: on a Ctrl-C or SIGTERM (the recordings under way stop with their outputs
            written, ``on_done`` gets them with ``interrupted``, and those not started with ``not_run``;
            in this process, ``workers`` 1, as in worker processes).
    """
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ConfigError(
            f"--jobs {workers!r} (run_batch workers): expected an integer of at least 1 worker process "
            "(or none: one per CPU, at most one per run)"
        )
    names = camera_names or ["cam0"]
    jobs: list[tuple[dict, str, str | None]] = []
    used: set[str] = set()

    def add(videos: list[Path], stem: str, folder: Path | None) -> None:
        d = cfg.model_dump(mode="python")
        d["inputs"]["videos"] = [str(v) for v in videos]
        d["inputs"]["images"] = []
        if folder is not None:
            if (
                d["rig"]["calibration"] is None
                and not d["rig"]["cameras"]
                and (folder / "camchain.yaml").is_file()
            ):
                d["rig"]["calibration"] = folder / "camchain.yaml"
            em = d["ego_motion"]
            if em["trajectory"] is None and em["speed_mps"] is None and (folder / "trajectory.tum").is_file():
                if em["t0_s"]:  # as load_config refuses it beside a trajectory
                    raise t0_beside_trajectory(f"{folder / 'trajectory.tum'} (the recording's trajectory)",
                                               em["t0_s"])
                em["trajectory"] = folder / "trajectory.tum"
        name = stem
        k = 1
        while name in used:
            k += 1
            name = f"{stem}_{k}"
        used.add(name)
        jobs.append((d, str(out_root / name), str(config_source) if config_source else None))

    def names_for(folder: Path) -> list[str]:
        calib = folder / "camchain.yaml"
        if camera_names is None and cfg.rig.calibration is None and not cfg.rig.cameras and calib.is_file():
            from estimators.calibration import load_rig

            return list(load_rig(calib).names)  # the recording's own rig
        return names

    for item in items:
        item = Path(item)
        if item.is_dir():
            rec = find_recording(item, names_for(item))
            if rec is not None:
                add(rec, item.name, item)
                continue
            vids = sorted(p for p in item.iterdir() if p.suffix.lower() in VIDEO_SUFFIXES)
            if not vids:
                raise SourceError(f"{item}: no videos ({', '.join(VIDEO_SUFFIXES)}) in the folder")
            for v in vids:
                add([v], v.stem, None)
        elif item.is_file():
            add([item], item.stem, item.parent if len(names) == 1 else None)
        else:
            raise SourceError(f"{item}: not found")
    make_output_dir(out_root)
    n = workers or min(len(jobs), os.cpu_count() or 1)
    results: list[dict] = []
    if n <= 1 or len(jobs) == 1:
        for k, j in enumerate(jobs):
            try:
                r = _batch_worker(j)
            except KeyboardInterrupt:  # as with worker processes: the recording's line, and the rest's
                if on_done:
                    on_done({"out_dir": j[1], "interrupted": True})
                    for rest in jobs[k + 1:]:
                        on_done({"out_dir": rest[1], "frames": 0, "not_run": True})
                raise
            results.append(r)
            if on_done:
                on_done(r)
        return results
    ctx = get_context("spawn")
    stop = ctx.Event()
    with ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=_batch_worker_init,
                             initargs=(stop,)) as ex:
        futures = [ex.submit(_batch_pool_job, j) for j in jobs]
        try:
            for f, j in zip(futures, jobs, strict=True):
                r = _pool_result(f, j[1])
                results.append(r)
                if on_done:
                    on_done(r)
        except KeyboardInterrupt:  # stop the recordings under way (their outputs kept), start no other
            import signal

            stop.set()
            # the pool's own processes (a caller's other children are not the batch's to stop); a Ctrl-C
            # reached them already, a SIGTERM this process alone
            for pid in list(getattr(ex, "_processes", None) or {}):
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGTERM)
            ex.shutdown(wait=True, cancel_futures=True)
            if on_done:
                for f, j in zip(futures[len(results):], jobs[len(results):], strict=True):
                    on_done(_stopped_result(f, j[1]))
            raise
    return results
