"""creature-music: autonomous musical creatures for interactive installations.

The package follows Downie (2001), *Behavior, Animation, Music*: creatures are built from
action-tuples (Trigger | Action | Do-until | Value), percepts and state objects
(:mod:`creatures.behaviour`), a note-space motor graph (:mod:`creatures.motor`) and a
rendered body (:mod:`creatures.body`). Audio and MIDI input/output live in the sibling
top-level packages :mod:`audio` and :mod:`midi`.
"""

__version__ = "0.1.0"
