"""Metrics of a run's ``tracks.jsonl`` against a simulated scenario's ground truth.

Truth of a report: the ray from the body origin along the report's ``bearing_body`` (rotated to W
with ``T_W_B`` of ``trajectory.tum`` at the report's ``t_s``; within ``pipeline.run.EDGE_S`` past either
end the end's pose, as a run takes it) is cast into the scene with
:func:`pipeline.sim.world.raycast`. The hit's depth is the true range along that bearing and the
hit's object associates the report with an obstacle. A ray that narrowly misses (it hits sky or
ground) is associated with the obstacle of smallest angular distance to its bounding sphere if
within ``assoc_tol_deg``; its truth is then that obstacle's nearest-surface range. A report on the
sky that no obstacle claims, with a non-null ``range_m``, is a *false range*.

Reports with ``status == "lost"`` are not scored (they are predictions without a measurement).

A run is scored only against the scenario it ran on (:func:`check_run_inputs`): every input its
``config.resolved.yaml`` names must be in the scenario folder or be a byte-identical copy of one of
its videos; another scenario's truth is refused. An input that cannot be checked (an image folder
elsewhere, a file no longer there, a camera, no resolved config) is scored with a note.

Metrics (per group: overall, per scenario, per obstacle, stationary vs moving, by true-range bin;
these groups hold the tentative and confirmed reports, near misses included; beside them
``confirmed_hits``, the reports ``fisheye-des demo`` scores: :func:`scored_reports`, and
``near_misses`` alone, whose error measures the association, not the range along the bearing):
relative range error ``|r - r_true| / r_true`` (median, p90, signed median as bias), share within
5% and 10%, coverage of ``[range_min_m, range_max_m]``, its median width (an interval without an
upper end counts as infinitely wide) and the share without an upper end, speed and heading
error of ``velocity_world_mps`` against the obstacle's ``v_W``, NEES of the range (1-D,
``((r - r_true) / range_sigma_m)^2``: share within 1 sigma, mean and its 95% chi-square interval),
NIS of the tracker's own innovations when reported. Per obstacle also: detection coverage (share of
processed frames in which a visible obstacle has an associated report, counted after its first
``settle_s`` seconds of visibility), time from first sight to the first range within 10%, and id
switches (the obstacle's associated track id changes between consecutive tracked frames).
"""

from __future__ import annotations

import filecmp
import json
import math
from collections import defaultdict
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from estimators.egomotion import TumTrajectory
from estimators.errors import InputError
from pipeline.run import ClockOffset
from pipeline.sim.scene import Scenario, load_scenario
from pipeline.sim.world import SKY_ID, World, object_velocity, raycast, surface_distance
from pipeline.sinks import make_output_dir, to_plain

RANGE_BINS_M = (0.0, 2.0, 5.0, 10.0, 20.0, 50.0, math.inf)


# ----------------------------------------------------------------------------- chi-square helpers
_CHI2_95 = {1: 3.841458820694124, 2: 5.991464547107979, 3: 7.814727903251178, 4: 9.487729036781154}


def chi2_quantile(p: float, k: int) -> float:
    """Quantile of the chi-square distribution with ``k`` degrees of freedom.

    Wilson-Hilferty: ``chi2_p(k) ~ k (1 - 2/(9k) + z_p sqrt(2/(9k)))^3`` (relative error < 1e-2
    for k >= 2, far less for large k); exact table values for p = 0.95 and k <= 4."""
    if abs(p - 0.95) < 1e-12 and k in _CHI2_95:
        return _CHI2_95[k]
    z = _normal_quantile(p)
    a = 2.0 / (9.0 * k)
    return float(k * max(1.0 - a + z * math.sqrt(a), 0.0) ** 3)


def _normal_quantile(p: float) -> float:
    # Acklam's rational approximation (|error| < 1.2e-9)
    a = [
        -3.969683028665376e01,
        2.209460984245205e02,
        -2.759285104469687e02,
        1.383577518672690e02,
        -3.066479806614716e01,
        2.506628277459239e00,
    ]
    b = [
        -5.447609879822406e01,
        1.615858368580409e02,
        -1.556989798598866e02,
        6.680131188771972e01,
        -1.328068155288572e01,
    ]
    c = [
        -7.784894002430293e-03,
        -3.223964580411365e-01,
        -2.400758277161838e00,
        -2.549732539343734e00,
        4.374664141464968e00,
        2.938163982698783e00,
    ]
    d = [7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e00, 3.754408661907416e00]
    if p < 0.02425:
        q = math.sqrt(-2 * math.log(p))
        return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) / (
            (((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1
        )
    if p > 1 - 0.02425:
        return -_normal_quantile(1 - p)
    q = p - 0.5
    r = q * q
    return (
        (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5])
        * q
        / (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1)
    )


# ----------------------------------------------------------------------------------------- rows
@dataclass
class Row:
    """One scored report (one track in one frame)."""

    scenario: str
    frame: int
    t_s: float
    track_id: int
    status: str
    hit: str  # "obstacle" | "near" (narrow miss, associated) | "ground" | "sky"
    obstacle_id: int | None
    moving: bool | None
    range_true_m: float | None
    range_m: float | None
    range_sigma_m: float | None
    range_min_m: float | None
    range_max_m: float | None
    v_est_W: list | None
    v_true_W: list | None
    nis: float | None
    nis_dim: int | None


@dataclass
class ScenarioTruth:
    """The ground truth of one simulated scenario folder."""

    name: str
    scn: Scenario
    world: World
    traj: ClockOffset  # trajectory.tum at frame times (within pipeline.run.EDGE_S past an end: its pose)
    gt: list[dict] = field(default_factory=list)  # gt.jsonl lines

    @classmethod
    def load(cls, folder: str | Path) -> ScenarioTruth:
        folder = Path(folder)
        for f in ("scene.yaml", "trajectory.tum", "gt.jsonl"):
            if not (folder / f).is_file():
                raise InputError(
                    f"{folder}: expected a simulated scenario folder with {f} (fisheye-des simulate)"
                )
        scn = load_scenario(folder / "scene.yaml")
        gt = _read_jsonl(folder / "gt.jsonl")
        traj = ClockOffset(TumTrajectory.load(folder / "trajectory.tum"))
        return cls(scn.name, scn, World(scn), traj, gt)


def check_run_inputs(run_dir: str | Path, scen_dir: str | Path) -> list[str]:
    """Check that the run in ``run_dir`` ran on the scenario of ``scen_dir``: each input its
    ``config.resolved.yaml`` names (``inputs.videos`` / ``inputs.images``, or a live run's
    ``live.cameras``) is in the scenario folder, or a file with the bytes of one of its videos.

    No override: the truth describes exactly the frames rendered into that folder's videos; a variant
    of them (a re-encoded copy, frames exported to images) is scored by putting it in (a copy of) the
    scenario folder, where it counts as that scenario's.

    Returns notes on inputs that cannot be checked (an image folder or file elsewhere that is no
    copy, ...): scored as given.

    Raises:
        InputError: an input that exists and is not that scenario's, naming both.
    """
    from pipeline.sources import VIDEO_SUFFIXES

    run_dir, scen_dir = Path(run_dir), Path(scen_dir)
    resolved = run_dir / "config.resolved.yaml"
    if not resolved.is_file():
        return [f"{run_dir}: no config.resolved.yaml, so the run's inputs cannot be checked against "
                f"{scen_dir}'s videos; scored as given"]
    import yaml

    try:
        cfg = yaml.safe_load(resolved.read_text()) or {}
        inputs = cfg.get("inputs") or {}
        given = [*(inputs.get("videos") or []), *(inputs.get("images") or [])]
        if not given:  # a live run: its cameras (device indices, URLs or replayed files)
            given = list((cfg.get("live") or {}).get("cameras") or [])
    except (yaml.YAMLError, AttributeError) as e:
        raise InputError(f"{resolved}: expected the run's resolved config (fisheye-des run): {e}") from None
    videos = sorted(p for p in scen_dir.iterdir() if p.suffix.lower() in VIDEO_SUFFIXES)
    notes, foreign = [], []
    for item in given:
        p = Path(str(item))
        if isinstance(item, str) and p.parent.exists() and p.parent.samefile(scen_dir):
            continue  # in the scenario folder
        if isinstance(item, str) and p.is_file():
            size = p.stat().st_size
            if any(v.stat().st_size == size and filecmp.cmp(p, v, shallow=False) for v in videos):
                continue  # a copy of one of its videos
            if p.suffix.lower() in VIDEO_SUFFIXES:
                foreign.append(str(item))
                continue
        kind = ("a camera" if not isinstance(item, str) or "://" in item
                or (p.exists() and not p.is_file() and not p.is_dir())  # a device node, /dev/video0
                else "an image folder" if p.is_dir()
                else "not there any more" if not p.exists() else "a file")
        notes.append(f"{run_dir}: input {item} ({kind}) cannot be checked against {scen_dir}'s videos; "
                     "scored as given")
    if foreign:
        raise InputError(
            f"{run_dir}: the run's video{'s' if len(foreign) > 1 else ''} {', '.join(foreign)} "
            f"{'are' if len(foreign) > 1 else 'is'} not scenario {scen_dir}'s "
            f"({', '.join(v.name for v in videos) or 'no videos'}), so its truth does not describe "
            f"{'them' if len(foreign) > 1 else 'it'}; expected a run of that scenario's videos or of "
            "byte-identical copies of them (a re-encoded variant counts as the scenario's once it is put in "
            "a copy of its folder)"
        )
    return notes


def _read_jsonl(path: Path) -> list[dict]:
    out = []
    with path.open() as f:
        for lineno, line in enumerate(f, start=1):
            s = line.strip()
            if not s:
                continue
            try:
                out.append(json.loads(s))
            except json.JSONDecodeError as e:
                raise InputError(f"{path}:{lineno}: not valid JSON ({e.msg})") from None
    return out


def score_reports(truth: ScenarioTruth, frames: list[dict], assoc_tol_deg: float = 2.0) -> list[Row]:
    """Associate and score every non-lost report of ``frames`` (tracks.jsonl lines)."""
    rows: list[Row] = []
    tol = math.radians(assoc_tol_deg)
    ground_id = truth.scn.ground.id if truth.scn.ground.enabled else None
    for fr in frames:
        t, tracks = _check_frame(fr)
        tracks = [tr for tr in tracks if tr.get("status") != "lost"]
        if not tracks or not truth.traj.covers(t):
            continue
        T_W_B = truth.traj.pose_at(t)
        b_B = np.array([_bearing(tr, fr) for tr in tracks], float)
        b_B /= np.linalg.norm(b_B, axis=1, keepdims=True)
        d_W = T_W_B.rotate(b_B)
        depth, ids = raycast(truth.world, t, T_W_B.t, d_W)
        placed = {p.spec.id: p for p in truth.world.place(t)}
        for k, tr in enumerate(tracks):
            oid = int(ids[k])
            r_true = float(depth[k])
            if oid != SKY_ID and oid != ground_id:
                hit = "obstacle"
            else:
                hit = "sky" if oid == SKY_ID else "ground"
                near = _nearest_obstacle(placed, T_W_B.t, d_W[k], tol, truth.world, t)
                if near is not None:
                    oid, hit = near, "near"
                    pl = placed[near]
                    r_true = min(surface_distance(p, pl, T_W_B.t) for p in pl.parts)
                else:
                    oid = None
                    r_true = r_true if hit == "ground" else None
            spec = placed[oid].spec if hit in ("obstacle", "near") else None
            v_true = None
            if spec is not None:
                v_true = object_velocity(spec, t).tolist()
            inn = tr.get("innovation")
            rows.append(
                Row(
                    scenario=truth.name,
                    frame=int(fr.get("frame", -1)),
                    t_s=t,
                    track_id=int(tr["id"]),
                    status=str(tr.get("status", "")),
                    hit=hit,
                    obstacle_id=oid,
                    moving=None if spec is None else bool(spec.moving),
                    range_true_m=r_true,
                    range_m=_f(tr.get("range_m")),
                    range_sigma_m=_f(tr.get("range_sigma_m")),
                    range_min_m=_f(tr.get("range_min_m")),
                    range_max_m=_f(tr.get("range_max_m")),
                    v_est_W=tr.get("velocity_world_mps"),
                    v_true_W=v_true,
                    nis=_f(tr.get("nis")),
                    nis_dim=len(inn) if isinstance(inn, list) and inn else None,
                )
            )
    return rows


def _check_frame(fr) -> tuple[float, list[dict]]:
    """A tracks.jsonl line -> (t_s, tracks) after checking its shape (CONVENTIONS.md); InputError
    naming the frame and the field otherwise."""
    if not isinstance(fr, dict) or "t_s" not in fr:
        raise InputError(f"tracks.jsonl: expected objects with t_s and tracks, got {str(fr)[:80]!r}")
    where = f"tracks.jsonl frame {fr.get('frame')} (t_s {fr.get('t_s')!r})"
    try:
        t = float(fr["t_s"])
    except (TypeError, ValueError):
        t = math.nan
    if not math.isfinite(t):
        raise InputError(f"{where}: expected t_s a finite number of seconds")
    tracks = fr.get("tracks", [])
    if not isinstance(tracks, list) or not all(isinstance(tr, dict) for tr in tracks):
        raise InputError(f"{where}: expected 'tracks' a list of track objects, got {str(tracks)[:80]!r}")
    for tr in tracks:
        if not isinstance(tr.get("id"), int) or isinstance(tr.get("id"), bool):
            raise InputError(f"{where}: every track needs an integer 'id', got {str(tr)[:80]!r}")
        for key in ("range_m", "range_sigma_m", "range_min_m", "range_max_m", "nis"):
            v = tr.get(key)
            if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)):
                raise InputError(f"{where}: track {tr['id']}: expected {key} a number or null, got {v!r}")
        v = tr.get("velocity_world_mps")
        if v is not None and not (
            isinstance(v, list) and len(v) == 3 and all(isinstance(x, int | float) for x in v)
        ):
            raise InputError(f"{where}: track {tr['id']}: expected velocity_world_mps [vx, vy, vz] or null, "
                             f"got {v!r}")
    return t, tracks


def _bearing(tr: dict, fr: dict) -> list[float]:
    b = tr.get("bearing_body")
    try:
        v = np.asarray(b, float).reshape(3)
    except (TypeError, ValueError):
        v = None
    if v is None or not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-12:
        raise InputError(
            f"tracks.jsonl frame {fr.get('frame')} (t_s {fr.get('t_s')}): track {tr.get('id')} has "
            f"bearing_body {b!r}; expected a non-zero [x, y, z]"
        )
    return v.tolist()


def _f(v) -> float | None:
    return None if v is None else float(v)


def _nearest_obstacle(placed: dict, o_W: np.ndarray, d_W: np.ndarray, tol_rad: float,
                      world: World, t_s: float) -> int | None:
    """Obstacle angularly nearest to the ray from o_W (3,) m along d_W (3,) (W), within tol_rad, else None.

    Candidates: obstacles whose bounding sphere lies within tol_rad of the ray (angle to the
    sphere, negative inside it). One candidate: that one. Several: a
    bounding sphere is no measure of the distance to the surface (a 7 m pole 6 m away has a sphere
    of +-34 deg, so a ray 0.2 px beside a sphere 15 m away is "inside" the pole's sphere and was
    given to the pole), so rays on cones of growing half-angle th_i = tol_rad * (1/64 ... 1) around
    d_W are cast into ``world`` at t_s; the first cone that hits a candidate decides (the candidate
    its rays hit most, ties to the smaller sphere angle); no cone hits one: the smallest sphere angle.
    """
    cands: list[tuple[float, int]] = []
    for oid, pl in placed.items():
        v = pl.bound_c_W - o_W
        dist = float(np.linalg.norm(v))
        if dist <= pl.bound_r:
            continue
        ang = math.acos(float(np.clip(d_W @ v / dist, -1, 1))) - math.asin(pl.bound_r / dist)
        if ang <= tol_rad:
            cands.append((ang, oid))
    if not cands:
        return None
    cands.sort()
    if len(cands) == 1:
        return cands[0][1]
    d = np.asarray(d_W, float) / float(np.linalg.norm(d_W))
    e = np.zeros(3)
    e[int(np.argmin(np.abs(d)))] = 1.0
    e1 = np.cross(d, e)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    phi = np.linspace(0.0, 2.0 * math.pi, 16, endpoint=False)
    ring = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2  # (16, 3) unit, perpendicular to d
    rank = {oid: i for i, (_a, oid) in enumerate(cands)}
    origins = np.repeat(np.asarray(o_W, float)[None], len(phi), axis=0)
    for f in (1 / 64, 1 / 32, 1 / 16, 1 / 8, 1 / 4, 1 / 2, 3 / 4, 1.0):
        th = f * tol_rad
        # a cone of half-angle th about d: b = cos(th) d + sin(th) (cos(phi) e1 + sin(phi) e2)
        _depth, ids = raycast(world, t_s, origins, math.cos(th) * d + math.sin(th) * ring)
        hit = [int(i) for i in ids.tolist() if int(i) in rank]
        if hit:
            return min(set(hit), key=lambda oid: (-hit.count(oid), rank[oid]))
    return cands[0][1]


# -------------------------------------------------------------------------------------- metrics
def _pct(x: np.ndarray, q: float) -> float | None:
    return float(np.percentile(x, q)) if len(x) else None


def range_metrics(rows: list[Row], surface: str = "obstacle") -> dict:
    """Range, bounds, velocity and consistency metrics of associated rows (see module doc).

    surface: ``"obstacle"`` scores reports associated with an obstacle; ``"ground"`` scores the
    reports whose ray hit the ground (truth: the ground's depth along the bearing)."""
    if surface == "ground":
        assoc = [r for r in rows if r.hit == "ground" and r.obstacle_id is None and r.range_true_m]
    else:
        assoc = [r for r in rows if r.obstacle_id is not None and r.range_true_m]
    ranged = [r for r in assoc if r.range_m is not None]
    out: dict = {"reports": len(assoc), "ranged": len(ranged)}
    if ranged:
        e = np.array([(r.range_m - r.range_true_m) / r.range_true_m for r in ranged])
        a = np.abs(e)
        out.update(
            rel_err_median=float(np.median(a)),
            rel_err_p90=_pct(a, 90),
            rel_err_signed_median=float(np.median(e)),
            within_5pct=float(np.mean(a <= 0.05)),
            within_10pct=float(np.mean(a <= 0.10)),
        )
    bnd = [r for r in assoc if r.range_min_m is not None or r.range_max_m is not None]
    if bnd:
        lo = np.array([r.range_min_m if r.range_min_m is not None else 0.0 for r in bnd])
        hi = np.array([r.range_max_m if r.range_max_m is not None else math.inf for r in bnd])
        tr = np.array([r.range_true_m for r in bnd])
        w = hi - lo  # +inf for an interval without an upper end: it sorts last in the median
        out.update(
            bounds_reports=len(bnd),
            bounds_coverage=float(np.mean((lo <= tr) & (tr <= hi))),
            bounds_width_median_m=float(np.median(w)),  # inf (null in JSON) if most are unbounded
            bounds_rel_width_median=float(np.median(w / tr)),
            bounds_unbounded_share=float(np.mean(~np.isfinite(w))),
        )
    vel = [r for r in assoc if r.v_est_W is not None and r.v_true_W is not None]
    if vel:
        ve = np.array([r.v_est_W for r in vel], float)
        vt = np.array([r.v_true_W for r in vel], float)
        sp_e, sp_t = np.linalg.norm(ve, axis=1), np.linalg.norm(vt, axis=1)
        out.update(
            velocity_reports=len(vel),
            speed_err_median_mps=float(np.median(np.abs(sp_e - sp_t))),
            speed_err_p90_mps=_pct(np.abs(sp_e - sp_t), 90),
        )
        ok = (sp_t > 0.5) & (sp_e > 1e-6)  # heading only where the obstacle really moves
        if ok.any():
            cosang = np.sum(ve[ok] * vt[ok], axis=1) / (sp_e[ok] * sp_t[ok])
            h = np.degrees(np.arccos(np.clip(cosang, -1, 1)))
            out.update(heading_err_median_deg=float(np.median(h)), heading_err_p90_deg=_pct(h, 90))
    sig = [r for r in ranged if r.range_sigma_m is not None and r.range_sigma_m > 0]
    if sig:
        z = np.array([(r.range_m - r.range_true_m) / r.range_sigma_m for r in sig])
        nees = z * z
        n = len(nees)
        lo, hi = chi2_quantile(0.025, n) / n, chi2_quantile(0.975, n) / n  # mean of n chi2(1)
        out.update(
            nees_reports=n,
            within_1sigma=float(np.mean(np.abs(z) <= 1.0)),
            nees_mean=float(nees.mean()),
            nees_mean_ci95=[lo, hi],
            nees_consistent=bool(lo <= nees.mean() <= hi),
        )
    nis = [r for r in assoc if r.nis is not None]
    if nis:
        v = np.array([r.nis for r in nis])
        dims = np.array([r.nis_dim or 1 for r in nis])
        gate = np.array([chi2_quantile(0.95, int(k)) for k in dims])
        out.update(
            nis_reports=len(v),
            nis_mean=float(v.mean()),
            nis_mean_expected=float(dims.mean()),
            nis_within_95=float(np.mean(v <= gate)),
        )
    return out


def scored_reports(rows: list[Row]) -> list[Row]:
    """The reports ``fisheye-des demo`` scores: those of **confirmed** tracks whose bearing hits an
    obstacle (``hit == "obstacle"``; truth: the depth of that hit), of any age. Tentative tracks'
    reports and near misses (the ray passes beside the obstacle) are left out."""
    return [r for r in rows if r.status == "confirmed" and r.obstacle_id is not None and r.hit == "obstacle"]


def scored_range_metrics(rows: list[Row]) -> dict[str, dict]:
    """:func:`range_metrics` of :func:`scored_reports` (``rows``: :func:`score_reports`' rows), as
    ``fisheye-des demo``'s summary gives them: {"confirmed": all of them, "stationary": those on
    stationary obstacles, "moving": those on moving obstacles}."""
    on = scored_reports(rows)
    return {
        "confirmed": range_metrics(on),
        "stationary": range_metrics([r for r in on if r.moving is False]),
        "moving": range_metrics([r for r in on if r.moving is True]),
    }


def obstacle_metrics(
    truth: ScenarioTruth, frames: list[dict], rows: list[Row], settle_s: float = 0.5
) -> dict:
    """Per-obstacle detection coverage, time to the first range within 10%, id switches."""
    run_t = np.array(sorted(float(f["t_s"]) for f in frames))
    dt_tol = 0.25 / truth.scn.fps
    by_obs: dict[int, dict[float, list[Row]]] = defaultdict(lambda: defaultdict(list))
    for r in rows:
        if r.obstacle_id is not None and r.hit in ("obstacle", "near"):
            by_obs[r.obstacle_id][round(r.t_s, 6)].append(r)
    out = {}
    for spec in truth.scn.obstacles:
        vis_t = [
            float(g["t_s"])
            for g in truth.gt
            for o in g["obstacles"]
            if o["id"] == spec.id and any(o["visible"].values())
        ]
        first = vis_t[0] if vis_t else None
        processed = [t for t in vis_t if len(run_t) and np.min(np.abs(run_t - t)) <= dt_tol]
        eligible = [t for t in processed if first is not None and t >= first + settle_s]
        tracked_t = sorted(by_obs[spec.id])
        tracked = [t for t in eligible if tracked_t and np.min(np.abs(np.array(tracked_t) - t)) <= dt_tol]
        # time to the first report within 10%
        t10 = None
        for t in tracked_t:
            if any(
                r.range_m is not None and abs(r.range_m - r.range_true_m) <= 0.10 * r.range_true_m
                for r in by_obs[spec.id][t]
            ):
                t10 = t
                break
        # id switches: the associated track id (continuing the previous one when several) changes
        last, switches, ids = None, 0, set()
        for t in tracked_t:
            tids = sorted({r.track_id for r in by_obs[spec.id][t]})
            ids.update(tids)
            cur = last if last in tids else tids[0]
            if last is not None and cur != last:
                switches += 1
            last = cur
        out[str(spec.id)] = {
            "kind": spec.kind,
            "moving": spec.moving,
            "visible_frames": len(vis_t),
            "eligible_frames": len(eligible),
            "tracked_frames": len(tracked),
            "detection_coverage": (len(tracked) / len(eligible)) if eligible else None,
            "first_seen_s": first,
            "time_to_10pct_s": (t10 - first) if (t10 is not None and first is not None) else None,
            "id_switches": switches,
            "track_ids": sorted(ids),
        }
    return out


def sky_metrics(rows: list[Row]) -> dict:
    sky = [r for r in rows if r.hit == "sky"]
    ground = [r for r in rows if r.hit == "ground" and r.obstacle_id is None]
    false = [r for r in sky if r.range_m is not None]
    return {
        "all_reports": len(rows),
        "sky_reports": len(sky),
        "false_ranges_sky": len(false),
        "false_range_share": (len(false) / len(rows)) if rows else None,
        "ground_reports": len(ground),
    }


def _bin_name(lo: float, hi: float) -> str:
    return f"{lo:g}-{hi:g}m" if math.isfinite(hi) else f">{lo:g}m"


@dataclass
class Evaluation:
    """Result of :func:`evaluate`: ``metrics`` (metrics.json), the scored rows, and per
    (RUN_DIR, SCENARIO_DIR) pair its truth, its tracks.jsonl lines and its key in ``by_scenario``
    (the scenario's name, ``name#k`` when a name repeats; ``Row.scenario`` holds the same key)."""

    metrics: dict
    rows: list[Row]
    truths: list[ScenarioTruth]
    frames: list[list[dict]]
    keys: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # inputs check_run_inputs could not check


def evaluate(
    pairs: list[tuple[str | Path, str | Path]], assoc_tol_deg: float = 2.0, settle_s: float = 0.5
) -> Evaluation:
    """Evaluate (RUN_DIR, SCENARIO_DIR) pairs. Returns metrics (the ``metrics.json`` mapping)."""
    all_rows: list[Row] = []
    truths, frames_all, keys, notes = [], [], [], []
    by_scenario, by_obstacle, sky_by = {}, {}, {}
    for run_dir, scen_dir in pairs:
        tracks = Path(run_dir) / "tracks.jsonl"
        if not tracks.is_file():
            raise InputError(f"{run_dir}: expected a run folder with tracks.jsonl (fisheye-des run)")
        frames = _read_jsonl(tracks)
        truth = ScenarioTruth.load(scen_dir)
        notes += check_run_inputs(run_dir, scen_dir)
        rows = score_reports(truth, frames, assoc_tol_deg)
        key = truth.name if truth.name not in by_scenario else f"{truth.name}#{len(by_scenario)}"
        for r in rows:
            r.scenario = key
        all_rows += rows
        truths.append(truth)
        frames_all.append(frames)
        keys.append(key)
        by_scenario[key] = range_metrics(rows)
        sky_by[key] = sky_metrics(rows)
        for oid, m in obstacle_metrics(truth, frames, rows, settle_s).items():
            m.update(range_metrics([r for r in rows if r.obstacle_id == int(oid)]))
            by_obstacle[f"{key}/{oid}"] = m
    by_motion = {
        "stationary": range_metrics([r for r in all_rows if r.moving is False]),
        "moving": range_metrics([r for r in all_rows if r.moving is True]),
    }
    by_bin = {}
    for lo, hi in zip(RANGE_BINS_M[:-1], RANGE_BINS_M[1:], strict=True):
        sel = [r for r in all_rows if r.range_true_m is not None and lo <= r.range_true_m < hi]
        by_bin[_bin_name(lo, hi)] = range_metrics(sel)
    obs_vals = list(by_obstacle.values())
    cov = [m["detection_coverage"] for m in obs_vals if m["detection_coverage"] is not None]
    overall = range_metrics(all_rows)
    overall.update(sky_metrics(all_rows))
    overall["frames_outside_truth"] = int(
        sum(
            1
            for tr, frs in zip(truths, frames_all, strict=True)
            for f in frs
            if not tr.traj.covers(float(f["t_s"]))
        )
    )
    overall.update(
        detection_coverage=float(np.mean(cov)) if cov else None,
        id_switches=int(sum(m["id_switches"] for m in obs_vals)),
    )
    metrics = {
        "overall": overall,
        "confirmed_hits": range_metrics(scored_reports(all_rows)),
        "near_misses": range_metrics([r for r in all_rows if r.hit == "near"]),
        "by_scenario": by_scenario,
        "sky_by_scenario": sky_by,
        "ground": range_metrics(all_rows, surface="ground"),
        "by_obstacle": by_obstacle,
        "by_motion": by_motion,
        "by_range_bin": by_bin,
        "settings": {
            "assoc_tol_deg": assoc_tol_deg,
            "settle_s": settle_s,
            "range_bins_m": [b if math.isfinite(b) else None for b in RANGE_BINS_M],
        },
    }
    return Evaluation(metrics, all_rows, truths, frames_all, keys, notes)


# --------------------------------------------------------------------------------------- output
_COLS = [
    ("reports", "n", "{:d}"),
    ("ranged", "ranged", "{:d}"),
    ("rel_err_median", "med%", "{:.1%}"),
    ("rel_err_p90", "p90%", "{:.1%}"),
    ("within_5pct", "<5%", "{:.0%}"),
    ("within_10pct", "<10%", "{:.0%}"),
    ("bounds_coverage", "bnd cov", "{:.0%}"),
    ("bounds_width_median_m", "bnd w m", "{:.2f}"),
    ("speed_err_median_mps", "spd err", "{:.2f}"),
    ("heading_err_median_deg", "hdg deg", "{:.1f}"),
    ("within_1sigma", "<1sig", "{:.0%}"),
    ("nees_mean", "NEES", "{:.2f}"),
    ("detection_coverage", "det cov", "{:.0%}"),
    ("time_to_10pct_s", "t10 s", "{:.2f}"),
    ("id_switches", "idsw", "{:d}"),
]


def format_table(metrics: dict) -> str:
    """A plain-text table of the groups of ``metrics`` (one row per group)."""
    groups = [("overall", metrics["overall"]), ("(confirmed hits)", metrics["confirmed_hits"]),
              ("(near misses)", metrics["near_misses"])]
    groups += [(f"scenario {k}", v) for k, v in metrics["by_scenario"].items()]
    groups += [
        (f"obstacle {k} ({v['kind']}{', moving' if v['moving'] else ''})", v)
        for k, v in metrics["by_obstacle"].items()
    ]
    groups += [(k, v) for k, v in metrics["by_motion"].items()]
    groups += [(f"range {k}", v) for k, v in metrics["by_range_bin"].items()]
    groups += [("(reports on the ground)", metrics["ground"])]
    w0 = max(len(g) for g, _ in groups) + 1
    head = "group".ljust(w0) + " ".join(h.rjust(8) for _, h, _ in _COLS)
    lines = [head, "-" * len(head)]
    for name, m in groups:
        cells = []
        for key, _, fmt in _COLS:
            v = m.get(key)
            cells.append(("-" if v is None else fmt.format(v)).rjust(8))
        lines.append(name.ljust(w0) + " ".join(cells))
    o = metrics["overall"]
    lines.append("")
    lines.append(
        "scored: overall and the scenario, obstacle, motion and range rows take tentative and confirmed "
        "reports whose bearing hits an obstacle or narrowly misses it (near misses: truth the obstacle's "
        "nearest surface, while the report ranges what lies behind it); (confirmed hits): confirmed "
        "reports whose bearing hits an obstacle, as fisheye-des demo scores them"
    )
    if o.get("frames_outside_truth"):
        lines.append(
            f"note: {o['frames_outside_truth']} tracks.jsonl frames lie outside the scenario's time span "
            "and were not scored (is SCENARIO_DIR the one the run was made on?)"
        )
    lines.append(
        f"false ranges on sky: {o['false_ranges_sky']} of {o['all_reports']} reports; "
        f"sky reports {o['sky_reports']}, ground reports {o['ground_reports']}"
    )
    if o.get("nees_mean") is not None:
        lo, hi = o["nees_mean_ci95"]
        lines.append(
            f"NEES mean {o['nees_mean']:.2f} (95% interval for a consistent filter {lo:.2f}-{hi:.2f}); "
            f"within 1 sigma {o['within_1sigma']:.0%} (expected 68%)"
        )
    if o.get("nis_mean") is not None:
        lines.append(
            f"NIS mean {o['nis_mean']:.2f} (expected {o['nis_mean_expected']:.2f}); "
            f"within the 95% gate {o['nis_within_95']:.0%}"
        )
    return "\n".join(lines)


def plot_ranges(ev: Evaluation, out_dir: str | Path) -> list[Path]:
    """PNG per obstacle: true range (along the reports' bearings, and to the centre / nearest
    surface), estimates with a 1-sigma band, and the bounds, against time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for truth, key in zip(ev.truths, ev.keys or [t.name for t in ev.truths], strict=True):
        rows = [r for r in ev.rows if r.scenario == key]
        for spec in truth.scn.obstacles:
            gt_t, gt_c, gt_s = [], [], []
            for g in truth.gt:
                o = next((o for o in g["obstacles"] if o["id"] == spec.id), None)
                if o is not None and any(o["visible"].values()):
                    gt_t.append(g["t_s"])
                    gt_c.append(o["range_m"])
                    gt_s.append(o["surface_range_m"])
            mine = sorted((r for r in rows if r.obstacle_id == spec.id), key=lambda r: r.t_s)
            if not gt_t and not mine:
                continue
            fig, ax = plt.subplots(figsize=(8, 4.5), dpi=100)
            if gt_t:
                ax.plot(gt_t, gt_c, "k-", lw=1, label="truth: centre")
                ax.plot(gt_t, gt_s, "k--", lw=1, label="truth: nearest surface")
            if mine:
                t = np.array([r.t_s for r in mine])
                ax.plot(
                    t, [r.range_true_m for r in mine], ".", color="0.5", ms=3, label="truth along bearing"
                )
                for tid in sorted({r.track_id for r in mine}):
                    sel = [r for r in mine if r.track_id == tid and r.range_m is not None]
                    if not sel:
                        continue
                    tt = np.array([r.t_s for r in sel])
                    rr = np.array([r.range_m for r in sel])
                    ax.plot(tt, rr, ".-", ms=3, lw=0.8, label=f"track {tid}")
                    ss = np.array([r.range_sigma_m if r.range_sigma_m is not None else np.nan for r in sel])
                    if np.isfinite(ss).any():
                        ax.fill_between(tt, rr - ss, rr + ss, alpha=0.2)
                bt = [r for r in mine if r.range_min_m is not None or r.range_max_m is not None]
                if bt:
                    ax.vlines(
                        [r.t_s for r in bt],
                        [r.range_min_m or 0.0 for r in bt],
                        [r.range_max_m if r.range_max_m is not None else np.nan for r in bt],
                        colors="tab:orange",
                        alpha=0.3,
                        lw=1,
                        label="bounds",
                    )
            ax.set_xlabel("t [s]")
            ax.set_ylabel("range [m]")
            ax.set_title(f"{key}: obstacle {spec.id} ({spec.kind}{', moving' if spec.moving else ''})")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="best")
            p = out_dir / f"range_{key.replace('#', '_')}_obstacle{spec.id}.png"
            fig.tight_layout()
            fig.savefig(p)
            plt.close(fig)
            paths.append(p)
    return paths


def write_outputs(ev: Evaluation, out_dir: str | Path, plots: bool = True) -> dict[str, Path]:
    """Write ``metrics.json``, ``metrics.txt``, ``reports.jsonl`` (scored rows) and the plots."""
    out_dir = make_output_dir(out_dir)
    (out_dir / "metrics.json").write_text(json.dumps(to_plain(ev.metrics), indent=2))
    (out_dir / "metrics.txt").write_text(format_table(ev.metrics) + "\n")
    with (out_dir / "reports.jsonl").open("w") as f:
        for r in ev.rows:
            f.write(json.dumps(to_plain(asdict(r))) + "\n")
    paths = {"metrics.json": out_dir / "metrics.json", "metrics.txt": out_dir / "metrics.txt"}
    if plots:
        for p in plot_ranges(ev, out_dir / "plots"):
            paths[p.name] = p
    return paths
