"""``creatures inspect PATH``: what the creatures learned, as plots and one HTML page.

An artist whose installation has run for weeks needs to see inside the creatures without a
debugger (DESIGN.md "Seeing inside"). The inspector reads only what a run leaves behind — an
offline output directory (``events.jsonl``) and/or a state directory (one JSON file per
creature and one for the colony, written by ``Session.save_state``, i.e. ``creatures run
--state``) — and renders:

* action-tuples with their learned values, and expectations (e.g. *listen*'s expected match),
  with confidence where the value kind has one (thesis, "surprise and confidence": a
  :class:`GaussianValue`'s reliability, faded by time untested);
* each action-tuple's expectation: its confidence as saved (the reliability of its
  expectation, thesis "expectations about value"), how often it was tested and violated;
* percept trees with the size of every node (thesis, "percept trees");
* duration models: the pulse and the ratio histogram of a low-integer-ratio model (thesis,
  figure 11) — the colony's heard pulse, and any a creature keeps —, the mean of a simple one;
* drive levels and their time series (thesis, "motivation");
* each body's motor graph and the path it walked over it (thesis, "graph-based motor
  systems"), with the run's other plots from :mod:`creatures.runtime.report`.

State files are read generically, without building creatures from code: every kind saves
plain dicts, and the inspector recognises the parts by their ``kind`` tags (value kinds,
``motivation``, duration-model kinds) and tree nodes by their ``children``. The page embeds
every image as a base64 data URI, so it can be mailed or archived as one file.
"""

from __future__ import annotations

import base64
import html
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from creatures.behaviour.expectation import check_saved
from creatures.behaviour.value import value_from_dict
from creatures.events import read_events
from creatures.persist import StateFileError, load_json
from creatures.runtime.outputs import publishing
from creatures.runtime.report import PLOTTED, counts_table, event_plots, html_page, plot_bars, plt, saved
from creatures.runtime.session import COLONY_FILE, COLONY_KIND, STATE_KIND
from creatures.state_set import files
from creatures.temporal.durations import LowIntegerRatioModel, SimpleDurationModel

VALUE_KINDS = ("scalar", "chain", "gaussian", "stance")
DURATION_MODELS = {m.kind: m for m in (LowIntegerRatioModel, SimpleDurationModel)}
PAGE = "index.html"
KNOWN_PLOTS = ("known_values.png", "known_drives.png", "known_trees.png", "known_durations.png")
"""What the page shows from saved state, beside the events' plots (creatures.runtime.report)."""


class InspectError(Exception):
    """PATH holds neither an events log nor creature state; the message says what was looked for."""


@dataclass
class Tree:
    """One percept tree node: its name, how many nodes hang below it (itself included)."""

    name: str
    size: int
    children: list["Tree"] = field(default_factory=list)


@dataclass
class Knowledge:
    """What one creature's saved state says it has learned."""

    creature: str
    kind: str
    values: dict[str, float] = field(default_factory=dict)
    confidence: dict[str, float] = field(default_factory=dict)
    drives: dict[str, float] = field(default_factory=dict)
    trees: list[Tree] = field(default_factory=list)
    durations: list[tuple[str, Any]] = field(default_factory=list)  # (where, rebuilt model)
    expected: dict[str, tuple[float, int, int]] = field(default_factory=dict)  # "group: tuple" → reliability, tests, violated


def _tree(node: dict[str, Any]) -> Tree:
    # a node whose children are not a list (a hand-edited leaf without its "children") is a
    # leaf: it raised KeyError, a traceback for the whole page
    below = node.get("children")
    children = [_tree(c) for c in below if isinstance(c, dict)] if isinstance(below, list) else []
    return Tree(str(node.get("name", "?")), 1 + sum(c.size for c in children), children)


def _is_tree(node: Any) -> bool:
    return isinstance(node, dict) and isinstance(node.get("children"), list)


def knowledge(creature: str, kind: str, state: dict[str, Any]) -> Knowledge:
    """Walk a creature's saved ``state`` and collect what it knows (see the module docstring)."""
    known = Knowledge(creature, kind)

    def visit(node: Any, label: str, path: str) -> None:
        if isinstance(node, list):
            # [trigger, action, name, value] rows name their value by the last string before it.
            names = [x for x in node if isinstance(x, str)]
            for i, child in enumerate(node):
                visit(child, names[-1] if names and isinstance(child, dict) else label, f"{path}[{i}]")
            return
        if not isinstance(node, dict):
            return
        tag = node.get("kind")
        if tag in VALUE_KINDS and "value" in node:
            try:
                value = value_from_dict(node)
            except (KeyError, TypeError, ValueError):
                return
            known.values[label] = value.to_float()
            if hasattr(value, "confidence"):
                known.confidence[label] = float(value.confidence())
            return
        if tag == "motivation" and isinstance(node.get("levels"), dict):
            known.drives.update({k: float(v) for k, v in node["levels"].items() if isinstance(v, (int, float))})
            return
        if tag in DURATION_MODELS:
            try:
                known.durations.append((path, DURATION_MODELS[tag].from_dict(node)))
            except (KeyError, TypeError, ValueError, ArithmeticError):  # e.g. a damaged ratio n/0
                pass
            return
        if _is_tree(node):
            known.trees.append(_tree(node))
            return
        for key, child in node.items():
            name = node.get("name") if key == "value" and isinstance(node.get("name"), str) else str(key)
            visit(child, name, f"{path}.{key}" if path else str(key))

    visit(state, "", "")
    known.expected = _expectations(state.get("expectations"))
    return known


def _expectations(saved: Any) -> dict[str, tuple[float, int, int]]:
    """The saved ``expectations`` section (group → tuple → reliability, tests, violations) as
    rows; an entry not as saved is left out, as a damaged value is."""
    rows = {}
    for group, tuples in (saved.items() if isinstance(saved, dict) else ()):
        for name, entry in (tuples.items() if isinstance(tuples, dict) else ()):
            try:  # the check a restore makes of it (creatures.behaviour.expectation)
                tests, violations = check_saved(entry, f"expectations.{group}.{name}")
            except ValueError:
                continue
            rows[f"{group}: {name}"] = (float(entry["reliability"]), tests, violations)
    return rows


COLONY = "colony"
"""How the inspector names what the creatures learned together (the colony's state file)."""


def read_state(directory: Path, skipped: list[str] | None = None) -> list[Knowledge]:
    """Every creature state file in ``directory``, then the colony's. Files that are not
    state, or are damaged, are skipped, each with why (the error naming it) in ``skipped``."""
    found = []
    skipped = [] if skipped is None else skipped
    state_files = files(directory)  # as the last whole save left them (creatures.state_set)
    for path in state_files.values():
        if path.name == COLONY_FILE:
            continue
        try:
            document = load_json(path, kind=STATE_KIND)
        except StateFileError as exc:
            skipped.append(str(exc))
            continue
        state = document.get("state")
        if isinstance(state, dict):
            found.append(knowledge(path.stem, str(document.get("kind", "?")), state))
    colony = state_files.get(COLONY_FILE, directory / COLONY_FILE)
    try:
        found.append(knowledge(COLONY, "what the creatures hear together", load_json(colony, kind=COLONY_KIND)))
    except StateFileError as exc:  # none (a state directory from before colonies saved one), or unreadable
        if colony.exists():
            skipped.append(str(exc))
    return found


def latest_values(events: list[dict]) -> list[Knowledge]:
    """Without saved state, the last ``values``/``motivation`` each creature logged."""
    known: dict[str, Knowledge] = {}
    for e in events:
        if e["kind"] in ("values", "motivation") and "creature" in e:
            k = known.setdefault(e["creature"], Knowledge(e["creature"], "from the events log"))
            fields = e.get("values" if e["kind"] == "values" else "drives")
            if isinstance(fields, dict):
                target = k.values if e["kind"] == "values" else k.drives
                target.update({n: float(v) for n, v in fields.items() if isinstance(v, (int, float))})
    return list(known.values())


def _plot_durations(known: list[Knowledge], path: Path) -> Path | None:
    models = [(k.creature, where, m) for k in known for where, m in k.durations]
    if not models:
        return None
    fig, axes = plt.subplots(len(models), 1, figsize=(9, 2.4 * len(models)), squeeze=False)
    for ax, (creature, where, model) in zip(axes[:, 0], models):
        if isinstance(model, LowIntegerRatioModel):
            labels = [f"{r.numerator}/{r.denominator}" for r in model.ratios]
            ax.bar(labels, model.ratio_distribution(), color="C2")
            ax.set_ylabel("p(ratio)")
            ax.set_title(f"{creature} · {where}: pulse {model.pulse:.3f} s", fontsize=9)
        else:
            ax.bar(["mean"], [model.pulse], color="C2")
            ax.set_title(f"{creature} · {where}: mean duration {model.pulse:.3f} s", fontsize=9)
    return saved(fig, path)


def _tree_html(tree: Tree) -> str:
    children = "".join(_tree_html(c) for c in tree.children)
    inner = f"<ul>{children}</ul>" if children else ""
    return f"<li>{html.escape(tree.name)} <small>({tree.size} node{'s' if tree.size != 1 else ''})</small>{inner}</li>"


def _duration_html(where: str, model: Any) -> str:
    """One duration model as a table row: its pulse and, for a low-integer-ratio model, the
    ratio histogram (most probable first; the plot shows the ratios under 1 % too)."""
    if isinstance(model, LowIntegerRatioModel):
        p = model.ratio_distribution()
        ratios = ", ".join(f"{model.ratios[i].numerator}/{model.ratios[i].denominator}: {p[i]:.2f}"
                           for i in sorted(range(len(p)), key=lambda i: -p[i]) if p[i] >= 0.01)
        return f"<tr><td>{html.escape(where)}</td><td>pulse {model.pulse:.3f} s</td><td>{ratios}</td></tr>"
    return f"<tr><td>{html.escape(where)}</td><td>mean {model.pulse:.3f} s</td><td></td></tr>"


def _creature_html(k: Knowledge) -> str:
    rows = "".join(
        f"<tr><td>{html.escape(n)}</td><td>{v:.4g}</td>"
        f"<td>{'' if n not in k.confidence else f'{k.confidence[n]:.3f}'}</td></tr>"
        for n, v in sorted(k.values.items()))
    drives = "".join(f"<tr><td>{html.escape(n)}</td><td>{v:.4g}</td></tr>" for n, v in sorted(k.drives.items()))
    parts = [f"<h3>{html.escape(k.creature)} <small>({html.escape(k.kind)})</small></h3>"]
    if rows:
        parts.append(f"<table><tr><th>action-tuple or expectation</th><th>value</th><th>confidence</th></tr>"
                     f"{rows}</table>")
    if k.expected:
        parts.append("<table><tr><th>expectation of</th><th>confidence</th><th>tested</th><th>violated</th></tr>"
                     + "".join(f"<tr><td>{html.escape(n)}</td><td>{r:.3f}</td><td>{t}</td><td>{v}</td></tr>"
                               for n, (r, t, v) in sorted(k.expected.items())) + "</table>")
    if k.durations:
        parts.append("<table><tr><th>duration model</th><th>pulse</th><th>p(ratio)</th></tr>"
                     + "".join(_duration_html(where, m) for where, m in k.durations) + "</table>")
    if drives:
        parts.append(f"<table><tr><th>drive</th><th>level</th></tr>{drives}</table>")
    if k.trees:
        parts.append("<p>percept trees</p><ul>" + "".join(_tree_html(t) for t in k.trees) + "</ul>")
    return "".join(parts)


def _embed(path: Path) -> str:
    return "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def inspect(path: Path, out: Path, skipped: list[str] | None = None) -> Path:
    """Render what the creatures at ``path`` know into ``out`` (PNGs and ``index.html``);
    return the page. ``path`` is an offline output directory, a state directory, or both.
    State files that could not be read are listed in ``skipped`` (and on the page)."""
    path = Path(path)
    skipped = [] if skipped is None else skipped
    events_path = path / "events.jsonl"
    # exists(), not is_file(): an events.jsonl that is a FIFO or a device is refused by
    # read_events, not skipped in silence
    counts: Counter[str] = Counter()
    events = read_events(events_path, kinds=PLOTTED, counts=counts) if events_path.exists() else []
    saved = path / "state" if (path / "state").is_dir() else path  # an offline run saves into DIR/state
    known = read_state(saved, skipped) if saved.is_dir() else []
    if not counts and not known and skipped:
        more = f" (and {len(skipped) - 1} more)" if len(skipped) > 1 else ""
        raise InspectError(f"{saved}: no events.jsonl, and every state file there was skipped: {skipped[0]}{more}")
    if not counts and not known:
        raise InspectError(f"{path}: no events.jsonl and no creature state files "
                           f"(give an offline output directory or a --state directory)")
    from_state = bool(known)
    if not known:
        known = latest_values(events)
    # Drawn aside and published whole (a Ctrl-C or a full disk leaves the previous page as it was),
    # and never over a file no run wrote: `--out ~/site` wrote its index.html over the artist's.
    with publishing(out, {PAGE, *KNOWN_PLOTS}) as staged:
        _render(staged, path, events, counts, known, skipped, from_state)
    return out / PAGE


def _render(out: Path, path: Path, events: list[dict[str, Any]], counts: Counter[str], known: list[Knowledge],
            skipped: list[str], from_state: bool) -> None:
    """Draw the plots and write the page into ``out``."""
    what = "saved state" if from_state else "the last values logged"
    plots = [
        (f"Values of action-tuples and expectations, with confidence ({what})",
         plot_bars({k.creature: k.values for k in known}, "values", "V", out / KNOWN_PLOTS[0],
                   shade={k.creature: k.confidence for k in known})),
        (f"Drives ({what})",
         plot_bars({k.creature: k.drives for k in known}, "drive levels", "level", out / KNOWN_PLOTS[1])),
        ("Percept trees (saved state)",
         plot_bars({k.creature: {t.name: t.size for t in k.trees} for k in known}, "percept tree sizes", "nodes",
                   out / KNOWN_PLOTS[2])),
        ("Duration models (saved state)", _plot_durations(known, out / KNOWN_PLOTS[3])),
    ]
    plots = [(name, p) for name, p in plots if p is not None] + event_plots(events, out)
    title = f"inside {path.name or path}"
    figures = "".join(f'<h2>{html.escape(name)}</h2><img src="{_embed(p)}" alt="{html.escape(name)}">'
                      for name, p in plots)
    unread = "".join(f"<li>{html.escape(s)}</li>" for s in skipped)
    creatures = sum(k.creature != COLONY for k in known)  # the colony's own knowledge is not a creature
    colony = " and the colony" if creatures < len(known) else ""
    page = html_page(title, f"<p>{counts.total()} events, {creatures} creature(s){colony} from {html.escape(what)}.</p>"
                            f"{f'<p>State files skipped:</p><ul>{unread}</ul>' if unread else ''}"
                            f"{counts_table(counts) if counts else ''}"
                            f"<h2>What each creature knows</h2>{''.join(_creature_html(k) for k in known)}{figures}")
    (out / PAGE).write_text(page, encoding="utf-8")
