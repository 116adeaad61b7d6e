"""Run a scenario: render every camera, write videos, timestamps, calibration, trajectory, truth.

Output folder (docs/ARCHITECTURE.md "Simulator output"):
``<cam>.mkv`` (FFV1, lossless, BGR), ``<cam>.timestamps.txt`` (``frame t_s`` per written frame),
``camchain.yaml`` (Kalibr), ``trajectory.tum`` (T_W_B), ``scene.yaml`` (the resolved scenario) and
``gt.jsonl`` (one flushed line per written frame).

Frame numbering: frame ``k`` of the scenario is at ``t_s = k / fps``. Dropped frames (realism
``frame_drop_prob``) are dropped for the whole rig: not rendered, not written, and skipped in the
timestamps and gt.jsonl, like a camera whose frame counter jumps. ``frame`` in the sidecar and
gt.jsonl is k (with gaps where frames were dropped); the n-th line of the sidecar belongs to the
n-th frame of the video, and gt.jsonl also carries that ``video_frame`` index n.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from estimators.egomotion import TumTrajectory
from estimators.errors import ConfigError, SourceError
from estimators.rig import Rig
from estimators.se3 import Pose
from pipeline.sim.groundtruth import body_velocity_W, obstacle_truth, pose_record
from pipeline.sim.render import Renderer, lens_mask, to_uint8
from pipeline.sim.rigs import build_rig
from pipeline.sim.scene import ExposureSpec, Scenario, dump_scenario
from pipeline.sim.trajectory import observer_trajectory
from pipeline.sim.world import World

VIDEO_FOURCC = "FFV1"
VIDEO_EXT = ".mkv"


def exposure_gain(spec: ExposureSpec, t_s: float) -> float:
    """Gain at ``t_s``: base * (1 + amplitude sin(2 pi t / period)) * factor of the last step passed."""
    g = spec.base_gain * (1.0 + spec.amplitude * np.sin(2.0 * np.pi * t_s / spec.period_s))
    passed = [factor for ts, factor in sorted(spec.steps) if t_s >= ts]
    if passed:
        g *= passed[-1]
    return float(g)


@dataclass
class Simulation:
    """A scenario made ready to render: world, rig, observer trajectory, renderer.

    Args:
        scn: the scenario.
        resolution: (W, H) overriding the scenario's (the lens is scaled to it).
        n_frames: frames to cover (default: the scenario's duration x fps).
    """

    scn: Scenario
    resolution: tuple[int, int] | None = None
    n_frames: int | None = None
    world: World = field(init=False)
    rig: Rig = field(init=False)
    traj: TumTrajectory = field(init=False)
    renderer: Renderer = field(init=False)

    def __post_init__(self) -> None:
        if self.n_frames is None:
            self.n_frames = self.scn.n_frames
        if self.n_frames < 1:
            raise ConfigError(f"scenario {self.scn.name!r}: expected at least 1 frame, got {self.n_frames}")
        self.world = World(self.scn)
        self.rig = build_rig(self.scn.rig, self.resolution)
        half_exp = 0.5 * self.scn.realism.motion_blur.exposure_s
        t_end = (self.n_frames - 1) / self.scn.fps + half_exp
        t_end = max(t_end, 1.0 / self.scn.fps)
        self.traj = observer_trajectory(self.scn.observer, t_end, t_start_s=-half_exp)
        self.renderer = Renderer(self.world, self.rig, self.scn.realism.supersample)
        self._masks = {c.name: lens_mask(self.renderer, c.name) for c in self.rig}

    def frame_time(self, k: int) -> float:
        return k / self.scn.fps

    def render(self, cam: str, t_s: float, rng: np.random.Generator | None = None) -> np.ndarray:
        """The frame of camera ``cam`` at ``t_s`` as uint8 BGR (H, W, 3), with motion blur,
        exposure gain and pixel noise of the scenario's realism settings."""
        r = self.scn.realism
        mb = r.motion_blur
        if mb.subframes > 1 and mb.exposure_s > 0:
            ts = t_s + mb.exposure_s * (np.arange(mb.subframes) / (mb.subframes - 1) - 0.5)
        else:
            ts = [t_s]
        acc = None
        for t in ts:
            img = self.renderer.render_float(cam, self.traj.pose_at(float(t)), float(t))
            acc = img if acc is None else acc + img
        acc /= np.float32(len(ts))
        return to_uint8(acc, exposure_gain(r.exposure, t_s), r.noise_sigma, rng, self._masks[cam])

    def render_clean(self, cam: str, t_s: float) -> np.ndarray:
        """uint8 BGR without blur, gain or noise."""
        return to_uint8(self.renderer.render_float(cam, self.traj.pose_at(t_s), t_s))

    def truth(self, t_s: float) -> tuple[Pose, list[dict]]:
        T_W_B = self.traj.pose_at(t_s)
        return T_W_B, obstacle_truth(self.world, self.rig, T_W_B, body_velocity_W(self.traj, t_s), t_s)


@dataclass
class SimulateResult:
    out_dir: Path
    frames_written: int
    frames_dropped: int
    cameras: tuple[str, ...]
    resolution: tuple[int, int]
    render_s_per_frame: float  # mean wall time per rig frame (all cameras, blur included)
    render_cpu_s_per_frame: float = 0.0  # the same in CPU time of this process (robust to a busy machine)


def simulate(scn: Scenario, out_dir: str | Path, frames: int | None = None, seconds: float | None = None,
             resolution: tuple[int, int] | None = None, progress: bool = False,
             grey: bool = False) -> SimulateResult:
    """Render ``scn`` into ``out_dir`` (created). ``frames`` or ``seconds`` shorten/lengthen the run;
    ``resolution`` (W, H) renders at another size with the same lens scaled; ``grey`` writes
    single-channel videos (``cv2.cvtColor`` BGR2GRAY of the colour frames; OpenCV reads them back
    as three equal channels)."""
    if frames is not None and seconds is not None:
        raise ConfigError("simulate: give frames or seconds, not both")
    n = frames if frames is not None else (int(np.floor(seconds * scn.fps + 1e-9)) if seconds else None)
    if n is not None and n < 1:
        raise ConfigError(f"simulate: expected at least 1 frame, got {n}")
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ConfigError(f"{out}: cannot create the output folder ({e.strerror}); expected a "
                          "writable folder path") from None
    sim = Simulation(scn, resolution, n)
    n = sim.n_frames
    # resolved scenario, with the run's actual span and resolution
    res = (sim.rig[0].model.width, sim.rig[0].model.height)
    resolved = scn.model_copy(update={
        "duration_s": n / scn.fps,
        "rig": scn.rig.model_copy(update={"resolution": res}),
    })
    dump_scenario(resolved, out / "scene.yaml")
    sim.traj.save(out / "trajectory.tum")
    from estimators.calibration import save_kalibr

    save_kalibr(sim.rig, out / "camchain.yaml")

    import cv2

    writers, stamps = {}, {}
    for cam in sim.rig:
        path = out / f"{cam.name}{VIDEO_EXT}"
        w = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*VIDEO_FOURCC), float(scn.fps),
                            (cam.model.width, cam.model.height), not grey)
        if not w.isOpened():
            raise SourceError(f"{path}: OpenCV cannot open an {VIDEO_FOURCC} writer (FFmpeg backend needed)")
        writers[cam.name] = w
        stamps[cam.name] = (out / f"{cam.name}.timestamps.txt").open("w")
    rng_noise = np.random.default_rng([scn.seed, 1])
    rng_drop = np.random.default_rng([scn.seed, 2])
    written = dropped = 0
    t_render = c_render = 0.0
    it = range(n)
    if progress:
        from tqdm import tqdm

        it = tqdm(it, desc=f"simulate {scn.name}", unit="frame")
    try:
        with (out / "gt.jsonl").open("w") as gt:
            for k in it:
                t = sim.frame_time(k)
                if scn.realism.frame_drop_prob > 0 and rng_drop.random() < scn.realism.frame_drop_prob:
                    dropped += 1
                    continue
                a, ac = time.perf_counter(), time.process_time()
                imgs = {c.name: sim.render(c.name, t, rng_noise) for c in sim.rig}
                t_render += time.perf_counter() - a
                c_render += time.process_time() - ac
                for name, img in imgs.items():
                    writers[name].write(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if grey else img)
                    stamps[name].write(f"{k} {t:.9f}\n")
                    stamps[name].flush()
                T_W_B, obs = sim.truth(t)
                rec = {"frame": k, "video_frame": written, "t_s": round(t, 9), "T_W_B": pose_record(T_W_B),
                       "obstacles": obs}
                gt.write(json.dumps(rec) + "\n")
                gt.flush()
                written += 1
    finally:
        for w in writers.values():
            w.release()
        for f in stamps.values():
            f.close()
    for cam in sim.rig:  # OpenCV only warns when it skips a frame: check the container's count
        path = out / f"{cam.name}{VIDEO_EXT}"
        cap = cv2.VideoCapture(str(path))
        n_file = int(round(cap.get(cv2.CAP_PROP_FRAME_COUNT))) if cap.isOpened() else -1
        cap.release()
        if written and n_file != written:
            raise SourceError(f"{path}: holds {n_file} frames; {written} were written (the writer failed)")
    return SimulateResult(out, written, dropped, sim.rig.names, res, t_render / max(written, 1),
                          c_render / max(written, 1))
