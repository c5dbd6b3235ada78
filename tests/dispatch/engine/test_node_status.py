"""initial_node_status, set_leaf_state and how tick treats stored node states."""

import copy

import pytest

from dispatch.engine import ROOT, TreeError, initial_node_status, parse_tree, set_leaf_state, tick

from .trees import CANCELED, COMPLETED, FAILED, PENDING, RUNNING, route, selector, states


def test_initial_node_status_has_root_and_every_node_pending():
    tree = parse_tree([route("a"), selector("s"), route("b", "s")])
    assert initial_node_status(tree) == {
        ROOT: {"state": PENDING, "error_msg": None},
        "a": {"state": PENDING, "error_msg": None},
        "s": {"state": PENDING, "error_msg": None},
        "b": {"state": PENDING, "error_msg": None},
    }


def test_set_leaf_state_returns_a_copy():
    node_status = initial_node_status(parse_tree([route("a"), route("b")]))
    before = copy.deepcopy(node_status)
    changed = set_leaf_state(node_status, "a", RUNNING)
    assert node_status == before
    assert changed["a"] == {"state": RUNNING, "error_msg": None}
    assert changed["b"] == before["b"]


def test_set_leaf_state_keeps_the_error_message_unless_given():
    node_status = initial_node_status(parse_tree([route("a")]))
    failed = set_leaf_state(node_status, "a", FAILED, "Action failure")
    assert failed["a"] == {"state": FAILED, "error_msg": "Action failure"}
    assert set_leaf_state(failed, "a", CANCELED)["a"] == {"state": CANCELED, "error_msg": "Action failure"}


@pytest.mark.parametrize(
    ("name", "state", "message"),
    [
        pytest.param("ghost", RUNNING, "Node ghost does not exist", id="unknown node"),
        pytest.param("a", "DONE", "Unknown node state DONE", id="unknown state"),
    ],
)
def test_set_leaf_state_refuses(name, state, message):
    with pytest.raises(TreeError, match=message):
        set_leaf_state(initial_node_status(parse_tree([route("a")])), name, state)


def test_tick_keeps_error_messages_and_unknown_keys():
    tree = parse_tree([selector("s"), route("a", "s"), route("b", "s")])
    node_status = set_leaf_state(initial_node_status(tree), "a", FAILED, "Action failure")
    node_status["s"]["error_msg"] = "kept"
    result = tick(tree, node_status)
    assert result.node_status["a"] == {"state": FAILED, "error_msg": "Action failure"}
    assert result.node_status["s"] == {"state": RUNNING, "error_msg": "kept"}


def test_tick_fills_in_nodes_missing_from_a_stored_status():
    tree = parse_tree([route("a"), route("b")])
    result = tick(tree, {"a": {"state": COMPLETED, "error_msg": None}})
    assert (result.mission_state, result.current_node) == (RUNNING, 1)
    assert states(result.node_status, [ROOT, "a", "b"]) == {ROOT: RUNNING, "a": COMPLETED, "b": PENDING}


def test_tick_refuses_an_unknown_leaf_state():
    tree = parse_tree([route("a")])
    node_status = initial_node_status(tree)
    node_status["a"]["state"] = "SUCCESS"
    with pytest.raises(TreeError, match="Node a has unknown state SUCCESS"):
        tick(tree, node_status)


def test_current_leaf_carries_what_the_worker_needs_to_run_it():
    mission_tree = [route("a")]
    tree = parse_tree(mission_tree)
    result = tick(tree, initial_node_status(tree))
    assert result.current_leaf is not None
    assert (result.current_leaf.kind, result.current_leaf.index) == ("route", 0)
    assert result.current_leaf.params == mission_tree[0]["route"]


def test_leaf_to_start_only_while_the_current_leaf_is_pending():
    tree = parse_tree([route("a")])
    first = tick(tree, initial_node_status(tree))
    assert first.leaf_to_start == tree.node("a")
    started = tick(tree, set_leaf_state(first.node_status, "a", RUNNING))
    assert started.current_leaf == tree.node("a")
    assert started.leaf_to_start is None


def test_tick_is_idempotent():
    tree = parse_tree([route("a"), selector("s"), route("b", "s"), route("c", "s")])
    node_status = set_leaf_state(initial_node_status(tree), "a", COMPLETED)
    node_status = set_leaf_state(node_status, "b", FAILED)
    first = tick(tree, node_status)
    second = tick(tree, first.node_status)
    assert second == first
    assert (first.mission_state, first.current_node) == (RUNNING, 3)


def test_tick_does_not_modify_its_input():
    tree = parse_tree([selector("s"), route("a", "s"), route("b", "s")])
    node_status = set_leaf_state(initial_node_status(tree), "a", FAILED)
    before = copy.deepcopy(node_status)
    result = tick(tree, node_status)
    assert node_status == before
    assert result.node_status != before
    result.node_status["b"]["state"] = COMPLETED
    assert node_status == before


@pytest.mark.parametrize("state", [COMPLETED, FAILED, CANCELED])
def test_a_finished_mission_is_not_evaluated_again(state):
    tree = parse_tree([selector("s"), route("a", "s"), route("b", "s")])
    node_status = set_leaf_state(initial_node_status(tree), "a", CANCELED)
    node_status = set_leaf_state(node_status, ROOT, state)
    result = tick(tree, node_status)
    assert (result.mission_state, result.current_node, result.current_leaf) == (state, None, None)
    assert result.node_status == node_status
