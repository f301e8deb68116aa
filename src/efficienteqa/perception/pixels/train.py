"""Fit the pixel network on rendered frames (``dataset``) and write its weights.

Training houses are every house of the data folder outside VALIDATION_SEEDS; validation houses
those inside it (scored once, at the end, on whole frames: ``validation``). Each step draws
``batch`` crops (``batches``: drawn by rarity, half flipped, cross-entropy on the category,
colour and state maps), with AdamW on a one-cycle schedule of a fixed number of steps: the
command states the steps, so the result is reproducible from it (``minutes`` only guards against
a slow machine; a checkpoint beside the output every ``checkpoint_every`` steps lets ``resume``
continue the same schedule).
"""

from __future__ import annotations

import json
import math
import os
import pickle
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from efficienteqa.errors import EfficientEQAError, first_line
from efficienteqa.perception.pixels.batches import (
    RARITY_SHARE,
    WEIGHT_CROPS,
    CropSampler,
    losses,
    weights_of_counts,
)
from efficienteqa.perception.pixels.dataset import code_version, load_shards
from efficienteqa.perception.pixels.houses import VALIDATION_SEEDS
from efficienteqa.perception.pixels.jobs import CHECKPOINT_EVERY, THREADS, WIDE_WIDTHS, TrainJob
from efficienteqa.perception.pixels.net import PixelNet, Vocabulary, save_weights
from efficienteqa.perception.pixels.validation import evaluate

CROP = (160, 224)  # (height, width) at half size: 2/3 x 0.7 of a 240x320 frame
CHECKPOINT_FORMAT = 1


@dataclass(frozen=True)
class TrainConfig:
    steps: int = 4000
    seed: int = 0
    batch: int = 8
    crop: tuple[int, int] = CROP  # (height, width) at the network's (half) resolution
    lr: float = 4e-3
    weight_decay: float = 1e-4
    widths: tuple[int, ...] = WIDE_WIDTHS
    minutes: float = 90.0
    threads: int = THREADS
    device: str = "auto"  # auto (cuda where there is one) | cpu | cuda
    checkpoint_every: int = CHECKPOINT_EVERY
    resume: bool = False

    def schedule(self) -> dict[str, Any]:
        """What a checkpoint must share with the run that resumes it."""
        return {"steps": self.steps, "seed": self.seed, "batch": self.batch,
                "crop": list(self.crop), "lr": self.lr, "weight_decay": self.weight_decay,
                "widths": list(self.widths)}


def pick_device(name: str) -> torch.device:
    """"auto": cuda when torch sees one, else cpu; "cuda" without one is an error."""
    if name not in ("auto", "cpu", "cuda"):
        raise EfficientEQAError(f"unknown device {name!r}", fix="use auto, cpu or cuda")
    if name == "cuda" and not torch.cuda.is_available():
        raise EfficientEQAError("--device cuda: torch sees no CUDA device",
                                fix="use --device cpu (or auto)")
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    return torch.device(name)


def checkpoint_path(out: Path) -> Path:
    return Path(out).with_suffix(".ckpt")


def check_data(data: Path) -> dict[str, Any]:
    """The data folder's metadata; one-line errors for a missing or empty folder."""
    data = Path(data)
    fix = "render frames first: efficienteqa perception dataset --seeds 3000-3199 --out DIR"
    meta_path = data / "meta.json"
    if not data.is_dir():
        raise EfficientEQAError(f"no data folder {data}", fix=fix)
    if not meta_path.is_file() or not any(data.glob("houses-*.npz")):
        raise EfficientEQAError(f"{data} holds no rendered frames (meta.json and houses-*.npz)",
                                fix=fix)
    try:
        meta: dict[str, Any] = json.loads(meta_path.read_text())
        Vocabulary.from_json(meta["vocabulary"])
        houses = meta.get("houses")
        if not isinstance(houses, list) or not all(type(h) is int for h in houses):
            raise ValueError(f"'houses' must be a list of house seeds, not {houses!r}"[:200])
    except (ValueError, KeyError, TypeError) as exc:
        raise EfficientEQAError(f"unreadable {meta_path}: {exc}", fix=fix) from None
    if not [h for h in meta.get("houses", []) if h not in VALIDATION_SEEDS]:
        raise EfficientEQAError(f"{data} holds validation houses only", fix=fix)
    return meta


def check_writable(out: Path) -> None:
    """A one-line error when ``out`` (a file to be) cannot be written."""
    out = Path(out)
    parent = out.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if out.is_dir() or not os.access(parent, os.W_OK) or (out.exists() and not os.access(out, os.W_OK)):
        raise EfficientEQAError(f"cannot write the weights to {out}",
                                fix="give a writable file path ending in .pt")


def train(data: Path, out: Path, config: TrainConfig = TrainConfig(), command: str = "",
          log: Any = None) -> dict[str, Any]:
    """Train on ``data``, evaluate on its validation houses, write ``out`` (+ .json); returns
    the metadata written; progress goes to ``log`` (None: the standard error of the moment).
    Every ``checkpoint_every`` steps (and when ``minutes`` stops it) the state is saved to
    ``checkpoint_path(out)``; with ``resume`` a matching checkpoint there is continued, giving
    the weights an uninterrupted run gives (on the same device)."""
    log = sys.stderr if log is None else log
    meta = check_data(data)
    check_writable(out)
    device = pick_device(config.device)
    torch.manual_seed(config.seed)
    torch.set_num_threads(config.threads)
    # deterministic kernels on CPU; CUDA's bilinear backward has none (the record says which)
    torch.use_deterministic_algorithms(device.type == "cpu", warn_only=True)
    rng = np.random.default_rng(config.seed)
    vocab = Vocabulary.from_json(meta["vocabulary"])
    houses = sorted(meta["houses"])
    train_houses = [h for h in houses if h not in VALIDATION_SEEDS]
    val_houses = [h for h in houses if h in VALIDATION_SEEDS]
    frames = load_shards(data, train_houses)
    if not frames:
        raise EfficientEQAError(f"{data} holds no frames of its training houses")
    # read before training, not after it: a damaged shard of them must not cost the training
    val = load_shards(data, val_houses) if val_houses else {}
    sampler = CropSampler(frames, vocab, config.crop, rng)
    weights = weights_of_counts(sampler.crop_counts(WEIGHT_CROPS, len(vocab.categories))).to(device)
    net = PixelNet(vocab, config.widths).to(device)
    net.train()
    opt = torch.optim.AdamW(net.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=config.lr, total_steps=config.steps,
                                                pct_start=0.1)
    every = max(1, min(50, config.steps // 20))
    running: dict[str, float] = {}
    history: list[dict[str, float]] = []
    done, before_min, resumed_at = 0, 0.0, None
    ckpt = checkpoint_path(out)
    data_id = {"houses": houses, "frames": int(len(frames["category"]))}
    if config.resume and ckpt.is_file():
        try:  # tensors, numbers and strings only: a checkpoint is never unpickled as code
            state = torch.load(ckpt, map_location=device, weights_only=True)
        except (pickle.UnpicklingError, RuntimeError, ValueError, EOFError, OSError) as exc:
            raise EfficientEQAError(f"{ckpt} is not a readable training checkpoint "
                                    f"({first_line(exc)})",
                                    fix="delete it to train from the start") from None
        if (not isinstance(state, dict) or state.get("schedule") != config.schedule()
                or state.get("data") != data_id):
            raise EfficientEQAError(f"{ckpt} was written by another training (steps, seed, "
                                    "batch, crop, lr, widths or data differ)",
                                    fix="give the same options and data, or delete it")
        net.load_state_dict(state["net"])
        opt.load_state_dict(state["opt"])
        sched.load_state_dict(state["sched"])
        rng.bit_generator.state = state["rng"]
        torch.set_rng_state(state["torch_rng"])
        done, running, history = state["step"], state["running"], state["history"]
        before_min, resumed_at = state["minutes"], state["step"]
        print(f"resuming from {ckpt} at step {done}", file=log, flush=True)

    def save_checkpoint() -> None:
        ckpt.parent.mkdir(parents=True, exist_ok=True)  # --out in a folder not made yet
        tmp = ckpt.with_name(ckpt.name + ".tmp")
        torch.save({"format": CHECKPOINT_FORMAT, "schedule": config.schedule(), "data": data_id,
                    "net": net.state_dict(), "opt": opt.state_dict(),
                    "sched": sched.state_dict(), "rng": rng.bit_generator.state,
                    "torch_rng": torch.get_rng_state(), "step": done, "running": running,
                    "history": history,
                    "minutes": before_min + (time.perf_counter() - start) / 60}, tmp)
        tmp.replace(ckpt)

    start = time.perf_counter()
    first = done
    while done < config.steps:
        if (time.perf_counter() - start) / 60 > config.minutes:
            print(f"stopping at step {done}: --minutes {config.minutes} reached (checkpoint "
                  f"{ckpt}; --resume continues)", file=log, flush=True)
            save_checkpoint()
            break
        x, cat, col, st = (t.to(device, non_blocking=True) for t in sampler.batch(config.batch))
        loss, parts = losses(net, x, cat, col, st, weights)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()
        done += 1
        for k, v in {"loss": float(loss.detach()), **parts, "n": 1.0}.items():
            running[k] = running.get(k, 0.0) + v
        if done % every == 0 or done == config.steps:
            # mean over the steps since the last line (the last window can be shorter)
            n_steps = running.pop("n")
            avg = {k: v / n_steps for k, v in running.items()}
            running = {}
            history.append({"step": done, **{k: round(v, 4) for k, v in avg.items()}})
            elapsed = time.perf_counter() - start
            rate = (done - first) / elapsed
            print(f"step {done}/{config.steps} loss {avg['loss']:.3f} (category "
                  f"{avg['category']:.3f}, colour {avg['colour']:.3f}, state {avg['state']:.3f}) "
                  f"{rate:.2f} steps/s, {elapsed / 60:.1f} min, eta "
                  f"{(config.steps - done) / max(rate, 1e-9) / 60:.1f} min", file=log, flush=True)
        if config.checkpoint_every and done % config.checkpoint_every == 0 and done < config.steps:
            save_checkpoint()
    minutes = before_min + (time.perf_counter() - start) / 60
    rate = (done - first) / max(time.perf_counter() - start, 1e-9)
    del sampler, frames
    validation: dict[str, Any] | None = None
    if val_houses:
        validation = evaluate(net, val, vocab, batch=32 if device.type == "cuda" else 4,
                              device=device)
        brief = {k: v for k, v in validation.items() if k != "iou_per_category"}
        print(f"validation: {json.dumps(brief)}", file=log, flush=True)
    record = {
        "command": command, "seed": config.seed, "steps": config.steps, "steps_done": done,
        "batch": config.batch, "crop": list(config.crop), "lr": config.lr,
        "weight_decay": config.weight_decay, "minutes": round(minutes, 2),
        "minutes_guard": config.minutes, "threads": config.threads, "torch": torch.__version__,
        "device": _device_name(device), "steps_per_s": round(rate, 2),
        "resumed_at_step": resumed_at, "rarity_share": RARITY_SHARE,
        "code_version": code_version(),
        "data": {"houses": [houses[0], houses[-1]] if houses else [],
                 "train_houses": len(train_houses), "validation_houses": val_houses,
                 "frames_per_house": meta.get("frames_per_house"),
                 "render_seed": meta.get("seed"), "assets": meta.get("assets"),
                 "recolour_share": meta.get("recolour_share"),
                 "heldout_model_keys": meta.get("heldout_model_keys"),
                 "train_seed_range": meta.get("train_seeds"),
                 "validation_seed_range": meta.get("validation_seeds")},
        "validation": validation, "loss_history": history[-5:],
        "final_loss": history[-1]["loss"] if history else math.nan,
    }
    net.cpu()
    save_weights(out, net, vocab, record)
    if done >= config.steps and ckpt.is_file():
        ckpt.unlink()  # finished: the weights hold everything
    return record


def _device_name(device: torch.device) -> str:
    if device.type == "cuda":
        return f"cuda ({torch.cuda.get_device_name(device)})"
    return f"cpu ({torch.get_num_threads()} threads)"


def train_as_asked(job: TrainJob) -> dict[str, Any]:
    """``efficienteqa perception train``: the options checked first, each in one line (then
    the data and the output), and ``train`` run with the command that makes its result. That
    command names the data DATA (its houses are in the record's "data"; a path on this machine
    would mean nothing on another); --resume and --device do not change the recipe (the record
    says where it ran and whether it resumed)."""
    if job.steps < 1 or job.batch < 1 or job.threads < 1 or job.checkpoint_every < 0:
        raise EfficientEQAError("--steps, --batch and --threads must be at least 1, "
                                "--checkpoint-every at least 0")
    try:
        widths = tuple(int(w) for w in job.widths.split(","))
    except ValueError:
        raise EfficientEQAError(f"cannot read --widths {job.widths!r}", fix="give 5 numbers such "
                                "as 16,32,64,96,160") from None
    if len(widths) != 5 or min(widths) < 1:
        raise EfficientEQAError(f"--widths needs 5 positive numbers, got {job.widths!r}")
    check_data(job.data)
    check_writable(job.out)
    command = " ".join(["efficienteqa", "perception", "train", "--data", "DATA", "--out",
                        str(job.out), "--steps", str(job.steps), "--seed", str(job.seed),
                        "--batch", str(job.batch), "--minutes", f"{job.minutes:g}", "--threads",
                        str(job.threads), "--widths", ",".join(map(str, widths)), "--device",
                        job.device])
    return train(job.data, job.out,
                 TrainConfig(steps=job.steps, seed=job.seed, batch=job.batch,
                             minutes=job.minutes, threads=job.threads, widths=widths,
                             device=job.device, checkpoint_every=job.checkpoint_every,
                             resume=job.resume),
                 command=command)


def trained_line(record: dict[str, Any], out: Path) -> str:
    """What ``perception train`` prints at the end: the steps, the time and the validation."""
    val = record["validation"] or {}
    figures = ", ".join(f"{k} {val[k]}" for k in ("pixel_accuracy", "mean_iou", "colour_accuracy",
                                                  "state_accuracy") if val.get(k) is not None)
    return (f"{record['steps_done']} steps in {record['minutes']:.1f} min -> {out}"
            + (f"; validation: {figures}" if figures else ""))
