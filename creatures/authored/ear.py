"""What an authored creature hears, as state objects (thesis: "state objects and decaying
memory traces"), and the phrases it remembers.

Every heard note pushes its pitch, velocity, interval from the previous note, register
(octave) and the note density of the last :data:`DENSITY_WINDOW` seconds into one
:class:`StateObject` each, so percepts read one flow by name (:meth:`Ear.flow`) and learning
can look back at what led up to an action. A flow no percept has asked for yet keeps its
last samples in a buffer and takes them when first asked (in a crowd every note reaches
every ear, and most creatures read none of the five flows). Notes separated by more than
``phrase_gap`` seconds of silence start a new phrase, and so does a phrase reaching
:data:`PHRASE_NOTES` notes (in a crowd that hears a note every tick no silence ever comes, and
one unending phrase grew by ~50 notes a second for as long as the installation ran);
:class:`Ear` keeps the last ``max_phrases`` (the material a creature sings back). The creature's own notes go to
``played`` (a percept of what it just did).
"""

from __future__ import annotations

from collections import deque

from creatures.behaviour.state_object import StateObject
from midi.notes import NoteEvent

FEATURES = ("pitch", "velocity", "interval", "register", "density")
"""The flows a heard note feeds; each is a percept type of the same name."""

PHRASE_NOTES = 64
"""The most notes one phrase holds: the next note heard begins a new phrase, so an ear's memory
is bounded however continuous what it hears."""

DENSITY_WINDOW = 4.0
"""Seconds over which ``density`` counts notes (notes per second)."""


class Ear:
    """Heard notes in, flows and remembered phrases out."""

    def __init__(self, *, phrase_gap: float = 2.0, max_phrases: int = 8, history: int = 256) -> None:
        self._flows = tuple(StateObject(name, history=history) for name in FEATURES)
        self._asked: list[int] = []  # the flows handed out (FEATURES positions): pushed as notes come
        # (time, sample) of the last notes heard, for the flows not asked for yet; a flow keeps
        # only its last ``history`` samples, so these are all it would hold when it is asked.
        self._unread: deque[tuple[float, tuple[float, ...]]] = deque(maxlen=history)
        self.phrase_gap = float(phrase_gap)
        self.phrases: deque[list[NoteEvent]] = deque(maxlen=max_phrases)
        self.phrases_made = 0  # phrases begun so far (numbers stay unique as old ones leave)
        self.heard_at = -float("inf")  # clock time of the last heard onset
        self.heard_from = ""
        self.played: deque[NoteEvent] = deque(maxlen=64)
        self._recent: deque[float] = deque()
        self._last_pitch: int | None = None

    def hear(self, t: float, note: NoteEvent, source: str) -> None:
        if t - self.heard_at > self.phrase_gap or not self.phrases or len(self.phrases[-1]) >= PHRASE_NOTES:
            self.phrases.append([])
            self.phrases_made += 1
        self.phrases[-1].append(note)
        self.heard_at, self.heard_from = t, source
        self._recent.append(t)
        while self._recent and self._recent[0] < t - DENSITY_WINDOW:
            self._recent.popleft()
        interval = 0 if self._last_pitch is None else note.pitch - self._last_pitch
        self._last_pitch = note.pitch
        sample = (float(note.pitch), float(note.velocity), float(interval), float(note.pitch // 12),
                  len(self._recent) / DENSITY_WINDOW)  # in FEATURES order
        for k in self._asked:
            self._flows[k].push(t, sample[k])
        if len(self._asked) < len(FEATURES):
            self._unread.append((t, sample))

    def flow(self, name: str) -> StateObject:
        """The flow ``name`` (one of :data:`FEATURES`), from now on fed every note heard; the
        first time, it takes the samples it would have been pushed (the last ``history``)."""
        k = FEATURES.index(name)
        if k not in self._asked:
            for t, sample in self._unread:
                self._flows[k].push(t, sample[k])
            self._asked.append(k)
        return self._flows[k]

    def phrase(self, number: int) -> list[NoteEvent] | None:
        """Phrase ``number`` (1 = the first ever heard) if still remembered and complete."""
        first = self.phrases_made - len(self.phrases) + 1
        if not first <= number <= self.phrases_made:
            return None
        return self.phrases[number - first]

    def last(self, count: int) -> list[NoteEvent]:
        """The last ``count`` notes heard (across phrases), oldest first."""
        out: list[NoteEvent] = []
        for phrase in reversed(self.phrases):
            out[:0] = phrase[-(count - len(out)):]
            if len(out) >= count:
                break
        return out

    def since_heard(self, t: float) -> float:
        return t - self.heard_at
