"""Fit the v2 image tower on a training bundle, on any torch device.

``python -m tower_training.fit BUNDLE --out DIR [--device cuda] [--workers N] [--steps ...]``

The optimisation of :func:`tower_training.training.train_tower_multicaption` (same tower, loss,
augmentations, AdamW with warm-up and cosine decay, learned logit scale, model selection on the
bundle's validation crops at full and half resolution), reading only the bundle
(:mod:`tower_training.bundle`), so it runs where torch and an accelerator are and the simulator is
not. Two things differ, both so that it scales over cores and devices:

* batches come from ``--workers`` loader processes; batch ``k`` is drawn and augmented with its own
  generator, seeded by ``(seed, k)``, so the batches are the same for any worker count;
* crops are padded and resized to the tower's input on the workers and normalised on the device
  (the same table lookup as :func:`conceptfusion.perception.image_tower.preprocess`).

Writes ``DIR/fit.pt`` (the weights with the best validation score so far, the tower and fit
settings, the history, the bundle's SHA-256), rewritten whenever validation improves, so an
interrupted run still leaves its best weights; and ``DIR/last.pt`` (weights, optimiser and step of
the last validation), from which ``--resume`` continues. ``python -m tower_training.train --world
v2 --fit DIR/fit.pt --out TOWER_DIR`` then measures the test sets once and exports ONNX.
On a GPU the result is not bit-reproducible (cuDNN's convolutions); on a CPU with
``--workers 0`` it is, for a given thread count.
"""

from __future__ import annotations

import argparse
import io
import logging
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from conceptfusion.io_utils import atomic_write_bytes
from conceptfusion.perception.image_tower import NORMALISED_LEVELS, TowerConfig, build_tower, square_crops
from tower_training.bundle import Bundle, file_sha256, load_bundle
from tower_training.training import (
    TrainConfig, augment, descend, half_res, load_tower_weights_from_onnx, make_optimiser, multicaption_loss, name_top1,
)

__all__ = ["FitConfig", "step_batch", "fit", "load_fit", "main"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class FitConfig:
    """What :func:`fit` runs."""

    train: TrainConfig = field(default_factory=lambda: TrainConfig(steps=3000, batch_size=96, lr=5e-4,
                                                                    tower=TowerConfig(stem_stride=2), low_res_p=0.5))
    """Optimisation settings and architecture (defaults: the shipped v2 recipe's)."""
    select_every: int = 200
    """Validation every this many steps (and at the end)."""
    workers: int = 0
    """Loader processes (0: batches are made in the training process)."""
    device: str = "cpu"
    """Torch device of the tower."""
    init: str | None = None
    """An exported tower folder whose weights start the run (its batch norms then stay frozen)."""


def step_batch(train_images, labels: np.ndarray, config: TrainConfig, step: int) -> tuple[np.ndarray, np.ndarray]:
    """Batch ``step``: ``batch_size`` crops drawn with replacement and augmented with a generator
    seeded by ``(config.seed, step)``, padded and resized to the tower's input.

    Shape:
        -> ((B, S, S, 3) uint8, (B,) int64 labels).
    """
    rng = np.random.default_rng([config.seed, step])
    idx = rng.integers(0, len(labels), config.batch_size)
    ims = [augment(train_images[i], rng, low_res_p=config.low_res_p, low_res_scale=config.low_res_scale) for i in idx]
    return square_crops(ims, config.tower.input_size), labels[idx]


def _loader(bundle: Bundle, config: FitConfig, start: int):
    import torch

    train_images, labels, tc = bundle.train.images, np.asarray(bundle.train.labels, np.int64), config.train

    class Steps(torch.utils.data.Dataset):
        def __len__(self) -> int:
            return tc.steps - start

        def __getitem__(self, k: int):
            x, y = step_batch(train_images, labels, tc, start + k)
            return torch.from_numpy(x), torch.from_numpy(y)

    kw = {"prefetch_factor": 4, "persistent_workers": False} if config.workers > 0 else {}
    return torch.utils.data.DataLoader(Steps(), batch_size=None, shuffle=False, num_workers=config.workers,
                                       pin_memory=config.device.startswith("cuda"), **kw)


def _save(path: Path, payload: dict) -> None:
    import torch

    buf = io.BytesIO()
    torch.save(payload, buf)
    atomic_write_bytes(path, buf.getvalue())


def fit(bundle: Bundle, config: FitConfig, out_dir: str | Path, *, resume: bool = False, record: dict | None = None,
        log_every: int = 100) -> dict:
    """Train on ``bundle``; writes ``fit.pt`` / ``last.pt`` in ``out_dir`` (module docstring) and
    returns the final ``fit.pt`` payload (``state_dict`` holds the best weights)."""
    import torch

    tc = config.train
    if len(bundle.train.labels) == 0:
        raise ValueError("bundle: expected at least one training crop")
    if bundle.captions_td.shape[1] != tc.tower.embed_dim:
        raise ValueError(f"bundle: caption embeddings have dimension {bundle.captions_td.shape[1]}, "
                         f"the tower {tc.tower.embed_dim}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    dev = torch.device(config.device)
    torch.manual_seed(tc.seed)
    model = build_tower(tc.tower)
    if config.init is not None:
        load_tower_weights_from_onnx(model, str(Path(config.init) / "tower.onnx"))
    model.to(dev)
    logit_scale, opt, lr_at = make_optimiser(model, tc, device=dev)
    history: dict = {"evals": [], "best_step": None, "best_val": None}
    best_state, start = None, 0
    last_file, fit_file = out / "last.pt", out / "fit.pt"
    if resume and last_file.is_file():
        last = torch.load(last_file, map_location=dev, weights_only=False)
        if last["fit_config"] != asdict(config):
            raise ValueError(f"--resume: {last_file} was written with other settings: {last['fit_config']}")
        model.load_state_dict(last["state_dict"])
        opt.load_state_dict(last["optimiser"])
        with torch.no_grad():
            logit_scale.copy_(last["log_logit_scale"].to(dev))
        start, history = last["step"], last["history"]
        if fit_file.is_file():
            best_state = torch.load(fit_file, map_location="cpu", weights_only=False)["state_dict"]
        logger.info("resuming at step %d of %d", start, tc.steps)

    def set_train() -> None:
        model.train()
        if config.init is not None:  # folded batch norms stay the identity
            for m in model.modules():
                if isinstance(m, torch.nn.BatchNorm2d):
                    m.eval()

    table = torch.from_numpy(NORMALISED_LEVELS).to(dev)  # (256, 3)

    def normalise(x_u8):
        x = x_u8.to(dev, non_blocking=True).long()
        return torch.stack([table[:, c][x[..., c]] for c in range(3)], dim=1)  # (B, 3, S, S)

    # the validation crops at full and half resolution, squared once: name_top1 hands each set to embed
    val_sets = [torch.from_numpy(square_crops(ims, tc.tower.input_size)) if len(ims) else None
                for ims in (bundle.val_images, half_res(bundle.val_images))]

    def embed(x_all) -> np.ndarray:
        outs = []
        model.eval()
        with torch.no_grad():
            for s in range(0, len(x_all), 1024):
                outs.append(model(normalise(x_all[s:s + 1024])).float().cpu().numpy())
        set_train()
        return np.concatenate(outs)

    caps = torch.from_numpy(np.ascontiguousarray(bundle.captions_td, np.float32)).to(dev)
    pos = torch.from_numpy(np.asarray(bundle.positives_ct, bool)).to(dev)
    wts = torch.from_numpy(np.asarray(bundle.caption_weights_t, np.float32)).to(dev)
    meta = {"tower_config": asdict(tc.tower), "fit_config": asdict(config), **(record or {})}

    def payload(state) -> dict:
        return {**meta, "state_dict": state, "history": history, "logit_scale": float(logit_scale.exp().item())}

    set_train()
    t0, t_log, step_log = time.perf_counter(), time.perf_counter(), start
    for k, (x_u8, y) in enumerate(_loader(bundle, config, start)):
        step = start + k
        y = y.to(dev, non_blocking=True)
        logits = logit_scale.exp().clamp(max=100.0) * model(normalise(x_u8)) @ caps.T
        loss = multicaption_loss(logits, pos[y], wts)
        descend(opt, loss, lr_at(step))
        if log_every and (step % log_every == 0 or step == tc.steps - 1):
            hit = float(pos[y, logits.argmax(1)].float().mean())
            rate = (step - step_log) / max(1e-9, time.perf_counter() - t_log)
            t_log, step_log = time.perf_counter(), step
            logger.info("step %d/%d loss %.3f batch top-1 caption is a positive %.2f scale %.1f (%.1f steps/s)",
                        step, tc.steps, loss.item(), hit, logit_scale.exp().item(), rate)
        if (step + 1) % config.select_every == 0 or step == tc.steps - 1:
            v = name_top1(embed, val_sets, np.asarray(bundle.val_truth), np.asarray(bundle.names_td, np.float32))
            history["evals"].append({"step": step + 1, "val": v})
            logger.info("step %d: validation %.4f", step + 1, v)
            if history["best_val"] is None or v > history["best_val"]:
                history["best_val"], history["best_step"] = v, step + 1
                best_state = {n: t.detach().cpu().clone() for n, t in model.state_dict().items()}
                _save(fit_file, payload(best_state))
            _save(last_file, {"fit_config": asdict(config), "state_dict": model.state_dict(),
                              "optimiser": opt.state_dict(), "log_logit_scale": logit_scale.detach().cpu(),
                              "step": step + 1, "history": history})
    history["minutes"] = round((time.perf_counter() - t0) / 60, 2)
    final = payload(best_state)
    _save(fit_file, final)
    return final


def load_fit(path: str | Path, tower_config: TowerConfig | None = None):
    """The tower ``fit.pt`` holds (eval mode, CPU) and the payload without its weights."""
    import torch

    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"fit result: expected a fit.pt file at {p}, not found")
    payload = torch.load(p, map_location="cpu", weights_only=False)
    missing = {"state_dict", "tower_config", "fit_config", "history"} - set(payload)
    if missing:
        raise ValueError(f"{p}: expected a fit result of python -m tower_training.fit, missing {sorted(missing)}")
    cfg = TowerConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in payload["tower_config"].items()})
    if tower_config is not None and cfg != tower_config:
        raise ValueError(f"{p}: the fit's tower is {cfg}, expected {tower_config}")
    model = build_tower(cfg)
    model.load_state_dict(payload["state_dict"])
    return model.eval(), {k: v for k, v in payload.items() if k != "state_dict"}


def _parser() -> argparse.ArgumentParser:
    d = FitConfig()
    p = argparse.ArgumentParser(prog="python -m tower_training.fit", description=__doc__.splitlines()[0])
    p.add_argument("bundle", help="a training bundle (python -m tower_training.train --world v2 --bundle FILE)")
    p.add_argument("--out", required=True, help="folder for fit.pt and last.pt")
    p.add_argument("--device", default=d.device, help="torch device (default: cpu; e.g. cuda)")
    p.add_argument("--workers", type=int, default=d.workers, help="loader processes (default: 0)")
    p.add_argument("--steps", type=int, default=d.train.steps)
    p.add_argument("--batch-size", type=int, default=d.train.batch_size)
    p.add_argument("--lr", type=float, default=d.train.lr, help="peak learning rate")
    p.add_argument("--weight-decay", type=float, default=d.train.weight_decay)
    p.add_argument("--low-res-p", type=float, default=d.train.low_res_p)
    p.add_argument("--seed", type=int, default=d.train.seed)
    p.add_argument("--select-every", type=int, default=d.select_every)
    p.add_argument("--widths", default=",".join(str(w) for w in d.train.tower.widths), help="channels per stage")
    p.add_argument("--init", default=None, metavar="TOWER_DIR", help="start from an exported tower's weights")
    p.add_argument("--threads", type=int, default=0, help="torch CPU threads (default: torch's choice)")
    p.add_argument("--resume", action="store_true", help="continue from OUT/last.pt")
    return p


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = _parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    import torch

    if args.threads > 0:
        torch.set_num_threads(args.threads)
    try:
        widths = tuple(int(w) for w in args.widths.split(","))
    except ValueError:
        raise SystemExit(f"--widths: expected comma-separated channel counts, got {args.widths!r}") from None
    if not 0.0 <= args.low_res_p <= 1.0:
        raise SystemExit(f"--low-res-p: expected a probability in [0, 1], got {args.low_res_p}")
    if args.steps < 1 or args.batch_size < 1 or args.select_every < 1 or args.workers < 0:
        raise SystemExit("--steps, --batch-size and --select-every: expected at least 1; --workers at least 0")
    if args.device.startswith("cuda") and not torch.cuda.is_available():
        raise SystemExit(f"--device {args.device}: this torch ({torch.__version__}) sees no CUDA device; "
                         "use --device cpu, or run where torch has a GPU")
    tc = TrainConfig(steps=args.steps, batch_size=args.batch_size, lr=args.lr, weight_decay=args.weight_decay,
                     seed=args.seed, tower=TowerConfig(widths=widths, stem_stride=2), low_res_p=args.low_res_p)
    config = FitConfig(train=tc, select_every=args.select_every, workers=args.workers, device=args.device, init=args.init)
    bundle = load_bundle(args.bundle)
    record = {"bundle": {"file": str(args.bundle), "sha256": file_sha256(args.bundle), "meta": bundle.meta},
              "command": "python -m tower_training.fit " + " ".join(argv), "torch": torch.__version__,
              "device_name": torch.cuda.get_device_name(0) if args.device.startswith("cuda") else "cpu"}
    print(f"bundle: {len(bundle.train.labels)} training crops, {len(bundle.captions_td)} captions, "
          f"{len(bundle.val_truth)} validation crops", flush=True)
    result = fit(bundle, config, args.out, resume=args.resume, record=record)
    h = result["history"]
    print(f"fitted {tc.steps} steps in {h['minutes']:.1f} min; best validation {h['best_val']:.4f} at step {h['best_step']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
