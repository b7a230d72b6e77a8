"""Not listening while singing: half-duplex hearing through StateObject inhibition.

Thesis, "soundcreatures": "we cannot expect that the creature's ear (microphone) will not
pick up the creature's mouth (loudspeaker). This inhibition of hearing while singing is easy
to produce with StateObject's ability to process the saliency of data before passing it on
to the Percepts" (and "state objects": one StateObject inhibiting another). The singing flow
is a :class:`SingingState` whose saliency is the creature's own output level and which holds
for ``release`` seconds after the voice stops, covering the room's echo of the last note.
Half-duplex hearing is then one call, ``hearing.inhibit_by(singing, strength)``, made by
whoever owns both flows (:class:`creatures.kinds.hearing_parts.Ear`)::

    singing = SingingState(release=0.3)
    segmenter.hearing.inhibit_by(singing)
    singing.sing(clock.now()); ...; singing.silence(clock.now())

Why a hold and not a fade: inhibition scales the hearing saliency, which measures dB above
the noise floor; a loud echo 40 dB up still crosses the threshold when the inhibition has
faded only halfway (measured in tests/test_audio_self_hearing.py).
"""

from __future__ import annotations

import numpy as np

from creatures.behaviour.state_object import StateObject


class SingingState(StateObject):
    """The creature's own voice as a data flow: level in [0, 1] while singing, then a release.

    After :meth:`silence`, saliency stays at the last sung level for ``release`` seconds,
    then drops to 0.
    """

    def __init__(
        self, name: str = "singing", *, release: float = 0.25, history: int = 1024
    ) -> None:
        if release < 0:
            raise ValueError(f"release must be >= 0 seconds (got {release})")
        super().__init__(
            name, history=history, saliency_fn=lambda level: min(max(float(level), 0.0), 1.0)
        )
        self.release = float(release)

    def sing(self, t: float, level: float = 1.0) -> None:
        """The voice is sounding at ``level`` (e.g. the output block's peak) from ``t``."""
        self.push(t, level)

    def silence(self, t: float) -> None:
        """The voice stopped at ``t`` (repeats are ignored so the release is not restarted)."""
        if len(self) and self.latest() > 0.0:
            self.push(t, 0.0)

    def saliency_at(self, t: float) -> float:
        times, saliencies = self.times_array, self.saliencies_array
        i = int(np.searchsorted(times, t, side="right")) - 1
        if i < 0:
            return 0.0
        if saliencies[i] > 0.0 or i == 0 or self.release == 0.0:
            return float(saliencies[i])
        # A silence that follows singing: the sung level holds until the release has passed.
        return float(saliencies[i - 1]) if t - times[i] < self.release else 0.0

