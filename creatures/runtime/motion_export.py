"""``creatures export-motion``: a run's log and its installation → the BVH of one creature's path.

The events log names the installation it ran (``run`` event, ``config``); loading it again
gives the creature's motor graph (from its cache: no rebuild) and the file conventions its
body was read with, so the exported take loads back through the same ``[creature.body]``.
"""

from __future__ import annotations

from pathlib import Path

from creatures.events import read_events
from creatures.kinds.body_source import MaterialSpec
from creatures.kinds.figures import figure_graph, figure_of
from creatures.motor.export import ExportError, export_motion, taken_nodes
from creatures.motor.material import Conventions
from creatures.runtime.schema import load_installation


def export_motion_of_run(path: Path, creature: str, out: Path, *, config: Path | None = None,
                         fps: float = 30.0) -> int:
    """Write ``creature``'s path in the run at ``path`` (a run's or state directory holding
    ``events.jsonl``, or the events log itself: a live run's ``--log``) to ``out``; returns the
    number of frames written."""
    log = path if path.is_file() else path / "events.jsonl"
    if not log.is_file():
        raise ExportError(f"{path}: no events.jsonl (give a run's output directory, or the events log a live run "
                          "wrote with --log: the path is in the log, not in the learned state)")
    events = read_events(log)
    if config is None:
        named = [e.get("config") for e in events if e.get("kind") == "run" and e.get("config")]
        if not named:
            raise ExportError(f"{log}: the log does not name its installation; give --config")
        config = Path(named[-1])
    installation = load_installation(config)
    spec = next((s for s in installation.specs if s.name == creature), None)
    if spec is None:
        raise ExportError(f"{config}: no creature {creature!r} (creatures: "
                          f"{', '.join(s.name for s in installation.specs)})")
    body = getattr(spec, "body", None)
    if isinstance(body, MaterialSpec) and body.custom:
        graph, conventions = body.material().graph, Conventions(body.scale, body.up_axis, body.root_motion)
    elif body:  # a shipped figure (body = true: the stick figure; figure = "dog", "bird", ...)
        graph, conventions = figure_graph(figure_of(body), bool(getattr(spec, "ratio_metric", False))), Conventions()
    else:
        raise ExportError(f"creature {creature!r} ({spec.kind}) has no body")
    poses = export_motion(graph, taken_nodes(events, creature, len(graph)), out, fps=fps, conventions=conventions)
    return len(poses)
