"""``DIR/report``: plots of a run drawn from its events log alone, plus a small HTML page.

Reading only ``events.jsonl`` keeps the report honest (it shows what was logged, not what the
code meant to do) and lets the inspector reuse it. Each plot is drawn only when its events
exist: notes (a piano roll per creature), action selections, action values, motivations,
percept-tree sizes and the motor path.
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
        ax.broken_barh([(e["time"], max(e["duration"], 0.02)) for e in mine], (0, 0), color=f"C{i}")
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


def write_report(events_path: Path, out: Path, *, title: str) -> Path:
    """Write PNG plots and ``index.html`` for the run logged at ``events_path``; return ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    events = read_events(events_path)
    plots = [
        ("Notes", _plot_notes(events, out / "notes.png")),
        ("Action selections", _plot_selections(events, out / "selections.png")),
        ("Action values", _plot_series(_series(events, "values", "values"), "action values", "V", out / "values.png")),
        ("Motivations", _plot_series(_series(events, "motivation", "drives"), "motivations", "level", out / "motivations.png")),
        ("Percept trees", _plot_series(_series(events, "percepts", "sizes"), "percept tree sizes", "nodes", out / "percepts.png")),
        ("Motor path", _plot_series(_series(events, "motor", "position"), "end-effector position", "m", out / "motor.png")),
    ]
    counts: dict[str, int] = defaultdict(int)
    for e in events:
        counts[e["kind"]] += 1
    rows = "".join(f"<tr><td>{html.escape(k)}</td><td>{v}</td></tr>" for k, v in sorted(counts.items()))
    figures = "".join(
        f'<h2>{html.escape(name)}</h2><img src="{path.name}" alt="{html.escape(name)}">'
        for name, path in plots if path is not None
    )
    page = (
        f"<!doctype html><meta charset=utf-8><title>{html.escape(title)}</title>"
        "<style>body{font-family:sans-serif;max-width:960px;margin:auto}img{max-width:100%}"
        "td{padding:0 1em}</style>"
        f"<h1>{html.escape(title)}</h1><p>{len(events)} events from {html.escape(events_path.name)}</p>"
        f"<table><tr><th>event</th><th>count</th></tr>{rows}</table>{figures}"
    )
    (out / "index.html").write_text(page, encoding="utf-8")
    return out
