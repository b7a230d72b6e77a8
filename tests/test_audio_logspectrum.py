"""The note model's front end (audio/logspectrum.py) and the model's runtime (audio/note_model.py)."""

from __future__ import annotations

import numpy as np
import pytest

from audio.logspectrum import HOP, RATE, LogSpectrum, midi_hz
from audio.note_model import NoteModel, default, join
from audio.transcribe import Transcriber


@pytest.mark.parametrize("hop", [HOP, HOP // 2])
def test_a_stream_fed_in_pieces_gives_the_rows_it_gives_whole(rng: np.random.Generator, hop: int) -> None:
    x = (0.1 * rng.standard_normal(3 * RATE)).astype(np.float32)
    whole = LogSpectrum(hop).feed(x)
    pieces = LogSpectrum(hop)
    cut = np.concatenate([pieces.feed(x[i:i + 333]) for i in range(0, len(x), 333)])
    assert whole.shape == (len(x) // hop, LogSpectrum().width)
    np.testing.assert_allclose(cut, whole, atol=1e-5)


def test_a_finer_hop_is_the_same_analysis_twice_as_often() -> None:
    """Every other row of a 128-sample hop ends where a 256-sample hop's row ends: on a chord
    after silence they are the same rows (the floors rise by the same amount a second), and the
    rows between show the attack half a hop sooner."""
    t = np.arange(RATE) / RATE
    chord = sum(np.sin(2 * np.pi * midi_hz(p) * t) for p in (48, 64, 67))
    x = np.r_[np.zeros(RATE // 2 + 100), 0.1 * chord].astype(np.float32)
    coarse, fine = LogSpectrum().feed(x), LogSpectrum(HOP // 2).feed(x)
    np.testing.assert_allclose(fine[1::2], coarse, atol=1e-3)
    first_fine, first_coarse = (int(np.argmax(rows.max(axis=1) > 0)) for rows in (fine, coarse))
    assert (first_fine + 1) * (HOP // 2) == (first_coarse + 1) * HOP - HOP // 2  # its row ends 5.8 ms sooner


def test_a_hop_the_windows_cannot_cover_is_refused() -> None:
    with pytest.raises(ValueError, match="hop must be 1–512 samples, not 1024"):
        LogSpectrum(1024)


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


@pytest.mark.parametrize("look", ["live", "quick", "offline"])
def test_the_shipped_models_hear_a_plain_chord_and_nothing_in_silence(look: str) -> None:
    """Each look's weights, run as the product runs them: a chord of three plain tones after half
    a second of silence is its three notes, at its attack, and the silence is none."""
    assert NoteModel(default(look)).hop == (HOP // 2 if look == "quick" else HOP)
    t = np.arange(RATE) / RATE
    chord = sum(np.sin(2 * np.pi * midi_hz(p) * k * t) / k for p in (60, 64, 67) for k in range(1, 5))
    x = np.r_[np.zeros(RATE // 2), 0.05 * chord, np.zeros(RATE // 2)].astype(np.float32)
    ear = Transcriber(RATE, look=look)
    notes = ear.feed(x)
    assert sorted(n.pitch for n in notes) == [60, 64, 67]
    assert all(abs(n.time - 0.5) < 0.03 for n in notes)


def test_a_file_that_is_not_a_note_model_is_refused_by_name(tmp_path) -> None:
    path = tmp_path / "notes.npz"
    np.savez(path, w1=np.zeros((78, 32)), context=np.array(8))
    with pytest.raises(ValueError, match="not a note model's weights .*delay"):
        NoteModel(path)


def _chord_rows() -> np.ndarray:
    t = np.arange(RATE) / RATE
    chord = sum(np.sin(2 * np.pi * midi_hz(p) * k * t) / k for p in (48, 55, 64) for k in range(1, 5))
    return LogSpectrum().feed(np.r_[np.zeros(RATE // 4), 0.05 * chord].astype(np.float32))


def test_a_committee_averages_its_members_and_holds_back_one_that_looks_less_far(tmp_path) -> None:
    """A committee (audio/note_model.py, ``join``) of one model and the same weights told to judge
    2 hops further back: its judgement of a frame is the mean of the model's judgement of that
    frame and of the frame 2 hops later (what the second member, looking 2 hops less far past the
    frame it names, said), so each member judges the committee's frame."""
    live = default("live")
    with np.load(live) as z:
        later = {k: z[k] for k in z.files}
    later["delay"] = np.array(int(later["delay"]) + 2)
    np.savez(tmp_path / "later.npz", **later)
    join(tmp_path / "both.npz", [live, tmp_path / "later.npz"])
    rows = _chord_rows()
    alone, both = NoteModel(live)(rows), NoteModel(tmp_path / "both.npz")(rows)
    assert both.frame == alone.frame - 2 and NoteModel(tmp_path / "both.npz").threshold == 0.5
    for mine, ours in ((alone.onset, both.onset), (alone.sounding, both.sounding)):
        np.testing.assert_allclose(ours[2:], (mine[:-2] + mine[2:]) / 2, atol=1e-6)
        np.testing.assert_allclose(ours[:2], mine[:2] / 2, atol=1e-6)  # nothing was held before the stream
    assert alone.sounding.max() > 0.9  # the chord sounds: the means above are of something


def test_a_committee_of_models_on_different_grids_or_of_committees_is_refused(tmp_path) -> None:
    with pytest.raises(ValueError, match="one grid"):
        join(tmp_path / "mixed.npz", [default("live"), default("quick")])
    assert not list(tmp_path.iterdir())  # nothing half-written is left
    with pytest.raises(ValueError, match="already a committee"):
        join(tmp_path / "twice.npz", [default("offline"), default("live")])
