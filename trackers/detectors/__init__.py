"""Detectors by name: ``make_detector("orb")``; built-ins register on import, plug-ins through the
entry-point group ``fisheye_des.detectors``.

Built-ins: ``orb`` (default), ``navlights``, ``kornia`` (optional extra), ``torch`` (a user's model),
``orb+navlights`` (ORB keypoints and navlights boxes; any ``"<keypoint detector>+<box detector>"``
name combines two the same way, ``trackers.detectors.composite``).
Adding one is one new module here with ``@register_detector("name")`` and its import below.
"""

from trackers.detectors import composite, kornia_det, navlights, orb, torch_det  # noqa: F401  (register built-ins)
from trackers.detectors.base import (
    ENTRY_POINT_GROUP,
    GREY_DETECTORS,
    Detections,
    Detector,
    available_detectors,
    box_detectors,
    boxes_unused,
    gives_boxes,
    make_detector,
    register_detector,
    to_grey,
)

__all__ = [
    "ENTRY_POINT_GROUP",
    "GREY_DETECTORS",
    "Detections",
    "Detector",
    "available_detectors",
    "box_detectors",
    "boxes_unused",
    "gives_boxes",
    "make_detector",
    "register_detector",
    "to_grey",
]
