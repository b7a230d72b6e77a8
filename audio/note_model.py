"""A small learned note detector: log-frequency spectra in, note onsets and sounding pitches out.

This is the "model made for it" of issue 18, one of hearing's two ears (audio/transcribe.py;
docs/hearing.md has the candidates measured side by side and why both ears were chosen). Its shape follows what made basic-pitch (Bittner et al.,
ICASSP 2022) small and general — *harmonic stacking*: for each candidate pitch ``p`` (MIDI
21–108) the same weights look at the bands where ``p``'s partials lie (harmonics 1–8) and where
a lower note would put ``p`` among its partials (sub-harmonics ½, ⅓, ¼), so what is learnt about
a harmonic series at one pitch holds at every other, and a few thousand weights suffice.

Three stages, each one cheap matrix product per hop:

1. **Per pitch, per frame**: the 39 stacked band levels (11 harmonic positions × 3 long-spectrum
   bands, 6 short-spectrum semitones) and how much each rose since the frame before (the
   spectral flux of onset detectors, per partial: an organ's repeated note or a bowed swell
   shows there first) → ``H1`` features, with a learnt bias per pitch (a low piano note's
   fundamental is weak; a flute's upper partials are).
2. **Per pitch, over time**: the last ``context`` frames of those features → ``H2``, and from
   them two logits for the frame ``delay`` hops back: *a note began here* (onset) and *a note
   sounds here* (frame). ``delay`` is how far the model may look past the frame it judges: the
   live model looks 3 hops (35 ms), the offline one 6 (a bowed string's swell shows later than a
   piano's hammer).
3. **Across pitches**: each pitch's logits are revised from the logits at the intervals where
   confusions live (octaves, twelfths, the 5th and 6th partials, fifths, fourths, thirds, the
   semitones beside it) — an octave heard because the note below is bright is withdrawn here.

The weights (``audio/models/notes-{live,offline}.npz``: ~21 thousand, and a committee of two
models of ~24 thousand each offline) are trained by
``tools/train_hearing.py`` on audio rendered by fluidsynth from three General MIDI soundfonts —
never a program that plays the samples of FluidR3_GM, the soundfont the tests and the bench
score on — and loaded from a ``.npz`` of plain arrays with the model's layout (never a pickle).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np

from audio.logspectrum import HOP, LONG_LOW, LONG_STEP, SHORT_LOW, SHORT_STEP, LogSpectrum
from creatures.persist import save_npz

LOW, HIGH = 21, 108
"""The pitches the model judges (the piano's compass)."""
PITCHES = np.arange(LOW, HIGH + 1)
HARMONICS = (1 / 4, 1 / 3, 1 / 2, 1, 2, 3, 4, 5, 6, 7, 8)
"""Where a pitch's partials lie (1–8), and where a lower note would hold it as a partial."""
SHORT_HARMONICS = (1, 2, 3, 4, 5, 6)
CROSS = (-36, -28, -24, -19, -12, -7, -5, -4, -3, -1, 1, 3, 4, 5, 7, 12, 19, 24, 28, 31, 36)
"""Intervals (semitones) whose logits each pitch's are revised from."""
ABSENT = -8.0
"""The logit of a pitch beyond the compass, for the across-pitch stage: surely no note."""
MODELS = Path(__file__).with_name("models")
WEIGHTS = ("w1", "b1", "w2", "b2", "w3", "b3", "wc1", "bc1", "wc2", "bc2")
FILE_KEYS = WEIGHTS + ("context", "delay", "threshold", "harmonics", "short_harmonics", "cross")
"""What a weights file holds: the three stages' weights, and the layout they were trained with."""


def stack_index(width: int, harmonics: tuple[float, ...] = HARMONICS,
                short_harmonics: tuple[float, ...] = SHORT_HARMONICS) -> np.ndarray:
    """(pitches, 39) indices into a feature row (``width`` bands, then one zero at ``width``):
    each pitch's harmonic positions in the long bands (±1 band each) and in the short ones."""
    spectrum = LogSpectrum()
    n_long, n_short = spectrum.long_bands.shape[0], spectrum.short_bands.shape[0]
    assert n_long + n_short == width
    rows = []
    for p in PITCHES:
        idx = []
        for h in harmonics:
            centre = int(round((p + 12 * np.log2(h) - LONG_LOW) / LONG_STEP))
            idx += [c if 0 <= c < n_long else width for c in (centre - 1, centre, centre + 1)]
        for h in short_harmonics:
            c = int(round((p + 12 * np.log2(h) - SHORT_LOW) / SHORT_STEP))
            idx.append(n_long + c if 0 <= c < n_short else width)
        rows.append(idx)
    return np.array(rows, dtype=np.intp)


def cross_index(cross: tuple[int, ...] = CROSS) -> np.ndarray:
    """(pitches, len(cross)) indices into a pitch axis padded by one absent pitch at the end."""
    n = len(PITCHES)
    k = np.arange(n)[:, None] + np.array(cross)[None, :]
    return np.where((k >= 0) & (k < n), k, n)


@dataclass
class Judged:
    """The model's judgement of frames ``frame``, ``frame + 1`` … (each ``delay`` hops before the
    row that completed it): per frame and pitch, P(a note began) and P(a note sounds)."""

    frame: int
    onset: np.ndarray
    sounding: np.ndarray


class NoteModel:
    """Runs trained weights over a stream of :class:`audio.logspectrum.LogSpectrum` rows.

    A file may hold a *committee*: several sets of weights trained apart (another seed, another
    shape of look) that judge the same rows, their probabilities averaged. Two models err on
    different notes more than on the same ones, so the mean is surer than either: measured on the
    offline look, 2026-12-06 (docs/hearing.md, "A committee"). The first set's keys are plain
    (``w1`` …, so a one-model file is a committee of one); the others' carry ``m1.``, ``m2.`` …
    (:func:`join`, ``tools/committee.py``, joins exports). All hear one grid (one ``hop``); a
    member that looks less far past the frame it judges (a smaller ``delay``) is held back to
    judge the frame the others judge."""

    def __init__(self, path: Path | str) -> None:
        with np.load(path, allow_pickle=False) as z:
            files = {k: z[k] for k in z.files}
        members = [files] + [{k[len(f"m{i}."):]: v for k, v in files.items() if k.startswith(f"m{i}.")}
                             for i in range(1, 1 + sum(k.startswith("m") and k.endswith(".w1") for k in files))]
        for i, member in enumerate(members):
            missing = sorted(set(FILE_KEYS) - set(member))
            if missing:
                whose = "" if i == 0 else f" (member {i})"
                raise ValueError(f"{path}: not a note model's weights{whose} (no {', '.join(missing)})")
        self._members = [_Member(m) for m in members]
        if len({m.hop for m in self._members}) > 1:
            raise ValueError(f"{path}: a committee's members must hear one grid, not hops of "
                             f"{sorted({m.hop for m in self._members})} samples")
        self.hop = self._members[0].hop
        self.delay = max(m.delay for m in self._members)
        for member in self._members:  # a member that looks less far ahead is heard later, with the others
            member.hold(self.delay - member.delay)
        self.context = max(m.context for m in self._members)
        self.reach = self.delay * self.hop
        """Samples it hears past the frame it judges: a live look's model reaches at most 3 :data:`HOP`."""
        self.threshold = float(members[0]["threshold"])
        """P(onset) through which a rise is a note: tuned with the weights (tools/tune_hearing.py)."""
        self.frames = 0

    def __call__(self, rows: np.ndarray) -> Judged | None:
        """Judge the frames ``delay`` hops before each of ``rows``' frames (``None`` if no rows)."""
        n = len(rows)
        if n == 0:
            return None
        rows = np.ascontiguousarray(rows, dtype=np.float32)
        onset = np.zeros((n, len(PITCHES)), dtype=np.float32)
        sounding = np.zeros_like(onset)
        for member in self._members:
            member.judge(rows, onset, sounding)
        if len(self._members) > 1:
            onset /= len(self._members)
            sounding /= len(self._members)
        first = self.frames - self.delay
        self.frames += n
        return Judged(first, onset, sounding)


class _Member:
    """One set of weights of a :class:`NoteModel` and its stream's state (its context ring and
    the row before), adding its judgement to the committee's sums."""

    def __init__(self, w: dict[str, np.ndarray]) -> None:
        self.context, self.delay = int(w["context"]), int(w["delay"])
        self.hop = int(w["hop"]) if "hop" in w else HOP
        """Samples between the rows it hears (files before the quick look's finer hop have none: 256)."""
        # The model's own layout, kept with its weights: a file trained with other
        # intervals or harmonics runs as it was trained.
        harmonics, short, cross = (tuple(w[k].tolist()) for k in ("harmonics", "short_harmonics", "cross"))
        self._weights = tuple(np.ascontiguousarray(w[k], dtype=np.float32) for k in WEIGHTS)
        width = LogSpectrum().width
        self._stack = stack_index(width, harmonics, short)
        self._cross = cross_index(cross)
        # Stage 1's last ``context`` outputs, a ring (oldest at ``_head``), begun as silence.
        b1 = self._weights[WEIGHTS.index("b1")]
        self._ring = np.repeat(np.maximum(b1, 0.0)[None], self.context, axis=0)
        self._head = 0
        self._previous = np.zeros(width, dtype=np.float32)  # the last row (silence before the first)
        self._onset = self._sounding = np.empty((0, len(PITCHES)), dtype=np.float32)
        self.hold(0)

    def hold(self, rows: int) -> None:
        """Hold its judgements back ``rows`` rows: the committee looks further ahead than it."""
        self.lag = rows
        self._held = (np.zeros((rows, len(PITCHES)), np.float32),) * 2  # before the stream: nothing sounds

    def judge(self, rows: np.ndarray, onset: np.ndarray, sounding: np.ndarray) -> None:
        """Add this member's P(onset) and P(sounding) for ``rows``' judged frames to the sums."""
        n = len(rows)
        if len(self._onset) < n:
            self._onset, self._sounding = np.empty_like(onset), np.empty_like(sounding)
        mine, also = self._onset[:n], self._sounding[:n]
        self._head = _judge(rows, self._previous, self._stack, self._cross, self._ring, self._head,
                            *self._weights, mine, also)
        if self.lag:  # its judgements of the committee's frames came ``lag`` rows ago
            mine, also = np.concatenate([self._held[0], mine]), np.concatenate([self._held[1], also])
            self._held = (mine[n:].copy(), also[n:].copy())
        onset += mine[:n]
        sounding += also[:n]


@numba.njit(cache=True, nogil=True)
def _judge(rows, previous, stack, cross, ring, head, w1, b1, w2, b2, w3, b3, wc1, bc1, wc2, bc2, onset,
           sounding):  # pragma: no cover
    """The three stages for each row, one frame at a time (the ring makes each frame's context).
    Compiled: per frame it is four small matrix products and gathers, which numpy would spend
    more time dispatching than computing (a 390-band row in, judged in ~50 µs)."""
    pitches, k1 = stack.shape
    frames, h1 = ring.shape[0], ring.shape[2]
    width = rows.shape[1]
    n_cross = cross.shape[1]
    gathered = np.empty((pitches, 2 * k1), dtype=np.float32)
    window = np.empty((pitches, frames * h1), dtype=np.float32)
    revise = np.empty((pitches, 2 * n_cross + w2.shape[1]), dtype=np.float32)
    for i in range(rows.shape[0]):
        for p in range(pitches):
            for k in range(k1):
                j = stack[p, k]
                if j < width:
                    gathered[p, k] = rows[i, j]
                    gathered[p, k1 + k] = max(rows[i, j] - previous[j], 0.0)
                else:
                    gathered[p, k] = gathered[p, k1 + k] = 0.0
        previous[:] = rows[i]
        first = np.dot(gathered, w1)
        for p in range(pitches):
            for j in range(h1):
                ring[head, p, j] = max(first[p, j] + b1[p, j], 0.0)
        head = (head + 1) % frames
        for c in range(frames):  # oldest first, as trained
            s = (head + c) % frames
            for p in range(pitches):
                for j in range(h1):
                    window[p, c * h1 + j] = ring[s, p, j]
        second = _biased_relu(np.dot(window, w2), b2)
        logits = np.dot(second, w3)
        for p in range(pitches):
            logits[p, 0] += b3[0]
            logits[p, 1] += b3[1]
        for p in range(pitches):
            for c in range(n_cross):
                q = cross[p, c]
                revise[p, 2 * c] = logits[q, 0] if q < pitches else ABSENT
                revise[p, 2 * c + 1] = logits[q, 1] if q < pitches else ABSENT
            revise[p, 2 * n_cross:] = second[p]
        hidden = _biased_relu(np.dot(revise, wc1), bc1)
        delta = np.dot(hidden, wc2)
        for p in range(pitches):
            onset[i, p] = 1.0 / (1.0 + np.exp(-(logits[p, 0] + delta[p, 0] + bc2[0])))
            sounding[i, p] = 1.0 / (1.0 + np.exp(-(logits[p, 1] + delta[p, 1] + bc2[1])))
    return head


@numba.njit(cache=True, nogil=True, inline="always")
def _biased_relu(x, bias):  # pragma: no cover
    """``max(x + bias, 0)`` row by row, in place."""
    for p in range(x.shape[0]):
        for j in range(x.shape[1]):
            x[p, j] = max(x[p, j] + bias[j], 0.0)
    return x


def join(out: Path | str, members: list[Path | str]) -> None:
    """Write single models' exports as one committee file (see :class:`NoteModel`), atomically.
    Its onset threshold is reset to 0.5: a committee's is its own (tools/tune_hearing.py)."""
    keys: dict[str, np.ndarray] = {}
    hops = {NoteModel(path).hop for path in members}  # a file not a note model's weights is refused by name
    if len(hops) > 1:
        raise ValueError(f"{out}: a committee's members must hear one grid, not hops of {sorted(hops)} samples")
    for i, path in enumerate(members):
        with np.load(path, allow_pickle=False) as z:
            if any(k.startswith("m1.") for k in z.files):
                raise ValueError(f"{path}: already a committee; join single models")
            prefix = "" if i == 0 else f"m{i}."
            keys.update({prefix + k: z[k] for k in z.files if k in FILE_KEYS or k == "hop"})
    keys["threshold"] = np.array(0.5)
    save_npz(out, keys)


def default(look: str) -> Path:
    """The shipped weights for ``look`` ("live", "quick" or "offline")."""
    return MODELS / f"notes-{look}.npz"
