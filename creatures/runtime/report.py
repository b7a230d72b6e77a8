"""``DIR/report``: plots of a run drawn from its events log alone, plus a small HTML page.

Reading only ``events.jsonl`` keeps the report honest (it shows what was logged, not what the
code meant to do) and lets the inspector reuse it. Each plot is drawn only when its events
exist: notes (a piano roll per creature), action selections, action values, motivations,
percept-tree sizes, the motor path and the part of the motor graph walked. The inspector
(``creatures inspect``) draws with the same functions.
"""

from __future__ import annotations

import html
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

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


def _plot_series(series: dict, title: str, ylabel: str, path: Path) -> Path | None:
    if not series:
        return None
    fig, axes = plt.subplots(len(series), 1, figsize=(9, 2.6 * len(series)), squeeze=False, sharex=True)
    for ax, (creature, lines) in zip(axes[:, 0], sorted(series.items())):
        for name, points in sorted(lines.items()):
            ts, vs = zip(*points)
            ax.plot(ts, vs, label=name, linewidth=1)
        ax.set_title(f"{creature}: {title}", fontsize=9)
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=6, loc="upper left", ncol=4)
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _plot_notes(events: list[dict], path: Path) -> Path | None:
    played = [e for e in events if e["kind"] in ("note", "heard")]
    if not played:
        return None
    who = sorted({e.get("creature") or e.get("source", "") for e in played})
    fig, ax = plt.subplots(figsize=(9, 3.2))
    for i, name in enumerate(who):
        mine = [e for e in played if (e.get("creature") or e.get("source")) == name]
        ax.hlines([e["pitch"] for e in mine], [e["time"] for e in mine],
                  [e["time"] + max(e["duration"], 0.02) for e in mine], color=f"C{i}", linewidth=3)
        ax.scatter([e["time"] for e in mine], [e["pitch"] for e in mine], s=8, color=f"C{i}", label=name)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("MIDI pitch")
    ax.set_title("notes heard and played", fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _plot_selections(events: list[dict], path: Path) -> Path | None:
    chosen = [e for e in events if e["kind"] == "selection"]
    if not chosen:
        return None
    rows = sorted({(e.get("creature", ""), e["tuple"]) for e in chosen})
    index = {row: i for i, row in enumerate(rows)}
    fig, ax = plt.subplots(figsize=(9, 0.6 + 0.22 * len(rows)))
    ax.scatter([e["t"] for e in chosen], [index[(e.get("creature", ""), e["tuple"])] for e in chosen], s=6, marker="|")
    ax.set_yticks(range(len(rows)), [f"{c}: {t}" for c, t in rows], fontsize=6)
    ax.set_xlabel("time (s)")
    ax.set_title("action selections", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def event_plots(events: list[dict], out: Path) -> list[tuple[str, Path]]:
    """Every plot the events support, drawn into ``out``: (title, PNG) pairs, in page order."""
    plots = [
        ("Notes", _plot_notes(events, out / "notes.png")),
        ("Action selections", _plot_selections(events, out / "selections.png")),
        ("Action values", _plot_series(_series(events, "values", "values"), "action values", "V", out / "values.png")),
        ("Motivations", _plot_series(_series(events, "motivation", "drives"), "motivations", "level", out / "motivations.png")),
        ("Percept trees", _plot_series(_series(events, "percepts", "sizes"), "percept tree sizes", "nodes", out / "percepts.png")),
        ("Motor path", _plot_series(_series(events, "motor", "position"), "end-effector position", "m", out / "motor.png")),
        ("Motor graph", plot_motor_graph(events, out / "motor_graph.png")),
    ]
    return [(name, path) for name, path in plots if path is not None]


def motor_walks(events: list[dict]) -> dict[str, tuple[list[int], dict[int, tuple[float, float]]]]:
    """creature → (graph nodes in the order visited, node → mean hand (x, z) there), from
    ``motor`` events (thesis "graph-based motor systems": the body's path through its graph)."""
    walks: dict[str, list[int]] = defaultdict(list)
    where: dict[str, dict[int, list[tuple[float, float]]]] = defaultdict(lambda: defaultdict(list))
    for e in events:
        if e["kind"] != "motor" or not isinstance(e.get("node"), int):
            continue
        creature, node = e.get("creature", ""), e["node"]
        if not walks[creature] or walks[creature][-1] != node:
            walks[creature].append(node)
        position = e.get("position")
        if isinstance(position, dict) and all(isinstance(position.get(k), (int, float)) for k in "xz"):
            where[creature][node].append((position["x"], position["z"]))
    layout = {c: {n: (sum(x for x, _ in ps) / len(ps), sum(z for _, z in ps) / len(ps)) for n, ps in nodes.items()}
              for c, nodes in where.items()}
    return {c: (walk, layout.get(c, {})) for c, walk in walks.items()}


def plot_motor_graph(events: list[dict], path: Path) -> Path | None:
    """The part of each creature's motor graph it visited: nodes at the hand's mean place
    there (x–z plane), an edge per transition walked (thicker when walked more often)."""
    walks = {c: w for c, w in motor_walks(events).items() if len(w[0]) > 1 and w[1]}
    if not walks:
        return None
    fig, axes = plt.subplots(1, len(walks), figsize=(4.2 * len(walks), 4), squeeze=False)
    for ax, (creature, (walk, layout)) in zip(axes[0], sorted(walks.items())):
        counts: dict[tuple[int, int], int] = defaultdict(int)
        for a, b in zip(walk, walk[1:]):
            if a in layout and b in layout:
                counts[(min(a, b), max(a, b))] += 1
        for (a, b), n in counts.items():
            ax.plot(*zip(layout[a], layout[b]), color="0.5", linewidth=0.5 + n ** 0.5, alpha=0.6)
        xs, zs = zip(*layout.values())
        ax.scatter(xs, zs, s=12, color="C0", zorder=3)
        ax.set_title(f"{creature}: {len(layout)} nodes, {len(counts)} edges walked", fontsize=9)
        ax.set_xlabel("hand x (m)")
        ax.set_ylabel("hand z (m)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def plot_bars(groups: dict[str, dict[str, float]], title: str, xlabel: str, path: Path,
              *, shade: dict[str, dict[str, float]] | None = None) -> Path | None:
    """One horizontal bar chart per group (e.g. a creature's action values or drive levels);
    ``shade`` in [0, 1] per bar (e.g. confidence) sets its opacity and is written beside it."""
    groups = {g: bars for g, bars in groups.items() if bars}
    if not groups:
        return None
    height = sum(1.3 + 0.25 * len(bars) for bars in groups.values())
    fig, axes = plt.subplots(len(groups), 1, figsize=(9, height), squeeze=False)
    for ax, (group, bars) in zip(axes[:, 0], sorted(groups.items())):
        names = sorted(bars)
        alpha = [min(1.0, max(0.15, (shade or {}).get(group, {}).get(n, 1.0))) for n in names]
        for i, (name, a) in enumerate(zip(names, alpha)):
            ax.barh(i, bars[name], color="C0", alpha=a)
            if shade and name in shade.get(group, {}):
                ax.text(bars[name], i, f"  confidence {shade[group][name]:.2f}", va="center", fontsize=6)
        ax.set_yticks(range(len(names)), names, fontsize=7)
        ax.set_title(f"{group}: {title}", fontsize=9)
        ax.set_xlabel(xlabel)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def counts_table(events: list[dict]) -> str:
    """An HTML table of how many events of each kind were logged."""
    counts: dict[str, int] = defaultdict(int)
    for e in events:
        counts[e["kind"]] += 1
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
    events = read_events(events_path)
    plots = event_plots(events, out)
    figures = "".join(
        f'<h2>{html.escape(name)}</h2><img src="{path.name}" alt="{html.escape(name)}">'
        for name, path in plots
    )
    page = html_page(title, f"<p>{len(events)} events from {html.escape(events_path.name)}</p>"
                            f"{counts_table(events)}{figures}")
    (out / "index.html").write_text(page, encoding="utf-8")
    return out
