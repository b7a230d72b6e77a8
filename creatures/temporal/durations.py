"""Duration models for Do-until (thesis: "temporal models – simple durations" and "exotic
duration models", figure 11 "low integer ratio blind duration models").

A Du that says "for around 5 s" samples a duration model when its tuple starts and teaches
it the actual duration when the tuple stops (:class:`~creatures.behaviour.DoUntil`). Both
models here satisfy the :class:`~creatures.behaviour.DurationModel` protocol
(``sample(rng)``, ``update(duration)``) and add ``pulse`` and ``sample_pulse(rng)`` so a
:mod:`creatures.temporal.tree` percept can share one pulse among many tuples.

Bad durations — zero, negative, NaN, ±inf or longer than ``max_duration`` (an hour by
default) — are handled per entry point:

* ``update(d)`` raises :class:`ValueError` naming the value: one duration is an explicit
  claim by the caller, and a wrong claim is a bug to surface;
* ``update_many(ds)`` skips them and counts them in ``rejected``: a stream of onsets from
  MIDI or audio carries junk (double triggers, a dropped note-off) that must not stop the
  listening, and the count says how much was dropped.
"""

from __future__ import annotations

import bisect
import math
import operator
from collections import deque
from itertools import accumulate, islice
from fractions import Fraction
from typing import Any, Iterable, Mapping, Protocol

import numpy as np

from creatures import bounds
from creatures.behaviour.action_tuple import DurationModel
from creatures.behaviour.models.gaussian import GaussianModel

MAX_SIZE = 65_536
"""Largest FIFO or label window a saved low-integer-ratio model may ask for (the default is
32 and 128): a damaged ``size`` of 1e12 is refused, not allocated."""

LEARNED = ("fifo", "labels", "recent", "recent_trouble", "since_anchor", "since_level", "rejected", "reanchors")
"""What a low-integer-ratio model learns (the rest of its saved state is its settings)."""

MAX_DURATION = 3600.0

#: Prior preferences for reinterpreting ratios (duration : pulse): the simpler the ratio,
#: the likelier (Desain & Honing's rhythm-induction preferences, thesis ref. [28]).
DEFAULT_RATIOS: dict[Fraction, float] = {
    Fraction(1): 8.0,
    Fraction(2): 4.0,
    Fraction(1, 2): 4.0,
    Fraction(3, 2): 2.0,
    Fraction(2, 3): 2.0,
    Fraction(3): 2.0,
    Fraction(1, 3): 2.0,
    Fraction(4): 1.0,
    Fraction(1, 4): 1.0,
    Fraction(4, 3): 1.0,
    Fraction(3, 4): 1.0,
}


class PulseModel(DurationModel, Protocol):
    """A duration model with a pulse: what :mod:`creatures.temporal.tree` shares."""

    @property
    def pulse(self) -> float: ...

    def sample_pulse(self, rng: np.random.Generator) -> float: ...


def check_duration(duration: float, *, max_duration: float = MAX_DURATION) -> float:
    """``duration`` as a float, or :class:`ValueError` saying why it cannot be a duration."""
    d = float(duration)
    if not math.isfinite(d):
        raise ValueError(f"a duration must be a finite number of seconds (got {d!r})")
    if not 0.0 < d <= max_duration:
        raise ValueError(f"a duration must be in (0, {max_duration:g}] seconds (got {d!r})")
    return d


def valid_durations(
    durations: Iterable[float] | np.ndarray, *, max_duration: float = MAX_DURATION
) -> np.ndarray:
    """Boolean mask of the entries of ``durations`` that :func:`check_duration` accepts."""
    d = np.asarray(durations, dtype=float)
    with np.errstate(invalid="ignore"):
        return np.isfinite(d) & (d > 0.0) & (d <= max_duration)


class SimpleDurationModel:
    """"Around 5 s": the thesis's simple duration model — a :class:`GaussianModel` (rolling
    FIFO with a prior) over durations, made safe for durations.

    The Gaussian can put mass below zero; a sampled duration is floored at ``min_duration``
    so a Du never plans a negative or zero activation.
    """

    kind = "simple_duration_model"

    def __init__(
        self,
        prior_mean: float,
        prior_std: float,
        *,
        size: int = 32,
        prior_weight: float = 0.1,
        min_duration: float = 1e-3,
        max_duration: float = MAX_DURATION,
        rng: np.random.Generator | None = None,
    ) -> None:
        check_duration(prior_mean, max_duration=max_duration)
        self.gaussian = GaussianModel(prior_mean, prior_std, size=size, prior_weight=prior_weight, rng=rng)
        self.min_duration = check_duration(min_duration, max_duration=max_duration)
        self.max_duration = float(max_duration)
        self.rejected = 0

    @property
    def pulse(self) -> float:
        return self.gaussian.mean

    mean = pulse

    @property
    def std(self) -> float:
        return self.gaussian.std

    def update(self, duration: float) -> None:
        """Learn one actual duration; raises ValueError for a bad one."""
        self.gaussian.update(check_duration(duration, max_duration=self.max_duration))

    def update_many(self, durations: Iterable[float] | np.ndarray) -> int:
        """Learn a stream of durations in order, skipping (and counting) bad ones."""
        d = np.asarray(durations, dtype=float).ravel()
        ok = valid_durations(d, max_duration=self.max_duration)
        self.rejected += int(d.size - ok.sum())
        for x in d[ok]:
            self.gaussian.update(float(x))
        return int(ok.sum())

    def sample(self, rng: np.random.Generator) -> float:
        return max(self.gaussian.sample(rng), self.min_duration)

    sample_pulse = sample

    def sample_many(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return np.maximum(rng.normal(self.gaussian.mean, self.gaussian.std, n), self.min_duration)

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "gaussian": self.gaussian.to_dict(),
            "min_duration": self.min_duration,
            "max_duration": self.max_duration,
            "rejected": self.rejected,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "SimpleDurationModel":
        try:
            gaussian = GaussianModel.from_dict(data["gaussian"])
            model = cls(
                gaussian.prior_mean,
                gaussian.prior_std,
                size=gaussian.size,
                prior_weight=gaussian.prior_weight,
                min_duration=data["min_duration"],
                max_duration=data["max_duration"],
            )
            model.rejected = int(data["rejected"])
        except KeyError as exc:
            raise ValueError(f"simple duration model state is missing key {exc.args[0]!r}") from None
        model.gaussian = gaussian
        return model

    def __repr__(self) -> str:
        return f"SimpleDurationModel(mean={self.pulse:.4g}, std={self.std:.4g})"


class LowIntegerRatioModel:
    """A duration model that hears durations as low-integer ratios of a pulse (figure 11).

    **Hearing.** A new duration ``d`` is first reinterpreted against the pulse ``p`` (the
    mean of a FIFO of normalised durations): every ratio ``r`` in the ratio set with
    ``|log(d / (r·p))| ≤ tolerance`` explains it, and the explanation with the best
    ``log prior(r) − ½(residual/σ)²`` (σ = tolerance/2) wins. The normalised duration
    ``d / r`` enters the pulse FIFO (2.1 under 2:1 adds 1.05) and ``r`` enters the ratio
    distribution. A duration no ratio explains is left out of the pulse (it would blur it).

    **Generating.** ``sample`` draws a ratio from the learned ratio distribution (counts of
    the last ``recency`` interpretations plus ``prior_strength`` pseudo-counts spread by the
    ratio prior), then a base duration from N(pulse, std of the FIFO) kept within the heard
    jitter of the pulse (half the range of the normalised durations in the FIFO, either
    side; never beyond the tolerance band), and multiplies: a performance heard with ±5 %
    jitter is played back on the lattice with the same spread and at most that jitter.

    **Following the tempo (re-anchoring rule).** Slow drift is followed by the FIFO itself:
    each admitted duration pulls the pulse toward it. Anything faster shows as *trouble*:
    durations no ratio explains, or explained only by a ratio the recent style makes
    surprising (learned probability below ``surprise``; 100 → 130 BPM is within 2.5 % of a
    4:3 modulation, so quarters at the new tempo pass as 3:4 of the old beat, but a piece
    that never used 3:4 finds that surprising). When ``reanchor_count`` of the last
    ``reanchor_window`` durations since the last anchor were trouble and at least
    ``reanchor_segment`` durations have been heard since the first of them, the model
    re-anchors on that *segment* (what came before it fitted the old pulse): every
    ``d_i / r`` is a candidate pulse, moved to the mean pulse its explanations imply,
    scored by how well it explains the whole segment under the ratio distribution learned
    *before* the segment (so the style heard so far keeps its metrical level across a
    tempo change) less a cost for jumping far from the old pulse (log-normal, width
    ``tempo_spread``), and the winner's normalised durations restart the FIFO while the
    segment's interpretations are revised. The prior pulse is only the first anchor: a fresh
    model anchors itself on its first segment of durations the same way.
    A steady beat that jumps by about a modulating ratio (quarters 100 → 130 BPM, heard as
    3:4 notes) makes only two durations trouble, since they make 3:4 familiar; a whole
    window of that one ratio, the first of them surprising, re-anchors as well
    (:meth:`_steady_surprise`), so the pulse follows within ``reanchor_window`` beats.

    **Metrical level.** Every ``level_every`` durations the pulse moves to the level at
    which the recently heard ratios are simplest under the ratio prior (see
    :meth:`_check_level`): whether the first segment happened to be full of dotted quarters
    or of eighths, a piece of quarters, eighths, halves and dotted quarters ends up counted
    in quarters. While the anchor is young (fewer than ``level_every`` durations old) the
    level is checked every ``YOUNG_LEVEL_EVERY`` durations instead: a first segment of six
    durations cannot tell the eighth from the beat, and the labels heard *online* (what
    ``update`` returns, before any later revision) are at the wrong level until a check
    corrects it. Checked only every 128 durations, a fresh model heard up to two thirds of
    the first 200 notes of a seeded test rhythm that way (23 of 200 seeds); checked every 8,
    at most a fifth, and from the 32nd note on at least 97 % are right.

    **Hot path.** A Du teaches its model one duration at a time (``DoUntil.end``), so
    ``update`` is the path that has to be fast, and it is plain Python on floats: the
    scoring rule is precomputed as a step function of log(d / pulse) (one bisection finds
    the winning ratio), the ratio counts and the trouble count are kept up to date as labels
    enter and leave their windows, and the pulse is the mean of a ring of ``size`` floats.
    numpy is kept for what runs rarely (re-anchoring, the level check) and for whole arrays
    (``interpret``, ``sample_many``). ``update_many`` is ``update`` in a loop (one code
    path, so the two cannot disagree) that skips bad durations instead of raising.
    """

    kind = "low_integer_ratio_model"
    LEVEL_MARGIN = 2.0  #: nats a simpler metrical level must gain before the pulse moves to it
    REFINE = 3  #: passes that move each re-anchoring candidate to the pulse its explanations imply
    YOUNG_LEVEL_EVERY = 8  #: how often the level is checked in the ``level_every`` durations after an anchoring

    def __init__(
        self,
        prior_pulse: float = 0.5,
        *,
        ratios: Mapping[Fraction | tuple[int, int] | int, float] | None = None,
        tolerance: float = 0.08,
        size: int = 32,
        recency: int = 128,
        prior_strength: float = 2.0,
        reanchor_window: int = 16,
        reanchor_count: int = 3,
        reanchor_segment: int = 6,
        surprise: float = 0.01,
        level_every: int = 128,
        tempo_spread: float = 0.35,
        max_duration: float = MAX_DURATION,
        block: int = 256,
    ) -> None:
        table = {_fraction(r): float(w) for r, w in (ratios or DEFAULT_RATIOS).items()}
        if Fraction(1) not in table or any(not (r > 0 and w > 0) for r, w in table.items()):
            raise ValueError("ratios must map positive ratios (1 among them) to positive prior preferences")
        if not 0.0 < tolerance < 1.0:
            raise ValueError(f"tolerance is a log-ratio in (0, 1) (got {tolerance!r})")
        if not 1 <= reanchor_count <= reanchor_segment <= reanchor_window <= recency:
            raise ValueError("need 1 ≤ reanchor_count ≤ reanchor_segment ≤ reanchor_window ≤ recency")
        if size < reanchor_window or block < 1 or level_every < 1:
            raise ValueError("need size ≥ reanchor_window, block ≥ 1 and level_every ≥ 1")
        if not (prior_strength > 0 and tempo_spread > 0):
            raise ValueError("prior_strength and tempo_spread must be positive")
        self.ratios = tuple(sorted(table))
        self.preferences = [table[r] for r in self.ratios]  # as authored, for persistence
        self.prior = np.array(self.preferences) / sum(self.preferences)
        self.tolerance = float(tolerance)
        self.prior_strength = float(prior_strength)
        self.reanchor_window = int(reanchor_window)
        self.reanchor_count = int(reanchor_count)
        self.reanchor_segment = int(reanchor_segment)
        self.surprise = float(surprise)
        self.level_every = int(level_every)
        self.tempo_spread = float(tempo_spread)
        self.max_duration = float(max_duration)
        self.block = int(block)  # kept for saved states and callers; hearing no longer batches
        self._values = np.array([float(r) for r in self.ratios])
        self._log_ratios = np.log(self._values)
        self._log_prior = np.log(self.prior)
        self._half_inv_var = 0.5 / (self.tolerance / 2.0) ** 2
        self._band = math.exp(self.tolerance)
        # The same tables as Python lists: indexing a list with an int is what the hot path
        # does, and it is several times cheaper than indexing a numpy array.
        self._value_list: list[float] = self._values.tolist()
        self._modulating = [r.numerator > 1 and r.denominator > 1 for r in self.ratios]
        self._pseudo: list[float] = (self.prior_strength * self.prior).tolist()
        self._edges, self._winners = self._explanation_table()
        index = {r: j for j, r in enumerate(self.ratios)}
        # _quotient[j, s]: index of ratio_j / ratio_s (ratio_j heard against a pulse ratio_s
        # times longer), −1 when that is not in the set; the last row maps "unexplained".
        self._quotient = np.array(
            [[index.get(r / q, -1) for q in self.ratios] for r in self.ratios] + [[-1] * len(self.ratios)],
            dtype=np.intp,
        )
        self.size = int(size)
        # The pulse FIFO, oldest first: starts full of the prior pulse; a re-anchoring restarts
        # it with the few durations it reinterpreted, and it refills to ``size`` from there.
        self._fifo: deque[float] = deque([check_duration(prior_pulse, max_duration=max_duration)] * self.size, self.size)
        self._labels: deque[int] = deque(maxlen=int(recency))  # ratio index per duration, −1 unexplained
        self._recent: deque[float] = deque(maxlen=self.reanchor_window)  # for re-anchoring
        self._recent_trouble: deque[bool] = deque(maxlen=self.reanchor_window)
        self._since_anchor = 0
        self._since_level = 0
        self.rejected = 0
        self.reanchors = 0
        self._changed()

    # -- what the model knows ----------------------------------------------------------
    @property
    def pulse(self) -> float:
        """The current pulse: the mean of the FIFO of normalised durations."""
        return self._pulse

    @property
    def std(self) -> float:
        """Standard deviation of the FIFO of normalised durations (the heard jitter)."""
        return self._spread()[0]

    def _spread(self) -> tuple[float, float, float]:
        """(std, lowest, highest) a base duration is drawn with: N(pulse, std) kept within
        the heard jitter of the pulse — half the range of the normalised durations in the
        FIFO, either side — and within the tolerance band. Computed in plain Python once per
        change, when first sampled."""
        if self._stats is None:
            fifo, pulse, band = self._fifo, self._pulse, self._band
            # E[x²] − pulse²: normalised durations agree to a few per cent, so the difference
            # keeps ~12 significant digits; max() absorbs rounding below zero.
            std = math.sqrt(max(sum(map(operator.mul, fifo, fifo)) / len(fifo) - pulse * pulse, 0.0))
            jitter = (max(fifo) - min(fifo)) / 2.0
            self._stats = (std, max(pulse - jitter, pulse / band), min(pulse + jitter, pulse * band))
        return self._stats

    @property
    def surprised(self) -> bool:
        """Whether the last duration heard surprised the model (thesis, "expectations about
        value": an expectation violated): no ratio explains it, or only one the recent style
        makes unlikely (learned probability below ``surprise``). The same *trouble* that
        drives re-anchoring, so the percept and the model's own reaction to it agree."""
        return bool(self._recent_trouble) and self._recent_trouble[-1]

    def ratio_distribution(self) -> np.ndarray:
        """P(ratio) over ``self.ratios``: recent interpretation counts plus the prior."""
        return self._smoothed(np.array(self._counts), self.prior_strength)

    def _weights(self) -> list[float]:
        """Cumulative unnormalised P(ratio) (counts plus pseudo-counts), for drawing a ratio
        with one bisection; computed once per change, when first sampled."""
        if self._cumulative is None:
            self._cumulative = list(accumulate(map(operator.add, self._counts, self._pseudo)))
        return self._cumulative

    def _count(self, labels: Iterable[int]) -> np.ndarray:
        """How often each ratio occurs among ``labels`` (−1, unexplained, is not counted)."""
        lab = np.fromiter(labels, dtype=np.intp)
        return np.bincount(lab[lab >= 0], minlength=len(self.ratios))

    def _smoothed(self, counts: np.ndarray, strength: float) -> np.ndarray:
        """Counts plus ``strength`` pseudo-counts spread by the ratio prior, normalised."""
        return (counts + strength * self.prior) / (counts.sum() + strength)

    def interpret(self, durations: Iterable[float] | np.ndarray) -> np.ndarray:
        """Ratio index (into ``self.ratios``) each duration would get now, −1 if none; no learning."""
        x = np.log(np.asarray(durations, dtype=float).ravel()) - self._log_pulse
        return np.asarray(self._winners, dtype=np.intp)[np.searchsorted(self._edges, x, side="right")]

    # -- hearing -----------------------------------------------------------------------
    def update(self, duration: float) -> int:
        """Hear one duration; returns its ratio index (−1: unexplained). Bad input raises."""
        d = float(duration)
        if not 0.0 < d <= self.max_duration:  # also false for NaN: one comparison on the hot path
            check_duration(d, max_duration=self.max_duration)  # raises, saying why
        heard: list[int] = []
        self._hear(d, heard)
        return heard[0]

    def update_many(self, durations: Iterable[float] | np.ndarray) -> np.ndarray:
        """Hear durations in order; bad ones are skipped and counted in ``rejected``.

        Returns the ratio index of each accepted duration (−1 unexplained); a re-anchoring
        revises the indices of the window it reinterpreted.
        """
        d = np.asarray(durations, dtype=float).ravel()
        ok = valid_durations(d, max_duration=self.max_duration)
        self.rejected += int(d.size - ok.sum())
        heard: list[int] = []
        for x in d[ok].tolist():
            self._hear(x, heard)
        return np.array(heard, dtype=np.intp)

    def _best(self, x: np.ndarray) -> np.ndarray:
        """Index of the ratio that best explains each log(d / pulse) in ``x``, −1 if none:
        the scoring rule itself, as an argmax over every ratio (the first best wins)."""
        residual = x[:, None] - self._log_ratios
        fit = self._log_prior - self._half_inv_var * residual**2
        score = np.where(np.abs(residual) <= self.tolerance, fit, -np.inf)
        return np.where(np.isfinite(score.max(axis=1)), score.argmax(axis=1), -1)

    def _explanation_table(self) -> tuple[list[float], list[int]]:
        """The scoring rule as a step function of x = log(d / pulse): (edges, winners), where
        ``winners[bisect_right(edges, x)]`` is ``_best(x)``.

        The winner can only change where a ratio's tolerance band starts or ends, or where
        two ratios' scores cross (equal curvature makes that one point per pair), so probing
        once between consecutive such points finds it everywhere: hearing one duration is
        then one bisection instead of scoring every ratio.
        """
        lr, tol = self._log_ratios, self.tolerance
        a, b = np.triu_indices(lr.size, 1)
        crossings = (lr[a] + lr[b]) / 2 + (self._log_prior[a] - self._log_prior[b]) / (
            2 * self._half_inv_var * (lr[b] - lr[a])
        )
        edges = np.unique(np.concatenate((lr - tol, lr + tol, crossings)))
        probes = np.concatenate(([edges[0] - 1.0], (edges[:-1] + edges[1:]) / 2, [edges[-1] + 1.0]))
        winners = self._best(probes)
        change = np.flatnonzero(winners[1:] != winners[:-1])  # edge k separates steps k and k + 1
        return edges[change].tolist(), winners[np.concatenate(([0], change + 1))].tolist()

    def _hear(self, d: float, heard: list[int]) -> None:
        """Hear one valid duration: append its ratio index to ``heard``, revising the entries
        of ``heard`` a re-anchoring reinterprets or a change of metrical level renames.

        The hot path: state is read into locals and every running total is updated in place.
        """
        label = self._winners[bisect.bisect_right(self._edges, math.log(d) - self._log_pulse)]
        counts, labels, flags = self._counts, self._labels, self._recent_trouble
        # Trouble: unexplained, or explained by a ratio the recent style makes surprising
        # (e.g. 3:4 in a piece that never used it — how a tempo change close to a simple
        # ratio, 100 → 130 BPM ≈ 4:3, shows itself).
        if label < 0:
            trouble = True
        else:
            seen = counts[label] + self._pseudo[label]
            trouble = seen / (self._explained + self.prior_strength) < self.surprise
            fifo = self._fifo
            fifo.append(d / self._value_list[label])
            self._pulse = pulse = sum(fifo) / len(fifo)
            self._log_pulse = math.log(pulse)
        self._run = self._run + 1 if labels and labels[-1] == label else 1
        if len(labels) == labels.maxlen and labels[0] >= 0:  # a label leaves the window
            counts[labels[0]] -= 1
            self._explained -= 1
        labels.append(label)
        if label >= 0:
            counts[label] += 1
            self._explained += 1
        if len(flags) == flags.maxlen:
            self._trouble_held -= flags[0]
        flags.append(trouble)
        self._trouble_held += trouble
        self._recent.append(d)
        self._since_anchor += 1
        self._since_level += 1
        self._stats = self._cumulative = None
        heard.append(label)
        young = self._since_anchor < self.level_every and self._since_anchor % self.YOUNG_LEVEL_EVERY == 0
        if self._since_level >= self.level_every or young:
            shift = self._check_level()
            if shift is not None:
                heard[:] = self._quotient[heard, shift].tolist()
        elif (self._trouble_held >= self.reanchor_count and self._reanchor_due()) or self._steady_surprise(label):
            revised = self._reanchor().tolist()
            k = min(len(revised), len(heard))
            heard[len(heard) - k :] = revised[len(revised) - k :]

    def _steady_surprise(self, label: int) -> bool:
        """A whole window of one modulating ratio (3:4, 4:3, 2:3, 3:2 …), the first of them
        surprising: a steady beat whose tempo moved by about that ratio (quarters 100 → 130
        BPM are heard as 3:4 notes). Only the first two are trouble (they make 3:4 familiar),
        so the trouble rule alone left the pulse behind until the metrical level check, ~190
        notes later; re-anchoring scores the simpler reading, one pulse with 1:1 notes.

        Runs of a plain subdivision or multiple (1:2, 1:3, 2:1 …) do not count: sixteen
        eighths after a passage of quarters are eighths at the same tempo."""
        return (self._run >= self.reanchor_window and self._since_anchor >= self.reanchor_window
                and label >= 0 and self._modulating[label] and self._recent_trouble[0])

    def _reanchor_due(self) -> bool:
        """``reanchor_count`` trouble among the last ``reanchor_window`` durations since the
        anchor, the first of them at least ``reanchor_segment`` durations ago."""
        since = min(self._since_anchor, self.reanchor_window)
        flags = list(self._recent_trouble)[len(self._recent_trouble) - since :]
        return sum(flags) >= self.reanchor_count and since - flags.index(True) >= self.reanchor_segment

    def _reanchor(self) -> np.ndarray:
        """Choose the pulse that best explains the recent durations; returns their indices.

        Only the durations from the window's first trouble on (the segment) are
        reinterpreted: those before it fitted the old pulse and belong to the old tempo.
        """
        d = np.array(self._recent)[list(self._recent_trouble).index(True) :]
        log_d = np.log(d)
        # The segment's own (old-pulse) interpretations are what is in doubt: they do not vote;
        # and the style must have been heard for a while (a window's worth of pseudo-counts)
        # before it overrules the authored preferences — a fresh model's few coincidental
        # explanations under its prior pulse must not pick the metrical level.
        strength = max(self.prior_strength, float(self.reanchor_window))
        before = islice(self._labels, 0, len(self._labels) - d.size)
        log_post = np.log(self._smoothed(self._count(before), strength))
        unexplained_cost = log_post.min() - 2.0 * self._half_inv_var * self.tolerance**2
        log_pulse = (log_d[:, None] - self._log_ratios).ravel()  # every d_i / r_j, in logs
        for _ in range(self.REFINE):
            residual = log_d[None, :, None] - log_pulse[:, None, None] - self._log_ratios
            fit = log_post - self._half_inv_var * residual**2
            score = np.where(np.abs(residual) <= self.tolerance, fit, -np.inf)
            labels = score.argmax(axis=2)  # (candidate, duration)
            chosen = np.take_along_axis(score, labels[..., None], axis=2)[..., 0]
            explained = np.isfinite(chosen)
            fitted = np.take_along_axis(residual, labels[..., None], axis=2)[..., 0]
            # Move each candidate to the (log-)mean of the pulses its explanations imply.
            log_pulse = log_pulse + (fitted * explained).sum(axis=1) / np.maximum(explained.sum(axis=1), 1)
        # Tempo continuity: a jump of the pulse by log-ratio x costs ½(x / tempo_spread)², so a
        # segment that fits the beat and the half-bar alike (all quarters) keeps the level.
        continuity = 0.5 * ((log_pulse - self._log_pulse) / self.tempo_spread) ** 2
        winner = int((np.where(explained, chosen, unexplained_cost).sum(axis=1) - continuity).argmax())
        labels = np.where(explained[winner], labels[winner], -1)
        explained = labels >= 0
        self._fifo = deque((d[explained] / self._values[labels[explained]]).tolist(), self.size)
        for _ in range(d.size):
            self._labels.pop()
        self._labels.extend(labels.tolist())
        self._since_anchor = 0
        self.reanchors += 1
        self._changed()
        return labels

    def _check_level(self) -> int | None:
        """Move the pulse to the metrical level at which the heard ratios are simplest.

        The same rhythm reads as quarters-and-eighths (1, 1/2, 2, 3/2) or as dotted-quarters
        (2/3, 1/3, 4/3, 1); both explain every duration, so only the ratio prior can choose:
        the level whose reinterpreted recent counts score best under the prior wins, if it
        beats the current level by ``LEVEL_MARGIN`` nats. Returns the shift used, if any.
        """
        self._since_level = 0
        mapped = self._quotient[: len(self.ratios)]
        unexplained_cost = self._log_prior.min() - 2.0 * self._half_inv_var * self.tolerance**2
        score = np.array(self._counts) @ np.where(mapped >= 0, self._log_prior[mapped], unexplained_cost)
        shift = int(score.argmax())
        if score[shift] - score[self.ratios.index(Fraction(1))] <= self.LEVEL_MARGIN:
            return None
        remapped = self._quotient[np.array(self._labels, dtype=np.intp), shift].tolist()
        self._labels.clear()
        self._labels.extend(remapped)
        factor = self._value_list[shift]
        self._fifo = deque((x * factor for x in self._fifo), self.size)
        self._changed()
        return shift

    def _changed(self) -> None:
        """Recompute everything derived from the FIFO and the labels (after a wholesale
        change: a re-anchoring, a level shift, a restore); ``_hear`` keeps it up to date."""
        self._pulse = sum(self._fifo) / len(self._fifo)
        self._log_pulse = math.log(self._pulse)
        self._counts: list[int] = self._count(self._labels).tolist()
        self._explained = sum(self._counts)
        self._trouble_held = sum(self._recent_trouble)
        self._run = 0  # how many of the latest labels are the same ratio
        for lab in reversed(self._labels):
            if lab != self._labels[-1]:
                break
            self._run += 1
        self._stats: tuple[float, float, float] | None = None
        self._cumulative: list[float] | None = None

    # -- generating --------------------------------------------------------------------
    def sample_pulse(self, rng: np.random.Generator) -> float:
        """A base duration: N(pulse, std) kept inside the range heard (see :meth:`_spread`)."""
        std, lo, hi = self._spread()
        return min(max(rng.normal(self._pulse, std), lo), hi)

    def sample(self, rng: np.random.Generator) -> float:
        """Draw a ratio from the ratio distribution, a base duration, and multiply (fig. 11)."""
        cumulative = self._weights()
        j = min(bisect.bisect_right(cumulative, rng.random() * cumulative[-1]), len(cumulative) - 1)
        return self._value_list[j] * self.sample_pulse(rng)

    def sample_many(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` independent draws of :meth:`sample` in one vectorised pass."""
        cumulative = np.array(self._weights())
        j = np.minimum(np.searchsorted(cumulative, rng.random(n) * cumulative[-1], side="right"), cumulative.size - 1)
        std, lo, hi = self._spread()
        return self._values[j] * np.clip(rng.normal(self._pulse, std, n), lo, hi)

    # -- persistence -------------------------------------------------------------------
    def _settings(self) -> dict[str, Any]:
        """The constructor's keywords that made this model (what the author chose)."""
        return {"tolerance": self.tolerance, "recency": self._labels.maxlen, "prior_strength": self.prior_strength,
                "reanchor_window": self.reanchor_window, "reanchor_count": self.reanchor_count,
                "reanchor_segment": self.reanchor_segment, "surprise": self.surprise,
                "level_every": self.level_every, "tempo_spread": self.tempo_spread,
                "max_duration": self.max_duration, "block": self.block, "size": self.size}

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "ratios": [[r.numerator, r.denominator, w] for r, w in zip(self.ratios, self.preferences)],
            **self._settings(),
            "fifo": list(self._fifo),
            "labels": list(self._labels),
            "recent": list(self._recent),
            "recent_trouble": list(self._recent_trouble),
            "since_anchor": self._since_anchor,
            "since_level": self._since_level,
            "rejected": self.rejected,
            "reanchors": self.reanchors,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "LowIntegerRatioModel":
        """A model with the settings and the learned pulse of ``data`` (see :meth:`learned`)."""
        try:
            settings = {key: data[key] for key in cls(1.0)._settings()}
            ratios = {Fraction(n, m): w for n, m, w in data["ratios"]}
        except KeyError as exc:
            raise ValueError(f"low-integer ratio model state is missing key {exc.args[0]!r}") from None
        if not 0 < settings["size"] <= MAX_SIZE or not 0 < settings["recency"] <= MAX_SIZE:
            raise ValueError(f"low-integer ratio model state: 'size' and 'recency' must be 1 to {MAX_SIZE}")
        return cls(1.0, ratios=ratios, **settings).learned(data)

    def learned(self, data: dict[str, Any]) -> "LowIntegerRatioModel":
        """A model with this one's settings (ratios, sizes, tolerances: the author's, so an
        edited setting wins over a saved file) that knows what ``data`` learnt: the pulse
        FIFO, the recent labels and durations, the counters. Every part is checked against
        those settings (raises ValueError naming the key): a state that loads is one that runs."""
        missing = [key for key in LEARNED if key not in data]
        if missing:
            raise ValueError(f"low-integer ratio model state is missing key {missing[0]!r}")
        model = type(self)(1.0, ratios=dict(zip(self.ratios, self.preferences)), **self._settings())
        what = "pulse"
        fifo = bounds.items(data.get("fifo"), f"{what}.fifo", shortest=1, longest=model.size)
        labels = bounds.items(data.get("labels"), f"{what}.labels", longest=model._labels.maxlen)
        recent = bounds.items(data.get("recent"), f"{what}.recent", longest=min(model.reanchor_window, len(labels)))
        trouble = bounds.items(data.get("recent_trouble"), f"{what}.recent_trouble", shortest=len(recent),
                               longest=len(recent))
        # The FIFO holds pulses, d / r: a duration up to max_duration heard as the smallest
        # ratio (1/4 by default) is a pulse of four times it, as the model runs.
        longest_pulse = model.max_duration / float(min(1, *model.ratios))
        for key, durations, longest in (("fifo", fifo, longest_pulse), ("recent", recent, model.max_duration)):
            for i, d in enumerate(durations):
                bounds.number(d, f"{what}.{key}.{i}", low=0.0, high=longest)
            if not valid_durations(durations, max_duration=longest).all():
                raise ValueError(f"{what}.{key}: must hold positive, finite durations")
        model._fifo = deque((float(d) for d in fifo), model.size)
        model._labels.extend(bounds.count(lab, f"{what}.labels.{i}", low=-1, high=len(model.ratios) - 1)
                             for i, lab in enumerate(labels))
        model._recent.extend(float(d) for d in recent)
        if any(not isinstance(flag, bool) for flag in trouble):
            raise ValueError(f"{what}.recent_trouble: must hold true/false flags")
        model._recent_trouble.extend(trouble)
        model._since_anchor, model._since_level, model.rejected, model.reanchors = (
            bounds.count(data.get(key), f"{what}.{key}") for key in ("since_anchor", "since_level", "rejected", "reanchors"))
        model._changed()
        return model

    def __repr__(self) -> str:
        return f"LowIntegerRatioModel(pulse={self._pulse:.4g}, ratios={len(self.ratios)}, reanchors={self.reanchors})"


def _fraction(r: Fraction | tuple[int, int] | int) -> Fraction:
    return Fraction(*r) if isinstance(r, tuple) else Fraction(r)
