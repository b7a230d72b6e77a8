"""ScannedString: pitch from the scan rate, decay from damping, timbre from stiffness, safety."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from pydantic import ValidationError
from scipy.signal import find_peaks
from hypothesis import given, settings
from hypothesis import strategies as st

from audio.scanned import GESTURAL_LIMIT_HZ, ScannedString, StringParameters, UnstableStringError
from audio.voices import VoicePool, midi_to_hz
from creatures.kinds.parts import Voice, VoiceSpec

SR = 48000


def fundamental(signal: np.ndarray, *, low: float = 50.0) -> float:
    """Lowest spectral peak above ``low`` Hz within 20 dB of the strongest, refined by
    parabolic interpolation of log |X| (the strongest partial wanders as the shape evolves)."""
    n = 1 << 19  # zero-padded: ~0.09 Hz bins before interpolation
    spectrum = np.abs(np.fft.rfft(signal * np.hanning(len(signal)), n))
    freqs = np.fft.rfftfreq(n, 1.0 / SR)
    spectrum[freqs < low] = 0.0
    peaks, _ = find_peaks(spectrum, height=0.1 * spectrum.max())
    k = int(peaks[0])
    a, b, c = np.log(spectrum[k - 1 : k + 2])
    return float(freqs[k] + 0.5 * (a - c) / (a - 2 * b + c) * SR / n)


def centroid(signal: np.ndarray) -> float:
    power = np.abs(np.fft.rfft(signal * np.hanning(len(signal)))) ** 2
    return float(power @ np.fft.rfftfreq(len(signal), 1.0 / SR) / power.sum())


def test_plucked_string_sounds_at_the_scan_frequency():
    string = ScannedString(StringParameters(), sample_rate=SR, frequency=220.0)
    string.pluck(position=0.3, width=0.2, amplitude=0.5)
    audio = string.render(2 * SR)
    assert fundamental(audio[SR // 10 :]) == pytest.approx(220.0, abs=2.0)


def test_note_event_sets_pitch_through_the_scan_rate():
    string = ScannedString(StringParameters(), sample_rate=SR)
    string.note_on(midi_to_hz(57), 0.5)  # A3
    assert fundamental(string.render(SR)[SR // 10 :]) == pytest.approx(220.0, abs=2.0)


def test_one_mass_is_a_damped_oscillator_scanned_as_a_pulse_wave():
    """The smallest string: one mass on springs to two fixed ends rings at ω² = (2·stiffness +
    centring)/mass (symplectic Euler: cos ωh = 1 − h²ω²/2), and the scan, passing the fixed end
    and the mass once per period, is a pulse wave at the scan frequency times the ringing mass:
    a ring modulation, its lowest partial at scan − ringing. On a ring the one mass is its own
    neighbour: its spring pulls on nothing, so only centring rings it."""
    def positions(parameters: StringParameters, frames: int) -> tuple[np.ndarray, np.ndarray]:
        string = ScannedString(parameters, sample_rate=SR, frequency=220.0)
        string.pluck(position=0.0, width=0.5, amplitude=1.0)  # the one mass, displaced 1
        per_step = SR // int(parameters.haptic_rate)
        blocks = [(string.render_raw(np.empty(per_step)), string.x[0]) for _ in range(frames)]
        return np.array([x for _, x in blocks]), np.concatenate([audio for audio, _ in blocks])

    def ringing_hz(x: np.ndarray, rate: float) -> float:
        ups = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
        return (len(ups) - 1) / ((ups[-1] - ups[0]) / rate)

    fixed = StringParameters(n_masses=1, stiffness=800.0, centring=4.0, damping=0.0, haptic_rate=1000.0,
                             interpolation="none")
    x, audio = positions(fixed, 4000)
    h = 1.0 / fixed.haptic_rate
    expected = math.acos(1.0 - h * h * (2 * fixed.stiffness + fixed.centring) / 2.0) / h / (2 * math.pi)
    assert ringing_hz(x, fixed.haptic_rate) == pytest.approx(expected, rel=0.01)
    assert np.abs(x).max() == pytest.approx(1.0, abs=0.05)  # undamped: neither grows nor decays
    assert fundamental(audio[SR // 10:], low=100.0) == pytest.approx(220.0 - expected, abs=1.0)
    ring = dataclasses.replace(fixed, ring=True)
    x_ring, _ = positions(ring, 8000)
    x_slack, _ = positions(dataclasses.replace(ring, stiffness=0.0), 8000)
    np.testing.assert_array_equal(x_ring, x_slack)  # no spring to pull on
    centring_hz = math.acos(1.0 - h * h * ring.centring / 2.0) / h / (2 * math.pi)
    assert ringing_hz(x_ring, ring.haptic_rate) == pytest.approx(centring_hz, rel=0.02)


@pytest.mark.parametrize("masses", [1, 2, 3, 4, 12])
def test_a_note_sounds_on_a_string_of_any_mass_count_the_config_takes(masses):
    """note_on plucks 0.2 wide at 0.3: on 1–3 masses no mass lay under that bump, so the string
    stayed at rest and the note was silence. A bump at least two spacings wide moves one."""
    string = ScannedString(StringParameters(n_masses=masses), sample_rate=SR)
    string.note_on(220.0, 0.5)
    assert np.abs(string.x).max() >= 0.15  # the nearest mass carries a good part of the pluck
    assert np.sqrt(np.mean(string.render(SR // 4) ** 2)) > 0.01


def test_a_bump_wider_than_two_spacings_is_as_asked():
    string = ScannedString(StringParameters(n_masses=64), sample_rate=SR)
    u = np.linspace(0.0, 1.0, 64)
    d = np.abs(u - 0.3)
    np.testing.assert_array_equal(string._bump(0.3, 0.2), np.where(d < 0.1, 0.5 * (1 + np.cos(2 * np.pi * d / 0.2)), 0.0))


@pytest.mark.parametrize("damping", [0.5, 2.0])
def test_energy_decays_and_faster_with_more_damping(damping):
    def energies(d):
        string = ScannedString(StringParameters(damping=d), sample_rate=SR, frequency=220.0)
        string.pluck(amplitude=0.5)
        start = string.energy()
        string.render(SR)
        audio = string.render(SR // 4)
        return start, string.energy(), np.sqrt(np.mean(audio**2))

    start, after, rms = energies(damping)
    assert after < 0.7 * start
    _, after_more, rms_more = energies(2 * damping)
    assert after_more < after and rms_more < rms


def test_damping_past_critical_holds_the_shape_and_the_note_rings_longer():
    """[creature.voice] damping's description: a note ends soonest near the string's critical
    damping 2·√(mass·(centring + stiffness·π²/(masses + 1)²)); past it the string creeps and the
    scan reads a shape that holds (the docs said only "how fast a string rings down", and an
    artist asking damping 50 for a short note got one that rang on)."""
    def falls(damping: float) -> float:
        string = ScannedString(StringParameters(n_masses=64, damping=damping), sample_rate=8000)
        string.note_on(220.0, 0.5)
        string.render(4000)
        early = np.sqrt(np.mean(string.render(400) ** 2))  # at 0.5 s
        string.render(3600)
        return 1.0 - np.sqrt(np.mean(string.render(400) ** 2)) / early  # at 1 s

    critical = 2.0 * math.sqrt(4.0 + 800.0 * math.pi ** 2 / 65 ** 2)
    assert critical == pytest.approx(4.8, abs=0.05)
    assert falls(5.0) == pytest.approx(0.65, abs=0.05)
    assert falls(50.0) == pytest.approx(0.20, abs=0.05) and falls(500.0) == pytest.approx(0.06, abs=0.03)


def test_stiffer_string_struck_by_a_hammer_sounds_darker():
    """A strike gives mode n displacement v_n / ω_n; stiffness raises high-mode ω_n most,
    so the stiffer string's shape is smoother and its spectral centroid *falls*."""

    def struck_centroid(stiffness):
        string = ScannedString(StringParameters(stiffness=stiffness), sample_rate=SR, frequency=110.0)
        string.strike(position=0.3, width=0.05, velocity=5.0)
        return centroid(string.render(SR))

    soft, stiff = struck_centroid(100.0), struck_centroid(3000.0)
    assert stiff < 0.8 * soft


@pytest.mark.parametrize(
    "changes, words",
    [
        ({"stiffness": 1e6}, "use stiffness <"),
        ({"damping": 2000.0}, "damping/mass × step"),
        ({"mass": 0.0}, "mass must be a positive"),
        ({"centring": float("nan")}, "centring must be"),
        ({"n_masses": 0}, "at least 1 mass"),
    ],
)
def test_unstable_parameters_are_rejected_with_a_clear_error(changes, words):
    with pytest.raises(UnstableStringError, match=words):
        StringParameters(**changes)


def test_stability_bound_is_the_real_one():
    """Just inside the documented bound the fastest mode neither grows nor decays (undamped);
    just outside it the parameters are refused."""
    p = StringParameters(damping=0.0, centring=0.0, haptic_rate=500.0, stiffness=0.999 * 500.0**2)
    string = ScannedString(p, sample_rate=SR)
    string.x[:] = (-1.0) ** np.arange(p.n_masses)  # the highest (zig-zag) mode
    early = max(np.abs(string.render_raw(np.empty(SR // 10))).max() for _ in range(2))
    string.render_raw(np.empty(5 * SR))
    late = max(np.abs(string.render_raw(np.empty(SR // 10))).max() for _ in range(2))
    assert late == pytest.approx(early, rel=0.2)
    with pytest.raises(UnstableStringError):
        StringParameters(damping=0.0, centring=0.0, haptic_rate=500.0, stiffness=1.001 * 500.0**2)


def test_config_keeps_strings_gestural_and_the_haptic_rate_in_its_band():
    with pytest.raises(ValidationError, match=r"stiffness 3000 .* highest mode at 17\.4 Hz.* use stiffness ≤ 2219"):
        VoiceSpec(stiffness=3000.0)
    assert VoiceSpec(stiffness=2219.0).parameters().highest_mode_hz <= GESTURAL_LIMIT_HZ  # the advice holds
    with pytest.raises(ValidationError, match=r"use centring ≤ 8882 and stiffness 0"):
        VoiceSpec(centring=1e4)
    for rate in (99.0, 1001.0):
        with pytest.raises(ValidationError, match="haptic_rate"):
            VoiceSpec(haptic_rate=rate)
    with pytest.raises(ValidationError, match="unstable string"):  # stability is checked first
        VoiceSpec(stiffness=1e9)


@st.composite
def accepted_voices(draw: st.DrawFn) -> VoiceSpec:
    """A ``[creature.voice]`` the config accepts, each constant drawn across its whole range:
    haptic rate 100–1000 Hz, masses 1–1024, mass over twelve decades (the config bounds it
    to 0 < mass ≤ 1e6), centring and stiffness up to the gestural limit, damping up to the
    integrator's bound ``h²(4k + c)/m < 4 − 2·damping·h/m`` (audio/scanned.py)."""
    mass = draw(st.floats(1e-6, 1e6))
    haptic_rate = draw(st.floats(100.0, 1000.0))
    centring = draw(st.floats(0.0, 0.999)) * (2.0 * math.pi * GESTURAL_LIMIT_HZ) ** 2 * mass
    rest = StringParameters(mass=mass, centring=centring, stiffness=0.0, damping=0.0, haptic_rate=haptic_rate)
    stiffness = draw(st.floats(0.0, 0.999)) * rest.stiffness_for_highest_mode(GESTURAL_LIMIT_HZ)
    omega_h_squared = (4.0 * stiffness + centring) / mass / haptic_rate**2
    damping = draw(st.floats(0.0, 0.999)) * mass * haptic_rate * (4.0 - omega_h_squared) / 2.0
    return VoiceSpec(masses=draw(st.integers(1, 1024)), mass=mass, stiffness=stiffness, centring=centring,
                     damping=damping, haptic_rate=haptic_rate)


def accepted_string(spec: VoiceSpec, *, ring: bool, frequency: float, gain: float = 1.0) -> ScannedString:
    parameters = dataclasses.replace(spec.parameters(), ring=ring)
    return ScannedString(parameters, sample_rate=SR, frequency=frequency, gain=gain)


@settings(max_examples=40, deadline=None)
@given(spec=accepted_voices(), ring=st.booleans(), frequency=st.floats(0.0, 23999.0),
       position=st.floats(0.0, 1.0), width=st.floats(0.01, 1.0))
def test_every_accepted_string_stays_bounded(spec, ring, frequency, position, width):
    """Plucked to amplitude 1 and left for a second, no string the config accepts grows: the
    scanned shape (before gain and limiter) stays finite and within twice the pluck."""
    string = accepted_string(spec, ring=ring, frequency=frequency)
    string.pluck(position=position, width=width, amplitude=1.0)
    raw = string.render_raw(np.empty(SR))
    assert np.isfinite(raw).all() and string.resets == 0
    assert np.abs(raw).max() <= 2.0
    assert np.abs(string.x).max() <= 2.0


@settings(max_examples=25, deadline=None)
@given(
    spec=accepted_voices(),
    amplitude=st.floats(-1e150, 1e150),
    force=st.floats(-1e300, 1e300),
    frequency=st.floats(0.0, 23999.0),
    ring=st.booleans(),
)
def test_output_is_finite_and_limited_for_extreme_inputs(spec, amplitude, force, frequency, ring):
    string = accepted_string(spec, ring=ring, frequency=frequency, gain=1e6)
    string.pluck(amplitude=amplitude)
    string.push(np.full(spec.masses, force))
    audio = string.render(4096)
    assert np.isfinite(audio).all()
    assert np.abs(audio).max() <= 1.0


def test_voice_pool_steals_the_oldest_voice_and_releases():
    pool = VoicePool(2, sample_rate=SR, release=0.01, block_size=512)
    first, second = pool.note_on(60), pool.note_on(64)
    assert first != second and pool.active == 2
    assert pool.note_on(67) == first  # full: the oldest (60) is stolen
    assert sorted(pool.pitch[: pool.n_voices]) == [64, 67]  # 60 fades out aside
    out = np.empty(512)
    assert np.abs(pool.render(out)).max() > 0
    for index in (first, second):
        pool.release(index, pool.started[index])
    for _ in range(2):  # 0.01 s release = 480 samples
        pool.render(out)
    assert pool.active == 0
    assert not pool.render(out).any()


def test_a_full_pool_steals_a_fading_voice_before_a_sounding_one():
    """A stolen voice's note is cut short (faded out in 5 ms), so the one nearest silence is
    taken: a note already fading (the quietest of them), not the oldest still sounding in full."""
    pool = VoicePool(3, sample_rate=SR, release=0.5, block_size=512)
    held, ending, later = pool.note_on(48), pool.note_on(60), pool.note_on(64)
    pool.release(ending, pool.started[ending])
    pool.render(np.empty(512))
    assert pool.note_on(67) == ending and pool.pitch[held] == 48  # the held 48, the oldest, sounds on
    pool.release(held, pool.started[held])
    pool.render(np.empty(512))
    pool.release(later, pool.started[later])
    pool.render(np.empty(512))
    assert pool.note_on(72) == held  # released first, so the quieter of the two fading


def test_a_sounding_voice_stolen_fades_out_instead_of_clicking():
    """A full pool of sounding notes steals the oldest: its string became the new note's at
    once, and the output stepped from the old note's last sample to the new one's first (a
    step of 0.05–0.09 at five moments, larger than any step of the music around it, 0.065).
    The stolen note now fades out over STEAL_FADE on a string kept aside."""
    steps, amplitude = [], []
    for blocks in (20, 37, 53, 71, 90):
        pool = VoicePool(2, sample_rate=48000, release=0.2, block_size=256)
        pool.note_on(48)
        pool.note_on(55)
        out = np.empty(256)
        for _ in range(blocks):
            pool.render(out)
        last = out[-1]
        amplitude.append(np.abs(out).max())
        assert pool.note_on(67) == 0 and pool.active == 2  # the oldest taken; the one aside is no voice
        pool.render(out)
        steps.append(abs(out[0] - last))
    assert min(amplitude) > 0.1  # loud enough for a cut to click
    assert np.mean(steps) < 0.01 and max(steps) < 0.03
    pool.render(out)
    assert pool.pitch[-1] == -1  # 5 ms later the stolen note is gone from the string aside


@pytest.mark.parametrize("second_end", [3.0, 0.8])
def test_a_note_ends_at_its_own_end_not_at_another_of_its_pitch(second_end):
    """Two notes of one pitch overlapping (0–1 s and 0.5 s–``second_end``): each voice is
    released at its own note's end. The first's end released every voice of the pitch, so
    the second, due to 3 s, fell silent at 1 s (or the first was cut at 0.8 s by the second's)."""
    sr, block = 8000, 400
    voice = Voice(VoiceSpec(damping=0.0, release=0.05), sr, block_size=block)
    voice.play(60, 100, end=1.0)
    voice.play(60, 100, end=second_end, start=0.5)
    heard = []
    for k in range(1, 31):  # 0.05 s blocks up to 1.5 s
        out = np.zeros(block)
        voice.render(out, k * block / sr)
        heard.append(np.sqrt(np.mean(out**2)))
    assert heard[18] > 0.01  # 0.9 s: the first note, to its end
    assert heard[26] > 0.01 if second_end > 1.0 else heard[26] == 0.0  # 1.3 s: the longer note alone
    assert voice.pool.active == (1 if second_end > 1.0 else 0)


@pytest.mark.parametrize("haptic_rate", [250.0, 1000.0])
def test_fastest_mode_is_gestural_and_independent_of_the_haptic_rate(haptic_rate):
    """The default string's fastest mode rings at ``highest_mode_hz`` (< 15 Hz, thesis figure 47),
    whatever the physics rate: time comes from the step size, not from counting steps."""
    p = StringParameters(damping=0.0, haptic_rate=haptic_rate)
    assert p.highest_mode_hz < GESTURAL_LIMIT_HZ
    string = ScannedString(p, sample_rate=SR)
    string.x[:] = 1e-3 * (-1.0) ** np.arange(p.n_masses)  # the zig-zag: fastest mode
    block = np.empty(SR // 1000)
    middle = np.empty(2000)  # the middle mass, once per millisecond for 2 s
    for i in range(len(middle)):
        string.render_raw(block)
        middle[i] = string.x[p.n_masses // 2]
    crossings = np.count_nonzero(np.diff(np.signbit(middle)))
    assert crossings / 2 / 2.0 == pytest.approx(p.highest_mode_hz, rel=0.03)


@pytest.mark.parametrize("tension,damping", [(0.0, 0.0), (0.5, 2.0), (3.0, 1.0), (1e6, 1e6), (-1.0, -1.0)])
def test_retuned_strings_stay_gestural_and_stable(tension, damping):
    """A hand on the string (a skill's voice.tension and voice.damping) never takes it past what
    a config may ask for: every retuned parameter set passes the stability check it would fail
    otherwise, and no mode rises above the gestural limit."""
    from audio.scanned import GESTURAL_LIMIT_HZ, StringParameters

    base = StringParameters(n_masses=64, stiffness=800.0, centring=4.0, damping=0.5, haptic_rate=500.0)
    tuned = base.retuned(tension, damping)
    StringParameters(**{**tuned.__dict__})  # the check a config's string passes
    assert tuned.highest_mode_hz <= GESTURAL_LIMIT_HZ + 1e-9
    assert 0.0 <= tuned.stiffness and 0.0 <= tuned.damping
    if 0.0 <= tension <= 1.0 and 0.0 <= damping <= 2.0:
        assert tuned.stiffness == pytest.approx(800.0 * tension) and tuned.damping == pytest.approx(0.5 * damping)
