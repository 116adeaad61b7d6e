"""Stage records: validation and the tracks.jsonl entry."""

import json

import numpy as np
import pytest

from estimators.errors import InputError
from estimators.records import CameraView, ObstacleObservation, TrackReport


@pytest.mark.parametrize(
    "b_B, az, el",
    [([1, 0, 0], 0.0, 0.0), ([0, 1, 0], 90.0, 0.0), ([-1, 0, 0], 180.0, 0.0), ([0, 0, 1], 0.0, 90.0),
     ([1, -1, 0], -45.0, 0.0)],
)
def test_azimuth_elevation_flu(b_B, az, el):
    b = np.array(b_B, float)
    d = TrackReport(id=1, status="confirmed", camera="cam0", bearing_body=b / np.linalg.norm(b)).to_json()
    assert d["azimuth_deg"] == pytest.approx(az) and d["elevation_deg"] == pytest.approx(el)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(b_C=[0, 0, 2]), "unit 3-vector"),
        (dict(b_C=[0, np.nan, 1]), "unit 3-vector"),
        (dict(sigma_rad=0.0), "positive angle"),
        (dict(feature_ids=[1, 2], feature_b_C=[[0, 0, 1]]), "differ in length"),
        (dict(uv=[np.nan, 1.0]), "finite pixel"),
        (dict(uv=np.array([1.0, np.inf])), "finite pixel"),
        (dict(uv=[1.0, 2.0, 3.0]), "finite pixel"),
        # entries that are not numbers: an InputError naming the field, not numpy's bare ValueError
        (dict(b_C=["a", "b", "c"]), r"CameraView.b_C: .*not numbers"),
        (dict(uv=["x", "y"]), r"CameraView.uv: .*not numbers"),
        (dict(uv={"u": 1}), r"CameraView.uv: .*not numbers"),
        (dict(sigma_rad="wide"), "positive angle"),
        (dict(sigma_rad=None), "positive angle"),
        (dict(feature_ids=["q"], feature_b_C=[[0, 0, 1]]), r"CameraView.feature_ids: .*not numbers"),
        (dict(feature_ids=[1], feature_b_C=[["a", 0, 1]]), r"CameraView.feature_b_C: .*not numbers"),
        # beyond float64 / int64 (Python's or numpy's bare OverflowError before)
        (dict(b_C=[10**400, 0, 0]), r"CameraView.b_C: .*out of range"),
        (dict(uv=[10**400, 0]), r"CameraView.uv: .*out of range"),
        (dict(sigma_rad=10**400), "positive angle"),
        (dict(feature_ids=[2**70], feature_b_C=[[0, 0, 1]]), r"CameraView.feature_ids: .*out of range"),
        (dict(feature_ids=[1e30], feature_b_C=[[0, 0, 1]]), r"CameraView.feature_ids: .*out of range"),
        (dict(feature_ids=[1], feature_b_C=[[10**400, 0, 1]]), r"CameraView.feature_b_C: .*out of range"),
        # ids that are not whole numbers (numpy cut 1.5 to 1 and NaN to -2**63 before, silently)
        (dict(feature_ids=[1.5], feature_b_C=[[0, 0, 1]]), r"CameraView.feature_ids: .*not whole numbers"),
        (dict(feature_ids=np.array([np.nan]), feature_b_C=[[0, 0, 1]]),
         r"CameraView.feature_ids: .*not whole numbers"),
    ],
)
def test_camera_view_validation(kwargs, match):
    base = dict(camera="cam0", b_C=[0, 0, 1], uv=[1, 1], sigma_rad=0.01)
    base.update(kwargs)
    with pytest.raises(InputError, match=match):
        CameraView(**base)


def test_a_camera_view_without_a_pixel_says_so():
    """A view whose representative bearing does not project into the image (beyond the lens's
    field) carries uv None, not a made-up pixel; a pixel given is kept as float64 (2,)."""
    assert CameraView("cam0", [0, 0, -1], None, 0.01).uv is None
    v = CameraView("cam0", [0, 0, 1], [3, 4], 0.01)
    assert v.uv.dtype == np.float64 and v.uv.tolist() == [3.0, 4.0]


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("as_float64", [True, False])
def test_camera_view_rejects_a_non_finite_feature_bearing(bad, as_float64):
    """Any NaN or inf among the member-feature bearings is an InputError, on the float64 fast path and
    on the converting path (a list)."""
    fb = np.tile([0.0, 0.0, 1.0], (12, 1))
    fb[7, 1] = bad
    with pytest.raises(InputError, match="feature_b_C"):
        CameraView("cam0", [0, 0, 1], [1, 1], 0.01, np.arange(12), fb if as_float64 else fb.tolist())


def test_camera_view_accepts_huge_finite_feature_values_and_other_byte_orders():
    """Values whose squares overflow float64 (1e200) are finite: no error. A big-endian array takes the
    converting path and comes out as native float64 / int64."""
    fb = np.array([[1e200, 0.0, 1.0], [0.0, 0.0, 1.0]])
    with np.errstate(over="ignore"):  # the sum of squares overflows (numpy would warn), then decides
        CameraView("cam0", [0, 0, 1], [1, 1], 0.01, np.arange(2), fb)
    big_endian = np.array([0, 0, 1], ">f8"), np.arange(2, dtype=">i8"), fb.astype(">f8")
    v = CameraView("cam0", big_endian[0], [1, 1], 0.01, big_endian[1], big_endian[2])
    assert v.b_C.dtype == np.float64 and v.feature_ids.dtype == np.int64 and v.feature_b_C[0, 0] == 1e200


def test_observation_rejects_a_non_finite_or_non_numeric_time():
    v = CameraView("cam0", [0, 0, 1], [0, 0], 0.01)
    for t_s in (np.nan, np.float64(np.inf), "0.1", None):
        with pytest.raises(InputError, match="finite time"):
            ObstacleObservation(1, 0, t_s, "confirmed", (v,))
    assert ObstacleObservation(1, 0, np.float32(0.5), "confirmed", (v,)).t_s == 0.5


def test_camera_view_keeps_numbers_it_reads():
    """sigma_rad is kept as the float it was read as (a string '0.01' was stored as the string before,
    to fail later in the fusion's arithmetic); whole-number float ids become int64."""
    v = CameraView("cam0", [0, 0, 1], [1, 1], "0.01", np.array([3.0, 4.0]), [[0, 0, 1], [0, 0, 1]])
    assert type(v.sigma_rad) is float and v.sigma_rad == 0.01
    assert v.feature_ids.dtype == np.int64 and v.feature_ids.tolist() == [3, 4]


def test_observation_rejects_a_time_beyond_float64_an_id_not_an_integer_and_views_not_camera_views():
    v = CameraView("cam0", [0, 0, 1], [0, 0], 0.01)
    with pytest.raises(InputError, match="finite time"):
        ObstacleObservation(1, 0, 10**400, "confirmed", (v,))  # (OverflowError before)
    for tid in ("x", 1.5, None, True):
        with pytest.raises(InputError, match="ObstacleObservation.track_id: expected an integer id"):
            ObstacleObservation(tid, 0, 0.0, "confirmed", (v,))
    for views in (None, 5, ("cam0",), [v, "cam1"]):  # (TypeError, AttributeError or accepted before)
        with pytest.raises(InputError, match="ObstacleObservation.views: expected a tuple of CameraView"):
            ObstacleObservation(1, 0, 0.0, "confirmed", views)
    assert ObstacleObservation(np.int64(7), 0, 0.0, "lost", ()).track_id == 7


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


def test_records_keep_their_dataclass_behaviour_with_hand_written_inits():
    """Defaults, immutability, equality and keyword construction as the generated __init__ gave them."""
    import dataclasses

    v = CameraView("cam0", [0.0, 0.0, 1.0], [1, 2], 0.01)
    assert v.feature_ids.dtype == np.int64 and v.feature_ids.shape == (0,)
    assert v.feature_b_C.shape == (0, 3) and v.uv.dtype == np.float64
    with pytest.raises(dataclasses.FrozenInstanceError):
        v.camera = "cam1"
    a = ObstacleObservation(track_id=1, frame=2, t_s=0.5, status="lost", views=())
    b = ObstacleObservation(1, 2, 0.5, "lost", ())
    assert a == b and a.label == "orb" and a.attributes == {}
    a.attributes["x"] = 1  # each record has its own attributes dict, never a shared default
    assert b.attributes == {}
    assert [f.name for f in dataclasses.fields(CameraView)] == [
        "camera", "b_C", "uv", "sigma_rad", "feature_ids", "feature_b_C"]
