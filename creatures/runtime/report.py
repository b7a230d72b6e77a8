"""``DIR/report``: plots of a run drawn from its events log alone, plus a small HTML page.

Reading only ``events.jsonl`` keeps the report honest (it shows what was logged, not what the
code meant to do) and lets the inspector reuse it. Each plot is drawn only when its events
exist: notes (a piano roll per creature), action selections, action values, motivations,
percept counts (whatever each kind counts: notes in space, models, members of each percept),
the motor path, and each motor graph with the path walked over it. The inspector
(``creatures inspect``) draws with the same functions.
"""

from __future__ import annotations

import html
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from creatures.events import read_events  # noqa: E402


def _series(events: list[dict], kind: str, key: str) -> dict[str, dict[str, list[tuple[float, float]]]]:
    """creature → name → [(t, value)] from events of ``kind`` carrying a dict under ``key``."""
    out: dict[str, dict[str, list[tuple[float, float]]]] = defaultdict(lambda: defaultdict(list))
    for e in events:
        if e["kind"] == kind and isinstance(e.get(key), dict):
            for name, value in e[key].items():
                if isinstance(value, (int, float)):
                    out[e.get("creature", "")][name].append((e["t"], float(value)))
    return out


MAX_PANELS = 12
"""Most creatures a report's plot draws one by one (a panel, a legend entry, rows of
selections): a REACT crowd of 300 singers drew 300 panels a plot, a figure 780 inches tall,
and its report took 302 of a 364 s offline run; the plot says how many it leaves out."""


def _some(names: "Iterable[str]") -> tuple[list[str], str]:
    """The creatures a plot draws one by one (the first :data:`MAX_PANELS`, by name) and what
    its title adds when there were more."""
    every = sorted(names)
    kept = every[:MAX_PANELS]
    return kept, "" if len(every) == len(kept) else f" ({len(kept)} of {len(every)} creatures shown)"


def saved(fig: Figure, path: Path) -> Path:
    """Lay ``fig`` out, write it to ``path`` (PNG) and let it go. A write that fails (a full
    disk) is an :class:`OSError` naming the file: from inside matplotlib it named none, and a
    run's last line said only "No space left on device"."""
    fig.tight_layout()
    try:
        fig.savefig(path, dpi=90)
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from None
    finally:
        plt.close(fig)
    return path


def _plot_series(series: dict, title: str, ylabel: str, path: Path) -> Path | None:
    if not series:
        return None
    shown, left = _some(series)
    fig, axes = plt.subplots(len(shown), 1, figsize=(9, 2.6 * len(shown)), squeeze=False, sharex=True)
    for ax, creature in zip(axes[:, 0], shown):
        for name, points in sorted(series[creature].items()):
            ts, vs = zip(*points)
            ax.plot(ts, vs, label=name, linewidth=1)
        ax.set_title(f"{creature}: {title}" + (left if ax is axes[0, 0] else ""), fontsize=9)
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=6, loc="upper left", ncol=4)
    axes[-1, 0].set_xlabel("time (s)")
    return saved(fig, path)


def _plot_notes(events: list[dict], path: Path) -> Path | None:
    played = [e for e in events if e["kind"] in ("note", "heard")]
    if not played:
        return None
    by: dict[str, list[dict]] = defaultdict(list)
    for e in played:
        by[e.get("creature") or e.get("source", "")].append(e)
    shown, left = _some(by)
    fig, ax = plt.subplots(figsize=(9, 3.2))
    others = [e for name in sorted(set(by) - set(shown)) for e in by[name]]
    for i, (name, mine, colour) in enumerate([*((n, by[n], None) for n in shown), ("the others", others, "0.6")]):
        if not mine:
            continue
        colour = colour or f"C{i}"
        ax.hlines([e["pitch"] for e in mine], [e["time"] for e in mine],
                  [e["time"] + max(e["duration"], 0.02) for e in mine], color=colour, linewidth=3)
        ax.scatter([e["time"] for e in mine], [e["pitch"] for e in mine], s=8, color=colour, label=name)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("MIDI pitch")
    ax.set_title("notes heard and played" + (f" ({len(shown)} of {len(by)} in colour, the others in grey)"
                                             if left else ""), fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    return saved(fig, path)


def _plot_selections(events: list[dict], path: Path) -> Path | None:
    chosen = [e for e in events if e["kind"] == "selection"]
    if not chosen:
        return None
    shown, left = _some({e.get("creature", "") for e in chosen})
    chosen = [e for e in chosen if e.get("creature", "") in shown]
    rows = sorted({(e.get("creature", ""), e["tuple"]) for e in chosen})
    index = {row: i for i, row in enumerate(rows)}
    fig, ax = plt.subplots(figsize=(9, 1.4 + 0.22 * len(rows)))  # 1.4 in: the title and the time axis, for one row too
    ax.scatter([e["t"] for e in chosen], [index[(e.get("creature", ""), e["tuple"])] for e in chosen], s=6, marker="|")
    ax.set_yticks(range(len(rows)), [f"{c}: {t}" for c, t in rows], fontsize=6)
    ax.set_xlabel("time (s)")
    ax.set_title("action selections" + left, fontsize=9)
    return saved(fig, path)


PLOTTED = frozenset({"note", "heard", "selection", "values", "motivation", "percepts", "motor", "motor graph"})
"""The kinds of event :func:`event_plots` draws from: a reader keeps these and counts the rest
(a run's log is mostly ``pose`` events, 85 % of the bytes of a 10-minute exchange run)."""


def event_plots(events: list[dict], out: Path) -> list[tuple[str, Path]]:
    """Every plot the events support, drawn into ``out``: (title, PNG) pairs, in page order."""
    plots = [
        ("Notes", _plot_notes(events, out / "notes.png")),
        ("Action selections", _plot_selections(events, out / "selections.png")),
        ("Action values", _plot_series(_series(events, "values", "values"), "action values", "V", out / "values.png")),
        ("Motivations", _plot_series(_series(events, "motivation", "drives"), "motivations", "level", out / "motivations.png")),
        ("Percept counts", _plot_series(_series(events, "percepts", "sizes"), "what it perceives and holds, counted",
                                        "count", out / "percepts.png")),
        ("Motor path", _plot_series(_series(events, "motor", "position"), "end-effector position", "m", out / "motor.png")),
        ("Motor graph", plot_motor_graph(events, out / "motor_graph.png")),
    ]
    return [(name, path) for name, path in plots if path is not None]


@dataclass
class MotorWalk:
    """One body's motor graph and its way through it, as logged by
    :class:`~creatures.kinds.report_parts.MotorTrail`."""

    hands: np.ndarray  # (N, 3): where the effector is at each node's pose
    edges: set[tuple[int, int]]  # undirected node pairs
    path: list[int] = field(default_factory=list)  # nodes in the order reached

    def steps(self) -> dict[tuple[int, int], int]:
        """Graph edges walked (undirected), with how often."""
        walked: dict[tuple[int, int], int] = defaultdict(int)
        for a, b in zip(self.path, self.path[1:]):
            if (min(a, b), max(a, b)) in self.edges:
                walked[(min(a, b), max(a, b))] += 1
        return walked

    def jumps(self) -> int:
        """Consecutive nodes of the path that no edge joins (a restart: another run in the same log)."""
        return sum((min(a, b), max(a, b)) not in self.edges for a, b in zip(self.path, self.path[1:]))


def motor_walks(events: list[dict]) -> dict[str, MotorWalk]:
    """creature → its graph (the latest ``motor graph`` event) and the nodes its ``motor``
    events say it reached after it (thesis "graph-based motor systems")."""
    walks: dict[str, MotorWalk] = {}
    for e in events:
        creature = e.get("creature", "")
        if e["kind"] == "motor graph":
            walks[creature] = MotorWalk(np.asarray(e["hands"], dtype=float).reshape(-1, 3),
                                        {(min(a, b), max(a, b)) for a, b in e["edges"]})
        elif e["kind"] == "motor" and creature in walks and isinstance(e.get("reached"), list):
            walks[creature].path.extend(n for n in e["reached"] if isinstance(n, int))
    return walks


def plot_motor_graph(events: list[dict], path: Path) -> Path | None:
    """Each body's whole motor graph seen from the front (every node at its pose's hand
    position, hand x across and height up; every edge in grey) and the path it walked over
    it (edges walked in colour, thicker when walked more often; nodes visited, the first
    and the last marked)."""
    walks = {c: w for c, w in motor_walks(events).items() if len(w.hands)}
    if not walks:
        return None
    shown, left = _some(walks)
    fig, axes = plt.subplots(1, len(shown), figsize=(4.4 * len(shown), 4.4), squeeze=False)
    for ax, creature in zip(axes[0], shown):
        walk = walks[creature]
        front = walk.hands[:, :2]
        ax.add_collection(LineCollection([front[[a, b]] for a, b in sorted(walk.edges)], colors="0.82",
                                         linewidths=0.4, zorder=1))
        ax.scatter(*front.T, s=5, color="0.6", zorder=2)
        steps = walk.steps()
        if steps:
            ax.add_collection(LineCollection([front[[a, b]] for a, b in steps], colors="C1", alpha=0.8, zorder=3,
                                             linewidths=[0.8 + n ** 0.5 for n in steps.values()]))
        visited = sorted(set(walk.path))
        ax.scatter(*front[visited].T, s=14, color="C0", zorder=4)
        if walk.path:
            ax.scatter(*front[walk.path[0]], s=60, marker="o", facecolors="none", edgecolors="k", zorder=5,
                       label="first")
            ax.scatter(*front[walk.path[-1]], s=60, marker="s", facecolors="none", edgecolors="k", zorder=5,
                       label="last")
            ax.legend(fontsize=6, loc="lower right")
        jumps = walk.jumps()
        ax.set_title(f"{creature}: {len(walk.hands)} nodes, {len(walk.edges)} edges; walked {len(steps)} edges "
                     f"through {len(visited)} nodes" + (f" ({jumps} restarts)" if jumps else "")
                     + (left if ax is axes[0, 0] else ""), fontsize=8)
        ax.set_xlabel("hand x (m)")
        ax.set_ylabel("hand height (m)")
        ax.autoscale_view()
    return saved(fig, path)


def plot_bars(groups: dict[str, dict[str, float]], title: str, xlabel: str, path: Path,
              *, shade: dict[str, dict[str, float]] | None = None) -> Path | None:
    """One horizontal bar chart per group (e.g. a creature's action values or drive levels);
    ``shade`` in [0, 1] per bar (e.g. confidence) sets its opacity and is written beside it."""
    groups = {g: bars for g, bars in groups.items() if bars}
    if not groups:
        return None
    shown, left = _some(groups)
    height = sum(1.3 + 0.25 * len(groups[g]) for g in shown)
    fig, axes = plt.subplots(len(shown), 1, figsize=(9, height), squeeze=False)
    for ax, group in zip(axes[:, 0], shown):
        bars = groups[group]
        names = sorted(bars)
        alpha = [min(1.0, max(0.15, (shade or {}).get(group, {}).get(n, 1.0))) for n in names]
        for i, (name, a) in enumerate(zip(names, alpha)):
            ax.barh(i, bars[name], color="C0", alpha=a)
            if shade and name in shade.get(group, {}):
                ax.text(bars[name], i, f"  confidence {shade[group][name]:.2f}", va="center", fontsize=6)
        ax.set_yticks(range(len(names)), names, fontsize=7)
        ax.set_title(f"{group}: {title}" + (left if ax is axes[0, 0] else ""), fontsize=9)
        ax.set_xlabel(xlabel)
    return saved(fig, path)


def counts_table(counts: Counter[str]) -> str:
    """An HTML table of how many events of each kind were logged."""
    rows = "".join(f"<tr><td>{html.escape(k)}</td><td>{v}</td></tr>" for k, v in sorted(counts.items()))
    return f"<table><tr><th>event</th><th>count</th></tr>{rows}</table>"


def html_page(title: str, body: str) -> str:
    """A plain standalone page (the report's and the inspector's)."""
    return (
        f"<!doctype html><meta charset=utf-8><title>{html.escape(title)}</title>"
        "<style>body{font-family:sans-serif;max-width:960px;margin:auto}img{max-width:100%}"
        "td,th{padding:0 1em;text-align:left}</style>"
        f"<h1>{html.escape(title)}</h1>{body}"
    )


def write_report(events_path: Path, out: Path, *, title: str) -> Path:
    """Write PNG plots and ``index.html`` for the run logged at ``events_path``; return ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    counts: Counter[str] = Counter()
    events = read_events(events_path, kinds=PLOTTED, counts=counts)
    plots = event_plots(events, out)
    figures = "".join(
        f'<h2>{html.escape(name)}</h2><img src="{path.name}" alt="{html.escape(name)}">'
        for name, path in plots
    )
    page = html_page(title, f"<p>{counts.total()} events from {html.escape(events_path.name)}</p>"
                            f"{counts_table(counts)}{figures}")
    (out / "index.html").write_text(page, encoding="utf-8")
    return out
