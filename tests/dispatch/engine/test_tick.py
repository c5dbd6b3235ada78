"""Table-driven tick scenarios: a tree, leaf results applied one by one, the expected status sequence.

Each step is (leaf results written before the tick, mission state, current_node, some node states after
the tick). The driver starts every newly selected leaf (PENDING -> RUNNING) as a worker would, and checks
on every tick that the input is not modified and that ticking again without news changes nothing.
The scenarios named "reference" reproduce the status sequences of the reference's mission_tree tests.
"""

import pytest

from dispatch.engine import ROOT

from .trees import (
    CANCELED,
    COMPLETED,
    FAILED,
    PENDING,
    RUNNING,
    action,
    constant,
    move,
    notify,
    play,
    route,
    selector,
    sequence,
)

CASES = [
    # --- flat trees: the implicit root sequence ---
    pytest.param(
        [route("a")],
        [
            ({}, RUNNING, 0, {"a": PENDING, ROOT: RUNNING}),
            ({"a": COMPLETED}, COMPLETED, 0, {"a": COMPLETED, ROOT: COMPLETED}),
        ],
        id="single route",
    ),
    pytest.param(
        [route("a"), route("b"), route("c")],
        [
            ({}, RUNNING, 0, {"a": PENDING, "b": PENDING, "c": PENDING}),
            ({"a": COMPLETED}, RUNNING, 1, {"a": COMPLETED, "b": PENDING, "c": PENDING}),
            ({"b": COMPLETED}, RUNNING, 2, {"c": PENDING}),
            ({"c": COMPLETED}, COMPLETED, 2, {"a": COMPLETED, "b": COMPLETED, "c": COMPLETED}),
        ],
        id="three routes: RUNNING/0, RUNNING/1, RUNNING/2, COMPLETED/2",
    ),
    pytest.param(
        [route("a"), route("b")],
        [
            ({}, RUNNING, 0, {"a": PENDING}),
            ({}, RUNNING, 0, {"a": RUNNING, "b": PENDING}),
            ({"a": RUNNING}, RUNNING, 0, {"a": RUNNING, "b": PENDING}),
        ],
        id="running leaf: nothing moves",
    ),
    pytest.param(
        [route("a"), route("b")],
        [
            ({}, RUNNING, 0, {}),
            ({"a": FAILED}, FAILED, 0, {"a": FAILED, "b": PENDING, ROOT: FAILED}),
        ],
        id="failed first route fails the mission",
    ),
    pytest.param(
        [route("a"), route("b")],
        [
            ({}, RUNNING, 0, {}),
            ({"a": CANCELED}, FAILED, 0, {"a": CANCELED, "b": PENDING, ROOT: FAILED}),
        ],
        id="canceled leaf counts as a failure",
    ),
    pytest.param(
        [route("0"), action("1"), action("2"), route("3")],
        [
            ({}, RUNNING, 0, {}),
            ({"0": COMPLETED}, RUNNING, 1, {}),
            ({"1": COMPLETED}, RUNNING, 2, {}),
            ({"2": COMPLETED}, RUNNING, 3, {}),
            (
                {"3": COMPLETED},
                COMPLETED,
                3,
                {ROOT: COMPLETED, "0": COMPLETED, "1": COMPLETED, "2": COMPLETED, "3": COMPLETED},
            ),
        ],
        id="reference 1: routes and actions",
    ),
    pytest.param(
        [route("0"), action("1"), route("2")],
        [
            ({}, RUNNING, 0, {}),
            ({"0": COMPLETED}, RUNNING, 1, {}),
            ({"1": FAILED}, FAILED, 1, {ROOT: FAILED, "0": COMPLETED, "1": FAILED, "2": PENDING}),
        ],
        id="reference 2: action failure in the root sequence",
    ),
    pytest.param(
        [move("a"), move("b")],
        [
            ({}, RUNNING, 0, {"a": PENDING}),
            ({"a": COMPLETED}, RUNNING, 1, {"b": PENDING}),
            ({"b": COMPLETED}, COMPLETED, 1, {"a": COMPLETED, "b": COMPLETED}),
        ],
        id="move leaves",
    ),
    pytest.param(
        [move("a"), route("b")],
        [({}, RUNNING, 0, {}), ({"a": FAILED}, FAILED, 0, {"b": PENDING})],
        id="move failure",
    ),
    pytest.param(
        [action("a"), move("b"), route("c")],
        [
            ({}, RUNNING, 0, {}),
            ({"a": COMPLETED}, RUNNING, 1, {}),
            ({"b": COMPLETED}, RUNNING, 2, {}),
            ({"c": FAILED}, FAILED, 2, {"a": COMPLETED, "b": COMPLETED, "c": FAILED}),
        ],
        id="last leaf fails",
    ),
    # --- notify leaves ---
    pytest.param(
        [route("0"), notify("1")],
        [
            ({}, RUNNING, 0, {}),
            ({"0": COMPLETED}, RUNNING, 1, {"1": PENDING}),
            ({"1": COMPLETED}, COMPLETED, 1, {ROOT: COMPLETED, "0": COMPLETED, "1": COMPLETED}),
        ],
        id="reference 7: route then notify",
    ),
    pytest.param(
        [notify("0")],
        [({}, RUNNING, 0, {}), ({"0": COMPLETED}, COMPLETED, 0, {ROOT: COMPLETED, "0": COMPLETED})],
        id="reference 8: single notify",
    ),
    pytest.param(
        [route("0"), notify("1")],
        [
            ({}, RUNNING, 0, {}),
            ({"0": COMPLETED}, RUNNING, 1, {}),
            ({"1": FAILED}, FAILED, 1, {ROOT: FAILED, "0": COMPLETED, "1": FAILED}),
        ],
        id="reference 9: failing notify",
    ),
    pytest.param(
        [notify("n"), route("a"), action("b")],
        [
            ({}, RUNNING, 0, {"n": PENDING}),
            ({"n": COMPLETED}, RUNNING, 1, {"a": PENDING}),
            ({"a": COMPLETED}, RUNNING, 2, {"b": PENDING}),
            ({"b": COMPLETED}, COMPLETED, 2, {}),
        ],
        id="notify first: the next leaves still run",
    ),
    pytest.param(
        [route("a"), notify("n"), route("b")],
        [
            ({}, RUNNING, 0, {}),
            ({"a": COMPLETED}, RUNNING, 1, {"b": PENDING}),
            ({"n": COMPLETED}, RUNNING, 2, {"b": PENDING}),
            ({"b": COMPLETED}, COMPLETED, 2, {}),
        ],
        id="notify between routes does not stall",
    ),
    pytest.param(
        [notify("n1"), notify("n2"), move("m")],
        [
            ({}, RUNNING, 0, {}),
            ({"n1": COMPLETED}, RUNNING, 1, {}),
            ({"n2": COMPLETED}, RUNNING, 2, {"m": PENDING}),
            ({"m": COMPLETED}, COMPLETED, 2, {}),
        ],
        id="two notifies then a move",
    ),
    pytest.param(
        [selector("s"), notify("n", "s"), route("a", "s")],
        [
            ({}, RUNNING, 1, {"s": RUNNING}),
            ({"n": FAILED}, RUNNING, 2, {"n": FAILED, "s": RUNNING, "a": PENDING}),
            ({"a": COMPLETED}, COMPLETED, 2, {"s": COMPLETED}),
        ],
        id="failing notify in a selector falls back",
    ),
    pytest.param(
        [notify("n"), route("a")],
        [({}, RUNNING, 0, {}), ({"n": FAILED}, FAILED, 0, {"a": PENDING})],
        id="failing notify stops the root sequence",
    ),
    # --- selectors ---
    pytest.param(
        [route("0"), selector("selector_1"), action("2", "selector_1"), route("3", "selector_1")],
        [
            ({}, RUNNING, 0, {"selector_1": PENDING}),
            ({"0": COMPLETED}, RUNNING, 2, {"selector_1": RUNNING}),
            ({"2": FAILED}, RUNNING, 3, {"selector_1": RUNNING, "2": FAILED, "3": PENDING}),
            (
                {"3": COMPLETED},
                COMPLETED,
                3,
                {ROOT: COMPLETED, "0": COMPLETED, "selector_1": COMPLETED, "2": FAILED, "3": COMPLETED},
            ),
        ],
        id="reference 3: selector with failing action",
    ),
    pytest.param(
        [selector("s"), route("a", "s"), route("b", "s"), route("c")],
        [
            ({}, RUNNING, 1, {"s": RUNNING}),
            ({"a": COMPLETED}, RUNNING, 3, {"s": COMPLETED, "b": PENDING, "c": PENDING}),
            ({"c": COMPLETED}, COMPLETED, 3, {"b": PENDING}),
        ],
        id="selector: first child succeeds, the others are skipped",
    ),
    pytest.param(
        [selector("s"), route("a", "s"), action("b", "s"), route("c")],
        [
            ({}, RUNNING, 1, {}),
            ({"a": FAILED}, RUNNING, 2, {"s": RUNNING}),
            ({"b": FAILED}, FAILED, 2, {"s": FAILED, "a": FAILED, "b": FAILED, "c": PENDING, ROOT: FAILED}),
        ],
        id="selector: all children fail",
    ),
    pytest.param(
        [selector("s"), route("a", "s"), sequence("q", "s"), route("b", "q"), route("c", "q")],
        [
            ({}, RUNNING, 1, {}),
            ({"a": FAILED}, RUNNING, 3, {"q": RUNNING}),
            ({"b": FAILED}, FAILED, 3, {"q": FAILED, "s": FAILED, "c": PENDING}),
        ],
        id="selector: all fail, last child a sequence; tip is where it failed",
    ),
    pytest.param(
        [selector("s"), route("a", "s"), route("b", "s")],
        [
            ({}, RUNNING, 1, {}),
            ({"a": CANCELED}, RUNNING, 2, {"a": CANCELED, "s": RUNNING}),
            ({"b": COMPLETED}, COMPLETED, 2, {"s": COMPLETED}),
        ],
        id="selector: canceled child falls back",
    ),
    pytest.param(
        [selector("o"), selector("i", "o"), route("a", "i"), route("b", "i"), route("c", "o")],
        [
            ({}, RUNNING, 2, {"o": RUNNING, "i": RUNNING}),
            ({"a": FAILED}, RUNNING, 3, {"i": RUNNING}),
            ({"b": FAILED}, RUNNING, 4, {"i": FAILED, "o": RUNNING, "c": PENDING}),
            ({"c": COMPLETED}, COMPLETED, 4, {"o": COMPLETED, "i": FAILED}),
        ],
        id="selector inside selector",
    ),
    # --- sequences ---
    pytest.param(
        [sequence("q"), route("a", "q"), route("b", "q")],
        [
            ({}, RUNNING, 1, {"q": RUNNING}),
            ({"a": COMPLETED}, RUNNING, 2, {"q": RUNNING}),
            ({"b": COMPLETED}, COMPLETED, 2, {"q": COMPLETED}),
        ],
        id="sequence: all children succeed",
    ),
    pytest.param(
        [route("0"), sequence("sequence_1"), action("2", "sequence_1"), route("3", "sequence_1")],
        [
            ({}, RUNNING, 0, {"sequence_1": PENDING}),
            ({"0": COMPLETED}, RUNNING, 2, {"sequence_1": RUNNING}),
            (
                {"2": FAILED},
                FAILED,
                2,
                {ROOT: FAILED, "0": COMPLETED, "sequence_1": FAILED, "2": FAILED, "3": PENDING},
            ),
        ],
        id="reference 4: sequence with failing action",
    ),
    pytest.param(
        [sequence("q1"), sequence("q2", "q1"), route("a", "q2"), route("b", "q1"), route("c")],
        [
            ({}, RUNNING, 2, {"q1": RUNNING, "q2": RUNNING}),
            ({"a": COMPLETED}, RUNNING, 3, {"q2": COMPLETED, "q1": RUNNING}),
            ({"b": COMPLETED}, RUNNING, 4, {"q1": COMPLETED}),
            ({"c": COMPLETED}, COMPLETED, 4, {}),
        ],
        id="nested sequences",
    ),
    pytest.param(
        [selector("s"), sequence("q", "s"), route("a", "q"), route("b", "q"), route("c", "s")],
        [
            ({}, RUNNING, 2, {"s": RUNNING, "q": RUNNING}),
            ({"a": COMPLETED}, RUNNING, 3, {}),
            ({"b": FAILED}, RUNNING, 4, {"q": FAILED, "s": RUNNING, "a": COMPLETED, "c": PENDING}),
            ({"c": COMPLETED}, COMPLETED, 4, {"s": COMPLETED, "q": FAILED}),
        ],
        id="sequence inside selector fails midway, selector falls back",
    ),
    pytest.param(
        [selector("s"), sequence("q", "s"), route("a", "q"), route("b", "q"), route("c", "s")],
        [
            ({}, RUNNING, 2, {}),
            ({"a": COMPLETED}, RUNNING, 3, {}),
            ({"b": COMPLETED}, COMPLETED, 3, {"q": COMPLETED, "s": COMPLETED, "c": PENDING}),
        ],
        id="sequence inside selector succeeds, fallback skipped",
    ),
    pytest.param(
        [sequence("q"), selector("s", "q"), route("a", "s"), route("b", "s"), route("c", "q")],
        [
            ({}, RUNNING, 2, {"q": RUNNING, "s": RUNNING}),
            ({"a": FAILED}, RUNNING, 3, {}),
            ({"b": COMPLETED}, RUNNING, 4, {"s": COMPLETED, "q": RUNNING}),
            ({"c": COMPLETED}, COMPLETED, 4, {"q": COMPLETED}),
        ],
        id="selector inside sequence succeeds, sequence continues",
    ),
    pytest.param(
        [sequence("q"), selector("s", "q"), route("a", "s"), route("b", "s"), route("c", "q")],
        [
            ({}, RUNNING, 2, {}),
            ({"a": FAILED}, RUNNING, 3, {}),
            ({"b": FAILED}, FAILED, 3, {"s": FAILED, "q": FAILED, "c": PENDING}),
        ],
        id="selector failure fails the enclosing sequence",
    ),
    # --- three layers ---
    pytest.param(
        [
            route("0"),
            selector("selector_1"),
            action("2", "selector_1"),
            sequence("sequence_1", "selector_1"),
            route("4", "sequence_1"),
            route("5", "sequence_1"),
            route("6"),
        ],
        [
            ({}, RUNNING, 0, {}),
            ({"0": COMPLETED}, RUNNING, 2, {}),
            ({"2": FAILED}, RUNNING, 4, {"sequence_1": RUNNING, "selector_1": RUNNING}),
            ({"4": COMPLETED}, RUNNING, 5, {}),
            ({"5": COMPLETED}, RUNNING, 6, {"sequence_1": COMPLETED, "selector_1": COMPLETED}),
            (
                {"6": COMPLETED},
                COMPLETED,
                6,
                {
                    ROOT: COMPLETED,
                    "0": COMPLETED,
                    "selector_1": COMPLETED,
                    "2": FAILED,
                    "sequence_1": COMPLETED,
                    "4": COMPLETED,
                    "5": COMPLETED,
                    "6": COMPLETED,
                },
            ),
        ],
        id="reference 5: selector with a nested sequence",
    ),
    pytest.param(
        [
            route("0"),
            action("pickup"),
            selector("selector_1"),
            action("fake_failure_route", "selector_1"),
            sequence("sequence_1", "selector_1"),
            route("5", "sequence_1"),
            action("dropoff", "sequence_1"),
            constant("constant_node", False, "sequence_1"),
            action("dropoff_at_goal"),
        ],
        [
            ({}, RUNNING, 0, {}),
            ({"0": COMPLETED}, RUNNING, 1, {}),
            ({"pickup": COMPLETED}, RUNNING, 3, {}),
            ({"fake_failure_route": FAILED}, RUNNING, 5, {}),
            ({"5": COMPLETED}, RUNNING, 6, {"constant_node": PENDING}),
            (
                {"dropoff": COMPLETED},
                FAILED,
                7,
                {
                    ROOT: FAILED,
                    "0": COMPLETED,
                    "pickup": COMPLETED,
                    "selector_1": FAILED,
                    "fake_failure_route": FAILED,
                    "sequence_1": FAILED,
                    "5": COMPLETED,
                    "dropoff": COMPLETED,
                    "constant_node": FAILED,
                    "dropoff_at_goal": PENDING,
                },
            ),
        ],
        id="reference 6: three layers ending on a failing constant",
    ),
    pytest.param(
        [
            sequence("q"),
            selector("s", "q"),
            sequence("q2", "s"),
            route("a", "q2"),
            route("b", "q2"),
            route("c", "s"),
            route("d", "q"),
        ],
        [
            ({}, RUNNING, 3, {"q": RUNNING, "s": RUNNING, "q2": RUNNING}),
            ({"a": COMPLETED}, RUNNING, 4, {}),
            ({"b": FAILED}, RUNNING, 5, {"q2": FAILED, "s": RUNNING}),
            ({"c": COMPLETED}, RUNNING, 6, {"s": COMPLETED, "q": RUNNING}),
            ({"d": COMPLETED}, COMPLETED, 6, {"q": COMPLETED, "q2": FAILED, "b": FAILED}),
        ],
        id="three layers: sequence in selector in sequence",
    ),
    pytest.param(
        [
            selector("s"),
            sequence("q", "s"),
            selector("s2", "q"),
            route("a", "s2"),
            route("b", "s2"),
            route("c", "q"),
        ],
        [
            ({}, RUNNING, 3, {}),
            ({"a": FAILED}, RUNNING, 4, {}),
            ({"b": FAILED}, FAILED, 4, {"s2": FAILED, "q": FAILED, "s": FAILED, "c": PENDING}),
        ],
        id="three layers: deep failure with no fallback",
    ),
    pytest.param(
        [
            selector("s"),
            sequence("q1", "s"),
            action("a", "q1"),
            route("b", "q1"),
            sequence("q2", "s"),
            selector("s2", "q2"),
            route("c", "s2"),
            move("d", "s2"),
            notify("e", "q2"),
            route("f"),
        ],
        [
            ({}, RUNNING, 2, {"s": RUNNING, "q1": RUNNING, "q2": PENDING}),
            ({"a": FAILED}, RUNNING, 6, {"q1": FAILED, "q2": RUNNING, "s2": RUNNING, "b": PENDING}),
            ({"c": FAILED}, RUNNING, 7, {}),
            ({"d": COMPLETED}, RUNNING, 8, {"s2": COMPLETED, "q2": RUNNING}),
            ({"e": COMPLETED}, RUNNING, 9, {"q2": COMPLETED, "s": COMPLETED}),
            ({"f": COMPLETED}, COMPLETED, 9, {"b": PENDING, "c": FAILED}),
        ],
        id="three layers: every leaf kind",
    ),
    # --- constants ---
    pytest.param(
        [constant("k", True)],
        [({}, COMPLETED, 0, {"k": COMPLETED, ROOT: COMPLETED})],
        id="constant true alone",
    ),
    pytest.param(
        [constant("k", False)],
        [({}, FAILED, 0, {"k": FAILED, ROOT: FAILED})],
        id="constant false alone",
    ),
    pytest.param(
        [{"name": "k", "parent": ROOT, "constant": {}}],
        [({}, COMPLETED, 0, {"k": COMPLETED})],
        id="constant succeeds by default",
    ),
    pytest.param(
        [constant("k", True), route("a")],
        [({}, RUNNING, 1, {"k": COMPLETED, "a": PENDING}), ({"a": COMPLETED}, COMPLETED, 1, {})],
        id="constant true before a route",
    ),
    pytest.param(
        [constant("k", False), route("a")],
        [({}, FAILED, 0, {"k": FAILED, "a": PENDING})],
        id="constant false before a route",
    ),
    pytest.param(
        [route("a"), constant("k", True)],
        [({}, RUNNING, 0, {"k": PENDING}), ({"a": COMPLETED}, COMPLETED, 1, {"k": COMPLETED})],
        id="constant true after a route",
    ),
    pytest.param(
        [route("a"), constant("k", False)],
        [({}, RUNNING, 0, {"k": PENDING}), ({"a": COMPLETED}, FAILED, 1, {"k": FAILED})],
        id="constant false after a route",
    ),
    pytest.param(
        [selector("s"), constant("k", False, "s"), route("a", "s")],
        [({}, RUNNING, 2, {"k": FAILED, "s": RUNNING}), ({"a": COMPLETED}, COMPLETED, 2, {"s": COMPLETED})],
        id="selector: constant false falls through to a route",
    ),
    pytest.param(
        [selector("s"), constant("k", True, "s"), route("a", "s")],
        [({}, COMPLETED, 1, {"k": COMPLETED, "s": COMPLETED, "a": PENDING})],
        id="selector: constant true wins before the route",
    ),
    pytest.param(
        [selector("s"), route("a", "s"), constant("k", True, "s")],
        [({}, RUNNING, 1, {"k": PENDING}), ({"a": FAILED}, COMPLETED, 2, {"k": COMPLETED, "s": COMPLETED})],
        id="selector: constant true after a failing route",
    ),
    pytest.param(
        [selector("s"), constant("k1", False, "s"), constant("k2", False, "s")],
        [({}, FAILED, 2, {"k1": FAILED, "k2": FAILED, "s": FAILED})],
        id="selector: only failing constants",
    ),
    pytest.param(
        [sequence("q"), route("a", "q"), constant("k", False, "q")],
        [({}, RUNNING, 1, {}), ({"a": COMPLETED}, FAILED, 2, {"k": FAILED, "q": FAILED})],
        id="sequence: failing constant after a route",
    ),
    pytest.param(
        [sequence("q"), constant("k1", True, "q"), constant("k2", True, "q")],
        [({}, COMPLETED, 2, {"k1": COMPLETED, "k2": COMPLETED, "q": COMPLETED})],
        id="sequence: only succeeding constants",
    ),
    pytest.param(
        [sequence("q"), selector("s", "q"), constant("k", False, "s"), route("a", "s"), route("b", "q")],
        [
            ({}, RUNNING, 3, {"k": FAILED}),
            ({"a": COMPLETED}, RUNNING, 4, {"s": COMPLETED}),
            ({"b": COMPLETED}, COMPLETED, 4, {"q": COMPLETED}),
        ],
        id="constant false guarding a route inside a sequence",
    ),
    # --- empty composites and trees (py_trees: empty sequence succeeds, empty selector fails) ---
    pytest.param([sequence("q")], [({}, COMPLETED, 0, {"q": COMPLETED})], id="empty sequence succeeds"),
    pytest.param([selector("s")], [({}, FAILED, 0, {"s": FAILED})], id="empty selector fails"),
    pytest.param(
        [route("a"), sequence("q"), route("b")],
        [
            ({}, RUNNING, 0, {"q": PENDING}),
            ({"a": COMPLETED}, RUNNING, 2, {"q": COMPLETED}),
            ({"b": COMPLETED}, COMPLETED, 2, {}),
        ],
        id="empty sequence between routes is passed",
    ),
    pytest.param(
        [route("a"), selector("s"), route("b")],
        [({}, RUNNING, 0, {}), ({"a": COMPLETED}, FAILED, 1, {"s": FAILED, "b": PENDING})],
        id="empty selector between routes fails the mission",
    ),
    pytest.param(
        [route("a"), sequence("q")],
        [({}, RUNNING, 0, {}), ({"a": COMPLETED}, COMPLETED, 1, {"q": COMPLETED})],
        id="empty sequence last: current_node is the composite",
    ),
    pytest.param(
        [selector("s"), selector("e", "s"), route("a", "s")],
        [({}, RUNNING, 2, {"e": FAILED, "s": RUNNING}), ({"a": COMPLETED}, COMPLETED, 2, {"e": FAILED})],
        id="selector skips an empty selector",
    ),
    pytest.param(
        [selector("s"), sequence("e", "s"), route("a", "s")],
        [({}, COMPLETED, 1, {"e": COMPLETED, "s": COMPLETED, "a": PENDING})],
        id="selector takes an empty sequence",
    ),
    pytest.param(
        [], [({}, COMPLETED, None, {ROOT: COMPLETED})], id="empty tree completes with no current node"
    ),
]


@pytest.mark.parametrize(("mission_tree", "steps"), CASES)
def test_tick_sequence(mission_tree, steps):
    play(mission_tree, steps)
