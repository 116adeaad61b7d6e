"""Composite detectors: the keypoints of one detector and the boxes of another, from one frame.

``orb+navlights`` (registered) is ORB's keypoints, tracked and grouped into obstacles as with ``orb``
alone, plus navlights' drone boxes, tracked by the BoxTracker: textured obstacles and drones seen by
their lights in one front end. Any two detectors combine the same way by name, ``"<kp>+<box>"``
(``make_detector("kornia+torch")``): the first must produce keypoints, the second boxes.

Options (``detector.options`` in the config) are given per part, under the part's name:
``{"orb": {"max_features": 800}, "navlights": {"min_value": 170}}``; any other key is a ConfigError.

How the front end uses it (``FrontEnd``): the keypoint part itself is given to the FeatureTracker
(``Detector.keypoint_part``), so ORB runs exactly as it does alone (on its detection frames, on the
lens's crop, describing only what may be kept) and the feature tracks are those of ``orb`` alone,
labelled ``orb``; the box part runs every frame (``Detector.detect_boxes``). A box part that needs
colour (``needs_colour``) gives no boxes on a grey frame: a grey video gives keypoints only.

One obstacle found by both (a drone textured enough for ORB, a textured obstacle with a light-like
spot) is reported once: the BoxTracker links a box track to a feature track whose member features lie
in the box and move with it, and reports the feature track only, with the box's label and attributes
added (``BoxTracker`` in trackers/grouping.py).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from estimators.errors import ConfigError
from trackers.detectors.base import Detections, Detector, make_detector, register_detector


class CompositeDetector(Detector):
    """Keypoints from ``keypoints``, boxes from ``boxes`` (two Detectors or registered names).

    Args:
        keypoints: the keypoint detector (name or instance); it must produce keypoints.
        boxes: the box detector (name or instance); it must produce boxes.
        **options: per part, ``{part name: {its keyword options}}`` (parts given by name only).
    Raises:
        ConfigError: a part that does not produce what it is used for, an options key that is not a
            part's name or whose value is not a dict, or a part's own bad options.
    """

    produces_keypoints = True
    produces_boxes = True

    def __init__(self, keypoints: str | Detector = "orb", boxes: str | Detector = "navlights",
                 **options: Any) -> None:
        names = [p if isinstance(p, str) else p.name for p in (keypoints, boxes)]
        named = [n for n, p in zip(names, (keypoints, boxes), strict=True) if isinstance(p, str)]
        bad = [k for k in options if k not in named]
        if bad:
            raise ConfigError(
                f"detector {'+'.join(names)!r}: unknown key '{bad[0]}' in its options; options are given per "
                f"part, under the part's name: {{{names[0]!r}: {{...}}, {names[1]!r}: {{...}}}}"
            )
        for k, v in options.items():
            if not isinstance(v, dict):
                raise ConfigError(
                    f"detector {'+'.join(names)!r}: options of part {k!r} expected a mapping of its "
                    f"keyword options, got {v!r}"
                )
        if names[0] == names[1]:
            raise ConfigError(f"detector {'+'.join(names)!r}: expected two different parts")
        parts = [
            p if isinstance(p, Detector) else make_detector(p, **options.get(p, {}))
            for p in (keypoints, boxes)
        ]
        if not parts[0].produces_keypoints:
            raise ConfigError(
                f"detector {'+'.join(names)!r}: its first part {names[0]!r} gives no keypoints; expected "
                "'<keypoint detector>+<box detector>', e.g. 'orb+navlights'"
            )
        if not parts[1].produces_boxes:
            raise ConfigError(
                f"detector {'+'.join(names)!r}: its second part {names[1]!r} gives no boxes; expected "
                "'<keypoint detector>+<box detector>', e.g. 'orb+navlights'"
            )
        self._kp, self._box = parts

    @property
    def keypoint_part(self) -> Detector:
        """The keypoint detector (the FeatureTracker is given it, not the composite)."""
        return self._kp

    @property
    def box_part(self) -> Detector:
        """The box detector."""
        return self._box

    def detect_boxes(
        self, image: np.ndarray, mask: np.ndarray | None = None, camera: str | None = None
    ) -> Detections:
        """The box part's boxes (none on a grey frame when the box part needs colour); ``camera`` is
        passed on when given (a plug-in box part may take only ``image`` and ``mask``)."""
        if self._box.needs_colour and image.ndim != 3:
            return Detections.empty()
        if camera is None:
            return self._box.detect_boxes(image, mask)
        return self._box.detect_boxes(image, mask, camera=camera)

    def detect(self, image: np.ndarray, mask: np.ndarray | None = None) -> Detections:
        """See Detector.detect: the keypoint part's keypoints (and descriptors) and the box part's
        boxes of one frame."""
        k = self._kp.detect(image, mask)
        b = self.detect_boxes(image, mask)
        return Detections(
            keypoints=k.keypoints,
            scores=k.scores,
            descriptors=k.descriptors,
            boxes=b.boxes,
            box_scores=b.box_scores,
            labels=b.labels,
            attributes=b.attributes,
        )


@register_detector("orb+navlights")
class OrbNavLightsDetector(CompositeDetector):
    """ORB keypoints + navlights boxes (see the module docstring). Options per part:
    ``orb={...}``, ``navlights={...}``."""

    def __init__(self, orb: dict[str, Any] | None = None, navlights: dict[str, Any] | None = None) -> None:
        opts = {k: v for k, v in (("orb", orb), ("navlights", navlights)) if v is not None}
        super().__init__("orb", "navlights", **opts)
