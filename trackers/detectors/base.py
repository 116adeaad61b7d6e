"""Detector interface, the ``Detections`` record and the registry of detectors by name.

A detector turns one frame into keypoints (to be tracked and grouped into obstacles) and/or boxes
(each box one obstacle candidate with a label and attributes). Built-ins register themselves with
``@register_detector("name")``; ``"a+b"`` combines a keypoint detector ``a`` with a box detector
``b`` (``trackers.detectors.composite``); outside packages add theirs through the entry-point group
``fisheye_des.detectors`` (``name = "package.module:DetectorClass"``), and ``make_detector(name)``
finds both. An unknown name is a ConfigError that lists the installed ones.
"""

from __future__ import annotations

import inspect
import re
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any, ClassVar

import numpy as np

from estimators.errors import ConfigError, FisheyeDesError, InputError, check_rows, did_you_mean

ENTRY_POINT_GROUP = "fisheye_des.detectors"


@dataclass(frozen=True)
class Detections:
    """What a detector found in one frame (supervision-style: one array per field).

    Attributes:
        keypoints: (N, 2) float32 pixel positions (OpenCV convention: integer = pixel centre).
        scores: (N,) float32 detector response of each keypoint (larger = stronger).
        descriptors: (N, D) descriptors of the keypoints (ORB: D = 32 bytes, uint8) or None.
        boxes: (M, 4) float64 boxes ``[x1, y1, x2, y2]`` in pixels.
        box_scores: (M,) float64 confidence of each box in [0, 1].
        labels: (M,) label of each box (e.g. ``"drone"``).
        attributes: (M,) JSON-serialisable dict per box (e.g. navlights' ``heading``).
    """

    keypoints: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.float32))
    scores: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32))
    descriptors: np.ndarray | None = None
    boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    box_scores: np.ndarray = field(default_factory=lambda: np.zeros(0))
    labels: tuple[str, ...] = ()
    attributes: tuple[dict[str, Any], ...] = ()

    def __post_init__(self) -> None:
        kp = check_rows("Detections.keypoints", self.keypoints, 2, np.float32)
        sc = np.asarray(self.scores, dtype=np.float32).reshape(-1)
        if len(sc) != len(kp):
            raise InputError(f"Detections: {len(kp)} keypoints but {len(sc)} scores")
        de = self.descriptors
        if de is not None:
            de = np.asarray(de)
            if de.ndim != 2 or len(de) != len(kp):
                raise InputError(f"Detections.descriptors: expected shape ({len(kp)}, D), got {de.shape}")
        bx = check_rows("Detections.boxes", self.boxes, 4, np.float64)
        if np.any(bx[:, 2] < bx[:, 0]) or np.any(bx[:, 3] < bx[:, 1]):
            raise InputError("Detections.boxes: expected x1 <= x2 and y1 <= y2 in every row")
        bs = np.asarray(self.box_scores, dtype=np.float64).reshape(-1)
        if len(bs) == 0 and len(bx):
            bs = np.ones(len(bx))
        labels = tuple(str(s) for s in self.labels) if len(self.labels) else ("object",) * len(bx)
        attrs = tuple(dict(a) for a in self.attributes) if len(self.attributes) else ({},) * len(bx)
        if not (len(bs) == len(labels) == len(attrs) == len(bx)):
            raise InputError(
                f"Detections: {len(bx)} boxes but {len(bs)} box_scores, {len(labels)} labels, "
                f"{len(attrs)} attributes"
            )
        object.__setattr__(self, "keypoints", kp)
        object.__setattr__(self, "scores", sc)
        object.__setattr__(self, "descriptors", de)
        object.__setattr__(self, "boxes", bx)
        object.__setattr__(self, "box_scores", bs)
        object.__setattr__(self, "labels", labels)
        object.__setattr__(self, "attributes", attrs)

    @staticmethod
    def empty() -> Detections:
        """No keypoints, no boxes."""
        return Detections()

    def __len__(self) -> int:
        """Number of keypoints (boxes: ``len(d.boxes)``)."""
        return len(self.keypoints)

    def select(self, keep: np.ndarray) -> Detections:
        """The keypoints picked by a boolean mask or index array ``keep`` (N,); boxes unchanged."""
        keep = np.asarray(keep)
        return Detections(
            keypoints=self.keypoints[keep],
            scores=self.scores[keep],
            descriptors=None if self.descriptors is None else self.descriptors[keep],
            boxes=self.boxes,
            box_scores=self.box_scores,
            labels=self.labels,
            attributes=self.attributes,
        )

    def scaled(self, factor: float) -> Detections:
        """The detections of this frame as found on the frame resized by ``factor`` (e.g. a
        1920x1080 frame's boxes on the 1280x720 frame the front end tracks, factor 2/3).

        Keypoints and box corners (pixels, integer = pixel centre) map as the camera model's
        principal point does (``CameraModel.scaled``): ``p' = (p + 0.5) * factor - 0.5``.
        Descriptors, scores, labels and attributes are unchanged: pixel positions in the attributes
        (navlights' ``red_uv``...) stay in this frame's pixels, those of ``CameraView.uv``.
        """
        f = float(factor)
        if not np.isfinite(f) or f <= 0:
            raise InputError(f"Detections.scaled: expected a finite factor > 0, got {factor!r}")
        if f == 1.0:
            return self
        return Detections(
            keypoints=((self.keypoints.astype(np.float64) + 0.5) * f - 0.5).astype(np.float32),
            scores=self.scores,
            descriptors=self.descriptors,
            boxes=(self.boxes + 0.5) * f - 0.5,  # p' = (p + 0.5) f - 0.5
            box_scores=self.box_scores,
            labels=self.labels,
            attributes=self.attributes,
        )

    @property
    def box_centres(self) -> np.ndarray:
        """(M, 2) pixel centres of the boxes."""
        return (
            np.stack(
                [(self.boxes[:, 0] + self.boxes[:, 2]) / 2, (self.boxes[:, 1] + self.boxes[:, 3]) / 2], axis=1
            )
            if len(self.boxes)
            else np.zeros((0, 2))
        )


#: detectors that work on grey images: a video for one of them is decoded straight to grey (the pipeline's
#: ``inputs.grey`` default, ``trackers.benchmark --mjpeg``); any other (navlights, a composite with a
#: box part, torch and plug-ins, whose models may take colour) gets colour frames
GREY_DETECTORS = ("orb", "kornia")


def to_grey(image: np.ndarray) -> np.ndarray:
    """(H, W) uint8 grey or (H, W, 3) uint8 BGR -> (H, W) uint8 grey (a view when already grey)."""
    import cv2

    if image.ndim == 2:
        return image
    if image.ndim == 3 and image.shape[2] == 3:
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.ndim == 3 and image.shape[2] == 1:
        return image[:, :, 0]
    raise InputError(f"image: expected (H, W) grey or (H, W, 3) BGR uint8, got shape {image.shape}")


class Detector(ABC):
    """Turns one frame into keypoints and/or boxes.

    Subclasses set ``name`` (through ``@register_detector``) and say what they produce:
    ``produces_keypoints`` (tracked by KLT and grouped into obstacles) and/or ``produces_boxes``
    (each box tracked as one obstacle candidate).
    """

    name: ClassVar[str] = ""
    produces_keypoints: ClassVar[bool] = True
    produces_boxes: ClassVar[bool] = False
    needs_colour: ClassVar[bool] = False  # refuses grey frames (navlights)

    @property
    def keypoint_part(self) -> Detector:
        """The detector whose keypoints the FeatureTracker tracks: this one (a composite detector
        gives its keypoint part, so that e.g. ORB runs as it does alone)."""
        return self

    def detect_boxes(
        self, image: np.ndarray, mask: np.ndarray | None = None, camera: str | None = None
    ) -> Detections:
        """This frame's boxes (for the BoxTracker; ``image`` and ``mask`` as ``detect``). Default:
        ``detect``; a composite detector runs only its box part. ``camera``: the name of the camera
        whose frame this is, for a detector that follows each camera's sequence of frames (navlights'
        ``scan_every``); None: cameras are told apart by their mask objects."""
        return self.detect(image, mask)

    @abstractmethod
    def detect(self, image: np.ndarray, mask: np.ndarray | None = None) -> Detections:
        """Detect in one frame.

        Args:
            image: (H, W) uint8 grey or (H, W, 3) uint8 BGR, the raw fisheye frame.
            mask: (H, W) uint8, non-zero where detections are wanted (the lens circle minus what is
                already tracked), or None for the whole frame.
        Returns:
            Detections with keypoints and/or boxes in pixels of ``image``.
        """


def torch_device(torch: Any, device: str, detector: str) -> str:
    """The torch device detector ``detector`` runs on (``kornia``, ``torch``): ``"auto"`` is CUDA when
    this torch sees a CUDA device, else the CPU; ``"cuda:N"`` is the N-th CUDA device.

    Raises:
        ConfigError: ``device`` is not ``"auto"``, ``"cpu"``, ``"cuda"`` or ``"cuda:N"``, or names a CUDA
            device this torch does not see (it failed at the first frame).
    """
    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device == "cpu":
        return device
    m = re.fullmatch(r"cuda(?::(\d+))?", device) if isinstance(device, str) else None
    if m is None:
        raise ConfigError(f"detector {detector!r}: device expected 'auto', 'cpu', 'cuda' or 'cuda:N', "
                          f"got {device!r}")
    n = torch.cuda.device_count() if torch.cuda.is_available() else 0
    if not n:
        raise ConfigError(f"detector {detector!r}: device {device!r}, but this torch sees no CUDA device (or "
                          "is a CPU build); expected 'auto' or 'cpu' here")
    if m.group(1) is not None and int(m.group(1)) >= n:
        raise ConfigError(f"detector {detector!r}: device {device!r}, but this torch sees {n} CUDA "
                          f"device{'s' if n != 1 else ''} (cuda:0 to cuda:{n - 1})")
    return device


_REGISTRY: dict[str, Callable[..., Detector]] = {}


def register_detector(name: str) -> Callable[[type[Detector]], type[Detector]]:
    """Class decorator: register a Detector subclass under ``name`` (lower-case, unique)."""

    def deco(cls: type[Detector]) -> type[Detector]:
        if name in _REGISTRY and _REGISTRY[name] is not cls:
            raise ConfigError(f"detector name {name!r} is already registered by {_REGISTRY[name]!r}")
        cls.name = name
        _REGISTRY[name] = cls
        return cls

    return deco


def _entry_points() -> dict[str, metadata.EntryPoint]:
    return {ep.name: ep for ep in metadata.entry_points(group=ENTRY_POINT_GROUP)}


def available_detectors() -> list[str]:
    """Names of the built-in detectors and of the installed plug-ins (entry-point group
    ``fisheye_des.detectors``), sorted."""
    return sorted(set(_REGISTRY) | set(_entry_points()))


def gives_boxes(name: str) -> bool | None:
    """Whether the detector named ``name`` reports boxes (``produces_boxes``: a BoxTracker is built for
    it), found without building it: a registered class's flag; a ``"<keypoint>+<box>"`` composite gives
    boxes (its second part must); a plug-in's class is loaded to read it. None when that cannot be told
    (an unknown name, a plug-in that does not load or is no Detector class): ``make_detector`` reports it.
    """
    cls = _REGISTRY.get(name)
    if cls is None and "+" in name and name not in _entry_points():
        return True
    if cls is None:
        ep = _entry_points().get(name)
        if ep is None:
            return None
        try:
            cls = ep.load()
        except Exception:  # a broken plug-in: make_detector names the failure
            return None
    return bool(cls.produces_boxes) if isinstance(cls, type) and issubclass(cls, Detector) else None


def box_detectors() -> list[str]:
    """The registered detectors that report boxes, sorted (``gives_boxes``; composites such as
    ``orb+navlights`` beside them)."""
    return sorted(n for n, c in _REGISTRY.items() if isinstance(c, type) and c.produces_boxes)


def boxes_unused(detector: str, keys) -> str:
    """The refusal of box-tracker options (``keys``) beside ``detector``, a detector that gives no boxes:
    one wording for a config (``tracker.boxes``, checked at load) and for ``FrontEnd(..., boxes=...)``."""
    return (
        f"boxes ({', '.join(keys)}) set, and detector {detector!r} gives no boxes (no box tracker is "
        f"built: they would be ignored); expected a detector that gives boxes ({', '.join(box_detectors())} "
        "or another '<keypoint detector>+<box detector>' composite), or no boxes options"
    )


def make_detector(name: str, **options: Any) -> Detector:
    """Build the detector registered as ``name`` with its keyword ``options``.

    Raises:
        ConfigError: unknown name (the message lists the installed ones), a plug-in that does not
            load or is not a Detector, or options the detector does not accept.
    """
    factory = _REGISTRY.get(name)
    if factory is None and "+" in name and name not in _entry_points():
        # "<keypoint detector>+<box detector>": a composite of two registered detectors
        parts = [p.strip() for p in name.split("+")]
        if len(parts) != 2 or not all(parts):
            raise ConfigError(
                f"detector {name!r}: expected '<keypoint detector>+<box detector>', e.g. 'orb+navlights' "
                f"(two names, one '+'); installed detectors: {', '.join(available_detectors())}"
            )
        kp, box = parts
        from trackers.detectors.composite import CompositeDetector

        det = CompositeDetector(kp, box, **options)
        det.name = name
        return det
    if factory is None:
        ep = _entry_points().get(name)
        if ep is None:
            raise ConfigError(
                f"unknown detector {name!r}; installed detectors: {', '.join(available_detectors())}"
            )
        try:
            factory = ep.load()
        except Exception as e:  # a broken plug-in must not look like a crash of ours
            raise ConfigError(f"detector plug-in {name!r} ({ep.value}) failed to load: {e}") from e
    try:
        sig = inspect.signature(factory)
        sig.bind(**options)
    except TypeError as e:
        named = [n for n, p in sig.parameters.items() if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
        takes_any = any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values())
        unknown = [k for k in options if k not in named]
        if unknown and not takes_any:  # a misspelt option: in the words of an unknown config key
            raise ConfigError(f"detector {name!r}: unknown key '{unknown[0]}' in its options"
                              + did_you_mean(str(unknown[0]), named)) from e
        raise ConfigError(f"detector {name!r}: bad options {sorted(options)}: {e}; accepted: {sig}") from e
    except ValueError:
        pass  # no signature available (builtin): let the call report
    try:
        det = factory(**options)
    except FisheyeDesError:
        raise
    except Exception as e:  # a plug-in's own failure, reported as a configuration problem
        raise ConfigError(
            f"detector {name!r} could not be built with {options}: {type(e).__name__}: {e}"
        ) from e
    if not isinstance(det, Detector):
        raise ConfigError(
            f"detector {name!r}: {factory!r} returned {type(det).__name__}, expected a Detector"
        )
    if not getattr(det, "name", ""):
        det.name = name
    return det
