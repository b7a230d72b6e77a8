"""The project's own bodies, generated as BVH files (issue 16: no third-party motion data).

``python -m creatures.body.generate DIR`` writes ``dog.bvh``/``dog.labels.toml`` and
``bird.bvh``/``bird.labels.toml`` and the drawn line creature ``line.svg`` into DIR (the shipped copies are in
``installations/bodies/``; a test regenerates them byte for byte). Generation only writes
files; :mod:`creatures.kinds.figures` reads them back like any user's BVH.
"""

from __future__ import annotations

from pathlib import Path

from creatures.body.generate import bird, dog, line
from creatures.body.generate.rig import write_body

BODIES = {"dog": dog, "bird": bird}
"""Each generator module has ``skeleton()``, ``clips(skeleton)`` and ``ABOUT``."""


def generate(directory: Path) -> list[Path]:
    """Write every generated body into ``directory``; returns the files written."""
    written: list[Path] = []
    for name, module in BODIES.items():
        skeleton = module.skeleton()
        written += write_body(directory, name, skeleton, module.clips(skeleton), module.ABOUT)
    written.append(line.write(directory))  # a drawing, not BVH: read back by creatures.motor.drawing
    return written
