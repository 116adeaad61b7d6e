"""Sinks: tracks.jsonl flushed per frame and NaN-free, summary JSON, annotation, plots."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from test_run_support import H, W, mono_rig

from estimators.records import TrackReport
from pipeline.sinks import Annotator, TracksWriter, make_plots, read_tracks, to_plain, write_json


def _report(i, r):
    return TrackReport(
        id=i,
        status="confirmed",
        camera="cam0",
        bearing_body=np.array([1.0, 0.0, 0.0]),
        range_m=r,
        range_sigma_m=0.5,
        range_min_m=float("nan"),
        range_max_m=float("inf"),
        position_body_m=np.array([r, 0.0, 0.0]),
        attributes={"score": float("nan")},
    )


def test_each_line_is_readable_while_the_writer_is_open(tmp_path):
    w = TracksWriter(tmp_path / "tracks.jsonl")
    for k in range(3):
        w.write(k, 0.1 * k, [_report(1, 10.0 - k)])
        # a second reader sees the line at once: flushed per frame
        lines = (tmp_path / "tracks.jsonl").read_text().splitlines()
        assert len(lines) == k + 1
        rec = json.loads(lines[-1])
        assert rec["frame"] == k and rec["t_s"] == pytest.approx(0.1 * k)
        assert rec["tracks"][0]["range_m"] == 10.0 - k
    w.close()


def test_no_nan_or_infinity_in_output(tmp_path):
    w = TracksWriter(tmp_path / "tracks.jsonl")
    w.write(0, float("nan"), [_report(1, float("nan"))])
    w.close()
    text = (tmp_path / "tracks.jsonl").read_text()
    assert "NaN" not in text and "Infinity" not in text
    rec = json.loads(text)
    t = rec["tracks"][0]
    assert (
        rec["t_s"] is None and t["range_m"] is None and t["range_min_m"] is None and t["range_max_m"] is None
    )
    assert t["attributes"]["score"] is None


def test_write_json_is_nan_free_and_plain(tmp_path):
    p = write_json(tmp_path / "s.json", {"a": np.float32(1.5), "b": np.arange(3), "c": float("nan")})
    assert json.loads(p.read_text()) == {"a": 1.5, "b": [0, 1, 2], "c": None}
    assert to_plain({"x": (np.int64(2), np.bool_(True))}) == {"x": [2, True]}


def test_read_tracks_skips_a_cut_off_last_line(tmp_path):
    p = tmp_path / "tracks.jsonl"
    p.write_text('{"frame": 0, "t_s": 0.0, "tracks": []}\n{"frame": 1, "t_')
    assert [r["frame"] for r in read_tracks(p)] == [0]


def test_annotator_draws_at_the_projected_pixel():
    rig = mono_rig()
    img = np.zeros((H, W), np.uint8)
    t = to_plain(_report(1, 10.0))
    out = Annotator(rig).draw({"cam0": img}, [t])
    assert out.shape == (H, W, 3)
    # straight ahead projects to the principal point; the marker circle (radius 6) surrounds it
    cx, cy = (W - 1) / 2, (H - 1) / 2
    ring = out[int(round(cy)) - 8 : int(round(cy)) + 9, int(round(cx)) - 8 : int(round(cx)) + 9]
    assert ring.any()
    assert not out[int(round(cy)), int(round(cx))].any()  # the circle is hollow


def test_plots_written(tmp_path):
    w = TracksWriter(tmp_path / "tracks.jsonl")
    for k in range(10):
        w.write(k, 0.1 * k, [_report(1, 10.0 - k), _report(2, 20.0)])
    w.close()
    files = make_plots(tmp_path / "tracks.jsonl", tmp_path)
    assert [f.name for f in files] == ["range_over_time.png", "polar_map.png"]
    for f in files:
        assert f.stat().st_size > 1000 and f.read_bytes()[:4] == b"\x89PNG"


def test_velocity_arrow_points_where_the_obstacle_goes():
    from test_run_support import small_model

    from estimators.egomotion import ConstantVelocity
    from estimators.rig import mono_forward_rig

    rig = mono_forward_rig(small_model(640, 480))
    t = to_plain(_report(1, 5.0))
    t["velocity_world_mps"] = [0.0, 2.0, 0.0]  # to the body's left (+y): image left for a forward camera
    out = Annotator(rig, ConstantVelocity(0.0)).draw({"cam0": np.zeros((480, 640), np.uint8)}, [t], t_s=0.0)
    cx, cy = int(round(319.5)), int(round(239.5))
    row = out[cy - 1 : cy + 2].max(axis=0).max(axis=1)  # brightest channel along the centre row
    assert row[cx - 30 : cx - 10].min() > 0  # the arrow's shaft, left of the marker
    assert row[cx + 10 : cx + 60].max() == 0  # nothing to the right


def test_report_dicts_equal_to_json_field_for_field():
    """The writer's batched conversion gives exactly TrackReport.to_json() (the records' own code)."""
    from pipeline.sinks import report_dicts

    rng = np.random.default_rng(3)
    reps = []
    for i in range(20):
        b = rng.normal(size=3)
        reps.append(
            TrackReport(
                id=np.int64(i),
                status=("tentative", "confirmed", "lost")[i % 3],
                camera="cam0" if i % 2 else ["cam0", "cam1"],
                bearing_body=b / np.linalg.norm(b),
                range_m=None if i % 4 == 0 else np.float64(rng.uniform(1, 30)),
                range_sigma_m=None if i % 4 == 0 else 0.3,
                range_min_m=None if i % 5 == 0 else float(i),
                range_max_m=None if i % 5 == 0 else 2.0 * i + 1,
                position_body_m=None if i % 4 == 0 else rng.normal(size=3),
                velocity_world_mps=None if i % 3 else rng.normal(size=3),
                speed_mps=None if i % 3 else 1.5,
                ttc_s=None if i % 2 else 3.0,
                source="mono+bounds",
                nis=None if i % 2 else 0.7,
                innovation=None if i % 2 else np.array([0.1, -0.2]),
                gated=i,
                unobservable_reason=None if i % 4 else "no parallax yet",
                attributes={} if i % 2 else {"heading": 1.0},
            )
        )
    got = report_dicts(reps)
    want = [r.to_json() for r in reps]
    assert got == want
    assert json.dumps(got) == json.dumps(want)  # same types too (int ids, float values)
    assert report_dicts([want[0]]) == [want[0]]  # dicts pass through


def test_writer_line_for_a_nan_report_is_to_json_s(tmp_path):
    """A non-finite value sends the frame down the slow path: the line then equals to_json()'s."""
    r = _report(1, 5.0)  # NaN range_min_m, inf range_max_m, NaN in attributes
    w = TracksWriter(tmp_path / "tracks.jsonl")
    w.write(0, 0.0, [r])
    w.close()
    rec = json.loads((tmp_path / "tracks.jsonl").read_text())
    want = to_plain(r.to_json())
    assert rec["tracks"] == [want] and want["range_min_m"] is None and want["range_max_m"] is None


def test_every_field_of_a_tracks_jsonl_entry_is_documented_in_outputs_md():
    """docs/OUTPUTS.md's table names every key a track entry has (speed_sigma_mps was missing)."""
    import re
    from pathlib import Path

    import numpy as np

    from estimators.records import TrackReport

    doc = (Path(__file__).resolve().parents[2] / "docs" / "OUTPUTS.md").read_text()
    lines = doc.split("## `tracks.jsonl`", 1)[1].splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith("| field |"))
    rows = list(itertools.takewhile(lambda ln: ln.startswith("|"), lines[start + 2:]))  # the table alone
    # the names in its field column
    documented = {name for row in rows for name in re.findall(r"`(\w+)`", row.split("|")[1])}
    keys = TrackReport(1, "confirmed", "cam0", np.array([1.0, 0.0, 0.0])).to_json()
    assert len(rows) > 10 and [k for k in keys if k not in documented] == []
