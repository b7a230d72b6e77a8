"""Gesture models over motor-graph node identities (thesis "learning to chase your tail",
"gesture graph generation", figure 32; reused by *listen* for notes).

A body's recent history is a :class:`BodyMemory` of visited graph nodes. Because the motor
system generated those movements, the nodes already categorise them: a gesture model need
only look at node *identities* ("node A, moving to node B, moving to node C"), not at
hundreds of joint angles. :class:`GestureModel` is an augmented-Markov-style model of them:

* **learning** aligns each new sequence with the best-matching chain already in the model
  ("23456" is explained by "2345", so only "6" is added) and creates fresh states for poses
  repeated within one sequence, so loops do not tangle;
* **confidence** of a state rises with how many sequences visited it and falls with the
  entropy of its outgoing transitions (being part of a tangled mess);
* **segmentation** grows the *core* from the most confident state forwards and backwards
  along the most probable transitions until confidence stays below a threshold for two
  steps;
* **execution** samples (or takes the core of) the model as an executable
  :class:`~creatures.motor.programs.MotorProgram`.

States may also carry note references, as in *listen*, where heard notes are modelled with
the same machinery and played out through their BodyPose references.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable, Hashable, Iterable, Sequence

import numpy as np

from creatures import bounds
from creatures.motor.programs import MotorProgram, Statement
from creatures.temporal.durations import MAX_DURATION


_NO_ROW: dict[int, float] = {}


@dataclass(frozen=True)
class Observation:
    """One entry of a BodyMemory: a motor-graph node reached at ``time`` (maybe with a note)."""

    node: int
    time: float
    note: Any = None


class BodyMemory:
    """A bounded record of the graph nodes the body passed through, oldest first."""

    def __init__(self, capacity: int = 256) -> None:
        self._items: deque[Observation] = deque(maxlen=capacity)

    def record(self, node: int, time: float, note: Any = None) -> None:
        if self._items and self._items[-1].node == node:
            return  # staying on a node is not a new transition
        self._items.append(Observation(int(node), float(time), note))

    def since(self, time: float) -> list[Observation]:
        return [o for o in self._items if o.time >= time]

    def __iter__(self):
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)


@dataclass
class GestureNode:
    """A model state: which motor node it stands for, how often it was seen, its timing."""

    node: int
    visits: int = 0
    dwell: float = 0.0  # mean seconds until the next observation
    notes: list[Any] = field(default_factory=list)
    out: dict[int, int] = field(default_factory=dict)  # next state -> count
    _entropy: float | None = field(default=None, init=False, repr=False, compare=False)

    def followed_by(self, state: int) -> None:
        """Count one transition to ``state``."""
        self.out[state] = self.out.get(state, 0) + 1
        self._entropy = None

    def probabilities(self) -> dict[int, float]:
        total = sum(self.out.values())
        return {s: c / total for s, c in self.out.items()} if total else {}

    def entropy(self) -> float:
        """Entropy (bits) of the outgoing transitions, with transitions seen only once pooled
        into one "anywhere" outcome: uncorrelated noise is one kind of thing, not many.

        Kept until :meth:`followed_by` changes the counts: a lesson touches a few states,
        and the confidence of all of them is asked for after it."""
        if self._entropy is None:
            self._entropy = self._count_entropy()
        return self._entropy

    def _count_entropy(self) -> float:
        counts = [c for c in self.out.values() if c > 1]
        anywhere = sum(c for c in self.out.values() if c == 1)
        counts += [anywhere] if anywhere else []
        total = sum(counts)
        return -sum(c / total * math.log2(c / total) for c in counts) if total else 0.0


class GestureModel:
    """Augmented-Markov model over motor node identities, learnt from BodyMemories.

    What is derived from the states (confidences, the core, the transition table that
    :meth:`log_likelihood` reads) is computed once per :attr:`version` and cached: a listening
    creature asks every model for its core and its match every tick, while a model changes
    only when it learns. The states are therefore changed only through :meth:`learn`, and
    ``entropy_weight`` and ``threshold`` are fixed at construction.
    """

    def __init__(self, *, entropy_weight: float = 0.25, threshold: float = 0.25) -> None:
        self.states: list[GestureNode] = []
        self._of_node: dict[int, list[int]] = {}  # node -> its states, ascending
        self.sequences = 0
        self._entropy_weight = entropy_weight
        self._threshold = threshold
        self._version = 0
        self._derived: dict[Hashable, Any] = {}
        self._log_rows: dict[int, dict[int, float]] = {}  # node a -> node b -> best log p(a → b)
        self._incoming: dict[int, dict[int, int]] = {}  # state -> {state before it: count}
        self._stale_rows: set[int] = set()  # nodes whose row a lesson changed

    @property
    def entropy_weight(self) -> float:
        return self._entropy_weight

    @property
    def threshold(self) -> float:
        return self._threshold

    @property
    def version(self) -> int:
        """Bumped by every change to the states, so results derived from them can be cached."""
        return self._version

    def _changed(self) -> None:
        self._version += 1
        self._derived.clear()

    def _derive(self, key: Hashable, compute: Callable[[], Any]) -> Any:
        """``compute()``, once per version."""
        if key not in self._derived:
            self._derived[key] = compute()
        return self._derived[key]

    # --- learning -------------------------------------------------------------------------

    def learn(self, observations: Iterable[Observation | int]) -> list[int]:
        """Add one sequence; returns the state each observation was assigned to. A gap between
        observations counts towards a state's dwell as at most ``MAX_DURATION`` seconds."""
        items = [o if isinstance(o, Observation) else Observation(int(o), float(i)) for i, o in enumerate(observations)]
        if not items:
            return []
        nodes = [o.node for o in items]
        states = self._align(nodes)
        for k, (state, obs) in enumerate(zip(states, items)):
            g = self.states[state]
            g.visits += 1
            if obs.note is not None:
                g.notes.append(obs.note)
            if k + 1 < len(items):
                self._link(state, states[k + 1])
                # within [0, MAX_DURATION], the bound :meth:`from_dict` reads back: music that
                # stops overnight made a dwell of hours, and the saved model was refused
                gap = min(max(items[k + 1].time - obs.time, 0.0), MAX_DURATION)
                g.dwell += (gap - g.dwell) / g.visits
        self.sequences += 1
        self._changed()
        return states

    def _new(self, node: int) -> int:
        return self._add(GestureNode(node))

    def _add(self, state: GestureNode) -> int:
        index = len(self.states)
        self.states.append(state)
        self._of_node.setdefault(state.node, []).append(index)
        for t, c in state.out.items():  # a loaded state arrives with its transitions
            self._incoming.setdefault(t, {})[index] = c
        self._stale_rows.add(state.node)
        return index

    def _link(self, state: int, after: int) -> None:
        """Count the transition ``state → after`` everywhere it is kept: the state's own counts,
        the incoming links the core grows backwards along, and (marked stale) the log row of
        the state's node. A lesson touches a few states; rebuilding these for the whole model
        after every lesson was most of a listening creature's time."""
        g = self.states[state]
        g.followed_by(after)
        self._incoming.setdefault(after, {})[state] = g.out[after]
        self._stale_rows.add(g.node)

    def states_of(self, node: int) -> tuple[int, ...]:
        """The states standing for motor node ``node``, oldest first (looked up, not searched:
        learning and matching ask this for every note)."""
        return tuple(self._of_node.get(node, ()))

    def _match_lengths(self, nodes: Sequence[int]) -> dict[tuple[int, int], int]:
        """``(i, s) -> n``: states from ``s`` follow transitions matching ``nodes[i:i+n]``."""
        length: dict[tuple[int, int], int] = {}
        for i in range(len(nodes) - 1, -1, -1):
            for s in self._of_node.get(nodes[i], ()):
                g = self.states[s]
                best = 0
                if i + 1 < len(nodes):
                    for t in g.out:
                        best = max(best, length.get((i + 1, t), 0))
                length[(i, s)] = 1 + best
        return length

    def _align(self, nodes: Sequence[int]) -> list[int]:
        """Assign states: the longest chain the model already has, then extend both ways."""
        length = self._match_lengths(nodes)
        assigned: list[int | None] = [None] * len(nodes)
        if length:
            (i, s), n = max(length.items(), key=lambda item: (item[1], self.states[item[0][1]].visits))
            assigned[i] = s
            for k in range(i + 1, i + n):
                prev = self.states[assigned[k - 1]]
                assigned[k] = max(
                    (t for t in prev.out if length.get((k, t), 0) == i + n - k),
                    key=lambda t: prev.out[t],
                )
        else:
            i = 0  # nothing in common with the model yet: start a fresh chain
            assigned[0] = self._new(nodes[0])
        used = {s for s in assigned if s is not None}
        for k in range(i - 1, -1, -1):
            assigned[k] = self._extend(nodes[k], into=assigned[k + 1], used=used)
        for k in range(i + 1, len(nodes)):
            if assigned[k] is None:
                assigned[k] = self._extend(nodes[k], after=assigned[k - 1], used=used)
        return [int(s) for s in assigned]

    def _extend(self, node: int, *, used: set[int], after: int | None = None, into: int | None = None) -> int:
        """A state for ``node`` next to an assigned neighbour: an existing linked state, else
        any unused state of that node, else a new one (repeats get new states: no tangles)."""
        linked = [s for s in self._of_node.get(node, ()) if s not in used]
        if after is not None:
            linked.sort(key=lambda s: -self.states[after].out.get(s, 0))
        if into is not None:
            linked.sort(key=lambda s: -self.states[s].out.get(into, 0))
        state = linked[0] if linked else self._new(node)
        used.add(state)
        return state

    # --- confidence and segmentation ------------------------------------------------------

    def confidence(self, state: int) -> float:
        """Visits relative to the most visited state, minus ``entropy_weight`` × transition
        entropy in bits: frequently seen, untangled states are core."""
        return self._confidences()[state]

    def _confidences(self) -> list[float]:
        """:meth:`confidence` of every state at once (the most visited state is found once,
        not once per state)."""
        return self._derive("confidences", self._compute_confidences)

    def _compute_confidences(self) -> list[float]:
        most = max(max((s.visits for s in self.states), default=1), 1)
        return [g.visits / most - self.entropy_weight * g.entropy() for g in self.states]

    def core(self) -> list[int]:
        """The gesture's core: states grown out from the most confident one along the most
        probable transitions, stopping after two consecutive low-confidence steps."""
        return list(self._derive("core", self._compute_core))

    def _compute_core(self) -> tuple[int, ...]:
        if not self.states:
            return ()
        confidence = self._confidences()
        seed = max(range(len(self.states)), key=lambda s: (confidence[s], self.states[s].visits))
        seen = {seed}
        forward = self._grow(seed, lambda s: self.states[s].out, seen, confidence)
        # oldest state first, as in the states' own order: a tie goes to the oldest
        backward = self._grow(seed, lambda s: dict(sorted(self._incoming.get(s, _NO_ROW).items())), seen,
                              confidence)
        return (*reversed(backward), seed, *forward)

    def _grow(self, seed: int, links: Callable[[int], dict[int, int]], seen: set[int],
              confidence: list[float]) -> list[int]:
        """Follow the most frequent repeated transition from ``seed`` while confidence holds.

        A transition seen only once, beside others, is the "anywhere" of
        :meth:`GestureNode.entropy` — uncorrelated noise, not a path to follow.
        """
        chain: list[int] = []
        pending: list[int] = []
        current = seed
        while True:
            out = links(current)
            options = {t: c for t, c in out.items() if t not in seen and (c > 1 or len(out) == 1)}
            if not options:
                break
            current = max(options, key=options.get)
            seen.add(current)
            if confidence[current] >= self.threshold:
                chain.extend(pending)
                chain.append(current)
                pending = []
            else:
                pending.append(current)
                if len(pending) >= 2:
                    break
        return chain

    def core_nodes(self) -> list[int]:
        """Motor-graph nodes of the core, in order."""
        return list(self._derive("core nodes", lambda: tuple(self.states[s].node for s in self.core())))

    # --- percept model and execution ------------------------------------------------------

    def log_likelihood(self, observations: Iterable[Observation | int], *, floor: float = 1e-3) -> float:
        """Mean log-probability per transition of a sequence under the model (best alignment
        of states by node identity), so models can categorise incoming BodyMemory data."""
        nodes = [o.node if isinstance(o, Observation) else int(o) for o in observations]
        if len(nodes) < 2:
            return 0.0
        rows = self._rows()
        unseen = math.log(floor)
        total = 0.0
        for a, b in zip(nodes, nodes[1:]):
            log_p = rows.get(a, _NO_ROW).get(b, unseen)
            total += log_p if log_p > unseen else unseen
        return total / (len(nodes) - 1)

    def _rows(self) -> dict[int, dict[int, float]]:
        """``a -> b -> log p``: the most probable transition from a state of node ``a`` to a
        state of node ``b`` (what the best alignment of a sequence uses at that step), the rows
        a lesson changed rebuilt first."""
        for a in self._stale_rows:
            best: dict[int, float] = {}
            for s in self._of_node[a]:
                g = self.states[s]
                total = sum(g.out.values())
                for t, c in g.out.items():
                    b = self.states[t].node
                    if c / total > best.get(b, 0.0):
                        best[b] = c / total
            self._log_rows[a] = {b: math.log(p) for b, p in best.items()}
        self._stale_rows.clear()
        return self._log_rows

    def sample(self, rng: np.random.Generator, *, start: int | None = None, max_length: int = 64) -> list[int]:
        """A random walk of states by transition probability, from ``start`` (default: the
        first core state)."""
        if not self.states:
            return []
        state = self.core()[0] if start is None else start
        walk = [state]
        while len(walk) < max_length:
            options = self.states[state].probabilities()
            if not options:
                break
            choices = list(options)
            state = choices[int(rng.choice(len(choices), p=np.array([options[c] for c in choices])))]
            walk.append(state)
        return walk

    def to_program(self, name: str, states: Sequence[int] | None = None) -> MotorProgram:
        """An executable motor program visiting ``states`` (default: the core) in order."""
        states = self.core() if states is None else states
        statements: list[Statement] = []
        for s in states:
            statements += [Statement("getTo", (self.states[s].node,)), Statement("wait")]
        return MotorProgram(name, [*statements, Statement("end")])

    def to_dict(self) -> dict[str, Any]:
        """Plain data for :func:`creatures.persist.save_json` (note references are dropped)."""
        return {
            "sequences": self.sequences,
            "entropy_weight": self.entropy_weight,
            "threshold": self.threshold,
            "states": [
                {"node": g.node, "visits": g.visits, "dwell": g.dwell, "out": {str(t): c for t, c in g.out.items()}}
                for g in self.states
            ],
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, nodes: int = bounds.LARGEST_COUNT, longest: int = 65_536,
                  where: str = "model") -> GestureModel:
        """A model of the states in ``data`` (at most ``longest``, over graph nodes below
        ``nodes``). Raises ValueError naming the key on damaged data."""
        model = cls(entropy_weight=bounds.number(data["entropy_weight"], f"{where}.entropy_weight", low=0.0, high=1e3),
                    threshold=bounds.number(data["threshold"], f"{where}.threshold"))
        model.sequences = bounds.count(data["sequences"], f"{where}.sequences")
        states = bounds.items(data["states"], f"{where}.states", longest=longest)
        for i, s in enumerate(states):
            at = f"{where}.states.{i}"
            s = bounds.table(s, at)
            out = bounds.table(s["out"], f"{at}.out")
            if not all(t.isdigit() and int(t) < len(states) for t in out):
                raise ValueError(f"{at}.out: keys must be indices of states")
            model._add(GestureNode(bounds.count(s["node"], f"{at}.node", high=nodes - 1),
                                   bounds.count(s["visits"], f"{at}.visits"),
                                   bounds.number(s["dwell"], f"{at}.dwell", low=0.0, high=MAX_DURATION), [],
                                   {int(t): bounds.count(c, f"{at}.out.{t}", low=1) for t, c in out.items()}))
        return model
