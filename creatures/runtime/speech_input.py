"""Generated speech for runs given no recording: Shelley's *Ozymandias*, spoken by formants.

Thesis, "ozymandias (video)": a colony is "driven … with the spoken text of the poem" and
trained "by repeatedly playing the text at them". On a fresh machine there is no recording,
so ``[input] generate = "speech"`` reads the poem aloud with :func:`audio.formants.speak`
(every written word becomes a formant "word" of its vowels), from the start again whenever
it ends, until the run's duration is covered. A real recording is given with ``--audio``.
"""

from __future__ import annotations

import numpy as np

from audio.formants import speak

POEM = """\
I met a traveller from an antique land
Who said Two vast and trunkless legs of stone
Stand in the desert Near them on the sand
Half sunk a shattered visage lies whose frown
And wrinkled lip and sneer of cold command
Tell that its sculptor well those passions read
Which yet survive stamped on these lifeless things
The hand that mocked them and the heart that fed
And on the pedestal these words appear
My name is Ozymandias King of Kings
Look on my works ye Mighty and despair
Nothing beside remains Round the decay
Of that colossal wreck boundless and bare
The lone and level sands stretch far away
"""


def spoken_poem(duration: float, sample_rate: int, rng: np.random.Generator, *,
                start: float = 0.5, lines: int = 4) -> np.ndarray:
    """``duration`` seconds of mono float32: silence until ``start``, then the first
    ``lines`` lines of the poem spoken again and again (a fresh reading each time, so
    repeats are near, not exact, as a reader's would be)."""
    text = "\n".join(POEM.splitlines()[:lines])
    out = np.zeros(int(round(duration * sample_rate)), dtype=np.float32)
    at = int(round(start * sample_rate))
    while at < len(out):
        reading, _ = speak(text, rng, sample_rate)
        n = min(len(reading), len(out) - at)
        out[at : at + n] = reading[:n]
        at += len(reading)
    return out
