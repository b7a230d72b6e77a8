"""libasound's own error printing, turned off: the reasons reach the user once, in our words.

Without ``/dev/snd/seq`` (a container, a machine with JACK MIDI only) every rtmidi client
makes libasound print ``ALSA lib seq_hw.c:…(snd_seq_hw_open) open /dev/snd/seq failed`` on
stderr, below any Python, before rtmidi raises the error that ``creatures devices`` and a live
run already report with what to do. An installation's log would fill with that line at every
port lookup, so the library's handler is replaced by one that prints nothing (the same
``snd_lib_error_set_handler`` call PortAudio users make).
"""

from __future__ import annotations

import ctypes
import ctypes.util

_HANDLER = ctypes.CFUNCTYPE(None, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p)
_quiet = _HANDLER(lambda file, line, function, err, fmt: None)  # kept: libasound holds the pointer


def quiet() -> bool:
    """Silence libasound's stderr messages for this process; False where there is no libasound."""
    name = ctypes.util.find_library("asound")
    if name is None:
        return False
    try:
        ctypes.cdll.LoadLibrary(name).snd_lib_error_set_handler(_quiet)
    except (OSError, AttributeError):
        return False
    return True
