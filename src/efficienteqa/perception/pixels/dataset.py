"""Shards of training frames for the pixel network: rendering a folder of them and reading it back.

Shards of up to SHARD_HOUSES houses are compressed ``.npz`` files; ``meta.json`` holds the
vocabulary, the houses, the frame count, the seed and the code version. Several runs into one
folder (training and validation houses) merge their ``meta.json`` when they agree. Only training
houses (``houses.TRAIN_SEEDS``) are recoloured and miss the held-out meshes; the frames of one
house are ``frames.render_house``'s.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import subprocess
import sys
import time
import zipfile
import zlib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.envs.synthetic.house import check_assets
from efficienteqa.errors import EfficientEQAError, first_line
from efficienteqa.perception.pixels.frames import build_vocabulary, render_house
from efficienteqa.perception.pixels.houses import (
    RECOLOUR_SHARE,
    TRAIN_SEEDS,
    VALIDATION_SEEDS,
    check_seeds,
    heldout_model_keys,
)
from efficienteqa.perception.pixels.net import Vocabulary

# What reading a damaged .npz raises: numpy's own errors, the zip archive's and the deflate data's.
SHARD_ERRORS = (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error)
SHARD_HOUSES = 5
ProgressFn = Callable[[int, int], None]


def code_version() -> str:
    """$EFFICIENTEQA_CODE_VERSION (set where a copy of the source runs outside its checkout,
    e.g. on a GPU machine), else ``git describe`` of the checkout this runs from, else the
    package version."""
    if os.environ.get("EFFICIENTEQA_CODE_VERSION"):
        return os.environ["EFFICIENTEQA_CODE_VERSION"]
    try:
        out = subprocess.run(["git", "describe", "--always", "--dirty", "--tags"],
                             cwd=Path(__file__).parent, capture_output=True, text=True, timeout=10)
        if out.returncode == 0 and out.stdout.strip():
            return out.stdout.strip()
    except OSError:
        pass
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("efficienteqa")
    except PackageNotFoundError:
        return "unknown"


def _render_shard(job: tuple[list[int], int, int, dict[str, Any], str, str, float]
                  ) -> tuple[str, int]:
    houses, frames, seed, vocab_json, assets, out, share = job
    vocab = Vocabulary.from_json(vocab_json)
    # only training houses are recoloured and miss the held-out meshes
    parts = [render_house(h, frames, seed, vocab, assets, share if h in TRAIN_SEEDS else 0.0,
                          h in TRAIN_SEEDS) for h in houses]
    arrays = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    path = Path(out) / shard_name(houses)
    tmp = path.with_name(path.stem + ".tmp.npz")
    np.savez_compressed(tmp, **arrays)  # type: ignore[arg-type]
    tmp.replace(path)
    return path.name, len(arrays["house"])


def shard_name(houses: Sequence[int]) -> str:
    return f"houses-{houses[0]}-{houses[-1]}.npz"


def _line_progress(done: int, total: int) -> None:
    sys.stderr.write(f"\rrendered {done}/{total} houses")
    sys.stderr.flush()
    if done == total:
        sys.stderr.write("\n")


def render_dataset(seeds: range, out: Path, frames_per_house: int = 20, seed: int = 0,
                   progress: ProgressFn | bool = True, workers: int = 2,
                   assets: str = "sh3d", recolour_share: float = RECOLOUR_SHARE
                   ) -> dict[str, Any]:
    """Render ``frames_per_house`` frames of every house in ``seeds`` into shards under ``out``
    and merge ``out/meta.json``; returns that metadata. Shards already there are kept."""
    check_seeds(seeds)
    check_assets(assets)
    if frames_per_house < 1:
        raise EfficientEQAError("--frames-per-house must be at least 1")
    if not 0.0 <= recolour_share <= 1.0:
        raise EfficientEQAError("--recolour-share must lie between 0 and 1")
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise EfficientEQAError(f"cannot write to {out}: {exc.strerror}") from None
    vocab = build_vocabulary()
    from efficienteqa.envs.synthetic.env import catalog_for

    heldout = sorted(heldout_model_keys(catalog_for(assets)))
    meta_path = out / "meta.json"
    old = json.loads(meta_path.read_text()) if meta_path.is_file() else None
    if old is not None:
        for key, value in (("vocabulary", vocab.to_json()), ("frames_per_house", frames_per_house),
                           ("seed", seed), ("assets", assets), ("recolour_share", recolour_share),
                           ("heldout_model_keys", heldout)):
            if old.get(key) != value:
                raise EfficientEQAError(f"{out} holds frames rendered with another {key}",
                                        fix="render into a new folder")
    houses = list(seeds)
    jobs = [(houses[i:i + SHARD_HOUSES], frames_per_house, seed, vocab.to_json(), assets, str(out),
             recolour_share) for i in range(0, len(houses), SHARD_HOUSES)]
    todo = [j for j in jobs if not (out / shard_name(j[0])).is_file()]
    report: ProgressFn | None = (_tqdm_progress(len(houses)) if progress is True
                                 else progress or None)
    start = time.perf_counter()
    done = len(houses) - sum(len(j[0]) for j in todo)
    if report:
        report(done, len(houses))
    if workers > 1 and len(todo) > 1:
        ctx = multiprocessing.get_context("spawn")  # one renderer (GL context) per process
        with ctx.Pool(min(workers, len(todo))) as pool:
            for job, _ in zip(todo, pool.imap(_render_shard, todo)):
                done += len(job[0])
                if report:
                    report(done, len(houses))
    else:
        for job in todo:
            _render_shard(job)
            done += len(job[0])
            if report:
                report(done, len(houses))
    all_houses = sorted(set(houses) | set(old["houses"] if old else []))
    meta = {"vocabulary": vocab.to_json(), "frames_per_house": frames_per_house, "seed": seed,
            "assets": assets, "recolour_share": recolour_share, "heldout_model_keys": heldout,
            "houses": all_houses, "frames": len(all_houses) * frames_per_house,
            "size": [240, 320], "code_version": code_version(),
            "train_seeds": [TRAIN_SEEDS.start, TRAIN_SEEDS.stop - 1],
            "validation_seeds": [VALIDATION_SEEDS.start, VALIDATION_SEEDS.stop - 1],
            "minutes": round((time.perf_counter() - start) / 60 + (old or {}).get("minutes", 0), 2)}
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")
    return meta


def _tqdm_progress(total: int) -> ProgressFn:
    try:
        from tqdm import tqdm
    except ImportError:
        return _line_progress
    bar = tqdm(total=total, unit="house", desc="rendering")

    def update(done: int, _total: int) -> None:
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    return update


def load_shards(data: Path, houses: Sequence[int] | None = None) -> dict[str, np.ndarray]:
    """All frames under ``data`` (of ``houses`` only, when given), concatenated. A shard that
    cannot be read whole (a copy cut short, a disk error) is one line naming it: rendering into
    the folder again renders only the shards that are missing."""
    parts = []
    for path in sorted(Path(data).glob("houses-*.npz")):
        if path.name.endswith(".tmp.npz"):
            continue
        try:
            with np.load(path) as shard:
                keep = np.ones(len(shard["house"]), bool) if houses is None else np.isin(
                    shard["house"], list(houses))
                if keep.any():
                    parts.append({k: shard[k][keep] for k in shard.files})
        except SHARD_ERRORS as exc:
            raise EfficientEQAError(f"{path} is not a readable shard of frames ({first_line(exc)})",
                                    fix="delete it and run the efficienteqa perception dataset "
                                        "command that made the folder again: it renders the "
                                        "missing shards only") from None
    if not parts:
        return {}
    try:
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    except (KeyError, ValueError) as exc:
        raise EfficientEQAError(f"the shards in {data} do not fit together ({first_line(exc)})",
                                fix="render the frames into a new folder") from None
