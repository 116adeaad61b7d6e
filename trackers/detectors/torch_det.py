"""``torch``: a user's own box detector, a ``torch.export`` program (``.pt2``), a TorchScript
(``.pt``/``.pth``/``.ts``) or an ONNX (``.onnx``) file given by path. Nothing is downloaded.

Model contract: input a float32 tensor (1, 3, H, W), BGR->RGB, values in [0, 1] (``input_size`` =
(W, H) resizes first); output a tensor (M, 4..6) or (1, M, 4..6) of rows
``[x1, y1, x2, y2, score?, class?]`` (torch models: or a tuple or list whose first item is that tensor)
in the input's pixels (scaled back to the frame here). Rows below ``min_score`` are dropped;
``class_names`` maps class indices to labels. A model that fails, or returns anything else, is an
InputError naming the model and what was expected.
An exported program is specialised to the input shape it was exported with unless exported with dynamic
shapes: give that shape as ``input_size``. torch 2.13 deprecates TorchScript (``torch.jit``) in favour of
``torch.export``; both load. Torch models need torch (``pip install fisheye-des[kornia]``); ONNX runs on
cv2.dnn.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from estimators.errors import ConfigError, InputError
from trackers.detectors.base import Detections, Detector, register_detector, torch_device


@register_detector("torch")
class TorchModelDetector(Detector):
    """Boxes from a user's exported (``.pt2``), TorchScript or ONNX model (see the module docstring for
    the contract).

    Args:
        model_path: path of the ``.pt2``, TorchScript or ``.onnx`` file.
        input_size: (W, H) the model expects, or None to feed the frame's own size.
        min_score: drop boxes scored below this.
        class_names: labels by class index; default ``"object"`` / ``"class<k>"``.
        device: ``"auto"``, ``"cpu"``, ``"cuda"`` or ``"cuda:N"`` (torch models only).
    """

    produces_keypoints = False
    produces_boxes = True

    def __init__(
        self,
        model_path: str | Path = "",
        input_size: tuple[int, int] | None = None,
        min_score: float = 0.5,
        class_names: Sequence[str] = (),
        device: str = "auto",
    ) -> None:
        expected = ("expected the path of your torch.export (.pt2), TorchScript (.pt/.pth/.ts) or ONNX "
                    "(.onnx) model (in a config: detector.options.model_path, or as a composite's part, e.g. "
                    "orb+torch: detector.options.torch.model_path; nothing is downloaded)")
        if not model_path:
            raise ConfigError(f"detector 'torch': no model_path given; {expected}")
        path = Path(model_path)
        if not path.is_file():
            raise ConfigError(f"detector 'torch': model_path {str(model_path)!r} is not a file; {expected}")
        self.path = path
        self.input_size = None if input_size is None else (int(input_size[0]), int(input_size[1]))
        self.min_score = float(min_score)
        self.class_names = tuple(class_names)
        self._net: Any = None
        self._module: Any = None
        if path.suffix.lower() == ".onnx":
            try:
                self._net = cv2.dnn.readNetFromONNX(str(path))
            except cv2.error as e:
                raise ConfigError(f"detector 'torch': cv2.dnn cannot read ONNX model {path}: {e}") from e
        else:
            try:
                import torch
            except ImportError as e:
                raise ConfigError(
                    "detector 'torch' with a torch model needs torch: pip install fisheye-des[kornia]"
                ) from e
            self._torch = torch
            self.device = torch_device(torch, device, "torch")
            exported = path.suffix.lower() == ".pt2"
            loader = "torch.export.load" if exported else "torch.jit.load"
            try:
                if exported:  # an ExportedProgram: its module runs as exported (eval mode is fixed then);
                    # moved by torch's pass, which rewrites the graph's device constants too (.to() does not)
                    from torch.export.passes import move_to_device_pass

                    self._module = move_to_device_pass(torch.export.load(str(path)), self.device).module()
                else:
                    self._module = torch.jit.load(str(path), map_location=self.device).eval()
            except Exception as e:
                raise ConfigError(f"detector 'torch': {loader} cannot read {path}: {e}") from e

    def _run(self, rgb01: np.ndarray) -> np.ndarray:
        blob = np.ascontiguousarray(rgb01.transpose(2, 0, 1)[None], dtype=np.float32)
        # the user's model is not ours: any failure inside it is bad input (exit 2), named with the input
        failed = f"detector 'torch': model {self.path.name} failed on a float32 input of shape {blob.shape}"
        if self._net is not None:
            try:
                self._net.setInput(blob)
                out = self._net.forward()
            except cv2.error as e:
                raise InputError(f"{failed}: {e}") from e
        else:
            torch = self._torch
            with torch.no_grad():
                try:
                    out = self._module(torch.from_numpy(blob).to(self.device))
                except Exception as e:  # TorchScript's message: its traceback, then "RuntimeError: ..."; an
                    # exported program's shape guard: "Guard failed: x.size()[2] == 48" (see input_size)
                    lines = [ln.strip() for ln in str(e).splitlines() if ln.strip()]
                    why = lines[-1] if len(lines) > 1 else f"{type(e).__name__}: {''.join(lines)}"
                    if self.path.suffix.lower() == ".pt2":
                        why += ("; an exported program takes the input shape it was exported with unless "
                                "exported with dynamic shapes: give its (W, H) as "
                                "detector.options.input_size")
                    raise InputError(f"{failed}: {why}") from e
                if isinstance(out, (tuple, list)) and out:
                    out = out[0]  # (boxes, ...) as many detection models return
                if not isinstance(out, torch.Tensor):
                    raise InputError(
                        f"detector 'torch': model {self.path.name} returned a {type(out).__name__}; expected "
                        "a tensor (M, 4..6) or (1, M, 4..6) of rows [x1, y1, x2, y2, score?, class?] (or a "
                        "tuple or list whose first item is one)"
                    )
                out = out.detach().float().cpu().numpy()
        out = np.asarray(out, dtype=np.float64)
        if out.ndim == 3 and out.shape[0] == 1:
            out = out[0]
        if out.size == 0:
            return np.zeros((0, 6))
        if out.ndim != 2 or not 4 <= out.shape[1] <= 6:
            raise InputError(
                f"detector 'torch': model {self.path.name} returned shape {out.shape}; "
                "expected (M, 4..6) rows "
                "[x1, y1, x2, y2, score?, class?]"
            )
        return out

    def detect(self, image: np.ndarray, mask: np.ndarray | None = None) -> Detections:
        """See Detector.detect; boxes whose centre lies outside ``mask`` are dropped."""
        bgr = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        h, w = bgr.shape[:2]
        inp = (
            bgr if self.input_size is None else cv2.resize(bgr, self.input_size, interpolation=cv2.INTER_AREA)
        )
        rgb01 = cv2.cvtColor(inp, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
        out = self._run(rgb01)
        out = out[np.all(np.isfinite(out), axis=1)]
        sx = w / inp.shape[1]
        sy = h / inp.shape[0]
        boxes = out[:, :4] * [sx, sy, sx, sy]
        boxes = np.stack(
            [
                np.minimum(boxes[:, 0], boxes[:, 2]),
                np.minimum(boxes[:, 1], boxes[:, 3]),
                np.maximum(boxes[:, 0], boxes[:, 2]),
                np.maximum(boxes[:, 1], boxes[:, 3]),
            ],
            1,
        )
        scores = out[:, 4] if out.shape[1] > 4 else np.ones(len(out))
        cls = out[:, 5].astype(int) if out.shape[1] > 5 else np.full(len(out), -1)
        keep = scores >= self.min_score
        if mask is not None and len(boxes):
            cu = np.clip(((boxes[:, 0] + boxes[:, 2]) / 2).astype(int), 0, w - 1)
            cv = np.clip(((boxes[:, 1] + boxes[:, 3]) / 2).astype(int), 0, h - 1)
            keep &= mask[cv, cu] > 0
        if not np.any(keep):
            return Detections.empty()
        labels = tuple(self._label(int(c)) for c in cls[keep])
        return Detections(
            boxes=boxes[keep],
            box_scores=np.clip(scores[keep], 0, 1),
            labels=labels,
            attributes=tuple({"class_id": int(c)} for c in cls[keep]),
        )

    def _label(self, c: int) -> str:
        if c < 0:
            return "object"
        return self.class_names[c] if c < len(self.class_names) else f"class{c}"
