"""The visitors of a rehearsed gallery week (``creatures rehearse``, ``[rehearse]``).

An installation is met by people, not by a file played from start to end: they come in over
the opening hours, play or speak a phrase, listen, and play again sooner when a creature
answers them (the thesis's exchange is "a game" a visitor plays with the colony, "exchange
(installation)"), or walk away after a few phrases that nothing answered. This module is that
crowd, seeded: Poisson arrivals, exponential stays, each visitor's phrases drawn from a corpus
(the config's MIDI files or text, or the generated fragments and poem), and the answer rule
that both steers them and gives the rehearsal its answer rate.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from creatures.runtime.inputs import FRAGMENTS
from creatures.runtime.schema import RehearseSection
from creatures.runtime.speech_input import POEM
from midi.files import MidiFileError, read_notes
from midi.notes import NoteEvent

BEAT = 0.6
"""Seconds a beat of the generated fragments lasts (100 bpm, as ``phrase_notes`` plays them)."""

LONGEST_PHRASE = 60.0
"""Seconds of a corpus phrase a visitor plays (a longer file is cut: a visitor is no concert)."""


MIDI_SUFFIXES = (".mid", ".midi")
"""The names of a corpus folder's MIDI files, in any case (``.MID``)."""


class CorpusError(ValueError):
    """``[rehearse] corpus`` cannot be read; the message names the file."""


@dataclass(frozen=True)
class Phrase:
    """What one visitor plays at once: notes (times from the phrase's start) or a line to speak."""

    notes: tuple[NoteEvent, ...] = ()
    line: str | None = None

    @property
    def length(self) -> float:
        if self.line is not None:
            return 0.35 * len(self.line.split())  # about a word every 0.35 s, as audio.formants speaks
        return max((n.time + n.duration for n in self.notes), default=0.0)

    @property
    def pitch_classes(self) -> frozenset[int] | None:
        """What an answer must share with it (None: any act answers a spoken line)."""
        return None if self.line is not None else frozenset(n.pitch % 12 for n in self.notes)


def generated(speech: bool) -> list[Phrase]:
    """The default corpus: the poem's lines for a piece that hears speech, else the three fragments."""
    if speech:
        return [Phrase(line=line) for line in POEM.splitlines() if line.strip()]
    phrases = []
    for fragment in FRAGMENTS:
        t, notes = 0.0, []
        for pitch, beats in fragment:
            notes.append(NoteEvent(round(t, 6), pitch, 90, 0, round(0.9 * beats * BEAT, 6)))
            t += beats * BEAT
        phrases.append(Phrase(tuple(notes)))
    return phrases


def load_corpus(path: Path) -> list[Phrase]:
    """A text file (one spoken line a line), a MIDI file (one phrase) or a folder of MIDI files."""
    if path.suffix.lower() == ".txt":
        try:
            lines = [line.strip() for line in path.read_text(encoding="utf-8").splitlines()]
        except (OSError, UnicodeDecodeError) as exc:
            raise CorpusError(f"[rehearse] corpus {path}: cannot read it ({exc})") from None
        phrases = [Phrase(line=line) for line in lines if line]
    else:
        # a folder's MIDI files whatever their case: one copied from Windows or a DAW ("Take 1.MID",
        # "b.midi") was passed over, and a folder of them held "no phrase"
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in MIDI_SUFFIXES) if path.is_dir() else [path]
        phrases = []
        for file in files:
            try:
                notes = read_notes(file)
            except (MidiFileError, OSError, ValueError) as exc:
                raise CorpusError(f"[rehearse] corpus {file}: cannot read it ({exc})") from None
            if notes:
                t0 = notes[0].time
                # Channels are kept: a note on a sensor's channel is a reading (a rock moved
                # in sand:stone), which a visitor makes as surely as a played phrase.
                phrases.append(Phrase(tuple(NoteEvent(round(n.time - t0, 6), n.pitch, n.velocity, n.channel, n.duration)
                                            for n in notes if n.time - t0 <= LONGEST_PHRASE)))
    if not phrases:
        raise CorpusError(f"[rehearse] corpus {path}: holds no phrase (a .txt of lines, a .mid, or a folder of .mid)")
    return phrases


@dataclass
class Visitor:
    leaves: float
    next_phrase: float
    unanswered: int = 0


@dataclass
class _Pending:
    start: float
    end: float
    classes: frozenset[int] | None
    visitor: Visitor


@dataclass
class Visitors:
    """The crowd of one rehearsal: :meth:`play` yields what they play in a span of open time,
    :meth:`hear` tells them what the colony did, and the counters say how often it answered."""

    params: RehearseSection
    corpus: list[Phrase]
    rng: np.random.Generator
    present: list[Visitor] = field(default_factory=list)
    pending: list[_Pending] = field(default_factory=list)
    answered: int = 0
    unanswered: int = 0
    arrived: int = 0
    _next_arrival: float | None = None

    def _gap(self, mean: float) -> float:
        return float(self.rng.exponential(mean))

    def open(self, t: float) -> None:
        """The doors open at ``t``: the first visitor is on the way."""
        rate = self.params.visitors_per_hour / 3600.0
        self._next_arrival = t + self._gap(1.0 / rate) if rate > 0 else None

    def close(self, t: float) -> None:
        """Closing time: everyone leaves; phrases still waiting for an answer go unanswered."""
        self._expire(float("inf"))
        self.present.clear()
        self._next_arrival = None

    def play(self, t0: float, t1: float) -> list[tuple[float, Phrase]]:
        """Arrivals, departures and the phrases begun in ``(t0, t1]``, each with its start time."""
        p = self.params
        while self._next_arrival is not None and self._next_arrival <= t1:
            at = self._next_arrival
            self.present.append(Visitor(leaves=at + self._gap(p.stay), next_phrase=at + self._gap(p.phrase_every / 4)))
            self.arrived += 1
            self._next_arrival = at + self._gap(3600.0 / p.visitors_per_hour)
        self._expire(t1)
        self.present = [v for v in self.present if v.leaves > t1]
        out = []
        for visitor in self.present:
            if visitor.next_phrase <= t1 and not any(q.visitor is visitor for q in self.pending):
                start = max(visitor.next_phrase, t0)
                phrase = self.corpus[int(self.rng.integers(len(self.corpus)))]
                self.pending.append(_Pending(start, start + phrase.length, phrase.pitch_classes, visitor))
                visitor.next_phrase = start + phrase.length + self._gap(p.phrase_every)
                out.append((start, phrase))
        return out

    def hear(self, t: float, pitch: int | None) -> None:
        """A creature acted at ``t`` (a note of ``pitch``, or a sung or read sound: None): the
        phrases it answers are answered, and their visitors play again twice as soon."""
        for q in [q for q in self.pending if q.start <= t <= q.end + self.params.answer_window
                  and (q.classes is None or pitch is None or pitch % 12 in q.classes)]:
            self.pending.remove(q)
            self.answered += 1
            q.visitor.unanswered = 0
            q.visitor.next_phrase = min(q.visitor.next_phrase, t + self._gap(self.params.phrase_every / 2))

    def _expire(self, t: float) -> None:
        """Phrases whose answer window has passed: unanswered; a visitor out of patience leaves."""
        for q in [q for q in self.pending if q.end + self.params.answer_window < t]:
            self.pending.remove(q)
            self.unanswered += 1
            q.visitor.unanswered += 1
            if q.visitor.unanswered >= self.params.patience:
                q.visitor.leaves = min(q.visitor.leaves, t)
