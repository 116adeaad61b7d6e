"""Conformance to /work/shared/CONVENTIONS.md (and docs/OUTPUTS.md), read as an outside tool would.

The reader below is written from the documents' text alone: it imports nothing of the project's
sinks or records (a tool outside the project has only the documents), parses strictly (no NaN or
Infinity tokens) and reads the camchain with a plain YAML load. It runs on the outputs of real
pipeline runs over small simulated mono and stereo scenes, and on ``calibrate``'s camchain.
"""

from __future__ import annotations

import ast
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]

# docs/OUTPUTS.md's table: every field of a track and the JSON types it may take ("float" takes an
# int too: JSON does not tell 1.0 from 1; a reader gets either). `attributes` is the detector's
# extras, present when there are any.
_NUM = (int, float)
_FIELDS: dict[str, tuple] = {
    "id": (int,),
    "status": (str,),
    "camera": (str, list),
    "bearing_body": (list,),
    "azimuth_deg": _NUM,
    "elevation_deg": _NUM,
    "range_m": (*_NUM, type(None)),
    "range_sigma_m": (*_NUM, type(None)),
    "range_min_m": (*_NUM, type(None)),
    "range_max_m": (*_NUM, type(None)),
    "position_body_m": (list, type(None)),
    "velocity_world_mps": (list, type(None)),
    "speed_mps": (*_NUM, type(None)),
    "speed_sigma_mps": (*_NUM, type(None)),
    "ttc_s": (*_NUM, type(None)),
    "miss_distance_m": (*_NUM, type(None)),
    "miss_distance_sigma_m": (*_NUM, type(None)),
    "source": (str,),
    "label": (str,),
    "nis": (*_NUM, type(None)),
    "innovation": (list, type(None)),
    "gated": (int,),
    "unobservable_reason": (str, type(None)),
}
_OPTIONAL = {"attributes": (dict,)}
_SOURCES = {"mono", "stereo", "bounds"}
_SOURCE_ORDER = ("mono", "stereo", "bounds")


def _no_constant(name: str):
    raise ValueError(f"non-JSON number token {name}")


def strict_loads(text: str):
    """json.loads that refuses NaN, Infinity and -Infinity (which Python's json accepts)."""
    return json.loads(text, parse_constant=_no_constant)


def _vec3(v) -> bool:
    return isinstance(v, list) and len(v) == 3 and all(type(x) in _NUM for x in v)


def check_track(t: dict, rig_names: set[str]) -> list[str]:
    """What is wrong with one track object (empty when nothing)."""
    bad: list[str] = []
    keys = set(t)
    missing = set(_FIELDS) - keys
    extra = keys - set(_FIELDS) - set(_OPTIONAL)
    if missing or extra:
        return [f"keys: missing {sorted(missing)}, undocumented {sorted(extra)}"]
    for k, types in {**_FIELDS, **{k: v for k, v in _OPTIONAL.items() if k in t}}.items():
        if type(t[k]) not in types:  # type(): a bool is not an int here
            bad.append(f"{k}: {type(t[k]).__name__} {t[k]!r}")
    if bad:
        return bad
    if t["status"] not in ("tentative", "confirmed", "lost"):
        bad.append(f"status {t['status']!r}")
    cams = t["camera"] if isinstance(t["camera"], list) else [t["camera"]]
    if not cams or not set(cams) <= rig_names or not all(isinstance(c, str) for c in cams):
        bad.append(f"camera {t['camera']!r} not of the rig {sorted(rig_names)}")
    for k in ("bearing_body", "position_body_m", "velocity_world_mps"):
        if t[k] is not None and not _vec3(t[k]):
            bad.append(f"{k} not [x, y, z]: {t[k]!r}")
    if bad:
        return bad
    # bearing: unit, in B = FLU; azimuth from x (forward) toward y (left), elevation toward z (up)
    x, y, z = t["bearing_body"]
    if abs(math.sqrt(x * x + y * y + z * z) - 1.0) > 1e-9:
        bad.append(f"bearing_body norm {math.sqrt(x * x + y * y + z * z)}")
    if abs(t["azimuth_deg"] - math.degrees(math.atan2(y, x))) > 1e-9:
        bad.append(f"azimuth_deg {t['azimuth_deg']} for bearing {t['bearing_body']}")
    if abs(t["elevation_deg"] - math.degrees(math.asin(max(-1.0, min(1.0, z))))) > 1e-6:
        bad.append(f"elevation_deg {t['elevation_deg']} for bearing {t['bearing_body']}")
    # range from B's origin; its sigma with it ("null until observable")
    r = t["range_m"]
    if r is None:
        if t["range_sigma_m"] is not None:
            bad.append(f"range_sigma_m {t['range_sigma_m']} without range_m")
        if not t["unobservable_reason"]:
            bad.append("range_m null without unobservable_reason")
    elif not (r > 0 and t["range_sigma_m"] is not None and t["range_sigma_m"] > 0):
        bad.append(f"range_m {r} range_sigma_m {t['range_sigma_m']}")
    # bounds: null, or [min, max] with max null = unbounded. They bound the true range for an obstacle
    # no faster than the maximum speed; range_m is not promised to lie within them (the fusion fuses
    # a soft pseudo-measurement for mono tracks only, stereo measures the range itself), so no
    # relation of range_m to the bounds is checked.
    lo, hi = t["range_min_m"], t["range_max_m"]
    if lo is None and hi is not None:
        bad.append(f"range_max_m {hi} without range_min_m")
    if lo is not None and (lo < 0 or (hi is not None and not lo <= hi)):
        bad.append(f"bounds [{lo}, {hi}]")
    # position in B: the range along the bearing (both from B's origin)
    p = t["position_body_m"]
    if (p is None) != (r is None):
        bad.append(f"position_body_m {p} with range_m {r}")
    elif p is not None and max(abs(p[i] - r * t["bearing_body"][i]) for i in range(3)) > 1e-9 * max(r, 1.0):
        bad.append(f"position_body_m {p} != range_m {r} * bearing_body {t['bearing_body']}")
    # velocity, its speed and the speed's sigma come together
    v = t["velocity_world_mps"]
    if v is None:
        if t["speed_mps"] is not None or t["speed_sigma_mps"] is not None:
            bad.append(f"speed_mps {t['speed_mps']}, speed_sigma_mps {t['speed_sigma_mps']} no velocity")
    else:
        if t["speed_mps"] is None or abs(t["speed_mps"] - math.hypot(*v)) > 1e-9 * max(1.0, math.hypot(*v)):
            bad.append(f"speed_mps {t['speed_mps']} != |velocity_world_mps| {math.hypot(*v)}")
        if t["speed_sigma_mps"] is None or t["speed_sigma_mps"] < 0:
            bad.append(f"speed_sigma_mps {t['speed_sigma_mps']} with a velocity")
    if t["ttc_s"] is not None and (t["ttc_s"] < 0 or r is None):
        bad.append(f"ttc_s {t['ttc_s']} (range_m {r})")
    # the distance at that closest approach and its sigma: null exactly when ttc_s is; the miss is
    # the range's component across the relative velocity, so at most the range
    md, ms = t["miss_distance_m"], t["miss_distance_sigma_m"]
    if (md is None) != (t["ttc_s"] is None) or (ms is None) != (t["ttc_s"] is None):
        bad.append(f"miss_distance_m {md}, miss_distance_sigma_m {ms} with ttc_s {t['ttc_s']}")
    elif md is not None and not (0 <= md <= r * (1 + 1e-9) and ms >= 0):
        bad.append(f"miss_distance_m {md} +- {ms} (range_m {r})")
    # source: "" or members of {mono, stereo, bounds} joined by "+" in that order
    s = t["source"]
    parts = s.split("+") if s else []
    if not set(parts) <= _SOURCES or parts != [x for x in _SOURCE_ORDER if x in parts]:
        bad.append(f"source {s!r}")
    elif r is not None and not {"mono", "stereo"} & set(parts):
        bad.append(f"range_m {r} from source {s!r} (no mono or stereo measurement)")
    elif r is None and s not in ("", "bounds"):
        bad.append(f"source {s!r} without range_m")
    elif "bounds" in parts and lo is None:
        bad.append(f"source {s!r} without bounds")
    elif s == "" and lo is not None:
        bad.append(f"bounds [{lo}, {hi}] with source ''")
    return bad


def check_tracks_jsonl(path: Path, rig_names: set[str]) -> dict:
    """Assert that ``path`` is a tracks.jsonl as the conventions define it; return counts of what it
    held (so a caller can require that the run exercised the fields)."""
    text = path.read_text()
    assert text.endswith("\n"), "the last line is not terminated"
    lines = text.splitlines()
    assert lines, f"{path} is empty"
    bad: list[str] = []
    counts = {"frames": len(lines), "tracks": 0, "ranged": 0, "bounded": 0, "velocity": 0, "ttc": 0,
              "camera_lists": 0, "sources": set()}
    prev = None
    ended: dict[int, int] = {}  # id -> the frame it was reported lost in
    for i, line in enumerate(lines, 1):
        rec = strict_loads(line)
        assert isinstance(rec, dict) and set(rec) == {"frame", "t_s", "tracks"}, f"line {i}: {line[:120]}"
        f, ts = rec["frame"], rec["t_s"]
        assert type(f) is int and type(ts) is float and isinstance(rec["tracks"], list), f"line {i}"
        if prev is not None:
            assert f > prev[0] and ts > prev[1], f"line {i}: frame {f} t_s {ts} after {prev}"
        prev = (f, ts)
        ids = [t.get("id") for t in rec["tracks"]]
        if len(ids) != len(set(ids)):
            bad.append(f"line {i}: an id twice in one frame: {ids}")
        for t in rec["tracks"]:
            bad += [f"line {i} id {t.get('id')}: {m}" for m in check_track(t, rig_names)]
            # "id: stable over the track's life"; "lost: reported once when the track ends"
            if t.get("id") in ended:
                bad.append(f"line {i}: id {t['id']} ({t.get('status')}) after it was reported lost in "
                           f"frame {ended[t['id']]}")
            elif t.get("status") == "lost":
                ended[t["id"]] = f
            counts["tracks"] += 1
            counts["ranged"] += t.get("range_m") is not None
            counts["bounded"] += t.get("range_min_m") is not None
            counts["velocity"] += t.get("velocity_world_mps") is not None
            counts["ttc"] += t.get("ttc_s") is not None
            counts["camera_lists"] += isinstance(t.get("camera"), list)
            counts["sources"].add(t.get("source"))
    assert not bad, f"{len(bad)} violations in {path}:\n" + "\n".join(bad[:20])
    return counts


def camchain_names(path: Path) -> set[str]:
    """The rig's camera names from a Kalibr camchain, by a plain YAML read."""
    d = yaml.safe_load(path.read_text())
    return {e.get("camera_name", k) for k, e in d.items()}


def documented_summary_keys() -> set[str]:
    """The names in backticks of docs/OUTPUTS.md's "`summary.json`" section."""
    import re

    text = (ROOT / "docs" / "OUTPUTS.md").read_text()
    section = text.partition("## `summary.json`")[2].split("\n## ", 1)[0]
    return set(re.findall(r"`([a-z_0-9]+)`", section))


def check_run_folder(out: Path, rig_names: set[str]) -> dict:
    """tracks.jsonl and, beside it, the resolved config and the summary JSON (every key of it named
    in docs/OUTPUTS.md)."""
    counts = check_tracks_jsonl(out / "tracks.jsonl", rig_names)
    summary = strict_loads((out / "summary.json").read_text())
    assert isinstance(summary, dict) and summary["frames"] == counts["frames"]
    undocumented = set(summary) - documented_summary_keys()
    assert not undocumented, f"summary.json keys not in docs/OUTPUTS.md: {sorted(undocumented)}"
    assert isinstance(yaml.safe_load((out / "config.resolved.yaml").read_text()), dict)
    return counts


# ------------------------------------------------------------------------- the strict reader itself
def test_the_reader_refuses_what_the_conventions_exclude(tmp_path):
    good = {"id": 1, "status": "confirmed", "camera": "cam0", "bearing_body": [0.6, 0.8, 0.0],
            "azimuth_deg": math.degrees(math.atan2(0.8, 0.6)), "elevation_deg": 0.0,
            "range_m": 5.0, "range_sigma_m": 0.5, "range_min_m": 1.0, "range_max_m": None,
            "position_body_m": [3.0, 4.0, 0.0], "velocity_world_mps": [0.0, 3.0, 4.0], "speed_mps": 5.0,
            "speed_sigma_mps": 0.1, "ttc_s": 2.0, "miss_distance_m": 1.5, "miss_distance_sigma_m": 0.2,
            "source": "mono+bounds", "label": "orb", "nis": None,
            "innovation": None, "gated": 0, "unobservable_reason": None}
    assert check_track(good, {"cam0"}) == []
    for change, what in [
        ({"azimuth_deg": -good["azimuth_deg"]}, "azimuth_deg"),  # y is left: +azimuth
        ({"bearing_body": [0.6, 0.8, 0.1]}, "norm"),
        ({"position_body_m": [3.0, -4.0, 0.0]}, "position_body_m"),
        ({"speed_mps": 7.0}, "speed_mps"),
        ({"ttc_s": -1.0}, "ttc_s"),
        ({"ttc_s": None}, "miss_distance_m"),
        ({"miss_distance_m": 6.0}, "miss_distance_m"),
        ({"source": "bounds+mono"}, "source"),
        ({"camera": ["cam0", "cam9"]}, "camera"),
        ({"status": "deleted"}, "status"),
        ({"range_min_m": 6.0, "range_max_m": 2.0}, "bounds"),
        ({"gated": True}, "gated"),
        ({"extra": 1}, "undocumented"),
    ]:
        assert any(what in m for m in check_track({**good, **change}, {"cam0"})), change
    p = tmp_path / "tracks.jsonl"
    lines = [{"frame": f, "t_s": f / 30, "tracks": [{**good, "status": st}]}
             for f, st in enumerate(("confirmed", "lost", "confirmed"))]
    p.write_text("".join(json.dumps(x) + "\n" for x in lines))
    with pytest.raises(AssertionError, match="id 1 \\(confirmed\\) after it was reported lost in frame 1"):
        check_tracks_jsonl(p, {"cam0"})
    p.write_text('{"frame": 0, "t_s": 0.0, "tracks": [{"range_m": NaN}]}\n')
    with pytest.raises(ValueError, match="NaN"):
        check_tracks_jsonl(p, {"cam0"})


# ---------------------------------------------------------------- real runs over simulated scenes
def _simulate_and_run(tmp_path: Path, scenario: str, resolution: str | None, cams: int) -> Path:
    from pipeline.cli import main

    sim = tmp_path / "sim"
    args = ["simulate", str(ROOT / "configs" / "scenarios" / f"{scenario}.yaml"), "--out", str(sim),
            "--frames", "20", "--no-progress"]
    assert main(args + (["--resolution", resolution] if resolution else [])) == 0
    out = tmp_path / "run"
    videos = [a for i in range(cams) for a in ("--video", str(sim / f"cam{i}.mkv"))]
    rc = main(["run", *videos, "--calibration", str(sim / "camchain.yaml"),
               "--trajectory", str(sim / "trajectory.tum"), "--out", str(out), "--no-progress"])
    assert rc == 0
    return out


@pytest.mark.parametrize(
    ("scenario", "resolution", "cams"),
    [
        pytest.param("ci_small", None, 1, id="mono"),
        pytest.param("stereo_flying", "640x360", 2, id="stereo"),
        pytest.param("wide_angle_beyond90", "640x360", 1, id="mono-wide-angle"),
    ],
)
def test_run_outputs_keep_the_conventions(tmp_path, scenario, resolution, cams):
    pytest.importorskip("trackers.frontend")
    out = _simulate_and_run(tmp_path, scenario, resolution, cams)
    names = camchain_names(tmp_path / "sim" / "camchain.yaml")
    assert len(names) == cams
    c = check_run_folder(out, names)
    # the runs exercised the fields checked (measured: mono 175 tracks, 68 ranged, 89 with bounds,
    # 10 with ttc_s; stereo 594 tracks, 335 ranged, 492 with bounds, 306 with ttc_s, 3 velocities,
    # 288 seen by both cameras)
    assert c["frames"] == 20 and c["ranged"] > 0 and c["bounded"] > 0 and c["ttc"] > 0
    if cams == 2:
        assert c["velocity"] > 0 and c["camera_lists"] > 0 and "mono+stereo" in c["sources"]
    else:
        assert "mono" in c["sources"]


# ------------------------------------------------------------------------------ import direction
def _imports(path: Path) -> list[tuple[int, str]]:
    """(line, top-level package) of every import in the module, at any depth (function-level too);
    relative imports resolve to the module's own package."""
    tree = ast.parse(path.read_text(), str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name.split(".")[0]) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            own = path.relative_to(ROOT).parts[0]
            out.append((node.lineno, own if node.level else (node.module or "").split(".")[0]))
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant):
            fn = getattr(node.func, "attr", getattr(node.func, "id", None))  # importlib.import_module
            if fn == "import_module" and isinstance(node.args[0].value, str):
                out.append((node.lineno, node.args[0].value.split(".")[0]))
    return out


def test_data_flows_one_way_in_the_imports():
    """CONVENTIONS.md "Names": estimators imports nothing from trackers or pipeline; trackers nothing
    from pipeline (every module, imports inside functions included)."""
    forbidden = {"estimators": {"trackers", "pipeline"}, "trackers": {"pipeline"}}
    bad = []
    n = 0
    for pkg, banned in forbidden.items():
        for f in sorted((ROOT / pkg).rglob("*.py")):
            n += 1
            bad += [f"{f.relative_to(ROOT)}:{ln} imports {mod}" for ln, mod in _imports(f) if mod in banned]
    assert n > 20 and not bad, "\n".join(bad)


# ------------------------------------------------------------------------ calibrate's camchain
def _kalibr_entry(e: dict) -> np.ndarray:
    """Check one camchain entry as Kalibr writes it (pinhole + equidistant); return its T_cam_imu."""
    assert e["camera_model"] == "pinhole" and e["distortion_model"] == "equidistant"
    assert len(e["intrinsics"]) == 4 and all(type(v) is float for v in e["intrinsics"])
    assert len(e["distortion_coeffs"]) == 4 and all(type(v) is float for v in e["distortion_coeffs"])
    assert len(e["resolution"]) == 2 and all(type(v) is int for v in e["resolution"])
    T = np.array(e["T_cam_imu"], dtype=float)
    assert T.shape == (4, 4) and np.allclose(T[3], [0, 0, 0, 1], atol=0)
    assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9) and np.linalg.det(T[:3, :3]) > 0
    return T


def test_calibrate_writes_a_kalibr_camchain_a_plain_yaml_reader_takes(tmp_path, capsys):
    """Stereo boards rendered through two known lenses -> `calibrate --right` -> the camchain by a
    plain YAML read: Kalibr's keys and types for both cameras, cam1's T_cn_cnm1 the pose of cam0 in
    cam1 (p_c1 = T_cn_cnm1 p_c0), which is T_cam_imu(cam1) T_cam_imu(cam0)^-1, and near the truth."""
    from test_calibrate import BOARD, POSES, TRUE, render_board

    from pipeline.cli import main

    left_dir, right_dir = tmp_path / "l", tmp_path / "r"
    left_dir.mkdir()
    right_dir.mkdir()
    # cam1 8 cm to the right of cam0 (+x of C), turned 2 degrees about y
    a = np.radians(2.0)
    R = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    t_c1_c0 = -R @ np.array([0.08, 0.0, 0.0])
    for i, (r, t) in enumerate(POSES):
        cv2.imwrite(str(left_dir / f"v{i}.png"), render_board(TRUE, r, t))
        Rb, _ = cv2.Rodrigues(np.asarray(r, dtype=float))
        rr, _ = cv2.Rodrigues(R @ Rb)
        cv2.imwrite(str(right_dir / f"v{i}.png"),
                    render_board(TRUE, rr.ravel(), R @ np.asarray(t, dtype=float) + t_c1_c0))
    out = tmp_path / "camchain.yaml"
    rc = main(["calibrate", str(left_dir / "*.png"), "--right", str(right_dir / "*.png"),
               "--board", f"{BOARD.cols}x{BOARD.rows}", "--square-m", str(BOARD.square_m), "--out", str(out)])
    assert rc == 0, capsys.readouterr().out
    d = yaml.safe_load(out.read_text())
    assert list(d) == ["cam0", "cam1"]
    T0, T1 = _kalibr_entry(d["cam0"]), _kalibr_entry(d["cam1"])
    assert "T_cn_cnm1" not in d["cam0"]
    T10 = np.array(d["cam1"]["T_cn_cnm1"], dtype=float)
    np.testing.assert_allclose(T10, T1 @ np.linalg.inv(T0), atol=1e-9)
    np.testing.assert_allclose(T10[:3, 3], t_c1_c0, atol=5e-3)
    np.testing.assert_allclose(T10[:3, :3], R, atol=5e-3)
    assert d["cam0"]["resolution"] == [TRUE.width, TRUE.height]
    assert d["cam0"]["intrinsics"][0] == pytest.approx(TRUE.fx, rel=5e-3)
