"""Outputs of a run: ``tracks.jsonl`` (one flushed line per frame), ``summary.json``, an annotated
video and PNG plots.

``tracks.jsonl`` lines follow CONVENTIONS.md "Outputs": ``{"frame": int, "t_s": float, "tracks":
[TrackReport.to_json(), ...]}``. JSON has no NaN: every non-finite number becomes ``null`` and the
writer refuses to emit NaN (``allow_nan=False``).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from estimators.errors import InputError

__all__ = [
    "TracksWriter",
    "read_tracks",
    "to_plain",
    "report_dicts",
    "write_json",
    "make_output_dir",
    "Annotator",
    "VideoWriter",
    "make_plots",
    "TRACKS_NAME",
    "SUMMARY_NAME",
]

TRACKS_NAME = "tracks.jsonl"
SUMMARY_NAME = "summary.json"


def to_plain(obj: Any) -> Any:
    """A JSON-ready copy: numpy scalars/arrays to Python, non-finite floats to None, Paths to str."""
    if isinstance(obj, Mapping):
        return {str(k): to_plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_plain(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, Path):
        return str(obj)
    if hasattr(obj, "to_json"):
        return to_plain(obj.to_json())
    return obj


def make_output_dir(path: str | Path) -> Path:
    """Create the output folder ``path`` (and its parents) if needed and check it can be written.

    The one check of an ``--out`` folder for ``run``, ``live``, ``evaluate`` and ``demo``.

    Raises:
        InputError: ``path`` is a file, one of its parents is a file, or it cannot be created or
            written (the reason named).
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"{path}: cannot create the output folder (it is a file); expected a folder path "
                         "that can be created and written")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        blocker = next((p for p in path.parents if p.exists()), None)
        why = (f"{blocker} is a file" if blocker is not None and not blocker.is_dir()
               else (e.strerror or str(e)).lower())
        raise InputError(f"{path}: cannot create the output folder ({why}); expected a folder path "
                         "that can be created and written") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise InputError(f"{path}: the output folder cannot be written (permission denied); expected a "
                         "writable folder")
    return path


def write_json(path: str | Path, obj: Any) -> Path:
    """Write ``obj`` as indented JSON atomically (temp file + rename), NaN-free."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(to_plain(obj), indent=2, allow_nan=False) + "\n")
    os.replace(tmp, path)
    return path


# json.dumps' own format; no check for circular references (a frame's line is plain dicts and lists
# built here, never circular; the check cost ~4 % of the encoding)
_dumps = json.JSONEncoder(allow_nan=False, separators=(", ", ": "), check_circular=False).encode


def report_dicts(tracks: Iterable[Any]) -> list[dict]:
    """The ``tracks.jsonl`` objects of one frame's reports (``TrackReport``s, or dicts taken as they are).

    ``TrackReport``s go through ``estimators.records.reports_to_json`` together, with non-finite
    numbers NOT replaced: :class:`TracksWriter` encodes with ``allow_nan=False`` and, on a non-finite
    value, falls back to ``to_json()`` (which nulls them), so the line written is always the same.
    """
    from estimators.records import TrackReport, reports_to_json

    items = list(tracks)
    fast = [k for k, t in enumerate(items) if type(t) is TrackReport]
    if len(fast) < len(items):
        items = [t.to_json() if hasattr(t, "to_json") and type(t) is not TrackReport else t for t in items]
    for k, d in zip(fast, reports_to_json([items[k] for k in fast], null_nonfinite=False), strict=True):
        items[k] = d
    return items


class TracksWriter:
    """Appends one ``{"frame", "t_s", "tracks"}`` line per frame to ``tracks.jsonl`` and flushes it.

    Args:
        path: the file (created, truncated).
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._f = self.path.open("w", encoding="utf-8")
        self.lines = 0
        self.track_ids: set[int] = set()
        self.statuses: dict[str, int] = {}  # track reports written, by status

    def write(self, frame: int, t_s: float, tracks: Iterable[Any]) -> list[dict]:
        """Write one frame's line; ``tracks`` are ``TrackReport``s or their ``to_json()`` dicts.

        One ``write`` and one ``flush`` per frame. Returns the track dicts as written (for the annotator).
        """
        tracks = list(tracks)
        items = report_dicts(tracks)
        rec = {"frame": int(frame), "t_s": to_plain(float(t_s)), "tracks": items}
        try:  # fast path: plain and finite (the encoder refuses NaN / inf and numpy scalars)
            line = _dumps(rec)
        except (TypeError, ValueError):  # a NaN or a numpy value somewhere: to_json() nulls, to_plain cleans
            items = [t.to_json() if hasattr(t, "to_json") else t for t in tracks]
            rec["tracks"] = items = [to_plain(t) for t in items]
            line = _dumps(rec)
        ids, statuses = self.track_ids, self.statuses
        for t in items:
            if isinstance(t, dict):
                i, st = t.get("id"), t.get("status")
                if i is not None:
                    ids.add(int(i))
                if st is not None:
                    statuses[st] = statuses.get(st, 0) + 1
        self._f.write(line + "\n")
        self._f.flush()
        self.lines += 1
        return items

    def close(self) -> None:
        if not self._f.closed:
            self._f.flush()
            self._f.close()

    def __enter__(self) -> TracksWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def read_tracks(path: str | Path) -> Iterator[dict]:
    """Stream the lines of a ``tracks.jsonl`` (a partial last line, from a killed run, is skipped)."""
    with Path(path).open(encoding="utf-8") as f:
        for lineno, line in enumerate(f, start=1):
            if not line.strip():
                continue
            try:
                yield json.loads(line)
            except json.JSONDecodeError:
                if not line.endswith("\n"):
                    return  # cut off mid-write
                raise InputError(f"{path}:{lineno}: not a JSON line") from None


# ------------------------------------------------------------------------------------- annotation
_STATUS_BGR = {"confirmed": (60, 220, 60), "tentative": (0, 200, 255), "lost": (140, 140, 140)}


class Annotator:
    """Draws tracks over the raw fisheye frames of a rig, cameras side by side.

    For every track: a marker at its pixel (its body position, or bearing, projected through the
    camera model), ``#id range [min, max]`` text, a velocity arrow (where the obstacle will be in
    ``arrow_s`` seconds relative to the body, projected), and each camera's lens circle.

    Args:
        rig: an ``estimators.rig.Rig`` (cameras with ``model`` and ``T_C_B``).
        egomotion: optional ``EgoMotion``; gives ``R_W_B`` to turn ``velocity_world_mps`` into the body frame.
        arrow_s: seconds of motion the velocity arrow shows.
    """

    def __init__(self, rig: Any, egomotion: Any = None, arrow_s: float = 1.0):
        self.rig = rig
        self.egomotion = egomotion
        self.arrow_s = float(arrow_s)

    @staticmethod
    def _project(cam: Any, p_C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) points or directions in C -> (N, 2) int pixels, (N,) valid (zero vectors invalid)."""
        n = np.linalg.norm(p_C, axis=1)
        ok = n > 1e-9
        safe = np.where(ok[:, None], p_C, np.array([0.0, 0.0, 1.0]))
        uv, valid = cam.model.bearing_to_pixel(safe)
        return np.rint(uv).astype(int), valid & ok

    def draw(
        self,
        images: Mapping[str, np.ndarray],
        tracks: list[dict],
        t_s: float | None = None,
        frame: int | None = None,
    ) -> np.ndarray:
        """One BGR image: every camera's frame (rig order) side by side with the tracks drawn on it.

        Args:
            images: camera name -> (H, W) grey or (H, W, 3) BGR uint8.
            tracks: ``TrackReport.to_json()`` dicts of this frame.

        Every camera's markers are projected in one batch (``bearing_to_pixel`` of all tracks' body
        positions, or bearings when unranged, in C: ``p_C = T_C_B p_B``); so are the arrow tips.
        """
        import cv2

        R_B_W = None
        if self.egomotion is not None and t_s is not None:
            try:
                R_B_W = self.egomotion.pose_at(t_s).R.T
            except Exception:  # outside a trajectory's span: no arrows
                R_B_W = None
        tiles = []
        for cam in self.rig.cameras:
            img = images.get(cam.name)
            if img is None:
                continue
            canvas = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if img.ndim == 2 else img.copy()
            scale = max(1, int(round(max(canvas.shape[:2]) / 640)))
            cx, cy, r = cam.model.image_circle()
            if np.isfinite(r) and r > 0:
                cv2.circle(
                    canvas, (int(round(cx)), int(round(cy))), int(round(r)), (255, 200, 0), scale, cv2.LINE_AA
                )
            sel = []
            for t in tracks:
                cams = t.get("camera")
                if cam.name in (cams if isinstance(cams, list) else [cams]):
                    sel.append(t)
            if sel:
                R_C_B = cam.T_C_B.R
                has_p = np.array([t.get("position_body_m") is not None for t in sel])
                p_B = np.array([t.get("position_body_m") or [0.0, 0.0, 0.0] for t in sel], dtype=float)
                b_B = np.array([t.get("bearing_body") or [1.0, 0.0, 0.0] for t in sel], dtype=float)
                # a ranged track at its position, an unranged one along its bearing (a direction)
                p_C = np.where(has_p[:, None], cam.T_C_B.apply(p_B), b_B @ R_C_B.T)
                uv, ok = self._project(cam, p_C)
                arrows = []  # (k, v_B) of confirmed, ranged tracks with a velocity
                for k, t in enumerate(sel):
                    if not ok[k]:
                        continue
                    pt = (int(uv[k, 0]), int(uv[k, 1]))
                    colour = _STATUS_BGR.get(t.get("status", ""), (255, 255, 255))
                    if t.get("status") != "confirmed":  # tentative / lost: a small dot, no text
                        cv2.circle(canvas, pt, 2 * scale, colour, -1, cv2.LINE_AA)
                        continue
                    cv2.circle(canvas, pt, 6 * scale, colour, scale, cv2.LINE_AA)
                    rng = t.get("range_m")
                    txt = f"#{t.get('id')}"
                    txt += f" {rng:.1f}m" if rng is not None else " ?m"
                    lo, hi = t.get("range_min_m"), t.get("range_max_m")
                    if hi is not None or (lo is not None and lo > 0):  # [0, inf) says nothing
                        txt += f" [{'-' if lo is None else f'{lo:.1f}'},{'-' if hi is None else f'{hi:.1f}'}]"
                    cv2.putText(
                        canvas,
                        txt,
                        (pt[0] + 8 * scale, pt[1] - 6 * scale),
                        cv2.FONT_HERSHEY_SIMPLEX,
                        0.45 * scale,
                        colour,
                        scale,
                        cv2.LINE_AA,
                    )
                    v_W = t.get("velocity_world_mps")
                    if v_W is not None and has_p[k] and R_B_W is not None:
                        arrows.append((k, R_B_W @ np.asarray(v_W, dtype=float)))
                if arrows:
                    # where the obstacle will be after dt (its own motion, in B), projected; a straight
                    # line is only faithful over a short stretch of a fisheye image: halve dt until the
                    # arrow is under a tenth of the image (at most 6 tries), all arrows in one batch
                    idx = np.array([k for k, _ in arrows])
                    v_B = np.array([v for _, v in arrows])
                    colours = [_STATUS_BGR["confirmed"]] * len(idx)
                    max_len = 0.1 * max(canvas.shape[:2])
                    dt = np.full(len(idx), self.arrow_s)
                    todo = np.ones(len(idx), dtype=bool)
                    for _ in range(6):
                        if not todo.any():
                            break
                        j = todo.nonzero()[0]
                        tip_C = cam.T_C_B.apply(p_B[idx[j]] + dt[j, None] * v_B[j])
                        uv2, ok2 = self._project(cam, tip_C)
                        length = np.hypot(uv2[:, 0] - uv[idx[j], 0], uv2[:, 1] - uv[idx[j], 1])
                        good = ok2 & (length <= max_len)
                        for jj, u2 in zip(j[good], uv2[good], strict=True):
                            k = int(idx[jj])
                            cv2.arrowedLine(
                                canvas,
                                (int(uv[k, 0]), int(uv[k, 1])),
                                (int(u2[0]), int(u2[1])),
                                colours[jj],
                                scale,
                                cv2.LINE_AA,
                                tipLength=0.25,
                            )
                        todo[j[good]] = False
                        dt[j] /= 2
            if frame is not None:
                label = f"{cam.name}  frame {frame}" + (f"  t={t_s:.2f}s" if t_s is not None else "")
                cv2.putText(
                    canvas,
                    label,
                    (8 * scale, 20 * scale),
                    cv2.FONT_HERSHEY_SIMPLEX,
                    0.5 * scale,
                    (255, 255, 255),
                    scale,
                    cv2.LINE_AA,
                )
            tiles.append(canvas)
        if not tiles:
            raise InputError("Annotator.draw: none of the rig's cameras has an image in this frame")
        h = max(t.shape[0] for t in tiles)
        tiles = [np.pad(t, ((0, h - t.shape[0]), (0, 0), (0, 0))) for t in tiles]
        return np.hstack(tiles)


class VideoWriter:
    """Writes BGR frames to a video (mp4v in .mp4, MJPG in .avi); opened on the first frame's size."""

    def __init__(self, path: str | Path, fps: float):
        self.path = Path(path)
        self.fps = float(fps) if fps and fps > 0 else 30.0
        self._w = None
        self.frames = 0

    def write(self, image: np.ndarray) -> None:
        import cv2

        if self._w is None:
            fourcc = "MJPG" if self.path.suffix.lower() == ".avi" else "mp4v"
            h, w = image.shape[:2]
            self._w = cv2.VideoWriter(
                str(self.path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*fourcc), self.fps, (w, h)
            )
            if not self._w.isOpened():
                raise InputError(f"{self.path}: cannot open a {fourcc} video writer")
            self._size = (w, h)
        if (image.shape[1], image.shape[0]) != self._size:
            import cv2

            image = cv2.resize(image, self._size)
        self._w.write(image)
        self.frames += 1

    def close(self) -> None:
        if self._w is not None:
            self._w.release()
            self._w = None


# ------------------------------------------------------------------------------------------- plots
def make_plots(
    tracks_path: str | Path, out_dir: str | Path, max_tracks: int = 12, max_polar_points: int = 5000
) -> list[Path]:
    """PNG plots from a ``tracks.jsonl`` (streamed from disk, so a run never holds its history).

    - ``range_over_time.png``: per track (the ``max_tracks`` longest), range with a 1-sigma band and
      the moving-obstacle bounds over time.
    - ``polar_map.png``: obstacles around the drone (azimuth vs range, body frame; 0 deg = nose, +90 deg =
      left), coloured by time.

    Returns the written files.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    counts: dict[int, int] = {}
    n_points = 0
    for rec in read_tracks(tracks_path):
        for t in rec["tracks"]:
            if t.get("range_m") is not None or t.get("range_min_m") is not None:
                counts[t["id"]] = counts.get(t["id"], 0) + 1
                n_points += 1
    chosen = sorted(counts, key=lambda k: -counts[k])[:max_tracks]
    series: dict[int, list[tuple]] = {k: [] for k in chosen}
    polar: list[tuple[float, float, float]] = []
    stride = max(1, n_points // max_polar_points)
    seen = 0
    for rec in read_tracks(tracks_path):
        for t in rec["tracks"]:
            if t["id"] in series:
                series[t["id"]].append(
                    (
                        rec["t_s"],
                        t.get("range_m"),
                        t.get("range_sigma_m"),
                        t.get("range_min_m"),
                        t.get("range_max_m"),
                    )
                )
            if t.get("range_m") is not None and t.get("status") != "lost":
                if seen % stride == 0:
                    polar.append((rec["t_s"], math.radians(t["azimuth_deg"]), t["range_m"]))
                seen += 1

    def col(rows, i):
        return np.array([np.nan if r[i] is None else r[i] for r in rows], dtype=float)

    written = []
    n = max(1, len(chosen))
    ncols = min(3, n)
    nrows = math.ceil(n / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(5 * ncols, 3 * nrows), squeeze=False)
    for ax, k in zip(axes.ravel(), chosen, strict=False):
        rows = series[k]
        t, r, s, lo, hi = (col(rows, i) for i in range(5))
        ax.plot(t, r, "b-", lw=1.2, label="range")
        ax.fill_between(t, r - s, r + s, color="b", alpha=0.2, lw=0, label="±1σ")
        ax.plot(t, lo, "g--", lw=0.8, label="bounds")
        ax.plot(t, hi, "g--", lw=0.8)
        ax.set_title(f"track {k}")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("range [m]")
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(chosen) :]:
        ax.axis("off")
    if chosen:
        axes.ravel()[0].legend(fontsize=7)
    else:
        axes.ravel()[0].text(0.5, 0.5, "no ranged tracks", ha="center", va="center")
    fig.tight_layout()
    p = out_dir / "range_over_time.png"
    fig.savefig(p, dpi=90)
    plt.close(fig)
    written.append(p)

    fig = plt.figure(figsize=(6, 6))
    ax = fig.add_subplot(projection="polar")
    ax.set_theta_zero_location("N")  # nose up
    ax.set_theta_direction(1)  # counter-clockwise: +azimuth (left) to the left of the nose
    if polar:
        a = np.array(polar)
        sc = ax.scatter(a[:, 1], a[:, 2], c=a[:, 0], s=6, cmap="viridis")
        fig.colorbar(sc, ax=ax, label="t [s]", shrink=0.7)
    ax.set_title("obstacles around the drone (range m, azimuth; nose up)")
    p = out_dir / "polar_map.png"
    fig.savefig(p, dpi=90)
    plt.close(fig)
    written.append(p)
    return written
