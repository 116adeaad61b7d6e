"""``kornia``: weight-free corner responses (GFTT / Harris / Hessian / DoG) from kornia + NMS.

kornia and torch are an optional extra (``pip install fisheye-des[kornia]``), imported lazily when
the detector is built. Runs on CUDA when available (``device="auto"``), else on the CPU.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from estimators.errors import ConfigError
from trackers.detectors.base import Detections, Detector, register_detector, to_grey, torch_device
from trackers.detectors.orb import bucket

RESPONSES = ("gftt", "harris", "hessian", "dog")


def _import_torch() -> tuple[Any, Any]:
    try:
        import kornia
        import torch
    except ImportError as e:
        raise ConfigError("detector 'kornia' needs kornia and torch: pip install fisheye-des[kornia]") from e
    return torch, kornia


@register_detector("kornia")
class KorniaDetector(Detector):
    """Corner response from kornia, local-maximum suppression, grid bucketing, strongest kept.

    Args:
        response: one of ``gftt`` (Shi-Tomasi), ``harris``, ``hessian`` (determinant), ``dog``
            (difference of Gaussians, SIFT-like blob response).
        max_features: keypoints wanted per frame.
        nms_radius_px: suppression radius (a keypoint is the maximum of its (2r+1)^2 window).
        min_response: relative threshold: keep responses above ``min_response * max response``.
        grid: (cols, rows) bucketing grid.
        device: ``"auto"`` (CUDA when available), ``"cpu"``, ``"cuda"`` or ``"cuda:N"``.
    """

    def __init__(
        self,
        response: str = "gftt",
        max_features: int = 600,
        nms_radius_px: int = 4,
        min_response: float = 0.01,
        grid: tuple[int, int] = (16, 9),
        device: str = "auto",
    ) -> None:
        if response not in RESPONSES:
            raise ConfigError(
                f"detector 'kornia': unknown response {response!r}; expected one of {', '.join(RESPONSES)}"
            )
        self.torch, self.kornia = _import_torch()
        self.device = torch_device(self.torch, device, "kornia")
        self.response = response
        self.max_features = int(max_features)
        self.nms_radius_px = int(nms_radius_px)
        self.min_response = float(min_response)
        self.grid = (int(grid[0]), int(grid[1]))

    def __getstate__(self) -> dict:
        """Picklable (a live run's detection worker process gets the detector): the torch and kornia
        modules are imported again, not pickled."""
        return {k: v for k, v in self.__dict__.items() if k not in ("torch", "kornia")}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.torch, self.kornia = _import_torch()

    def detect(self, image: np.ndarray, mask: np.ndarray | None = None) -> Detections:
        """See Detector.detect; keypoints without descriptors."""
        torch, kornia = self.torch, self.kornia
        grey = to_grey(image)
        with torch.no_grad():
            t = (
                torch.from_numpy(np.ascontiguousarray(grey)).to(self.device, torch.float32)[None, None]
                / 255.0
            )
            if self.response == "gftt":
                r = kornia.feature.gftt_response(t)
            elif self.response == "harris":
                r = kornia.feature.harris_response(t)
            elif self.response == "hessian":
                r = kornia.feature.hessian_response(t).abs()
            else:
                r = kornia.feature.dog_response_single(t).abs()
            if mask is not None:
                r = r * torch.from_numpy(mask > 0).to(self.device, torch.float32)[None, None]
            k = 2 * self.nms_radius_px + 1
            mx = torch.nn.functional.max_pool2d(r, k, stride=1, padding=self.nms_radius_px)
            thr = float(r.max()) * self.min_response
            keep = (r == mx) & (r > thr) & (r > 0)
            ys, xs = torch.nonzero(keep[0, 0], as_tuple=True)
            sc = r[0, 0, ys, xs].float().cpu().numpy()
            uv = torch.stack([xs, ys], 1).float().cpu().numpy()
        if len(uv) == 0:
            return Detections.empty()
        per_cell = max(1, int(np.ceil(self.max_features / (self.grid[0] * self.grid[1]) * 2)))
        idx = bucket(uv, sc, grey.shape[:2], self.grid, per_cell)[: self.max_features]
        return Detections(keypoints=uv[idx], scores=sc[idx])
