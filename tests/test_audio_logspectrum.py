"""The note model's front end (audio/logspectrum.py) and the model's runtime (audio/note_model.py)."""

from __future__ import annotations

import numpy as np
import pytest

from audio.logspectrum import HOP, RATE, LogSpectrum, midi_hz
from audio.note_model import PITCHES, NoteModel, default


def test_a_stream_fed_in_pieces_gives_the_rows_it_gives_whole(rng: np.random.Generator) -> None:
    x = (0.1 * rng.standard_normal(3 * RATE)).astype(np.float32)
    whole = LogSpectrum().feed(x)
    pieces = LogSpectrum()
    cut = np.concatenate([pieces.feed(x[i:i + 333]) for i in range(0, len(x), 333)])
    assert whole.shape == (len(x) // HOP, LogSpectrum().width)
    np.testing.assert_allclose(cut, whole, atol=1e-5)


def test_a_sine_lights_the_bands_at_its_pitch() -> None:
    """A 440 Hz sine after silence: in the long spectrum the band nearest MIDI 69 is the loudest,
    and every band of the silence before it is zero (its floor is itself)."""
    t = np.arange(RATE) / RATE
    x = np.r_[np.zeros(RATE // 2), 0.3 * np.sin(2 * np.pi * midi_hz(69) * t)].astype(np.float32)
    spectrum = LogSpectrum()
    rows = spectrum.feed(x)
    n_long = spectrum.long_bands.shape[0]
    assert np.all(rows[: RATE // 2 // HOP - 1] == 0.0)
    loudest = int(np.argmax(rows[-1, :n_long]))
    assert loudest == round((69 - 21) * 3)


@pytest.mark.parametrize("look", ["live", "offline"])
def test_the_shipped_models_hear_a_plain_chord_and_nothing_in_silence(look: str) -> None:
    model = NoteModel(default(look))
    t = np.arange(RATE) / RATE
    chord = sum(np.sin(2 * np.pi * midi_hz(p) * k * t) / k for p in (60, 64, 67) for k in range(1, 5))
    x = np.r_[np.zeros(RATE // 2), 0.05 * chord].astype(np.float32)
    judged = model(LogSpectrum().feed(x))
    began = {int(PITCHES[k]) for k in np.flatnonzero(judged.onset.max(axis=0) >= model.threshold)}
    assert {60, 64, 67} <= began and len(began) <= 4
    silent = judged.onset[: RATE // 2 // HOP - model.delay]
    assert silent.max() < model.threshold


def test_a_file_that_is_not_a_note_model_is_refused_by_name(tmp_path) -> None:
    path = tmp_path / "notes.npz"
    np.savez(path, w1=np.zeros((78, 32)), context=np.array(8))
    with pytest.raises(ValueError, match="not a note model's weights .*delay"):
        NoteModel(path)
