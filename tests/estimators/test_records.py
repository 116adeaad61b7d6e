"""Stage records: validation and the tracks.jsonl entry."""

import json

import numpy as np
import pytest

from estimators.errors import InputError
from estimators.records import CameraView, ObstacleObservation, TrackReport, azimuth_elevation_deg


@pytest.mark.parametrize(
    "b_B, az, el",
    [([1, 0, 0], 0.0, 0.0), ([0, 1, 0], 90.0, 0.0), ([-1, 0, 0], 180.0, 0.0), ([0, 0, 1], 0.0, 90.0),
     ([1, -1, 0], -45.0, 0.0)],
)
def test_azimuth_elevation_flu(b_B, az, el):
    a, e = azimuth_elevation_deg(np.array(b_B, float))
    assert a == pytest.approx(az) and e == pytest.approx(el)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(b_C=[0, 0, 2]), "unit 3-vector"),
        (dict(b_C=[0, np.nan, 1]), "unit 3-vector"),
        (dict(sigma_rad=0.0), "positive angle"),
        (dict(feature_ids=[1, 2], feature_b_C=[[0, 0, 1]]), "differ in length"),
    ],
)
def test_camera_view_validation(kwargs, match):
    base = dict(camera="cam0", b_C=[0, 0, 1], uv=[1, 1], sigma_rad=0.01)
    base.update(kwargs)
    with pytest.raises(InputError, match=match):
        CameraView(**base)


def test_observation_rejects_bad_status_and_duplicate_cameras():
    v = CameraView("cam0", [0, 0, 1], [0, 0], 0.01)
    with pytest.raises(InputError, match="status"):
        ObstacleObservation(1, 0, 0.0, "alive", (v,))
    with pytest.raises(InputError, match="one view per camera"):
        ObstacleObservation(1, 0, 0.0, "confirmed", (v, v))


def test_track_report_json_has_no_nan_and_round_trips():
    r = TrackReport(
        id=3, status="confirmed", camera=["cam0", "cam1"], bearing_body=np.array([0.0, 1.0, 0.0]),
        range_m=float("nan"), range_sigma_m=0.1, position_body_m=np.array([0.0, np.inf, 0.0]),
        source="stereo",
    )
    d = r.to_json()
    assert d["range_m"] is None and d["position_body_m"] is None
    assert d["azimuth_deg"] == pytest.approx(90.0)
    assert json.loads(json.dumps(d, allow_nan=False)) == d
