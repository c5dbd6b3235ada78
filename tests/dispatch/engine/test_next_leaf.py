"""next_leaf: the leaf a tick starts once the running leaf succeeds, whatever lies between them.

Table-driven: a tree, leaf results written before (the running leaf is started by ticking as a worker
would), the running leaf, and the leaf expected next (None: the mission ends with it). Each case is also
checked against the engine itself: completing the running leaf and ticking starts exactly that leaf.
"""

from typing import Any

import pytest

from dispatch.engine import initial_node_status, next_leaf, parse_tree, set_leaf_state, tick

from .trees import COMPLETED, FAILED, RUNNING, action, constant, move, notify, route, selector, sequence

CASES = [
    pytest.param([route("a"), route("b")], {}, "a", "b", id="route after route in the root sequence"),
    pytest.param([route("a")], {}, "a", None, id="last leaf: the mission ends"),
    pytest.param([route("a"), action("x"), route("b")], {}, "a", "x", id="an action between"),
    pytest.param([route("a"), notify("n"), route("b")], {}, "a", "n", id="a notify between"),
    pytest.param([route("a"), move("m")], {}, "a", "m", id="a move next"),
    pytest.param(
        [sequence("q"), route("a", "q"), route("b", "q"), route("c")],
        {"a": COMPLETED},
        "b",
        "c",
        id="out of a nested sequence into the next",
    ),
    pytest.param(
        [selector("s"), route("a", "s"), route("b", "s"), route("c")],
        {},
        "a",
        "c",
        id="a selector's first success skips its other children",
    ),
    pytest.param(
        [selector("s"), route("a", "s"), route("b", "s"), route("c")],
        {"a": FAILED},
        "b",
        "c",
        id="a selector's fallback child, then what follows the selector",
    ),
    pytest.param(
        [selector("s"), sequence("q", "s"), route("a", "q"), route("b", "q"), route("c", "s")],
        {},
        "a",
        "b",
        id="inside a sequence under a selector",
    ),
    pytest.param(
        [route("a"), constant("k", True), route("b")],
        {},
        "a",
        "b",
        id="a succeeding constant between: fixed, not a branch",
    ),
    pytest.param(
        [route("a"), constant("k", False), route("b")],
        {},
        "a",
        None,
        id="a failing constant between: the mission fails",
    ),
    pytest.param(
        [selector("s"), sequence("q", "s"), route("a", "q"), constant("k", False, "q"), route("b", "s")],
        {},
        "a",
        "b",
        id="a failing constant after it makes the selector take its next child",
    ),
    pytest.param(
        [sequence("q"), route("a", "q"), sequence("e", "q"), route("b")],
        {},
        "a",
        "b",
        id="an empty sequence between succeeds",
    ),
    pytest.param(
        [route("a"), selector("e"), route("b")],
        {},
        "a",
        None,
        id="an empty selector between fails the mission",
    ),
]


def _running(mission_tree: list[dict[str, Any]], results: dict[str, str], leaf: str):
    tree = parse_tree(mission_tree)
    node_status = initial_node_status(tree)
    for name, state in results.items():
        node_status = set_leaf_state(node_status, name, state)
    ticked = tick(tree, node_status)
    assert ticked.leaf_to_start is not None and ticked.leaf_to_start.name == leaf
    return tree, set_leaf_state(ticked.node_status, leaf, RUNNING)


@pytest.mark.parametrize(("mission_tree", "results", "leaf", "expected"), CASES)
def test_next_leaf(mission_tree, results, leaf, expected) -> None:
    tree, node_status = _running(mission_tree, results, leaf)

    following = next_leaf(tree, node_status, leaf)

    assert (following.name if following else None) == expected
    after = tick(tree, set_leaf_state(node_status, leaf, COMPLETED))
    assert after.leaf_to_start == following


def test_next_leaf_leaves_the_node_states_alone() -> None:
    tree, node_status = _running([route("a"), route("b")], {}, "a")
    before = {name: dict(entry) for name, entry in node_status.items()}

    next_leaf(tree, node_status, "a")

    assert node_status == before
