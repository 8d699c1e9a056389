"""Per-frame pixel-aligned features, end to end, and the quality of the mask proposals.

    python benchmarks/bench_features.py [--frames 12] [--sizes 64 96]

One 240x320 RGB-D frame goes through: mask proposals (the default RGB-D proposer), one crop
per mask (tight box), ONE batched encoder call for the whole image plus every crop, and
the paper's mixing (eqs. 3-6, palette form). Encoders measured:

* ``ColorNameEncoder``: the built-in test encoder (colour histograms, no network);
* a stand-in CPU CNN of realistic size: the embedded image tower's residual architecture
  (:func:`conceptfusion.perception.image_tower.build_tower`) widened to about 5 M parameters, random
  weights, 512-d output, on crops padded to squares and resized to 64x64 or 96x96, run
  in ``torch.inference_mode`` (channels-last layout) and in onnxruntime (how the embedded
  encoder runs). Weights do not change the cost, so the figure stands for a trained
  tower of that size.

Target (2-core CPU): at most 0.5 s per frame. Timings need an otherwise idle machine: torch's
OpenMP threads slow down several-fold when other processes compete for the two cores. Also reports the mean best-IoU of the
proposals against the ground-truth instance masks (objects only; floor, walls and table
are background) on the tabletop scene and on a cluttered room.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _scenes import room_boxes, room_trajectory  # noqa: E402

from conceptfusion.cameras import intrinsics_from_fovy  # noqa: E402
from conceptfusion.perception.encoders import ColorNameEncoder  # noqa: E402
from conceptfusion.perception.features import crop_masks, pixel_aligned_palette  # noqa: E402
from conceptfusion.perception.masks.rgbd import RGBDProposer  # noqa: E402
from conceptfusion.synthetic import orbit_poses, render_boxes, tabletop_boxes  # noqa: E402

H, W = 240, 320


def tabletop_frames(num: int):
    K = intrinsics_from_fovy(60.0, W, H)
    boxes = tabletop_boxes()
    far = orbit_poses((0.0, 0.0, 0.45), 1.3, 0.8, num - num // 3)
    near = orbit_poses((0.0, 0.0, 0.45), 0.9, 0.5, num // 3, start_deg=20.0)
    return [render_boxes(boxes, K, pose, H, W) for pose in far + near], range(2, len(boxes))


def room_frames(num: int):
    K = intrinsics_from_fovy(60.0, W, H)
    boxes = room_boxes(0)
    return [render_boxes(boxes, K, pose, H, W) for pose in room_trajectory(num)], range(5, len(boxes))


def best_ious(frames, objects, proposer, min_px: int = 100) -> list[float]:
    """Best IoU of any proposal with each object showing at least ``min_px`` pixels."""
    out = []
    for f in frames:
        masks = proposer.propose(f.rgb, f.depth, f.K)
        for obj in objects:
            truth = f.segmentation == obj
            if truth.sum() < min_px:
                continue
            if len(masks) == 0:
                out.append(0.0)
                continue
            inter = (masks & truth).sum(axis=(1, 2))
            union = (masks | truth).sum(axis=(1, 2))
            out.append(float((inter / union).max()))
    return out


class StandInCNN:
    """A ~5 M-parameter residual CNN on CPU (random weights) behind the encoder's image API.

    ``runtime`` is ``"torch"`` (``inference_mode``, channels-last layout) or ``"onnxruntime"``
    (the graph exported as the embedded encoder ships it).
    """

    def __init__(self, input_size: int, runtime: str, dim: int = 512) -> None:
        import torch

        from conceptfusion.perception.image_tower import TowerConfig, build_tower, export_tower_onnx, preprocess

        self.torch = torch
        self.preprocess = preprocess
        self.size = input_size
        self.runtime = runtime
        torch.manual_seed(0)
        cfg = TowerConfig(embed_dim=dim, input_size=input_size, widths=(42, 84, 168, 336))
        self.model = build_tower(cfg).eval()
        self.params = sum(p.numel() for p in self.model.parameters())
        if runtime == "torch":
            self.model = self.model.to(memory_format=torch.channels_last)
        else:
            import onnxruntime as ort

            with tempfile.TemporaryDirectory() as tmp:
                path = export_tower_onnx(self.model, cfg, tmp)
                opts = ort.SessionOptions()
                opts.intra_op_num_threads = 2
                self.session = ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])

    def prepare(self, images) -> np.ndarray:
        return self.preprocess(images, self.size)

    def encode_batch(self, x: np.ndarray) -> np.ndarray:
        if self.runtime != "torch":
            return self.session.run(None, {"images": x})[0]
        with self.torch.inference_mode():
            t = self.torch.from_numpy(x).contiguous(memory_format=self.torch.channels_last)
            return self.model(t).numpy()


def end_to_end(frames, proposer, prepare, encode):
    """Per-frame stage times (seconds) and mask counts."""
    stages = {"proposals": [], "crop+resize": [], "encoder": [], "mixing": [], "total": []}
    counts = []
    for f in frames:
        rgb = f.rgb
        t0 = time.perf_counter()
        masks = proposer.propose(rgb, f.depth, f.K)
        t1 = time.perf_counter()
        batch = prepare([rgb] + crop_masks(rgb, masks))
        t2 = time.perf_counter()
        emb = encode(batch)  # the whole image and every crop in ONE call
        t3 = time.perf_counter()
        feats = pixel_aligned_palette(emb[0], emb[1:], masks, image_hw=rgb.shape[:2])
        t4 = time.perf_counter()
        assert feats.index_hw.shape == (H, W)
        for key, dt in zip(stages, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t4 - t0)):
            stages[key].append(dt)
        counts.append(len(masks))
    return stages, counts


def report(name: str, stages, counts) -> None:
    total = stages["total"]
    parts = ", ".join(f"{k} {1000 * statistics.mean(v):.1f}" for k, v in stages.items() if k != "total")
    verdict = "OK" if statistics.median(total) <= 0.5 else "OVER the 0.5 s target"
    print(f"{name}: {1000 * statistics.mean(total):.0f} ms/frame mean, {1000 * statistics.median(total):.0f} ms median, "
          f"{1000 * max(total):.0f} ms worst  [{verdict}]")
    print(f"  breakdown (ms, mean): {parts}")
    print(f"  masks per frame: mean {statistics.mean(counts):.1f}, min {min(counts)}, max {max(counts)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=12, help="frames per scene")
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 96], help="CNN input sizes")
    args = ap.parse_args()

    try:
        import torch

        torch.set_num_threads(2)
    except ImportError:
        torch = None

    proposer = RGBDProposer()
    table, table_objects = tabletop_frames(args.frames)
    room, room_objects = room_frames(args.frames)
    proposer.propose(table[0].rgb, table[0].depth, table[0].K)  # compile the kernels once
    frames = table + room

    print(f"pixel-aligned features of one {H}x{W} frame, {len(frames)} frames (tabletop + room), 2-core CPU\n")
    color = ColorNameEncoder(512)
    stages, counts = end_to_end(frames, proposer, lambda imgs: imgs, color.encode_image)
    report("ColorNameEncoder (512-d)", stages, counts)
    if torch is None:
        print("stand-in CNN: skipped (torch is not installed)")
    for runtime in ("torch", "onnxruntime") if torch is not None else ():
        for size in args.sizes:
            cnn = StandInCNN(size, runtime)
            cnn.encode_batch(cnn.prepare([table[0].rgb] * 16))  # warm-up
            stages, counts = end_to_end(frames, proposer, cnn.prepare, cnn.encode_batch)
            report(f"stand-in CNN {cnn.params / 1e6:.1f} M params, {size}x{size} crops, 512-d, {runtime}", stages, counts)
    print("\nproposal quality: best IoU of any proposal with each ground-truth object (>= 100 px visible)")
    for name, scene, objects in (("tabletop", table, table_objects), ("room", room, room_objects)):
        ious = np.array(best_ious(scene, objects, proposer))
        print(f"  {name}: mean best-IoU {ious.mean():.3f} over {len(ious)} object views, "
              f"median {np.median(ious):.3f}, share >= 0.5: {np.mean(ious >= 0.5):.2f}")


if __name__ == "__main__":
    main()
