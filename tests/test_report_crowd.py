"""A run's report on a crowd (REACT's rooms of hundreds): each plot draws at most
``MAX_PANELS`` creatures one by one and says how many it leaves out. A crowd of 300 singers
drew a panel per creature in every plot, figures hundreds of inches tall, and the report took
most of the run."""

from __future__ import annotations

from pathlib import Path

import matplotlib.image

from creatures.runtime.report import MAX_PANELS, _some, event_plots


def _events(creatures: int) -> list[dict]:
    events = []
    for i in range(creatures):
        name = f"s{i:03d}"
        for t in (0.5, 1.0, 1.5):
            events += [{"t": t, "kind": "values", "creature": name, "values": {"sing": t, "rest": 1 - t}},
                       {"t": t, "kind": "motivation", "creature": name, "drives": {"boredom": t}},
                       {"t": t, "kind": "selection", "creature": name, "tuple": "sing"},
                       {"t": t, "kind": "note", "creature": name, "time": t, "pitch": 60 + i % 12, "duration": 0.2}]
    return events


def _sizes(tmp_path: Path, creatures: int) -> dict[str, tuple[int, int]]:
    out = tmp_path / str(creatures)
    out.mkdir()
    return {path.name: matplotlib.image.imread(path).shape[:2] for _, path in event_plots(_events(creatures), out)}


def test_a_crowd_s_report_draws_as_many_panels_as_a_dozen_creatures_and_says_so(tmp_path):
    crowd, dozen = _sizes(tmp_path, 300), _sizes(tmp_path, MAX_PANELS)
    assert set(crowd) == {"notes.png", "selections.png", "values.png", "motivations.png"}
    assert crowd == dozen  # the same figures: a dozen panels, rows, legend entries
    assert dozen["values.png"][0] > _sizes(tmp_path, 2)["values.png"][0]  # which are one per creature below it
    names = [f"s{i}" for i in range(300)]
    assert _some(names) == (sorted(names)[:MAX_PANELS], f" ({MAX_PANELS} of 300 creatures shown)")
    assert _some(["b", "a"]) == (["a", "b"], "")
