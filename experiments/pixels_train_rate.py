"""Steps/s of the training step (sampler + forward + backward + AdamW) on fake frames, as
experiments/pixels_device_run.sh measures it.

Usage: python -m experiments.pixels_train_rate DEVICE BATCH STEPS THREADS [old]
("old": the crop and widths of the weights committed before the GPU run)."""
import sys
import time

import numpy as np
import torch

from efficienteqa.perception.pixels.batches import CropSampler, losses
from efficienteqa.perception.pixels.frames import build_vocabulary
from efficienteqa.perception.pixels.jobs import WIDE_WIDTHS
from efficienteqa.perception.pixels.net import PixelNet
from efficienteqa.perception.pixels.train import CROP

device, batch, steps, threads = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
if len(sys.argv) > 5 and sys.argv[5] == "old":  # the committed weights' recipe
    CROP, WIDE_WIDTHS = (128, 160), (16, 32, 48, 64, 96)
torch.set_num_threads(threads)
vocab = build_vocabulary()
rng = np.random.default_rng(0)
n = 64
frames = {"rgb": rng.integers(0, 255, (n, 240, 320, 3), dtype=np.uint8),
          "depth": rng.uniform(0.5, 5, (n, 240, 320)).astype(np.float16),
          "category": rng.integers(0, len(vocab.categories), (n, 240, 320), dtype=np.uint8),
          "colour": rng.integers(0, 12, (n, 240, 320), dtype=np.uint8),
          "state": rng.integers(0, 5, (n, 240, 320), dtype=np.uint8)}
sampler = CropSampler(frames, vocab, CROP, rng)
net = PixelNet(vocab, WIDE_WIDTHS).to(device)
opt = torch.optim.AdamW(net.parameters(), lr=1e-3)
weights = torch.ones(len(vocab.categories), device=device)
t0 = None
for step in range(steps + 3):
    if step == 3:
        if device == "cuda":
            torch.cuda.synchronize()
        t0 = time.perf_counter()
    x, cat, col, st = (t.to(device) for t in sampler.batch(batch))
    loss, _ = losses(net, x, cat, col, st, weights)
    opt.zero_grad(set_to_none=True)
    loss.backward()
    opt.step()
    float(loss.detach())
rate = steps / (time.perf_counter() - t0)
print(f"RATE {sys.argv[5:]} {device} batch {batch} threads {threads}: {rate:.2f} steps/s")
