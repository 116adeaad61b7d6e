"""Detectors: every registered one on a frame it should find something in, the Detections record,
the registry's errors, ORB coverage of the rim, navlights' heading convention, torch models."""

from __future__ import annotations

import re

import cv2
import numpy as np
import pytest

from estimators.errors import ConfigError, InputError
from tests.trackers.conftest import SphereScene, equidistant
from trackers.detectors import Detections, Detector, available_detectors, make_detector
from trackers.detectors.base import torch_device
from trackers.detectors.composite import CompositeDetector
from trackers.detectors.navlights import heading_from_lights
from trackers.features import lens_mask

BUILTINS = ("orb", "navlights", "kornia", "torch")


def lights_image(red_u: float, green_u: float, white: bool = True, size=(240, 320)) -> np.ndarray:
    """Dark BGR frame with a red, a green and (optionally) a white light on one row."""
    img = np.full(size + (3,), 20, np.uint8)
    cv2.circle(img, (int(red_u), 120), 3, (0, 0, 255), -1)
    cv2.circle(img, (int(green_u), 120), 3, (0, 255, 0), -1)
    if white:
        cv2.circle(img, (int((red_u + green_u) / 2), 118), 3, (255, 255, 255), -1)
    return img


@pytest.fixture
def torchscript_model(tmp_path):
    torch = pytest.importorskip("torch")

    class Boxes(torch.nn.Module):
        """Two fixed boxes [x1, y1, x2, y2, score, class] in the input's pixels; the second weak."""

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            z = x.mean() * 0.0
            return (
                torch.stack(
                    [
                        torch.tensor([10.0, 20.0, 50.0, 60.0, 0.9, 1.0]),
                        torch.tensor([0.0, 0.0, 5.0, 5.0, 0.1, 0.0]),
                    ]
                )
                + z
            )

    p = tmp_path / "boxes.pt"
    torch.jit.script(Boxes()).save(str(p))
    return p


def setup_for(name: str, tmp_path, request):
    """(options, image, mask) under which detector ``name`` must find something."""
    model = equidistant()
    mask = lens_mask(model)
    textured = SphereScene(model).render()
    if name == "orb":
        return {}, textured, mask, "keypoints"
    if name == "kornia":
        pytest.importorskip("torch")
        pytest.importorskip("kornia")
        return {"device": "cpu"}, textured, mask, "keypoints"
    if name == "navlights":
        return {}, lights_image(200, 120), mask, "boxes"
    if name == "torch":
        return {"model_path": request.getfixturevalue("torchscript_model")}, textured, None, "boxes"
    pytest.skip(f"no test setup for plug-in detector {name!r}")


@pytest.mark.parametrize("name", BUILTINS)
def test_each_registered_detector_finds_something(name, tmp_path, request):
    assert name in available_detectors()
    opts, img, mask, kind = setup_for(name, tmp_path, request)
    det = make_detector(name, **opts)
    assert isinstance(det, Detector) and det.name == name
    d = det.detect(img, mask)
    assert isinstance(d, Detections)
    if kind == "keypoints":
        assert len(d) >= 50
        u = np.round(d.keypoints[:, 0]).astype(int)
        v = np.round(d.keypoints[:, 1]).astype(int)
        assert np.all(mask[v, u] > 0), "keypoints outside the mask"
    else:
        assert len(d.boxes) >= 1
        assert np.all(d.boxes[:, 2] >= d.boxes[:, 0]) and np.all(d.boxes[:, 3] >= d.boxes[:, 1])
        assert len(d.labels) == len(d.boxes) == len(d.attributes)


def test_orb_covers_the_rim_like_the_centre():
    """On a uniformly textured world the outer ring of the lens circle (beyond 70 % of its radius,
    > 70 deg off-axis here) gets keypoints in proportion to its area (within a factor of 2)."""
    model = equidistant(640, 480)
    img = SphereScene(model).render()
    mask = lens_mask(model)
    d = make_detector("orb", max_features=500).detect(img, mask)
    cx, cy, r = model.image_circle()
    rr = np.hypot(d.keypoints[:, 0] - cx, d.keypoints[:, 1] - cy) / r
    frac_outer = float(np.mean(rr > 0.7))
    area_outer = 1 - 0.7**2
    assert frac_outer > area_outer / 2, (
        f"{frac_outer:.2f} of keypoints in the outer ring (area {area_outer:.2f})"
    )


@pytest.mark.parametrize(
    "kwargs,exc",
    [
        ({"keypoints": np.zeros((3, 3))}, InputError),
        ({"keypoints": np.zeros((3, 2)), "scores": np.zeros(2)}, InputError),
        ({"keypoints": [[np.nan, 1.0]], "scores": [1.0]}, InputError),
        (
            {"keypoints": np.zeros((2, 2)), "scores": np.zeros(2), "descriptors": np.zeros((3, 32))},
            InputError,
        ),
        ({"boxes": [[10, 10, 5, 20]]}, InputError),
        ({"boxes": [[0, 0, 5, 5]], "labels": ("a", "b")}, InputError),
        ({"boxes": [[0, 0, 5, 5]]}, None),
        ({}, None),
    ],
)
def test_detections_validation(kwargs, exc):
    if exc is None:
        d = Detections(**kwargs)
        assert len(d.labels) == len(d.boxes) == len(d.box_scores) == len(d.attributes)
    else:
        with pytest.raises(exc):
            Detections(**kwargs)


def test_detections_empty_and_select():
    e = Detections.empty()
    assert len(e) == 0 and e.boxes.shape == (0, 4)
    d = Detections(keypoints=[[1, 2], [3, 4], [5, 6]], scores=[0.1, 0.2, 0.3])
    s = d.select(d.scores > 0.15)
    np.testing.assert_array_equal(s.keypoints, [[3, 4], [5, 6]])


def test_unknown_detector_lists_installed_ones():
    with pytest.raises(ConfigError) as ei:
        make_detector("nosuch")
    for n in ("orb", "navlights", "kornia", "torch"):
        assert n in str(ei.value)


def test_bad_detector_option_is_config_error():
    with pytest.raises(ConfigError, match="bogus"):
        make_detector("orb", bogus=3)


# ------------------------------------------------------------------------------------ navlights
@pytest.mark.parametrize(
    "red_u,green_u,expected",
    [(200, 120, "towards"), (120, 200, "away")],
)
def test_navlights_heading_follows_the_thesis(red_u, green_u, expected):
    """Thesis 5.2: red on the drone's left wingtip, green on its right; "green navigation light on
    the left and red light on the right, that means the drone is flying towards" us."""
    d = make_detector("navlights").detect(lights_image(red_u, green_u), None)
    assert len(d.boxes) == 1 and d.labels == ("drone",)
    a = d.attributes[0]
    assert a["heading"] == expected
    assert heading_from_lights(red_u, green_u) == expected
    x1, y1, x2, y2 = d.boxes[0]
    assert x1 <= min(red_u, green_u) and x2 >= max(red_u, green_u) and y1 <= 120 <= y2


def test_navlights_needs_the_white_light_only_when_told():
    """The white light is not required by default (a far drone's merges into its body); it raises
    the box's score; ``require_white`` is the thesis's strict test."""
    img = lights_image(200, 120, white=False)
    assert len(make_detector("navlights", require_white=True).detect(img).boxes) == 0
    d = make_detector("navlights").detect(img)
    assert len(d.boxes) == 1 and d.attributes[0]["white_uv"] is None and d.box_scores[0] < 1.0
    d = make_detector("navlights").detect(lights_image(200, 120))
    assert len(d.boxes) == 1 and d.attributes[0]["white_uv"] is not None and d.box_scores[0] == 1.0


def test_navlights_rejects_grey_frames():
    with pytest.raises(InputError, match="BGR"):
        make_detector("navlights").detect(np.zeros((240, 320), np.uint8))


# ---------------------------------------------------------------------------------------- torch
def test_exported_program_boxes_scaled_and_its_input_shape_named(tmp_path):
    """A torch.export program (.pt2, the successor of TorchScript, which torch 2.13 deprecates): its boxes
    scaled from its 64x48 input to the frame as TorchScript's are; a frame of another shape fed without
    input_size is bad input naming input_size (the program's shape guard), not a traceback."""
    torch = pytest.importorskip("torch")

    class Box(torch.nn.Module):
        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return torch.tensor([[8.0, 12.0, 32.0, 24.0, 0.8, 0.0]]) + x.mean() * 0.0

    p = tmp_path / "box.pt2"
    torch.export.save(torch.export.export(Box(), (torch.zeros(1, 3, 48, 64),)), str(p))
    det = make_detector("torch", model_path=p, input_size=(64, 48))
    d = det.detect(np.zeros((240, 320, 3), np.uint8))
    np.testing.assert_allclose(d.boxes, [[40, 60, 160, 120]])  # x5 from 64x48 to 320x240
    assert d.labels == ("class0",)
    with pytest.raises(InputError, match=r"^detector 'torch': model box\.pt2 failed on a float32 input of "
                                         r"shape \(1, 3, 240, 320\): .*Guard failed.*give its \(W, H\) as "
                                         r"detector\.options\.input_size$"):
        make_detector("torch", model_path=p).detect(np.zeros((240, 320, 3), np.uint8))


def test_torchscript_boxes_scaled_filtered_and_labelled(torchscript_model):
    det = make_detector(
        "torch",
        model_path=torchscript_model,
        input_size=(160, 120),
        min_score=0.5,
        class_names=("person", "drone"),
    )
    d = det.detect(np.zeros((240, 320, 3), np.uint8))
    assert d.labels == ("drone",)
    np.testing.assert_allclose(d.boxes, [[20, 40, 100, 120]])  # x2 from 160x120 to 320x240
    np.testing.assert_allclose(d.box_scores, [0.9], rtol=1e-6)


def test_a_misspelt_detector_option_names_the_closest_one(monkeypatch, request):
    """As an unknown config key: the closest accepted option and all of them (was the TypeError and the
    constructor's whole signature), also for a composite's part; a CUDA device on a torch without one is a
    ConfigError when the detector is built (was an AssertionError traceback at the first frame)."""
    with pytest.raises(ConfigError, match=r"^detector 'orb': unknown key 'max_featurs' in its options; did "
                                          r"you mean 'max_features'\? Valid keys: max_features, grid, "):
        make_detector("orb", max_featurs=100)
    with pytest.raises(ConfigError, match=r"^detector 'navlights': unknown key 'min_vale' in its options; "
                                          r"did you mean 'min_value'\?"):
        make_detector("orb+navlights", navlights={"min_vale": 3})
    with pytest.raises(ConfigError, match=r"^detector 'orb\+navlights': unknown key 'max_features' in its "
                                          r"options; options are given per part, under the part's name: "
                                          r"\{'orb': \{\.\.\.\}, 'navlights': \{\.\.\.\}\}$"):
        CompositeDetector("orb", "navlights", max_features=100)  # (was "unknown options ['max_features']")
    torch = pytest.importorskip("torch")
    pytest.importorskip("kornia")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    model = request.getfixturevalue("torchscript_model")
    for name, options in (("kornia", {}), ("torch", {"model_path": model})):  # one check, one wording
        with pytest.raises(ConfigError, match=rf"^detector '{name}': device 'cuda', but this torch sees no "
                                              r"CUDA device \(or is a CPU build\); expected 'auto' or 'cpu'"):
            make_detector(name, device="cuda", **options)
        with pytest.raises(ConfigError, match=rf"^detector '{name}': device expected 'auto', 'cpu', 'cuda' "
                                              r"or 'cuda:N', got 'gpu'$"):
            make_detector(name, device="gpu", **options)
    # a CUDA device by index, as torch names it ('cuda:1'), is taken when this torch sees it
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 2)
    assert torch_device(torch, "cuda:1", "torch") == "cuda:1"
    assert torch_device(torch, "cuda", "torch") == "cuda"
    with pytest.raises(ConfigError, match=r"^detector 'torch': device 'cuda:2', but this torch sees 2 CUDA "
                                          r"devices \(cuda:0 to cuda:1\)$"):
        torch_device(torch, "cuda:2", "torch")


def test_torch_missing_or_broken_model_file(tmp_path):
    """A model_path that is not a file, or none (was "model_path not given is not a file"): the message
    names the config key, also a composite part's (detector.options.torch.model_path)."""
    keys = (r"\(in a config: detector\.options\.model_path, or as a composite's part, e\.g\. orb\+torch: "
            r"detector\.options\.torch\.model_path; nothing is downloaded\)$")
    missing = tmp_path / "nothing.onnx"
    shown = re.escape(repr(str(missing)))
    with pytest.raises(ConfigError, match=rf"^detector 'torch': model_path {shown} is not a file; .*{keys}"):
        make_detector("torch", model_path=missing)
    for name, options in (("torch", {}), ("orb+torch", {"torch": {}})):
        with pytest.raises(ConfigError, match=rf"^detector 'torch': no model_path given; expected .*{keys}"):
            make_detector(name, **options)
    broken = tmp_path / "broken.onnx"
    broken.write_bytes(b"not an onnx model")
    with pytest.raises(ConfigError, match="ONNX"):
        make_detector("torch", model_path=broken)


def test_a_torch_model_that_fails_or_returns_no_tensor_is_bad_input_naming_the_contract(tmp_path):
    """The user's model raising (TorchScript's multi-line message) or returning a dict is an InputError
    (exit 2) of one line naming the model and what was expected, not a traceback (exit 1); a wrong
    shape names the rows expected."""
    torch = pytest.importorskip("torch")

    class Raises(torch.nn.Module):
        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return x.view(7, -1)

    class Named(torch.nn.Module):
        def forward(self, x: torch.Tensor) -> dict[str, torch.Tensor]:
            return {"boxes": torch.zeros(1, 4)}

    class Wide(torch.nn.Module):
        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return torch.zeros(3, 7)

    img = np.zeros((24, 32, 3), np.uint8)
    for cls, expected in (
        (Raises, r"^detector 'torch': model Raises\.pt failed on a float32 input of shape \(1, 3, 24, 32\): "
                 r"RuntimeError: shape '\[7, -1\]' is invalid for input of size 2304$"),
        (Named, r"^detector 'torch': model Named\.pt returned a dict; expected a tensor \(M, 4\.\.6\)"),
        (Wide, r"^detector 'torch': model Wide\.pt returned shape \(3, 7\); expected \(M, 4\.\.6\) rows"),
    ):
        p = tmp_path / f"{cls.__name__}.pt"
        torch.jit.script(cls()).save(str(p))
        with pytest.raises(InputError, match=expected):
            make_detector("torch", model_path=p).detect(img)


def test_kornia_responses_run_on_cpu():
    pytest.importorskip("torch")
    pytest.importorskip("kornia")
    model = equidistant()
    img = SphereScene(model).render()
    for resp in ("gftt", "harris", "hessian", "dog"):
        d = make_detector("kornia", response=resp, device="cpu", max_features=100).detect(
            img, lens_mask(model)
        )
        assert 10 <= len(d) <= 100, resp
    with pytest.raises(ConfigError, match="response"):
        make_detector("kornia", response="sift9000")


@pytest.mark.parametrize("name", ["orb", "kornia"])
def test_keypoint_detectors_pickle_for_the_live_detection_worker(name):
    """A live run's detection worker process gets the feature tracker's detector pickled: the copy finds
    the same keypoints (ORB: the same descriptors too; cv2.ORB and the torch modules are made again)."""
    import pickle

    if name == "kornia":
        pytest.importorskip("torch")
        pytest.importorskip("kornia")
    model = equidistant()
    img = SphereScene(model).render()
    opts = {"device": "cpu"} if name == "kornia" else {}
    d = make_detector(name, max_features=200, **opts)
    a, b = d.detect(img, lens_mask(model)), pickle.loads(pickle.dumps(d)).detect(img, lens_mask(model))
    assert len(a) > 50
    np.testing.assert_array_equal(a.keypoints, b.keypoints)
    if a.descriptors is not None:
        np.testing.assert_array_equal(a.descriptors, b.descriptors)


def test_navlights_through_the_front_end_gives_a_drone_track_with_heading():
    """Box detectors run through the FrontEnd's BoxTracker: one confirmed track that follows the
    lights, labelled ``drone``, with the heading in its attributes; lost once after they vanish."""
    from estimators.rig import mono_forward_rig
    from trackers.frontend import FrontEnd

    model = equidistant()
    fe = FrontEnd(mono_forward_rig(model), detector="navlights")
    seen = []
    for k in range(12):
        img = lights_image(170 + k, 130 + k) if k < 8 else np.full((240, 320, 3), 20, np.uint8)
        for o in fe.process({"cam0": img}, k, k / 30):
            seen.append((k, o))
    live = [o for _, o in seen if o.status != "lost"]
    assert {o.track_id for o in live} == {live[0].track_id}
    assert live[-1].status == "confirmed" and live[-1].label == "drone"
    assert live[-1].attributes["heading"] == "towards"
    # the track's bearing is the box centre's, through the camera model
    b, _ = model.pixel_to_bearing(np.array([[150.0 + 7, 119.0]]))
    assert np.degrees(np.arccos(np.clip(live[-1].views[0].b_C @ b[0], -1, 1))) < 1.0
    lost = [o for _, o in seen if o.status == "lost"]
    assert len(lost) <= 1
