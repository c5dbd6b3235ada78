"""finish: ending a mission as CANCELED (user cancel) or FAILED (timeout, deadline) from outside the tree.

Each case plays a mission to some point, finishes it, and checks the result: the running leaf takes the
final state, root mirrors it, every other node keeps its stored state.
"""

import copy

import pytest

from dispatch.engine import ROOT, TreeError, finish, initial_node_status, parse_tree, set_leaf_state, tick

from .trees import CANCELED, COMPLETED, FAILED, PENDING, RUNNING, play, route, selector, sequence, states

CASES = [
    pytest.param(
        [route("a"), route("b")],
        [({}, RUNNING, 0, {})],
        FAILED,
        "Mission timed out",
        0,
        {ROOT: FAILED, "a": FAILED, "b": PENDING},
        id="timeout while the first route runs",
    ),
    pytest.param(
        [route("a"), route("b")],
        [({}, RUNNING, 0, {}), ({"a": COMPLETED}, RUNNING, 1, {})],
        CANCELED,
        None,
        1,
        {ROOT: CANCELED, "a": COMPLETED, "b": CANCELED},
        id="cancel while the second route runs",
    ),
    pytest.param(
        [selector("s"), route("a", "s"), route("b", "s"), route("c")],
        [({}, RUNNING, 1, {})],
        CANCELED,
        None,
        1,
        {ROOT: CANCELED, "s": RUNNING, "a": CANCELED, "b": PENDING, "c": PENDING},
        id="cancel inside a selector: the fallback is not started",
    ),
    pytest.param(
        [sequence("q"), route("a", "q"), route("b", "q")],
        [({}, RUNNING, 1, {}), ({"a": COMPLETED}, RUNNING, 2, {})],
        FAILED,
        "Mission timed out",
        2,
        {ROOT: FAILED, "q": RUNNING, "a": COMPLETED, "b": FAILED},
        id="timeout inside a sequence leaves the sequence as it was",
    ),
    pytest.param(
        [selector("s"), route("a", "s")],
        [],
        CANCELED,
        None,
        1,
        {ROOT: CANCELED, "s": PENDING, "a": PENDING},
        id="mission never started: only root changes",
    ),
]


@pytest.mark.parametrize(("mission_tree", "steps", "state", "error_msg", "current_node", "expected"), CASES)
def test_finish(mission_tree, steps, state, error_msg, current_node, expected):
    tree = parse_tree(mission_tree)
    node_status = play(mission_tree, steps)
    before = copy.deepcopy(node_status)
    result = finish(tree, node_status, state=state, error_msg=error_msg)
    assert node_status == before
    assert (result.mission_state, result.current_node, result.current_leaf) == (state, current_node, None)
    assert states(result.node_status, expected) == expected
    current_leaf = tick(tree, before).current_leaf
    for name, entry in result.node_status.items():
        if name not in (ROOT, current_leaf.name):
            assert entry == before[name], name


def test_finish_puts_the_error_message_on_the_running_leaf():
    tree = parse_tree([route("a")])
    node_status = play([route("a")], [({}, RUNNING, 0, {})])
    result = finish(tree, node_status, state=FAILED, error_msg="Mission timed out")
    assert result.node_status["a"] == {"state": FAILED, "error_msg": "Mission timed out"}
    assert result.node_status[ROOT] == {"state": FAILED, "error_msg": None}


def test_finish_leaves_a_leaf_that_was_never_started_pending():
    tree = parse_tree([route("a")])
    ticked = tick(tree, initial_node_status(tree))
    result = finish(tree, ticked.node_status, state=FAILED)
    assert states(result.node_status, [ROOT, "a"]) == {ROOT: FAILED, "a": PENDING}


@pytest.mark.parametrize("state", [COMPLETED, RUNNING, PENDING])
def test_finish_refuses_other_states(state):
    tree = parse_tree([route("a")])
    with pytest.raises(TreeError, match=f"can only be finished as CANCELED or FAILED, not {state}"):
        finish(tree, initial_node_status(tree), state=state)


def test_finishing_a_finished_mission_changes_nothing():
    mission_tree = [route("a")]
    tree = parse_tree(mission_tree)
    node_status = play(mission_tree, [({}, RUNNING, 0, {}), ({"a": COMPLETED}, COMPLETED, 0, {})])
    node_status = tick(tree, node_status).node_status
    result = finish(tree, node_status, state=CANCELED)
    assert result.mission_state == COMPLETED
    assert result.node_status == node_status


def test_a_finished_mission_stays_finished_when_ticked():
    mission_tree = [selector("s"), route("a", "s"), route("b", "s")]
    tree = parse_tree(mission_tree)
    finished = finish(tree, play(mission_tree, [({}, RUNNING, 1, {})]), state=CANCELED)
    result = tick(tree, finished.node_status)
    assert (result.mission_state, result.current_leaf) == (CANCELED, None)
    assert result.node_status == finished.node_status
    assert result.node_status["b"]["state"] == PENDING


def test_cancel_acknowledged_by_the_robot_before_finish():
    """The robot reports the leaf CANCELED, then the caller ends the mission: states agree."""
    mission_tree = [route("a"), route("b")]
    tree = parse_tree(mission_tree)
    node_status = set_leaf_state(play(mission_tree, [({}, RUNNING, 0, {})]), "a", CANCELED)
    result = finish(tree, node_status, state=CANCELED)
    assert states(result.node_status, [ROOT, "a", "b"]) == {ROOT: CANCELED, "a": CANCELED, "b": PENDING}
    assert result.current_node == 0
