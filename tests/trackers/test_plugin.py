"""An outside package adds a detector through the entry-point group ``fisheye_des.detectors``.

The test installs a tiny distribution into a temporary folder on sys.path (a module plus a
``*.dist-info`` with ``entry_points.txt``, what pip would write), then builds the detector by name
and runs it through the FrontEnd."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from estimators.errors import ConfigError
from tests.trackers.conftest import SphereScene
from trackers.detectors import ENTRY_POINT_GROUP, available_detectors, make_detector
from trackers.frontend import FrontEnd

PLUGIN = '''
import cv2
import numpy as np

from trackers.detectors import Detections, Detector


class GfttPlugin(Detector):
    """Shi-Tomasi corners (cv2.goodFeaturesToTrack): keypoints for the KLT front end."""

    def __init__(self, max_corners=200):
        self.max_corners = max_corners

    def detect(self, image, mask=None):
        grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        pts = cv2.goodFeaturesToTrack(grey, self.max_corners, 0.01, 8, mask=mask)
        if pts is None:
            return Detections.empty()
        pts = pts.reshape(-1, 2)
        return Detections(keypoints=pts, scores=np.ones(len(pts)))


class NotADetector:
    pass


def broken():
    raise RuntimeError("boom")
'''


def install(tmp_path, monkeypatch, entries: dict[str, str]) -> None:
    (tmp_path / "fdes_test_plugin.py").write_text(textwrap.dedent(PLUGIN))
    info = tmp_path / "fdes_test_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: fdes-test-plugin\nVersion: 0.1\n")
    lines = "\n".join(f"{k} = {v}" for k, v in entries.items())
    (info / "entry_points.txt").write_text(f"[{ENTRY_POINT_GROUP}]\n{lines}\n")
    monkeypatch.syspath_prepend(str(tmp_path))


def test_plugin_found_by_name_and_run_through_the_front_end(tmp_path, monkeypatch, model, rig):
    install(tmp_path, monkeypatch, {"gftt_plugin": "fdes_test_plugin:GfttPlugin"})
    assert "gftt_plugin" in available_detectors()
    det = make_detector("gftt_plugin", max_corners=150)
    assert det.name == "gftt_plugin"
    scene = SphereScene(model)
    d = det.detect(scene.render(), None)
    assert 50 <= len(d) <= 150
    fe = FrontEnd(rig, detector="gftt_plugin", detector_options={"max_corners": 150})
    rot = np.radians(0.5)
    out = []
    for k in range(10):
        c, s = np.cos(rot * k), np.sin(rot * k)
        R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
        out = fe.process({"cam0": scene.render(R)}, k, k / 30)
    live = [o for o in out if o.status != "lost"]
    assert live and all(o.label == "gftt_plugin" for o in live)
    assert fe.trackers["cam0"].n_live > 50


def test_unknown_name_lists_the_plugin_too(tmp_path, monkeypatch):
    install(tmp_path, monkeypatch, {"gftt_plugin": "fdes_test_plugin:GfttPlugin"})
    with pytest.raises(ConfigError, match="gftt_plugin"):
        make_detector("not_installed")


@pytest.mark.parametrize(
    "target,match",
    [
        ("fdes_test_plugin:NotADetector", "expected a Detector"),
        ("fdes_test_plugin:broken", "boom"),
        ("fdes_no_such_module:X", "failed to load"),
    ],
)
def test_broken_plugins_are_config_errors(tmp_path, monkeypatch, target, match):
    install(tmp_path, monkeypatch, {"bad_plugin": target})
    with pytest.raises(ConfigError, match=match):
        make_detector("bad_plugin")


def test_whether_a_plugin_gives_boxes_is_read_from_its_class_without_building_it(tmp_path, monkeypatch):
    """gives_boxes (the config's check of tracker.boxes beside a detector): a plug-in class's own flag;
    None (left to make_detector) for one that is no Detector class, does not load or is not installed."""
    from trackers.detectors import gives_boxes

    install(tmp_path, monkeypatch, {"gftt_plugin": "fdes_test_plugin:GfttPlugin",
                                    "bad_plugin": "fdes_no_such_module:X",
                                    "fn_plugin": "fdes_test_plugin:broken"})
    assert gives_boxes("gftt_plugin") is False
    assert gives_boxes("bad_plugin") is None and gives_boxes("fn_plugin") is None
    assert gives_boxes("not_installed") is None
    assert gives_boxes("orb") is False and gives_boxes("navlights") is True
    assert gives_boxes("orb+torch") is True
