"""Motivational state as linear "synthetic chemistry" (thesis: "soft state"; sand:stone,
figure 37; after Grand, Cliff and Malhotra's *Creatures*).

Motivations are explicit scalar drives ("hunger", "desire to sing", "breath", "boredom"),
modelled *ad hoc* by the author and read by behaviour in two ways: by modulating values
(a hungry creature values eating, and through value chaining everything that precedes
eating) and by being modelled directly by Tr percepts (scale-free "hungry"). Between events
they obey one linear system

    dx/dt = r − D(x − x_eq) + Cx + u

with per-second growth r, decay rates D (diagonal) toward equilibria x_eq, a coupling matrix
C (C[i, j]: how drive j feeds drive i) and external inputs u held until changed. Behaviour
closes the loop with impulses (:meth:`Motivation.perturb`: eating takes hunger down).

The system is integrated *exactly* over any elapsed clock time, x(t+dt) = Φx + Ψb with
M = C − D, b = r + D·x_eq + u, Φ = e^{M·dt} and Ψ = ∫₀^dt e^{M·s} ds, both read from one
matrix exponential of [[M, I], [0, 0]]·dt, so the result never depends on how often the
creature ticks. Φ and Ψ depend on the step only (not on the inputs), so a creature that
re-sets its inputs every step (a sensed presence) still reuses them. A floor/ceiling clip
afterwards (chemical concentrations do not go negative); clipping is the only non-linear
step. A bound left open is ±:data:`creatures.bounds.LARGEST_RATE`, the range a saved level
is read back within: a drive that only grows (growth, no decay) or a coupling loop that
feeds itself faster than it decays would otherwise climb for as long as the show runs, out
of the range its own saved state loads in, and a loop to overflow and NaN within hours.

A live run hears notes between its ticks (creatures/runtime/ticking.py), at times off the
tick grid: integrating to such a time would need a matrix exponential for a step seen once
(twice: the next tick's step from there is new too), on the way to a reflex answer. So inside
:func:`between_ticks` an impulse lands at the drives' own time instead (their last tick) and
the next tick carries it forward with the step it already knows: the impulse starts decaying
less than a tick early. Offline runs never enter it and integrate as before.
"""

from __future__ import annotations

from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any, Iterator, Mapping, Sequence

import numpy as np
from scipy.linalg import expm

from creatures import bounds
from creatures.behaviour.unplaced import Unplaced

_between_ticks: ContextVar[bool] = ContextVar("between_ticks", default=False)


@contextmanager
def between_ticks() -> Iterator[None]:
    """Inside (on this thread): impulses land at each motivation's last tick (see the module
    docstring); the live loop delivers the notes it hears between ticks in here."""
    token = _between_ticks.set(True)
    try:
        yield
    finally:
        _between_ticks.reset(token)


MOST_SUBSTEPS = 2 ** 16
"""Most clipped sub-steps run for one step of the drives (:meth:`Motivation._in_steps`): a few
tenths of a second of the creature's thread, once, after a clock gap."""


class Motivation:
    """A creature's named drives and their linear dynamics.

    Parameters are mappings by drive name (missing entries are 0, equilibria default to the
    initial level); ``coupling`` maps ``(to, from)`` pairs to rates.
    """

    def __init__(
        self,
        levels: Mapping[str, float],
        *,
        growth: Mapping[str, float] | None = None,
        decay: Mapping[str, float] | None = None,
        equilibrium: Mapping[str, float] | None = None,
        coupling: Mapping[tuple[str, str], float] | None = None,
        floor: float | None = 0.0,
        ceiling: float | None = None,
        start: float = 0.0,
    ) -> None:
        if not levels:
            raise ValueError("a motivation needs at least one drive")
        self.names = list(levels)
        self._index = {name: k for k, name in enumerate(self.names)}
        self.levels = self._vector(levels, "levels")
        self.growth = self._vector(growth or {}, "growth")
        self.decay = self._vector(decay or {}, "decay")
        if (self.decay < 0).any():
            raise ValueError("decay rates must be non-negative")
        self.equilibrium = self._vector({**levels, **(equilibrium or {})}, "equilibrium")
        n = len(self.names)
        self.coupling = np.zeros((n, n))
        for (to, frm), rate in (coupling or {}).items():
            self.coupling[self.index(to), self.index(frm)] = float(rate)
        self.inputs = np.zeros(n)
        self._propagators: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self._last_levels: tuple[tuple, np.ndarray] | None = None
        self.floor = floor
        self.ceiling = ceiling
        self.time = float(start)
        self.unplaced = Unplaced()
        """Saved ``levels`` and ``inputs`` of drives this motivation has none of (a drive renamed
        or removed in the config): kept and saved again (:meth:`to_dict`), so a drive named back
        takes its level back, as a renamed tuple's value is kept."""

    def _vector(self, values: Mapping[str, float], what: str) -> np.ndarray:
        out = np.zeros(len(self.names))
        for name, v in values.items():
            if name not in self._index:
                raise KeyError(f"{what}: no drive named {name!r} (drives: {self.names})")
            out[self._index[name]] = float(v)
        if not np.isfinite(out).all():
            raise ValueError(f"{what} must be finite numbers")
        return out

    def index(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(f"no drive named {name!r} (drives: {self.names})") from None

    # -- dynamics ------------------------------------------------------------------------------
    def _propagator(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """``(Φ, offset)`` of a step ``dt`` with the present inputs."""
        phi, psi = self._step(dt)
        return phi, psi @ (self.growth + self.decay * self.equilibrium + self.inputs)

    def _step(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """``(Φ, Ψ)`` of a step ``dt``."""
        # A creature ticks at a fixed rate, so the same few steps recur: keep their (Φ, Ψ),
        # keyed by the step rounded to a nanosecond (clock sums differ in the last bits).
        # The propagator is computed for the rounded step itself, so a result never depends
        # on which nearby step happened to fill the cache first (a reloaded creature must
        # continue bit for bit).
        key = round(dt, 9)
        cached = self._propagators.get(key)
        if cached is None:
            if len(self._propagators) >= 16:
                self._propagators.clear()
            cached = self._propagators[key] = self._compute_propagator(key)
        return cached

    def _compute_propagator(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        n = len(self.names)
        augmented = np.zeros((2 * n, 2 * n))
        augmented[:n, :n] = self.coupling - np.diag(self.decay)
        augmented[:n, n:] = np.eye(n)
        e = expm(augmented * dt)
        return e[:n, :n], e[:n, n:]

    def _clip(self, x: np.ndarray) -> np.ndarray:
        # The ufuncs np.clip itself resolves to, called directly: every tick clips each
        # creature's drives, and np.clip's dispatch cost more than the clip. An open bound is
        # ±LARGEST_RATE (see the module docstring).
        low = -bounds.LARGEST_RATE if self.floor is None else self.floor
        high = bounds.LARGEST_RATE if self.ceiling is None else self.ceiling
        return np.minimum(np.maximum(x, low), high)

    def levels_at(self, t: float) -> np.ndarray:
        """Every drive's level at ``t`` ≥ the current time, without moving the state."""
        dt = float(t) - self.time
        if dt < 0:
            raise ValueError(f"motivation: time went backwards ({t} < {self.time})")
        if dt == 0:
            return self.levels.copy()
        # Many percepts of one creature read its drives at one time in a tick: the last answer
        # is kept for the same instant and the same state (levels and inputs, which a drive's
        # percept inputs set in place).
        key = (float(t), self.time, self.levels.tobytes(), self.inputs.tobytes(), self.growth.tobytes())
        if self._last_levels is not None and self._last_levels[0] == key:
            return self._last_levels[1].copy()
        phi, offset = self._propagator(dt)
        levels = self._clip(phi @ self.levels + offset)
        if not np.isfinite(levels).all():
            levels = self._in_steps(dt)
        self._last_levels = (key, levels)
        return levels.copy()

    def _in_steps(self, dt: float) -> np.ndarray:
        """The levels after ``dt``, integrated in as many equal steps, each clipped, as keep
        every step finite: a drive that feeds itself (a coupling loop growing at +0.05/s)
        grows by e^1800 over a night's clock gap, past any float, and one exact step gave
        inf − inf = NaN for good; clipped step by step it reaches its bound. Every step is
        the same map, so levels it leaves unchanged (held at their bounds) stay so for the
        steps left: a loop at the largest rates (1e6/s, 2^26 steps over ten hours) saturates
        within a few. Drives that never settle (a coupling that oscillates) beside one that
        needs that many would run them all, minutes on the creature's thread, so at most
        :data:`MOST_SUBSTEPS` are run: such drives are then where that many sub-steps took
        them, short of the gap's end (finite, and at their bounds where they fed themselves)."""
        steps = 2
        while True:
            with np.errstate(over="ignore", invalid="ignore"):
                phi, offset = self._propagator(dt / steps)
                levels = self.levels
                for _ in range(min(steps, MOST_SUBSTEPS)):
                    after = self._clip(phi @ levels + offset)
                    if not np.isfinite(after).all() or np.array_equal(after, levels):
                        break
                    levels = after
            if np.isfinite(after).all():
                return levels
            steps *= 2

    def advance(self, t: float) -> None:
        """Integrate exactly from the current time to clock time ``t`` (nothing to do at the
        drives' own time: a crowd's were advanced together before each creature's feed)."""
        if float(t) != self.time:
            self.levels = self.levels_at(t)
            self.time = float(t)

    @staticmethod
    def advance_all(motivations: Sequence["Motivation"], t: float) -> None:
        """:meth:`advance` of many motivations (a crowd's) to clock time ``t`` at once: the same
        products, Φ·x + Ψ·b then the clip, as stacked matrix products over every motivation
        with as many drives and the same bounds (numpy's stacked matmul gives each product
        bit for bit as the one alone: tests/test_motivation.py), instead of a few numpy calls
        on vectors of one or two drives per creature."""
        t = float(t)
        alike: dict[tuple, list[Motivation]] = {}
        for m in motivations:
            if t != m.time:  # none to make at the drives' own time; going back raises, as advance does
                if t < m.time:
                    m.advance(t)
                alike.setdefault((len(m.names), m.floor, m.ceiling), []).append(m)
        join = np.concatenate  # of the motivations' own vectors and matrices, then shaped (faster than np.array)
        for (d, _, _), ms in alike.items():
            n = len(ms)
            steps = [m._step(t - m.time) for m in ms]
            rates = (join([m.growth for m in ms]) + join([m.decay for m in ms]) * join([m.equilibrium for m in ms])
                     + join([m.inputs for m in ms])).reshape(n, d, 1)
            offset = np.matmul(join([psi for _, psi in steps]).reshape(n, d, d), rates)
            levels = np.matmul(join([phi for phi, _ in steps]).reshape(n, d, d), join([m.levels for m in ms]).reshape(n, d, 1))
            rows = ms[0]._clip((levels + offset)[:, :, 0])
            if not np.isfinite(rows).all():  # a step too long for a drive that feeds itself
                rows = [row if np.isfinite(row).all() else m._in_steps(t - m.time) for m, row in zip(ms, rows)]
            for m, row in zip(ms, rows):
                m.levels, m.time = row, t

    def level(self, name: str, t: float | None = None) -> float:
        if t is None or t == self.time:  # the drives' own time: their levels, no step to make
            return float(self.levels[self.index(name)])
        return float(self.levels_at(t)[self.index(name)])

    def set_input(self, t: float, name: str, rate: float) -> None:
        """From ``t`` on, feed ``rate`` per second into a drive (a sensed presence, say)."""
        self.advance(t)
        self.hold_input(self.index(name), rate)

    def hold_input(self, i: int, rate: float) -> None:
        """Feed ``rate`` per second into drive ``i`` until changed, within
        ±:data:`creatures.bounds.LARGEST_RATE`, the bound a saved state's inputs load in: 256
        percept inputs at the largest accepted rate, reading a pitch, summed to 3e10/s, and the
        creature's next run refused its own state. A NaN rate (a broken sensor) keeps the last."""
        if not np.isnan(rate):
            self.inputs[i] = min(max(float(rate), -bounds.LARGEST_RATE), bounds.LARGEST_RATE)

    def perturb(self, t: float, name: str, amount: float) -> None:
        """An impulse at ``t``: behaviour acting on state (eating: hunger − amount); between
        a live run's ticks, at the last tick (:func:`between_ticks`)."""
        if not _between_ticks.get():
            self.advance(t)
        i = self.index(name)
        self.levels[i] = self._clip(self.levels[i : i + 1] + float(amount))[0]

    # -- reaching behaviour ---------------------------------------------------------------------
    def importance(self, sources: Mapping[str, str]) -> Mapping[str, float]:
        """A live map from value-chain source to the level of the drive it serves, e.g.
        ``{"eat": "hunger"}``, to hand to :class:`ChainValue` as its ``importance``."""
        for drive in sources.values():
            self.index(drive)
        return _Importance(self, dict(sources))

    # -- persistence -------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        def named(v: np.ndarray) -> dict[str, float]:
            return {n: float(x) for n, x in zip(self.names, v)}

        return {
            "kind": "motivation",
            "levels": named(self.levels),
            "growth": named(self.growth),
            "decay": named(self.decay),
            "equilibrium": named(self.equilibrium),
            "coupling": [
                [to, frm, float(self.coupling[i, j])]
                for i, to in enumerate(self.names)
                for j, frm in enumerate(self.names)
                if self.coupling[i, j] != 0.0
            ],
            "inputs": named(self.inputs),
            "floor": self.floor,
            "ceiling": self.ceiling,
            "time": self.time,
            **({"unplaced": self.unplaced.kept} if self.unplaced.kept else {}),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, now: float | None = None) -> "Motivation":
        """Rebuild saved drives; ``now`` restarts their clock at a new run's time (levels
        carry over, the saved time belongs to a clock that no longer runs)."""
        keys = ("levels", "growth", "decay", "equilibrium", "coupling", "inputs", "floor",
                "ceiling", "time")
        missing = [k for k in keys if k not in data]
        if missing:
            raise ValueError(f"motivation state is missing key {missing[0]!r}")
        try:
            motivation = cls(
                data["levels"],
                growth=data["growth"],
                decay=data["decay"],
                equilibrium=data["equilibrium"],
                coupling={(to, frm): rate for to, frm, rate in data["coupling"]},
                floor=data["floor"],
                ceiling=data["ceiling"],
                start=data["time"] if now is None else now,
            )
            motivation.inputs = motivation._vector(data["inputs"], "inputs")
        except KeyError as exc:  # a parameter names a drive that has no level
            raise ValueError(f"motivation state: {exc.args[0]}") from None
        return motivation

    def restore(self, data: Any, *, now: float) -> None:
        """Take back the levels (and inputs) of saved drives into this motivation, whose
        rates, equilibria, coupling and bounds stay the ones it was built with: those are
        the author's settings (an edited config wins over a saved file), the levels are
        what the creature lived through. Each level is kept within [floor, ceiling] (or
        ±:data:`creatures.bounds.LARGEST_RATE` without them); the clock restarts at ``now``.
        Raises ValueError naming the key on malformed data."""
        data = bounds.table(data, "motivation")
        low = -bounds.LARGEST_RATE if self.floor is None else self.floor
        high = bounds.LARGEST_RATE if self.ceiling is None else self.ceiling
        kept = bounds.table(data.get("unplaced", {}), "motivation.unplaced")
        restored = self.levels.copy(), self.inputs.copy()
        unplaced = Unplaced()
        for vector, what, (lo, hi) in ((restored[0], "levels", (low, high)),
                                       (restored[1], "inputs", (-bounds.LARGEST_RATE, bounds.LARGEST_RATE))):
            numbers = {name: bounds.number(value, f"{where}.{name}", low=lo, high=hi)
                       for where, saved in ((f"motivation.unplaced.{what}", kept.get(what, {})),
                                            (f"motivation.{what}", data.get(what, {} if what == "inputs" else None)))
                       for name, value in bounds.table(saved, where).items()}
            # a drive the config no longer has: kept, not forgotten
            for name, number in unplaced.place(what, numbers, self._index, what="level", of="drive").items():
                vector[self._index[name]] = number
        self.levels, self.inputs, self.unplaced = *restored, unplaced
        self.time = float(now)

    def __repr__(self) -> str:
        inner = ", ".join(f"{n}={x:.3g}" for n, x in zip(self.names, self.levels))
        return f"Motivation({inner} @ t={self.time:.3g})"


class _Importance(Mapping[str, float]):
    """Read-only view: source name → current level of the drive it serves."""

    def __init__(self, motivation: Motivation, sources: dict[str, str]) -> None:
        self._motivation = motivation
        self._sources = sources

    def __getitem__(self, source: str) -> float:
        return self._motivation.level(self._sources[source])

    def __iter__(self) -> Iterator[str]:
        return iter(self._sources)

    def __len__(self) -> int:
        return len(self._sources)
