"""Optional SAM / MobileSAM mask proposals (the official ConceptFusion code's proposer).

Used when a user supplies a checkpoint (registry spec ``"sam:/path/to/checkpoint.pth"``).
The packages are imported only when a :class:`SamProposer` is built: ``segment_anything``
for ViT-H/L/B checkpoints, ``mobile_sam`` for MobileSAM's ViT-T (either works for the
others if only it is installed). SAM's automatic generator also needs ``torchvision``.

Defaults follow the official ConceptFusion code: 8 points per side, predicted-IoU
threshold 0.92, one crop layer with the point count halved per layer. The depth and
intrinsics the protocol passes are ignored: SAM sees only the image.
"""

from __future__ import annotations

import logging
import re
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from conceptfusion.errors import CheckpointError, MissingDependencyError
from conceptfusion.perception.masks.base import check_frame, empty_masks

__all__ = ["SamConfig", "SamProposer", "SAM_INSTALL_HINT", "check_checkpoint", "infer_model_type"]

log = logging.getLogger(__name__)

SAM_INSTALL_HINT = (
    'pip install "conceptfusion-harness[sam]" (segment-anything and torchvision), or pip install mobile_sam '
    "for MobileSAM checkpoints"
)
"""What to install for the SAM backend; part of every missing-package error."""

_MODEL_TYPES = ("vit_h", "vit_l", "vit_b", "vit_t")
# torch.save's zip container, and a bare pickle (protocol 2+) of older torch versions.
_CHECKPOINT_MAGIC = (b"PK\x03\x04", b"\x80")


@dataclass(frozen=True)
class SamConfig:
    """Settings of SAM's automatic mask generator (defaults: the official ConceptFusion code)."""

    points_per_side: int = 8
    """Prompt points along each side of the image grid."""
    pred_iou_thresh: float = 0.92
    """Masks with a lower predicted IoU are dropped."""
    stability_score_thresh: float = 0.95
    """Masks with a lower stability score are dropped (SAM's default)."""
    crop_n_layers: int = 1
    """Layers of image crops the generator also runs on (0: the whole image only)."""
    crop_n_points_downscale_factor: int = 2
    """Prompt points per side are divided by this factor at each crop layer."""
    min_mask_region_area: int = 0
    """Disconnected islands and holes smaller than this (pixels) are removed (0: off)."""
    points_per_batch: int = 64
    """Prompt points the model decodes at once (memory, not results)."""

    def __post_init__(self) -> None:
        for name in ("points_per_side", "crop_n_points_downscale_factor", "points_per_batch"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name}: expected at least 1, got {getattr(self, name)}")
        for name in ("crop_n_layers", "min_mask_region_area"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name}: expected >= 0, got {getattr(self, name)}")
        for name in ("pred_iou_thresh", "stability_score_thresh"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name}: expected a value in [0, 1], got {getattr(self, name)}")


def check_checkpoint(path) -> Path:
    """Validate a checkpoint path before any model code runs: it must exist, be a non-empty
    file and start like a PyTorch checkpoint (zip container or pickle).

    Raises :class:`CheckpointError` naming the path and what is wrong.
    """
    if not isinstance(path, (str, Path)):
        raise TypeError(f"checkpoint: expected a path (str or Path), got {type(path).__name__}")
    p = Path(path).expanduser()
    if not p.exists():
        raise CheckpointError(f"checkpoint: {p} does not exist (download a SAM or MobileSAM checkpoint and pass its path)")
    if not p.is_file():
        raise CheckpointError(f"checkpoint: {p} is not a file")
    with open(p, "rb") as fh:
        head = fh.read(4)
    if not head:
        raise CheckpointError(f"checkpoint: {p} is empty")
    if not head.startswith(_CHECKPOINT_MAGIC):
        raise CheckpointError(f"checkpoint: {p} is not a PyTorch checkpoint (unexpected file header {head!r})")
    return p


def infer_model_type(path: Path) -> str:
    """SAM model type from a checkpoint's file name (``sam_vit_h_4b8939.pth`` -> ``vit_h``,
    ``mobile_sam.pt`` -> ``vit_t``); ``ValueError`` when the name does not say."""
    name = path.name.lower()
    match = re.search(r"vit_([hlbt])", name)
    if match:
        return f"vit_{match.group(1)}"
    if "mobile" in name:
        return "vit_t"
    raise ValueError(
        f"model_type: cannot tell the SAM variant from the file name {path.name!r}; pass model_type= one of {_MODEL_TYPES}"
    )


def _import_backend(model_type: str):
    """``(sam_model_registry, SamAutomaticMaskGenerator)`` of the package that builds ``model_type``."""
    modules = ("mobile_sam",) if model_type == "vit_t" else ("segment_anything", "mobile_sam")
    errors = []
    for module in modules:
        try:
            pkg = __import__(module, fromlist=["sam_model_registry", "SamAutomaticMaskGenerator"])
            return pkg.sam_model_registry, pkg.SamAutomaticMaskGenerator
        except ImportError as exc:  # the package, or torchvision under it, is missing
            errors.append(f"{module}: {exc}")
    raise MissingDependencyError(
        f"the SAM mask proposer ({model_type}) needs an optional package that could not be imported "
        f"({'; '.join(errors)}); install it with: {SAM_INSTALL_HINT}"
    )


class SamProposer:
    """Masks from SAM's (or MobileSAM's) automatic mask generator.

    Building it validates the checkpoint, imports the package and loads the weights (all
    errors surface here, not at the first frame).

    Args:
        checkpoint: path to a SAM (``sam_vit_h_4b8939.pth``, ...) or MobileSAM
            (``mobile_sam.pt``) checkpoint.
        model_type: ``"vit_h"``, ``"vit_l"``, ``"vit_b"`` or ``"vit_t"``; inferred from the
            file name when ``None``.
        config: generator settings (:class:`SamConfig`).
        device: torch device string.

    Raises:
        CheckpointError: missing, empty or non-PyTorch checkpoint, or weights that do not
            fit the model.
        MissingDependencyError: ``segment_anything`` / ``mobile_sam`` (or torchvision) is
            not installed; the message says what to install.
    """

    privileged = False

    def __init__(self, checkpoint, *, model_type: str | None = None, config: SamConfig = SamConfig(),
                 device: str = "cpu") -> None:
        if not isinstance(config, SamConfig):
            raise TypeError(f"config: expected SamConfig, got {type(config).__name__}")
        path = check_checkpoint(checkpoint)
        mtype = infer_model_type(path) if model_type is None else model_type
        if mtype not in _MODEL_TYPES:
            raise ValueError(f"model_type: expected one of {_MODEL_TYPES}, got {mtype!r}")
        registry, generator_cls = _import_backend(mtype)
        import torch

        model = registry[mtype](checkpoint=None)
        try:
            state = torch.load(path, map_location="cpu", weights_only=True)
            if isinstance(state, dict) and "model" in state and isinstance(state["model"], dict):
                state = state["model"]
            model.load_state_dict(state)
        except Exception as exc:  # torch raises several types for truncated or foreign files
            raise CheckpointError(f"checkpoint: {path} could not be loaded as a {mtype} SAM model: {exc}") from exc
        model.to(device).eval()
        self.config = config
        self.model_type = mtype
        self.checkpoint = path
        self._generator = generator_cls(model, **asdict(config))
        log.info("SAM proposer: %s from %s on %s", mtype, path, device)

    def propose(self, rgb_hw3, depth_hw, K_33) -> np.ndarray:
        """Masks of one frame in SAM's output order (depth and intrinsics are only validated).

        Shape:
            (H, W, 3) uint8, (H, W), (3, 3) -> ``masks_rhw`` (R, H, W) bool.
        """
        rgb, _, _ = check_frame(rgb_hw3, depth_hw, K_33)
        import torch

        with torch.inference_mode():
            records = self._generator.generate(rgb)
        if not records:
            return empty_masks(*rgb.shape[:2])
        return np.stack([np.asarray(r["segmentation"], bool) for r in records])
