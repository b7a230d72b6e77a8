"""Heard audio → note events, as it streams: how audio-only installations hear notes.

A creature that listens to notes (exchange, listen, sand:stone) should hear a piano's chords,
a string section, a flute or a voice as readily as a MIDI keyboard. It hears with two ears on
one stream (measured against each ear alone and basic-pitch's published model in
``docs/hearing.md``):

1. **Spectra.** Input of any rate and any number of channels is mixed and resampled to 22.05
   kHz; every hop (11.6 ms; the quick look's 5.8 ms) :class:`audio.logspectrum.LogSpectrum` gives the log-frequency
   spectrum of the samples that end there (a long and a short window).
2. **The model.** :class:`audio.note_model.NoteModel`, a small network trained on sampled
   instruments, judges each hop a few hops back: per pitch (MIDI 21–108), did a note begin
   there, and does one sound there. The live look judges 3 hops back, the offline look 6
   (nobody waits offline, and a bowed or blown swell is heard better); the quick look's model
   hears a finer hop (128 samples) and judges 4 of them back, 23 ms (:data:`QUICK`). It hears
   swells, winds, strings and chords; on a bright struck note it also hears partials as notes.
3. **The onset ear.** :class:`audio.onset_ear.OnsetEar`, the hand-built method heard with
   before, finds notes where an attack is, by what began there: exact on struck sounds, deaf to
   swells. Its candidates are notes if the model hears their pitch sound (:data:`VERIFY`).
4. **Notes.** The onset ear's notes come first; the model's own — a pitch whose onset
   probability rises through ``threshold`` (the model's own, tuned with its weights), or that
   begins to sound after a faint onset (a swell: :data:`SWELL`) or after none, quiet before
   (a slow swell: :data:`SLOW_SWELL`) — follow,
   unless the onset ear gave that pitch, or a note it is a partial of, within :data:`NEAR` hops.
   A model's note must also stand clear of its bands' noise floors (:data:`CLEAR`): what a
   model hears in a fan's noise is not played. Live, a struck note is given 3 hops after the
   hop the model names it in, its attack's mostly (≤ 50 ms with a block on the generated
   phrases, the quick look ≤ 30 ms; on a sampled piano line p90 58 ms, a chord's notes later:
   docs/hearing.md, "Live latency"; a bowed swell when it is heard to sound), with the
   provisional duration ``heard_length`` (as the live MIDI input gives a note-on, whose length
   is not known until it ends); its velocity is its level.
   It is followed until the model stops hearing it sound (or it is struck again) and its
   measured duration goes to :attr:`Transcriber.ended`.

Non-finite samples, and finite ones beyond :data:`audio.sources.LARGEST_SAMPLE` (junk whose
squares overflow the spectra), hold the last good one and are counted (:attr:`Transcriber.bad_samples`),
clipped ones are counted (:attr:`Transcriber.clipped`), and no note is taken from the frames a
repair, a change of input rate (:meth:`Transcriber.set_rate`) or a clock gap
(:meth:`Transcriber.skip`) touched: each leaves a step in the stream that is not an attack.
While the input clips, a model's note at a partial of a lower one beginning with it is the
clipping's distortion (a clipped tone is nearly square: strong odd partials), not a note.
"""

from __future__ import annotations

from collections import deque
from pathlib import Path

import numba
import numpy as np

from audio.logspectrum import HOP, LONG_LOW, LONG_STEP, RATE, SCALE, LogSpectrum
from audio.note_model import PITCHES, Judged, NoteModel, default
from audio.onset_ear import LEAD, LIVE_WINDOW, OFFLINE_WINDOW, Candidate, OnsetEar
from audio.resample import Resampler
from audio.sources import unusable
from midi.notes import NoteEvent

LIVE, QUICK, OFFLINE = "live", "quick", "offline"
"""The looks: the live one answers a struck attack within 60 ms (p99 39 ms through JACK on probe
tones; nine in ten of a sampled piano line's notes, a chord's fewer: docs/hearing.md, "Live
latency"), the quick one sooner (its model hears a finer hop, 128 samples, and judges 4 of them back: through
JACK at a 128-frame period p99 22.6 ms against the live look's 38.6) but hears bowed and blown
notes and chords worse, the offline one hears more (docs/hearing.md has each measured)."""
LOOKS = (LIVE, QUICK, OFFLINE)
EARS = ("onsets", "model")
WARM_UP = 8
"""Hops (93 ms) heard before the first note may be taken: the noise floors are learnt first.
This and every span below is in hops of :data:`HOP` (11.6 ms) whatever the model's grid."""
SEAM = 12
"""Hops (139 ms) after a repaired sample, a rate change or a clock gap in which no note is taken
(the model's context, 70–116 ms, still holds the step)."""
PARTIALS = np.round(12 * np.log2(np.arange(2, 9))).astype(int)
"""Intervals (semitones) of partials 2–8 above a note: where a bright note's partials and
clipping's distortion land."""
VERIFY = 0.2
"""P(sounding) the model must give an onset-ear candidate's pitch, from two hops before its onset frame
on, for it to be a note. Chosen among 0.1, 0.2 and 0.3 on the tests' own FluidR3 renders (seeds
0–1; one number, which moves no texture's F1 by more than 0.05): so judged, the onset ear's
guitar lines went from 0.89–0.94 to 0.97–1.00, and both ears hear piano lines 1.00 offline."""
NEAR = 4
"""Hops (46 ms) within which two notes of one pitch are one note, and a model's note at a partial
of an onset-ear note is that note's partial."""
SWELL = 0.7
"""A pitch whose P(sounding) rises through this, with no note of it followed, begins a note if
its P(onset) reached :data:`SWELL_ONSET` in the last 4 hops: a flute's or a string's soft
attack, which the model hears sound but names an onset only faintly (FluidR3's high flute notes
peaked at P(onset) 0.27–0.7 against a threshold of 0.7, then sounded at 0.97). The note is
dated at the hop its P(onset) peaked. Chosen on TimGM6mb renders (tools-style tuning, never on
FluidR3): the eight tuning textures' mean F1 0.825 → 0.847 offline, 0.786 → 0.809 live, among
0.5–0.9 and 0.1–0.45."""
SWELL_ONSET = 0.3
SLOW_SWELL = 10
"""A pitch whose P(sounding) rises through :data:`SWELL` within this many hops (116 ms) of last
being below :data:`RELEASE`, its P(onset) short of :data:`SWELL_ONSET` in the last 4 hops,
begins a note too: a *slow swell*, the bow of a string section starting a chord, which the
model hears sound but never calls an onset (FluidR3's strings on the validation seeds 101–102,
in a room: of a chorale's notes missed, most sounded at P 0.6–0.95 with P(onset) below 0.3,
first sounding ≥ 0.3 0–9 hops after their attack). Live it is given when so heard, up to
SLOW_SWELL hops later than a struck note would be: a bowed chord heard late is better than one
not heard (dated, as every note is, where its attack was heard: see :data:`SLOW_BACK`). It must
also have been quiet for :data:`QUIET` hops first and brought :data:`SLOW_RISE` to its partials,
and is dated :data:`SLOW_BACK` hops before it first sounded (live, :data:`SLOW_BACK_LIVE`). Chosen on TimGM6mb renders (seeds
201–202) of the eight tuning textures and six more (string and organ chords; string, piano and
guitar chords and a flute in a room), never on FluidR3, among windows 6, 10, 16, quiets 4–24,
rises 0.35–2.1 and 0–3 hops back: the fourteen's mean F1 offline 0.792 → 0.818 (string chords
0.56 → 0.70, in a room 0.46 → 0.64; the eight 0.8676 → 0.8706), live 0.717 → 0.767 (string
chords 0.35 → 0.59, in a room 0.20 → 0.53; the eight 0.835 → 0.840). A rule against a slow
swell at a partial of a note followed moved the mean by −0.003 and was not taken."""
QUIET = 8
"""Hops (93 ms) P(sounding) must have stayed below :data:`RELEASE` before a slow swell: a note
whose P(sounding) dipped for a hop or two (and so ended) and came back is not begun again. On
the tuning renders, a slow swell after any dip took the mean 0.818 → 0.815 (string chords in a
room 0.64 → 0.62)."""
SLOW_RISE = 1.4
"""How much (natural-log units of the spectrum, ≈ 12 dB) the strongest of a slow swell's first
four partials must have risen since the last hop it was quiet: a new note brings its own
energy. A piano note ended and heard sounding again 0.3 s later, while a high note sounded over
it, had partials decaying, not rising. Without this gate the tuning renders' mean was 0.783
(piano lines 0.98 → 0.92, flute lines 0.96 → 0.80); 0.7–1.4 alike, 2.1 lost string chords."""
SLOW_RISE_SHORT = 1.0
""":data:`SLOW_RISE` for a model that judges less than 3 hops (35 ms) past a frame (the quick
look, 23 ms): the level a rise is measured to is the loudest of the rows that judged the frame,
and a shorter look's rows have heard less of a bow's swell. On the tuning renders (seeds
201–202, the fourteen textures, with :data:`SLOW_BACK_LIVE`) 0.7 → 0.85 → 1.0 → 1.2 → 1.4 gave the
quick look's mean F1 0.7753 → 0.7773 → 0.7772 → 0.7743 → 0.7703 (a string line 0.82 → 0.86); on
validation (FluidR3 101–102, eleven textures) 1.4 → 1.0: 0.722 → 0.735 (flute 0.865 → 0.888,
string chords in a room 0.574 → 0.610). The live look's tuning mean moved by 0.0015 (0.7962 →
0.7977), within the noise, so it keeps 1.4."""
SLOW_BACK = 2
"""Hops before a slow swell first sounded (P ≥ :data:`RELEASE`) that its note is dated offline:
the bow's attack comes before the model hears it sound. 1–3 were alike on the tuning renders; 0
took their mean 0.818 → 0.806 (string chords in a room 0.64 → 0.58). Chosen again with the
thresholds and :data:`RISE_FROM` of 2026-12-06, 2 → 3 → 4 hops: 0.8204 → 0.8247 → 0.8246, on
validation (FluidR3, seeds 101–102) 0.7857 → 0.7866 → 0.7853, and on the tests' seed guitar
lines 0.923 → 0.911 at 3: within the noise, so 2 was kept."""
SLOW_BACK_LIVE = 4
""":data:`SLOW_BACK` for the looks that give a note as soon as it is named: a model that judges
with a shorter look hears a bow sound later (as :data:`RISE_FROM` says), so its note is dated
further back. On the tuning renders 2 → 3 → 4 → 5 hops: the live look's mean F1 0.7840 → 0.7920
→ 0.7962 → 0.7951 (string chords 0.62 → 0.66, in a room 0.55 → 0.62), the quick look's 0.7602 →
0.7647 → 0.7703 → 0.7672; on validation (FluidR3, seeds 101–102, eleven textures) live 0.7405
→ 0.7568 (string chords in a room 0.568 → 0.639, the organ chorale 0.416 → 0.470), quick 0.686
→ 0.722 (0.425 → 0.574). Dating by where the partials' rise crossed a tenth of its height did
no better (tuning, live 0.7948). On the tests' seed the live look's 4-voice piano fell 0.867 →
0.847, its string chords in a room rose 0.415 → 0.523."""
RISE_FROM = 2
"""Live (both looks that give a note as soon as it is named), a slow swell's rise
(:data:`SLOW_RISE`) is measured from this many hops before the pitch was last quiet: a model that
judges with a shorter look hears a bow sound later, so its last quiet frame already holds the
bow's first energy. On the TimGM6mb tuning renders (the fourteen textures, seeds 201–202), 0 → 1
→ 2 hops: the live look's mean F1 0.7793 → 0.7855 → 0.7840, the quick look's 0.7405 → 0.7558 →
0.7602 (string chords 0.45 → 0.50, in a room 0.41 → 0.48, a string line 0.76 → 0.81); the
offline look's fell (0.8204 → 0.8187 → 0.8168), so it measures from the quiet frame itself."""
RESTRIKE = 0.3
"""An onset-ear candidate at a pitch whose note is still followed (sounding) is that note struck
again only if the model gave the pitch P(onset) ≥ this within a hop before to two after: a
flute's breath or a bow's change lets the onset ear see an attack in a note that goes on.
Chosen on TimGM6mb renders as :data:`SWELL` was (0.1–0.5 alike): tuning mean F1 0.847 → 0.856
offline, 0.809 → 0.813 live; held out (FluidR3), flute lines 0.923 → 0.973, a string line
0.841 → 0.879.

In a chord (:data:`CHORD`), a note still followed is struck again too when the model's P(onset)
for it rises through this, short of its threshold: a chorale's common tone, held from one chord
into the next and struck with it, shows the model only a faint onset (0.06–0.6 on FluidR3's
piano) and the onset ear, busy with the chord's new notes, often none. Chosen on the TimGM6mb
tuning renders (seeds 201–202) among 0.05–0.5, 0.2–0.5 alike: mean F1 offline 0.8656 → 0.8676
(the piano chorale 0.877 → 0.888, a guitar chorale 0.904 → 0.909), live 0.8343 → 0.8347;
held out (FluidR3), the tests' chorale 0.711 → 0.720 and 0.674 → 0.679 in a room, a guitar
chorale in a room 0.880 → 0.889, live the chorale 0.657 → 0.654."""
CHORD = 2
"""Onset-ear notes within NEAR hops that make a chord. In a chord, a model's note at a partial of
an onset-ear note is a note of its own (a chorale's octave doublings, a voice a twelfth above the
bass); outside one it is that note's partial (a guitar's bright 2nd partial). Chosen on
TimGM6mb renders as :data:`SWELL` was (2 against 3 and against no chord rule): tuning mean F1
0.856 → 0.873 offline, 0.813 → 0.817 live, the piano chorale 0.763 → 0.846; held out (FluidR3),
the piano chorale 0.649 → 0.702, a guitar chorale 0.849 → 0.876, guitar lines unchanged (0.900),
a string line 0.879 → 0.866, the organ chorale 0.329 → 0.294.

A chord is also where the notes given (by either ear) or waiting within NEAR hops hold two roots
(pitches not at a partial of a lower one): a bass, its octave and a third above are a chord; a
note and its bright octave and twelfth are not. Live, the onset ear's notes often come after
the model's (its look is a hop longer), so its own count alone missed chords. Chosen on TimGM6mb
renders with :data:`OWN_PARTIAL`: the tuning mean F1 live 0.827 → 0.832 (the piano chorale 0.777
→ 0.811, a guitar chorale 0.802 → 0.827), offline 0.8646 → 0.8656."""
LATE = 1
"""Offline, the model's notes wait this many hops more than the onset ear's look, in case its
onset is a hop late. Live they do not (since 2026-12-05, with :data:`OWN_PARTIAL`): a struck note the
model names outright is given 3 hops (35 ms) after the hop it names it in instead of 4. On the TimGM6mb tuning renders the live
mean F1 went 0.832 → 0.834; held out (FluidR3, the bench's seeds) 0.715 → 0.713, guitar lines
0.905 → 0.899. Offline it is kept: there the tuning renders rose (0.866 → 0.872) but FluidR3
fell (0.799 → 0.797, piano and guitar lines 0.992 → 0.984 and 0.930 → 0.912), and nobody
waits offline."""
OWN_PARTIAL = 20.0 / (20.0 * np.log10(np.e))
"""Live, a model's note at a partial (2–8) of a lower model note given within NEAR hops, outside
a chord, is that note's partial if the lower note's fundamental band stands no more than 20 dB
(this, in the spectrum's natural-log units) below its own. Live, the model's notes cannot wait
for the onset ear's (60 ms), so a bright attack's octave or twelfth was given beside its note
before the onset ear's note came to explain it: piano and guitar lines were heard worse with
both ears than with the onset ear alone. The margin keeps a flute's faint sub-octave (the model
sometimes names a note an octave low, where the band is nearly empty) from silencing the note
above it. Chosen on TimGM6mb renders as :data:`SWELL` was: the eight tuning textures' mean F1
live 0.822 → 0.827, piano lines 0.961 → 0.973, guitar lines 0.960 → 0.986 (the onset ear alone
0.971 and 0.979); 0, 10 and 20 dB gave the same mean, 30 dB let the flute's sub-octave through
(flute 0.905 → 0.881). Offline, where the onset ear's notes are waited for, it lost the organ
0.365 → 0.317, so the offline look keeps the rule to onset-ear notes."""
RELEASE = 0.3
"""A followed note ends when the model's P(sounding) for it falls below this."""
F32_RELEASE, F32_RESTRIKE = np.float32(RELEASE), np.float32(RESTRIKE)
F32_SWELL = np.array([SWELL, SWELL_ONSET], dtype=np.float32)
"""As the model's float32 probabilities are compared (numpy compared them so)."""
SLOW_RULE = np.array([SLOW_SWELL, QUIET], dtype=np.int64)
"""The slow swell's hops, as the compiled :func:`_beginning` takes them."""
CLEAR = 16.0
"""How many times its band's noise floor a note's strongest partial (of its first four) must be:
a gate for what the model hears in noise. Measured on the current weights: notes heard in a
minute of brown room noise at −40 dBFS and in white noise at −20 dBFS stood 3–14 times their
floors; true notes of sampled piano, guitar, strings, organ and flute in a room (noise 30 dB
below the music) at least 26 times (their 1st percentile). (Measured with the floors' rise of
1 % a hop; at 0.25 %, ``FLOOR_RISE``, the floors sit lower, and no note is heard in either
noise, steady or switched on after silence: tests/test_audio_transcribe_input.py.)"""
RIVAL = 0.3
"""A short look (the quick one: the model judges 23 ms past an attack) often names a note that
falls a semitone as the semitone below it in its first frame, while the old note rings: at its attack
the fine model gave the lower neighbour P(onset) 0.53 and P(sounding) 0.73 (a swell), the true
pitch 0.42 and 0.59, and a frame later 0.18/0.19 against 0.70/0.97. So a quick look's note whose
semitone neighbour has P(onset) ≥ this in its frame is judged again a frame (5.8 ms) later and
given only if it sounds at least as surely as its neighbours. Without it the generated phrases
were not heard note for note at any threshold (tools/tune_hearing.py); the live and offline
looks, which judge 35 ms and more past an attack, never needed it and do not use it."""


def velocity_from_level(level_db: float, *, floor_db: float = -60.0) -> int:
    """Map an RMS level (dBFS) linearly onto MIDI velocity: ``floor_db`` → 1, 0 dBFS → 127."""
    return int(np.clip(round(1 + 126 * (level_db - floor_db) / -floor_db), 1, 127))


def _level_bands() -> np.ndarray:
    """(pitches, 4) long-spectrum bands of each pitch's first four partials (for its level)."""
    partials = PITCHES[:, None] + 12 * np.log2(np.arange(1, 5))[None, :]
    return np.round((partials - LONG_LOW) / LONG_STEP).astype(int)


class Transcriber:
    """Streams audio blocks in, gives the notes that began, as soon as each is recognised."""

    def __init__(self, samplerate: int, *, t0: float = 0.0, look: str = OFFLINE, model: Path | str | None = None,
                 threshold: float | None = None, heard_length: float = 0.25, max_length: float = 8.0,
                 ears: tuple[str, ...] = EARS) -> None:
        """``ears``: both by default; one alone (``("onsets",)`` or ``("model",)``) is how the bench
        measures what each adds (the model still follows the notes' durations)."""
        if look not in LOOKS:
            raise ValueError(f"look must be one of {', '.join(map(repr, LOOKS))}, not {look!r}")
        if not ears or set(ears) - set(EARS):
            raise ValueError(f"ears must be some of {EARS}, not {ears!r}")
        self.ears = tuple(ears)
        self.t0 = float(t0)
        self.look = look
        self.heard_length = float(heard_length)
        self.max_length = float(max_length)
        self.model = NoteModel(model if model is not None else default(look))
        if HOP % self.model.hop:
            raise ValueError(f"a note model's hop must divide {HOP} samples, not {self.model.hop}")
        self.hop = self.model.hop
        """Samples between the frames the model judges (the quick look's model hears on a finer
        grid than the onset ear's :data:`HOP`: an attack is named sooner)."""
        # The note logic's spans (NEAR, QUIET …) are in HOPs (11.6 ms) whatever the model's grid;
        # counted in the model's frames, there are ``per`` to a HOP. The onset ear keeps its grid.
        per = self._per = HOP // self.hop
        self.spectrum = LogSpectrum(self.hop)
        self.threshold = self.model.threshold if threshold is None else float(threshold)
        live = look != OFFLINE  # the live and the quick look give each note as soon as it is named
        self.ear = OnsetEar(LIVE_WINDOW if live else OFFLINE_WINDOW)
        # The onset ear's candidates wait until the model has judged a few hops past their
        # onset frame (offline, where nobody waits; live, that frame), and offline the
        # model's notes wait until the onset ear's have been given (a hop more: the ear's onset
        # may be a hop late): its notes come first, the model adds what it alone heard. Live the
        # model's notes do not wait: a struck note is given when the model names it, 3 hops after
        # its attack's (the quick look: 4 of its 128-sample hops), and a block (see LATE).
        self._verify_after = 0 if live else NEAR * per
        self._hold = 0 if live else max(0, (self.ear.delay_frames + LATE) * per - self.model.delay) + self._verify_after
        self._near_frames, self._slow_rule = NEAR * per, SLOW_RULE * per
        self._candidates: deque[Candidate] = deque()
        # The model's notes: (frame, pitch index, level, root, struck again: a note only in a chord).
        self._waiting: deque[tuple[int, int, float, float, bool]] = deque()
        # A short look (the model judges < 3 HOPs back): a note whose semitone neighbour began with
        # it is judged again a frame later (RIVAL), and a slow swell need rise less (SLOW_RISE_SHORT).
        self._short = self.model.reach < 3 * HOP
        self._slow_rise = SLOW_RISE_SHORT if self._short else SLOW_RISE
        self._doubted: list[tuple[int, int, float, float, bool]] = []
        self._recent: deque[tuple[int, np.ndarray, np.ndarray]] = deque(maxlen=(2 * NEAR + 4) * per)  # (frame, P(sounding), P(onset))
        # (frame, pitch, by the onset ear, its root: the level of its fundamental's band; an
        # onset-ear note's is taken as infinite, it explains its partials whatever their level)
        self._given: deque[tuple[int, int, bool, float]] = deque(maxlen=64)
        self._own_partials = live
        self._rise_from = RISE_FROM * per if live else 0
        self._slow_back = (SLOW_BACK_LIVE if live else SLOW_BACK) * per
        n_long = self.spectrum.long_bands.shape[0]
        self._level_bands = np.minimum(_level_bands(), n_long - 1)
        # The latest rows' frames, levels and bands' noise floors: the last delay + 1 for a note's
        # level and clearance, back as far as a slow swell may have begun for its rise.
        self._rows: deque[tuple[int, np.ndarray, np.ndarray]] = deque(maxlen=self.model.delay + (SLOW_SWELL + 2 + RISE_FROM) * per)
        self._previous = np.zeros(len(PITCHES), dtype=np.float32)  # last judged frame's P(onset)
        self._previous_sounding = np.zeros(len(PITCHES), dtype=np.float32)  # and its P(sounding)
        # Per judged frame, per pitch: a followed note ends, a note begins (either way), by a swell.
        self._ending, self._rising, self._swelling, self._again = (np.zeros(len(PITCHES), dtype=bool)
                                                                   for _ in range(4))
        self._onsets = np.zeros((4 * per, len(PITCHES)), dtype=np.float32)  # the last 4 hops' P(onset), a ring
        self._slowing = np.zeros(len(PITCHES), dtype=bool)  # a note begins by a slow swell
        # Per pitch, the last frame its P(sounding) was below RELEASE, and for how many frames it had been.
        self._quiet_at = np.zeros(len(PITCHES), dtype=np.int64)
        self._quiet_for = np.zeros(len(PITCHES), dtype=np.int64)
        self._quiet_until = WARM_UP * per  # no note is taken from a judged frame before this one
        self._clipping_until = -1  # frames up to this one were heard through clipping
        # Notes followed until they end, per pitch: whether one is, when it began, its velocity.
        self._held = np.zeros(len(PITCHES), dtype=bool)
        self._began = np.zeros(len(PITCHES))
        self._velocity = np.zeros(len(PITCHES), dtype=int)
        self.ended: deque[NoteEvent] = deque(maxlen=1024)
        """Notes that ended, with their measured durations (the latest 1024)."""
        self.onsets = 0  # frames in which a note began
        self.notes = 0  # notes given
        self.bad_samples = 0  # non-finite or out-of-range samples replaced
        self.clipped = 0  # samples at or beyond full scale
        self._last_good = 0.0
        self._rate = 0
        self._resampler: Resampler
        self.set_rate(samplerate)

    @property
    def latency(self) -> float:
        """Seconds from the end of an attack's hop until its note is given (the model's judgement,
        then the hops its notes wait for the onset ear's)."""
        return (self.model.delay + self._hold) * self.hop / RATE

    def set_rate(self, samplerate: int) -> None:
        """The input's rate from now on (a live device reopened at another rate)."""
        samplerate = int(samplerate)
        if samplerate == self._rate:
            return
        if self._rate:
            # The old resampler's tail is lost and the new one starts cold: a seam in the
            # stream, which must not be heard as an attack.
            self._seam()
        self._rate = samplerate
        self._resampler = Resampler(samplerate, RATE)

    def _seam(self, frames: int = SEAM) -> None:
        """No note from the next ``frames`` hops, in either ear: they hold a step, not an attack."""
        self._quiet_until = max(self._quiet_until, self.spectrum.frames + frames * self._per)
        self.ear.seam(frames)

    def feed(self, block: np.ndarray) -> list[NoteEvent]:
        """The notes recognised within ``block`` (any shape ``(frames,)`` or ``(frames, ch)``)."""
        x = np.asarray(block, dtype=np.float32)
        if x.ndim == 2:
            x = x.mean(axis=1)
        hops = -(-len(x) * RATE // (self._rate * HOP))  # the hops this block reaches into
        bad = unusable(x)
        if bad.any():
            # Each bad sample holds the last good one: a zero in a loud tone would be a click.
            self.bad_samples += int(bad.sum())
            self._seam(SEAM + hops)
            good = np.where(bad, 0, np.arange(len(x)))
            np.maximum.accumulate(good, out=good)
            x = np.where(bad[good], self._last_good, x[good]).astype(np.float32)
        if len(x):
            self._last_good = float(x[-1])
        clipped = int(np.count_nonzero(np.abs(x) >= 0.999))
        if clipped:
            self.clipped += clipped
            self._clipping_until = self.spectrum.frames + (hops + 1) * self._per
        x = self._resampler(x)
        if "onsets" in self.ears:
            # On a finer model grid a candidate takes its hop's first frame (dated 2.9 ms before its middle).
            self._candidates.extend(c._replace(frame=c.frame * self._per) for c in self.ear.feed(x))
        rows = self.spectrum.feed(x)
        judged = self.model(rows)
        if judged is None:
            return []
        notes: list[NoteEvent] = []
        for i, (row, floor) in enumerate(zip(rows, self.spectrum.floors)):
            self._rows.append((judged.frame + i + self.model.delay, row[self._level_bands], floor[self._level_bands]))
            notes.extend(self._judge(judged, i))
        return notes

    def flush(self) -> list[NoteEvent]:
        """End every note still sounding (the input stopped); returns nothing new."""
        end = self._time(self.spectrum.frames - self.model.delay)
        for k in np.flatnonzero(self._held):
            self._end(k, end)
        return []

    @property
    def fed_until(self) -> float:
        """The time just after the last sample fed: where the next block begins, counted in samples."""
        return self.t0 + (self.spectrum.frames * self.hop + self.spectrum.pending) / RATE

    def skip(self, seconds: float) -> None:
        """The clock jumped ``seconds`` ahead between two blocks (``creatures.clock.clock_gap``):
        times are counted in samples, so without this every note heard after a suspended night
        would be dated before it. Notes sounding end where they were heard, the step the gap
        leaves in the stream is not taken as an attack, and the next sample is dated after it."""
        self.flush()
        self._seam()
        self.ear.skip()
        self._candidates.clear()
        self._waiting.clear()
        self._doubted.clear()
        self.t0 += float(seconds)

    # -- per judged frame --------------------------------------------------------------------
    def _time(self, frame: int) -> float:
        """The middle of frame ``frame``'s hop: where in it an attack lies, ± 5.8 ms."""
        return self.t0 + (frame + 0.5) * self.hop / RATE

    def _judge(self, judged: Judged, i: int) -> list[NoteEvent]:
        frame = judged.frame + i
        onset, sounding = judged.onset[i], judged.sounding[i]
        t = self._time(frame)
        if _ending(self._held, sounding, self._began, t - self.max_length, F32_RELEASE, self._ending):
            for k in np.flatnonzero(self._ending):
                self._end(k, t)
        self._recent.append((frame, sounding, onset))
        notes = []
        # The onset ear's candidates, if the model hears their pitch sound.
        while self._candidates and self._candidates[0].frame <= frame - self._verify_after:
            c = self._candidates.popleft()
            k = c.pitch - int(PITCHES[0])
            verified = self._verified(c.frame, k) or "model" not in self.ears
            if c.frame >= self._quiet_until and verified and not self._near(c.frame, c.pitch):
                notes.append(self._give(k, c.frame, c.level_db, by_ear=True))
        # The model's own onsets (offline they wait for the onset ear's; those it explains are not notes again).
        rising, swelling, again = self._rising, self._swelling, self._again
        began = _beginning(onset, sounding, self._previous, self._previous_sounding, self._held,
                           np.float32(self.threshold), F32_RESTRIKE, F32_SWELL,
                           self._onsets, frame % len(self._onsets), rising, swelling, again,
                           frame, F32_RELEASE, self._slow_rule, self._quiet_at, self._quiet_for, self._slowing)
        if self._doubted:  # a frame later: a note if it sounds at least as surely as its semitone neighbours
            self._waiting.extend(w for w in self._doubted if sounding[w[1]] >= sounding[max(w[1] - 1, 0):w[1] + 2].max())
            self._doubted.clear()
        if frame >= self._quiet_until and began and "model" in self.ears:
            if frame <= self._clipping_until:
                rising = self._undistorted(rising)
            latest = list(self._rows)[-(self.model.delay + 1):]  # the rows that judged this frame
            levels = np.max([level for _, level, _ in latest], axis=0)  # (pitches, 4)
            clear = np.max([self.spectrum.above_floor(level, floor) for _, level, floor in latest],
                           axis=0).max(axis=1) >= CLEAR
            for k in np.flatnonzero((rising | again) & clear):
                if self._slowing[k] and not self._rose(k, levels[k]):
                    continue
                level_db = 20.0 * np.log10(max(float(np.expm1(levels[k].max())) / SCALE, 1e-10))
                at = frame
                if swelling[k]:  # dated where its onset peaked (the earliest, if tied)
                    ring = len(self._onsets)
                    oldest_first = [self._onsets[(frame - back) % ring, k] for back in range(ring - 1, -1, -1)]
                    at -= ring - 1 - int(np.argmax(oldest_first))
                elif self._slowing[k]:
                    at = int(self._quiet_at[k]) + 1 - self._slow_back
                note = (at, int(k), level_db, float(levels[k, 0]), bool(again[k]))
                neighbours = onset[[j for j in (k - 1, k + 1) if 0 <= j < len(onset)]]
                (self._doubted if self._short and neighbours.max() >= RIVAL else self._waiting).append(note)
        while self._waiting and self._waiting[0][0] <= frame - self._hold:
            f, k, level_db, root, struck_again = self._waiting.popleft()
            chord = self._in_chord(f)
            if (chord or not struck_again) and not self._near(f, int(PITCHES[k]), partials=not chord, root=root):
                notes.append(self._give(k, f, level_db, by_ear=False, root=root))
        self.onsets += bool(notes)
        self.notes += len(notes)
        return notes

    def _rose(self, k: int, levels: np.ndarray) -> bool:
        """Whether pitch index ``k``'s first four partials (``levels``, now) rose by
        :data:`SLOW_RISE` (:data:`SLOW_RISE_SHORT`) since the last frame it was quiet: a slow swell that
        brought its own energy."""
        before = [level[k] for f, level, _ in self._rows if f <= self._quiet_at[k] - self._rise_from]
        return not before or float(np.max(levels - before[-1])) >= self._slow_rise

    def _verified(self, frame: int, k: int) -> bool:
        """Whether the model heard pitch index ``k`` sound from two hops before ``frame`` on (and,
        if a note of it is followed, begin again: :data:`RESTRIKE`)."""
        per = self._per
        if not (0 <= k < len(PITCHES) and any(s[k] >= VERIFY for f, s, _ in self._recent if f >= frame - 2 * per)):
            return False
        if self._held[k]:  # struck again, or a fluctuation of the note sounding
            return any(o[k] >= RESTRIKE for f, _, o in self._recent if frame - per <= f <= frame + 2 * per)
        return True

    def _in_chord(self, frame: int) -> bool:
        """Whether a chord began within NEAR hops of ``frame``: the onset ear gave :data:`CHORD`
        notes or more there, or the other notes given or waiting there hold CHORD roots (pitches
        not at a partial, 2–8, of a lower one)."""
        near = [(p, by_ear) for f, p, by_ear, _ in self._given if abs(f - frame) <= self._near_frames]
        if sum(by_ear for _, by_ear in near) >= CHORD:
            return True
        waiting = {int(PITCHES[k]) for f, k, _, _, again in self._waiting if abs(f - frame) <= self._near_frames and not again}
        pitches = sorted({p for p, _ in near} | waiting)
        roots: list[int] = []
        for p in pitches:
            if not any(p - q in PARTIALS for q in roots):
                roots.append(p)
        return len(roots) >= CHORD

    def _near(self, frame: int, pitch: int, *, partials: bool = False, root: float = np.inf) -> bool:
        """Whether a note of ``pitch`` was given within NEAR hops of ``frame`` — or, with
        ``partials``, a note it is a partial of: an onset-ear note, or live a model's note whose
        root stands at most :data:`OWN_PARTIAL` below ``root`` (this note's)."""
        return any(abs(f - frame) <= self._near_frames and (p == pitch or (
            partials and pitch - p in PARTIALS and (by_ear or (self._own_partials and r >= root - OWN_PARTIAL))))
            for f, p, by_ear, r in self._given)

    def _give(self, k: int, frame: int, level_db: float, *, by_ear: bool, root: float = np.inf) -> NoteEvent:
        """A note of pitch index ``k`` begins at ``frame``'s hop (an onset-ear note, :data:`LEAD`
        hop before its onset's): given, and followed."""
        t = self._time(frame - LEAD * self._per if by_ear else frame)
        if self._held[k]:
            self._end(k, t)  # struck again
        note = NoteEvent(max(t, 0.0), int(PITCHES[k]), velocity_from_level(level_db), 0, self.heard_length)
        self._held[k], self._began[k], self._velocity[k] = True, note.time, note.velocity
        self._given.append((frame, note.pitch, by_ear, root))
        return note

    @staticmethod
    def _undistorted(rising: np.ndarray) -> np.ndarray:
        """``rising`` without pitches at a partial (2–8) of a lower rising one."""
        kept = rising.copy()
        for k in np.flatnonzero(rising):
            above = k + PARTIALS
            kept[above[above < len(kept)]] = False
        return kept

    def _end(self, k: int, at: float) -> None:
        """The note followed at pitch index ``k`` ended at ``at``: into :attr:`ended`, measured."""
        began = float(self._began[k])
        self._held[k] = False
        self.ended.append(NoteEvent(began, int(PITCHES[k]), int(self._velocity[k]), 0, max(at - began, 0.0)))


@numba.njit(cache=True, nogil=True)
def _ending(held, sounding, began, horizon, release, ending):  # pragma: no cover
    """Which followed notes end this frame (the model stops hearing them sound, or they began
    before ``horizon``), into ``ending``; whether any does. Compiled with :func:`_beginning`:
    a dozen numpy operations on 88 pitches a hop cost more than the rest of the note logic."""
    any_ending = False
    for k in range(len(held)):
        ending[k] = held[k] and (sounding[k] < release or began[k] < horizon)
        any_ending |= ending[k]
    return any_ending


@numba.njit(cache=True, nogil=True)
def _beginning(onset, sounding, previous, previous_sounding, held, threshold, restrike, swell, ring, slot,
               rising, swelling, again, frame, release, slow, quiet_at, quiet_for, slowing):  # pragma: no cover
    """Which pitches begin a note this frame: P(onset) rising through ``threshold``, or a swell
    (``swell``: :data:`SWELL`, :data:`SWELL_ONSET`; marked in ``swelling`` too), or a slow swell
    (``slow``: :data:`SLOW_SWELL`, :data:`QUIET`; marked in ``slowing``: whether it rose enough
    is judged after); whether any does;
    in ``again``, followed notes whose P(onset) rose through ``restrike`` (struck again, if in a
    chord: :data:`RESTRIKE`). Keeps this frame's probabilities as the previous ones and its
    P(onset) in ``ring`` at ``slot``, and per pitch the last ``frame`` its P(sounding) was below
    ``release`` in ``quiet_at``, how many frames running in ``quiet_for``."""
    any_beginning = False
    for k in range(len(onset)):
        ring[slot, k] = onset[k]
        rising[k] = onset[k] >= threshold and previous[k] < threshold
        again[k] = held[k] and not rising[k] and onset[k] >= restrike and previous[k] < restrike
        any_beginning |= again[k]
        swelling[k] = slowing[k] = False
        if sounding[k] < release:
            quiet_for[k] = quiet_for[k] + 1 if quiet_at[k] == frame - 1 else 1
            quiet_at[k] = frame
        if not rising[k] and not held[k] and sounding[k] >= swell[0] and previous_sounding[k] < swell[0]:
            peak = ring[0, k]
            for j in range(1, ring.shape[0]):
                peak = max(peak, ring[j, k])
            swelling[k] = peak >= swell[1]
            slowing[k] = not swelling[k] and frame - quiet_at[k] <= slow[0] and quiet_for[k] >= slow[1]
        rising[k] |= swelling[k] | slowing[k]
        any_beginning |= rising[k]
        previous[k] = onset[k]
        previous_sounding[k] = sounding[k]
    return any_beginning
