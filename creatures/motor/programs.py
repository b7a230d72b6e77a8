"""Motor programs: small programs that drive the body around the motor graph.

Thesis "towards a complete motor system: complex labels" and "motor program graphs".
A program is a list of statements run by a stack machine::

    walk:
      getToClosest {"sway left", "sway right"}; wait
      getToFurthest {"sway left", "sway right"}; wait
      cycle 2

``getTo`` sets a course (it does not block), ``wait`` blocks until the body arrives (or a
sub-program ends or cycles), ``cycle [n]`` waits for arrival then jumps to statement ``n``,
``end`` finishes. A target is a node label, a node index, or the name of another program,
which is then pushed on the stack ("a dynamic alias for other nodes"). ``forcedGetTo``
marks the statements that still run when the program is asked to exit (the "forced low
energy state" example).

A course followed at once by another (``getTo "low"; getTo "high"``: no ``wait`` between, in
the text or along a graph's edge) is refused at load (:func:`replaced_course`). The second
replaced the first in the same tick, so the body never set off for "low", and nothing said so;
an author writing "go low, then go high" means both. Refusing keeps the thesis's meaning of
``getTo`` (it sets a course and does not wait: ``getTo a; end`` leaves the body on its way, a
graph branches on where the body is headed) where an implied wait would change it for every
program, and the fix is one word the message gives. A call of another program is judged by
what the callee does: ``getTo a; getTo sub`` loses ``a`` when ``sub`` begins with a course, and
``getTo sub; getTo b`` loses the course ``sub`` ends on when it ends without a wait (it returns
in the same tick, and ``b`` replaces its last course); a callee that waits first, or last, is
left alone. A score's pattern generator (creatures/score/program.py) lays its ``getTo`` in
turn, and keeps that.

:class:`MotorProgramGraph` lays the same statements out as vertices: flow starts at the
vertex ``"start"``, takes at each branch the successor whose target is nearest in the
motor graph, and on exit heads for the nearest vertex ``"exit"``.

Every program runs under :class:`ProgramStack`, whose life cycle is the project's one
life cycle: ``start(t)``, ``update(t) -> Status``, ``done``.
"""

from __future__ import annotations

import enum
import re
from collections import deque
from dataclasses import dataclass, field
from graphlib import CycleError, TopologicalSorter
from typing import Callable, Mapping, Protocol, Sequence

import numpy as np

from creatures.clock import SimulatedClock
from creatures.config import nearest
from creatures.motor.graph import MotorGraph
from creatures.motor.playback import Playback
from creatures.motor.pose import BodyPose
from creatures.motor.search import GraphPosition, NoPath, Path, PathFinder

Target = str | int


class Status(enum.Enum):
    RUNNING = "running"
    DONE = "done"


class ProgramSyntaxError(ValueError):
    """A motor program text is malformed; the message names the source and line."""


# --- the body the programs move ---------------------------------------------------------


class MotorSystem:
    """The body on its motor graph: where it is, the course it is following, where it arrived.

    ``arrivals`` logs ``(time, node)`` each time a course completes; it is what tests and a
    BodyMemory read. Only the latest ``ARRIVALS_KEPT`` are kept: a body in a gallery arrives
    somewhere every few seconds for weeks (an unbounded list here was the leak the soak found).
    """

    ARRIVALS_KEPT = 256

    def __init__(self, graph: MotorGraph, *, start: int = 0, finder: PathFinder | None = None) -> None:
        self.graph = graph
        self.finder = finder or PathFinder(graph)
        self._rest = GraphPosition(start)
        self.playback: Playback | None = None
        self.arrivals: deque[tuple[float, int]] = deque(maxlen=self.ARRIVALS_KEPT)
        self.owner: object | None = None  # who set the course the body follows (None: no one who says)

    def position(self, t: float) -> GraphPosition:
        return self.playback.position(t) if self.playback else self._rest

    def pose(self, t: float) -> BodyPose:
        """Current BodyPose (interpolated when travelling)."""
        if self.playback:
            return self.playback.sample(t)
        return self.graph.poses.pose(self._rest.node)

    def arrived(self, t: float) -> bool:
        """True once the current course is complete (logging the arrival once)."""
        if self.playback is None:
            return True
        if not self.playback.done(t):
            return False
        node = int(self.playback.path.goal)
        self.arrivals.append((self.playback.end_time, node))
        self._rest = GraphPosition(node)
        self.playback = None
        return True

    def resting(self, t: float) -> int | None:
        """The node the body rests on at ``t``, or None while it travels."""
        return self._rest.node if self.arrived(t) else None

    def goals(self, target: Target) -> list[int]:
        """Nodes a target names: a node index or every node with that label."""
        if isinstance(target, (int, np.integer)):
            return [int(target)]
        nodes = self.graph.poses.labelled(target).tolist()
        if not nodes:
            raise NoPath(f"no node is labelled {target!r}")
        return nodes

    def course(self, t: float, targets: Sequence[Target], *, furthest: bool = False) -> Path:
        """Shortest path to the closest (or, per target, furthest) of ``targets``."""
        start = self.position(t)
        if not furthest:
            return self.finder.path(start, [n for target in targets for n in self.goals(target)])
        paths = [self.finder.path(start, self.goals(target)) for target in targets]
        return max(paths, key=lambda p: p.cost)

    def set_course(self, t: float, path: Path, *, owner: object | None = None) -> None:
        """Follow ``path`` from time ``t`` (it starts where the body is, even mid-edge), set by
        ``owner`` (a :class:`ProgramStack` says it is; anything else setting a course takes the
        body from it). A path to the node the body rests on goes nowhere: the body stays, and
        logs no arrival (a program holding at its target would fill :attr:`arrivals` with it)."""
        self.owner = owner
        if self.resting(t) == path.goal and len(path.nodes) == 1:
            return
        origin = None
        if self.playback is not None and not self.arrived(t):
            rotations, roots = self.playback.sample_rotations(np.array([t]))
            origin = (rotations[0], roots[0])
        self.playback = Playback(self.graph, path, t, origin=origin)


# --- statements -------------------------------------------------------------------------


@dataclass(frozen=True)
class Statement:
    """One motor-program statement: ``op`` with its targets (labels, nodes or programs)."""

    op: str
    targets: tuple[Target, ...] = ()
    jump: int = 0

    COURSES = ("getTo", "getToClosest", "getToFurthest", "forcedGetTo")
    OPS = (*COURSES, "wait", "cycle", "end")

    def __post_init__(self) -> None:
        if self.op not in self.OPS:
            raise ValueError(f"unknown motor statement {self.op!r}{nearest(self.op, self.OPS, 'known')}")

    @property
    def sets_course(self) -> bool:
        """Whether it sends the body somewhere (or calls a program, when a target names one)."""
        return self.op in self.COURSES

    def __str__(self) -> str:
        if self.op == "cycle":
            return f"cycle {self.jump}"
        names = ", ".join(repr(t) for t in self.targets)
        return self.op if not self.targets else f"{self.op} {{{names}}}"


class Program(Protocol):
    """What the stack machine needs of a program: where to begin, go next, and exit."""

    name: str

    def first(self) -> object: ...
    def statement(self, cursor: object) -> Statement: ...
    def advance(self, cursor: object, motor: MotorSystem, t: float) -> object | None: ...
    def exit_cursor(self, cursor: object) -> object | None: ...


@dataclass
class MotorProgram:
    """A linear motor program (the thesis's textual form)."""

    name: str
    statements: list[Statement]

    def first(self) -> int:
        return 0

    def statement(self, cursor: int) -> Statement:
        return self.statements[cursor] if cursor < len(self.statements) else Statement("end")

    def advance(self, cursor: int, motor: MotorSystem, t: float) -> int | None:
        stmt = self.statement(cursor)
        if stmt.op == "end":
            return None
        return stmt.jump if stmt.op == "cycle" else cursor + 1

    def exit_cursor(self, cursor: int) -> int | None:
        """Exiting skips to the next ``forcedGetTo`` (if any): forced moves still happen."""
        for index in range(cursor, len(self.statements)):
            if self.statements[index].op == "forcedGetTo":
                return index
        return None

    def __str__(self) -> str:
        return f"{self.name}:\n" + "\n".join(f"  {i}: {s}" for i, s in enumerate(self.statements))


@dataclass
class MotorProgramGraph:
    """Statements as vertices; flow from ``"start"``, exit towards the nearest ``"exit"``."""

    name: str
    vertices: dict[str, Statement]
    edges: dict[str, list[str]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        problem = start_problem(self.vertices) or edge_problem(self.vertices, self.edges)
        if problem:
            raise ValueError(f"motor program graph {self.name!r}: {problem}")

    def first(self) -> str:
        return "start"

    def statement(self, cursor: str | tuple[str, ...]) -> Statement:
        return self.vertices[cursor[0] if isinstance(cursor, tuple) else cursor]

    def advance(self, cursor: str | tuple[str, ...], motor: MotorSystem, t: float) -> str | tuple[str, ...] | None:
        """Take the successor whose target is nearest by path cost (statements without
        targets cost nothing); no successor ends the program. A tuple cursor is a route
        being followed to an exit."""
        if isinstance(cursor, tuple):
            if len(cursor) > 1:
                return cursor[1:]
            cursor = cursor[0]
        options = self.edges.get(cursor, [])
        if not options:
            return None
        labels = motor.graph.poses.every_label

        def cost(name: str) -> float:
            stmt = self.vertices[name]
            if not stmt.targets or any(isinstance(x, str) and x not in labels for x in stmt.targets):
                return 0.0
            try:
                return motor.course(t, stmt.targets).cost
            except NoPath:
                return float("inf")

        return min(options, key=cost)

    def exit_cursor(self, cursor: str | tuple[str, ...]) -> tuple[str, ...] | None:
        """The fewest-hop route from ``cursor`` to a vertex named ``exit…`` (cursor excluded)."""
        here = cursor[0] if isinstance(cursor, tuple) else cursor
        parents: dict[str, str | None] = {here: None}
        queue = deque([here])
        while queue:
            name = queue.popleft()
            if name.startswith("exit"):
                route = [name]
                while parents[route[-1]] is not None:
                    route.append(parents[route[-1]])
                route.reverse()
                return tuple(route[1:]) or (here,)
            for nxt in self.edges.get(name, []):
                if nxt not in parents:
                    parents[nxt] = name
                    queue.append(nxt)
        return None


def start_problem(vertices: dict[str, object]) -> str | None:
    """What is wrong with a program graph's vertices (a config names them before its edges)."""
    if "start" not in vertices:
        return f"needs a 'start' vertex{nearest('start', vertices, 'vertices')}"
    return None


def replaced_course(first: Statement, then: Statement, programs: Mapping[str, object] | None = None) -> str | None:
    """Why running ``then`` straight after ``first`` loses a course, or None: both set a course,
    so the second replaces the first in the same tick and the body never heads for the first's
    targets. A call of one of ``programs`` stands for the course the callee begins with (as
    ``then``) or ends on without a wait (as ``first``); a callee that waits there loses nothing."""
    last, first_via = _course_of(first, programs or {}, _closing)
    begun, then_via = _course_of(then, programs or {}, _opening)
    if last is None or begun is None:
        return None
    return (f"{first}{first_via} is followed by {then}{then_via} with no 'wait' between: a getTo does not wait, "
            f"so the second course replaces the first at once and the body never heads for "
            f"{', '.join(repr(x) for x in last.targets)}; put a wait between them to go to both in turn")


def _course_of(stmt: Statement, programs: Mapping[str, object],
               end: Callable[[MotorProgram], Statement | None]) -> tuple[Statement | None, str]:
    """The course ``stmt`` sets at that ``end`` of itself (a call: the callee's, followed through
    calls), and how to say it; None if it sets none there or where it leads cannot be told (a
    call among node targets, a program graph, a call of itself)."""
    seen: set[str] = set()
    via = ""
    while stmt.sets_course:
        called = [x for x in stmt.targets if isinstance(x, str) and x in programs]
        if not called:
            return stmt, via
        callee = programs[called[0]]
        if len(stmt.targets) > 1 or not isinstance(callee, MotorProgram) or callee.name in seen:
            return None, ""
        seen.add(callee.name)
        inner = end(callee)
        if inner is None:
            return None, ""
        via += f" (whose program {callee.name!r} {'ends on' if end is _closing else 'begins with'} {inner})"
        stmt = inner
    return None, ""


def _opening(program: MotorProgram) -> Statement | None:
    """The statement a linear program runs first."""
    return program.statements[0] if program.statements else None


def _closing(program: MotorProgram) -> Statement | None:
    """The statement a linear program runs last before it ends by running out (or reaching a
    final ``end``); None when it ends no other way (a ``cycle`` laps on)."""
    statements = program.statements[:-1] if program.statements and program.statements[-1].op == "end" else program.statements
    return statements[-1] if statements and statements[-1].op != "cycle" else None


def replaced_courses(programs: dict[str, MotorProgram]) -> str | None:
    """The first course in ``programs`` (a motor program text) that the next statement replaces
    at once (:func:`replaced_course`), as a sentence naming the program, or None."""
    for name, program in programs.items():
        for first, then in zip(program.statements, program.statements[1:]):
            problem = replaced_course(first, then, programs)
            if problem:
                return f"program {name!r}: {problem}"
    return None


def edge_problem(vertices: dict[str, Statement], edges: dict[str, list[str]]) -> str | None:
    """What is wrong with a program graph's edges, as a sentence naming the edge: an edge to a
    vertex that is not there, or a loop on which the body never gets to arrive."""
    for source, targets in edges.items():
        for name in (source, *targets):
            if name not in vertices:
                edge = f"edge {source} → {name}" if name != source else f"edges from {name}"
                return f"{edge}: unknown vertex {name!r}{nearest(name, vertices, 'vertices')}"
    free = [v for v, s in vertices.items() if s.op not in ("wait", "cycle")]  # "start" first
    loop = _loop({v: [w for w in edges.get(v, []) if w in free] for v in free})
    if loop:
        return (f"the loop {' → '.join(loop)} has no 'wait' (or 'cycle') vertex, so the body never gets to "
                f"arrive: flow went round it {ProgramStack.MAX_STEPS} times in one tick and stopped the run; "
                "put a wait on it")
    for source, targets in edges.items():
        for name in targets:
            problem = replaced_course(vertices[source], vertices[name])
            if problem:
                return f"edge {source} → {name}: {problem} (a wait vertex: {source} → wait → {name})"
    return None


def _loop(edges: dict[str, list[str]]) -> list[str]:
    """A loop in the directed graph ``edges`` (name → successors, every one a key), as
    ``[a, …, a]`` in the edges' direction, or [] when there is none (graphlib finds it: given
    successors as predecessors, it lists the loop backwards)."""
    try:
        TopologicalSorter(edges).prepare()
    except CycleError as exc:
        return exc.args[1][::-1]
    return []


# --- the stack machine ------------------------------------------------------------------


@dataclass
class _Frame:
    program: Program
    cursor: object


class ProgramStack:
    """Runs a program (and the sub-programs it calls) against a :class:`MotorSystem`.

    ``library`` maps names to programs so a target can name a program. ``cycles`` counts
    the root program's ``cycle`` statements; ``trace`` records the latest ``TRACE_KEPT``
    executed statements (a cycling program held for a gallery hour ran 4,391: an unbounded
    list grew for as long as the tuple ran).

    A body follows one course, and the newest claim has it. A program whose course another
    action has since replaced (a second program, a ``go_to``, a sung breath) gives the body
    up (:attr:`paused`, counted in :attr:`yields`) until it is free again — the other program
    ended, the other action's course arrived — and then takes it back, sending it again where
    it was going. It used to wait on regardless: for an arrival where the other had sent the
    body, which a program cycling beside it never let come (a lunge stayed active 25 s, its
    ``done`` never reached), or, the other gone, frozen where that one had left it.
    """

    MAX_STEPS = 256
    TRACE_KEPT = 256

    def __init__(self, motor: MotorSystem, program: Program, *, library: dict[str, Program] | None = None) -> None:
        self.motor = motor
        self.program = program
        self.library = dict(library or {})
        self.stack: list[_Frame] = []
        self.cycles = 0
        self.trace: deque[tuple[float, str, str]] = deque(maxlen=self.TRACE_KEPT)
        self._held: tuple[int, int] | None = None  # (node, graph size) a lap went nowhere from
        self._course: Statement | None = None  # the last course it set: set again when it takes the body back
        self.paused = False
        self.yields = 0

    @property
    def done(self) -> bool:
        return not self.stack

    def start(self, t: float) -> None:
        self.stack = [_Frame(self.program, self.program.first())]
        self._held = None
        self._course, self.paused = None, False

    def request_exit(self, t: float) -> None:
        """Unwind: each frame jumps to its forced statements (or exit vertex) or is dropped.

        The body finishes the course it is on; only the programs stop issuing new ones.
        """
        kept = []
        for frame in self.stack:
            cursor = frame.program.exit_cursor(frame.cursor)
            if cursor is not None:
                kept.append(_Frame(frame.program, cursor))
        self.stack = kept
        self._held = None

    def update(self, t: float) -> Status:
        """Run statements until one blocks (waiting for the body) or the program ends.

        A program whose courses all lead where the body rests (``getTo "sit"; wait; cycle 0``
        once sat) comes back to a statement it ran this tick: it holds there, the body at its
        target, and is not run again (its courses searched again) until the body is moved
        or the motor graph grows. Running on, it spun until :data:`MAX_STEPS` and raised,
        ending the run (thesis "motor program graphs": a program is a way of being, here
        one of staying). A program whose course another has replaced waits for the body."""
        if self._course is not None and self.stack and self.motor.owner is not self:
            if self.motor.owner is not None or not self.motor.arrived(t):  # another holds it
                self.yields += not self.paused
                self.paused = True
                return Status.RUNNING
            self.paused, self._held = False, None
            self._go(t, self._course)  # free again: back on the way it was going
        if self._held is not None and self._held == self._resting(t):
            return Status.RUNNING
        self._held = None
        seen: dict[tuple[int, object], int] = {}  # statements run this tick: how many courses had been set
        courses, frames = 0, []  # frames kept alive: their ids key ``seen``
        for _ in range(self.MAX_STEPS):
            if not self.stack:
                self.release()
                return Status.DONE
            frame = self.stack[-1]
            stmt = frame.program.statement(frame.cursor)
            if stmt.op in ("wait", "cycle") and not self.motor.arrived(t):
                return Status.RUNNING
            here = (id(frame), frame.cursor)
            if seen.get(here, courses) < courses and self._resting(t) is not None:  # a lap went nowhere
                self._held = self._resting(t)
                return Status.RUNNING
            seen[here] = courses
            frames.append(frame)
            self.trace.append((t, frame.program.name, str(stmt)))
            nxt = frame.program.advance(frame.cursor, self.motor, t)
            callee = self._callee(stmt)
            if nxt is None:
                self.stack.pop()
            else:
                frame.cursor = nxt
            if callee is not None:
                self.stack.append(_Frame(callee, callee.first()))
            elif stmt.sets_course:
                self._go(t, stmt)
                courses += 1
            elif stmt.op == "cycle" and nxt is not None:
                if len(self.stack) > 1:
                    # A sub-program that cycles hands control back to its caller's wait.
                    self.stack.pop()
                else:
                    self.cycles += 1
        raise RuntimeError(
            f"motor program {self.stack[-1].program.name!r} ran {self.MAX_STEPS} statements"
            " without the body moving (a cycle with no course to follow?)"
        )

    def tick(self, t: float) -> None:
        """:meth:`update` for an action's tick: a program with nowhere to go from here is over
        (and gives the body up)."""
        try:
            self.update(t)
        except NoPath:
            self.stack.clear()
            self.release()

    def stop(self, t: float, *, interrupted: bool) -> None:
        """Its action stopped: an interrupted program unwinds (:meth:`request_exit`), and either
        way gives the body up, so a program waiting for it takes it back. An action that kept
        the body when it stopped left the one beside it paused until some other course came."""
        if interrupted:
            self.request_exit(t)
        self.release()

    def _go(self, t: float, stmt: Statement) -> None:
        """Set the course ``stmt`` (a ``getTo``-style statement) names, as this program's."""
        self.motor.set_course(t, self.motor.course(t, stmt.targets, furthest=stmt.op == "getToFurthest"), owner=self)
        self._course = stmt

    def release(self) -> None:
        """Give the body up (the program ended, or its tuple stopped): a program waiting for it
        takes it once its course has arrived."""
        if self.motor.owner is self:
            self.motor.owner = None

    def _resting(self, t: float) -> tuple[int, int] | None:
        """Where the body rests (its node, and the motor graph's size: a graph grown since
        may offer a nearer target), or None while it travels."""
        node = self.motor.resting(t)
        return None if node is None else (node, len(self.motor.graph))

    def _callee(self, stmt: Statement) -> Program | None:
        """The sub-program a ``getTo``-style statement names, if it names one."""
        if stmt.op not in ("getTo", "forcedGetTo"):
            return None
        names = [x for x in stmt.targets if isinstance(x, str) and x in self.library]
        return self.library[names[0]] if names else None

    def describe(self) -> str:
        """What the creature's body is doing, one line per stack frame (for debugging)."""
        return "\n".join(
            f"{'  ' * depth}{frame.program.name}: {frame.program.statement(frame.cursor)}"
            for depth, frame in enumerate(self.stack)
        ) or "(idle)"


# --- the textual language ---------------------------------------------------------------

_STATEMENT = re.compile(r"^(?P<op>[A-Za-z]+)\s*(?P<args>.*)$")
_TARGET = re.compile(r'"([^"]*)"|([^,\s{}"]+)')


def _parse_targets(args: str) -> tuple[Target, ...]:
    inner = args.strip()
    if inner.startswith("{"):
        if not inner.endswith("}"):
            raise ValueError(f"unclosed target set {inner!r}")
        inner = inner[1:-1]
    targets: list[Target] = []
    for quoted, bare in _TARGET.findall(inner):
        if quoted:
            targets.append(quoted)
        else:
            targets.append(int(bare) if bare.lstrip("-").isdigit() else bare)
    return tuple(targets)


def chosen_program(text: str, run: str | None, *, source: str) -> tuple[dict[str, MotorProgram], str]:
    """The programs of ``text`` and the name of the one that runs (``run``, default the first);
    a ValueError (a ProgramSyntaxError among them) says what is wrong: a config's parameters
    validate with it."""
    programs = parse_programs(text, source=source)
    if not programs:
        raise ValueError("the text holds no 'name:' program")
    if run is not None and run not in programs:
        raise ValueError(f"no program {run!r} in the text (programs: {sorted(programs)})")
    loop = _loop({name: [x for s in p.statements for x in s.targets if x in programs] for name, p in programs.items()})
    if loop:
        raise ValueError(f"program {loop[0]!r} calls itself ({' → '.join(loop)}): a call returns only when the "
                         "called program ends, so the calls pile up on the stack, one more each lap (or "
                         f"{ProgramStack.MAX_STEPS} in one tick, stopping the run); repeat with 'cycle n'")
    return programs, run or next(iter(programs))


def parse_statement(text: str) -> Statement:
    """One statement (``getTo "reach"``, ``wait``, ``cycle 2`` …); a ValueError says what is wrong."""
    match = _STATEMENT.match(text.strip())
    if match is None:
        raise ValueError(f"cannot read {text!r}")
    op, args = match.group("op"), match.group("args")
    if op == "cycle":
        return Statement("cycle", jump=int(args or 0))
    if op in ("wait", "end") and args.strip():
        raise ValueError(f"{op!r} takes no arguments")
    targets = _parse_targets(args) if args.strip() else ()
    if op.startswith(("getTo", "forcedGetTo")) and not targets:
        raise ValueError(f"{op!r} needs a target")
    return Statement(op, targets)


def parse_programs(text: str, *, source: str = "<motor program>") -> dict[str, MotorProgram]:
    """Parse ``name: statements`` blocks (``;`` or newlines between statements).

    The thesis's loop marks ``↑ | ↓`` are accepted and ignored; ``cycle n`` says where the
    loop starts. Errors name ``source`` and the line.
    """
    programs: dict[str, MotorProgram] = {}
    current: MotorProgram | None = None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        header = re.match(r"^([\w -]+):(.*)$", line)
        if header and not header.group(1).strip().startswith(Statement.OPS):
            current = MotorProgram(header.group(1).strip(), [])
            programs[current.name] = current
            line = header.group(2)
        for part in line.split(";"):
            part = part.strip().lstrip("↑|↓ ").strip()
            if not part:
                continue
            if current is None:
                raise ProgramSyntaxError(f"{source}:{number}: statement {part!r} before any 'name:' header")
            try:
                current.statements.append(parse_statement(part))
            except ValueError as exc:
                raise ProgramSyntaxError(f"{source}:{number}: {exc}") from None
    for program in programs.values():
        for stmt in program.statements:
            if stmt.op == "cycle" and not 0 <= stmt.jump < len(program.statements):
                raise ProgramSyntaxError(f"{source}: program {program.name!r}: cycle {stmt.jump} jumps outside it")
    return programs


def run(stack: ProgramStack, clock: SimulatedClock, *, until: float, step: float = 1.0 / 30.0) -> Status:
    """Drive a program stack from a simulated clock until ``until`` seconds or it is done."""
    status = Status.RUNNING
    while clock.now() < until and status is Status.RUNNING:
        status = stack.update(clock.now())
        clock.advance(step)
    return status
