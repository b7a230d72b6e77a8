"""Train the note model (audio/note_model.py) and write its weights as a plain ``.npz``.

Needs PyTorch (a development tool only: the project runs the weights in numpy)::

    pip install torch
    python -m tools.hearing_data /tmp/hearing --segments 300 --seed 1     # and --seed 2, …
    python -m tools.train_hearing /tmp/hearing first.npz --delay 6 --context 10
    python -m tools.train_hearing /tmp/hearing second.npz --delay 6 --context 10 --seed 1 --threads 1
    python -m tools.committee audio/models/notes-offline.npz first.npz second.npz   # offline: a committee of two
    python -m tools.train_hearing /tmp/hearing audio/models/notes-live.npz --delay 3 --context 8
    python -m tools.hearing_data /tmp/hearing128 --from /tmp/hearing --hop 128   # the quick look's grid
    python -m tools.train_hearing /tmp/hearing128 audio/models/notes-quick.npz --delay 4 --context 12 --h1 24
    python -m tools.tune_hearing audio/models/notes-offline.npz audio/models/notes-live.npz audio/models/notes-quick.npz

Every few thousand steps the weights are exported and scored exactly as they will run — the numpy
model behind :class:`audio.transcribe.Transcriber`, streaming — on FluidR3_GM renders (the
soundfont held out of training) of the tests' textures (other seeds than the tests' and the
bench's), with mir_eval's note F1; the best export is kept. ``--init`` continues from an export
(the shipped weights had a first round of 12,000 steps at 3e-3, then rounds at 1e-3 and 7e-4
with material added: organ registrations and plain tones, then clipped rooms; the offline
committee's second member, 2026-12-06, is one round of 30,000 steps from scratch, seed 1, its
last weights).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn

from audio.logspectrum import HOP, RATE
from audio.note_model import CROSS, HARMONICS, PITCHES, SHORT_HARMONICS, cross_index, stack_index


def labels(notes: np.ndarray, frames: int, hop: float = HOP / RATE) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per frame (``hop`` seconds apart) and pitch: a note began (1), the frame after a beginning
    (masked out of the onset loss: an attack late in a hop shows mostly in the next), a note sounds."""
    onset = np.zeros((frames, len(PITCHES)), np.uint8)  # bytes until batched
    mask = np.ones_like(onset)
    sounding = np.zeros_like(onset)
    for a, b, p in notes:
        k = int(p) - PITCHES[0]
        if not 0 <= k < len(PITCHES):
            continue
        i, j = int(a / hop), int(b / hop)
        if i >= frames:
            continue
        onset[i, k] = 1
        if i + 1 < frames:
            mask[i + 1, k] = 0
        sounding[i:min(j, frames - 1) + 1, k] = 1
    return onset, mask, sounding


class Net(nn.Module):
    """The numpy model's three stages, in torch (same shapes, same order of weights)."""

    def __init__(self, width: int, context: int, h1: int, h2: int, hc: int) -> None:
        super().__init__()
        self.context = context
        self.register_buffer("stack", torch.as_tensor(stack_index(width)))
        self.register_buffer("cross", torch.as_tensor(cross_index()))
        n = len(PITCHES)
        self.w1 = nn.Linear(2 * self.stack.shape[1], h1, bias=False)
        self.b1 = nn.Parameter(torch.zeros(n, h1))
        self.w2 = nn.Linear(context * h1, h2)
        self.w3 = nn.Linear(h2, 2)
        self.wc1 = nn.Linear(2 * len(CROSS) + h2, hc)
        self.wc2 = nn.Linear(hc, 2)
        nn.init.zeros_(self.wc2.weight)
        nn.init.zeros_(self.wc2.bias)

    def forward(self, rows: torch.Tensor) -> torch.Tensor:  # rows (B, C + 1, width): a row before the context
        b = rows.shape[0]
        padded = torch.cat([rows, rows.new_zeros(b, self.context + 1, 1)], dim=2)[:, :, self.stack]
        now = padded[:, 1:]
        stacked = torch.cat([now, torch.relu(now - padded[:, :-1])], dim=3)  # levels and their rises
        h1 = torch.relu(self.w1(stacked) + self.b1)  # (B, C, P, H1)
        h2 = torch.relu(self.w2(h1.permute(0, 2, 1, 3).reshape(b, h1.shape[2], -1)))  # (B, P, H2)
        logits = self.w3(h2)
        edge = torch.cat([logits, logits.new_full((b, 1, 2), -8.0)], dim=1)
        around = edge[:, self.cross].reshape(b, logits.shape[1], -1)
        return logits + self.wc2(torch.relu(self.wc1(torch.cat([around, h2], dim=2))))

    def load(self, path: Path) -> None:
        """Start from weights :meth:`export` wrote (a further round of training)."""
        with np.load(path) as z:
            pairs = [(self.w1.weight, z["w1"].T), (self.b1, z["b1"]), (self.w2.weight, z["w2"].T), (self.w2.bias, z["b2"]),
                     (self.w3.weight, z["w3"].T), (self.w3.bias, z["b3"]), (self.wc1.weight, z["wc1"].T),
                     (self.wc1.bias, z["bc1"]), (self.wc2.weight, z["wc2"].T), (self.wc2.bias, z["bc2"])]
        with torch.no_grad():
            for parameter, value in pairs:
                parameter.copy_(torch.as_tensor(value))

    def export(self, path: Path, delay: int, hop: int = HOP, threshold: float = 0.5) -> None:
        def a(t: torch.Tensor) -> np.ndarray:
            return t.detach().cpu().numpy().astype(np.float32)

        np.savez(path, context=np.array(self.context), delay=np.array(delay), hop=np.array(hop), threshold=np.array(threshold),
                 harmonics=np.array(HARMONICS),
                 short_harmonics=np.array(SHORT_HARMONICS), cross=np.array(CROSS),
                 w1=a(self.w1.weight.T), b1=a(self.b1), w2=a(self.w2.weight.T), b2=a(self.w2.bias),
                 w3=a(self.w3.weight.T), b3=a(self.w3.bias), wc1=a(self.wc1.weight.T), bc1=a(self.wc1.bias),
                 wc2=a(self.wc2.weight.T), bc2=a(self.wc2.bias))


VALIDATION = [("piano", 4, "random"), ("piano", 4, "chorale"), ("piano", 1, "random"), ("strings", 1, "random"),
              ("organ", 1, "random"), ("organ", 3, "chorale"), ("flute", 1, "random"), ("guitar", 3, "chorale")]


def validate(model: Path, look: str, seeds: tuple[int, ...] = (101, 102)) -> dict[str, float]:
    """Note F1 per FluidR3 texture (the tests' generators, other seeds), run as the product runs."""
    from audio.transcribe import Transcriber
    from bench._sampled import RANGES, chorale, note_f1, random_texture, render

    textures = {"random": random_texture, "chorale": chorale}
    scores = {}
    for instrument, voices, texture in VALIDATION:
        f1s = []
        for seed in seeds:
            rng = np.random.default_rng([seed, voices])
            notes = textures[texture](rng, voices, 20.0, *RANGES[instrument])
            audio = render(notes, instrument, 22050).mean(axis=1)
            ear = Transcriber(22050, look=look, model=model)
            ear.ended = type(ear.ended)()
            for i in range(0, len(audio), 2048):
                ear.feed(audio[i:i + 2048])
            ear.flush()
            f1s.append(note_f1(notes, [(n.time, n.end, n.pitch) for n in ear.ended]))
        scores[f"{instrument}-{voices}v-{texture}"] = float(np.mean(f1s))
    return scores


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--delay", type=int, default=6)
    parser.add_argument("--context", type=int, default=10)
    parser.add_argument("--h1", type=int, default=32)  # the live and offline weights' shape (the quick look's: 24)
    parser.add_argument("--h2", type=int, default=48)
    parser.add_argument("--hc", type=int, default=32)
    parser.add_argument("--steps", type=int, default=30000)
    parser.add_argument("--batch", type=int, default=128)
    parser.add_argument("--lr", type=float, default=3e-3)
    parser.add_argument("--every", type=int, default=5000, help="steps between validations (0: none, the latest weights written every 5000)")
    parser.add_argument("--look", choices=("live", "quick", "offline"),
                        help="the look the weights serve (default: offline if they judge more than 3 hops of 256 samples "
                             "back, else quick on a finer hop, else live)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--init", type=Path, help="weights to start from (an earlier export of the same shape)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)

    sets, hops = [], set()
    for f in sorted(args.data.glob("*.npz")):
        with np.load(f) as z:
            rows = torch.as_tensor(z["features"])  # float16 until batched: seven sets are ~6 GB
            hops.add(round(float(z["hop"]) * RATE))
            onset, mask, sounding = (torch.as_tensor(a) for a in labels(z["notes"], len(rows), float(z["hop"])))
        sets.append((rows, onset, mask, sounding))
        print(f"{f.name}: {len(rows)} frames, {int(onset.sum())} onsets", flush=True)
    if not sets:
        raise SystemExit(f"{args.data}: no sets (*.npz); render some with tools.hearing_data")
    if len(hops) != 1:
        raise SystemExit(f"{args.data}: sets of different hops {sorted(hops)}: one model hears one grid")
    hop = hops.pop()
    look = args.look or ("offline" if args.delay * hop > 3 * HOP else "quick" if hop < HOP else "live")
    sizes = np.array([len(s[0]) - args.context for s in sets], dtype=float)
    width = sets[0][0].shape[1]
    net = Net(width, args.context, args.h1, args.h2, args.hc)
    if args.init is not None:
        net.load(args.init)
    opt = torch.optim.Adam(net.parameters(), lr=args.lr)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=args.lr, total_steps=args.steps, pct_start=0.05)
    offsets = torch.arange(args.context + 1)  # the context and the row before it (for the rises)
    best, t0 = -1.0, time.time()
    running = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for step in range(1, args.steps + 1):
            which = rng.choice(len(sets), size=args.batch, p=sizes / sizes.sum())
            xs, ons, masks, snds = [], [], [], []
            for s in np.unique(which):
                rows, onset, mask, sounding = sets[s]
                ends = torch.as_tensor(rng.integers(args.context, len(rows), size=int((which == s).sum())))
                xs.append(rows[ends[:, None] - args.context + offsets[None, :]])
                target = ends - args.delay
                ons.append(onset[target]), masks.append(mask[target]), snds.append(sounding[target])
            x, on, m, snd = (torch.cat(t).float() for t in (xs, ons, masks, snds))
            x = x + torch.randn(x.shape[0], 1, 1) * 0.15 * x  # a little level jitter per example
            logits = net(x)
            loss_on = nn.functional.binary_cross_entropy_with_logits(logits[..., 0], on, weight=m,
                                                                     pos_weight=torch.tensor(4.0))
            loss_fr = nn.functional.binary_cross_entropy_with_logits(logits[..., 1], snd)
            loss = loss_on + 0.5 * loss_fr
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            running = 0.98 * running + 0.02 * float(loss.detach())
            if step % 500 == 0:
                print(f"step {step} loss {running:.4f} ({time.time() - t0:.0f} s)", flush=True)
            if not args.every and (step % 5000 == 0 or step == args.steps):
                net.export(args.out, args.delay, hop)  # the latest, to try while it trains
            elif args.every and (step % args.every == 0 or step == args.steps):
                trial = Path(tmp) / "trial.npz"
                net.export(trial, args.delay, hop)
                scores = validate(trial, look)
                mean = float(np.mean(list(scores.values())))
                print(f"step {step}: validation mean F1 {mean:.3f} " + " ".join(f"{k} {v:.2f}" for k, v in scores.items()),
                      flush=True)
                if mean > best:
                    best = mean
                    net.export(args.out, args.delay, hop)
    print(f"best validation mean F1 {best:.3f}; weights in {args.out}" if args.every else f"weights in {args.out}")


if __name__ == "__main__":
    main()
