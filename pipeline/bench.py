"""Benchmark harness of ``fisheye-des bench``: throughput, per-stage time, latency, memory, scaling.

Every measurement runs in a fresh subprocess (``python -m pipeline.bench``, a JSON task on stdin,
a JSON result on stdout) so that thread pinning really holds: the parent sets ``OMP_NUM_THREADS``,
``MKL_NUM_THREADS``, ``OPENBLAS_NUM_THREADS``, ... in the child's environment *before* any native
library is loaded, and the child then calls ``os.sched_setaffinity`` (one CPU), ``cv2.setNumThreads``
and ``torch.set_num_threads`` and reports what it got (``pinning`` in every result).

Nothing here fails on wall-clock time: targets are printed beside the measurement as met / missed.

Units: seconds and bytes in the JSON; frames/s, milliseconds and MiB only in the printed table.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from estimators.errors import ConfigError, InputError, SourceError

SCHEMA = "fisheye-des-bench/1"

#: Camera frame rate at each resolution (the thesis's camera, Table 4.1), frames per second.
CAMERA_RATE_HZ: dict[tuple[int, int], float] = {(1920, 1080): 30.0, (1280, 720): 60.0, (640, 480): 100.0}

#: Stage names in the order of the pipeline (per frame, seconds).
STAGES: tuple[str, ...] = ("decode", "detect", "track", "group", "associate", "estimate", "fuse", "write")

#: Environment variables that fix the thread pools of OpenMP, MKL, OpenBLAS, numexpr, Accelerate.
THREAD_ENV_VARS: tuple[str, ...] = (
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
)


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/fisheye-des/bench`` (``~/.cache/fisheye-des/bench``)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "fisheye-des" / "bench"


# ------------------------------------------------------------------------------------- statistics
def percentile(samples: Sequence[float], q: float) -> float:
    """The ``q``-th percentile (0..100) of ``samples`` by linear interpolation between order statistics.

    With sorted values ``x_0 <= ... <= x_{n-1}`` the rank is ``r = q/100 * (n - 1)`` and the result is
    ``x_floor(r) + (r - floor(r)) * (x_ceil(r) - x_floor(r))`` (numpy's default "linear" method).
    Raises InputError on an empty sequence or ``q`` outside [0, 100].
    """
    if not 0.0 <= q <= 100.0:
        raise InputError(f"percentile: q must lie in [0, 100], got {q}")
    x = np.sort(np.asarray(samples, dtype=float).reshape(-1))
    if x.size == 0:
        raise InputError("percentile: expected at least one sample, got none")
    r = q / 100.0 * (x.size - 1)
    lo = int(math.floor(r))
    hi = min(lo + 1, x.size - 1)
    return float(x[lo] + (r - lo) * (x[hi] - x[lo]))


@dataclass(frozen=True)
class Stats:
    """Summary of per-frame durations (seconds): count, median, 99th percentile, mean, max, total."""

    n: int
    median_s: float
    p99_s: float
    mean_s: float
    max_s: float
    total_s: float

    @classmethod
    def from_samples(cls, samples: Sequence[float]) -> Stats:
        """Summarise ``samples`` (seconds, any order). Raises InputError when it is empty."""
        x = np.asarray(samples, dtype=float).reshape(-1)
        if x.size == 0:
            raise InputError("Stats.from_samples: expected at least one sample, got none")
        return cls(
            n=int(x.size),
            median_s=percentile(x, 50.0),
            p99_s=percentile(x, 99.0),
            mean_s=float(x.mean()),
            max_s=float(x.max()),
            total_s=float(x.sum()),
        )

    def to_json(self) -> dict[str, float | int]:
        return asdict(self)


class StageClock:
    """Per-frame durations of named stages, collected frame by frame.

    ``add(stage, seconds)`` accumulates into the current frame (a stage may be entered several
    times per frame, e.g. once per camera); ``end_frame()`` closes it. Stages never entered in a
    frame count as 0 for that frame once the stage has been seen at all.
    """

    def __init__(self) -> None:
        self._frames: list[dict[str, float]] = []
        self._current: dict[str, float] = {}

    def add(self, stage: str, seconds: float) -> None:
        self._current[stage] = self._current.get(stage, 0.0) + float(seconds)

    def add_all(self, timings: Mapping[str, float] | None) -> None:
        for k, v in (timings or {}).items():
            self.add(k, v)

    def end_frame(self) -> None:
        self._frames.append(self._current)
        self._current = {}

    @property
    def n_frames(self) -> int:
        return len(self._frames)

    def stages(self) -> list[str]:
        seen = {k for f in self._frames for k in f}
        return [s for s in STAGES if s in seen] + sorted(seen - set(STAGES))

    def samples(self, stage: str) -> np.ndarray:
        """(n_frames,) seconds spent in ``stage`` per frame."""
        return np.array([f.get(stage, 0.0) for f in self._frames], dtype=float)

    def per_frame_total(self) -> np.ndarray:
        """(n_frames,) seconds spent in all stages per frame."""
        return np.array([sum(f.values()) for f in self._frames], dtype=float)

    def summary(self) -> dict[str, dict[str, float | int]]:
        if not self._frames:
            return {}
        return {s: Stats.from_samples(self.samples(s)).to_json() for s in self.stages()}


# ------------------------------------------------------------------------------------------ memory
def _proc_status_kib(key: str) -> int | None:
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def rss_bytes() -> int:
    """Current resident set size of this process in bytes (``VmRSS`` of /proc/self/status).

    Falls back to the peak (``resource.getrusage``) where /proc is absent."""
    kib = _proc_status_kib("VmRSS")
    return kib * 1024 if kib is not None else peak_rss_bytes()


def peak_rss_bytes() -> int:
    """Peak resident set size of this process in bytes (``VmHWM``, else ``ru_maxrss``)."""
    kib = _proc_status_kib("VmHWM")
    if kib is not None:
        return kib * 1024
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(r if sys.platform == "darwin" else r * 1024)


class MemorySampler:
    """RSS at chosen frame counts of a long run, and whether it grew.

    Args:
        checkpoints: frame counts (1-based: "after this many frames") at which to record RSS.
    """

    def __init__(self, checkpoints: Sequence[int]) -> None:
        self.checkpoints = sorted({int(c) for c in checkpoints})
        self.samples: dict[int, int] = {}
        self._rss_fn: Callable[[], int] = rss_bytes

    def after_frame(self, n_done: int) -> None:
        """Call once per frame with the number of frames processed so far."""
        if n_done in self.checkpoints:
            self.samples[n_done] = self._rss_fn()

    def growth(self, a: int, b: int) -> dict[str, float | int] | None:
        """RSS difference (bytes) and ratio between checkpoints ``a`` and ``b`` (None if either missing)."""
        if a not in self.samples or b not in self.samples:
            return None
        ra, rb = self.samples[a], self.samples[b]
        return {"from_frames": a, "to_frames": b, "rss_from_bytes": ra, "rss_to_bytes": rb,
                "growth_bytes": rb - ra, "ratio": rb / ra if ra else float("nan")}

    def to_json(self) -> dict[str, Any]:
        return {"rss_bytes_at_frames": {str(k): v for k, v in sorted(self.samples.items())},
                "peak_rss_bytes": peak_rss_bytes()}


def memory_grew(growth: Mapping[str, float | int] | None, tolerance_bytes: int = 16 * 2**20,
                tolerance_ratio: float = 0.05) -> bool | None:
    """Whether RSS grew between two checkpoints by more than both tolerances (None: not measured).

    Allocator noise and lazily mapped pages make a few MiB of drift normal; a leak of even 1 KiB
    per frame over 9,000 frames shows as ~9 MiB, a leak per frame of an image far more."""
    if growth is None:
        return None
    g = float(growth["growth_bytes"])
    return g > tolerance_bytes and g > tolerance_ratio * float(growth["rss_from_bytes"])


# ----------------------------------------------------------------------------------------- threads
def thread_env(n_threads: int | None) -> dict[str, str]:
    """Environment for a child process: every thread-pool variable set to ``n_threads``.

    ``None`` (all cores) removes them so that each library picks its own default."""
    env = dict(os.environ)
    for k in THREAD_ENV_VARS:
        if n_threads is None:
            env.pop(k, None)
        else:
            env[k] = str(int(n_threads))
    env["PYTHONUNBUFFERED"] = "1"
    return env


def pin_threads(n_threads: int | None) -> dict[str, Any]:
    """Restrict this process to ``n_threads`` CPUs and thread pools (None: leave all cores).

    Sets the CPU affinity to the first ``n_threads`` allowed CPUs (Linux), ``cv2.setNumThreads``,
    and ``torch.set_num_threads`` when torch is already imported (never imports torch). Returns what
    holds afterwards: ``{"requested", "affinity", "cv2_threads", "env", "torch_threads"}``.
    """
    import cv2

    info: dict[str, Any] = {"requested": n_threads}
    if n_threads is not None:
        if n_threads < 1:
            raise ConfigError(f"pin_threads: n_threads must be >= 1 or None, got {n_threads}")
        if hasattr(os, "sched_setaffinity"):
            allowed = sorted(os.sched_getaffinity(0))
            os.sched_setaffinity(0, set(allowed[:n_threads]))
        cv2.setNumThreads(int(n_threads))
        if "torch" in sys.modules:
            sys.modules["torch"].set_num_threads(int(n_threads))
    info["affinity"] = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
    info["cv2_threads"] = int(cv2.getNumThreads())
    info["env"] = {k: os.environ.get(k) for k in THREAD_ENV_VARS}
    info["torch_threads"] = (
        int(sys.modules["torch"].get_num_threads()) if "torch" in sys.modules else None
    )
    return info


# ------------------------------------------------------------------------------------------- video
def read_timestamps(path: str | Path) -> np.ndarray | None:
    """Frame times (seconds) of a ``<cam>.timestamps.txt`` (lines ``frame t_s``), or None if absent."""
    p = Path(path)
    if not p.is_file():
        return None
    rows = [ln.split() for ln in p.read_text().splitlines() if ln.strip() and not ln.startswith("#")]
    try:
        return np.array([float(r[1]) for r in rows], dtype=float)
    except (IndexError, ValueError):
        raise InputError(f"{p}: expected lines 'frame t_s', got e.g. {rows[:1]}") from None


def _open(path: str | Path):
    import cv2

    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise SourceError(f"{path}: cannot open the video (expected a file OpenCV's FFmpeg backend reads)")
    return cap


def video_info(path: str | Path) -> dict[str, Any]:
    """Width, height, frame count and nominal fps of a video file (from its container)."""
    import cv2

    cap = _open(path)
    try:
        return {
            "width": int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)),
            "height": int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)),
            "frames": int(cap.get(cv2.CAP_PROP_FRAME_COUNT)),
            "fps": float(cap.get(cv2.CAP_PROP_FPS)),
        }
    finally:
        cap.release()


@dataclass
class DecodedFrame:
    """One step of a multi-camera video: ``images`` maps camera name -> (H, W) uint8 grey."""

    frame: int
    t_s: float
    images: dict[str, np.ndarray]
    decode_s: float


def looped_frames(videos: Mapping[str, str | Path], n_frames: int, fps: float | None = None,
                  grey: bool = True) -> Iterator[DecodedFrame]:
    """Decode ``n_frames`` steps of every camera's video, in step, re-opening the files at their end.

    Looping lets a short rendered clip stand in for a long flight (memory over 10,000 frames).
    ``t_s`` keeps increasing across loops: ``frame / fps`` (``fps`` from the first video when None).
    ``decode_s`` is the wall time of reading (and converting to grey) all cameras' images.
    Raises SourceError when a video cannot be opened or yields no frame at all.
    """
    import cv2

    names = list(videos)
    if not names:
        raise InputError("looped_frames: expected at least one video, got none")
    caps = {n: _open(videos[n]) for n in names}
    if fps is None:
        fps = float(caps[names[0]].get(cv2.CAP_PROP_FPS)) or 30.0
    try:
        for i in range(int(n_frames)):
            t0 = time.perf_counter()
            images: dict[str, np.ndarray] = {}
            for n in names:
                ok, img = caps[n].read()
                if not ok:
                    caps[n].release()
                    caps[n] = _open(videos[n])
                    ok, img = caps[n].read()
                    if not ok:
                        raise SourceError(f"{videos[n]}: the video yields no frame")
                if grey and img.ndim == 3:
                    img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
                images[n] = img
            dt = time.perf_counter() - t0
            yield DecodedFrame(frame=i, t_s=i / fps, images=images, decode_s=dt)
    finally:
        for c in caps.values():
            c.release()


def decode_only(videos: Mapping[str, str | Path], n_frames: int) -> dict[str, Any]:
    """Read and convert to grey ``n_frames`` steps of all cameras, nothing else: the decoder floor.

    Returns ``{"frames", "wall_s", "fps", "per_frame": Stats json}``; ``fps`` counts multi-camera
    steps per second (a stereo step decodes two images)."""
    clock: list[float] = []
    t0 = time.perf_counter()
    for f in looped_frames(videos, n_frames):
        clock.append(f.decode_s)
    wall = time.perf_counter() - t0
    return {"frames": len(clock), "wall_s": wall, "fps": len(clock) / wall if wall > 0 else None,
            "per_frame": Stats.from_samples(clock).to_json()}


# ------------------------------------------------------------------------------------ render cache
def cache_key(spec: Mapping[str, Any]) -> str:
    """Stable short hash of a JSON-serialisable render spec (scenario + resolution + frames)."""
    blob = json.dumps(spec, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def cached_render(scenario: Mapping[str, Any], cache_dir: str | Path, *, resolution: tuple[int, int],
                  frames: int, render: Callable[[Path, Path], None] | None = None) -> Path:
    """Directory of a simulator render of ``scenario`` at ``resolution`` with ``frames`` frames.

    Renders once into ``cache_dir/<name>-<WxH>-<frames>f-<hash>/`` and reuses it afterwards (a
    ``.complete`` marker is written last, so a killed render is redone). ``render(scenario_yaml,
    out_dir)`` defaults to ``fisheye-des simulate SCENARIO --out DIR --resolution WxH --frames N``
    in a subprocess.
    """
    import yaml

    spec = {"scenario": scenario, "resolution": list(resolution), "frames": int(frames)}
    name = str(scenario.get("name", "scenario"))
    d = Path(cache_dir) / f"{name}-{resolution[0]}x{resolution[1]}-{frames}f-{cache_key(spec)}"
    if (d / ".complete").is_file():
        return d
    d.mkdir(parents=True, exist_ok=True)
    scn_path = d / "scenario.yaml"
    scn_path.write_text(yaml.safe_dump(dict(scenario), sort_keys=False))
    if render is None:
        def render(scn: Path, out: Path) -> None:
            cmd = [sys.executable, "-m", "pipeline.cli", "simulate", str(scn), "--out", str(out),
                   "--resolution", f"{resolution[0]}x{resolution[1]}", "--frames", str(int(frames))]
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0:
                raise SourceError(f"simulate failed for {scn} (exit {r.returncode}): "
                                  f"{(r.stderr or r.stdout).strip()[-800:]}")
    render(scn_path, d)
    (d / ".complete").write_text(time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))
    return d


def render_videos(render_dir: str | Path) -> dict[str, Path]:
    """Camera name -> video path of a render directory (``<cam>.mkv``, sorted by name)."""
    vids = {p.stem: p for p in sorted(Path(render_dir).glob("*.mkv"))}
    if not vids:
        raise SourceError(f"{render_dir}: no <cam>.mkv video found (expected simulator output)")
    return vids


# -------------------------------------------------------------------------------------- subprocess
def run_task(task: Mapping[str, Any], n_threads: int | None, timeout_s: float = 3600.0) -> dict[str, Any]:
    """Run one measurement ``task`` in a fresh ``python -m pipeline.bench`` with ``n_threads`` pinned.

    The task is a JSON mapping with ``kind`` (see ``TASKS``); the child answers one JSON object on
    its last stdout line. A failing child gives ``{"error": message}`` rather than raising, so one
    broken measurement does not lose the others.
    """
    payload = dict(task, threads=n_threads)
    try:
        r = subprocess.run([sys.executable, "-m", "pipeline.bench"], input=json.dumps(payload),
                           capture_output=True, text=True, env=thread_env(n_threads), timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout_s:.0f} s"}
    lines = [ln for ln in r.stdout.splitlines() if ln.strip()]
    if r.returncode != 0 or not lines:
        tail = (r.stderr or r.stdout).strip().splitlines()[-6:]
        return {"error": f"worker exit {r.returncode}: " + " | ".join(tail)}
    try:
        return json.loads(lines[-1])
    except json.JSONDecodeError:
        return {"error": f"worker printed no JSON: {lines[-1][:200]}"}


def _task_decode(task: Mapping[str, Any]) -> dict[str, Any]:
    return decode_only(task["videos"], int(task["frames"]))


def _task_memory_probe(task: Mapping[str, Any]) -> dict[str, Any]:
    """Decode-only long loop with RSS checkpoints (the harness's own baseline for memory)."""
    sampler = MemorySampler(task.get("checkpoints", [1000, int(task["frames"])]))
    n = 0
    for _ in looped_frames(task["videos"], int(task["frames"])):
        n += 1
        sampler.after_frame(n)
    return sampler.to_json()


#: Worker task kinds -> function(task) -> JSON result. The pipeline tasks are registered below.
TASKS: dict[str, Callable[[Mapping[str, Any]], dict[str, Any]]] = {
    "decode": _task_decode,
    "memory_probe": _task_memory_probe,
}


def worker_main(stdin: str) -> dict[str, Any]:
    """Body of the child process: pin threads, run the task, return its result with the pinning."""
    task = json.loads(stdin)
    pinning = pin_threads(task.get("threads"))
    kind = task.get("kind")
    if kind not in TASKS:
        raise ConfigError(f"bench worker: unknown task kind {kind!r}; expected one of {sorted(TASKS)}")
    if task.get("threads") is not None and task.get("detector") == "kornia":
        import torch

        torch.set_num_threads(int(task["threads"]))
        pinning["torch_threads"] = int(torch.get_num_threads())
    t0 = time.perf_counter()
    out = TASKS[kind](task)
    out["task_wall_s"] = time.perf_counter() - t0
    out["pinning"] = pinning
    return out


# ------------------------------------------------------------------------------------------ report
@dataclass
class Row:
    """One line of the printed table, also one entry of ``bench.json``'s ``rows``.

    ``value`` is in ``unit``; ``baseline_value`` (same unit) is what the ratio compares against,
    measured in the same run; ``target`` is a human-readable goal, ``met`` True/False/None (no target
    or not measured).
    """

    section: str
    name: str
    value: float | None
    unit: str
    baseline_name: str | None = None
    baseline_value: float | None = None
    ratio: float | None = None
    target: str | None = None
    met: bool | None = None
    note: str = ""
    inverse: bool = False
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # ratio = value / baseline; with inverse (rates: frames/s) baseline / value, i.e. the ratio of
        # the times per frame, so "x2.0 time of decode-only" reads as "takes twice as long as decoding".
        if self.ratio is None and self.value and self.baseline_value:
            v, b = float(self.value), float(self.baseline_value)
            self.ratio = b / v if self.inverse else v / b


def _fmt(v: float | None, unit: str = "") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    a = abs(v)
    s = f"{v:.0f}" if a >= 1000 else f"{v:.1f}" if a >= 10 else f"{v:.2f}" if a >= 0.1 else f"{v:.3g}"
    return f"{s} {unit}".rstrip()


def format_table(rows: Sequence[Row]) -> str:
    """Plain-text table: section, measurement, value, ratio to baseline, target and met/missed."""
    head = ("measurement", "value", "vs baseline", "target", "")
    body: list[tuple[str, ...]] = []
    out: list[str] = []
    section = None
    for r in rows:
        if r.section != section:
            body.append(("## " + r.section, "", "", "", ""))
            section = r.section
        kind = "time " if r.inverse else ""
        base = "" if r.ratio is None else f"x{r.ratio:.2f} {kind}of {r.baseline_name}"
        met = "" if r.met is None else ("met" if r.met else "MISSED")
        name = r.name + (f"  ({r.note})" if r.note and r.value is None else "")
        body.append(("  " + name, _fmt(r.value, r.unit), base, r.target or "", met))
    widths = [max(len(x[i]) for x in [head, *body]) for i in range(len(head))]
    line = "  ".join(h.ljust(w) for h, w in zip(head, widths, strict=True)).rstrip()
    out.append(line)
    out.append("-" * len(line))
    for x in body:
        out.append("  ".join(c.ljust(w) for c, w in zip(x, widths, strict=True)).rstrip())
    return "\n".join(out)


def machine_info() -> dict[str, Any]:
    """What ran the benchmark: CPU model and count, memory, Python, OpenCV, numpy, torch/CUDA."""
    import cv2

    cpu = None
    try:
        for ln in Path("/proc/cpuinfo").read_text().splitlines():
            if ln.startswith("model name"):
                cpu = ln.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = None
    try:
        for ln in Path("/proc/meminfo").read_text().splitlines():
            if ln.startswith("MemTotal:"):
                mem = int(ln.split()[1]) * 1024
    except OSError:
        pass
    info: dict[str, Any] = {
        "cpu": cpu or platform.processor(),
        "cpus": os.cpu_count(),
        "cpus_allowed": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
        "mem_bytes": mem,
        "python": platform.python_version(),
        "platform": platform.platform(),
        "opencv": cv2.__version__,
        "numpy": np.__version__,
    }
    try:
        import torch

        info["torch"] = torch.__version__
        info["cuda"] = bool(torch.cuda.is_available())
    except ImportError:
        info["torch"] = None
        info["cuda"] = False
    return info


def write_report(path: str | Path, rows: Sequence[Row], sections: Mapping[str, Any],
                 meta: Mapping[str, Any]) -> dict[str, Any]:
    """Write ``bench.json``: ``{"schema", "meta", "rows": [Row...], "sections": {...raw results}}``."""
    doc = {"schema": SCHEMA, "meta": dict(meta), "rows": [asdict(r) for r in rows],
           "sections": dict(sections)}
    text = json.dumps(doc, indent=1, default=_json_default, allow_nan=False)
    Path(path).write_text(text)
    return doc


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON-serialisable: {type(o).__name__}")


def sanitize(o: Any) -> Any:
    """Replace NaN/inf floats by None, recursively (JSON has no such numbers)."""
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, dict):
        return {k: sanitize(v) for k, v in o.items()}
    if isinstance(o, list | tuple):
        return [sanitize(v) for v in o]
    return o


if __name__ == "__main__":  # the measurement child: JSON task on stdin, JSON result on stdout
    try:
        result = worker_main(sys.stdin.read())
    except Exception as e:  # reported to the parent as data, not a traceback
        import traceback

        traceback.print_exc(file=sys.stderr)
        result = {"error": f"{type(e).__name__}: {e}"}
    sys.stdout.write(json.dumps(sanitize(result), default=_json_default) + "\n")
