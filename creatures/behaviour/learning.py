"""Learning that grows: value-driven model building, percept fission and fusion, new
action-tuple hypotheses, and Ac percepts (thesis: "percept updating – model building",
"extending the percept tree", "percept trees", simple shaping).

A :class:`PerceptLearning` is attached to an :class:`ActionGroup` (``group.learning``) and is
told about every credit assignment. It then

1. updates the models of the Tr percepts of the tuples that took credit, but only where the
   tuple's value is above a *statistics threshold* (``relative × mean value of the group's
   leaves``): effort is spent where high-value actions are. The situation modelled is the
   one that *led up to* the activation: the percept is updated at the time the last active
   tuple became active, reading the StateObject's history;
2. teaches Ac percepts (:class:`ParametrisedAction`) the parameter that earned the credit;
3. above a higher *innovation threshold*, reviews the percept tree: a 1-D Gaussian percept
   whose buffer has become bimodal splits into two child percepts (fission), and every tuple
   triggered by the parent gets a copy triggered by each child (new hypotheses, value
   inherited); children whose models have stopped being distinct fuse back, their tuples go.

Bimodality is judged on the best one-dimensional two-means split of the buffer: two Gaussians
must explain it very strongly better than one by the Bayesian information criterion, and the halves must
be separated by Ashman's D = √2·|μ₁ − μ₂| / √(σ₁² + σ₂²) > 2, the usual criterion for a clean
two-Gaussian mixture (Ashman, Bird & Zepf 1994). (D alone is not enough: the two halves of
*any* sample, even one Gaussian, are D ≈ 2.6 apart.) Children fuse back when their models'
D falls below a lower threshold, or when the parent's buffer, which keeps seeing all the data,
no longer prefers two categories at all (ΔBIC < 0): both with hysteresis against fission.
"""

from __future__ import annotations

import itertools
from typing import Any, Callable

import numpy as np

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.models.gaussian import GaussianModel, GaussianPercept
from creatures.behaviour.percept import Percept
from creatures.behaviour.value import Value, value_from_dict


def ashman_d(m1: float, s1: float, m2: float, s2: float) -> float:
    """Ashman's D: how well two Gaussians are separated (> 2: a clean bimodal mixture)."""
    spread = np.sqrt(s1 * s1 + s2 * s2)
    return float(np.sqrt(2.0) * abs(m1 - m2) / spread) if spread > 0 else float("inf")


def two_means_split(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The exact 1-D two-means partition of ``x`` (least within-cluster squared error).

    In one dimension the optimal split is between two neighbours of the sorted data, so all
    splits are scored at once from cumulative sums.
    """
    xs = np.sort(np.asarray(x, dtype=float))
    n = len(xs)
    k = np.arange(1, n)  # size of the lower part
    c1, c2 = np.cumsum(xs), np.cumsum(xs * xs)
    low_sse = c2[:-1] - c1[:-1] ** 2 / k
    high_sse = (c2[-1] - c2[:-1]) - (c1[-1] - c1[:-1]) ** 2 / (n - k)
    cut = int(np.argmin(low_sse + high_sse)) + 1
    return xs[:cut], xs[cut:]


def split_evidence(low: np.ndarray, high: np.ndarray) -> float:
    """ΔBIC of one Gaussian against two for ``low ∪ high`` split this way: positive means
    two categories explain the data better.

    Twice the difference of the maximised classification log-likelihoods, minus the BIC
    penalty 3·ln n for the extra mean, variance and weight. The Gaussian constant
    ½·n·ln(2πe) is the same on both sides and cancels. A hard split of one Gaussian's
    samples scores about −0.38·n − 3·ln n (the halves are narrower, by 0.6, but the labels
    cost n·ln 2), so unimodal data does not split however much of it there is.
    """
    x = np.concatenate([low, high])
    n = len(x)
    floor = 1e-12
    one = -n * np.log(max(x.std(), floor))
    two = sum(len(c) * (np.log(len(c) / n) - np.log(max(c.std(), floor))) for c in (low, high))
    return float(2.0 * (two - one) - 3.0 * np.log(n))


def bimodal_clusters(
    buffer: np.ndarray, *, split_at: float = 2.0, min_evidence: float = 10.0, min_share: float = 0.2
) -> tuple[np.ndarray, np.ndarray] | None:
    """The two clusters of ``buffer`` if it is clearly bimodal, else ``None``.

    Clearly bimodal: the best two-means split has :func:`split_evidence` above
    ``min_evidence`` (ΔBIC > 10 is "very strong" on Kass & Raftery's scale) and its halves
    are separated by Ashman's D above ``split_at``. Each cluster must hold at
    least ``min_share`` of the samples, so a few outliers do not make a category.
    """
    low, high = two_means_split(buffer)
    if min(len(low), len(high)) < min_share * len(buffer):
        return None
    if split_evidence(low, high) <= min_evidence:
        return None
    d = ashman_d(low.mean(), low.std(), high.mean(), high.std())
    return (low, high) if d > split_at else None


def copy_value(value: Value) -> Value:
    """An independent value of the same kind and state (a hypothesis inherits, not shares);
    a live motivational ``importance`` map, which is creature state, stays shared."""
    copy = value_from_dict(value.to_dict())
    if getattr(value, "importance", None) is not None:
        copy.importance = value.importance
    return copy


def hypothesise(name: str, trigger: Percept, tuple_: ActionTuple) -> ActionTuple:
    """``trigger | Ac | Du | V`` named ``name``: ``tuple_``'s Ac (shared), a fresh Do-until on
    its Du's duration (model) and until-percept, its V copied. What fission tries on a new
    child, and what a restart builds again for each such tuple saved."""
    du = tuple_.do_until
    return ActionTuple(name, trigger, tuple_.action,
                       DoUntil(du.duration, until=du.until, learn=du.learn, graded=du.graded, fresh=du.fresh),
                       copy_value(tuple_.value))


class ParametrisedAction(Action):
    """An Ac percept: an action whose parameter is drawn from a model each time it starts,
    and whose model learns the parameters that were followed by valuable credit (thesis:
    Ac percepts; the simple-shaping problem — "try out whole classes of actions and slowly
    refine them").

    ``perform(t, parameter)`` (optional) is the author's code driving the motor system; it
    is code, so it is re-bound by name when a creature is loaded.
    """

    def __init__(
        self,
        name: str,
        model: GaussianModel,
        rng: np.random.Generator,
        perform: Callable[[float, float], None] | None = None,
    ) -> None:
        super().__init__(name)
        self.model = model
        self.rng = rng
        self.perform = perform
        self.parameter: float | None = None

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.parameter = self.model.sample(self.rng)
        if self.perform is not None:
            self.perform(t, self.parameter)

    def learn(self) -> None:
        """Teach the model the parameter of the last performance (it earned credit)."""
        if self.parameter is not None:
            self.model.update(self.parameter)

    def to_dict(self) -> dict[str, Any]:
        """The learnt state (model, last parameter); ``perform`` is code and is not saved."""
        return {"parameter": self.parameter, "model": self.model.to_dict()}

    def restore(self, data: dict[str, Any]) -> None:
        """Take back state saved by :meth:`to_dict`, in place (the model may be shared)."""
        self.model.__dict__.update(GaussianModel.from_dict(data["model"]).__dict__)
        self.parameter = None if data["parameter"] is None else float(data["parameter"])


class PerceptLearning:
    """Value-driven model building and percept-tree growth for one action-group.

    ``statistics`` and ``innovation`` are multiples of the mean value of the group's leaf
    tuples: a tuple must be worth more than ``statistics × mean`` for its percept models to
    be updated, and more than ``innovation × mean`` for its percept to be reviewed for
    fission. A percept's model is only taught a situation it recognised (its Tr was at
    least ``min_trigger`` when the action began): a Gaussian likelihood is never exactly
    zero, and a child must not learn its sibling's data. ``on_event`` receives
    ``fission`` / ``fusion`` / ``hypothesis`` events.
    """

    def __init__(
        self,
        *,
        statistics: float = 1.0,
        innovation: float = 1.5,
        split_at: float = 2.0,
        fuse_below: float = 1.0,
        min_evidence: float = 10.0,
        min_share: float = 0.2,
        min_trigger: float = 0.1,
        on_event: Callable[[dict[str, Any]], None] | None = None,
    ) -> None:
        if innovation < statistics:
            raise ValueError("the innovation threshold must not be below the statistics threshold")
        if fuse_below >= split_at:
            raise ValueError("fuse_below must be below split_at (hysteresis between fission and fusion)")
        self.statistics = statistics
        self.innovation = innovation
        self.split_at = split_at
        self.fuse_below = fuse_below
        self.min_evidence = min_evidence
        self.min_share = min_share
        self.min_trigger = min_trigger
        self.on_event = on_event
        self.grown = 0  # percepts made by fission so far: names stay unique across saves

    def thresholds(self, group: ActionGroup) -> tuple[float, float]:
        """(statistics, innovation) thresholds in value units for ``group`` now."""
        values = group.leaf_values()
        mean = float(values.mean()) if len(values) else 0.0
        return self.statistics * mean, self.innovation * mean

    def after_credit(
        self, group: ActionGroup, t: float, last: ActionTuple, a: np.ndarray, target: Value, before: np.ndarray
    ) -> None:
        """Called by the group after every credit assignment: ``a`` are the blend parameters,
        ``target`` is β·V_n and ``before`` the values before blending.

        A tuple's models learn from this transition only if the tuple is worth more than the
        statistics threshold *and* the transition led to something more valuable than the
        tuple itself (thesis: model "the portion of the state space that leads to the
        execution of actions *more* 'valuable' than the current action-tuple").
        """
        stats, innovation = self.thresholds(group)
        # The situation that led up to the last activation (not last.started_at: a tuple
        # that restarts itself has already been given its new start time).
        situation = group.last_started_at if group.last_started_at is not None else t
        reward = target.to_float()
        updated: set[int] = set()
        recognised = group.trigger_at_last_start >= self.min_trigger
        for i in np.flatnonzero(a):
            tuple_ = group.tuples[i]
            if before[i] <= stats:
                continue
            if reward > before[i]:
                if recognised[i] and id(tuple_.trigger) not in updated:
                    tuple_.trigger.update(situation, reward)
                    updated.add(id(tuple_.trigger))
                if tuple_ is last and isinstance(tuple_.action, ParametrisedAction):
                    tuple_.action.learn()
            if tuple_.value.to_float() > innovation:
                self.review(group, tuple_, t, innovation)

    # -- extending the percept tree -------------------------------------------------------
    def review(self, group: ActionGroup, tuple_: ActionTuple, t: float, innovation: float | None = None) -> None:
        """Fission of the tuple's trigger if bimodal, fusion of its children if they merged,
        and hypotheses for children that have no tuple yet. ``innovation``: the threshold in
        value units, when the caller has it (the group's values are the same for every tuple
        one credit assignment reviews; a learner that weighs worth against it need not sum
        them again for each)."""
        percept = tuple_.trigger
        if isinstance(percept, GaussianPercept):
            if not percept.children:
                self.fission(percept, t)
            else:
                self.fuse_if_merged(group, percept, t)
        self.spawn_hypotheses(group, tuple_, t)

    def fission(self, percept: GaussianPercept, t: float) -> list[GaussianPercept]:
        """Split a bimodal Gaussian percept into two children, each modelling one cluster."""
        clusters = bimodal_clusters(
            percept.model.buffer, split_at=self.split_at, min_evidence=self.min_evidence, min_share=self.min_share
        )
        if clusters is None:
            return []
        children = []
        for cluster in clusters:
            self.grown += 1
            model = GaussianModel(
                float(cluster.mean()),
                max(float(cluster.std()), 1e-6),
                size=percept.model.size,
                prior_weight=percept.model.prior_weight,
            )
            children.append(
                GaussianPercept(
                    f"{percept.name}.{self.grown}", percept.state, model, parent=percept,
                    lookback=percept.lookback, mask_reach=percept.mask_reach,
                )
            )
        self._emit("fission", t, percept=percept.name, children=[c.name for c in children],
                   means=[c.model.mean for c in children])
        return children

    def fuse_if_merged(self, group: ActionGroup, percept: GaussianPercept, t: float) -> bool:
        """Fuse the Gaussian children of ``percept`` back when the split is no longer
        supported: either the parent's own buffer (which sees all the data) has stopped
        preferring two categories, or no pair of children is distinct any more."""
        kids = [c for c in percept.children if isinstance(c, GaussianPercept)]
        if len(kids) < 2:
            return False
        low, high = two_means_split(percept.model.buffer)
        split_gone = split_evidence(low, high) < 0.0
        alike = all(
            ashman_d(p.model.mean, p.model.std, q.model.mean, q.model.std) < self.fuse_below
            for p, q in itertools.combinations(kids, 2)
        )
        if not (split_gone or alike):
            return False
        for kid in kids:
            for tuple_ in [tp for tp in group.tuples if tp.trigger is kid]:
                group.remove(tuple_, t)
            percept.remove_child(kid)
        self._emit("fusion", t, percept=percept.name, children=[k.name for k in kids])
        return True

    def spawn_hypotheses(self, group: ActionGroup, tuple_: ActionTuple, t: float) -> list[ActionTuple]:
        """``child | Ac | Du | V`` for each child of the tuple's trigger that lacks one.

        Ac is shared (proximity 1, so credit flows between the hypotheses), Du is a fresh
        Do-until on the same duration (model) and until-percept, V is copied.
        """
        made = []
        for child in tuple_.trigger.children:
            if any(tp.trigger is child and tp.action is tuple_.action for tp in group.tuples):
                continue
            hypothesis = hypothesise(f"{child.name}|{tuple_.action.name}", child, tuple_)
            group.add(hypothesis)
            made.append(hypothesis)
            self._emit("hypothesis", t, tuple=hypothesis.name, parent=tuple_.name)
        return made

    def _emit(self, event: str, t: float, **fields: Any) -> None:
        if self.on_event is not None:
            self.on_event({"event": event, "t": t, **fields})
