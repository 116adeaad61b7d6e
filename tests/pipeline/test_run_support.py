"""Shared helpers of the pipeline run/live/demo tests: tiny videos and stub front end / fusion.

The stubs stand in for ``trackers.frontend.FrontEnd`` and ``estimators.fusion.ObstacleFusion`` with the
interfaces of docs/ARCHITECTURE.md "Stage interfaces" (no tests in this module).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from estimators.cameras import make_camera_model
from estimators.records import CameraView, ObstacleObservation, TrackReport
from estimators.rig import mono_forward_rig, stereo_forward_rig

W, H = 64, 48


def small_model(width: int = W, height: int = H):
    """An equidistant fisheye, 100 deg half-angle over the half-width."""
    f = (width / 2) / np.radians(100.0)
    return make_camera_model(
        "equidistant", fx=f, fy=f, cx=(width - 1) / 2, cy=(height - 1) / 2, width=width, height=height
    )


def mono_rig():
    return mono_forward_rig(small_model())


def stereo_rig():
    return stereo_forward_rig(small_model(), 0.30)


def write_video(
    path: Path,
    n: int,
    size: tuple[int, int] = (W, H),
    fps: float = 30.0,
    times: list[float] | None = None,
    frames: list[int] | None = None,
) -> Path:
    """An FFV1 .mkv whose frame k is uniformly grey level 4*k (lossless), with an optional sidecar."""
    path.parent.mkdir(parents=True, exist_ok=True)
    w = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*"FFV1"), fps, size)
    assert w.isOpened()
    for k in range(n):
        w.write(np.full((size[1], size[0], 3), (4 * k) % 256, np.uint8))
    w.release()
    if times is not None:
        idx = frames if frames is not None else list(range(len(times)))
        path.with_name(path.stem + ".timestamps.txt").write_text(
            "".join(f"{i} {t:.6f}\n" for i, t in zip(idx, times, strict=True))
        )
    return path


class FakeFrontEnd:
    """One obstacle straight ahead of cam0 in every frame; records what it was given."""

    def __init__(self, rig, fail_at: int | None = None, interrupt_at: int | None = None):
        self.rig = rig
        self.calls: list[tuple[int, float, dict]] = []
        self.timings = {"detect": 1e-4, "track": 2e-4, "group": 1e-5, "associate": 1e-5}
        self.interrupt_at = interrupt_at

    def process(self, images, frame, t_s, T_W_B=None):
        if self.interrupt_at is not None and len(self.calls) == self.interrupt_at:
            raise KeyboardInterrupt
        self.calls.append((frame, t_s, {k: int(v.reshape(-1)[0]) for k, v in images.items()}))
        view = CameraView(
            camera=self.rig.names[0],
            b_C=np.array([0.0, 0.0, 1.0]),
            uv=np.array([W / 2, H / 2]),
            sigma_rad=0.01,
        )
        return [ObstacleObservation(track_id=1, frame=frame, t_s=t_s, status="confirmed", views=(view,))]


class FakeFusion:
    """Range 20 - 5 t_s straight ahead, and a second, unobservable track with a NaN that must become null."""

    def __init__(self):
        self.timings = {"estimate": 1e-4, "fuse": 1e-4}

    def step(self, observations, frame, t_s):
        out = []
        for o in observations:
            r = 20.0 - 5.0 * t_s
            out.append(
                TrackReport(
                    id=o.track_id,
                    status=o.status,
                    camera=o.cameras[0],
                    bearing_body=np.array([1.0, 0.0, 0.0]),
                    range_m=r,
                    range_sigma_m=0.5,
                    range_min_m=r - 1,
                    range_max_m=r + 1,
                    position_body_m=np.array([r, 0, 0]),
                    velocity_world_mps=np.array([0.0, 1.0, 0.0]),
                    speed_mps=1.0,
                    source="mono",
                )
            )
        out.append(
            TrackReport(
                id=2,
                status="tentative",
                camera="cam0",
                bearing_body=np.array([0.0, 1.0, 0.0]),
                range_m=float("nan"),
                unobservable_reason="no parallax yet",
            )
        )
        return out
