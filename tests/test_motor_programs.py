"""Motor programs: the stack machine, sub-programs, forced moves and program graphs."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.motor import quaternion as quat
from creatures.motor.animations import creature_skeleton, example_animations
from creatures.motor.graph import MotorGraph
from creatures.motor.pose import PoseSet
from creatures.motor.programs import (
    MotorProgramGraph,
    MotorSystem,
    ProgramStack,
    ProgramSyntaxError,
    Statement,
    Status,
    parse_programs,
    replaced_courses,
    run,
)
from motor_fixtures import fastest_source_step

LEFT, RIGHT = "sway left", "sway right"


@pytest.fixture(scope="module")
def graph() -> MotorGraph:
    return MotorGraph.build(PoseSet.concatenate(example_animations(creature_skeleton())), k=5)


def arrived_labels(graph: MotorGraph, motor: MotorSystem) -> list[str]:
    """Which of the two sway extremes each completed course ended on."""
    out = []
    for _, node in motor.arrivals:
        tags = graph.poses.labels[node] & {LEFT, RIGHT}
        assert len(tags) == 1, "every course of the walk program ends on a labelled extreme"
        out.append(next(iter(tags)))
    return out


def merge_repeats(labels: list[str]) -> list[str]:
    return [x for k, x in enumerate(labels) if k == 0 or labels[k - 1] != x]


def test_biphasic_cycle_alternates(graph, clock):
    programs = parse_programs(f'walk: getToClosest {{"{LEFT}", "{RIGHT}"}}; wait; getToFurthest {{"{LEFT}", "{RIGHT}"}}; cycle')
    motor = MotorSystem(graph, start=int(graph.poses.labelled("reach")[10]))
    stack = ProgramStack(motor, programs["walk"])
    stack.start(clock.now())
    assert run(stack, clock, until=25.0) is Status.RUNNING  # a cycle never ends by itself
    visits = merge_repeats(arrived_labels(graph, motor))
    assert len(visits) >= 6
    assert all(a != b for a, b in zip(visits, visits[1:]))
    assert stack.cycles >= 3


def test_cycle_to_the_furthest_statement_alternates_every_arrival(graph, clock):
    text = f"""
    walk:
      getToClosest {{"{LEFT}", "{RIGHT}"}}; wait
      ↑ getToFurthest {{"{LEFT}", "{RIGHT}"}}; wait
      ↓ cycle 2
    """
    motor = MotorSystem(graph, start=0)
    stack = ProgramStack(motor, parse_programs(text)["walk"])
    stack.start(clock.now())
    run(stack, clock, until=20.0)
    visits = arrived_labels(graph, motor)
    assert len(visits) >= 6
    assert all(a != b for a, b in zip(visits, visits[1:]))


def test_sub_programs_and_forced_exit(graph, clock):
    text = """
    beg:
      getTo "strike"; wait
      getTo "strike ready"; wait
      forcedGetTo "low energy"; wait
      end
    perform:
      getTo beg; wait
      end
    """
    programs = parse_programs(text)
    motor = MotorSystem(graph, start=int(graph.poses.labelled("reach")[20]))
    stack = ProgramStack(motor, programs["perform"], library=programs)
    stack.start(clock.now())
    assert run(stack, clock, until=30.0) is Status.DONE
    labels = [graph.poses.labels[n] for _, n in motor.arrivals]
    assert "strike" in labels[0] and "strike ready" in labels[1] and "low energy" in labels[2]

    # Asked to stop early, the program still makes its forced move to a low-energy state.
    motor = MotorSystem(graph, start=int(graph.poses.labelled("reach")[20]))
    stack = ProgramStack(motor, programs["beg"], library=programs)
    stack.start(clock.now())
    stack.update(clock.now())
    stack.request_exit(clock.now())
    assert run(stack, clock, until=clock.now() + 30.0) is Status.DONE
    final = motor.arrivals[-1][1]
    assert "low energy" in graph.poses.labels[final]
    assert not any("strike ready" in graph.poses.labels[n] for _, n in motor.arrivals)


def test_program_graph_takes_the_nearer_branch_and_exits(graph, clock):
    program = MotorProgramGraph(
        "beg",
        {
            "start": Statement("getTo", ("strike",)),
            "w1": Statement("wait"),
            "left": Statement("getTo", (LEFT,)),
            "reach": Statement("getTo", ("reach",)),
            "w2": Statement("wait"),
            "exit": Statement("forcedGetTo", ("low energy",)),
            "w3": Statement("wait"),
        },
        {"start": ["w1"], "w1": ["left", "reach"], "left": ["w2"], "reach": ["w2"], "w2": ["exit"], "exit": ["w3"]},
    )
    motor = MotorSystem(graph, start=0)
    stack = ProgramStack(motor, program)
    stack.start(clock.now())
    assert run(stack, clock, until=30.0) is Status.DONE
    strike_node = motor.arrivals[0][1]
    chosen = motor.arrivals[1][1]
    cost_left = motor.finder.to_label(strike_node, LEFT).cost
    cost_reach = motor.finder.to_label(strike_node, "reach").cost
    expected = LEFT if cost_left < cost_reach else "reach"
    assert expected in graph.poses.labels[chosen]
    assert "low energy" in graph.poses.labels[motor.arrivals[-1][1]]
    # Asked to exit, flow follows the fewest-hop route to the "exit" vertex.
    assert program.exit_cursor("w2") == ("exit",)
    assert program.exit_cursor("start") == ("w1", "left", "w2", "exit")

    motor = MotorSystem(graph, start=0)
    stack = ProgramStack(motor, program)
    stack.start(clock.now())
    stack.update(clock.now())
    stack.request_exit(clock.now())
    assert run(stack, clock, until=clock.now() + 30.0) is Status.DONE
    assert "low energy" in graph.poses.labels[motor.arrivals[-1][1]]


def test_describe_shows_the_stack(graph, clock):
    programs = parse_programs('beg: getTo "strike"; wait\nperform: getTo beg; wait')
    stack = ProgramStack(MotorSystem(graph), programs["perform"], library=programs)
    stack.start(clock.now())
    stack.update(clock.now())
    assert stack.describe().splitlines() == ["perform: wait", "  beg: wait"]


def test_changing_course_mid_way_does_not_jump(graph, clock):
    motor = MotorSystem(graph, start=0)
    motor.set_course(clock.now(), motor.course(clock.now(), ["strike"]))
    frame = 1.0 / 60.0
    shown = []
    for k in range(40):
        if k == 17:  # the behaviour system changes its mind mid-course
            motor.set_course(clock.now(), motor.course(clock.now(), [LEFT]))
        shown.append(motor.pose(clock.now()).rotations)
        clock.advance(frame)
    steps = quat.angle_between(np.array(shown[1:]), np.array(shown[:-1])).max(axis=1)
    assert steps.max() < 1.25 * fastest_source_step(frame)
    # Across the switch the body keeps moving at the pace it had: no jump onto the new path.
    assert steps[16] < 2.0 * max(steps[14], steps[15])


@pytest.mark.parametrize(
    "text, message",
    [
        ('getTo "x"', r"<motor program>:1: statement .* before any 'name:' header"),
        ("walk:\n  fly away", r"<motor program>:2: unknown motor statement 'fly' \(known: getTo, "),
        ("walk:\n  wiat", r"<motor program>:2: unknown motor statement 'wiat' \(did you mean 'wait'\?\)"),
        ("walk:\n  getTo", r"<motor program>:2: 'getTo' needs a target"),
        ("walk:\n  wait 3", r"<motor program>:2: 'wait' takes no arguments"),
        ("walk:\n  getTo {a, b", r"<motor program>:2: unclosed target set"),
        ("walk:\n  wait; cycle 9", r"cycle 9 jumps outside it"),
    ],
)
def test_syntax_errors_name_the_line(text, message):
    with pytest.raises(ProgramSyntaxError, match=message):
        parse_programs(text)


def test_a_cycle_that_never_moves_is_reported(graph, clock):
    programs = parse_programs("spin: cycle")
    stack = ProgramStack(MotorSystem(graph), programs["spin"])
    stack.start(clock.now())
    with pytest.raises(RuntimeError, match="without the body moving"):
        stack.update(clock.now())


def test_a_program_at_its_target_holds_there_without_running_again(graph, clock):
    """``getTo "reach"; wait; cycle 0`` once at a reach pose: every course leads where the body
    rests. It spun to MAX_STEPS and raised (ending the run), logging an arrival per lap; now
    it holds, not run again each tick, until the body is moved, then it takes it back."""
    stack = ProgramStack(MotorSystem(graph, start=0), parse_programs('stay: getTo "reach"; wait; cycle 0')["stay"])
    motor = stack.motor
    stack.start(clock.now())
    assert run(stack, clock, until=10.0) is Status.RUNNING  # travelled there, then held
    assert len(motor.arrivals) == 1 and "reach" in graph.poses.labels[motor.arrivals[0][1]]
    held_at, ran = motor.resting(clock.now()), len(stack.trace)
    assert held_at is not None and stack.cycles >= 1
    for _ in range(30):  # held: no statement runs, no course is searched, the pose is the node's
        assert stack.update(clock.now()) is Status.RUNNING
        assert motor.pose(clock.now()).rotations == pytest.approx(graph.poses.pose(held_at).rotations)
        clock.advance(1.0 / 30.0)
    assert len(stack.trace) == ran and len(motor.arrivals) == 1
    elsewhere = int(graph.poses.labelled("strike")[0])  # another action moves the body
    motor.set_course(clock.now(), motor.course(clock.now(), [elsewhere]))
    run(stack, clock, until=clock.now() + 10.0)
    arrived = [node for _, node in motor.arrivals]
    assert len(arrived) == 3 and arrived[1] == elsewhere and "reach" in graph.poses.labels[arrived[2]]
    assert motor.resting(clock.now()) == arrived[2]  # back at its target, holding again
    stack.request_exit(clock.now())  # no forced statement: it ends
    assert stack.update(clock.now()) is Status.DONE


def test_a_course_to_where_the_body_rests_goes_nowhere(graph, clock):
    node = int(graph.poses.labelled("reach")[3])
    motor = MotorSystem(graph, start=node)
    motor.set_course(clock.now(), motor.course(clock.now(), ["reach"]))
    assert motor.playback is None and motor.arrived(clock.now()) and not motor.arrivals


def test_a_program_cycling_for_an_hour_keeps_a_bounded_trace(graph, clock):
    """A swaying program held for a gallery hour: the trace kept every statement run (4,391
    entries after an hour, growing for as long as the tuple ran); now the latest TRACE_KEPT."""
    stack = ProgramStack(MotorSystem(graph, start=0),
                         parse_programs(f'sway: getTo "{LEFT}"; wait; getTo "{RIGHT}"; wait; cycle 0')["sway"])
    stack.start(clock.now())
    assert run(stack, clock, until=3600.0, step=0.1) is Status.RUNNING
    assert stack.cycles > 500 and len(stack.trace) <= ProgramStack.TRACE_KEPT
    assert stack.trace[-1][0] > 3590.0  # the newest are the ones kept


def _sway_and_lunge(graph: MotorGraph) -> tuple[MotorSystem, ProgramStack, ProgramStack]:
    """One body, and two programs for it: a sway that cycles, a lunge that ends."""
    motor = MotorSystem(graph, start=0)
    sway = ProgramStack(motor, parse_programs(f'sway: getToClosest {{"{LEFT}"}}; wait; getTo "{RIGHT}"; wait; '
                                              "cycle 0")["sway"])
    lunge = ProgramStack(motor, parse_programs('lunge: getTo "strike ready"; wait; getTo "strike"; wait; end')["lunge"])
    return motor, sway, lunge


def test_a_program_gives_the_body_to_a_newer_one_and_takes_it_back_when_free(graph, clock):
    """One body, two programs: a sway cycling and a lunge begun later. The lunge's wait never
    arrived (the sway sent the body elsewhere each time it arrived) and it stayed unfinished; now
    the newer course has the body, the sway waits (paused), and sways on once the lunge ends."""
    motor, sway, lunge = _sway_and_lunge(graph)
    sway.start(clock.now())
    run(sway, clock, until=5.0)
    swayed = len(motor.arrivals)
    lunge.start(clock.now())
    ended = None
    while clock.now() < 20.0:
        sway.update(clock.now())
        if ended is None and lunge.update(clock.now()) is Status.DONE:
            ended = clock.now()
            assert sway.paused and sway.yields == 1
        clock.advance(1.0 / 30.0)
    assert ended is not None and ended < 10.0, "the lunge got the body and finished"
    labels = [graph.poses.labels[node] for _, node in motor.arrivals]
    assert any("strike" in tags for tags in labels)
    assert not sway.paused and len(motor.arrivals) - swayed >= 6  # swaying on after the lunge
    later = [tags & {LEFT, RIGHT} for at, node in motor.arrivals if at > ended
             for tags in [graph.poses.labels[node]]]
    assert later and all(later)


def test_a_program_stopped_gives_the_body_back_to_the_one_it_took_it_from(graph, clock):
    """A gesture's program (kinds/shaping.py) stopped mid-course kept the body: the sway beside
    it stayed paused until some other course came. Stopping a program gives the body up."""
    motor, sway, lunge = _sway_and_lunge(graph)
    sway.start(clock.now())
    run(sway, clock, until=3.0)
    lunge.start(clock.now())
    lunge.tick(clock.now())
    clock.advance(1.0 / 30.0)
    sway.tick(clock.now())
    assert sway.paused
    lunge.stop(clock.now(), interrupted=True)  # its tuple outbid, or its until ended
    before = len(motor.arrivals)
    run(sway, clock, until=30.0)
    assert not sway.paused and len(motor.arrivals) - before >= 4


@pytest.mark.parametrize(("text", "replaced"), [
    ('p: getTo "a"; getTo "b"; wait', "getTo {'a'} is followed by getTo {'b'}"),
    ('p: getToClosest {"a", "b"}; forcedGetTo "c"; wait', "getToClosest {'a', 'b'} is followed by forcedGetTo {'c'}"),
    ('p: getTo "a"; wait; getTo "b"; wait; cycle 0', None),
    ('p: getTo "a"; end', None),  # a course set last: the body goes on its way as the program ends
    ('p: getTo "a"; getTo q\nq: wait; getTo "b"; wait', None),  # a call: the callee says what comes first
])
def test_a_course_the_next_statement_replaces_at_once_is_found(text, replaced):
    """``getTo`` does not wait, so a course followed straight away by another is never followed."""
    problem = replaced_courses(parse_programs(text))
    assert (problem is None) if replaced is None else (replaced in problem and problem.startswith("program 'p'"))
