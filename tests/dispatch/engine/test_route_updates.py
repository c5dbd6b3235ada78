"""apply_route_updates: spec.update_nodes replaces the waypoints of route nodes."""

import copy

import pytest

from dispatch.engine import TreeError, apply_route_updates, parse_tree, set_leaf_state, tick

from .trees import RUNNING, action, play, route, selector

NEW_ROUTE = {"waypoints": [{"x": 5.0, "y": 6.0, "theta": 1.5}, {"x": 7.0, "y": 8.0, "theta": 0.0}]}


def test_named_route_gets_the_new_waypoints_and_nothing_else_changes():
    tree = parse_tree([route("a"), selector("s"), route("b", "s"), action("c", "s")])
    before = copy.deepcopy(tree)
    updated = apply_route_updates(tree, {"b": NEW_ROUTE})
    assert tree == before
    assert updated.node("b").params == NEW_ROUTE
    assert [n for n in updated.nodes if n.name != "b"] == [n for n in tree.nodes if n.name != "b"]
    assert updated.node("b").children == () and updated.node("s").children == ("b", "c")


def test_updated_params_do_not_share_data_with_update_nodes():
    update_nodes = {"a": copy.deepcopy(NEW_ROUTE)}
    updated = apply_route_updates(parse_tree([route("a")]), update_nodes)
    update_nodes["a"]["waypoints"].clear()
    assert updated.node("a").params == NEW_ROUTE


@pytest.mark.parametrize("update_nodes", [None, {}])
def test_no_updates_returns_the_tree(update_nodes):
    tree = parse_tree([route("a")])
    assert apply_route_updates(tree, update_nodes) is tree


@pytest.mark.parametrize(
    ("update_nodes", "message"),
    [
        pytest.param({"ghost": NEW_ROUTE}, "Node ghost does not exist", id="unknown node"),
        pytest.param(
            {"c": NEW_ROUTE}, "Only route nodes can be updated, but c is a action node", id="action"
        ),
        pytest.param({"s": NEW_ROUTE}, "but s is a selector node", id="selector"),
    ],
)
def test_only_existing_route_nodes_can_be_updated(update_nodes, message):
    with pytest.raises(TreeError, match=message):
        apply_route_updates(parse_tree([route("a"), selector("s"), action("c", "s")]), update_nodes)


def test_running_route_restarted_after_an_update():
    """The worker sets the canceled route back to PENDING; the next tick asks to start it again."""
    mission_tree = [route("a"), route("b")]
    node_status = play(mission_tree, [({}, RUNNING, 0, {})])
    tree = apply_route_updates(parse_tree(mission_tree), {"a": NEW_ROUTE})
    result = tick(tree, set_leaf_state(node_status, "a", "PENDING"))
    assert (result.mission_state, result.current_node) == (RUNNING, 0)
    assert result.leaf_to_start is not None
    assert result.leaf_to_start.params == NEW_ROUTE
