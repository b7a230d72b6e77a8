"""The schema of ``kind = "authored"``: a creature's drives, percepts, tuples, groups and
learning, as the config writes them.

Types and ranges are checked by pydantic; names are checked afterwards by
:mod:`creatures.authored.check` against the registries and against each other, so every
error names file, key and line.
"""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationInfo, field_validator, model_validator

from creatures.bounds import FINITE, LARGEST_RATE, LONGEST_SECONDS, Bounded, Seconds

from creatures.kinds.base import CreatureSpec, built_once
from creatures.kinds.figures import FigureBodySpec
from creatures.kinds.hearing_parts import HearingSpec, MouthSpec
from creatures.kinds.note_world import SpaceSpec
from creatures.kinds.parts import VOICE_READ_ONCE, VoiceSpec
from creatures.score.spec import ScoreSpec


class Strict(BaseModel):
    model_config = FINITE


class DriveSpec(Strict):
    """``[creature.drives.NAME]`` — one motivation of the synthetic chemistry (thesis "soft state")."""

    level: float = Field(0.0, ge=-LARGEST_RATE, le=LARGEST_RATE, description="starting level")
    growth: float = Field(0.0, ge=-LARGEST_RATE, le=LARGEST_RATE, description="per-second growth r")
    decay: float = Field(0.0, ge=0, le=LARGEST_RATE, description="per-second decay D toward the equilibrium")
    equilibrium: float | None = Field(None, ge=-LARGEST_RATE, le=LARGEST_RATE, description="level decay returns to; none = the starting level")
    coupling: dict[str, Bounded] = Field(default_factory=dict, max_length=256,
                                       description="other drive → rate it feeds this one (C[this, other])")
    inputs: dict[str, Bounded] = Field(default_factory=dict, max_length=256,
                                     description="percept → rate fed per second per unit of its saliency")
    on_heard: float = Field(0.0, ge=-LARGEST_RATE, le=LARGEST_RATE, description="impulse per note heard")
    on_played: float = Field(0.0, ge=-LARGEST_RATE, le=LARGEST_RATE, description="impulse per note the creature plays itself")
    arc: list[tuple[Seconds, Bounded]] = Field(default_factory=list, max_length=4096,
                                           description="scripted arc: [seconds, input rate] points, linear "
                                                       "between them, held after the last")

    arc_repeat: Seconds | None = Field(None, gt=0, description="seconds after which the arc starts again from its "
                                                               "first point: a cycle that waxes and wanes for as "
                                                               "long as the run lasts (thesis 'exchange': 'script "
                                                               "this linkage over time to create a waxing and "
                                                               "waning of a creature's musical complexity'); none "
                                                               "= held after the last point")

    @field_validator("arc")
    @classmethod
    def _in_time_order(cls, arc: list[tuple[float, float]]) -> list[tuple[float, float]]:
        if any(b[0] <= a[0] for a, b in zip(arc, arc[1:])):
            raise ValueError("arc points must be in increasing time order")
        return arc

    @model_validator(mode="after")
    def _cycle(self) -> "DriveSpec":
        if self.arc_repeat is not None and (not self.arc or self.arc[-1][0] > self.arc_repeat):
            raise ValueError(f"arc_repeat ({self.arc_repeat:g} s) repeats an arc: give 'arc' points, the last at "
                             "or before it")
        return self


class PerceptSpec(Strict):
    """``[creature.percepts.NAME]`` — a percept: ``type`` picks one of the percept library."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False)
    type: str = Field(description="percept type (see docs/authoring.md, 'Percepts')")
    parent: str = Field("whatever", description="parent in the percept tree (the root is 'whatever')")

    def params(self) -> dict[str, Any]:
        return dict(self.model_extra or {})


class PartSpec(Strict):
    """An action or model by ``type`` with its own keys."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False)
    type: str = Field(description="a name from the library")

    def params(self) -> dict[str, Any]:
        return dict(self.model_extra or {})


class UntilSpec(Strict):
    """Du: when an active tuple is done (thesis "the action-tuple", "temporal models"). Any
    combination; the tuple stops when the first says so."""

    seconds: float | None = Field(None, gt=0, le=LONGEST_SECONDS, description="fixed duration")
    gaussian: tuple[Seconds, Seconds] | None = Field(None, description="[mean, std] seconds, learnt from each activation")
    pulse: int | None = Field(None, ge=1, le=64, description="durations of the colony's heard pulse (low-integer "
                                                          "ratios); with 'gaussian', that is the fallback until "
                                                          "the pulse is trusted")
    model: PartSpec | None = Field(None, description="a duration model from the library by 'type' (see 'Models')")
    percept: str | None = Field(None, description="until this percept is salient")
    done: bool = Field(False, description="until the action says it is finished (a phrase played out)")
    follow: bool = Field(False, description="forward transition model: record what follows, prime likely "
                                            "successors (thesis 'forward transition models')")
    follow_as: str | None = Field(None, min_length=1, max_length=256,
                                  description="follow: the name its activations are recorded and primed under "
                                              "(default: the tuple's own); a perception tuple hearing phrase 'a' "
                                              "and a tuple playing it both say 'a', so what is heard primes what "
                                              "is played")
    record: bool = Field(True, description="follow: teach the model this tuple's starts (false: only primed by "
                                           "it, e.g. a colony that walks the order its perception tuples heard; "
                                           "thesis 'perception as action')")
    priming: float = Field(1.0, ge=0, le=16, description="follow: the trigger × (N·p(last → this))^priming: 0 "
                                                        "ignores the model, 1 weighs by the transition "
                                                        "probability itself, more sharpens it")
    graded: bool = Field(False, description="Du ramps from 0 to 1 over the planned duration instead of stepping, "
                                            "so the running tuple's expected value (1 − Du)·V declines as its time "
                                            "runs out and an interruption competes with what is left (thesis "
                                            "'computing expected values')")
    fresh: bool = Field(False, description="the percept counts only once it has fallen below 1 since the start: "
                                           "'until the next onset', not the onset that started the tuple")


class ValueSpec(Strict):
    """V: what the tuple is worth (thesis "computing expected values", "value chaining",
    "emotional tags")."""

    value: float = Field(1.0, ge=-LARGEST_RATE, le=LARGEST_RATE, description="the starting value")
    kind: Literal["scalar", "chain", "gaussian", "stance"] = Field("scalar", description="value type")
    plastic: bool = Field(True, description="credit assignment may change it (false: a grounding reward)")
    plasticity: float | None = Field(None, ge=0, le=1, description="how much of each credit assignment's blend "
                                     "reaches it (1: all; a small share, a value that learns slowly: thesis "
                                     "'what is value?', an innate value 'with a far lower plasticity')")
    source: str | None = Field(None, description="chain: this tuple is a goal (distance 0 from itself)")
    serves: dict[str, str] = Field(default_factory=dict,
                                   description="chain: goal source → drive whose level is its importance")
    spread: float = Field(1.0, gt=0, le=LARGEST_RATE, description="gaussian: prior spread of the incoming values")
    leak: float = Field(0.0, ge=0, le=LARGEST_RATE, description="per second: value leaks out toward 'rest' "
                                                                "(thesis 'value signal processing')")
    rest: float = Field(0.0, ge=-LARGEST_RATE, le=LARGEST_RATE, description="leak: the value it leaks toward")
    momentum: float = Field(0.0, ge=0, lt=1, description="credit assignment keeps this share of the last change "
                                                         "going (thesis 'value signal processing')")
    stance: float | None = Field(None, ge=-1, le=1, description="stance: its emotional tag, −1 (run away) to 1 "
                                                                "(glad), blended by credit assignment toward "
                                                                "the stance of the stance values that follow; "
                                                                "each start pulls the [creature.mood] drive "
                                                                "toward it (thesis 'emotional tags')")


class TupleSpec(Strict):
    """``[creature.tuples.NAME]`` — Tr | Ac | Du | V."""

    trigger: str = Field("whatever", description="Tr: a percept name")
    action: str | PartSpec = Field(description="Ac: an action name or a table with its 'type' and keys")
    until: UntilSpec = Field(description="Du")
    value: Bounded | ValueSpec = Field(1.0, description="V: a number or a table")


class ConstraintSpec(Strict):
    """An interval relation between two tuples (thesis "temporal logics": all thirteen of
    Allen's relations, made by gating Tr and Du): a's activations stand in ``relation`` to b's.
    Where the constraint gates a tuple's start on the other's start or end in the same tick
    (meets, starts, equals and their inverses), put the gated tuple in a group that ticks
    after the other's (a later top-level group)."""

    relation: Literal["before", "after", "meets", "met_by", "overlaps", "overlapped_by", "starts", "started_by",
                      "during", "contains", "finishes", "finished_by", "equals"] = Field(
        description="Allen relation of a to b")
    a: str = Field(description="first tuple")
    b: str = Field(description="second tuple")
    gap: float = Field(0.0, ge=0, le=LONGEST_SECONDS, description="before/after: seconds between the earlier one's "
                                                                  "end and the later one's start")

    @model_validator(mode="after")
    def _gap(self):
        if self.gap and self.relation not in ("before", "after"):
            raise ValueError(f"'gap' is for 'before' and 'after', not {self.relation!r}")
        return self


class ProximityLearningSpec(Strict):
    """``proximity_learning`` of a group: learn how reliably one tuple precedes another's reward
    (thesis "credit assignment": proximities "somewhere between 0 and 1")."""

    rate: float = Field(0.1, gt=0, le=1, description="how far each rewarded activation moves a proximity toward "
                                                     "whether the other tuple preceded it")
    window: float = Field(5.0, gt=0, le=10, description="seconds before a rewarded activation began in which the "
                                                        "other tuple counts as preceding it")


class GroupSpec(Strict):
    """``[creature.groups.NAME]`` — an action-group (thesis "the action-group", "hierarchical
    action-groups"). A group named among another group's members becomes one of its tuples."""

    tuples: list[str] = Field(min_length=1, max_length=1024, description="members: tuple names, or other groups' names")
    max_active: int = Field(1, ge=1, le=64, description="tuples active at once")
    temperature: float | None = Field(None, gt=0, le=1e3, description="Boltzmann temperature; none = ∝ expected value")
    alpha: float = Field(0.1, ge=0, le=1, description="credit assignment rate α (0 = values as authored)")
    discount: float = Field(0.8, ge=0, le=1, description="credit discount β")
    multiple: float = Field(1.5, ge=1, le=1e3, description="interruption hysteresis")
    innovation: float | None = Field(0.25, ge=0, le=LARGEST_RATE, description="value gap for forward-transition fission "
                                                              "(tuples with until.follow): a tuple A splits off 'A→B' "
                                                              "once per successor B, and a split-off tuple never "
                                                              "splits again, so N tuples grow at most N² (thesis "
                                                              "'forward transition models'); none = never")
    succession: str | None = Field(None, min_length=1, max_length=256,
                                   description="the colony's forward transition model of this name: the group's "
                                               "until.follow tuples record into, and are primed by, one model "
                                               "every creature's groups of that name share (no fission: a "
                                               "sub-hypothesis would belong to one creature); none = the "
                                               "group's own")
    constraints: list[ConstraintSpec] = Field(default_factory=list, max_length=1024, description="interval relations")
    heat: dict[str, Bounded] = Field(default_factory=dict, max_length=64,
                                     description="drive → gain: the temperature is temperature × (1 + Σ gain × "
                                                 "level), so a creature curious for sound explores its repertoire "
                                                 "rather than exploiting its best song")
    trigger: str = Field("whatever", description="as a member of another group: its Tr")
    value: float = Field(1.0, ge=-LARGEST_RATE, le=LARGEST_RATE, description="as a member of another group: its V")
    proximity: dict[str, dict[str, Annotated[float, Field(ge=0, le=1)]]] = Field(
        default_factory=dict, max_length=1024,
        description="credited tuple → {other tuple → proximity in [0, 1]}: how much of the credit one earns also "
                    "reaches the other (default 1 for the same action, 0 otherwise; thesis 'credit assignment')")
    proximity_learning: ProximityLearningSpec | None = Field(
        None, description="learn the proximities not fixed by complex shaping from what precedes rewards "
                          "(none: as written)")
    perception: bool = Field(False, description="a group of perception actions (thesis 'perception as action'): "
                                                "not mutually exclusive, every member whose Tr is salient is "
                                                "active at once (max_active = its size)")


class ExpectationSpec(Strict):
    """``[creature.expectations]`` — surprise and confidence (thesis "expectations about value",
    "expectations about the consequences of actions"): each tuple of the named groups expects
    its Du's end and, with ``value.kind = "gaussian"``, the values that follow it."""

    groups: list[str] = Field(default_factory=list, max_length=256, description="groups whose tuples keep expectations")
    tolerance: float = Field(0.25, gt=0, le=1, description="violation p = 1 − Du.evaluate(end) at or above this "
                                                           "is surprising")
    grace: float = Field(0.25, ge=0, le=10, description="× the planned duration the until-percept may come late")
    reliance: float = Field(0.2, gt=0, le=1, description="rate of the confidence's average of hits")
    memory: float = Field(600.0, gt=0, le=LONGEST_SECONDS, description="seconds untested over which confidence "
                                                                       "fades by 1/e")
    rigidity: float = Field(0.5, ge=0, le=1, description="credit rate × (1 − rigidity × confidence): confident "
                                                         "values change slower")
    confident: float = Field(0.5, ge=0, le=1, description="confidence at which a violated expectation reviews "
                                                          "the tuple's trigger for fission (its group in "
                                                          "learning.groups)")
    fission: bool = Field(True, description="a confident expectation violated may split the trigger percept")
    decay: float = Field(1.0, gt=0, le=LONGEST_SECONDS, description="seconds a surprise stays salient as a percept")
    transitions: bool = Field(False, description="forward transition models are expectations too: a tuple with "
                                                 "until.follow starting less likely than chance after the one "
                                                 "before it violates that one's expectation, p = 1 − N·p(last → "
                                                 "it) (thesis 'expectations about the consequences of actions': "
                                                 "surprise at 'an unexpected action')")


class MoodSpec(Strict):
    """``[creature.mood]`` — the character-wide emotional state that ``kind = "stance"`` values
    perturb (thesis "emotional tags"): one of the creature's drives, pulled toward a tuple's
    stance each time the tuple becomes active; its decay returns it to its equilibrium."""

    drive: str = Field(description="the drive that is the mood")
    strength: float = Field(0.25, gt=0, le=1, description="how far each start moves the mood toward the tuple's "
                                                          "stance (1: all the way)")


class PhraseHypotheses(Strict):
    """``[creature.learning.phrases]`` — a new hypothesis tuple for every phrase heard
    (thesis "percept trees": a new distinction lets the group try a new action-tuple)."""

    group: str = Field(description="the group the new tuples join")
    trigger: str = Field("whatever", description="their Tr")
    action: str = Field("play_learned", description="an action with a 'phrase' key")
    until: UntilSpec = Field(UntilSpec(done=True), description="their Du")
    value: float = Field(1.0, ge=-LARGEST_RATE, le=LARGEST_RATE, description="their starting V (plastic)")
    min_notes: int = Field(3, ge=1, le=1024, description="shorter phrases are not learnt")


class LearningSpec(Strict):
    """``[creature.learning]`` — value-driven model updates and percept-tree growth."""

    groups: list[str] = Field(default_factory=list, max_length=256, description="groups whose credit teaches their percept "
                                                                "models (fission/fusion of Gaussian percepts)")
    statistics: float = Field(1.0, ge=0, le=1e3, description="× mean value a tuple must exceed to teach its models")
    innovation: float = Field(1.5, ge=0, le=1e3, description="× mean value above which its percept may split")
    split_at: float = Field(2.0, gt=0, le=1e3, description="Ashman's D that splits a percept")
    fuse_below: float = Field(1.0, ge=0, le=1e3, description="Ashman's D below which children fuse")
    aural: list[str] = Field(default_factory=list, max_length=256,
                             description="groups whose credit grows the 'utterance' percept's tree: fission into "
                                         "sound classes, and new tuples triggered by each class and singing each "
                                         "(thesis 'aural Ac percept trees')")
    refine: bool = Field(False, description="aural groups: a tuple singing a class that has split gives way to the "
                                            "tuples singing its children, which inherit its review of the class and "
                                            "give its later classes tuples too (thesis 'aural Ac percept trees': "
                                            "tuples 'slowly refine what it is that they should be playing')")
    in_kind: bool = Field(False, description="aural groups: a tuple whose Tr and Ac are one 'utterance' percept (it "
                                             "answers a sound by singing one) gets, for each class of it, a tuple "
                                             "triggered by the class and singing the class: an answer in kind "
                                             "(with refine it gives way to them; thesis 'soundcreatures': one tree "
                                             "'shared in both Tr and Ac areas')")
    min_trigger: float = Field(0.1, ge=0, le=1, description="saliency a trigger must have had for its percept to learn")
    phrase_gap: float = Field(2.0, gt=0, le=3600, description="seconds of silence that end a heard phrase")
    max_phrases: int = Field(8, ge=1, le=256, description="phrases remembered")
    phrases: PhraseHypotheses | None = Field(None, description="a new tuple for every phrase heard "
                                                                "([creature.learning.phrases])")

    @field_validator("innovation")
    @classmethod
    def _innovation_above_statistics(cls, innovation: float, info: ValidationInfo) -> float:
        """A percept may split only once its tuple's value has taught it (PerceptLearning)."""
        statistics = info.data.get("statistics")
        if statistics is not None and innovation < statistics:
            raise ValueError(f"must not be below statistics ({statistics:g}): a percept may split only once "
                             "its tuple is worth enough to teach it")
        return innovation

    @field_validator("fuse_below")
    @classmethod
    def _fuse_below_split(cls, fuse_below: float, info: ValidationInfo) -> float:
        """Fission and fusion need a gap between them, or children would fuse as they split."""
        split_at = info.data.get("split_at")
        if split_at is not None and fuse_below >= split_at:
            raise ValueError(f"must be below split_at ({split_at:g}): between them lies the hysteresis that "
                             "keeps children from fusing as soon as they split")
        return fuse_below


class AuthoredSpec(CreatureSpec):
    kind: Literal["authored"]
    drives: dict[str, DriveSpec] = Field(default_factory=dict, max_length=256, description="drives by name: [creature.drives.NAME] "
                                                                           "(docs/authoring.md, 'Reference')")
    drive_floor: float | None = Field(0.0, ge=-LARGEST_RATE, le=LARGEST_RATE, description="lowest level of any drive; none = -1e6 (the range a saved level loads in)")
    drive_ceiling: float | None = Field(None, ge=-LARGEST_RATE, le=LARGEST_RATE, description="highest level of any drive; none = 1e6 (the range a saved level loads in)")
    percepts: dict[str, PerceptSpec] = Field(default_factory=dict, description="percepts by name: "
                                                                               "[creature.percepts.NAME]")
    tuples: dict[str, TupleSpec] = Field(default_factory=dict, description="action-tuples by name: "
                                                                           "[creature.tuples.NAME]")
    groups: dict[str, GroupSpec] = Field(min_length=1, max_length=256, description="action-groups by name: [creature.groups.NAME]; "
                                                                   "a group named in no other group is ticked "
                                                                   "by the creature")
    learning: LearningSpec = LearningSpec()
    expectations: ExpectationSpec = ExpectationSpec()
    mood: MoodSpec | None = Field(None, description="the drive stance values perturb ([creature.mood]; thesis "
                                                    "'emotional tags')")
    hears_input: bool = Field(True, description="hear notes from outside the colony")
    body: FigureBodySpec | bool = Field(False, description="a body on a motor graph; motor actions need it. "
                                                           "true: the stick figure (sway, reach, strike); a "
                                                           "[creature.body] table picks a shipped figure (dog, "
                                                           "bird) or a body of its own from files (docs/bodies.md)")
    ratio_metric: bool = Field(False, description="its body's graph favours moves at low-integer ratios of the "
                                                  "source animation length (exchange's metric)")
    space: SpaceSpec | None = Field(None, description="heard notes placed in space for the hand to strike "
                                                      "([creature.space]; needs body = true)")
    score: ScoreSpec | None = Field(None, description="a score of precomposed tiles laid out just in time, which "
                                                      "'score' actions steer ([creature.score]; thesis '(void *)')")
    body_rate: float | None = Field(None, gt=0, le=1000, description="body poses per second (forward kinematics "
                                                                      "is the costliest per-tick work); none = "
                                                                      "every tick")
    hearing: HearingSpec | None = Field(None, description="a microphone-as-ear: sound cut into utterances for "
                                                          "'utterance' percepts ([creature.hearing]); its mouth "
                                                          "sings them back")
    mouth: MouthSpec = Field(MouthSpec(), description="how the body shapes what it sings ([creature.mouth]; with "
                                                      "hearing)")
    report_every: float = Field(0.5, gt=0, le=3600, description="seconds between value, drive and motor snapshots in "
                                                                "the events log (a body's blend: who drives each joint)")
    soft_rate: float | None = Field(None, gt=0, le=1000, description="steps per second of the soft state: drive "
                                                                    "inputs and every choice (a new tuple, an "
                                                                    "interruption) run at this rate, since every "
                                                                    "trigger reads soft state; a running tuple acts "
                                                                    "and ends every tick; none = every tick")
    report_percepts: list[str] = Field(default_factory=list, max_length=256,
                                       description="percepts whose saliency each snapshot logs (a 'percepts' event "
                                                   "with their 'levels')")
    voice: VoiceSpec = VoiceSpec()
    modulate: dict[str, dict[str, Annotated[float, Field(ge=-LARGEST_RATE, le=LARGEST_RATE)]]] = Field(
        default_factory=dict, description="voice parameters modulated directly by percepts, no action between "
                                          "(thesis 'sand:stone': 'timbre is modulated directly by the boredom "
                                          "model'): [creature.modulate] \"voice.cutoff\" = { bored = -0.8 } adds "
                                          "weight × saliency to the parameter (and to what skills set), each block")
    READ_ONCE: ClassVar[dict[str, str]] = {
        **CreatureSpec.READ_ONCE, **VOICE_READ_ONCE,
        **built_once("drives", "drive_floor", "drive_ceiling", "percepts", "tuples", "groups", "body",
                     "ratio_metric", "space", "score", "hearing", "mouth", "expectations", "mood", "modulate")}
    """What :class:`~creatures.authored.creature.Authored` builds its parts from when it starts
    (its motivation, percepts, tuples, groups, body …) and its voice's strings: a console ``set``
    there was answered and changed nothing, or left the spec naming drives the creature does not have."""
    _file: Path | None = PrivateAttr(None)

    def check_references(self, file: Path, where: dict, prefix: tuple) -> list[str]:
        """Resolve every name (called by the loader with the config's key lines); return what
        runs but may be a mistake (the loader's notes)."""
        from creatures.authored.check import check

        self._file = where.get(prefix, (file, 0))[0]
        return check(self, file, where, prefix)

    def source_file(self) -> Path:
        """The config file this creature was written in (for errors found while building it)."""
        return self._file or Path("<config>")
