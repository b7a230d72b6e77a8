"""Graded, learnable proximity between actions (thesis "credit assignment": "all equivalent
action-tuples take place in credit assignment"; "learning to chase your tail – part 2").

Credit earned by one action-tuple's activation reaches every other tuple of the group in
proportion to ``proximity(credited, other)`` in [0, 1]. The thesis delegates the number to
Ac ("it is the usual case that the computation of the proximity is delegated to Ac – we will
see cases where proximities are somewhere between 0 and 1"): by default identical actions
are 1 and others 0 (:meth:`Action.proximity_to`). A :class:`Proximity` table overrides that
per ordered pair of action names, and can learn:

* **fixed** entries stay as written (complex shaping gives the tuple that executes a gesture
  model proximity 1 to the guide action, so it takes the guide's credit and its model learns
  from the guide's runs);
* every other pair ``(a, b)`` with ``a ≠ b`` is, when learning is on, a running estimate of
  how reliably ``b`` *precedes* a rewarded activation of ``a``: each time an activation of
  ``a`` earns positive credit, ``p(a, b) ← (1 − rate)·p(a, b) + rate·[b was active within
  window seconds before a began]``. The update is the same low-pass filter as a value's
  ``blendTo``, so an action that leads up to another's reward comes to share that reward
  directly, and one that stops doing so drifts back toward 0.

The diagonal (an action with itself) is always 1: the last active tuple always takes its
own credit.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Iterable

from creatures import bounds

if TYPE_CHECKING:
    from creatures.behaviour.action_group import Activation
    from creatures.behaviour.action_tuple import Action, ActionTuple


class Proximity:
    """Proximities by ordered pair of action names ``(credited, other)``, some fixed, the
    rest learnt at ``rate`` (0: learning off) from what preceded rewards within ``window`` s.

    ``version`` counts changes, so a group can cache its proximity rows between them.
    """

    def __init__(self, table: dict[tuple[str, str], float] | None = None, *, fixed: Iterable[tuple[str, str]] = (),
                 rate: float = 0.0, window: float = 5.0) -> None:
        if not 0.0 <= rate <= 1.0:
            raise ValueError(f"proximity learning rate must be in [0, 1] (got {rate!r})")
        if not window > 0.0:
            raise ValueError(f"proximity window must be positive (got {window!r})")
        self.table: dict[tuple[str, str], float] = {}
        self.fixed: set[tuple[str, str]] = set()
        self.rate = float(rate)
        self.window = float(window)
        self.version = 0
        for (a, b), p in (table or {}).items():
            self.set(a, b, p)
        self.written = set(self.table)  # the author's pairs: learnt further, never forgotten
        for a, b in fixed:
            self.fix(a, b, self.table.get((a, b), 1.0))

    def set(self, a: str, b: str, p: float) -> None:
        """Proximity of ``b`` to credit earned by ``a`` (learnt further when learning is on)."""
        if not 0.0 <= p <= 1.0:
            raise ValueError(f"proximity {a!r} → {b!r} must be in [0, 1] (got {p!r})")
        self.table[(a, b)] = float(p)
        self.version += 1

    def fix(self, a: str, b: str, p: float = 1.0) -> None:
        """As :meth:`set`, and never learnt (complex shaping's gesture tuple and its guide)."""
        self.set(a, b, p)
        self.fixed.add((a, b))

    def between(self, a: "Action", b: "Action") -> float:
        """How much of the credit earned by ``a`` reaches ``b``."""
        if a is b or a.name == b.name:
            return 1.0
        return self.table.get((a.name, b.name), a.proximity_to(b))

    def forget(self, name: str) -> None:
        """Drop the learnt pairs naming action ``name``, which no tuple of the group performs
        any more (its class fused away, its hypothesis was dropped). The table grew with every
        action a run ever tried; a new action given a freed name (a class numbered again)
        would also have inherited the old one's proximities. Written and fixed pairs stay."""
        gone = [key for key in self.table if name in key and key not in self.written and key not in self.fixed]
        for key in gone:
            del self.table[key]
        if gone:
            self.version += 1

    @property
    def learning(self) -> bool:
        return self.rate > 0.0

    def credited(self, credited: "ActionTuple", tuples: Iterable["ActionTuple"],
                 recent: Iterable["Activation"], started: float) -> None:
        """An activation of ``credited`` (begun at ``started``) earned positive credit: move
        every learnable ``p(credited, b)`` toward whether ``b`` was active within ``window``
        seconds before it began."""
        if not self.learning:
            return
        a = credited.action
        before = {id(act.tuple_) for act in recent if act.tuple_ is not credited and act.started < started
                  and (act.ended is None or act.ended >= started - self.window)}
        for tuple_ in tuples:
            b = tuple_.action
            key = (a.name, b.name)
            if b is a or b.name == a.name or key in self.fixed:
                continue
            target = 1.0 if id(tuple_) in before else 0.0
            old = self.table.get(key, a.proximity_to(b))
            self.table[key] = old + self.rate * (target - old)
        self.version += 1

    # -- what lasts across runs --------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The learnt table (fixed entries too: a gesture tuple made at run time brings its own)."""
        return {"table": [[a, b, p] for (a, b), p in sorted(self.table.items())],
                "fixed": [[a, b] for a, b in sorted(self.fixed)]}

    def restore(self, data: dict[str, Any], where: str = "proximity") -> None:
        """Take back :meth:`to_dict` (rate and window stay the config's); ValueError names the key."""
        rows = bounds.items(data["table"], f"{where}.table", longest=1 << 20)
        fixed = bounds.items(data["fixed"], f"{where}.fixed", longest=1 << 20)
        table: dict[tuple[str, str], float] = {}
        for i, row in enumerate(rows):
            if not (isinstance(row, list) and len(row) == 3 and all(isinstance(x, str) for x in row[:2])):
                raise ValueError(f"{where}.table.{i}: expected [action, action, proximity]")
            table[(row[0], row[1])] = bounds.number(row[2], f"{where}.table.{i}", low=0.0, high=1.0)
        pairs = set()
        for i, row in enumerate(fixed):
            if not (isinstance(row, list) and len(row) == 2 and all(isinstance(x, str) for x in row)):
                raise ValueError(f"{where}.fixed.{i}: expected [action, action]")
            pairs.add((row[0], row[1]))
        self.table, self.fixed = table, pairs
        self.version += 1
