"""Camera models: conventions pinned by closed forms, cv2.fisheye and numerical derivatives."""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
import pytest

from estimators.cameras import (
    CAMERA_MODELS,
    CameraModel,
    DoubleSphere,
    Equidistant,
    Eucm,
    KannalaBrandt,
    make_camera_model,
)
from estimators.errors import CalibrationError, InputError

# One example per registered model. Image large enough to hold the whole lens circle, so that
# the round trip over the circle runs with the default within_image=True.
EXAMPLES: dict[str, CameraModel] = {
    "equidistant": Equidistant(fx=300.0, fy=300.0, cx=799.5, cy=639.5, width=1600, height=1280,
                               max_angle_rad=math.radians(100.0)),
    "kannala_brandt": KannalaBrandt(fx=280.0, fy=281.0, cx=801.2, cy=638.9, width=1600, height=1280,
                                    k1=0.02, k2=-0.004, k3=0.0008, k4=-0.0001,
                                    max_angle_rad=math.radians(110.0)),
    # 195-degree lens: the model's own limit (acos(-w2) = 122 deg) is capped at 97.5 degrees.
    "double_sphere": DoubleSphere(fx=170.0, fy=171.0, cx=800.3, cy=640.7, width=1600, height=1280,
                                  xi=-0.2, alpha=0.6, max_angle_rad=math.radians(97.5)),
    "eucm": Eucm(fx=340.0, fy=339.0, cx=799.0, cy=641.0, width=1600, height=1280,
                 alpha=0.6, beta=1.1, max_angle_rad=math.radians(100.0)),
}


def test_every_registered_model_has_an_example():
    assert set(CAMERA_MODELS) == set(EXAMPLES)
    assert {"equidistant", "kannala_brandt", "double_sphere", "eucm"} <= set(CAMERA_MODELS)


@pytest.fixture(params=sorted(CAMERA_MODELS))
def model(request) -> CameraModel:
    return EXAMPLES[request.param]


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _bearings_at(theta_rad: float, n: int = 64) -> np.ndarray:
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.stack([np.sin(theta_rad) * np.cos(phi), np.sin(theta_rad) * np.sin(phi),
                     np.full(n, np.cos(theta_rad))], axis=1)


def _angle(a, b):
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1))


def test_principal_point_is_the_optical_axis(model):
    b, valid = model.pixel_to_bearing(np.array([[model.cx, model.cy]]))
    assert valid.all()
    np.testing.assert_allclose(b[0], [0.0, 0.0, 1.0], atol=1e-15)
    uv, valid = model.bearing_to_pixel(np.array([[0.0, 0.0, 2.5]]))
    assert valid.all()
    np.testing.assert_allclose(uv[0], [model.cx, model.cy], atol=1e-12)


def test_pixel_round_trip_over_the_image_circle_including_the_rim(model):
    cx, cy, radius = model.image_circle()
    assert cx == model.cx and cy == model.cy and radius > 100
    # concentric rings up to the rim (radius is the inscribed circle, so every ring is inside the lens)
    rings = np.linspace(0.0, radius, 200)
    phi = np.linspace(0, 2 * np.pi, 181)
    R, P = np.meshgrid(rings, phi)
    uv = np.stack([cx + R.ravel() * np.cos(P.ravel()), cy + R.ravel() * np.sin(P.ravel())], axis=1)
    b, valid = model.pixel_to_bearing(uv)
    assert valid.all()
    np.testing.assert_allclose(np.linalg.norm(b, axis=1), 1.0, atol=1e-14)
    uv2, valid2 = model.bearing_to_pixel(b)
    assert valid2.all()
    assert np.abs(uv2 - uv).max() < 1e-9


@pytest.mark.parametrize("theta_deg", [0.0, 45.0, 89.999, 90.0, 90.001, "limit"])
def test_bearing_round_trip_at_90_degrees_and_the_lens_limit(model, theta_deg):
    theta = model.max_angle_rad if theta_deg == "limit" else math.radians(theta_deg)
    if theta > model.max_angle_rad:
        pytest.skip("beyond this example's lens")
    b = _bearings_at(theta)
    uv, valid = model.bearing_to_pixel(b)
    assert valid.all()
    b2, valid2 = model.pixel_to_bearing(uv)
    assert valid2.all()
    assert _angle(b, b2).max() < 1e-9


def test_double_sphere_195_degree_lens_limit():
    m = EXAMPLES["double_sphere"]
    assert math.degrees(m.max_angle_rad) == pytest.approx(97.5)
    b = _bearings_at(math.radians(97.5))
    uv, valid = m.bearing_to_pixel(b)
    assert valid.all()
    b2, _ = m.pixel_to_bearing(uv)
    assert _angle(b, b2).max() < 1e-9
    # just beyond the limit: invalid, zeros
    uv, valid = m.bearing_to_pixel(_bearings_at(math.radians(97.6)))
    assert not valid.any() and not uv.any()


def test_double_sphere_natural_limit_is_acos_minus_w2():
    # Usenko et al. 2018 (validity of the projection): w1 = (1-alpha)/alpha for alpha > 0.5,
    # w2 = (w1 + xi)/sqrt(2 w1 xi + xi^2 + 1), domain z > -w2 |b|.
    xi, alpha = -0.2, 0.6
    w1 = (1 - alpha) / alpha
    w2 = (w1 + xi) / math.sqrt(2 * w1 * xi + xi * xi + 1)
    m = DoubleSphere(fx=170.0, fy=170.0, cx=320.0, cy=240.0, width=640, height=480, xi=xi, alpha=alpha)
    assert m.max_angle_rad == pytest.approx(math.acos(-w2), abs=1e-12)


def test_eucm_natural_limit_matches_its_validity_condition():
    # z > -w d, d = sqrt(beta (x^2 + y^2) + z^2): bisect on theta for the boundary, independently.
    alpha, beta = 0.7, 1.3
    w = (1 - alpha) / alpha
    lo, hi = math.pi / 2, math.pi
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        s, c = math.sin(mid), math.cos(mid)
        if c > -w * math.sqrt(beta * s * s + c * c):
            lo = mid
        else:
            hi = mid
    m = Eucm(fx=300.0, fy=300.0, cx=320.0, cy=240.0, width=640, height=480, alpha=alpha, beta=beta)
    assert m.max_angle_rad == pytest.approx(lo, abs=1e-12)


def test_kannala_brandt_default_limit_is_where_theta_d_stops_increasing():
    # theta_d = theta (1 + k1 theta^2): d theta_d/d theta = 1 + 3 k1 theta^2 = 0 at theta = sqrt(-1/(3 k1))
    m = KannalaBrandt(fx=300.0, fy=300.0, cx=320.0, cy=240.0, width=640, height=480, k1=-0.1)
    assert m.max_angle_rad == pytest.approx(math.sqrt(1 / 0.3), abs=1e-12)
    capped = KannalaBrandt(fx=300.0, fy=300.0, cx=320.0, cy=240.0, width=640, height=480, k1=-0.1,
                           max_angle_rad=1.2)
    assert capped.max_angle_rad == 1.2
    # no distortion: monotonic everywhere, limit just below pi
    assert KannalaBrandt(fx=1.0, fy=1.0, cx=0.0, cy=0.0, width=4, height=4).max_angle_rad == pytest.approx(
        math.pi, abs=1e-5)


def test_jacobians_match_central_differences(model):
    rng = np.random.default_rng(1)
    theta = rng.uniform(0.0, model.max_angle_rad * 0.97, 300)
    phi = rng.uniform(0, 2 * np.pi, 300)
    scale = rng.uniform(0.5, 3.0, 300)[:, None]  # non-unit inputs: d uv/d b scales with 1/|b|
    b = scale * np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=1)
    J = model.bearing_to_pixel_jacobian(b)
    h = 1e-6
    Jn = np.stack([(model.bearing_to_pixel(b + h * e)[0] - model.bearing_to_pixel(b - h * e)[0]) / (2 * h)
                   for e in np.eye(3)], axis=2)
    np.testing.assert_allclose(J, Jn, rtol=1e-6, atol=1e-4)  # px per unit; |J| ~ 100..1000

    uv, valid = model.bearing_to_pixel(b)
    assert valid.all()
    Ju = model.pixel_to_bearing_jacobian(uv)
    hp = 1e-3
    Jun = np.stack([(model.pixel_to_bearing(uv + hp * e)[0]
                     - model.pixel_to_bearing(uv - hp * e)[0]) / (2 * hp)
                    for e in np.eye(2)], axis=2)
    np.testing.assert_allclose(Ju, Jun, rtol=1e-5, atol=1e-9)  # per px; |Ju| ~ 1e-3
    # tangent to the sphere
    bu, _ = model.pixel_to_bearing(uv)
    assert np.abs(np.einsum("ni,nij->nj", bu, Ju)).max() < 1e-12


def test_jacobians_on_the_optical_axis_hand_computed(model):
    # On the axis every model is locally a pinhole with focal length f_eff: theta models and EUCM
    # (D = alpha + (1 - alpha) = 1) have f_eff = fx; double sphere has D = 1 + xi -> fx / (1 + xi).
    scale = 1.0 / (1.0 + model.xi) if model.name == "double_sphere" else 1.0
    J = model.bearing_to_pixel_jacobian(np.array([[0.0, 0.0, 2.0]]))[0]
    np.testing.assert_allclose(J, [[model.fx * scale / 2, 0, 0], [0, model.fy * scale / 2, 0]], rtol=1e-12,
                               atol=1e-12)
    Ju = model.pixel_to_bearing_jacobian(np.array([[model.cx, model.cy]]))[0]
    np.testing.assert_allclose(Ju, [[1 / (model.fx * scale), 0], [0, 1 / (model.fy * scale)], [0, 0]],
                               rtol=1e-12, atol=1e-15)


def test_invalid_rows_are_zero_and_flagged_never_nan(model):
    b = np.array([
        [0.0, 0.0, 1.0],
        [np.nan, 0.0, 1.0],
        [np.inf, 0.0, 1.0],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, -1.0],  # straight back: beyond every example's lens
    ])
    uv, valid = model.bearing_to_pixel(b)
    assert valid.tolist() == [True, False, False, False, False]
    assert np.all(np.isfinite(uv)) and not uv[1:].any()
    J = model.bearing_to_pixel_jacobian(b)
    assert np.all(np.isfinite(J)) and not J[1:].any()

    uv = np.array([[model.cx, model.cy], [np.nan, 3.0], [-np.inf, 3.0], [-5.0, 10.0],
                   [10.0, model.height + 1.0]])
    b, valid = model.pixel_to_bearing(uv)
    assert valid.tolist() == [True, False, False, False, False]
    assert np.all(np.isfinite(b)) and not b[1:].any()
    Ju = model.pixel_to_bearing_jacobian(uv)
    assert np.all(np.isfinite(Ju)) and not Ju[1:].any()
    # outside the image but inside the lens: valid only when asked not to check the image
    small = dataclasses.replace(model, width=model.width // 4, height=model.height // 4)
    centre = np.array([[model.cx, model.cy]])
    assert not small.pixel_to_bearing(centre)[1].any()
    assert small.pixel_to_bearing(centre, within_image=False)[1].all()
    assert not small.bearing_to_pixel(np.array([[0.0, 0.0, 1.0]]))[1].any()
    assert small.bearing_to_pixel(np.array([[0.0, 0.0, 1.0]]), within_image=False)[1].all()


def test_a_rows_pixel_does_not_depend_on_the_other_rows(model):
    """bearing_to_pixel works row by row: each direction's pixel and flag are the same bit for bit
    whether every row of the call is valid (projected at once) or invalid rows are mixed in (the
    valid ones gathered, projected and scattered back), also for rows outside the image."""
    rng = np.random.default_rng(7)
    b = rng.normal(size=(60, 3))
    b[:, 2] = np.abs(b[:, 2]) + 0.2  # ahead: inside every example's lens
    b[:4, :2] = 0.0  # on the optical axis (rho = 0)
    b *= rng.uniform(0.1, 10.0, size=(60, 1))  # any length
    mixed = np.insert(b, [0, 17, 60], [[np.nan, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, -1.0]], axis=0)
    keep = np.ones(len(mixed), bool)
    keep[[0, 18, 62]] = False
    small = dataclasses.replace(model, width=model.width // 2, height=model.height // 2)
    for m in (model, small):  # (small: part of the rows outside its image)
        for within in (True, False):
            uv, ok = m.bearing_to_pixel(b, within_image=within)
            uv_m, ok_m = m.bearing_to_pixel(mixed, within_image=within)
            assert ok_m[keep].tolist() == ok.tolist() and not ok_m[~keep].any()
            assert uv_m[keep].tobytes() == uv.tobytes() and not uv_m[~keep].any()
    assert not small.bearing_to_pixel(b)[1].all() and small.bearing_to_pixel(b)[1].any()


def test_pixels_beyond_the_lens_circle_are_invalid(model):
    cx, cy, r = model.image_circle()
    big = max(model.width, model.height) * 10.0
    uv = np.array([[cx + big, cy], [cx, cy - big]])
    b, valid = model.pixel_to_bearing(uv, within_image=False)
    assert not valid.any() and not b.any()


def test_wrong_shapes_raise_input_error(model):
    with pytest.raises(InputError, match=r"expected an array of shape \(N, 2\)"):
        model.pixel_to_bearing(np.zeros((3, 3)))
    with pytest.raises(InputError, match=r"\(N, 3\)"):
        model.bearing_to_pixel(np.zeros(3))


def test_empty_input(model):
    b, valid = model.pixel_to_bearing(np.zeros((0, 2)))
    assert b.shape == (0, 3) and valid.shape == (0,)
    assert model.bearing_to_pixel_jacobian(np.zeros((0, 3))).shape == (0, 2, 3)


def test_params_rebuild_the_same_model(model):
    again = make_camera_model(model.name, **model.params())
    assert again == model


def test_scaled_keeps_the_lens_and_the_pixel_centre_convention(model):
    half = model.scaled(0.5)
    assert (half.width, half.height) == (model.width // 2, model.height // 2)
    b = _unit(np.array([[0.3, -0.2, 1.0], [1.0, 0.5, 0.2], [-0.7, 0.1, 0.4]]))
    uv, _ = model.bearing_to_pixel(b)
    uv_half, valid = half.bearing_to_pixel(b)
    assert valid.all()
    # pixel edges scale: (u + 0.5) * f - 0.5
    np.testing.assert_allclose(uv_half, (uv + 0.5) * 0.5 - 0.5, atol=1e-9)


def test_equidistant_thesis_linear_scale():
    # Thesis sec. 4.1.3: every 1.2 (cm on its scaled print) corresponds to 10 degrees.
    deg_per_unit = 10.0 / 1.2
    m = Equidistant.from_deg_per_px(deg_per_unit, width=41, height=31)
    assert (m.cx, m.cy) == (20.0, 15.0)
    # 30 degrees to the right of the axis (in the x-z plane) -> r = 30 / (10/1.2) = 3.6 units
    b = np.array([[math.sin(math.radians(30)), 0.0, math.cos(math.radians(30))]])
    uv, valid = m.bearing_to_pixel(b)
    assert valid.all()
    np.testing.assert_allclose(uv[0], [20.0 + 3.6, 15.0], atol=1e-12)
    # 90 degrees straight down the image (+y of C): r = 10.8 units
    uv, _ = m.bearing_to_pixel(np.array([[0.0, 1.0, 0.0]]))
    np.testing.assert_allclose(uv[0], [20.0, 15.0 + 10.8], atol=1e-12)
    # and back: 1.2 units off the centre is 10 degrees off the axis
    b, _ = m.pixel_to_bearing(np.array([[20.0 - 1.2, 15.0]]))
    ten = math.radians(10)
    np.testing.assert_allclose(b[0], [-math.sin(ten), 0.0, math.cos(ten)], atol=1e-12)


@pytest.mark.parametrize(
    "model, radius",
    [
        # alpha = 0 (and xi = 0): the pinhole, r = f tan(theta)
        (DoubleSphere(fx=200.0, fy=200.0, cx=500.0, cy=400.0, width=1000, height=800, xi=0.0, alpha=0.0),
         lambda th: 200.0 * math.tan(th)),
        (Eucm(fx=200.0, fy=200.0, cx=500.0, cy=400.0, width=1000, height=800, alpha=0.0, beta=1.0),
         lambda th: 200.0 * math.tan(th)),
        # alpha = 0.5, beta = 1 (EUCM) or xi = 0 (DS): D = (1 + cos theta)/2 -> stereographic 2 f tan(theta/2)
        (Eucm(fx=200.0, fy=200.0, cx=500.0, cy=400.0, width=1000, height=800, alpha=0.5, beta=1.0),
         lambda th: 400.0 * math.tan(th / 2)),
        (DoubleSphere(fx=200.0, fy=200.0, cx=500.0, cy=400.0, width=1000, height=800, xi=0.0, alpha=0.5),
         lambda th: 400.0 * math.tan(th / 2)),
        # xi = 1, alpha = 0 (DS): D = 1 + cos theta -> f tan(theta/2)
        (DoubleSphere(fx=200.0, fy=200.0, cx=500.0, cy=400.0, width=1000, height=800, xi=1.0, alpha=0.0),
         lambda th: 200.0 * math.tan(th / 2)),
    ],
)
def test_double_sphere_and_eucm_special_cases_are_classic_projections(model, radius):
    for deg in (10.0, 45.0, 80.0, 120.0):
        th = math.radians(deg)
        b = np.array([[0.0, math.sin(th), math.cos(th)]])  # straight down the image (+y of C)
        uv, valid = model.bearing_to_pixel(b, within_image=False)
        if deg >= 90.0 and radius(math.radians(89.0)) > 10000:  # the pinhole cannot image it
            assert not valid.any()
            continue
        assert valid.all()
        np.testing.assert_allclose(uv[0], [500.0, 400.0 + radius(th)], rtol=1e-12)
        b2, valid2 = model.pixel_to_bearing(uv, within_image=False)
        assert valid2.all() and _angle(b, b2).max() < 1e-12


def test_kannala_brandt_beyond_90_degrees_hand_computed():
    # theta = 120 deg about +x: theta_d = theta (1 + k1 theta^2), u = cx + fx theta_d
    k1 = 0.01
    m = KannalaBrandt(fx=200.0, fy=200.0, cx=500.0, cy=400.0, width=1000, height=800, k1=k1)
    th = math.radians(120.0)
    uv, valid = m.bearing_to_pixel(np.array([[math.sin(th), 0.0, math.cos(th)]]))
    assert valid.all()
    np.testing.assert_allclose(uv[0], [500.0 + 200.0 * th * (1 + k1 * th * th), 400.0], atol=1e-12)


def _random_kb(rng):
    fx = rng.uniform(200, 600)
    K = np.array([[fx, 0, rng.uniform(300, 340)], [0, fx * rng.uniform(0.98, 1.02), rng.uniform(230, 250)],
                  [0, 0, 1.0]])
    D = rng.uniform([-0.05, -0.02, -0.01, -0.002], [0.05, 0.02, 0.01, 0.002])
    m = KannalaBrandt(fx=K[0, 0], fy=K[1, 1], cx=K[0, 2], cy=K[1, 2], width=640, height=480,
                      k1=D[0], k2=D[1], k3=D[2], k4=D[3])
    return K, D, m


def test_kannala_brandt_equals_cv2_fisheye_project_points():
    rng = np.random.default_rng(7)
    for _ in range(60):
        K, D, m = _random_kb(rng)
        theta = rng.uniform(0, math.radians(85), 500)
        phi = rng.uniform(0, 2 * np.pi, 500)
        dist = rng.uniform(0.5, 20, 500)[:, None]
        p = dist * np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=1)
        uv_cv, _ = cv2.fisheye.projectPoints(p.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D)
        uv, valid = m.bearing_to_pixel(p, within_image=False)
        # valid exactly up to the lens limit (where theta_d stops increasing, for some draws < 85 deg)
        np.testing.assert_array_equal(valid, theta <= m.max_angle_rad)
        assert valid.mean() > 0.8
        assert np.abs(uv - uv_cv.reshape(-1, 2))[valid].max() < 1e-6


def test_kannala_brandt_equals_cv2_fisheye_undistort_points():
    rng = np.random.default_rng(8)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)
    for _ in range(60):
        K, D, m = _random_kb(rng)
        theta = rng.uniform(0, min(math.radians(80), m.max_angle_rad - 0.02), 500)
        # cv2.fisheye.undistortPoints clamps theta_d to [-pi/2, pi/2]: compare where it is valid
        theta = theta[m._theta_d(theta)[0] < np.pi / 2 - 1e-9]
        phi = rng.uniform(0, 2 * np.pi, theta.size)
        b = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=1)
        uv, _ = m.bearing_to_pixel(b, within_image=False)
        # cv2 returns the pinhole (undistorted) pixel K [x/z, y/z, 1] with P = K
        und = cv2.fisheye.undistortPoints(uv.reshape(-1, 1, 2), K, D, P=K, criteria=crit).reshape(-1, 2)
        b_ours, valid = m.pixel_to_bearing(uv, within_image=False)
        assert valid.all()
        pin = np.stack([K[0, 0] * b_ours[:, 0] / b_ours[:, 2] + K[0, 2],
                        K[1, 1] * b_ours[:, 1] / b_ours[:, 2] + K[1, 2]], axis=1)
        assert np.abs(pin - und).max() < 1e-6


@pytest.mark.parametrize(
    "name, params, match",
    [
        ("pinhole", {}, r"unknown camera model 'pinhole'; expected one of: double_sphere, equidistant, eucm"),
        ("eucm", {"fx": 1.0}, r"expected: fx, fy"),
        ("kannala_brandt", {"fx": 1, "fy": 1, "cx": 0, "cy": 0, "width": 4, "height": 4, "k5": 0.1},
         r"unknown parameter\(s\) k5"),
        ("kannala_brandt", {"fx": -1, "fy": 1, "cx": 0, "cy": 0, "width": 4, "height": 4}, r"fx, fy > 0"),
        ("double_sphere",
         {"fx": 1, "fy": 1, "cx": 0, "cy": 0, "width": 4, "height": 4, "xi": 2.0, "alpha": 0.5},
         r"xi in \[-1, 1\]"),
        ("eucm", {"fx": 1, "fy": 1, "cx": 0, "cy": 0, "width": 4, "height": 4, "alpha": 0.5, "beta": 0.0},
         r"beta > 0"),
        ("equidistant", {"fx": 1, "fy": 1, "cx": 0, "cy": 0, "width": 4.5, "height": 4},
         r"width a positive integer"),
    ],
)
def test_make_camera_model_errors(name, params, match):
    with pytest.raises(CalibrationError, match=match):
        make_camera_model(name, **params)


# ------------------------------------------------------------------------- property tests
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@st.composite
def _random_model(draw) -> CameraModel:
    name = draw(st.sampled_from(sorted(CAMERA_MODELS)))
    f = draw(st.floats(80.0, 800.0))
    common = dict(fx=f, fy=f * draw(st.floats(0.95, 1.05)), cx=draw(st.floats(300.0, 340.0)),
                  cy=draw(st.floats(220.0, 260.0)), width=640, height=480)
    if name == "kannala_brandt":
        ks = draw(st.lists(st.floats(-0.05, 0.05), min_size=4, max_size=4))
        return KannalaBrandt(**common, k1=ks[0], k2=ks[1], k3=ks[2], k4=ks[3])
    if name == "double_sphere":
        return DoubleSphere(**common, xi=draw(st.floats(-0.6, 0.6)), alpha=draw(st.floats(0.3, 0.75)))
    if name == "eucm":
        return Eucm(**common, alpha=draw(st.floats(0.3, 0.8)), beta=draw(st.floats(0.6, 2.0)))
    return make_camera_model(name, **common)


@settings(max_examples=60, deadline=None)
@given(model=_random_model(), seed=st.integers(0, 2**32 - 1))
def test_random_models_never_nan_and_valid_rows_round_trip(model, seed):
    rng = np.random.default_rng(seed)
    b = rng.normal(size=(400, 3)) * rng.choice([1e-3, 1.0, 1e3], size=(400, 1))
    uv, valid = model.bearing_to_pixel(b, within_image=False)
    J = model.bearing_to_pixel_jacobian(b, within_image=False)
    assert np.all(np.isfinite(uv)) and np.all(np.isfinite(J))
    assert not uv[~valid].any() and not J[~valid].any()
    b2, valid2 = model.pixel_to_bearing(uv[valid], within_image=False)
    assert valid2.all()
    # well inside the lens the round trip is exact to rounding; near a KB turning point it is
    # ill-conditioned (sqrt(eps)), so the bound is looser there
    theta = np.arctan2(np.hypot(b[valid, 0], b[valid, 1]), b[valid, 2])
    inner = theta < model.max_angle_rad - 0.05
    ang = _angle(_unit(b[valid]), b2)
    assert ang[inner].max(initial=0.0) < 1e-9 and ang.max(initial=0.0) < 1e-6
    uv_any = rng.uniform(-2000, 2000, size=(400, 2))
    bb, vv = model.pixel_to_bearing(uv_any, within_image=False)
    Ju = model.pixel_to_bearing_jacobian(uv_any, within_image=False)
    assert np.all(np.isfinite(bb)) and np.all(np.isfinite(Ju)) and not bb[~vv].any()
    np.testing.assert_allclose(np.linalg.norm(bb[vv], axis=1), 1.0, atol=1e-12)
