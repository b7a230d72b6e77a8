"""``creatures export-motion``: a run's log and its installation → the BVH of one creature's path.

The events log names the installation it ran (``run`` event, ``config``); loading it again
gives the creature's motor graph (from its cache: no rebuild) and the file conventions its
body was read with, so the exported take loads back through the same ``[creature.body]``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from creatures.config import nearest
from creatures.events import read_events
from creatures.kinds.body_source import MaterialSpec
from creatures.kinds.figures import figure_graph, figure_of, metric_of
from creatures.kinds.layers import source_limits
from creatures.motor.blend import Limits
from creatures.motor.export import ExportError, export_motion, taken_path
from creatures.motor.graph import MotorGraph
from creatures.motor.material import Conventions
from creatures.paths import open_regular
from creatures.persist import load_json
from creatures.runtime.schema import load_installation
from creatures.runtime.session import STATE_KIND
from creatures.state_set import files


def export_motion_of_run(path: Path, creature: str, out: Path, *, config: Path | None = None,
                         fps: float = 30.0) -> int:
    """Write ``creature``'s path in the run at ``path`` to ``out``; returns the number of frames
    written. ``path`` is a run's output directory (its ``events.jsonl``), the events log itself
    (a live run's ``--log``), or a state folder (each creature's file keeps the path its body
    took in the run that saved it, and the config that ran)."""
    refuse_to_lose(out)
    log = path if path.is_file() else path / "events.jsonl"
    saved = files(path).get(f"{creature}.json", path / f"{creature}.json") if path.is_dir() else path / f"{creature}.json"
    if log.is_file():
        events = read_events(log, kinds=("run", "motor"))  # a path needs no poses, most of a log
        if config is None:
            named = [e.get("config") for e in events if e.get("kind") == "run" and e.get("config")]
            if not named:
                raise ExportError(f"{log}: the log does not name its installation; give --config")
            config = Path(named[-1])
    elif path.is_dir() and saved.is_file():
        motion = load_json(saved, kind=STATE_KIND).get("motion")
        if not isinstance(motion, dict) or not isinstance(motion.get("nodes"), list) or not isinstance(
                motion.get("at"), list):
            raise ExportError(f"{saved}: keeps no motion (a creature without a body, or saved before paths were kept)")
        events = [{"kind": "motor", "creature": creature, "reached": motion["nodes"], "at": motion["at"]}]
        if config is None:
            if not isinstance(motion.get("config"), str):
                raise ExportError(f"{saved}: does not name the installation that ran; give --config")
            config = Path(motion["config"])
    else:
        raise ExportError(f"{path}: no events.jsonl and no state file {creature}.json (give a run's output "
                          "directory, the events log a live run wrote with --log, or its --state folder)")
    installation = load_installation(config)
    spec = next((s for s in installation.specs if s.name == creature), None)
    if spec is None:
        raise ExportError(f"{config}: no creature {creature!r}"
                          f"{nearest(creature, [s.name for s in installation.specs], 'creatures')}")
    graph, conventions, limits = exported_body(spec)
    nodes, times = taken_path(events, creature, len(graph))
    poses = export_motion(graph, nodes, out, fps=fps, conventions=conventions, times=times, limits=limits)
    return len(poses)


BVH_START = b"HIERARCHY"
"""How every BVH file begins: an ``out`` that exists and begins otherwise is not an earlier take."""


def refuse_to_lose(out: Path) -> None:
    """Raise :class:`ExportError` when writing the take to ``out`` would lose something: a
    folder, or a file that is not a BVH. ``OUT`` is the second path on the command line, and
    one word swapped (the run's ``events.jsonl`` or a creature's state file given as ``OUT``)
    replaced the log or the learned state with a take, with nothing said."""
    if out.is_dir():
        raise ExportError(f"{out}: is a folder; give the BVH file to write (e.g. {out / 'motion.bvh'})")
    try:
        with open_regular(out, "OUT") as handle:  # a FIFO or a device: refused, never opened blocking
            start = handle.read(len(BVH_START))
    except FileNotFoundError:
        return
    except OSError as exc:
        raise ExportError(f"{out}: cannot tell what it holds ({exc.strerror or exc}); not replaced") from None
    if start != BVH_START:
        raise ExportError(f"{out}: exists and is not a BVH file (it would be lost); give another file to write")


def exported_body(spec: object) -> tuple[MotorGraph, Conventions, Limits | None]:
    """A creature's motor graph, the file conventions its body was read with, and the limits its
    layers held every shown frame within (None: the stick figure, shown as its course plays)."""
    body = getattr(spec, "body", None)
    if isinstance(body, MaterialSpec) and body.custom:
        material = body.material()
        own = source_limits(material.graph)
        return (material.graph, Conventions(body.scale, body.up_axis, body.root_motion),
                Limits(np.minimum(own.range, material.limits), own.max_speed))
    if body:  # a shipped figure (body = true: the stick figure; figure = "dog", "bird", ...)
        figure = figure_of(body)
        graph = figure_graph(figure, bool(getattr(spec, "ratio_metric", False)), metric_of(body))
        return graph, Conventions(), source_limits(graph) if figure != "stick" else None
    raise ExportError(f"creature {getattr(spec, 'name', '?')!r} ({getattr(spec, 'kind', '?')}) has no body")
