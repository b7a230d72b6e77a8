"""StringBank (the fast path) against ScannedString.render_raw (the reference integrator)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pydantic import ValidationError

from audio.scanned import ScannedString, StringParameters
from audio.string_bank import StringBank
from audio.voices import VoicePool, midi_to_hz
from creatures.kinds.parts import VoiceSpec

SR = 48000


def excite(string: ScannedString, rng: np.random.Generator) -> None:
    """A pluck, a strike and a body push, all drawn from ``rng``."""
    string.pluck(position=float(rng.uniform()), width=float(rng.uniform(0.05, 1.0)), amplitude=float(rng.normal()))
    string.strike(position=float(rng.uniform()), width=float(rng.uniform(0.05, 1.0)), velocity=float(rng.normal(0, 5)))
    string.push(rng.normal(0, 20, string.parameters.n_masses))


@pytest.mark.parametrize("interpolation", ["linear", "none"])
@pytest.mark.parametrize("ring", [False, True])
@pytest.mark.parametrize("masses, haptic_rate", [(1, 1000.0), (2, 500.0), (3, 1000.0), (32, 500.0), (64, 500.0),
                                                  (128, 1000.0), (1024, 250.0)])
def test_bank_samples_are_the_reference_integrators(ring, masses, haptic_rate, interpolation):
    """Every string of a bank, excited and pushed between blocks of uneven length, scans the
    same samples as a lone ScannedString given the same history (to 1e-6)."""
    parameters = StringParameters(n_masses=masses, haptic_rate=haptic_rate, ring=ring, interpolation=interpolation)
    rng_bank, rng_ref = np.random.default_rng(23), np.random.default_rng(23)
    frequencies = [55.0, 220.0, 1234.5, 23000.0]
    bank = StringBank(len(frequencies), parameters, sample_rate=SR, block_size=700)
    references = [ScannedString(parameters, sample_rate=SR, frequency=f) for f in frequencies]
    for string, f in zip(bank.strings, frequencies):
        string.frequency = f
    one, zero = np.ones(len(frequencies)), np.zeros(len(frequencies))
    loudest = 0.0
    for block in (1, 47, 700, 333, 512):
        for i, reference in enumerate(references):
            excite(bank.strings[i], rng_bank)
            excite(reference, rng_ref)
            mix = np.zeros(block)
            bank.render(mix, np.array([i]), one, zero)  # one string alone: the mix is its samples
            expected = reference.render_raw(np.empty(block))
            loudest = max(loudest, np.abs(expected).max())
            np.testing.assert_allclose(mix, expected, rtol=0, atol=1e-6)
            np.testing.assert_allclose(bank.strings[i].x, reference.x, rtol=0, atol=1e-9)
    assert loudest > 0.01


@pytest.mark.parametrize("lowest, apart", [(100.0, 37.0), (1500.0, 370.0)])  # the second band-limited from 32 masses
@pytest.mark.parametrize("interpolation", ["linear", "none"])
@pytest.mark.parametrize("masses", [1, 3, 32, 64, 128])
def test_strings_whose_frames_fall_due_apart_mix_as_the_references(masses, interpolation, lowest, apart):
    """Strings rendered together whose haptic frames come due at different samples (each was
    first played alone for a different length): the group steps each when its own frame is due,
    and the mix is the references' sum (to 1e-6), for short strings stepped across the voices
    and long ones along their masses, band-limited or not."""
    parameters = StringParameters(n_masses=masses, ring=masses % 2 == 1, haptic_rate=1000.0,
                                  interpolation=interpolation)
    rng_bank, rng_ref = np.random.default_rng(5), np.random.default_rng(5)
    count = 11
    bank = StringBank(count, parameters, sample_rate=SR, block_size=512)
    references = [ScannedString(parameters, sample_rate=SR, frequency=lowest + apart * i) for i in range(count)]
    for i, reference in enumerate(references):
        bank.strings[i].frequency = reference.frequency
        excite(bank.strings[i], rng_bank)
        excite(reference, rng_ref)
        bank.render(np.zeros(5 * i + 1), np.array([i]), np.ones(count), np.zeros(count))
        reference.render_raw(np.empty(5 * i + 1))
    everyone, level, slope = np.arange(count), np.ones(count), np.zeros(count)
    for block in (512, 100, 7, 300):
        mix = np.zeros(block)
        bank.render(mix, everyone, level, slope)
        expected = sum(reference.render_raw(np.empty(block)) for reference in references)
        assert np.abs(expected).max() > 0.01
        np.testing.assert_allclose(mix, expected, rtol=0, atol=1e-6)
    for string, reference in zip(bank.strings, references):
        np.testing.assert_allclose(string.x, reference.x, rtol=0, atol=1e-9)


@pytest.mark.parametrize("sample_rate, pitches", [(SR, (48, 55, 60, 67)), (22050, (48, 91, 60, 108))])
def test_voice_pool_mix_is_the_sum_of_enveloped_reference_strings(sample_rate, pitches):
    """The pool's one-call mix equals the old path: each sounding voice rendered alone, times
    its linear release, summed; released voices are freed when the release ends. At 22050 Hz
    MIDI 91 and 108 have harmonics above the band: band-limited, in the bank as alone."""
    parameters = StringParameters(n_masses=32, ring=False)
    pool = VoicePool(4, parameters, sample_rate=sample_rate, release=0.005, block_size=256)
    references: dict[int, ScannedString] = {}
    level = {}
    step = 1.0 / (0.005 * sample_rate)
    ended = pitches[1]
    for pitch in pitches:
        index = pool.note_on(pitch, 0.8)
        reference = ScannedString(parameters, sample_rate=sample_rate)
        reference.note_on(midi_to_hz(pitch), 0.8)
        references[index], level[index] = reference, (1.0, 0.0)
    out = np.empty(1000)  # longer than block_size: rendered in pieces
    for round_ in range(4):
        if round_ == 1:
            released = int(np.flatnonzero(pool.pitch == ended)[0])
            pool.release(released, pool.started[released])
            for index, reference in references.items():
                if pool.pitch[index] == ended:
                    level[index] = (1.0, -step)
        pool.render(out)
        expected = np.zeros(len(out))
        for start in range(0, len(out), 256):
            piece = slice(start, min(start + 256, len(out)))
            for index, reference in references.items():
                g, dg = level[index]
                if g <= 0.0 and dg:
                    continue
                samples = reference.render_raw(np.empty(piece.stop - piece.start))
                if dg:
                    envelope = np.clip(g + dg * np.arange(1, len(samples) + 1), 0.0, 1.0)
                    samples *= envelope
                    level[index] = (envelope[-1], dg)
                expected[piece] += samples
        assert np.abs(expected).max() > 0
        np.testing.assert_allclose(out, expected, rtol=0, atol=1e-6)
    assert pool.active == 3 and ended not in pool.pitch
    assert [bank_string.band()[0] < bank_string.band()[1] for bank_string in pool.voices] == [
        sample_rate == 22050 and midi_to_hz(pitch) * 16 > 0.45 * sample_rate for pitch in pitches]


@pytest.mark.parametrize("frequency", [220.0, 5000.0])  # the second band-limited (harmonics 5–8 above 0.45 SR)
def test_a_string_that_blows_up_is_reset_and_adds_nothing(frequency):
    parameters = dataclasses.replace(StringParameters(n_masses=16), ring=True)
    bank = StringBank(2, parameters, sample_rate=SR, block_size=512)
    for string in bank.strings:
        string.frequency = frequency
    bank.strings[0].pluck(amplitude=1e308)
    bank.strings[0].push(np.full(16, 1e308))
    bank.strings[1].pluck(amplitude=0.5)
    mix = np.zeros(512)
    bank.render(mix, np.array([0, 1]), np.ones(2), np.zeros(2))
    alone = np.zeros(512)
    reference = ScannedString(parameters, sample_rate=SR, frequency=frequency)
    reference.pluck(amplitude=0.5)
    alone[:] = reference.render_raw(np.empty(512))
    assert np.abs(alone).max() > 0.01
    np.testing.assert_allclose(mix, alone, rtol=0, atol=1e-6)
    assert bank.strings[0].resets == 1 and not bank.strings[0].x.any() and bank.strings[1].resets == 0


def test_a_block_longer_than_the_bank_is_refused():
    bank = StringBank(1, sample_rate=SR, block_size=64)
    with pytest.raises(ValueError, match="block_size 64"):
        bank.render(np.zeros(65), np.array([0]), np.ones(1), np.zeros(1))


def test_push_sets_the_force_of_the_chosen_strings_only():
    bank = StringBank(3, StringParameters(n_masses=8), sample_rate=SR)
    force = np.arange(8.0)
    force[3] = np.nan
    bank.push(np.array([0, 2]), force)
    assert bank.strings[0].force.tolist() == bank.strings[2].force.tolist() == [0, 1, 2, 0, 4, 5, 6, 7]
    assert not bank.strings[1].force.any()
    with pytest.raises(ValueError, match=r"shape \(8,\)"):
        bank.push(np.array([0]), np.zeros(7))


def test_scanning_without_interpolation_reads_the_nearest_mass_of_the_latest_frame():
    """``interpolation = "none"`` (Csound's scantable): a slow scan of a frozen shape holds each
    mass's value for a whole node span instead of ramping between masses; the config passes it on."""
    parameters = StringParameters(n_masses=8, ring=True, damping=0.0, stiffness=0.0, centring=0.0,
                                  interpolation="none")
    string = ScannedString(parameters, sample_rate=SR, frequency=SR / 800.0)  # 100 samples per mass
    string.x[:] = string._x_prev[:] = np.arange(8.0)
    raw = string.render_raw(np.empty(800))
    steps = np.flatnonzero(np.abs(np.diff(raw)) > 0.5)
    assert len(steps) == 7 and np.all(np.abs(np.diff(steps) - 100) <= 1)  # a step per mass, flat between
    linear = ScannedString(dataclasses.replace(parameters, interpolation="linear"), sample_rate=SR,
                           frequency=SR / 800.0)
    linear.x[:] = linear._x_prev[:] = np.arange(8.0)
    assert not (np.abs(np.diff(linear.render_raw(np.empty(800)))) > 0.5).any()
    assert VoiceSpec(interpolation="none").parameters().interpolation == "none"
    with pytest.raises(ValidationError, match="interpolation"):
        VoiceSpec(interpolation="cubic")
    with pytest.raises(ValueError, match="interpolation must be one of"):
        StringParameters(interpolation="cubic")


def test_a_scan_at_phase_one_reads_the_first_point_as_the_reference_does():
    """The reference reads ``phase × points`` with its index taken modulo the points, so a
    phase of 1.0 reads point 0 with weight 0 on point 1. The bank's reader wrapped the index
    but kept the weight ``pos - j`` of the unwrapped position: a phase of 1.0 read
    y0 + 4 × (y1 − y0) on a 4-point trajectory (the kernel's own wrap keeps a phase under 1;
    a phase of exactly 1 can only come from outside it, but must not read off the table)."""
    from audio.string_bank import _read

    rows = np.arange(10, dtype=float) + 1.0  # the shape, point p in row p
    shown = np.zeros(1)
    for phase in (0.0, 1.0):
        _read(shown, rows, rows, np.array([phase]), np.array([0.0]), 1, 4, 0, 1, 0, True)
        assert shown[0] == 1.0, phase
